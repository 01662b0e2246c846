"""Values of an EnergyPlus ``Schedule:Compact`` over the days of a year.

A compact schedule is a list of ``Through: MM/DD`` periods, each with ``For: <day types>`` clauses of
``Until: HH:MM, value`` pairs. :func:`daily_means` gives each day's time-weighted mean (ordinary days: the
weekday's clause; design days and holidays are not evaluated); :func:`steady_copy` holds one value on ordinary days.
``Interpolate:`` fields are accepted and read as steps (the value holds until its ``Until:`` time).
"""

from __future__ import annotations

import datetime as dt
import re

import numpy as np

from buildenv.errors import ReferenceBuildingError

from .idf import IdfObject

_KEYWORD = re.compile(r"^(through|for|until|interpolate)\b\s*:?\s*(.*)$", re.IGNORECASE)
_DESIGN_DAYS = {"summerdesignday", "winterdesignday"}
_WEEKDAY_TYPES = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")


def _day_types(weekday: int) -> set[str]:
    """The ``For:`` keywords a day of ``weekday`` (0 Monday) matches, ``AllOtherDays`` aside."""
    name = _WEEKDAY_TYPES[weekday]
    return {name, "alldays", "weekdays" if weekday < 5 else "weekends"}


def _periods(schedule: IdfObject) -> list[tuple[tuple[int, int], list[tuple[list[str], list[tuple[float, float]]]]]]:
    """``[((month, day) the period ends, [(day types, [(until hour, value)])])]`` of a compact schedule."""
    periods: list = []
    for raw in schedule[3:]:
        field = raw.strip()
        keyword = _KEYWORD.match(field)
        kind, rest = (keyword.group(1).lower(), keyword.group(2).strip()) if keyword else ("", field)
        if kind == "interpolate" or not field:
            continue
        try:
            if kind == "through":
                month, day = (int(p) for p in rest.split("/"))
                periods.append(((month, day), []))
            elif kind == "for":
                periods[-1][1].append((rest.lower().split(), []))
            elif kind == "until":
                hours, minutes = (int(p) for p in rest.split(":"))
                periods[-1][1][-1][1].append([hours + minutes / 60.0, np.nan])
            else:
                periods[-1][1][-1][1][-1][1] = float(field)
        except (IndexError, ValueError) as error:  # a malformed field, or one before what it belongs to
            raise ReferenceBuildingError(f"Schedule:Compact {schedule[1]}: cannot read the field '{field}'") from error
    return periods


def daily_means(schedule: IdfObject, year: int) -> np.ndarray:
    """Time-weighted mean of each day of ``year`` (``(days,)``, a day a row) under a ``Schedule:Compact``.

    Raises:
        ReferenceBuildingError: the schedule is not compact, cannot be read, or leaves a day undefined.
    """
    if schedule[0].lower() != "schedule:compact":
        raise ReferenceBuildingError(f"{schedule[1]} is a {schedule[0]}; only a Schedule:Compact can be evaluated")
    periods = _periods(schedule)
    day, out = dt.date(year, 1, 1), []
    while day.year == year:
        period = next((p for (m, d), p in periods if (day.month, day.day) <= (m, d)), None)
        clause = None
        for types, pieces in period or []:
            if _day_types(day.weekday()) & set(types) or "allotherdays" in types:
                clause = pieces
                break
        if not clause or any(np.isnan(v) for _, v in clause):
            raise ReferenceBuildingError(f"Schedule:Compact {schedule[1]} gives no value for {day:%d %B}")
        starts = [0.0] + [until for until, _ in clause[:-1]]
        out.append(sum((until - start) * value for start, (until, value) in zip(starts, clause)) / 24.0)
        day += dt.timedelta(days=1)
    return np.array(out)


def steady_copy(schedule: IdfObject, name: str, value: float) -> IdfObject:
    """A ``Schedule:Compact`` named ``name`` that holds ``value`` on every ordinary day of the year and keeps the
    design days of ``schedule``'s first period (what the model is sized with)."""
    fields, kept = ["Through: 12/31"], set()
    for types, pieces in _periods(schedule)[0][1]:
        design = [t for t in types if t in _DESIGN_DAYS and t not in kept]
        if design:
            kept |= set(design)
            fields.append("For: " + " ".join(design))
            for until, level in pieces:
                fields += [f"Until: {int(until):02d}:{round(until % 1 * 60):02d}", f"{level:g}"]
    return ["Schedule:Compact", name, schedule[2], *fields, "For: AllOtherDays", "Until: 24:00", f"{value:.4f}"]
