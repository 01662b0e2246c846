"""The "real building" stand-in: a DOE reference office run under given BMS settings, read like sensors.

A real building is stood in for by an EnergyPlus model none of us wrote: a reference office shipped with
pyenergyplus-lbnl (:data:`REFERENCE_BUILDINGS`) or a user's IDF. The site's settings I_k replace, hour by hour
through one Schedule:File, the schedules of four roles (:data:`SCHEDULE_ROLES`, :func:`prepare_model`): the
heating and cooling setpoints of every ``ThermostatSetpoint:DualSetpoint``, the HVAC availability (the union
of the heating, cooling and ventilation periods) and the minimum outdoor air of every ``Controller:OutdoorAir``
(``ventilation_on * min(1, ventilation_ach / design_ach)``, :func:`design_outdoor_air_ach`); the settings of
:data:`UNMAPPED_SETTINGS` are not mapped. A stand-in site declares that in its ``[bms]`` (:func:`reference_bms`):
the mapped settings are controllable, ventilation up to the design outdoor air. Infiltration that the model cuts
while its air handling units ventilate (the pressurised building of the reference offices,
:func:`pressurised_infiltration`) follows the site's ventilation hours instead of the model's fixed clock (from
:data:`STAND_IN_VERSION` 2; a site records the version it was made with, and its building runs again as that
version). Schedules are re-pointed, not rewritten. Systems of 24/7 spaces keep their own schedules
(:func:`serves_24h_space`); from version 3 their equipment runs steady at its level of the run's first day
(:func:`steady_24h_equipment`: the ASHRAE 90.1 large office steps its data centre's IT load 0.25, 0.5, 0.75, 1
from month to month, a change of base load no building parameter describes). Occupancy, lighting, the offices'
equipment, constructions and systems are untouched; public holidays and daylight-saving time are removed. The run
starts ``warmup_weeks`` before the first measured week.

Unmodelled effects (:mod:`buildenv.diagnosis.effects`) are put in by :mod:`buildenv.energyplus.injections`:
model edits after the schedules are re-pointed, sensor effects on the true temperature before the noise.

The two sensors (:func:`read_sensors`): the occupied-zone mean air temperature (floor-area weighted, zone
multipliers counted) and the consumption, kWh per hour: the EnergyPlus meters of the site's end uses
(:data:`END_USE_METERS`; default heating + lighting + plug loads), the counterpart of the model's outputs of
those end uses (:data:`buildenv.catalogue.END_USE_OUTPUTS`). The HVAC energy (heating + cooling coils, no
noise), for verifying optimised settings, is the counterpart of :data:`buildenv.catalogue.HVAC_OUTPUTS`. A site
that meters heat and electricity apart has a second consumption series, the meters of its own end uses.

Sensor noise (seeded, :func:`add_sensor_noise`): temperature ``N(0, 0.1 K)`` with a 0.1 K resolution (a
class-B Pt1000 read by a BMS); consumption ``N(0, 1 %)`` multiplicative with a 0.1 kWh meter resolution.
"""

from __future__ import annotations

import datetime as dt
import functools
import logging
import math
import re
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from buildenv import catalogue as cat
from buildenv.defaults import default_week
from buildenv.energyplus import workdirs
from buildenv.energyplus.compact_schedules import daily_means, steady_copy
from buildenv.energyplus.design_days import climate_design_days
from buildenv.energyplus.idf import IdfObject, format_idf, of_type, read_idf, without
from buildenv.energyplus.injections import (
    InjectedEffect,
    inject_energyplus,
    plan_effects,
    sensor_effect_series,
    sizing_objects,
    weekday_profile,
)
from buildenv.energyplus.model_files import user_model
from buildenv.energyplus.runner import WARMUP_TEMPERATURE_LIMIT_K, clean_outputs, run_energyplus, run_period_rows
from buildenv.energyplus.shoebox import FLOOR_HEIGHT_M
from buildenv.energyplus.ventilation_code import code_minimum_ventilation_ach
from buildenv.errors import ReferenceBuildingError, SimulationError
from buildenv.schedules import hourly_schedules
from buildenv.weather.epw import epw_day_of_year, resolve_epw

#: Reference offices shipped with pyenergyplus-lbnl: name -> (IDF file name, storeys).
REFERENCE_BUILDINGS: dict[str, tuple[str, int]] = {
    "small_office": ("RefBldgSmallOfficeNew2004_Chicago.idf", 1),
    "medium_office": ("RefBldgMediumOfficeNew2004_Chicago.idf", 3),
    "large_office": ("RefBldgLargeOfficeNew2004_Chicago.idf", 12),
    "small_office_2019": ("ASHRAE901_OfficeSmall_STD2019_Denver.idf", 1),
    "medium_office_2019": ("ASHRAE901_OfficeMedium_STD2019_Denver.idf", 3),
    "large_office_2019": ("ASHRAE901_OfficeLarge_STD2019_Denver.idf", 12),
}
SCHEDULE_ROLES = ("heating_setpoint", "cooling_setpoint", "hvac_availability", "outdoor_air")
#: How the stand-in maps a site's settings onto its model, recorded in a site's ``truth.json`` (``stand_in``; none:
#: 1): 1, the model's infiltration on its own clock; 2, infiltration it cuts while its fans run follows the site's
#: ventilation hours; 3, the equipment of 24/7 spaces held steady (:func:`steady_24h_equipment`).
STAND_IN_VERSION = 3
#: warm-up weeks of the run that makes a stand-in site (:func:`make_reference_site`)
SITE_WARMUP_WEEKS = 1
#: Settings the stand-in's schedules do not map: they do not act on the reference model.
UNMAPPED_SETTINGS: tuple[str, ...] = ("supply_air_c",)
#: End use (:data:`buildenv.catalogue.END_USE_OUTPUTS`) -> (EnergyPlus meter the stand-in's consumption sums,
#: what it is in words). Heating and cooling: energy the coils deliver, as the model's outputs are.
END_USE_METERS: dict[str, tuple[str, str]] = {
    "heating": ("HeatingCoils:EnergyTransfer", "heating coils"),
    "cooling": ("CoolingCoils:EnergyTransfer", "cooling coils"),
    "lighting": ("InteriorLights:Electricity", "interior lights"),
    "plug_loads": ("InteriorEquipment:Electricity", "interior equipment"),
}
TEMPERATURE_NOISE_K, TEMPERATURE_RESOLUTION_K = 0.1, 0.1
CONSUMPTION_NOISE_FRACTION, CONSUMPTION_RESOLUTION_KWH = 0.01, 0.1
HOURS_PER_YEAR = 8760
# the weather of the sizing run that gives a model's design outdoor air (which does not depend on the weather;
# some models fail to size their cooling coils with other files)
OUTDOOR_AIR_SIZING_WEATHER = "usa_il_chicago"
_DATA_CENTRE_COIL_ERROR = (
    "{}: EnergyPlus failed (Severe FindRootSimpleController) on the data centre's zero-capacity extra heating "
    "coil, which the model's EMS switches on when the data centre heats below 10 degC outdoors, with its setpoint "
    "at its inlet temperature (the BMS setbacks of the offices around it make it heat): try a warmer period"
)
log = logging.getLogger(__name__)
# names of the systems of 24/7 spaces, which keep their own schedules (see serves_24h_space)
_24H_NAME = re.compile(r"data[\s_-]*cent(er|re)|server[\s_-]*room", re.IGNORECASE)


