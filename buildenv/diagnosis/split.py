"""Fit and held-out weeks of a site: the split every diagnosis judges by, and what weather each side saw."""

from __future__ import annotations

from buildenv import catalogue as cat
from buildenv.calibration import problem as cal
from buildenv.diagnosis.effects import DIAGNOSIS_SPLITS

# Share (%) of held-out hours colder than every fit hour above which the diagnosis says so (:func:`split_weather`).
COLDER_HELDOUT_NOTE_PERCENT = 20.0


def split_weeks(n_weeks: int, split: str = DIAGNOSIS_SPLITS[0]) -> tuple[list[int], list[int]]:
    """Fit and held-out weeks of a site of ``n_weeks`` weeks: ``"first_half"`` fits the first half (rounded up,
    :func:`buildenv.calibration.problem.default_weeks`) and holds out the rest; ``"alternate"`` fits weeks 0, 2, 4, ...
    and holds out 1, 3, 5, ..., so both see the season's whole range of weather (an autumn site's first half
    is milder than its second, and an effect that only shows in the cold, such as an undersized heating plant,
    cannot be estimated from mild fit weeks)."""
    if split == "first_half":
        return cal.default_weeks(n_weeks)
    if split == "alternate":
        return list(range(0, n_weeks, 2)), list(range(1, n_weeks, 2))
    raise ValueError(f"unknown split {split!r}; choose {' or '.join(DIAGNOSIS_SPLITS)}")


def split_weather(site, split: str = DIAGNOSIS_SPLITS[0]) -> dict:
    """The outdoor temperature (degC) the fit and the held-out weeks of ``site`` saw under ``split``
    (:func:`split_weeks`): ``{"fit": {"mean_c", "min_c"}, "heldout": {...}, "heldout_colder_than_fit_percent",
    "note"}``.

    ``heldout_colder_than_fit_percent`` is the share of held-out hours colder than every fit hour. Over
    :data:`COLDER_HELDOUT_NOTE_PERCENT`, ``note`` says so (else None): an effect that only shows in the cold (a
    heating plant short of power) cannot be estimated from the fit weeks."""
    tamb = site.weather_hours()[:, :, cat.WEATHER_NAMES.index("TAMB")]

    def colder_percent(fit: list[int], heldout: list[int]) -> float:
        return round(100.0 * float((tamb[heldout] < tamb[fit].min()).mean()), 1)

    fit_weeks, heldout_weeks = split_weeks(site.weeks, split)
    sides = {
        name: {"mean_c": round(float(tamb[weeks].mean()), 2), "min_c": round(float(tamb[weeks].min()), 2)}
        for name, weeks in (("fit", fit_weeks), ("heldout", heldout_weeks))
    }
    colder = colder_percent(fit_weeks, heldout_weeks)
    note = None
    if colder > COLDER_HELDOUT_NOTE_PERCENT:
        note = (
            f"{colder:.0f} % of the held-out hours are colder than every fit hour: an effect that only shows "
            "in the cold cannot be estimated from the fit weeks"
        )
        if split != "alternate" and colder_percent(*split_weeks(site.weeks, "alternate")) < colder:
            note += " (--split alternate fits every other week)"
    return {**sides, "heldout_colder_than_fit_percent": colder, "note": note}
