"""The variable catalogue: every input and output of the building model, defined once.

The single source of truth for names, units, ranges, steps and granularity: sampling
(:mod:`buildenv.campaign.sampling`), the hourly schedules (:mod:`buildenv.schedules`), the EnergyPlus model
(:mod:`buildenv.energyplus.shoebox`), the action space and the calibration bounds all read their ranges here.

Groups, after the appendix of Cohen et al. ("End-to-end deep metamodeling to calibrate and optimize energy loads"):

``theta_build`` (static, one value per building)
    25 variables: the paper's 17 building parameters with its PC count replaced by plug-load power, plus
    floor area, number of floors, lighting power, heat recovery, the minimum supply air flow, the economiser,
    the share of infiltration left while the fans pressurise the building and the night cycle's heating share;
    extensive quantities are per m2 of floor area, so one model covers offices of any size. Ranges are taken
    from practice (the ASHRAE 90.1 2004-2019 reference offices) and are wide enough for the six shipped
    reference offices.
``settings`` (I_k, per day of the week: 13 settings x 7 days = 91 values a week)
    Heating, cooling and ventilation schedules and setpoints of the building management system (BMS).
``occupancy`` (O_k, per weekday Monday-Friday: 2 x 5 = 10 values a week)
    Arrival and departure hours; weekends are unoccupied.
``weather`` (W_k, per hour)
    The paper's seven series plus wind speed and direction (needed for sim-to-real diagnosis).
``outputs`` (per hour)
    The paper's 8 outputs; energies in Wh per m2 of floor area in the hour (x floor area / 1000 for kWh).

A variable with a ``step`` is sampled on the grid ``min, min + step, ...`` up to ``max`` (the paper's uniform
sampling): ``ventilation_ach`` (0.1-1.7 step 0.05) takes 0.1, 0.15, ..., 1.7, the paper's 0.7-1.6 (step 0.3)
among them, and any outdoor air a BMS sets between an office's ASHRAE 62.1 minimum and its design.

Data and checkpoints made with a catalogue this one replaced are read through :data:`EARLIER_CATALOGUES`
(its ranges, renamed variables and the values it implies for variables it lacked).
"""

from __future__ import annotations

import difflib
import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from enum import Enum

import numpy as np

from buildenv.errors import CatalogueError

DAYS: tuple[str, ...] = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")
WEEKDAYS: tuple[str, ...] = DAYS[:5]
HOURS_PER_DAY = 24
HOURS_PER_WEEK = 168
WEEKS_PER_YEAR = 52  # whole weeks of a 365-day weather year (January 1st is a Monday)


class Granularity(str, Enum):
    """How often a variable takes a new value."""

    STATIC = "static"  # one value per building
    PER_DAY = "per_day"  # one value for each of the 7 days of the week
    PER_WEEKDAY = "per_weekday"  # one value for each working day, Monday-Friday
    PER_HOUR = "per_hour"  # an hourly series


@dataclass(frozen=True)
class Variable:
    """One catalogue entry.

    Attributes:
        name: canonical name used everywhere in buildenv.
        group: ``theta_build``, ``settings``, ``occupancy``, ``weather`` or ``outputs``.
        unit: physical unit ("m2", "W/m2", "degC", "h", "1/h", "%", ...).
        min: smallest admissible value (also the sampling and calibration lower bound).
        max: largest admissible value.
        step: sampling grid step, or ``None`` for continuous / measured quantities.
        granularity: see :class:`Granularity`.
        description: what it means for a building engineer.
        paper_name: the name in the paper's appendix (accepted as an alias).
    """

    name: str
    group: str
    unit: str
    min: float
    max: float
    step: float | None
    granularity: Granularity
    description: str
    paper_name: str

    def grid(self) -> np.ndarray:
        """All values the variable takes when sampled: ``min, min+step, ..., <= max`` (shape ``(n,)``)."""
        if self.step is None:
            raise CatalogueError(f"variable {self.name!r} is continuous and has no sampling grid")
        n = int(np.floor((self.max - self.min) / self.step + 1e-9)) + 1
        return np.round(self.min + self.step * np.arange(n), 10)

    def snap(self, value: np.ndarray | float) -> np.ndarray:
        """Round values to the nearest grid point (clipped into ``[min, max]``)."""
        value = np.clip(np.asarray(value, dtype=float), self.min, self.max)
        if self.step is None:
            return value
        grid = self.grid()
        index = np.clip(np.rint((value - self.min) / self.step), 0, len(grid) - 1).astype(int)
        return grid[index]

    @property
    def is_switch(self) -> bool:
        """Whether the variable is on (its maximum) or off (its minimum) and nothing between: one step spans its
        range."""
        return self.step is not None and self.max > self.min and abs(self.max - self.min - self.step) < 1e-9

    def between_ends(self, value: np.ndarray | float) -> np.ndarray:
        """Boolean mask, the shape of ``value``: True where a switch (:attr:`is_switch`) is neither on nor off
        (NaN included); all False for other variables."""
        arr = np.asarray(value, dtype=float)
        return ~np.isin(arr, (self.min, self.max)) if self.is_switch else np.zeros(arr.shape, bool)

    def check_switch(self, value: np.ndarray | float, where: str = "") -> None:
        """Raise :class:`CatalogueError` if a switch (:attr:`is_switch`) holds a value other than its minimum or
        maximum; other variables pass."""
        arr = np.asarray(value, dtype=float)
        bad = self.between_ends(arr)
        if bad.any():
            first = arr.flat[int(np.flatnonzero(bad.ravel())[0])]
            loc = f" in {where}" if where else ""
            raise CatalogueError(
                f"{self.name}={first:g}{loc}: write {self.max:g} (on) or {self.min:g} (off), nothing between"
            )

    def check(self, value: np.ndarray | float, where: str = "") -> None:
        """Raise :class:`CatalogueError` if any value is NaN or outside ``[min, max]``."""
        arr = np.asarray(value, dtype=float)
        bad = ~np.isfinite(arr) | (arr < self.min - 1e-9) | (arr > self.max + 1e-9)
        if bad.any():
            first = arr.flat[int(np.flatnonzero(bad.ravel())[0])]
            loc = f" in {where}" if where else ""
            raise CatalogueError(
                f"{self.name}={first:g}{loc} is outside its range [{self.min:g}, {self.max:g}] {self.unit}"
            )


