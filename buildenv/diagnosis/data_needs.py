"""Whether a site's weeks can show an effect at all: the hours in which its footprint can be non-zero.

Some effects act only in some hours: a heating plant short of power only when the demand is high, heat recovery
only while the air handling unit heats outdoor air, cold air from night-cycling fans only while the zones are
heated with the ventilation off. An effect (:attr:`buildenv.diagnosis.effects.Effect.shows_in`) names such a need;
a site whose fit or held-out weeks have fewer than :data:`ENOUGH_HOURS` of those hours cannot be told to have it
or not: the diagnosis says "not enough data to tell" for it instead of judging it.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat
from buildenv.metamodel import surrogate as sg

#: Fewest hours of the fit weeks, and of the held-out weeks, in which an effect must be able to show (a working
#: day's occupied hours): below it there is nothing to estimate it from, or nothing to judge it on.
ENOUGH_HOURS = 10
#: Heat (Wh/m2 of floor in an hour) below which an hour counts as not heated: a tenth of a typical office's
#: lighting power, under what the consumption meter resolves.
HEATED_WH_M2 = 1.0

#: What each need means, as the verdict says it.
NEEDS = {
    "heating_peaks": "hours whose zone heating reaches the smallest plant share seen in practice",
    "ventilated_heating": "hours in which the air handling unit heats outdoor air",
    "heating_fans_off": "heated hours with the ventilation off",
}

_OUT = {name: i for i, name in enumerate(cat.OUTPUT_NAMES)}
_CH = {name: i for i, name in enumerate(sg.INPUT_CHANNELS)}


def hours_showing(need: str, outputs: np.ndarray, week_inputs: np.ndarray, smallest_share: float = 0.0) -> np.ndarray:
    """``(weeks, 168)`` booleans: the hours of a model's weeks in which an effect with ``need`` can show.

    Args:
        need: a key of :data:`NEEDS`.
        outputs: ``(weeks, 168, 8)`` the base model's outputs (:data:`buildenv.catalogue.OUTPUT_NAMES`).
        week_inputs: ``(weeks, 168, C)`` its encoded inputs over the weeks (context hours left out).
        smallest_share: for ``heating_peaks``, the smallest plant share of its heating power seen in practice
            (0-1); an hour counts when the zones' heating reaches that share of the model's heating power.
    Raises:
        KeyError: an unknown ``need``.
    """
    heat = outputs[..., _OUT["Q_HEAT_OFFICE"]] + outputs[..., _OUT["Q_AHU_H"]]
    fans_on = week_inputs[..., _CH["ventilation_on"]] > 0
    if need == "heating_peaks":  # the zones' heating, which the model's heating power limits
        zones = outputs[..., _OUT["Q_HEAT_OFFICE"]]
        power = week_inputs[..., _CH["heating_power_w_m2"]]
        return (zones >= HEATED_WH_M2) & (zones >= smallest_share * power)
    if need == "ventilated_heating":
        return fans_on & (outputs[..., _OUT["Q_AHU_H"]] >= HEATED_WH_M2)
    if need == "heating_fans_off":
        return ~fans_on & (heat >= HEATED_WH_M2)
    raise KeyError(f"unknown data need {need!r}; choose {', '.join(NEEDS)}")


def lacking(need: str | None, fit_hours: int, heldout_hours: int) -> str | None:
    """Why a site cannot show an effect with ``need`` (one phrase), or None when both its fit and held-out weeks
    have at least :data:`ENOUGH_HOURS` of the hours it needs (always None for an effect with no need)."""
    if need is None or min(fit_hours, heldout_hours) >= ENOUGH_HOURS:
        return None
    return (
        f"{fit_hours} fit-week and {heldout_hours} held-out {NEEDS[need]} (at least {ENOUGH_HOURS} of each are needed)"
    )