@dataclass
class ScheduleMap:
    """Names of the model's schedules each role replaces (see the module docstring)."""

    heating_setpoint: list[str] = field(default_factory=list)
    cooling_setpoint: list[str] = field(default_factory=list)
    hvac_availability: list[str] = field(default_factory=list)
    outdoor_air: list[str] = field(default_factory=list)


@dataclass
class ReferenceRun:
    """Hourly sensor readings of a reference run (before noise), one row per measured week."""

    temperature_c: np.ndarray  # (weeks, 168) occupied-zone mean air temperature
    consumption_kwh: np.ndarray  # (weeks, 168) consumption of the metered end uses per hour
    floor_area_m2: float  # occupied (people-bearing) floor area, multipliers counted
    zones: list[str]  # zones averaged into the temperature
    hvac_kwh: np.ndarray | None = None  # (weeks, 168) heat delivered by heating coils + cooling coils per hour
    warmup_temperature_c: np.ndarray | None = None  # (warmup_weeks*168,) true temperature of the warm-up hours
    supply_air_c: np.ndarray | None = (
        None  # (weeks, 168) central air loops' mean supply temperature (None: no such loop)
    )
    effects: list[dict[str, Any]] = field(default_factory=list)  # injected effects, truth.json entries
    electricity_kwh: np.ndarray | None = None  # (weeks, 168) a second meter's end uses per hour (None: one meter)


def reference_idf(building: str | Path) -> Path:
    """Path of a shipped reference office (a name of :data:`REFERENCE_BUILDINGS`) or the IDF of a user's model
    (an IDF of the shipped engine's version, or an epJSON, converted:
    :func:`~buildenv.energyplus.model_files.user_model`)."""
    if str(building) in REFERENCE_BUILDINGS:
        import pyenergyplus

        path = Path(pyenergyplus.__file__).parent / "data" / "model" / REFERENCE_BUILDINGS[str(building)][0]
    else:
        path = Path(building)
    if not path.is_file():
        known = ", ".join(REFERENCE_BUILDINGS)
        raise ReferenceBuildingError(
            f"reference building not found: {building} (shipped: {known}; or an IDF or epJSON path)"
        )
    return path if str(building) in REFERENCE_BUILDINGS else user_model(path)


def _unoccupied_thermostats(objects: list[IdfObject]) -> set[str]:
    """Names (lower case) of the dual-setpoint thermostats that control only zones without ``People``."""
    occupied = {o[2].lower() for o in of_type(objects, "People") if len(o) > 2}
    lists = {o[1].lower(): {z.lower() for z in o[2:]} for o in of_type(objects, "ZoneList")}
    for o in of_type(objects, "People"):  # People may name a ZoneList
        occupied |= lists.get(o[2].lower(), set()) if len(o) > 2 else set()
    controls: dict[str, bool] = {}  # dual setpoint name -> controls an occupied zone
    for o in of_type(objects, "ZoneControl:Thermostat"):
        zones = lists.get(o[2].lower(), {o[2].lower()}) | {o[2].lower()}
        for kind, name in zip(o[4::2], o[5::2]):
            if kind.lower() == "thermostatsetpoint:dualsetpoint":
                controls[name.lower()] = controls.get(name.lower(), False) or bool(zones & occupied)
    return {name for name, occ in controls.items() if not occ}


def serves_24h_space(obj: IdfObject, unoccupied_thermostats: set[str] = frozenset()) -> bool:
    """Whether ``obj`` belongs to a system of a 24/7 space (data centre, server room): it keeps its schedules.

    A dual-setpoint thermostat of zones without people, or an object named after a data centre or server
    room (the ASHRAE 90.1 large office's ``AirLoop DataCenter ...`` air loops, which share the offices'
    minimum outdoor-air schedule). Such objects are neither used to detect the schedules nor re-pointed.
    """
    name = obj[1] if len(obj) > 1 else ""
    if obj[0].lower() == "thermostatsetpoint:dualsetpoint" and name.lower() in unoccupied_thermostats:
        return True
    return bool(_24H_NAME.search(name))


def detect_schedule_map(objects: list[IdfObject]) -> ScheduleMap:
    """Find the schedules each role replaces, from the office systems that use them (not 24/7 spaces')."""
    unoccupied = _unoccupied_thermostats(objects)
    objects = [o for o in objects if not serves_24h_space(o, unoccupied)]
    dual = of_type(objects, "ThermostatSetpoint:DualSetpoint")
    found = ScheduleMap(
        heating_setpoint=sorted({o[2] for o in dual}),
        cooling_setpoint=sorted({o[3] for o in dual}),
        outdoor_air=sorted({o[17] for o in of_type(objects, "Controller:OutdoorAir") if len(o) > 17 and o[17]}),
    )
    hvac = {o[3] for o in of_type(objects, "AvailabilityManager:NightCycle") if len(o) > 3 and o[3]}
    for kind in ("Fan:VariableVolume", "Fan:ConstantVolume", "Fan:OnOff", "Fan:SystemModel"):
        hvac |= {o[2] for o in of_type(objects, kind) if len(o) > 2 and o[2]}
    found.hvac_availability = sorted(hvac - {"ALWAYS_ON", "Always_On", "Always On"})
    return found


