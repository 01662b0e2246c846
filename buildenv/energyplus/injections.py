"""Injection side of the effects catalogue: put an unmodelled effect into the reference-building stand-in.

The stand-in (:mod:`buildenv.energyplus.reference`) is a DOE reference office run in EnergyPlus and read like two
sensors. Each effect of :mod:`buildenv.diagnosis.effects` is put into it at a ``magnitude`` (in the effect's
:attr:`~buildenv.diagnosis.effects.Effect.magnitude_unit`) in one of two ways:

- **EnergyPlus edits** (``kind="energyplus"``, :func:`inject_energyplus`, on the IDF objects after
  :func:`buildenv.energyplus.reference.prepare_model` has re-pointed the BMS schedules): ``wind_infiltration``
  raises the infiltration's wind velocity coefficient; ``holidays`` declares absent weekdays on which only the
  occupants' schedules take their Sunday values; ``night_plug_loads`` adds equipment on the complement of the
  occupancy schedule; ``solar_shading`` scales the windows' solar heat gain coefficient;
  ``heating_capacity_limit`` hard-sizes every heating coil and boiler to a share of its design capacity (from a
  sizing run); ``heat_recovery`` puts a sensible heat exchanger on every outdoor-air system;
  ``night_cycle_cold_air`` raises the VAV boxes' minimum air flow out of hours; ``evening_departure`` lengthens
  the evening tail of the occupants' schedules. Each editor's docstring gives the details; a model that lacks
  what an effect needs raises :class:`~buildenv.errors.ReferenceBuildingError`.
- **Sensor post-processing** (``kind="sensor"``, :func:`apply_sensor_effects`, on the noise-free hourly
  occupied-zone mean temperature, warm-up weeks included, before the sensor noise is added):
  ``temperature_sensor_bias`` adds ``magnitude`` K; ``temperature_sensor_lag`` is a first-order lag of time
  constant ``magnitude`` h (:func:`first_order_lag`, the model side's form), started on the first warm-up hour.

An effect at its :data:`~buildenv.diagnosis.effects.NO_EFFECT_MAGNITUDE` changes nothing: it is recorded in the
truth but not injected, so the run is bit-identical to one without it.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from buildenv.diagnosis.effects import NO_EFFECT_MAGNITUDE, Effect, EffectError, get_effect
from buildenv.energyplus.idf import IdfObject, of_type, without
from buildenv.errors import ReferenceBuildingError

WEEKDAYS_PER_WEEK = 5
HOURS_PER_WEEK = 168
NIGHT_PLUG_SUBCATEGORY = "NightPlugLoads"
_DAY_TOKENS = {"monday": ("monday", "weekdays", "alldays"), "sunday": ("sunday", "weekends", "alldays")}
_HOLIDAY_TOKENS = ("holiday", "holidays")


@dataclass(frozen=True)
class InjectedEffect:
    """An effect planned for injection: name, magnitude and the details fixed when planning.

    Attributes:
        name: effect name (a key of :data:`buildenv.diagnosis.effects.EFFECTS`).
        magnitude: injected magnitude, in the effect's ``magnitude_unit``.
        details: what the injection chose, JSON-ready: ``{"dates": [...]}`` for holidays (fixed when planning);
            ``heating_capacity_limit`` adds ``design_capacity_kw`` and ``available_capacity_kw`` when injected.
    """

    name: str
    magnitude: float
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def effect(self) -> Effect:
        """The catalogue entry."""
        return get_effect(self.name)

    @property
    def active(self) -> bool:
        """False at the effect's no-effect magnitude (then nothing is injected)."""
        return self.magnitude != NO_EFFECT_MAGNITUDE[self.name]

    def truth(self) -> dict[str, Any]:
        """The ``truth.json`` entry: ``{"name", "magnitude", "unit", "details"}``."""
        return {
            "name": self.name,
            "magnitude": self.magnitude,
            "unit": self.effect.magnitude_unit,
            "details": dict(self.details),
        }


