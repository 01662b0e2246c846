"""The effects catalogue: unmodelled effects real buildings have and the metamodel lacks.

Each :class:`Effect` is defined once here and read by both sides of the gap diagnosis:

- **injection** (:mod:`buildenv.energyplus.injections`): the effect put into the reference-building stand-in,
  by editing its EnergyPlus model (``kind="energyplus"``) or by post-processing what its sensors read
  (``kind="sensor"``), at a ``magnitude`` in :attr:`Effect.magnitude_unit`; :attr:`Effect.magnitude_range` is
  the range seen in practice, which blind checks draw from;
- **model side** (:mod:`buildenv.diagnosis.model_effects`): an addition to the model whose
  :attr:`Effect.parameters` calibration estimates; each parameter's ``none`` value switches the addition off
  exactly (the model is then unchanged).

Magnitudes and plausibility floors (:attr:`Effect.smallest`) come from practice: NREL's fault models for
buildings (thermostat bias, excess infiltration, HVAC start delays), field studies of plug loads left on out of
hours, typical heat-recovery effectiveness and blinds' shading coefficients. A calibrated addition smaller than
the smallest instance seen in practice is not that effect.

An effect the model already carries through a calibrated building parameter (:attr:`Effect.building_parameter`:
the heating power for a capacity limit, the night shares for loads left on at night) is absorbed by the base
calibration, so the diagnosis tests it against the model without it (that parameter where the effect vanishes).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError

# How a gap diagnosis splits a site's weeks into fit and held-out weeks (buildenv.diagnosis.split.split_weeks); the
# first is buildenv.diagnosis.refit.DiagnosisSettings' default.
DIAGNOSIS_SPLITS = ("first_half", "alternate")
# The settings of `buildenv diagnose` and the blind checks (DiagnosisSettings' own defaults, the first half fitted
# and one base calibration, are faster).
CHECKED_DIAGNOSIS = {"split": "alternate", "base_restarts": 3, "max_effects": 3}
#: The catalogue (:func:`buildenv.catalogue.catalogue_hash`) the carried effects' limits are read in
#: (:func:`measured_range`), with the metamodel trained on it.
MEASURED_UNDER = "bf68f6178dc1d1b3"


def measured_range(name: str) -> tuple[float, float, float]:
    """``(min, max, step)`` of a building parameter in the catalogue the diagnosis was measured under
    (:data:`MEASURED_UNDER`)."""
    var = cat.get(name)
    earlier = cat.EARLIER_CATALOGUES.get(MEASURED_UNDER)
    return earlier.ranges.get(name, (var.min, var.max, var.step)) if earlier else (var.min, var.max, var.step)


#: ``share x wind speed`` (m/s) at which the wind term of ``wind_infiltration`` adds nothing: about the mean of a
#: temperate site's hours. Centred there, the calibrated air changes stay those of a typical hour.
WIND_REFERENCE_M_S = 3.0


def night_electricity_w_m2(theta: dict[str, float]) -> float:
    """Electric power the shoebox leaves on outside occupied hours, W/m2 of floor: its lighting power
    (``lighting_power_w_m2``) times the lights' night share, plus its plug loads (``plug_load_w_m2``) times
    their night share. Both night shares heat the zones and load the meter alike, so a calibration can move a
    night load from one to the other; their sum is what the data fix."""
    return (
        theta["lighting_power_w_m2"] * theta["light_night_percent"]
        + theta["plug_load_w_m2"] * theta["pc_night_percent"]
    ) / 100.0


#: Quantities derived from the calibrated building parameters that an effect carried by them can be judged on
#: (:attr:`Effect.judged_on`): name -> (function of the theta_build values, unit).
DERIVED_SIZES = {"night_electricity_w_m2": (night_electricity_w_m2, "W/m2")}


class EffectError(BuildenvError, ValueError):
    """An effect name or magnitude is unknown or out of range."""


@dataclass(frozen=True)
class ModelParameter:
    """A parameter of an effect's model-side addition, estimated by calibration.

    Attributes:
        name: parameter name (unique within the effect).
        unit: physical unit.
        lo, hi: calibration bounds.
        none: the value at which the addition changes nothing.
        description: what it means.
    """

    name: str
    unit: str
    lo: float
    hi: float
    none: float
    description: str


@dataclass(frozen=True)
class Effect:
    """An unmodelled effect (see the module docstring).

    Attributes:
        name: identifier used on the command line (``--effect NAME=MAGNITUDE``).
        title: short human title.
        description: what it is in a real building, and how it shows in the two sensors.
        kind: ``energyplus`` (model edit) or ``sensor`` (post-processing of what the sensors read).
        magnitude_unit: unit of the injected magnitude.
        magnitude_range: ``(low, high)`` magnitudes seen in practice (blind checks draw from it).
        default_magnitude: magnitude used when none is given.
        series: measured series it mainly shows in (``temperature``, ``consumption``).
        parameters: the model-side addition's parameters.
        model: one line on the model-side addition.
        smallest: the smallest size real buildings show, as ``|first parameter|`` (holidays: fit-week days
            flagged, :attr:`size_name`), or None when any estimate is plausible; a smaller estimate is not named,
            as it absorbs some other shortcoming of the model.
        smallest_reason: where ``smallest`` comes from, in a few words (shown with the verdict and by
            ``buildenv effects``).
        building_parameter: the theta_build variable through which the metamodel already carries the effect, or
            None; the diagnosis then tests whether the building needs it away from where the effect vanishes,
            unless the site declares it known (:mod:`buildenv.diagnosis.gap`).
        vanishes_at: the end of :attr:`building_parameter`'s range where the effect vanishes: ``max`` (an
            unlimited heating power) or ``min`` (no lighting left on at night).
        carried_starts: values of :attr:`building_parameter` (its unit) from which the diagnosis also recalibrates
            a carried effect's model, keeping the best fit on the fit weeks, since a calibration can settle where
            something else absorbs the effect (:func:`buildenv.diagnosis.refit.carried_trial`).
        judged_on: a quantity of :data:`DERIVED_SIZES` a carried effect is reported by, besides its building
            parameter (night loads: the night electricity both night shares add up to), or None.
        shows_in: the hours the effect needs in the fit and held-out weeks to show at all (a key of
            :data:`buildenv.diagnosis.data_needs.NEEDS`), or None when every week can show it.
        found_by_day: the effect is a matter of dates, found day by day from the data rather than calibrated
            (holidays: the days found absent, with no parameters); it can be judged only where its fit weeks hold
            such a day.
    """

    name: str
    title: str
    description: str
    kind: str
    magnitude_unit: str
    magnitude_range: tuple[float, float]
    default_magnitude: float
    series: tuple[str, ...]
    parameters: tuple[ModelParameter, ...]
    model: str
    smallest: float | None = None
    smallest_reason: str = ""
    building_parameter: str | None = None
    vanishes_at: str = "max"
    carried_starts: tuple[float, ...] = ()
    judged_on: str | None = None
    shows_in: str | None = None
    found_by_day: bool = False

    @property
    def size_name(self) -> str:
        """The value :meth:`plausible` judges: the first parameter, or ``absent_days`` for an effect without
        calibrated parameters (holidays, whose size is the number of fit-week days it flags)."""
        return self.parameters[0].name if self.parameters else "absent_days"

    def carried_limit(self) -> float | None:
        """The calibrated value of :attr:`building_parameter` from which a carried effect is named: one catalogue
        step inside the end of its range where the effect vanishes (:attr:`vanishes_at`; None for an effect not
        carried). Closer to that end, the calibrated model and the model it is judged against are the same
        building at the catalogue's resolution, and a held-out gain between them is the refits' own spread."""
        if self.building_parameter is None:
            return None
        lo, hi, step = measured_range(self.building_parameter)
        return hi - step if self.vanishes_at == "max" else lo + step

    def strength(self, value: float) -> float:
        """A value of :attr:`building_parameter` oriented so that larger means a stronger effect: negated where
        the effect vanishes at the top of the range (a lower heating power is a tighter limit)."""
        return -value if self.vanishes_at == "max" else value

    def _building_unit(self) -> str:
        """The catalogue's unit of :attr:`building_parameter`."""
        return cat.get(self.building_parameter).unit

    def vanishing_value(self) -> float | None:
        """The value of :attr:`building_parameter` at which the effect vanishes (None for an effect not carried)."""
        if self.building_parameter is None:
            return None
        lo, hi, _ = measured_range(self.building_parameter)
        return hi if self.vanishes_at == "max" else lo

    def named_from(self) -> str:
        """The smallest estimate a diagnosis names, with its unit and where it comes from ("" when any is)."""
        limit = self.carried_limit()
        if limit is not None:
            side, end = ("<=", "below the top") if self.vanishes_at == "max" else (">=", "above the bottom")
            return (
                f"{self.building_parameter} {side} {limit:g} {self._building_unit()} (one "
                f"catalogue step {end} of its range, where the effect vanishes)"
            )
        if self.smallest is None:
            return ""
        size, unit = self._size_label()
        return f"{size} >= {self.smallest:g}{unit} ({self.smallest_reason})"

    def _size_label(self) -> tuple[str, str]:
        """How :meth:`named_from` writes the size: its name (``|name|`` when it can be negative) and its unit with a
        leading space ("" for a ratio)."""
        unit = self.parameters[0].unit if self.parameters else "fit-week day"
        size = f"|{self.size_name}|" if self.parameters and self.parameters[0].lo < 0 else self.size_name
        return size, "" if unit == "-" else f" {unit}"

    def size(self, values: dict[str, float]) -> float:
        """The size :attr:`smallest` judges (unit of :attr:`size_name`): ``|value|`` of :attr:`size_name` in
        calibrated values ``{name: value}``."""
        return abs(float(values[self.size_name]))

    def plausible(self, values: dict[str, float]) -> bool:
        """Whether calibrated parameter values ``{name: value}`` describe an effect of a size seen in practice
        (a carried effect's building parameter: at least a step away from where it vanishes,
        :meth:`carried_limit`)."""
        limit = self.carried_limit()
        if limit is not None and self.building_parameter in values:
            value = values[self.building_parameter]
            return self.strength(value) >= self.strength(limit)
        if self.smallest is None:
            return True
        return self.size(values) >= self.smallest

    def estimate_text(self, values: dict[str, float]) -> str:
        """Calibrated values ``{name: value}`` (its parameters, or a carried effect's building parameter) as a
        person reads them, with units: e.g. "light_night_percent 2.22 %"."""
        units = {p.name: p.unit for p in self.parameters}
        if self.building_parameter is not None:
            units[self.building_parameter] = self._building_unit()
        if self.judged_on is not None:
            units[self.judged_on] = DERIVED_SIZES[self.judged_on][1]
        return ", ".join(
            f"{k} {v:.3g}" + ("" if units.get(k, "-") == "-" else f" {units[k]}") for k, v in values.items()
        )

    def carried_starts_text(self) -> str:
        """The values a diagnosis also recalibrates the carrying building parameter from, with its unit ("" when
        the effect has no :attr:`carried_starts`)."""
        if not self.carried_starts:
            return ""
        return f"{self.building_parameter} = {', '.join(f'{v:g}' for v in self.carried_starts)} {self._building_unit()}"

    def check_magnitude(self, magnitude: float) -> float:
        """The magnitude as a float; raises :class:`EffectError` if it lies outside what the injection can do."""
        lo, hi = INJECTION_LIMITS[self.name]
        if not lo <= magnitude <= hi:
            raise EffectError(
                f"effect {self.name}: magnitude {magnitude:g} {self.magnitude_unit} is outside "
                f"[{lo:g}, {hi:g}] (practice: {self.magnitude_range[0]:g}-{self.magnitude_range[1]:g})"
            )
        return float(magnitude)


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "wind_infiltration",
            "wind-driven infiltration",
            "Leaky envelope: air infiltration grows with wind speed (cracks, open doors, badly sealed windows). "
            "Windy hours need more heat and cool the zones faster when the heating is off.",
            "energyplus",
            "% of the design infiltration added per m/s of wind",
            (10.0, 40.0),
            25.0,
            ("consumption", "temperature"),
            (
                ModelParameter(
                    "ach_per_m_s",
                    "1/h per m/s",
                    0.0,
                    0.15,
                    0.0,
                    "infiltration air changes added per m/s of wind speed (out of hours)",
                ),
            ),
            "the infiltration input becomes hourly: calibrated air changes + ach_per_m_s x (wind speed - "
            f"{WIND_REFERENCE_M_S:g} m/s), the wind speed at a quarter while the air handling unit runs (at least 0 "
            "air changes)",
            0.01,
            smallest_reason="10 % of a tight office's 0.1 air changes per hour",
        ),
        Effect(
            "temperature_sensor_bias",
            "temperature sensor bias",
            "The indoor temperature sensor reads high or low by a constant offset (calibration drift, a sensor "
            "near a radiator or in the sun). The consumption is unaffected.",
            "sensor",
            "K (reading - truth)",
            (-3.0, 3.0),
            1.0,
            ("temperature",),
            (ModelParameter("bias_k", "K", -3.0, 3.0, 0.0, "offset added to the predicted temperature"),),
            "the predicted temperature reads bias_k higher",
            0.4,
            smallest_reason="a class-B Pt1000's tolerance near 20 degC",
        ),
        Effect(
            "temperature_sensor_lag",
            "temperature sensor lag",
            "The sensor responds slowly (a heavy housing, a sensor in a wall pocket): it reads a first-order "
            "lagged air temperature, so morning start-ups and evening setbacks look slower than they are.",
            "sensor",
            "h (time constant)",
            (0.5, 3.0),
            1.5,
            ("temperature",),
            (ModelParameter("tau_h", "h", 0.0, 4.0, 0.0, "first-order time constant of the sensor"),),
            "the predicted temperature is passed through a first-order lag of time constant tau_h",
            0.25,
            smallest_reason="below a quarter of the hourly sampling a lag cannot be told from noise",
        ),
        Effect(
            "holidays",
            "holidays and absent-occupancy days",
            "Weekdays nobody comes in (public holidays, bridge days, closures) while the BMS keeps its weekday "
            "schedule: no lights, plug loads or people, so less consumption and a colder building that day.",
            "energyplus",
            "absent weekdays in the measured period",
            (1.0, 3.0),
            2.0,
            ("consumption", "temperature"),
            (),
            "absent days: for each weekday the share of its occupants who did not come is fitted to its measured "
            "temperature and consumption; days where it is at least half and the day's standardised squared "
            "error falls by more than 15 % are simulated with that much less occupancy; they are estimated from "
            "the data like the occupancy hours",
            1.0,
            smallest_reason="a candidate that flags no fit-week day has estimated nothing from the fit weeks",
            found_by_day=True,
        ),
        Effect(
            "night_plug_loads",
            "plug loads left on at night",
            "Equipment left on outside occupied hours beyond what the model's night share allows (servers, "
            "printers, screens on standby): a higher night and weekend base load.",
            "energyplus",
            "W/m2 added outside occupied hours",
            (1.0, 5.0),
            3.0,
            ("consumption",),
            (ModelParameter("night_w_m2", "W/m2", 0.0, 8.0, 0.0, "electric load added in every unoccupied hour"),),
            "the metamodel's night share of the lighting (building parameter light_night_percent) is calibrated, "
            "and the diagnosis tests it against no lighting at night and sizes it by the night electricity both "
            "night shares add up to (night_electricity_w_m2); with light_night_percent declared known, "
            "the predicted consumption gains night_w_m2 in every hour the calibrated occupancy marks unoccupied",
            0.5,
            smallest_reason="one standby monitor per 10 m2",
            building_parameter="light_night_percent",
            vanishes_at="min",
            judged_on="night_electricity_w_m2",
        ),
        Effect(
            "solar_shading",
            "solar shading / blinds",
            "Blinds drawn or outside obstructions: a share of the solar gains never reaches the zones, so sunny "
            "hours are colder and need more heat than the model says.",
            "energyplus",
            "% of the solar gains blocked",
            (30.0, 70.0),
            50.0,
            ("temperature", "consumption"),
            (ModelParameter("blocked_fraction", "-", 0.0, 0.9, 0.0, "share of the irradiance inputs removed"),),
            "every irradiance input of the metamodel is scaled by (1 - blocked_fraction)",
            0.15,
            smallest_reason="half the lightest blinds' 30 %",
        ),
        Effect(
            "heating_capacity_limit",
            "heating capacity limit",
            "Undersized or degraded heating plant: on cold mornings the heating runs flat out and cannot hold "
            "the setpoint, so consumption plateaus and the temperature sags.",
            "energyplus",
            "% of the design heating capacity available",
            (25.0, 50.0),
            40.0,
            ("consumption", "temperature"),
            (
                ModelParameter(
                    "capacity_w_m2",
                    "W/m2",
                    5.0,
                    150.0,
                    150.0,
                    "largest heating power (zone + air handling unit) the plant delivers",
                ),
                ModelParameter(
                    "sag_k_per_wh_m2",
                    "K per Wh/m2",
                    0.0,
                    0.2,
                    0.0,
                    "temperature lost per Wh/m2 of heat not delivered (decaying over ~3 h)",
                ),
            ),
            "the metamodel's heating power (building parameter heating_power_w_m2) is calibrated, and the "
            "diagnosis tests it against an unlimited heating power; with the heating power declared known, the "
            "predicted heating is capped at capacity_w_m2 and the heat not delivered lowers the temperature",
            building_parameter="heating_power_w_m2",
            carried_starts=(25.0, 40.0),
            shows_in="heating_peaks",
        ),
        Effect(
            "heat_recovery",
            "heat recovery on the air handling unit",
            "An air-to-air heat exchanger preheats the outdoor air with the exhaust air: the air handling unit's "
            "heating falls, most in cold weather.",
            "energyplus",
            "% sensible effectiveness",
            (50.0, 80.0),
            70.0,
            ("consumption",),
            (ModelParameter("effectiveness", "-", 0.0, 0.9, 0.0, "sensible effectiveness of the heat exchanger"),),
            "the air handling unit's heating is reduced by the heat an exchanger of that effectiveness recovers",
            0.3,
            smallest_reason="the poorest exchangers sold reach about 0.5",
            shows_in="ventilated_heating",
        ),
        Effect(
            "night_cycle_cold_air",
            "cold supply air while the fans cycle at night",
            "A VAV system with terminal reheat supplies air at its cooling temperature (about 13 degC) whenever "
            "its fans run, so its night cycle cools the zones that need no heat and makes the others reheat: cold "
            "nights are colder and cost more heat, and ventilation after the heating period brings in cold air.",
            "energyplus",
            "points of maximum air flow added to the VAV boxes' minimum out of hours",
            (10.0, 30.0),
            20.0,
            ("temperature", "consumption"),
            (
                ModelParameter(
                    "cooling_k_per_wh_m2",
                    "K per Wh/m2",
                    0.0,
                    0.5,
                    0.0,
                    "temperature lost per Wh/m2 of the model's heating in hours its ventilation is off, "
                    "and per Wh/m2 the supply air brings less after the heating period",
                ),
                ModelParameter(
                    "reheat_share",
                    "-",
                    0.0,
                    1.0,
                    0.0,
                    "heat consumption added, as a share of the model's heating in those hours",
                ),
                ModelParameter(
                    "supply_shortfall_k",
                    "K",
                    0.0,
                    20.0,
                    0.0,
                    "how much colder than supply_air_c the air comes in when the ventilation runs outside "
                    "the heating period, times the supply flow over the model's fresh-air flow",
                ),
            ),
            "in the hours the ventilation is off, the predicted temperature falls by cooling_k_per_wh_m2 x the "
            "predicted heating and the consumption rises by reheat_share x the same heating; in the hours it runs "
            "outside the heating period, the supply air brings D = supply_shortfall_k x the air handling unit's "
            "heating per K of lift less heat: the temperature falls by the same coefficient x D and the air "
            "handling unit's heating by D (at most all of it)",
            0.02,
            smallest_reason="0.1 K on a night heated at 5 Wh/m2 (the sensor's resolution)",
            shows_in="heating_fans_off",
        ),
        Effect(
            "evening_departure",
            "occupants leaving gradually in the evening",
            "Offices do not empty at one hour: part of the occupants stay on after the main working day, with "
            "their lights and computers, so evenings are warmer and use more electricity than a model whose "
            "occupancy ends at one hour.",
            "energyplus",
            "hours the evening tail of the occupants' schedules is lengthened",
            (1.0, 3.0),
            2.0,
            ("temperature", "consumption"),
            (
                ModelParameter(
                    "share",
                    "-",
                    0.0,
                    1.0,
                    0.0,
                    "occupancy kept after the calibrated occupancy ends (share of the occupied level)",
                ),
                ModelParameter("hours", "h", 0.0, 6.0, 0.0, "how long it is kept"),
            ),
            "the metamodel's hourly occupancy input is raised to share for the hours after each day's occupancy "
            "ends (the last one pro rata)",
            0.1,
            smallest_reason="a tenth of the occupancy (the DOE offices keep 10-40 % for four hours)",
        ),
    )
}