def site_steady_day(site) -> dt.date:
    """The day whose level a stand-in site's 24/7 equipment holds in every run of its building: the first day of the
    run that made it (:func:`make_reference_site`: a warm-up week before its first measured week)."""
    return site.start - dt.timedelta(weeks=SITE_WARMUP_WEEKS)


def stand_in_version(site) -> int:
    """The version of the stand-in's mapping a site was made with (``truth.json``'s ``stand_in``; 1 where it names
    none: sites made before versions were recorded), see :data:`STAND_IN_VERSION`.

    Raises:
        ReferenceBuildingError: the version is not one this buildenv knows.
    """
    version = (site.truth or {}).get("stand_in", 1)
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= STAND_IN_VERSION:
        raise ReferenceBuildingError(
            f"{site.path}/truth.json: stand_in {version!r} is not a stand-in version this buildenv knows "
            f"(1-{STAND_IN_VERSION}); update buildenv or make the site again"
        )
    return version


def recorded_schedule_map(site) -> ScheduleMap | None:
    """The schedules a site's building was made with when they were named (``buildenv site reference --map``,
    ``truth.json``'s ``schedule_map``), so that its building runs again with them; ``None`` where they were detected.

    Raises:
        ReferenceBuildingError: ``schedule_map`` is not ``{role: [schedule names]}`` over :data:`SCHEDULE_ROLES`.
    """
    recorded = (site.truth or {}).get("schedule_map")
    if recorded is None:
        return None
    valid = (
        isinstance(recorded, dict)
        and set(recorded) == set(SCHEDULE_ROLES)
        and all(isinstance(v, list) and v and all(isinstance(n, str) for n in v) for v in recorded.values())
    )
    if not valid:
        raise ReferenceBuildingError(
            f"{site.path}/truth.json: schedule_map must name schedules for each of {', '.join(SCHEDULE_ROLES)}, "
            "as lists of names; make the site again with --map"
        )
    return ScheduleMap(**{role: list(recorded[role]) for role in SCHEDULE_ROLES})


def pressurised_infiltration(objects: list[IdfObject]) -> dict[str, tuple[float, float]]:
    """The infiltration schedules a model lowers while its air handling units ventilate: ``{name: (value while they
    ventilate, value otherwise)}``.

    A schedule of the offices' ``ZoneInfiltration:DesignFlowRate`` objects (not a 24/7 space's) counts when it is a
    ``Schedule:Compact`` whose weekday clause takes two values, the higher at 03:00 and the lower at noon (the
    reference offices: 1.0 outside, 0.25 inside their HVAC hours). Door-opening schedules, which rise by day, and
    constant ones do not.
    """
    unoccupied = _unoccupied_thermostats(objects)
    names = {
        o[3].lower()
        for o in of_type(objects, "ZoneInfiltration:DesignFlowRate")
        if len(o) > 3 and not serves_24h_space(o, unoccupied)
    }
    found = {}
    for o in of_type(objects, "Schedule:Compact"):
        if o[1].lower() not in names:
            continue
        try:
            values = weekday_profile(o)[2]
        except (ReferenceBuildingError, ValueError):
            continue  # not by weekday, whole hours and numbers: left on its own schedule
        if len(set(values.tolist())) == 2 and values[3] > values[12]:
            found[o[1]] = (float(values[12]), float(values[3]))
    return found


def _mapped(mapping: ScheduleMap) -> set[str]:
    """Names (lower case) of the schedules a map's roles replace."""
    return {name.lower() for role in SCHEDULE_ROLES for name in getattr(mapping, role)}


def _schedule_columns(settings: np.ndarray, design_ach: float) -> dict[str, np.ndarray]:
    """Hourly values of the four roles and ``ventilation_on`` for ``settings`` ``(weeks, 7, 13)`` -> ``{role:
    (weeks*168,)}``, for a model whose design minimum outdoor air is ``design_ach`` (1/h, see
    :func:`design_outdoor_air_ach`).

    Outside the HVAC availability the systems only cycle on to hold the setbacks (the model's night-cycle
    managers); outdoor air above the design cannot be expressed (EnergyPlus caps the schedule at 1).
    """
    occupancy = np.zeros((len(settings), len(cat.WEEKDAYS), len(cat.GROUPS["occupancy"])))
    occupancy[..., 0], occupancy[..., 1] = cat.get("occupancy_start_hour").min, cat.get("occupancy_end_hour").max
    s = {k: v.reshape(-1) for k, v in hourly_schedules(settings, occupancy).items()}
    hvac = np.maximum.reduce([s["heating_comfort_on"], s["cooling_comfort_on"], s["ventilation_on"]])
    return {
        "heating_setpoint": s["heating_setpoint_c"],
        "cooling_setpoint": s["cooling_setpoint_c"],
        "hvac_availability": hvac,
        "outdoor_air": s["ventilation_on"] * np.minimum(1.0, s["ventilation_ach"] / design_ach),
        "ventilation_on": s["ventilation_on"],
    }