def _v(name, group, unit, lo, hi, step, gran, desc, paper) -> Variable:
    return Variable(
        name, group, unit, float(lo), float(hi), None if step is None else float(step), Granularity(gran), desc, paper
    )


S, D, W, H = "static", "per_day", "per_weekday", "per_hour"

THETA_BUILD: tuple[Variable, ...] = (
    _v(
        "floor_area_m2",
        "theta_build",
        "m2",
        300,
        50000,
        100,
        S,
        "Conditioned floor area of the whole building (all floors).",
        "(geometry)",
    ),
    _v(
        "number_of_floors",
        "theta_build",
        "-",
        1,
        15,
        1,
        S,
        "Number of storeys; with the floor area it fixes footprint, facade and roof areas.",
        "(geometry)",
    ),
    _v(
        "infiltration_ach",
        "theta_build",
        "1/h",
        0.05,
        1.0,
        0.05,
        S,
        "Infiltration air changes per hour of the zone volume while the air handling unit's fans are off "
        "(wind-independent).",
        "airchange_infiltration_vol_per_h",
    ),
    _v(
        "infiltration_fans_on_share",
        "theta_build",
        "-",
        0,
        1,
        0.25,
        S,
        "Share of that infiltration left while the air handling unit ventilates, its supply exceeding its exhaust "
        "and pressurising the building: 1 unpressurised (infiltration the same day and night), 0.25 the DOE and "
        "ASHRAE 90.1 reference offices' convention.",
        "(infiltration with fans on)",
    ),
    _v(
        "heat_recovery_effectiveness",
        "theta_build",
        "-",
        0,
        0.8,
        0.1,
        S,
        "Sensible effectiveness of the air handling unit's heat recovery between exhaust and outdoor air "
        "(0: none; plate exchangers 0.5-0.7, wheels 0.7-0.8).",
        "(heat recovery)",
    ),
    _v(
        "minimum_supply_air_ach",
        "theta_build",
        "1/h",
        0,
        4,
        0.25,
        S,
        "Smallest air flow the air handling unit supplies while it runs, in air changes per hour of the zone "
        "volume: the minimum of VAV boxes, supplied at the supply temperature and reheated by the zones; above "
        "the outdoor air it is return air (0: a 100 % outdoor air unit; DOE reference VAV offices about 1.5-2).",
        "(VAV minimum flow)",
    ),
    _v(
        "night_cycle_heating_share",
        "theta_build",
        "-",
        0,
        1,
        0.25,
        S,
        "Share of the minimum supply flow the air handling unit night-cycles at the supply temperature while the "
        "coldest zone sits at its heating setback (the zones reheat it): 1 VAV systems with terminal reheat that "
        "cycle on any zone (the DOE 2004 medium and large offices), 0 units that heat their own supply air or hold "
        "the setback zone by zone (packaged single-zone units).",
        "(night cycle in heating)",
    ),
    _v(
        "economiser_share",
        "theta_build",
        "-",
        0,
        1,
        0.25,
        S,
        "Share of the zones' cooling the fan coils can meet with outdoor air while it is cooler than the zone air "
        "(an air-side economiser, differential dry-bulb): 0 none (mechanical cooling only), 1 all (VAV and packaged "
        "units with economisers, as ASHRAE 90.1 requires in most climates).",
        "(air-side economiser)",
    ),
    _v(
        "capacitance_kj_per_k_m3",
        "theta_build",
        "kJ/(K m3)",
        20,
        300,
        10,
        S,
        "Effective internal heat capacity per m3 of zone volume (furniture, partitions, slabs).",
        "capacitance_kJ_perdegreK_perm3",
    ),
    _v(
        "heating_power_w_m2",
        "theta_build",
        "W/m2",
        5,
        150,
        5,
        S,
        "Installed zone (fan-coil) heating power per m2 of floor area.",
        "power_VCV_kW_heat",
    ),
    _v(
        "cooling_power_w_m2",
        "theta_build",
        "W/m2",
        5,
        150,
        5,
        S,
        "Installed zone (fan-coil) cooling power per m2 of floor area.",
        "power_VCV_kW_clim",
    ),
    _v(
        "occupant_density_per_m2",
        "theta_build",
        "1/m2",
        0.02,
        0.1,
        0.005,
        S,
        "Occupants per m2 of floor area at full occupancy.",
        "nb_occupants",
    ),
    _v(
        "plug_load_w_m2",
        "theta_build",
        "W/m2",
        2,
        20,
        1,
        S,
        "Plug-load (equipment) power per m2 of floor area at full occupancy: workstations, screens, printers, "
        "kitchenettes (ASHRAE 90.1 reference offices: 8.1 in 2019, 10.8 in 2004).",
        "(nb_PCs x PC power)",
    ),
    _v(
        "lighting_power_w_m2",
        "theta_build",
        "W/m2",
        4,
        16,
        1,
        S,
        "Installed lighting power per m2 of floor area (ASHRAE 90.1 office: 6.9 in 2019, 10.8 in 2004, about 16 "
        "in buildings of the 1980s).",
        "(lighting power density)",
    ),
    _v(
        "light_night_percent",
        "theta_build",
        "%",
        0,
        70,
        10,
        S,
        "Lighting left on outside occupied hours, as a percentage of the occupied level.",
        "percent_light_night",
    ),
    _v(
        "pc_night_percent",
        "theta_build",
        "%",
        0,
        70,
        10,
        S,
        "Equipment left on outside occupied hours, as a percentage of the occupied level.",
        "percent_PCs_night",
    ),
    _v(
        "wall_insulation_north_m",
        "theta_build",
        "m",
        0.02,
        0.3,
        0.02,
        S,
        "Insulation thickness of the north facade (layer 2 of concrete/insulation/plasterboard).",
        "facade_1_thickness_2",
    ),
    _v(
        "wall_insulation_east_m",
        "theta_build",
        "m",
        0.02,
        0.3,
        0.02,
        S,
        "Insulation thickness of the east facade.",
        "facade_2_thickness_2",
    ),
    _v(
        "wall_insulation_south_m",
        "theta_build",
        "m",
        0.02,
        0.3,
        0.02,
        S,
        "Insulation thickness of the south facade.",
        "facade_3_thickness_2",
    ),
    _v(
        "wall_insulation_west_m",
        "theta_build",
        "m",
        0.02,
        0.3,
        0.02,
        S,
        "Insulation thickness of the west facade.",
        "facade_4_thickness_2",
    ),
    _v(
        "roof_insulation_m",
        "theta_build",
        "m",
        0.02,
        0.3,
        0.02,
        S,
        "Insulation thickness of the roof.",
        "roof_1_thickness_3",
    ),
    _v(
        "window_to_wall_north_percent",
        "theta_build",
        "%",
        10,
        70,
        5,
        S,
        "Glazed share of the north facade.",
        "facade_1_window_area_percent",
    ),
    _v(
        "window_to_wall_east_percent",
        "theta_build",
        "%",
        10,
        70,
        5,
        S,
        "Glazed share of the east facade.",
        "facade_2_window_area_percent",
    ),
    _v(
        "window_to_wall_south_percent",
        "theta_build",
        "%",
        10,
        70,
        5,
        S,
        "Glazed share of the south facade.",
        "facade_3_window_area_percent",
    ),
    _v(
        "window_to_wall_west_percent",
        "theta_build",
        "%",
        10,
        70,
        5,
        S,
        "Glazed share of the west facade.",
        "facade_4_window_area_percent",
    ),
)