#: Magnitudes the injections accept (wider than practice, for stress tests).
INJECTION_LIMITS: dict[str, tuple[float, float]] = {
    "wind_infiltration": (0.0, 200.0),
    "temperature_sensor_bias": (-5.0, 5.0),
    "temperature_sensor_lag": (0.0, 6.0),
    "holidays": (0.0, 10.0),
    "night_plug_loads": (0.0, 20.0),
    "solar_shading": (0.0, 95.0),
    "heating_capacity_limit": (10.0, 100.0),
    "heat_recovery": (0.0, 90.0),
    "night_cycle_cold_air": (0.0, 70.0),
    "evening_departure": (0.0, 6.0),
}

#: The magnitude at which each injection changes nothing.
NO_EFFECT_MAGNITUDE: dict[str, float] = {name: (100.0 if name == "heating_capacity_limit" else 0.0) for name in EFFECTS}


def get_effect(name: str) -> Effect:
    """The effect called ``name``; raises :class:`EffectError` naming the closest ones otherwise."""
    if name in EFFECTS:
        return EFFECTS[name]
    close = difflib.get_close_matches(name, list(EFFECTS), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise EffectError(f"unknown effect {name!r}{hint} (known: {', '.join(EFFECTS)})")


def check_declarable(names) -> tuple[str, ...]:
    """Effects a building may be declared to have (``site.toml``'s ``effects``, ``buildenv calibrate --effect``),
    as a tuple of catalogue names; raises :class:`EffectError` (one line) for a name that is not in the
    catalogue, one given twice, or ``holidays`` (its absent days are dates of the measured period, which the gap
    diagnosis detects from the data: ``buildenv diagnose``)."""
    out = tuple(names)
    for name in out:
        get_effect(name)
        if name == "holidays":
            raise EffectError(
                f"effect {name!r} cannot be declared (its days are found from the data: run `buildenv diagnose`)"
            )
    twice = sorted({name for name in out if out.count(name) > 1})
    if twice:
        raise EffectError(f"effect {', '.join(twice)} declared twice")
    return out


def parse_effect(text: str) -> tuple[Effect, float]:
    """``NAME`` or ``NAME=MAGNITUDE`` (command-line form) -> (effect, magnitude)."""
    name, sep, value = text.partition("=")
    effect = get_effect(name.strip())
    if not sep:
        return effect, effect.default_magnitude
    try:
        magnitude = float(value)
    except ValueError:
        raise EffectError(f"--effect {text}: magnitude {value!r} is not a number ({effect.magnitude_unit})") from None
    return effect, effect.check_magnitude(magnitude)