def prepare_model(
    source: Path,
    settings: np.ndarray,
    first_day: dt.date,
    workdir: Path,
    schedule_map: ScheduleMap | None = None,
    effects: Sequence[InjectedEffect] = (),
    epw: Path | None = None,
    stand_in: int = STAND_IN_VERSION,
    steady_day: dt.date | None = None,
) -> tuple[Path, ScheduleMap]:
    """Write the edited IDF and its Schedule:File for a run of ``len(settings)`` weeks from ``first_day``.

    ``effects`` (planned with :func:`buildenv.energyplus.injections.plan_effects`): the ``kind="energyplus"`` ones
    are injected into the model (:func:`buildenv.energyplus.injections.inject_energyplus`); none gives the model of
    a run without effects, unchanged. ``epw`` (an EPW path) is needed by ``heating_capacity_limit``, whose
    design capacities come from a sizing run in ``workdir/sizing``. ``stand_in``: the mapping's version
    (:data:`STAND_IN_VERSION`). ``steady_day``: the day whose level the equipment of 24/7 spaces holds
    (:func:`steady_24h_equipment`; default ``first_day``).

    Returns the IDF path and the schedule map used. Raises :class:`ReferenceBuildingError` if a role has no schedule
    or ``stand_in`` is not a known version.
    """
    if stand_in not in range(1, STAND_IN_VERSION + 1):
        raise ReferenceBuildingError(
            f"stand-in version {stand_in} is not one this buildenv knows (1-{STAND_IN_VERSION}); update buildenv"
        )
    objects = read_idf(source)
    mapping = schedule_map or detect_schedule_map(objects)
    missing = [r for r in SCHEDULE_ROLES if not getattr(mapping, r)]
    if missing:
        raise ReferenceBuildingError(
            f"{source}: no schedule found for {', '.join(missing)}; name them with --map ROLE=SCHEDULE"
        )
    last_day = first_day + dt.timedelta(days=7 * len(settings) - 1)
    if 7 * len(settings) > 364:
        raise ReferenceBuildingError(f"the run {first_day}..{last_day} is longer than a year; split it")
    # the Schedule:File: a year of hourly values, the run's hours filled from the settings from the run's first
    # day on; a run across a new year continues at the start of the table, where EnergyPlus reads January
    columns = _schedule_columns(settings, design_outdoor_air_ach(source, resolve_epw(OUTDOOR_AIR_SIZING_WEATHER)))
    # pressurised infiltration: one column per pair of levels, its schedules' value while the AHUs ventilate
    infiltration = pressurised_infiltration(objects) if stand_in >= 2 else {}
    mapped = _mapped(mapping)
    infiltration = {k: v for k, v in infiltration.items() if k.lower() not in mapped}
    levels = sorted(set(infiltration.values()))
    roles = list(SCHEDULE_ROLES)
    for k, (on, off) in enumerate(levels):
        roles.append(f"infiltration_{k + 1}")
        columns[roles[-1]] = off + (on - off) * columns["ventilation_on"]
    if infiltration:
        log.info("%s: infiltration %s follows the ventilation hours", source.stem, ", ".join(sorted(infiltration)))
    start = epw_day_of_year(first_day) * cat.HOURS_PER_DAY
    rows = (start + np.arange(7 * len(settings) * cat.HOURS_PER_DAY)) % HOURS_PER_YEAR
    table = np.empty((HOURS_PER_YEAR, len(roles)))
    for j, role in enumerate(roles):
        values = columns[role]
        table[:, j] = values[: cat.HOURS_PER_DAY * 7].mean()  # outside the run (design days only): a week's mean
        table[rows, j] = values
    csv = (workdir / "buildenv_schedules.csv").resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    np.savetxt(csv, table, fmt="%.4f", delimiter=",", header=",".join(roles), comments="")
    # re-point every reference to a replaced schedule (definitions and EMS objects keep the old names)
    rename = {old.lower(): f"buildenv_{role}" for role in SCHEDULE_ROLES for old in getattr(mapping, role)}
    rename |= {name.lower(): f"buildenv_infiltration_{levels.index(v) + 1}" for name, v in infiltration.items()}
    kept_kinds = ("schedule:", "energymanagementsystem:", "output:")
    unoccupied = _unoccupied_thermostats(objects)
    edited = []
    for o in without(
        objects,
        kinds={
            "RunPeriod",
            "RunPeriodControl:SpecialDays",
            "RunPeriodControl:DaylightSavingTime",
            "OutputControl:Files",
            "Output:SQLite",
            "OutputControl:Table:Style",
            "Output:Variable",
            "Output:Meter",
            "Output:Meter:MeterFileOnly",
            "Output:Table:Monthly",
            "Output:Table:SummaryReports",
            "Output:Table:TimeBins",
        },
    ):
        if not o[0].lower().startswith(kept_kinds) and not serves_24h_space(o, unoccupied):
            o = [o[0]] + [rename.get(f.lower(), f) for f in o[1:]]
        edited.append(o)
    if stand_in >= 3:
        edited = steady_24h_equipment(edited, steady_day or first_day)
    if epw is not None:
        edited = climate_design_days(edited, epw)
    sim = of_type(edited, "SimulationControl")
    if sim:
        sim[0][1:6] = ["Yes", "Yes", "Yes", "No", "Yes"]  # autosize on design days, simulate the run period only
    edited += [
        ["Schedule:File", f"buildenv_{role}", "", str(csv), str(j + 1), "1", str(HOURS_PER_YEAR), "Comma", "No", "60"]
        for j, role in enumerate(roles)
    ]
    edited.append(
        [
            "RunPeriod",
            "buildenv",
            str(first_day.month),
            str(first_day.day),
            str(first_day.year),
            str(last_day.month),
            str(last_day.day),
            str(last_day.year),
            "",
            "No",
            "No",
            "No",
            "No",
            "No",
            "No",
        ]
    )
    edited += [
        ["Output:Variable", "*", "Zone Mean Air Temperature", "Hourly"],
        *(["Output:Variable", node, "System Node Temperature", "Hourly"] for node in central_supply_nodes(objects)),
        *(["Output:Meter", meter, "Hourly"] for meter, _ in END_USE_METERS.values()),
        ["OutputControl:Files", "Yes", "No", "No", "Yes"] + ["No"] * 29,
    ]
    if any(e.active and e.effect.kind == "energyplus" for e in effects):
        edited = inject_energyplus(edited, effects, source.stem, sizing=_sizing_run(source, workdir, epw))
    idf = workdir / f"{source.stem}_buildenv.idf"
    idf.write_text(format_idf(edited))
    return idf, mapping


def steady_24h_equipment(objects: list[IdfObject], day: dt.date) -> list[IdfObject]:
    """``objects`` with the ``ElectricEquipment`` of 24/7 spaces (:func:`serves_24h_space`) on a steady schedule:
    on every ordinary day, the value their ``Schedule:Compact`` gives on ``day`` (its mean over the day,
    :func:`~buildenv.energyplus.compact_schedules.daily_means`); the design days the model is sized with kept.

    A data centre's IT load is steady over weeks; prototypes step it by month to span its utilisation over an
    annual run. Objects on other kinds of schedule are left as they are.
    """
    compact = {o[1].lower(): o for o in of_type(objects, "Schedule:Compact") if len(o) > 1}
    out, steady = [], {}
    for o in objects:
        schedule = o[3].lower() if o[0].lower() == "electricequipment" and len(o) > 3 else ""
        if schedule in compact and serves_24h_space(o):
            name = f"buildenv_steady_{compact[schedule][1]}"
            level = daily_means(compact[schedule], day.year)[day.timetuple().tm_yday - 1]
            steady[name] = steady_copy(compact[schedule], name, level)
            o = o[:3] + [name] + o[4:]
        out.append(o)
    return out + list(steady.values())