SETTINGS: tuple[Variable, ...] = (
    _v(
        "cooling_start_hour",
        "settings",
        "h",
        7,
        9,
        1,
        D,
        "Hour the cooling comfort setpoint comes into force.",
        "start_clim_day",
    ),
    _v(
        "cooling_end_hour",
        "settings",
        "h",
        18,
        20,
        1,
        D,
        "Hour the cooling setpoint returns to setback.",
        "end_clim_day",
    ),
    _v(
        "cooling_setback_c",
        "settings",
        "degC",
        24,
        30,
        0.5,
        D,
        "Cooling setpoint outside the cooling period.",
        "t_clim_red_day",
    ),
    _v(
        "cooling_comfort_c",
        "settings",
        "degC",
        20,
        24,
        0.5,
        D,
        "Cooling setpoint during the cooling period.",
        "t_clim_conf_day",
    ),
    _v(
        "heating_start_hour",
        "settings",
        "h",
        6,
        8,
        1,
        D,
        "Hour the heating comfort setpoint comes into force.",
        "start_heat_day",
    ),
    _v(
        "heating_end_hour",
        "settings",
        "h",
        17,
        19,
        1,
        D,
        "Hour the heating setpoint returns to setback.",
        "end_heat_day",
    ),
    _v(
        "heating_setback_c",
        "settings",
        "degC",
        17,
        22,
        0.5,
        D,
        "Heating setpoint outside the heating period.",
        "t_heat_red_day",
    ),
    _v(
        "heating_comfort_c",
        "settings",
        "degC",
        22,
        24,
        0.5,
        D,
        "Heating setpoint during the heating period.",
        "t_heat_conf_day",
    ),
    _v(
        "ventilation_start_hour",
        "settings",
        "h",
        7,
        9,
        1,
        D,
        "Hour the air handling unit starts supplying outdoor air.",
        "start_ventilation_day",
    ),
    _v(
        "ventilation_end_hour",
        "settings",
        "h",
        18,
        20,
        1,
        D,
        "Hour the air handling unit stops.",
        "end_ventilation_day",
    ),
    _v(
        "supply_air_c",
        "settings",
        "degC",
        12,
        26,
        0.5,
        D,
        "Air handling unit supply air temperature (outdoor air heated or cooled to it); VAV systems with terminal "
        "reheat supply about 13 degC all year.",
        "t_ventilation_day",
    ),
    _v(
        "ventilation_ach",
        "settings",
        "1/h",
        0.1,
        1.7,
        0.05,
        D,
        "Outdoor air supplied by the air handling unit, in air changes per hour of the zone volume (its minimum "
        "outdoor air damper or flow set point, which a BMS sets between the ASHRAE 62.1 minimum and the design).",
        "vol_ventilation_day",
    ),
    _v(
        "hvac_operating",
        "settings",
        "-",
        0,
        1,
        1,
        D,
        "1: the day's heating, cooling and ventilation periods run as set; 0: the whole day is held at the setbacks "
        "with the air handling unit off (a weekend or holiday shutdown).",
        "(day in occupied mode)",
    ),
)

