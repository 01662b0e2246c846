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

The clean-site ceilings (:attr:`Effect.clean_ceiling`, :attr:`Effect.declared_ceiling`,
:attr:`Effect.estimate_ceiling`, :attr:`Effect.sunshine_ceiling`) are the largest estimates calibrated on sites
without the effect in the blind checks; docs/gap-diagnosis.md describes how they were measured.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError

# How a gap diagnosis scores a candidate effect (buildenv.diagnosis.gap.DiagnosisSettings.judge): on both measured
# series pooled, or on the series the effect shows in (Effect.series).
JUDGES = ("pooled", "effect_series")
# How a gap diagnosis splits a site's weeks into fit and held-out weeks (buildenv.diagnosis.gap.split_weeks); the
# first is buildenv.diagnosis.gap.DiagnosisSettings' default.
DIAGNOSIS_SPLITS = ("first_half", "alternate")
# The settings the clean-site ceilings were measured under; `buildenv diagnose` defaults to them (DiagnosisSettings'
# own defaults, the first half fitted, one base calibration and three effects, are faster).
CHECKED_DIAGNOSIS = {"split": "alternate", "base_restarts": 3, "max_effects": 2}
# The smallest held-out gain a gap diagnosis names an effect without a clean-site ceiling for
# (buildenv.diagnosis.gap.DiagnosisSettings.min_gain; Effect.clean_ceiling).
MIN_GAIN = 0.10
# The lowest held-out gain at which a gap diagnosis still names an effect by its estimate alone
# (buildenv.diagnosis.gap.named_by_estimate); None: no such guard.
ESTIMATE_ALONE_LOWEST_GAIN: float | None = None
# How many times its estimate ceiling the night electricity the first step's model carries must reach for a gap
# diagnosis to name loads left on at night first, ahead of every held-out gain, unless the sensor bias candidate
# refits warm (buildenv.diagnosis.gap.night_load_named_first); None: never.
NIGHT_LOAD_FIRST_BEYOND: float | None = 1.25
# Where Effect.clean_ceiling comes from (quoted with a verdict and by `buildenv effects`).
CLEAN_CEILING_SOURCE = "estimate calibrated on 216 clean sites of the blind checks"

# Where Effect.declared_ceiling comes from.
DECLARED_CEILING_SOURCE = (
    "estimate calibrated on 44 clean sites declaring the medium office's internal loads known "
    "(occupants, workstations and both night shares)"
)

# Where the ceiling of night_plug_loads, judged on the night electricity, comes from.
NIGHT_CEILING_SOURCE = (
    "night electricity of the first step's recalibrated base model on 129 clean sites of the blind checks"
)

# Where the heating power's ceiling comes from: the clean sites above and those diagnosed again with
# Effect.carried_starts.
CAPACITY_CEILING_SOURCE = (
    "estimate calibrated on 216 clean sites of the blind checks and on 50 more diagnosed "
    "with the heating power's extra starts"
)

#: ``share x wind speed`` (m/s) at which the wind term of ``wind_infiltration`` adds nothing: about its mean over
#: the blind checks' Chicago weeks. Centred there, the calibrated air changes stay those of a typical hour.
#: The catalogue (:func:`buildenv.catalogue.catalogue_hash`) the ceilings and limits below were measured under,
#: with the metamodel trained on it.
MEASURED_UNDER = "bf68f6178dc1d1b3"


def measured_range(name: str) -> tuple[float, float, float]:
    """``(min, max, step)`` of a building parameter in the catalogue the diagnosis was measured under
    (:data:`MEASURED_UNDER`)."""
    var = cat.get(name)
    earlier = cat.EARLIER_CATALOGUES.get(MEASURED_UNDER)
    return earlier.ranges.get(name, (var.min, var.max, var.step)) if earlier else (var.min, var.max, var.step)


WIND_REFERENCE_M_S = 3.0

# Where the wind's ceiling comes from (measured with the term centred on WIND_REFERENCE_M_S).
WIND_CEILING_SOURCE = "estimate calibrated with the centred wind term on 147 clean sites of the blind checks"

# Where Effect.estimate_ceiling comes from.
ESTIMATE_CEILING_SOURCE = "estimate calibrated on 464 clean sites of the blind checks"