@functools.lru_cache(maxsize=32)
def design_outdoor_air_ach(source: Path, epw: Path | None) -> float:
    """The design minimum outdoor air of a model's occupied zones, in air changes per hour of
    ``floor area x FLOOR_HEIGHT_M`` (our model's ``ventilation_ach``), from a sizing run (cached).

    The sum over zones with ``People`` of the larger of each zone's heating and cooling "Calc Outdoor Air Flow
    Rate" (``eplusout.eio`` Zone Sizing Information), divided by the same zones' floor area. Raises
    :class:`ReferenceBuildingError` without a weather file or without zone outdoor air.
    """
    if epw is None:
        raise ReferenceBuildingError(f"{source.stem}: the design outdoor air needs a sizing run with a weather file")
    objects = read_idf(source)
    occupied = {o[2].upper() for o in of_type(objects, "People")}
    with workdirs.temporary_folder("oa") as tmp:
        eio = _sizing_run(source, Path(tmp), Path(epw))(sizing_objects(objects))
        flows = zone_outdoor_air_m3_s(eio)
        areas = zone_areas(eio)
    zones = [z for z in flows if z in occupied and z in areas]
    total = sum(flows[z] for z in zones)
    if total <= 0.0:
        raise ReferenceBuildingError(f"{source}: no design outdoor air in its occupied zones (sizing run)")
    return total * 3600.0 / (sum(areas[z] for z in zones) * FLOOR_HEIGHT_M)


#: a week of ordinary days (no holiday in the prototypes' calendars) on which a model's weekly operation is read
_ORDINARY_WEEK = dt.date(2019, 3, 4)


def operating_days(building: str | Path) -> tuple[int, ...]:
    """The days a model runs its HVAC, Monday to Sunday (1: on at some hour, 0: its availability schedules off all
    day, its building shut down): read from the ``Schedule:Compact`` availability schedules its schedule map
    replaces (:func:`detect_schedule_map`) on a week of ordinary days. Every day is on, with a warning naming the
    file, where it has no such schedule, one that is not compact or cannot be read, or one off all that week.
    """
    path = reference_idf(building)
    return _operating_days(path, path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=32)
def _operating_days(path: Path, mtime_ns: int) -> tuple[int, ...]:
    """:func:`operating_days` of the model file ``path`` as it was at ``mtime_ns`` (cached)."""
    objects = read_idf(path)
    compact = {o[1].lower(): o for o in of_type(objects, "Schedule:Compact") if len(o) > 1}
    names = detect_schedule_map(objects).hvac_availability
    every_day = (1,) * 7
    if not names:
        return every_day
    first = _ORDINARY_WEEK.timetuple().tm_yday - 1
    on = np.zeros(7, bool)
    for name in names:
        try:
            if name.lower() not in compact:
                raise ReferenceBuildingError(f"{name} is not a Schedule:Compact")
            on |= daily_means(compact[name.lower()], _ORDINARY_WEEK.year)[first : first + 7] > 0.0
        except ReferenceBuildingError as error:
            log.warning("%s: days off not read (%s); its history operates every day", path.name, error)
            return every_day
    if not on.any():
        log.warning(
            "%s: its HVAC availability is off all the week of %s; its history operates every day",
            path.name,
            _ORDINARY_WEEK,
        )
        return every_day
    return tuple(int(d) for d in on)


def historical_ventilation_ach(building: str | Path) -> float:
    """The ventilation a reference building's site records as its historical setting: its design minimum
    outdoor air (:func:`design_outdoor_air_ach`) on the catalogue's grid of ``ventilation_ach`` (1/h)."""
    var = cat.get("ventilation_ach")
    design = design_outdoor_air_ach(reference_idf(building), resolve_epw(OUTDOOR_AIR_SIZING_WEATHER))
    return float(var.snap(np.clip(design, var.min, var.max)))


def design_occupants_per_m2(objects: list[IdfObject]) -> float | None:
    """The design occupant density of a model (people per m2): the median over its ``People`` objects given per
    floor area (``People/Area`` or ``Area/Person``); ``None`` when none is."""
    densities = []
    for o in of_type(objects, "People"):
        method = o[4].strip().lower() if len(o) > 4 else ""
        try:
            if method == "people/area":
                densities.append(float(o[6]))
            elif method == "area/person" and float(o[7]) > 0.0:
                densities.append(1.0 / float(o[7]))
        except (IndexError, ValueError):
            continue
    return float(np.median(densities)) if densities else None


def reference_bms(building: str | Path) -> tuple[tuple[str, ...], dict[str, tuple[float, float]]]:
    """What a reference building's site declares in ``[bms]``: ``(controllable, setting_limits)``, the settings
    its schedules map (all but :data:`UNMAPPED_SETTINGS`, catalogue order) and ``ventilation_ach`` limited to
    ``[ASHRAE 62.1 minimum for its design occupants, historical_ventilation_ach(building)]`` (1/h, the minimum
    at least the catalogue's): above its design the model delivers no more outdoor air, below the code minimum
    no BMS may go."""
    controllable = tuple(n for n in cat.SETTING_NAMES if n not in UNMAPPED_SETTINGS)
    design = historical_ventilation_ach(building)
    occupants = design_occupants_per_m2(read_idf(reference_idf(building)))
    lowest = cat.get("ventilation_ach").min
    if occupants is not None:
        lowest = min(max(lowest, round(code_minimum_ventilation_ach(occupants), 2)), design)
    return controllable, {"ventilation_ach": (lowest, design)}


def zone_outdoor_air_m3_s(eio: Path) -> dict[str, float]:
    """``{zone name (upper case): design outdoor air (m3/s)}`` from the Zone Sizing Information of
    ``eplusout.eio`` (the larger of the heating and cooling lines, as EnergyPlus reports them)."""
    header: list[str] | None = None
    flows: dict[str, float] = {}
    for line in Path(eio).read_text(errors="replace").splitlines():
        fields = [f.strip() for f in line.split(",")]
        if fields[0] == "! <Zone Sizing Information>":
            header = [h.split("{")[0].strip().lower() for h in fields]
        elif fields[0] == "Zone Sizing Information" and header and "calc outdoor air flow rate" in header:
            value = float(fields[header.index("calc outdoor air flow rate")])
            flows[fields[1].upper()] = max(flows.get(fields[1].upper(), 0.0), value)
    return flows