OCCUPANCY: tuple[Variable, ...] = (
    _v(
        "occupancy_start_hour",
        "occupancy",
        "h",
        7,
        9,
        1,
        W,
        "Hour occupants arrive (Monday-Friday; weekends are unoccupied).",
        "start_occupation",
    ),
    _v("occupancy_end_hour", "occupancy", "h", 17, 20, 1, W, "Hour occupants leave.", "end_occupation"),
)

WEATHER: tuple[Variable, ...] = (
    _v("DNI", "weather", "W/m2", 0, 1400, None, H, "Direct normal irradiance.", "DNI"),
    _v(
        "IBEAM_H",
        "weather",
        "W/m2",
        0,
        1400,
        None,
        H,
        "Beam (direct) irradiance on a horizontal surface, DNI x cos(zenith).",
        "IBEAM_H",
    ),
    _v(
        "IBEAM_N",
        "weather",
        "W/m2",
        0,
        1400,
        None,
        H,
        "Beam irradiance on a vertical north-facing facade. The paper describes IBEAM_N with the same words "
        "as DNI; a copy of DNI would carry no information, so we read N as the north facade.",
        "IBEAM_N",
    ),
    _v("IDIFF_H", "weather", "W/m2", 0, 1000, None, H, "Diffuse horizontal irradiance.", "IDIFF_H"),
    _v("IGLOB_H", "weather", "W/m2", 0, 1500, None, H, "Global horizontal irradiance.", "IGLOB_H"),
    _v("RHUM", "weather", "%", 0, 100, None, H, "Outdoor relative humidity.", "RHUM"),
    _v("TAMB", "weather", "degC", -60, 60, None, H, "Outdoor dry-bulb temperature.", "TAMB"),
    _v("WIND_SPEED", "weather", "m/s", 0, 60, None, H, "Wind speed at 10 m.", "(added)"),
    _v(
        "WIND_DIR",
        "weather",
        "deg",
        0,
        360,
        None,
        H,
        "Wind direction, degrees clockwise from north (where the wind comes from).",
        "(added)",
    ),
)