# Where Effect.sunshine_ceiling comes from.
SUNSHINE_CEILING_SOURCE = (
    "ratio of the estimate to the fit weeks' mean global horizontal irradiance over 1552 clean "
    "sites of the blind checks (fit-week irradiance 66.9-95.6 W/m2)"
)

# Where the sensor bias's clean reading (Effect.clean_reading) and ceilings, measured from that reading, come from.
BIAS_READING_SOURCE = "estimate calibrated on 464 clean sites of the blind checks"


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
        clean_ceiling: the largest size (as :attr:`smallest`; for a carried effect, the value furthest from where
            it vanishes, or the :attr:`judged_on` quantity) calibrated on clean sites, or None where not measured;
            a significant held-out gain names the effect only beyond it (:meth:`beyond_clean_sites`).
        judged_on: a quantity of :data:`DERIVED_SIZES` the clean-site ceiling of a carried effect is on instead
            of :attr:`building_parameter` (larger: a stronger effect), or None; night loads are judged on the
            night electricity, which stays put when a calibration trades one night share for the other.
        ceiling_source: where :attr:`clean_ceiling` comes from.
        declared_ceiling: :attr:`clean_ceiling` measured on clean sites declaring building parameters known
            (``site.toml``'s ``[known]``; :data:`DECLARED_CEILING_SOURCE`), which such a site is judged by
            (:meth:`on_declared_site`); None: judged by the gain bar there.
        estimate_ceiling: the largest size (as :attr:`clean_ceiling`) over every clean site diagnosed
            (:data:`ESTIMATE_CEILING_SOURCE`), or None; a first-step estimate beyond it names the effect alone
            when no candidate improved the held-out weeks (:func:`buildenv.diagnosis.gap.named_by_estimate`).
        carried_starts: values of :attr:`building_parameter` (its unit) from which the diagnosis also recalibrates
            a carried effect's model, keeping the best fit on the fit weeks, since a calibration can settle where
            something else absorbs the effect (:func:`buildenv.diagnosis.gap.carried_trial`).
        clean_reading: for an effect whose size takes either sign, the median estimate on clean sites (unit of
            :attr:`size_name`, from :attr:`reading_source`), from which the floor and ceilings measure the size
            (:meth:`size`); 0 for every other effect.
        reading_source: where :attr:`clean_reading` comes from ("" where it is 0).
        sunshine_ceiling: ``(per_w_m2, lowest_w_m2)`` where clean sites' estimates grow with the fit weeks' mean
            global horizontal irradiance (W/m2): the largest ratio of estimate to irradiance, and the lowest
            irradiance measured; the ceilings are then that ratio times the site's (:meth:`in_sunshine`), else None.
        irradiance_w_m2: the fit-week irradiance (W/m2) :meth:`in_sunshine` judged the ceilings at, or None.
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
    clean_ceiling: float | None = None
    judged_on: str | None = None
    ceiling_source: str = CLEAN_CEILING_SOURCE
    declared_ceiling: float | None = None
    carried_starts: tuple[float, ...] = ()
    estimate_ceiling: float | None = None
    clean_reading: float = 0.0
    reading_source: str = ""
    sunshine_ceiling: tuple[float, float] | None = None
    irradiance_w_m2: float | None = None

    @property
    def size_name(self) -> str:
        """The value :meth:`plausible` judges: the first parameter, or ``absent_days`` for an effect without
        calibrated parameters (holidays, whose size is the number of fit-week days it flags)."""
        return self.parameters[0].name if self.parameters else "absent_days"

    @property
    def ceiling_on(self) -> str:
        """The calibrated value the clean-site and estimate ceilings judge: :attr:`judged_on`, else
        :attr:`building_parameter`, else :attr:`size_name`."""
        return self.judged_on or self.building_parameter or self.size_name

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
        reading = f"; sized from the {self.clean_reading:g}{unit} clean sites calibrate" if self.clean_reading else ""
        return f"{size} >= {self.smallest:g}{unit} ({self.smallest_reason}{reading})"

    def _size_label(self) -> tuple[str, str]:
        """How :meth:`named_from` and :meth:`clean_ceiling_text` write the size: its name (``|name|`` when it can
        be negative, ``|name + 0.233|`` when sized from a :attr:`clean_reading` of -0.233) and its unit with a
        leading space ("" for a ratio)."""
        unit = self.parameters[0].unit if self.parameters else "fit-week day"
        shift = f" {'+' if self.clean_reading < 0 else '-'} {abs(self.clean_reading):g}" if self.clean_reading else ""
        size = f"|{self.size_name}{shift}|" if self.parameters and self.parameters[0].lo < 0 else self.size_name
        return size, "" if unit == "-" else f" {unit}"

    def size(self, values: dict[str, float]) -> float:
        """The size :attr:`smallest` and the ceilings judge (unit of :attr:`size_name`): ``|value - clean
        reading|`` of :attr:`size_name` in calibrated values ``{name: value}``."""
        return abs(float(values[self.size_name]) - self.clean_reading)

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

    def beyond_clean_sites(self, values: dict[str, float]) -> bool | None:
        """Whether calibrated parameter values ``{name: value}`` lie beyond :attr:`clean_ceiling`: a size larger
        than it, or for a carried effect a :attr:`building_parameter` further than it from the end of its
        range where the effect vanishes (a heating power below it), or for one with :attr:`judged_on` that
        quantity above it (a night electricity above it). None when
        the effect has no ceiling, or ``values`` are a carried effect's model-side addition (the site declared
        its building parameter known)."""
        if self.clean_ceiling is None:
            return None
        if self.judged_on is not None:
            return None if self.judged_on not in values else bool(values[self.judged_on] > self.clean_ceiling)
        if self.building_parameter is not None:
            if self.building_parameter not in values:
                return None
            return bool(self.strength(values[self.building_parameter]) > self.strength(self.clean_ceiling))
        if self.size_name not in values:
            return None
        return bool(self.size(values) > self.clean_ceiling)

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

    def beyond_estimate_ceiling(self, values: dict[str, float]) -> bool | None:
        """:meth:`beyond_clean_sites` judged against :attr:`estimate_ceiling` instead (None where the effect has
        none, or ``values`` lack the size it is on)."""
        return dataclasses.replace(self, clean_ceiling=self.estimate_ceiling).beyond_clean_sites(values)

    def in_sunshine(self, irradiance_w_m2: float | None) -> Effect:
        """This effect as a diagnosis judges it on a site whose fit weeks had a mean global horizontal irradiance of
        ``irradiance_w_m2`` (W/m2): for an effect with a :attr:`sunshine_ceiling`, clean-site and estimate
        ceilings of ``per_w_m2 x max(irradiance_w_m2, lowest_w_m2)``; itself otherwise, or when the irradiance is
        unknown (None)."""
        if self.sunshine_ceiling is None or irradiance_w_m2 is None:
            return self
        per, lowest = self.sunshine_ceiling
        ceiling = round(per * max(float(irradiance_w_m2), lowest), 4)
        source = (
            f"{SUNSHINE_CEILING_SOURCE}: at most {per:g} per W/m2, times this site's "
            f"{float(irradiance_w_m2):.1f} W/m2" + (f" (taken as {lowest:g})" if irradiance_w_m2 < lowest else "")
        )
        return dataclasses.replace(
            self,
            clean_ceiling=ceiling,
            estimate_ceiling=ceiling,
            ceiling_source=source,
            irradiance_w_m2=float(irradiance_w_m2),
        )

    def sunshine_ceiling_text(self) -> str:
        """:attr:`sunshine_ceiling` as a person reads it ("" when the effect has none)."""
        if self.sunshine_ceiling is None:
            return ""
        per, lowest = self.sunshine_ceiling
        size, unit = self._size_label()
        return (
            f"{size} > {per:g}{unit} x the fit weeks' mean global horizontal irradiance in W/m2 (taken as "
            f"{lowest:g} where lower; {per:g} is the largest {SUNSHINE_CEILING_SOURCE})"
        )

    def estimate_ceiling_text(self) -> str:
        """:attr:`estimate_ceiling` with its unit and source, as :meth:`clean_ceiling_text` writes a ceiling ("" when
        the effect has none)."""
        source = (
            self.reading_source
            if self.clean_reading
            else (self.ceiling_source if self.irradiance_w_m2 is not None else ESTIMATE_CEILING_SOURCE)
        )
        return dataclasses.replace(
            self, clean_ceiling=self.estimate_ceiling, ceiling_source=source
        ).clean_ceiling_text()

    def on_declared_site(self) -> Effect:
        """This effect as a diagnosis judges it on a site declaring building parameters known: its clean-site
        ceiling is :attr:`declared_ceiling`, from :data:`DECLARED_CEILING_SOURCE` (and, for an effect sized from
        a :attr:`clean_reading`, from :attr:`reading_source`'s median)."""
        source = DECLARED_CEILING_SOURCE + (
            f"; {self.size_name} from the median {self.reading_source}" if self.clean_reading else ""
        )
        return dataclasses.replace(self, clean_ceiling=self.declared_ceiling, ceiling_source=source)

    def carried_starts_text(self) -> str:
        """The values a diagnosis also recalibrates the carrying building parameter from, with its unit ("" when
        the effect has no :attr:`carried_starts`)."""
        if not self.carried_starts:
            return ""
        return f"{self.building_parameter} = {', '.join(f'{v:g}' for v in self.carried_starts)} {self._building_unit()}"

    def clean_ceiling_text(self) -> str:
        """The clean-site ceiling with its unit and source ("" when the effect has none)."""
        if self.clean_ceiling is None:
            return ""
        if self.judged_on is not None:
            return (
                f"{self.judged_on} > {self.clean_ceiling:g} {DERIVED_SIZES[self.judged_on][1]} (the largest "
                f"{self.ceiling_source})"
            )
        if self.building_parameter is not None:
            below = self.vanishes_at == "max"
            return (
                f"{self.building_parameter} {'<' if below else '>'} {self.clean_ceiling:g} "
                f"{self._building_unit()} (the {'lowest' if below else 'largest'} "
                f"{self.ceiling_source})"
            )
        size, unit = self._size_label()
        return f"{size} > {self.clean_ceiling:g}{unit} (the largest {self.ceiling_source})"

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
            clean_ceiling=0.0144,
            declared_ceiling=0.0427,
            ceiling_source=WIND_CEILING_SOURCE,
            estimate_ceiling=0.0175,
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
            clean_ceiling=0.281,
            ceiling_source=BIAS_READING_SOURCE,
            declared_ceiling=0.431,
            estimate_ceiling=0.281,
            clean_reading=-0.233,
            reading_source=BIAS_READING_SOURCE,
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
            clean_ceiling=0.668,
            declared_ceiling=0.5,
            estimate_ceiling=0.713,
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
            clean_ceiling=0.0,
            declared_ceiling=1.0,
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
            clean_ceiling=3.61,
            judged_on="night_electricity_w_m2",
            ceiling_source=NIGHT_CEILING_SOURCE,
            estimate_ceiling=3.61,
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
            clean_ceiling=0.574,
            declared_ceiling=0.795,
            estimate_ceiling=0.581,
            sunshine_ceiling=(0.00616, 66.9),
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
            clean_ceiling=42.5,
            declared_ceiling=40.1,
            carried_starts=(25.0, 40.0),
            ceiling_source=CAPACITY_CEILING_SOURCE,
            estimate_ceiling=38.1,
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
            clean_ceiling=0.129,
            declared_ceiling=0.322,
            estimate_ceiling=0.148,
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


def declared_ceilings() -> dict[str, float]:
    """``{effect: Effect.declared_ceiling}`` where measured: the clean-site ceilings a diagnosis judges a site
    declaring building parameters known by (``buildenv.diagnosis.gap.DiagnosisSettings.clean_ceilings`` as a mapping; an
    effect missing from it is judged by the gain bar)."""
    return {e.name: e.declared_ceiling for e in EFFECTS.values() if e.declared_ceiling is not None}


def ceilings_in_sunshine(irradiance_w_m2: float | None, kind: str = "clean") -> dict[str, float]:
    """``{effect: ceiling}`` of every effect with a clean-site ceiling (``kind="clean"``,
    :attr:`Effect.clean_ceiling`) or an estimate ceiling (``"estimate"``, :attr:`Effect.estimate_ceiling`), as a
    diagnosis judges a site whose fit weeks had a mean global horizontal irradiance of ``irradiance_w_m2`` (W/m2;
    :meth:`Effect.in_sunshine`: the catalogue's own where unknown, None)."""
    if kind not in ("clean", "estimate"):
        raise ValueError(f"unknown ceiling kind {kind!r}; choose clean or estimate")
    ceilings = {name: getattr(e.in_sunshine(irradiance_w_m2), f"{kind}_ceiling") for name, e in EFFECTS.items()}
    return {name: c for name, c in ceilings.items() if c is not None}


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