def _sizing_run(source: Path, workdir: Path, epw: Path | None):
    """A callback running the sizing of a model in ``workdir/sizing``; returns its ``eplusout.eio``."""

    def size(objects: list[IdfObject]) -> Path:
        if epw is None:
            raise ReferenceBuildingError(f"{source.stem}: a sizing run needs the weather file (prepare_model(epw=))")
        folder = workdir / "sizing"
        folder.mkdir(parents=True, exist_ok=True)
        idf = folder / f"{source.stem}_sizing.idf"
        idf.write_text(format_idf(climate_design_days(objects, epw)))
        run_energyplus(idf, epw, folder, label=f"{source.stem} sizing")
        return folder / "eplusout.eio"

    return size


def zone_areas(eio: Path) -> dict[str, float]:
    """``{zone name (upper case): floor area x multipliers (m2)}`` from EnergyPlus's ``eplusout.eio``."""
    header: list[str] | None = None
    areas: dict[str, float] = {}
    for line in eio.read_text(errors="replace").splitlines():
        fields = [f.strip() for f in line.split(",")]
        if fields[0] == "! <Zone Information>":
            header = fields
        elif fields[0] == "Zone Information" and header:
            col = {name.split("{")[0].strip().lower(): i for i, name in enumerate(header)}
            area = float(fields[col["floor area"]])
            mult = float(fields[col["zone multiplier"]]) * float(fields[col["zone list multiplier"]])
            areas[fields[1].upper()] = area * mult
    if not areas:
        raise ReferenceBuildingError(f"{eio}: no Zone Information lines")
    return areas


#: set-point managers that hold a central air loop's supply air at a temperature of their own (not a zone's load)
CENTRAL_SUPPLY_MANAGERS = (
    "setpointmanager:scheduled",
    "setpointmanager:outdoorairreset",
    "setpointmanager:followoutdoorairtemperature",
    "setpointmanager:warmest",
    "setpointmanager:warmesttemperatureflow",
)


def central_supply_nodes(objects: list[IdfObject]) -> list[str]:
    """Supply outlet nodes of the air loops whose supply air temperature a central set-point manager sets
    (:data:`CENTRAL_SUPPLY_MANAGERS`; VAV systems with terminal reheat), 24/7 spaces' loops left out; single-zone
    units, whose supply follows their zone's load, have none."""
    lists = {o[1].strip().lower(): [f.strip().lower() for f in o[2:]] for o in of_type(objects, "NodeList")}
    managed = set()
    for o in objects:
        if o[0].lower() in CENTRAL_SUPPLY_MANAGERS:
            for f in o[1:]:
                managed.update(lists.get(f.strip().lower(), [f.strip().lower()]))
    return [
        o[10]
        for o in of_type(objects, "AirLoopHVAC")
        if len(o) > 10 and o[10].strip().lower() in managed and not serves_24h_space(o)
    ]


def read_sensors(
    out: Path,
    occupied: list[str],
    weeks: int,
    warmup_weeks: int,
    first_day: dt.date | None = None,
    end_uses: Sequence[str] = cat.DEFAULT_END_USES,
    electricity_end_uses: Sequence[str] = (),
) -> ReferenceRun:
    """Aggregate a finished reference run as the two sensors (see the module docstring).

    ``first_day`` (the run period's first day): read only the rows stamped with the run period's hours
    (:func:`buildenv.energyplus.runner.run_period_rows`); ``None`` takes every row of ``eplusout.csv`` as the run
    period's. ``end_uses`` (keys of :data:`END_USE_METERS`): the meters the consumption sums;
    ``electricity_end_uses``: those a second meter sums (none: no second meter).
    """
    import pandas as pd

    frame = pd.read_csv(out / "eplusout.csv")
    if first_day is not None:
        frame = run_period_rows(frame, first_day, (weeks + warmup_weeks) * cat.HOURS_PER_WEEK, out / "eplusout.csv")
    areas = zone_areas(out / "eplusout.eio")
    zones = [z for z in occupied if z.upper() in areas]
    temps, weights = [], []
    for zone in zones:
        col = [c for c in frame.columns if c.upper().startswith(f"{zone.upper()}:ZONE MEAN AIR TEMPERATURE [")]
        if col:
            temps.append(frame[col[0]].to_numpy(float))
            weights.append(areas[zone.upper()])
    if not temps:
        raise ReferenceBuildingError(f"{out}: no zone temperatures of the occupied zones {zones}")
    temperature = np.average(np.stack(temps), axis=0, weights=weights)

    def meter_kwh(meter: str) -> np.ndarray:  # a building without heating coils (or lights) simply adds nothing
        col = [c for c in frame.columns if c.upper().startswith(meter.upper() + " [")]
        return frame[col[0]].to_numpy(float) / 3.6e6 if col else np.zeros(len(frame))  # J -> kWh

    consumption = sum((meter_kwh(END_USE_METERS[use][0]) for use in end_uses), np.zeros(len(frame)))
    electricity = sum((meter_kwh(END_USE_METERS[use][0]) for use in electricity_end_uses), np.zeros(len(frame)))
    hvac = meter_kwh(END_USE_METERS["heating"][0]) + meter_kwh(END_USE_METERS["cooling"][0])
    hours = (weeks + warmup_weeks) * cat.HOURS_PER_WEEK
    if len(frame) != hours:
        raise ReferenceBuildingError(f"{out}/eplusout.csv: {len(frame)} hourly rows, expected {hours}")
    skip = warmup_weeks * cat.HOURS_PER_WEEK
    shape = (weeks, cat.HOURS_PER_WEEK)
    supply = [c for c in frame.columns if ":SYSTEM NODE TEMPERATURE [" in c.upper()]
    return ReferenceRun(
        temperature[skip:].reshape(shape),
        consumption[skip:].reshape(shape),
        float(sum(areas[z.upper()] for z in zones)),
        zones,
        hvac[skip:].reshape(shape),
        warmup_temperature_c=temperature[:skip].copy(),
        supply_air_c=frame[supply].to_numpy(float).mean(axis=1)[skip:].reshape(shape) if supply else None,
        electricity_kwh=electricity[skip:].reshape(shape) if electricity_end_uses else None,
    )