OUTPUTS: tuple[Variable, ...] = (
    _v(
        "Q_AC_OFFICE",
        "outputs",
        "Wh/m2",
        0,
        500,
        None,
        H,
        "Zone (fan-coil) cooling energy delivered in the hour.",
        "Q_AC_OFFICE",
    ),
    _v(
        "Q_HEAT_OFFICE",
        "outputs",
        "Wh/m2",
        0,
        500,
        None,
        H,
        "Zone (fan-coil) heating energy delivered in the hour.",
        "Q_HEAT_OFFICE",
    ),
    _v(
        "Q_PEOPLE",
        "outputs",
        "Wh/m2",
        0,
        100,
        None,
        H,
        "Heat given off by occupants (sensible + latent) in the hour.",
        "Q_PEOPLE",
    ),
    _v(
        "Q_EQP",
        "outputs",
        "Wh/m2",
        0,
        100,
        None,
        H,
        "Electricity used by equipment (computers, office appliances) in the hour.",
        "Q_EQP",
    ),
    _v("Q_LIGHT", "outputs", "Wh/m2", 0, 100, None, H, "Electricity used by lighting in the hour.", "Q_LIGHT"),
    _v(
        "Q_AHU_C",
        "outputs",
        "Wh/m2",
        0,
        500,
        None,
        H,
        "Air handling unit cooling coil energy (outdoor air cooled to the supply temperature).",
        "Q_AHU_C",
    ),
    _v(
        "Q_AHU_H",
        "outputs",
        "Wh/m2",
        0,
        500,
        None,
        H,
        "Air handling unit heating coil energy (outdoor air heated to the supply temperature).",
        "Q_AHU_H",
    ),
    _v("T_INT_OFFICE", "outputs", "degC", -30, 60, None, H, "Mean indoor air temperature.", "T_INT_OFFICE"),
)

GROUPS: dict[str, tuple[Variable, ...]] = {
    "theta_build": THETA_BUILD,
    "settings": SETTINGS,
    "occupancy": OCCUPANCY,
    "weather": WEATHER,
    "outputs": OUTPUTS,
}

ALL_VARIABLES: tuple[Variable, ...] = tuple(v for group in GROUPS.values() for v in group)
_BY_NAME: dict[str, Variable] = {v.name: v for v in ALL_VARIABLES}
_ALIASES: dict[str, str] = {v.paper_name.lower(): v.name for v in ALL_VARIABLES if not v.paper_name.startswith("(")}

THETA_NAMES: tuple[str, ...] = tuple(v.name for v in THETA_BUILD)
#: theta_build variables a building's drawings give (a site states them; calibration does not estimate them).
GEOMETRY_NAMES: tuple[str, ...] = tuple(v.name for v in THETA_BUILD if v.paper_name == "(geometry)")
SETTING_NAMES: tuple[str, ...] = tuple(v.name for v in SETTINGS)
OCCUPANCY_NAMES: tuple[str, ...] = tuple(v.name for v in OCCUPANCY)
WEATHER_NAMES: tuple[str, ...] = tuple(v.name for v in WEATHER)
OUTPUT_NAMES: tuple[str, ...] = tuple(v.name for v in OUTPUTS)
TEMPERATURE_OUTPUTS: tuple[str, ...] = ("T_INT_OFFICE",)
#: Outputs summed into the measured "heat consumption" of the paper's calibration appendix.
HEAT_CONSUMPTION_OUTPUTS: tuple[str, ...] = ("Q_HEAT_OFFICE", "Q_AHU_H", "Q_EQP", "Q_LIGHT")
#: End uses a site's consumption meter may sum (``site.toml`` ``[meters] consumption``) and the outputs each
#: maps onto; heating and cooling are the energy delivered (heat meter, chilled-water / cooling-coil energy).
END_USE_OUTPUTS: dict[str, tuple[str, ...]] = {
    "heating": ("Q_HEAT_OFFICE", "Q_AHU_H"),
    "cooling": ("Q_AC_OFFICE", "Q_AHU_C"),
    "lighting": ("Q_LIGHT",),
    "plug_loads": ("Q_EQP",),
}
#: End uses of a site without ``[meters]``: the sum of :data:`HEAT_CONSUMPTION_OUTPUTS`.
DEFAULT_END_USES: tuple[str, ...] = ("heating", "lighting", "plug_loads")