def plan_effects(
    effects: Sequence[tuple[str | Effect, float | None] | InjectedEffect] | None,
    start: dt.date,
    weeks: int,
    seed: int = 0,
    fit_weeks: Sequence[int] | None = None,
) -> list[InjectedEffect]:
    """Check the requested effects and fix their random choices.

    Args:
        effects: ``(name or Effect, magnitude or None for the default)`` pairs, or already planned effects
            (passed through).
        start: Monday of the first measured week.
        weeks: number of measured weeks.
        seed: seed of the random choices (the holiday dates).
        fit_weeks: the weeks a diagnosis will fit (:func:`choose_holidays`; default: the first half).

    Returns:
        One :class:`InjectedEffect` per effect, in the order given. Raises :class:`EffectError` for an
        unknown effect, a magnitude outside :data:`buildenv.diagnosis.effects.INJECTION_LIMITS`, a repeated effect or
        more holidays than measured weekdays.
    """
    planned: list[InjectedEffect] = []
    for item in effects or ():
        if isinstance(item, InjectedEffect):
            get_effect(item.name).check_magnitude(item.magnitude)
            planned.append(item)
            continue
        name, magnitude = item
        effect = name if isinstance(name, Effect) else get_effect(str(name))
        value = effect.default_magnitude if magnitude is None else effect.check_magnitude(float(magnitude))
        details: dict[str, Any] = {}
        if effect.name == "holidays":
            details["dates"] = [
                d.isoformat() for d in choose_holidays(int(_whole(value, effect)), start, weeks, seed, fit_weeks)
            ]
        planned.append(InjectedEffect(effect.name, float(value), details))
    names = [p.name for p in planned]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise EffectError(f"effect {', '.join(repeated)} given more than once; give each effect once")
    return planned


def _whole(value: float, effect: Effect) -> float:
    if value != round(value):
        raise EffectError(f"effect {effect.name}: magnitude {value:g} is not a whole number of days")
    return value