def recorded_supply_air(settings: np.ndarray, supply_air_c: np.ndarray) -> np.ndarray:
    """``settings`` ``(weeks, 7, 13)`` with ``supply_air_c`` replaced by what the building supplied: the mean of
    ``supply_air_c`` ``(weeks, 168)`` over each day's ventilation hours, on the catalogue's grid and range (a BMS
    trend of the supply air temperature, read as the day's setting)."""
    out = np.array(settings, float)
    var, j = cat.get("supply_air_c"), cat.SETTING_NAMES.index("supply_air_c")
    occupancy = np.zeros((len(out), len(cat.WEEKDAYS), len(cat.GROUPS["occupancy"])))
    on = hourly_schedules(out, occupancy)["ventilation_on"].reshape(len(out), 7, cat.HOURS_PER_DAY) > 0
    daily = np.asarray(supply_air_c, float).reshape(len(out), 7, cat.HOURS_PER_DAY)
    mean = np.where(on.any(-1), (daily * on).sum(-1) / np.maximum(on.sum(-1), 1), out[..., j])
    out[..., j] = var.snap(np.clip(mean, var.min, var.max))
    return out


def run_reference(
    building: str | Path,
    epw: str | Path,
    start: dt.date,
    settings: np.ndarray,
    warmup_weeks: int = 1,
    workdir: Path | None = None,
    schedule_map: ScheduleMap | None = None,
    effects: Sequence[tuple[str, float | None] | InjectedEffect] | None = None,
    effect_seed: int = 0,
    end_uses: Sequence[str] = cat.DEFAULT_END_USES,
    stand_in: int = STAND_IN_VERSION,
    electricity_end_uses: Sequence[str] = (),
    steady_day: dt.date | None = None,
) -> ReferenceRun:
    """Run a reference building for ``len(settings)`` measured weeks from ``start`` (a Monday).

    Args:
        building: a name of :data:`REFERENCE_BUILDINGS` or an IDF path.
        epw: weather short name or EPW path.
        start: Monday of the first measured week.
        settings: I_k per measured week ``(weeks, 7, 13)``; the warm-up weeks repeat the first week's.
        warmup_weeks: weeks simulated before ``start`` and discarded.
        workdir: where EnergyPlus runs (temporary if ``None``); its outputs are deleted afterwards.
        schedule_map: schedules to replace (detected from the model if ``None``).
        effects: unmodelled effects to inject, ``(name, magnitude or None for the default)`` pairs (see
            :mod:`buildenv.energyplus.injections`); the sensor effects act on the returned ``temperature_c`` (before
            noise), ``hvac_kwh`` and ``warmup_temperature_c`` stay true. Recorded in ``ReferenceRun.effects``.
        effect_seed: seed of the effects' random choices (holiday dates).
        end_uses: end uses the consumption sums (keys of :data:`END_USE_METERS`).
        electricity_end_uses: end uses a second meter sums (none: one meter).
        steady_day: the day whose level the equipment of 24/7 spaces holds (version 3; default the run's first
            day): a site's building runs again with its own, :func:`site_steady_day`.
        stand_in: the version of the stand-in's mapping (:data:`STAND_IN_VERSION`; a site's own, to run it again).
    Returns:
        the :class:`ReferenceRun` of the measured weeks (true readings, no noise).
    Raises:
        ReferenceBuildingError: ``start`` is not a Monday, the model lacks a schedule role or zones, or the
            ASHRAE 90.1 large office's data-centre coil fails (EnergyPlus, in cold periods): try a warmer one.
    """
    if start.weekday() != 0:
        raise ReferenceBuildingError(f"start {start} is a {start.strftime('%A')}; measured weeks start on a Monday")
    settings = np.asarray(settings, float)
    cat.check_values("settings", settings, "settings")
    source = reference_idf(building)
    full = np.concatenate([np.repeat(settings[:1], warmup_weeks, axis=0), settings])
    first_day = start - dt.timedelta(weeks=warmup_weeks)
    planned = plan_effects(effects, start, len(settings), effect_seed)
    with nullcontext(workdir) if workdir else workdirs.temporary_folder("ref") as tmp:
        work = Path(tmp)
        weather = resolve_epw(epw)
        idf, _ = prepare_model(
            source,
            full,
            first_day,
            work,
            schedule_map,
            effects=planned,
            epw=weather,
            stand_in=stand_in,
            steady_day=steady_day,
        )
        occupied = sorted({o[2] for o in of_type(read_idf(idf), "People")})
        try:
            # a simulated warm-up week sets the measured weeks' starting state, whatever EnergyPlus's warm-up days left
            limit = math.inf if warmup_weeks else WARMUP_TEMPERATURE_LIMIT_K
            run_energyplus(idf, weather, work, label=source.stem, warmup_limit_k=limit)
        except SimulationError as error:
            if "FindRootSimpleController" in str(error) and "DATACENTER" in str(error).upper():
                raise ReferenceBuildingError(_DATA_CENTRE_COIL_ERROR.format(source.stem)) from error
            raise
        result = read_sensors(work, occupied, len(settings), warmup_weeks, first_day, end_uses, electricity_end_uses)
        clean_outputs(work, keep=("eplusout.err",))
    result.temperature_c = sensor_effect_series(result.temperature_c, result.warmup_temperature_c, planned)
    result.effects = [e.truth() for e in planned]
    return result


def add_sensor_noise(run: ReferenceRun, seed: int) -> tuple[np.ndarray, ...]:
    """Measured series: ``(temperature_c, consumption_kwh)`` with seeded noise and meter resolution, and the second
    meter's ``electricity_kwh`` after them where the run has one (drawn last: the first two do not change)."""
    rng = np.random.default_rng(seed)
    t = run.temperature_c + rng.normal(0.0, TEMPERATURE_NOISE_K, run.temperature_c.shape)
    t = np.round(t / TEMPERATURE_RESOLUTION_K) * TEMPERATURE_RESOLUTION_K
    meters = [run.consumption_kwh] + ([] if run.electricity_kwh is None else [run.electricity_kwh])
    out = [t]
    for kwh in meters:
        q = kwh * (1.0 + rng.normal(0.0, CONSUMPTION_NOISE_FRACTION, kwh.shape))
        out.append(np.round(np.maximum(q, 0.0) / CONSUMPTION_RESOLUTION_KWH) * CONSUMPTION_RESOLUTION_KWH)
    return tuple(out)