def consumption_outputs(end_uses: Iterable[str] = DEFAULT_END_USES) -> tuple[str, ...]:
    """Output names a consumption meter over ``end_uses`` (keys of :data:`END_USE_OUTPUTS`) sums, in catalogue
    order; raises ``KeyError`` on an unknown end use."""
    names = {n for use in end_uses for n in END_USE_OUTPUTS[use]}
    return tuple(n for n in OUTPUT_NAMES if n in names)


#: Outputs summed into the HVAC energy the optimisation minimises (the paper's Delta_Q^opt): heating and
#: cooling delivered by the zone units and the air handling unit.
HVAC_OUTPUTS: tuple[str, ...] = ("Q_AC_OFFICE", "Q_HEAT_OFFICE", "Q_AHU_C", "Q_AHU_H")


def get(name: str) -> Variable:
    """Look a variable up by canonical name or paper alias; unknown names suggest the closest match."""
    if name in _BY_NAME:
        return _BY_NAME[name]
    alias = _ALIASES.get(name.lower())
    if alias is not None:
        return _BY_NAME[alias]
    close = difflib.get_close_matches(name, list(_BY_NAME) + list(_ALIASES), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise CatalogueError(f"unknown variable {name!r}{hint} (see `buildenv catalogue`)")


def weekly_names(group: str) -> tuple[str, ...]:
    """Flat names of one week's values of a per-day or per-weekday group, day-major.

    ``weekly_names("settings")`` gives ``("cooling_start_hour_monday", ..., "ventilation_ach_sunday")``
    (91 names); ``weekly_names("occupancy")`` gives the 10 Monday-Friday names.
    """
    variables = GROUPS[group]
    if variables[0].granularity is Granularity.PER_DAY:
        days = DAYS
    elif variables[0].granularity is Granularity.PER_WEEKDAY:
        days = WEEKDAYS
    else:
        raise CatalogueError(f"group {group!r} is {variables[0].granularity.value}, not per day or per weekday")
    return tuple(f"{v.name}_{day}" for day in days for v in variables)


def bounds(group: str) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of a group's variables, in catalogue order (two arrays of shape ``(n,)``)."""
    variables = GROUPS[group]
    return np.array([v.min for v in variables]), np.array([v.max for v in variables])


def check_values(group: str, values: np.ndarray, where: str = "") -> None:
    """Validate an array whose last axis follows the group's catalogue order; raise on the first bad value."""
    values = np.asarray(values, dtype=float)
    variables = GROUPS[group]
    if values.shape[-1] != len(variables):
        raise CatalogueError(
            f"{group}{' in ' + where if where else ''}: last axis has {values.shape[-1]} values, "
            f"expected {len(variables)} ({', '.join(v.name for v in variables)})"
        )
    for i, var in enumerate(variables):
        var.check(values[..., i], where)


def from_mapping(
    group: str, mapping: Mapping[str, float], defaults: Mapping[str, float] | None = None, where: str = ""
) -> np.ndarray:
    """Build a group vector (catalogue order) from named values, rejecting unknown or out-of-range names.

    Args:
        group: a static group (``theta_build``).
        mapping: ``{name or paper alias: value}``.
        defaults: values for names missing from ``mapping``; without it every name is required.
        where: file or argument name used in error messages.
    """
    names = [v.name for v in GROUPS[group]]
    resolved: dict[str, float] = {}
    for key, value in mapping.items():
        var = get(key)
        if var.group != group:
            raise CatalogueError(f"{key!r}{' in ' + where if where else ''} belongs to {var.group}, not {group}")
        resolved[var.name] = float(value)
    missing = [n for n in names if n not in resolved and not (defaults and n in defaults)]
    if missing:
        raise CatalogueError(f"{where or group}: missing value(s) for {', '.join(missing)}")
    vector = np.array([resolved.get(n, defaults[n] if defaults else np.nan) for n in names])
    check_values(group, vector, where)
    return vector


def catalogue_hash() -> str:
    """SHA-256 (first 16 hex digits) of every variable definition; stored in datasets and checkpoints."""
    payload = json.dumps([{**asdict(v), "granularity": v.granularity.value} for v in ALL_VARIABLES], sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class EarlierCatalogue:
    """What data and checkpoints made with a catalogue this one replaced need to be read under this one.

    Attributes:
        theta_names: its theta_build names, in its order.
        ranges: ``{name: (min, max, step)}`` of the variables whose range or grid it drew from differently, in
            this catalogue's names and units (a metamodel trained on it knows only these).
        renamed: ``{its name: (this catalogue's name, factor)}``: the value here is ``factor`` x its value.
        implied: ``{name: value}`` of this catalogue's variables it lacked: the value its building model had.
    """

    theta_names: tuple[str, ...]
    ranges: dict[str, tuple[float, float, float]]
    renamed: dict[str, tuple[str, float]]
    implied: dict[str, float]

    @property
    def same_variables(self) -> bool:
        """Whether it had this catalogue's variables, in this order and units, drawn within this one's ranges (a
        coarser grid or a narrower range): every value it holds is a value of this catalogue."""
        return self.theta_names == THETA_NAMES and not self.implied and self.read_by_padding

    @property
    def read_by_padding(self) -> bool:
        """Whether its data read as this catalogue's once the variables it lacked are added at their implied values
        (nothing renamed, every other variable drawn within this one's ranges)."""
        if self.renamed or set(self.theta_names) | set(self.implied) != set(THETA_NAMES):
            return False
        for name, (lo, hi, step) in self.ranges.items():
            var = get(name)
            on_grid = var.step is None or all(
                abs(x / var.step - round(x / var.step)) < 1e-9 for x in (lo - var.min, step)
            )
            if not (var.min <= lo and hi <= var.max and on_grid):
                return False
        return True


_WALLS = ("north", "east", "south", "west")
_VENTILATION_BY_0_3 = (0.1, 1.6, 0.3)  # the outdoor air grid before the 0.05 1/h step: 0.1, 0.4, ..., 1.6
_THETA_BEFORE_NIGHT_HEATING = tuple(v.name for v in THETA_BUILD if v.name != "night_cycle_heating_share")
_THETA_BEFORE_PRESSURISATION = tuple(n for n in _THETA_BEFORE_NIGHT_HEATING if n != "infiltration_fans_on_share")
_THETA_BEFORE_ECONOMISER = tuple(n for n in _THETA_BEFORE_PRESSURISATION if n != "economiser_share")
_THETA_BEFORE_MINIMUM_SUPPLY = tuple(n for n in _THETA_BEFORE_ECONOMISER if n != "minimum_supply_air_ach")
_NO_DAY_OFF = {"hvac_operating": (1.0, 1.0, 1.0)}  # every day in occupied mode, before days could be set back
_NO_NIGHT_HEATING = {"night_cycle_heating_share": 0.0}  # the heating setback held zone by zone
#: what the catalogues before the fans pressurised imply: infiltration the same with the fans on, no night heating
_BEFORE_PRESSURISATION = {"infiltration_fans_on_share": 1.0, **_NO_NIGHT_HEATING}
#: Catalogues this one replaced, by :func:`catalogue_hash`.
EARLIER_CATALOGUES: dict[str, EarlierCatalogue] = {
    "bf68f6178dc1d1b3": EarlierCatalogue(
        theta_names=(
            "floor_area_m2",
            "number_of_floors",
            "infiltration_ach",
            "capacitance_kj_per_k_m3",
            "heating_power_w_m2",
            "cooling_power_w_m2",
            "occupant_density_per_m2",
            "pc_density_per_m2",
            "light_night_percent",
            "pc_night_percent",
            *(f"wall_insulation_{w}_m" for w in _WALLS),
            "roof_insulation_m",
            *(f"window_to_wall_{w}_percent" for w in _WALLS),
        ),
        ranges={
            **_NO_DAY_OFF,
            "floor_area_m2": (1000.0, 50000.0, 1000.0),
            "infiltration_ach": (0.1, 0.5, 0.1),
            "capacitance_kj_per_k_m3": (50.0, 300.0, 10.0),
            "heating_power_w_m2": (10.0, 100.0, 10.0),
            "cooling_power_w_m2": (10.0, 100.0, 10.0),
            "occupant_density_per_m2": (0.035, 0.07, 0.005),
            "plug_load_w_m2": (5.25, 10.5, 0.75),
            **{f"wall_insulation_{w}_m": (0.05, 0.15, 0.05) for w in _WALLS},
            "roof_insulation_m": (0.05, 0.15, 0.05),
            **{f"window_to_wall_{w}_percent": (20.0, 60.0, 5.0) for w in _WALLS},
            "ventilation_ach": (0.7, 1.7, 0.3),
            "supply_air_c": (18.0, 26.0, 0.5),
        },
        renamed={"pc_density_per_m2": ("plug_load_w_m2", 150.0)},  # workstations of 150 W
        implied={
            "lighting_power_w_m2": 10.0,
            "heat_recovery_effectiveness": 0.0,
            "minimum_supply_air_ach": 0.0,
            "economiser_share": 0.0,
            **_BEFORE_PRESSURISATION,
        },
    ),
    # supply air from 18 degC
    "11c21d55c2939cd8": EarlierCatalogue(
        theta_names=_THETA_BEFORE_MINIMUM_SUPPLY,
        ranges={**_NO_DAY_OFF, "supply_air_c": (18.0, 26.0, 0.5), "ventilation_ach": _VENTILATION_BY_0_3},
        renamed={},
        implied={"minimum_supply_air_ach": 0.0, "economiser_share": 0.0, **_BEFORE_PRESSURISATION},
    ),
    # no minimum supply air flow: 100 % outdoor air units only
    "6f2f25c1acea3f20": EarlierCatalogue(
        theta_names=_THETA_BEFORE_MINIMUM_SUPPLY,
        ranges={**_NO_DAY_OFF, "ventilation_ach": _VENTILATION_BY_0_3},
        renamed={},
        implied={"minimum_supply_air_ach": 0.0, "economiser_share": 0.0, **_BEFORE_PRESSURISATION},
    ),
    # no economiser: the fan coils cool mechanically only
    "bda1c8ff3b9294aa": EarlierCatalogue(
        theta_names=_THETA_BEFORE_ECONOMISER,
        ranges={**_NO_DAY_OFF, "ventilation_ach": _VENTILATION_BY_0_3},
        renamed={},
        implied={"economiser_share": 0.0, **_BEFORE_PRESSURISATION},
    ),
    # outdoor air by 0.3 air changes per hour
    "88d16120a6d2221f": EarlierCatalogue(
        theta_names=_THETA_BEFORE_PRESSURISATION,
        ranges={**_NO_DAY_OFF, "ventilation_ach": _VENTILATION_BY_0_3},
        renamed={},
        implied=dict(_BEFORE_PRESSURISATION),
    ),
    # no day set back entirely: every day ran its heating, cooling and ventilation periods
    "d40fb58bb6ff03a6": EarlierCatalogue(
        theta_names=_THETA_BEFORE_PRESSURISATION,
        ranges=dict(_NO_DAY_OFF),
        renamed={},
        implied=dict(_BEFORE_PRESSURISATION),
    ),
    # infiltration the same whether the fans ran or not
    "bf2a5f1cabb2a9f8": EarlierCatalogue(
        theta_names=_THETA_BEFORE_PRESSURISATION, ranges={}, renamed={}, implied=dict(_BEFORE_PRESSURISATION)
    ),
    # no night cycling in heating: the air handling units night-cycled only as the warmest zone neared its
    # cooling setback
    "c272c689c0c27ec7": EarlierCatalogue(
        theta_names=_THETA_BEFORE_NIGHT_HEATING, ranges={}, renamed={}, implied=dict(_NO_NIGHT_HEATING)
    ),
}


def upgrade_theta(values: Mapping[str, float]) -> dict[str, float]:
    """theta_build ``{name: value}`` written under an earlier catalogue, in this one's names and units: renamed
    variables converted, variables it lacked at the value its building model had (others pass unchanged). A
    dict is taken as written under an earlier catalogue when it holds a renamed name or all of its names."""
    out = {k: float(v) for k, v in values.items()}
    for earlier in EARLIER_CATALOGUES.values():
        written = any(k in out for k in earlier.renamed) or set(earlier.theta_names) <= set(out)
        if not written:
            continue
        for old, (new, factor) in earlier.renamed.items():
            if old in out and new not in out:
                out[new] = factor * out.pop(old)
        for name, value in earlier.implied.items():
            out.setdefault(name, value)
    return out


def upgrade_settings(settings) -> np.ndarray:
    """Settings ``(..., 12)`` written before ``hvac_operating`` existed, with every day in occupied mode (1), as
    ``(..., 13)``; settings of this catalogue pass unchanged (as float arrays).

    Raises:
        CatalogueError: the last axis is neither length.
    """
    arr = np.asarray(settings, dtype=float)
    n = len(SETTINGS)
    if arr.shape[-1:] == (n,):
        return arr
    if arr.shape[-1:] == (n - 1,):  # hvac_operating, the last setting, was not there: every day operated
        return np.concatenate([arr, np.ones((*arr.shape[:-1], 1))], axis=-1)
    got = arr.shape[-1] if arr.ndim else 0
    raise CatalogueError(f"settings have {got} values a day; expected {n} ({', '.join(SETTING_NAMES)})")


def describe(groups: Iterable[str] | None = None) -> list[dict]:
    """The catalogue as a list of plain dicts (for the CLI, docs and JSON export)."""
    out = []
    for group in GROUPS if groups is None else groups:
        for v in GROUPS[group]:
            out.append({**asdict(v), "granularity": v.granularity.value})
    return out