def choose_holidays(
    count: int, start: dt.date, weeks: int, seed: int = 0, fit_weeks: Sequence[int] | None = None
) -> list[dt.date]:
    """``count`` distinct measured weekdays drawn with ``seed`` (sorted).

    With ``count >= 2`` and ``weeks >= 2`` one lies in the ``fit_weeks`` (default: the first ``ceil(weeks / 2)``
    weeks, the default calibration weeks) and one in the other weeks. Raises :class:`EffectError` if ``count``
    exceeds the ``5 x weeks`` measured weekdays.
    """
    days = [start + dt.timedelta(days=7 * w + d) for w in range(weeks) for d in range(WEEKDAYS_PER_WEEK)]
    if count > len(days):
        raise EffectError(
            f"effect holidays: {count} absent weekdays but only {len(days)} measured weekdays "
            f"in {weeks} week(s); give at most {len(days)}"
        )
    if count <= 0:
        return []
    rng = np.random.default_rng(seed)
    fit = set(range(math.ceil(weeks / 2)) if fit_weeks is None else fit_weeks)
    in_fit = [i for i in range(len(days)) if i // WEEKDAYS_PER_WEEK in fit]
    others = [i for i in range(len(days)) if i // WEEKDAYS_PER_WEEK not in fit]
    chosen: list[int] = []
    if count >= 2 and in_fit and others:
        chosen = [in_fit[int(rng.integers(len(in_fit)))], others[int(rng.integers(len(others)))]]
    rest = [i for i in range(len(days)) if i not in chosen]
    chosen += [int(i) for i in rng.choice(rest, size=count - len(chosen), replace=False)]
    return sorted(days[i] for i in chosen)


# --- EnergyPlus edits ------------------------------------------------------------------------------------------


def inject_energyplus(
    objects: list[IdfObject],
    effects: Sequence[InjectedEffect],
    building: str = "model",
    sizing: Callable[[list[IdfObject]], Path] | None = None,
) -> list[IdfObject]:
    """The IDF objects with every active ``kind="energyplus"`` effect injected (see the module docstring).

    Args:
        objects: IDF objects of a complete model (not modified; edited copies are returned).
        effects: planned effects; sensor effects and inactive ones are skipped.
        building: name used in error messages.
        sizing: runs the sizing of a model and returns its ``eplusout.eio`` (needed by
            ``heating_capacity_limit`` only; see :func:`sizing_objects`).

    Raises :class:`~buildenv.errors.ReferenceBuildingError` when the model lacks what an effect needs.
    """
    edits = {
        "wind_infiltration": _wind_infiltration,
        "holidays": _holidays,
        "night_plug_loads": _night_plug_loads,
        "solar_shading": _solar_shading,
        "heat_recovery": _heat_recovery,
        "night_cycle_cold_air": _night_cycle_cold_air,
        "evening_departure": _evening_departure,
    }
    out = [list(o) for o in objects]
    active = [e for e in effects if e.active and e.effect.kind == "energyplus"]
    for item in active:
        if item.name in edits:
            out = edits[item.name](out, item, building)
    for item in active:  # last: the design capacities are those of the model with the other effects
        if item.name == "heating_capacity_limit":
            if sizing is None:
                raise ReferenceBuildingError(
                    f"{building}: effect heating_capacity_limit needs a sizing run (pass sizing= to inject_energyplus)"
                )
            out = _heating_capacity_limit(out, item, building, sizing(sizing_objects(out)))
    return out


def sizing_objects(objects: list[IdfObject]) -> list[IdfObject]:
    """A copy of a model that only sizes (zone, system and plant sizing; neither design days nor the run period
    are simulated, components are still autosized) and writes nothing but ``eplusout.eio`` and ``eplusout.err``."""
    out = [list(o) for o in without(objects, kinds={"Output:Variable", "Output:Meter", "OutputControl:Files"})]
    sim = of_type(out, "SimulationControl")
    if not sim:
        out.insert(1, ["SimulationControl"])
        sim = of_type(out, "SimulationControl")
    sim[0][1:] = ["Yes", "Yes", "Yes", "No", "No"]
    out.append(["OutputControl:Files", "No", "No", "No", "Yes"] + ["No"] * 29)  # the EIO only
    return out


def _field(o: IdfObject, i: int) -> str:
    return o[i] if len(o) > i else ""


def _pad(o: IdfObject, n: int) -> IdfObject:
    return o + [""] * (n - len(o))


def _number(text: str, default: float) -> float:
    return float(text) if text.strip() else default


def _wind_infiltration(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Add ``magnitude / 100`` to the velocity coefficient ``C`` (field 11) of every
    ``ZoneInfiltration:DesignFlowRate``, ``I = I_design x F_schedule x (A + B |dT| + C v + D v^2)`` (v in m/s)."""
    added = item.magnitude / 100.0
    found = 0
    for k, o in enumerate(objects):
        if o[0].lower() == "zoneinfiltration:designflowrate":
            o = _pad(o, 13)
            o[11] = f"{_number(o[11], 0.0) + added:.6g}"  # Velocity Term Coefficient (1/(m/s))
            objects[k] = o
            found += 1
    if not found:
        raise ReferenceBuildingError(
            f"{building}: effect wind_infiltration needs ZoneInfiltration:DesignFlowRate objects and the model has none"
        )
    return objects


def _for_tokens(text: str) -> list[str]:
    return text.split(":", 1)[1].split()


def assign_holidays(schedule: IdfObject, like: str) -> IdfObject:
    """A ``Schedule:Compact`` whose Holiday day type takes the values of ``like`` (``monday`` or ``sunday``).

    In every ``Through:`` period, ``Holiday`` is removed from the ``For:`` clauses that name it (a clause left
    with no day type is dropped with its values) and added to the clause that covers ``like`` (``Monday`` /
    ``Weekdays`` / ``AllDays`` for monday, ``Sunday`` / ``Weekends`` / ``AllDays`` for sunday, else
    ``AllOtherDays``).
    """
    fields = list(schedule)
    bounds = [i for i, f in enumerate(fields) if f.lower().startswith("through:")] + [len(fields)]
    out = fields[: bounds[0]]
    for a, b in zip(bounds[:-1], bounds[1:]):
        starts = [i for i in range(a, b) if fields[i].lower().startswith("for:")]
        clauses = [(fields[i], fields[i + 1 : j]) for i, j in zip(starts, starts[1:] + [b])]
        tokens = [_for_tokens(head) for head, _ in clauses]
        lower = [[t.lower() for t in ts] for ts in tokens]
        target = next((k for k, ts in enumerate(lower) if any(t in _DAY_TOKENS[like] for t in ts)), None)
        if target is None:
            target = next((k for k, ts in enumerate(lower) if "allotherdays" in ts), None)
        out += fields[a : (starts[0] if starts else b)]
        for k, (_, body) in enumerate(clauses):
            kept = [t for t in tokens[k] if t.lower() not in _HOLIDAY_TOKENS]
            if k == target and "alldays" not in lower[k]:
                kept.append("Holiday")
            if kept:
                out += ["For: " + " ".join(kept), *body]
    return out


def _schedule_names(objects: list[IdfObject], kinds: tuple[str, ...]) -> set[str]:
    return {_field(o, 3).lower() for kind in kinds for o in of_type(objects, kind) if _field(o, 3)}


def _holidays(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Declare the planned dates as ``RunPeriodControl:SpecialDays`` of type ``Holiday``: the occupants' schedules
    (``People``, ``Lights``, ``ElectricEquipment``) take their Sunday values, every other ``Schedule:Compact`` its
    Monday values; the BMS's ``Schedule:File`` schedules ignore day types."""
    occupant = _schedule_names(objects, ("People", "Lights", "ElectricEquipment"))
    out = []
    for o in without(objects, kinds={"RunPeriodControl:SpecialDays"}):
        if o[0].lower() == "schedule:compact":
            o = assign_holidays(o, "sunday" if o[1].lower() in occupant else "monday")
        out.append(o)
    for text in item.details.get("dates", []):
        day = dt.date.fromisoformat(text)
        out.append(
            [
                "RunPeriodControl:SpecialDays",
                f"buildenv absent {day.isoformat()}",
                f"{day.month}/{day.day}",
                "1",
                "Holiday",
            ]
        )
    return out


def complement_schedule(schedule: IdfObject, name: str) -> IdfObject:
    """A ``Schedule:Compact`` copy named ``name`` with every value ``v`` replaced by ``1 - v`` (clipped to 0..1)."""
    if schedule[0].lower() != "schedule:compact":
        raise ReferenceBuildingError(
            f"schedule {schedule[1]} is a {schedule[0]}; only Schedule:Compact can be complemented"
        )
    out = ["Schedule:Compact", name, schedule[2]]
    for prev, f in zip(schedule[2:], schedule[3:]):
        if prev.lower().startswith("until:"):
            f = f"{min(1.0, max(0.0, 1.0 - float(f))):.6g}"
        out.append(f)
    return out


def _night_plug_loads(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """One extra ``ElectricEquipment`` of ``magnitude`` W/m2 per ``People`` object (radiant fraction 0.5, end use
    :data:`NIGHT_PLUG_SUBCATEGORY`, metered with the interior equipment) on ``1 - occupancy fraction``: the full
    load at night, on weekends and holidays."""
    people = of_type(objects, "People")
    if not people:
        raise ReferenceBuildingError(f"{building}: effect night_plug_loads needs People objects (occupied zones)")
    schedules = {o[1].lower(): o for o in objects if o[0].lower().startswith("schedule:")}
    added: dict[str, str] = {}  # occupancy schedule (lower) -> its complement's name
    new: list[IdfObject] = []
    for p in people:
        occupancy = p[3]
        if occupancy.lower() not in added:
            if occupancy.lower() not in schedules:
                raise ReferenceBuildingError(f"{building}: People {p[1]} uses schedule {occupancy}, not defined")
            added[occupancy.lower()] = f"buildenv night plug loads {len(added) + 1}"
            try:
                new.append(complement_schedule(schedules[occupancy.lower()], added[occupancy.lower()]))
            except ReferenceBuildingError as exc:
                raise ReferenceBuildingError(f"{building}: effect night_plug_loads: {exc}") from None
        new.append(
            [
                "ElectricEquipment",
                f"{p[1]} buildenv night plug loads",
                p[2],
                added[occupancy.lower()],
                "Watts/Area",
                "",
                f"{item.magnitude:.6g}",
                "",
                "0",
                "0.5",
                "0",
                NIGHT_PLUG_SUBCATEGORY,
            ]
        )
    return objects + new


def _hours_of(text: str) -> int:
    """The whole hour of an ``Until: HH:MM`` field; raises :class:`ReferenceBuildingError` otherwise."""
    clock = text.split(":", 1)[1].strip()
    hours, _, minutes = clock.partition(":")
    if not hours.strip().isdigit() or minutes.strip() not in ("00", "0", ""):
        raise ReferenceBuildingError(f"'{text}' is not on a whole hour")
    return int(hours)


def _weekday_clauses(schedule: IdfObject) -> list[int]:
    """Indices of the ``For:`` fields naming ``Weekdays`` or ``AllDays``."""
    return [
        i
        for i, f in enumerate(schedule)
        if f.lower().startswith("for:") and {t.lower() for t in _for_tokens(f)} & {"weekdays", "alldays"}
    ]


def weekday_profile(schedule: IdfObject) -> tuple[int, int, np.ndarray]:
    """The weekday clause of a ``Schedule:Compact``: ``(first, end)`` indices of its ``Until:``/value fields and
    its 24 hourly values. The clause is the first ``For:`` naming ``Weekdays`` (or ``AllDays``); its times must
    be whole hours and it must not interpolate. Raises :class:`ReferenceBuildingError` otherwise."""
    name = f"schedule {_field(schedule, 1)}"
    if schedule[0].lower() != "schedule:compact":
        raise ReferenceBuildingError(f"{name} is a {schedule[0]}; only Schedule:Compact weekdays can be edited")
    heads = _weekday_clauses(schedule)
    if not heads:
        raise ReferenceBuildingError(f"{name} has no For: Weekdays clause")
    first = j = heads[0] + 1
    values, hour = np.zeros(24), 0
    while j + 1 < len(schedule) and schedule[j].lower().startswith("until:"):
        until = _hours_of(schedule[j])
        values[hour:until] = float(schedule[j + 1])
        hour, j = until, j + 2
    if first < len(schedule) and schedule[first].lower().startswith("interpolate:"):
        raise ReferenceBuildingError(f"{name} interpolates its weekday values")
    if hour != 24:
        raise ReferenceBuildingError(f"{name}: its weekday clause does not run to 24:00")
    return first, j, values


def _evening_departure(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Every weekday clause of the occupants' ``Schedule:Compact`` schedules keeps its first evening value
    ``magnitude`` (rounded) hours longer after the first ``People`` schedule's last half-occupied weekday hour,
    and the rest of its evening moves that much later (midnight cuts it); other schedules are left alone."""
    people = of_type(objects, "People")
    if not people:
        raise ReferenceBuildingError(f"{building}: effect evening_departure needs People objects (occupied zones)")
    schedules = {o[1].lower(): o for o in objects if o[0].lower() == "schedule:compact"}
    occupancy = _field(people[0], 3).lower()
    try:
        if occupancy not in schedules:
            raise ReferenceBuildingError(
                f"People {people[0][1]} uses schedule {people[0][3]}, not a Schedule:Compact of the model"
            )
        occupied = np.nonzero(weekday_profile(schedules[occupancy])[2] >= 0.5)[0]
        if not len(occupied):
            raise ReferenceBuildingError(f"schedule {people[0][3]} is never half occupied on weekdays")
        end, k = int(occupied[-1]) + 1, int(round(item.magnitude))
        for name in sorted(_schedule_names(objects, ("People", "Lights", "ElectricEquipment"))):
            o = schedules.get(name)
            if o is None or not _weekday_clauses(o):
                continue  # not a Schedule:Compact, or not by weekday (a data centre's load, say): left alone
            first, stop, values = weekday_profile(o)
            later = values.copy()
            hours = np.arange(end, 24)
            later[end:] = values[np.maximum(end, hours - k)]
            pairs = [
                f
                for h in range(24)
                if h == 23 or later[h + 1] != later[h]
                for f in (f"Until: {h + 1:02d}:00", f"{later[h]:.6g}")
            ]
            o[first:stop] = pairs  # edited in place: the objects are copies
    except ReferenceBuildingError as exc:
        raise ReferenceBuildingError(f"{building}: effect evening_departure: {exc}") from None
    return objects


def _solar_shading(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Multiply the solar heat gain coefficient of every ``WindowMaterial:SimpleGlazingSystem`` by ``1 - magnitude
    / 100`` (U-factor kept: a blind drawn all the time); layered glazing raises."""
    keep = 1.0 - item.magnitude / 100.0
    glazings = of_type(objects, "WindowMaterial:SimpleGlazingSystem")
    if not glazings or of_type(objects, "WindowMaterial:Glazing"):
        raise ReferenceBuildingError(
            f"{building}: effect solar_shading scales the SHGC of "
            "WindowMaterial:SimpleGlazingSystem windows; this model has layered glazing"
        )
    for o in glazings:
        o[3] = f"{float(o[3]) * keep:.6g}"  # Solar Heat Gain Coefficient (edited in place: copies made above)
    return objects


#: The schedule of the BMS's HVAC availability (1 in the union of the heating, cooling and ventilation periods),
#: written by :func:`buildenv.energyplus.reference.prepare_model`; ``night_cycle_cold_air`` acts outside it.
HVAC_AVAILABILITY_SCHEDULE = "buildenv_hvac_availability"


def _night_cycle_cold_air(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Give every ``AirTerminal:SingleDuct:VAV:Reheat`` with a constant minimum air flow fraction a scheduled
    one, set by an EMS program: its design fraction while :data:`HVAC_AVAILABILITY_SCHEDULE` is on, the design +
    ``magnitude / 100`` (at most 1) outside it, so the night cycle sends more cold supply air to every zone."""
    terminals = [o for o in of_type(objects, "AirTerminal:SingleDuct:VAV:Reheat") if _field(o, 6).lower() == "constant"]
    if not terminals:
        raise ReferenceBuildingError(
            f"{building}: effect night_cycle_cold_air raises the night minimum air flow of "
            "AirTerminal:SingleDuct:VAV:Reheat boxes with a constant minimum; this model "
            "has none"
        )
    added = item.magnitude / 100.0
    schedules: dict[str, str] = {}  # design fraction -> its schedule
    for o in terminals:
        design = _field(o, 7) or "0.3"  # EnergyPlus's default constant minimum air flow fraction
        name = schedules.setdefault(design, f"buildenv night minimum flow {len(schedules) + 1}")
        o.extend([""] * (10 - len(o)))
        o[6], o[9] = "Scheduled", name  # edited in place: the objects are copies
    new: list[IdfObject] = [
        ["EnergyManagementSystem:Sensor", "buildenv_hvac_on", HVAC_AVAILABILITY_SCHEDULE, "Schedule Value"]
    ]
    program = ["EnergyManagementSystem:Program", "buildenv_night_minimum_flow", "IF buildenv_hvac_on > 0.5"]
    night = []
    for j, (design, name) in enumerate(schedules.items()):
        new += [
            ["Schedule:Constant", name, "", design],
            [
                "EnergyManagementSystem:Actuator",
                f"buildenv_minimum_flow_{j}",
                name,
                "Schedule:Constant",
                "Schedule Value",
            ],
        ]
        program.append(f"SET buildenv_minimum_flow_{j} = {design}")
        night.append(f"SET buildenv_minimum_flow_{j} = {min(1.0, float(design) + added):.6g}")
    new += [
        program + ["ELSE", *night, "ENDIF"],
        [
            "EnergyManagementSystem:ProgramCallingManager",
            "buildenv night minimum flow",
            "BeginTimestepBeforePredictor",
            "buildenv_night_minimum_flow",
        ],
    ]
    return objects + new


#: Heating components whose capacity the capacity limit scales: type (lower case) -> capacity field index.
HEATING_CAPACITY_FIELDS: dict[str, int] = {
    "coil:heating:electric": 4,
    "coil:heating:fuel": 5,
    "coil:heating:dx:singlespeed": 3,
    "boiler:hotwater": 3,
}


def design_capacities(eio: Path) -> dict[tuple[str, str], float]:
    """``{(component type lower, NAME upper): design capacity W}`` of the heating components of
    :data:`HEATING_CAPACITY_FIELDS` from the ``Component Sizing Information`` lines of ``eplusout.eio``."""
    found: dict[tuple[str, str], float] = {}
    for line in Path(eio).read_text(errors="replace").splitlines():
        f = [x.strip() for x in line.split(",")]
        if (
            len(f) >= 5
            and f[0] == "Component Sizing Information"
            and f[1].lower() in HEATING_CAPACITY_FIELDS
            and f[3].startswith("Design Size")
            and "Capacity [W]" in f[3]
        ):
            found[(f[1].lower(), f[2].upper())] = float(f[4])
    return found


def _heating_capacity_limit(
    objects: list[IdfObject], item: InjectedEffect, building: str, eio: Path
) -> list[IdfObject]:
    """Hard-size every heating component of :data:`HEATING_CAPACITY_FIELDS` to ``magnitude / 100`` of its design
    capacity (autosized ones read from the sizing run's ``eio``); records the design and available kW in the
    effect's details. Air flows and every other size are unchanged."""
    share = item.magnitude / 100.0
    sized = design_capacities(eio)
    total = limited = 0.0
    for o in objects:
        i = HEATING_CAPACITY_FIELDS.get(o[0].lower())
        if i is None:
            continue
        value = _field(o, i).strip()
        if not value or value.lower() in ("autosize", "autocalculate"):
            key = (o[0].lower(), o[1].upper())
            if key not in sized:
                raise ReferenceBuildingError(
                    f"{building}: effect heating_capacity_limit: no design capacity of "
                    f"{o[0]} {o[1]} in the sizing run's {eio}"
                )
            design = sized[key]
        else:
            design = float(value)
        o[i] = f"{design * share:.6g}"
        total, limited = total + design, limited + design * share
    if total <= 0.0:
        raise ReferenceBuildingError(
            f"{building}: effect heating_capacity_limit: no heating coil or boiler of "
            f"the types {', '.join(HEATING_CAPACITY_FIELDS)}"
        )
    item.details.update(
        {"design_capacity_kw": round(total / 1000.0, 1), "available_capacity_kw": round(limited / 1000.0, 1)}
    )
    return objects


def _heat_recovery(objects: list[IdfObject], item: InjectedEffect, building: str) -> list[IdfObject]:
    """Put a sensible plate ``HeatExchanger:AirToAir:SensibleAndLatent`` (effectiveness ``magnitude / 100``) on
    every outdoor-air system's outdoor-air stream, upstream of its ``OutdoorAir:Mixer``; with a mixed-air setpoint
    a ``SetpointManager:OutdoorAirPretreat`` controls its outlet and the economizer does not lock it out."""
    systems = of_type(objects, "AirLoopHVAC:OutdoorAirSystem")
    if not systems:
        raise ReferenceBuildingError(
            f"{building}: effect heat_recovery needs an AirLoopHVAC:OutdoorAirSystem "
            "(an air handling unit with outdoor air); the model has none"
        )
    lists = {o[1].lower(): o for o in of_type(objects, "AirLoopHVAC:OutdoorAirSystem:EquipmentList")}
    mixers = {o[1].lower(): o for o in of_type(objects, "OutdoorAir:Mixer")}
    setpoint_nodes = {o[-1].lower() for o in objects if o[0].lower().startswith("setpointmanager:")}
    eff = f"{item.magnitude / 100.0:.6g}"
    new: list[IdfObject] = []
    for system in systems:
        equipment = lists.get(_field(system, 3).lower())
        kinds = [t.lower() for t in equipment[2::2]] if equipment else []
        if not equipment or kinds.count("outdoorair:mixer") != 1 or any(k.startswith("heatexchanger:") for k in kinds):
            raise ReferenceBuildingError(
                f"{building}: effect heat_recovery: outdoor-air system {system[1]} must "
                "have one OutdoorAir:Mixer and no heat exchanger to add one"
            )
        mixer = mixers[equipment[2 + 2 * kinds.index("outdoorair:mixer") + 1].lower()]
        mixed, outdoor, relief, ret = mixer[2:6]
        hx, supply_out, exhaust_out = (
            f"{system[1]} buildenv heat recovery",
            f"{system[1]} buildenv HX supply outlet",
            f"{system[1]} buildenv HX exhaust outlet",
        )
        control = "Yes" if mixed.lower() in setpoint_nodes else "No"
        lockout = "No" if control == "Yes" else "Yes"  # the outlet control already stops it overheating
        new.append(
            [
                "HeatExchanger:AirToAir:SensibleAndLatent",
                hx,
                "",
                "Autosize",
                eff,
                "0",
                eff,
                "0",
                outdoor,
                supply_out,
                relief,
                exhaust_out,
                "0",
                control,
                "Plate",
                "None",
                "1.7",
                "0.083",
                "0.012",
                lockout,
            ]
        )
        if control == "Yes":
            new.append(
                [
                    "SetpointManager:OutdoorAirPretreat",
                    f"{hx} outlet temperature",
                    "Temperature",
                    "-99",
                    "99",
                    "0.00001",
                    "1.0",
                    mixed,
                    mixed,
                    outdoor,
                    ret,
                    supply_out,
                ]
            )
        equipment[2:2] = ["HeatExchanger:AirToAir:SensibleAndLatent", hx]
        mixer[3] = supply_out  # the mixer now draws the preheated outdoor air
    return objects + new


# --- sensor post-processing -------------------------------------------------------------------------------------


def first_order_lag(x: np.ndarray, tau_h: float) -> np.ndarray:
    """Discrete first-order lag of hourly values ``x`` ``(hours,)``, time constant ``tau_h`` (h), from ``y_0 = x_0``.

    ``y_t = y_{t-1} + (1 - exp(-1 / tau_h)) (x_t - y_{t-1})``; ``tau_h = 0`` returns ``x`` unchanged.
    """
    x = np.asarray(x, float)
    if tau_h <= 0.0 or x.size == 0:
        return x.copy()
    alpha = 1.0 - math.exp(-1.0 / tau_h)
    y = np.empty_like(x)
    y[0] = x[0]
    for t in range(1, len(x)):
        y[t] = y[t - 1] + alpha * (x[t] - y[t - 1])
    return y


def apply_sensor_effects(temperature_c: np.ndarray, effects: Sequence[InjectedEffect]) -> np.ndarray:
    """What the temperature sensor reads: the true hourly temperature ``(hours,)`` (degC, warm-up hours first)
    with the active ``kind="sensor"`` effects applied (lag, then bias; see the module docstring)."""
    reading = np.asarray(temperature_c, float)
    by_name = {e.name: e for e in effects if e.active and e.effect.kind == "sensor"}
    if "temperature_sensor_lag" in by_name:
        reading = first_order_lag(reading, by_name["temperature_sensor_lag"].magnitude)
    if "temperature_sensor_bias" in by_name:
        reading = reading + by_name["temperature_sensor_bias"].magnitude
    return reading


def sensor_effect_series(
    temperature_c: np.ndarray, warmup_c: np.ndarray | None, effects: Sequence[InjectedEffect]
) -> np.ndarray:
    """:func:`apply_sensor_effects` over the warm-up hours ``(warmup_hours,)`` then the measured
    ``(weeks, 168)`` temperatures; returns the measured part ``(weeks, 168)`` (a copy)."""
    if not any(e.active and e.effect.kind == "sensor" for e in effects):
        return temperature_c
    warm = np.zeros(0) if warmup_c is None else np.asarray(warmup_c, float).reshape(-1)
    full = apply_sensor_effects(np.concatenate([warm, np.asarray(temperature_c, float).reshape(-1)]), effects)
    return full[len(warm) :].reshape(np.shape(temperature_c))