def historical_settings(weeks: int, ventilation_ach: float | None = None) -> np.ndarray:
    """The default building's typical historical settings on every day, ``(weeks, 7, 13)``; ``ventilation_ach``
    (1/h) replaces the default ventilation (a reference building's: :func:`historical_ventilation_ach`)."""
    settings = default_week(weeks)[0]
    if ventilation_ach is not None:
        settings[..., cat.SETTING_NAMES.index("ventilation_ach")] = ventilation_ach
    return settings


def make_reference_site(
    out: str | Path,
    building: str | Path = "medium_office",
    epw: str | Path = "usa_il_chicago",
    start: dt.date = dt.date(2019, 11, 4),
    weeks: int = 4,
    settings: np.ndarray | None = None,
    seed: int = 0,
    floors: int | None = None,
    schedule_map: ScheduleMap | None = None,
    effects: Sequence[tuple[str, float | None] | InjectedEffect] | None = None,
    effect_seed: int = 0,
    known: dict[str, float] | None = None,
    end_uses: Sequence[str] = cat.DEFAULT_END_USES,
    record_supply_air: bool = True,
    electricity_end_uses: Sequence[str] = (),
) -> Path:
    """Run a reference building and write what its sensors read as a site folder (see :mod:`buildenv.sites`).

    Args:
        out: site folder to write.
        building: a name of :data:`REFERENCE_BUILDINGS` or an IDF path (then ``floors`` is required).
        epw: weather short name or EPW path.
        start: Monday of the first measured week.
        weeks: measured weeks.
        settings: I_k per week ``(weeks, 7, 13)``; default :func:`historical_settings` with the building's
            design ventilation (:func:`historical_ventilation_ach`).
        seed: seed of the sensor noise.
        floors: storeys (known geometry); taken from :data:`REFERENCE_BUILDINGS` for shipped buildings.
        schedule_map: schedules to replace (detected if ``None``).
        effects: unmodelled effects to inject, ``(name, magnitude or None for the default)`` pairs (see
            :mod:`buildenv.energyplus.injections`); written to ``truth.json`` as ``{"name", "magnitude", "unit",
            "details"}`` entries, never to ``site.toml`` (the diagnosis must find them blind).
        effect_seed: seed of the effects' random choices (holiday dates).
        known: building parameters the site declares known (``site.toml``'s ``[known]``, catalogue units):
            what the building's documents say, which calibration then keeps fixed.
        end_uses: end uses the consumption meter sums (keys of :data:`END_USE_METERS`), written as ``site.toml``'s
            ``[meters] consumption``.
        record_supply_air: write the supply air its central air loops delivered into the history
            (:func:`recorded_supply_air`); ``False`` keeps ``settings``' values.
        electricity_end_uses: end uses a second meter sums (``electricity_kwh``, ``[meters] electricity``), none
            of ``end_uses``; empty: one meter.

    The site's ``[bms]`` declares what the stand-in maps (:func:`reference_bms`).

    Raises:
        SiteError: ``end_uses`` is empty, repeats one or names one that is not an end use, or shares one with
            ``electricity_end_uses``.
        ReferenceBuildingError: as :func:`run_reference`.
    """
    from buildenv.errors import SiteError
    from buildenv.sites import write_site
    from buildenv.sites.reader import check_end_uses

    end_uses = check_end_uses(list(end_uses))
    electricity_end_uses = check_end_uses(list(electricity_end_uses)) if electricity_end_uses else ()
    twice = [use for use in electricity_end_uses if use in end_uses]
    if twice:
        raise SiteError(f"electricity_end_uses: {', '.join(twice)} also in end_uses: each end use on one meter")

    if floors is None:
        if str(building) not in REFERENCE_BUILDINGS:
            raise ReferenceBuildingError(f"{building}: give the number of floors of a user IDF (--floors)")
        floors = REFERENCE_BUILDINGS[str(building)][1]
    if settings is None:
        settings = historical_settings(weeks, historical_ventilation_ach(building))
    settings = np.asarray(settings, float)
    run = run_reference(
        building,
        epw,
        start,
        settings,
        schedule_map=schedule_map,
        effects=effects,
        effect_seed=effect_seed,
        end_uses=end_uses,
        electricity_end_uses=electricity_end_uses,
        warmup_weeks=SITE_WARMUP_WEEKS,
    )
    temperature, consumption, *electricity = add_sensor_noise(run, seed)
    if record_supply_air and run.supply_air_c is not None:  # what its BMS logs: its own, not mapped
        settings = recorded_supply_air(settings, run.supply_air_c)
    controllable, setting_limits = reference_bms(building)
    source = {
        "kind": "reference building stand-in",
        "building": str(building),
        "idf": reference_idf(building).name,
        "weather": str(epw),
        "seed": seed,
        "temperature_sensor": f"occupied-zone mean of {len(run.zones)} zones, noise {TEMPERATURE_NOISE_K} K, "
        f"resolution {TEMPERATURE_RESOLUTION_K} K",
        "consumption_meter": " + ".join(END_USE_METERS[use][1] for use in end_uses)
        + f", noise {CONSUMPTION_NOISE_FRACTION:.0%}, resolution {CONSUMPTION_RESOLUTION_KWH} kWh",
    }
    if electricity_end_uses:
        source["electricity_meter"] = " + ".join(END_USE_METERS[use][1] for use in electricity_end_uses)
    return write_site(
        out,
        name=f"{building} in {epw} (reference-building stand-in)",
        weather=str(epw),
        start=start,
        floor_area_m2=round(run.floor_area_m2, 1),
        number_of_floors=int(floors),
        settings=settings,
        temperature_c=temperature,
        consumption_kwh=consumption,
        source=source,
        truth={
            "building": str(building),
            "effects": run.effects,
            "stand_in": STAND_IN_VERSION,
            **({} if schedule_map is None else {"schedule_map": asdict(schedule_map)}),
        },
        known=known,
        consumption_end_uses=end_uses,
        controllable=controllable,
        setting_limits=setting_limits,
        electricity_kwh=electricity[0] if electricity else None,
        electricity_end_uses=electricity_end_uses,
    )
