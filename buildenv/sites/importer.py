"""Importing a raw BMS export as a site folder (``buildenv site import``).

A BMS export is a CSV file with a timestamp column, an indoor temperature column and one or more consumption
columns: often sub-hourly, on a local clock that keeps daylight saving, stamped at the end of each interval, in degF
or K, in Wh, MWh or GJ (or power in kW), or as meter register readings. :func:`import_export` finds the columns
(:func:`_columns`: named by :class:`ImportOptions` or guessed from the header when only one fits), converts each
timestamp to local standard time (:func:`_standard_stamps`, with the site reader's checks and hints of
:mod:`buildenv.sites.timestamps`) and each value to degC, kWh or kW (:func:`_series`),
resamples to hours (:func:`_hourly`: temperature and power the mean of the hour's readings, energy the sum of its
intervals, missing unless every interval is there) and writes whole weeks with
:func:`buildenv.sites.writer.write_site`, which writes atomically and loads the result back: a failed import leaves
no folder. Every problem it cannot fix raises :class:`~buildenv.errors.SiteError` as ``"<export>:<line>: <what is
wrong>; <what to do>"`` (line 1 is the header); hours without a value stay gaps and :attr:`ImportReport.notes`
names the first.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import difflib
import os
import re
import zoneinfo
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.sites.cells import _parse_value, _rows
from buildenv.sites.consumption import _check_not_a_register, _check_size, _register_differences
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.model import TEMPERATURE_RANGE_C
from buildenv.sites.reader import _read_settings
from buildenv.sites.timestamps import (
    _epw_location,
    _fmt,
    _offset_mismatch_error,
    _parse_timestamp,
    _standard_times,
    _ZoneWording,
    named_time_zone,
)

#: Longest temperature gap, hours, that ``fill_temperature_gaps`` interpolates.
MAX_FILLED_GAP_HOURS = 2


@dataclass(frozen=True)
class _Unit:
    """A column's unit: ``kind`` (temperature, energy or power) and ``value_in_si = (value + offset) * factor``
    with degC, kWh and kW as the target units."""

    name: str
    kind: str
    factor: float
    offset: float = 0.0


_UNITS = {
    u.name.lower(): u
    for u in (
        _Unit("degC", "temperature", 1.0),
        _Unit("degF", "temperature", 1 / 1.8, -32.0),
        _Unit("K", "temperature", 1.0, -273.15),
        _Unit("Wh", "energy", 1e-3),
        _Unit("kWh", "energy", 1.0),
        _Unit("MWh", "energy", 1e3),
        _Unit("MJ", "energy", 1 / 3.6),
        _Unit("GJ", "energy", 1000 / 3.6),
        _Unit("W", "power", 1e-3),
        _Unit("kW", "power", 1.0),
        _Unit("MW", "power", 1e3),
    )
}
_ALIASES = {"c": "degc", "°c": "degc", "celsius": "degc", "f": "degf", "°f": "degf", "fahrenheit": "degf"}
_ALIASES |= {"kelvin": "k", "degk": "k"}


@dataclass(frozen=True)
class ImportOptions:
    """How to read a BMS export; the flags of ``buildenv site import``, one to one.

    Attributes:
        time_column, temperature_column: header names; None guesses the one column whose name holds
            ``time``/``date``/``stamp`` (``temp``).
        consumption_columns: header names, summed; empty guesses every other column whose name holds an energy or
            power unit (the electricity columns aside).
        electricity_columns: header names of a second meter (heat and electricity metered apart), summed into
            the site's ``electricity_kwh``; empty: one meter.
        units: ``{column: unit}`` (degC, degF, K; Wh, kWh, MWh, MJ, GJ; W, kW, MW) where the name does not say it.
        time_format: a ``strptime`` format of the timestamps; None reads ``YYYY-MM-DD HH:MM[:SS]`` (``T`` or
            ``/`` allowed, ``24:00`` read as the next day's 00:00 where ``stamped="end"``). With ``%z`` the
            timestamps' UTC offsets give their time, converted to the weather file's standard time.
        time_zone: the IANA zone whose clock (daylight saving included) the export keeps, its standard time the
            weather file's; None: standard time (or UTC offsets in the timestamps).
        stamped: ``"start"`` or ``"end"`` of the interval a row covers.
        cumulative: the energy columns hold meter register readings.
        fill_temperature_gaps: interpolate temperature gaps of at most :data:`MAX_FILLED_GAP_HOURS` hours.
    """

    time_column: str | None = None
    temperature_column: str | None = None
    consumption_columns: tuple[str, ...] = ()
    electricity_columns: tuple[str, ...] = ()
    units: Mapping[str, str] = field(default_factory=dict)
    time_format: str | None = None
    time_zone: str | None = None
    stamped: str = "start"
    cumulative: bool = False
    fill_temperature_gaps: bool = False


@dataclass
class ImportReport:
    """What :func:`import_export` wrote: the site, its weeks, the columns read (with their units), the hours
    missing within the measured span (and the first of them, local standard time), and notes for the user."""

    site: str
    start: str
    weeks: int
    interval_minutes: int
    columns: dict[str, str]
    missing_temperature_hours: int
    missing_consumption_hours: int
    filled_temperature_hours: int
    settings: str
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def parse_unit(path: Path | str, column: str, text: str) -> _Unit:
    """The unit ``text`` (case-insensitive) given for ``column``; SiteError naming the known units otherwise."""
    unit = _UNITS.get(_ALIASES.get(text.strip().lower(), text.strip().lower()))
    if unit is None:
        known = ", ".join(u.name for u in _UNITS.values())
        raise SiteError(f"{path}: unit {text!r} of column {column!r} is not one of {known}")
    return unit


def _unit_in_name(name: str, kinds: tuple[str, ...]) -> _Unit | None:
    """The last word of a column name that is a unit of one of ``kinds`` (``Temp (°F)``, ``heat_meter_wh``)."""
    found = None
    for word in re.findall(r"°?[a-z]+", name.lower()):
        unit = _UNITS.get(_ALIASES.get(word, word))
        if unit is not None and unit.kind in kinds:
            found = unit
    return found


def _pick(path: Path, header: list[str], given: str | None, words: str, flag: str, taken: set[int]) -> int:
    """Index of the column named ``given``, or of the one column (not ``taken``) whose name matches ``words``."""
    listing = ", ".join(repr(h) for h in header)
    if given is not None:
        if given in header:
            return header.index(given)
        close = difflib.get_close_matches(given, header, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise SiteError(f"{path}:1: no column {given!r}{hint}: give {flag} one of {listing}")
    found = [i for i, h in enumerate(header) if i not in taken and re.search(words, h.lower())]
    if len(found) != 1:
        which = "no column" if not found else "columns " + ", ".join(repr(header[i]) for i in found)
        raise SiteError(f"{path}:1: cannot tell which column to use ({which} fits): give {flag} one of {listing}")
    return found[0]


def _unit_of(path: Path, name: str, units: Mapping[str, str], kinds: tuple[str, ...]) -> _Unit | None:
    """The unit of column ``name``: given in ``units``, else the last unit of ``kinds`` its name holds."""
    return parse_unit(path, name, units[name]) if name in units else _unit_in_name(name, kinds)


def _columns(path: Path, header: list[str], options: ImportOptions) -> list[tuple[int, str, _Unit | None]]:
    """``[(index, name, unit)]`` of the timestamp (unit None), temperature, consumption and electricity columns."""
    for name in options.units:
        _pick(path, header, name, "", "--unit", set())  # a unit for a column the export does not have
    time = _pick(path, header, options.time_column, "time|date|stamp", "--time-column", set())
    temp = _pick(path, header, options.temperature_column, "temp", "--temperature-column", {time})
    energy = ("energy", "power")
    chosen = [_pick(path, header, name, "", "--consumption-column", set()) for name in options.consumption_columns]
    second = [_pick(path, header, name, "", "--electricity-column", set()) for name in options.electricity_columns]
    both = [header[i] for i in second if i in chosen]
    if both:
        raise SiteError(f"{path}:1: column {both[0]!r} given to both meters: name each column once")
    if not chosen:
        for i, name in enumerate(header):
            unit = _unit_of(path, name, options.units, energy)
            if i not in (time, temp, *second) and unit is not None and unit.kind in energy:
                chosen.append(i)
    if not chosen:
        listing = ", ".join(repr(h) for h in header)
        raise SiteError(f"{path}:1: no column names an energy unit: give --consumption-column one of {listing}")
    out: list[tuple[int, str, _Unit | None]] = [(time, header[time], None)]
    for i, kinds in [(temp, ("temperature",))] + [(i, energy) for i in chosen + second]:
        name = header[i]
        unit = _unit_of(path, name, options.units, kinds)
        if unit is None or unit.kind not in kinds:
            what = "no unit in its name" if unit is None else f"{unit.name} is not a unit of {' or '.join(kinds)}"
            example = "degF" if kinds[0] == "temperature" else "kWh"
            raise SiteError(f"{path}:1: column {name!r}: {what}; give its unit with --unit '{name}={example}'")
        out.append((i, name, unit))
    return out


#: How timestamp messages name the zone of the export's clock (timestamps with UTC offsets: no zone, no hints).
_ZONE_WORDING = _ZoneWording("--time-zone", "--time-zone", "give the export's zone, --time-zone {} (an IANA name)")
_OFFSET_WORDING = _ZoneWording("--time-zone", "--time-zone", None)


def _time_zone(name: str) -> zoneinfo.ZoneInfo:
    """The IANA zone ``--time-zone`` names; SiteError (naming the closest known name) otherwise."""
    zone, hint = named_time_zone(name)
    if zone is None:
        raise SiteError(
            f"--time-zone {name!r}: unknown time zone{hint}: give the IANA name of the zone whose clock the export "
            "keeps, such as 'America/Chicago' or 'Europe/Paris' (an export in standard time needs no --time-zone)"
        )
    return zone


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header and ``[(line, cells)]`` of a CSV file separated by ``,``, ``;`` or tabs (the header's most
    frequent; :func:`~buildenv.sites.cells._rows`), blank lines and rows of empty cells skipped, cells stripped."""
    rows = [(line, cells) for line, cells in _rows(path, ",;\t") if any(cells)]
    if len(rows) < 3:
        raise SiteError(f"{path}: {max(len(rows) - 1, 0)} data row(s): expected a header and the readings")
    return rows[0][1], rows[1:]


def _parse_stamp(path: Path, line: int, text: str, options: ImportOptions, last: bool = False) -> dt.datetime:
    """A timestamp cell: by ``options.time_format`` (offset-aware where it has ``%z``), else as
    :func:`~buildenv.sites.timestamps._parse_timestamp` reads an export's; in the ``last`` row or in register
    readings (``--cumulative``), ``24:00`` is the next day's 00:00 without ``--stamped end`` too (an instant; a closing
    midnight row that is not a reading is left out)."""
    if not options.time_format:
        end = options.stamped == "end" or options.cumulative or last  # a register's reading is an instant
        return _parse_timestamp(path, line, text, stamped_end=end, export=True)
    try:
        return dt.datetime.strptime(text, options.time_format)
    except ValueError as exc:
        raise SiteError(
            f"{path}:{line}: cannot read timestamp {text!r}: expected format {options.time_format!r} ({exc}); give "
            "the export's format with --time-format, e.g. '%m/%d/%Y %H:%M'"
        ) from None


def _standard_stamps(
    path: Path, lines: list[int], stamps: list[dt.datetime], zone: zoneinfo.ZoneInfo | None, weather: str
) -> list[dt.datetime]:
    """Each row's timestamp in the local standard time of the EPW ``weather``, checked to rise as the site
    reader checks it (:func:`~buildenv.sites.timestamps._standard_times`: a repeated autumn hour is read as the
    next one, the hints name the zone whose clock skips or repeats an hour). Naive stamps are on ``zone``'s clock
    (None: standard time), whose standard time must be the weather file's; offset-aware ones (``%z``) are
    converted by their offsets, without a zone. SiteError otherwise, at the row where it shows."""
    if stamps[0].tzinfo is not None:
        tz_h, _ = _epw_location(weather)
        if zone is not None or tz_h is None:
            fix = "leave --time-zone out" if zone is not None else f"the weather file {weather} names no time zone"
            raise SiteError(
                f"{path}:{lines[0]}: the timestamps carry UTC offsets (%z in --time-format), which fix their time "
                f"(converted to the weather file's standard time): {fix}"
            )
        epw = dt.timezone(dt.timedelta(hours=tz_h))
        standard = [stamp.astimezone(epw).replace(tzinfo=None) for stamp in stamps]
        return _standard_times(path, lines, standard, None, weather, _OFFSET_WORDING)
    if zone is not None:
        fix = "give the zone of the export's clock (--time-zone), or the weather file of the building's place (--epw)"
        mismatch = _offset_mismatch_error(f"{path}: --time-zone {zone.key}", zone, stamps[0].year, weather, fix)
        if mismatch is not None:
            raise mismatch
    return _standard_times(path, lines, stamps, zone, weather, _ZONE_WORDING)


def _check_start_stamped(
    path: Path, lines: list[int], stamps: list[dt.datetime], standard: list[dt.datetime], step: int
) -> None:
    """SiteError where readings stamped at the start of their interval run from one interval after a midnight to a
    midnight, on the clock or in standard time: the site reader's end-of-hour hint, for any interval."""
    interval = dt.timedelta(minutes=step)
    for first, last in ((stamps[0], stamps[-1]), (standard[0], standard[-1])):
        if first - first.replace(hour=0, minute=0, second=0) == interval and last.time() == dt.time():
            raise SiteError(
                f"{path}:{lines[0]}: the readings run from {_fmt(first)} to {_fmt(last)} (line {lines[-1]}), "
                f"{step} minutes after a midnight to a midnight: stamped at the end of their interval? pass "
                f"--stamped end; if at its start, add the row {_fmt(first - interval)} with empty cells"
            )


def _grid(
    path: Path, lines: list[int], standard: list[dt.datetime], stamped_end: bool
) -> tuple[dt.datetime, int, np.ndarray]:
    """``(Monday 00:00 before the first interval, interval minutes, each row's interval index from it)``.

    The interval is the most frequent step between rows; it must divide the hour, and every row's interval must
    start on its grid. With ``stamped_end`` a row covers the interval that ends at its timestamp.
    """
    minutes = np.array([(s - standard[0]).total_seconds() / 60 for s in standard])
    steps, counts = np.unique(np.diff(minutes), return_counts=True)
    step = float(steps[np.argmax(counts)])
    if not step.is_integer() or 60 % step:
        line = lines[1 + int(np.argmax(np.diff(minutes) == step))]
        raise SiteError(
            f"{path}:{line}: the readings are most often {step:g} minutes apart: expected an interval that divides "
            "the hour (1, 5, 10, 15, 30 or 60 minutes)"
        )
    first = standard[0] - dt.timedelta(minutes=step if stamped_end else 0)
    monday = dt.datetime.combine(first.date() - dt.timedelta(days=first.weekday()), dt.time())
    begins = minutes + (first - monday).total_seconds() / 60
    off = np.flatnonzero(begins % step)
    if off.size:
        raise SiteError(
            f"{path}:{lines[off[0]]}: the reading at {standard[off[0]]:%Y-%m-%d %H:%M:%S} standard time is off the "
            f"export's {step:g}-minute grid (most readings are {step:g} minutes apart): correct its time or remove it"
        )
    return monday, int(step), (begins // step).astype(int)


def _series(
    path: Path, lines: np.ndarray, raw: np.ndarray, column: str, unit: _Unit, slots: np.ndarray, size: int, end: bool
) -> np.ndarray:
    """The interval series ``(size,)`` of one column: degC, kWh in the interval, or kW; NaN where missing.

    A ``unit.kind == "register"`` column holds meter readings, taken at the start of each row's interval (at its
    end where ``end``): an interval's energy is the next reading less this one, NaN next to a missing reading
    (:func:`~buildenv.sites.consumption._register_differences`). SiteError at a temperature outside the plausible
    range (naming the unit it was read in), a negative energy or power, or a falling register reading.
    """
    values = (raw + unit.offset) * unit.factor
    measured = np.flatnonzero(np.isfinite(values))
    if unit.kind == "register":
        readings, line_at = np.full(size, np.nan), np.zeros(size, int)
        readings[slots], line_at[slots] = raw, lines
        options = _MeasurementOptions(stamped_end=end, cumulative=True)
        fix = "or give each interval's energy without --cumulative"
        energy, _ = _register_differences(
            path, readings, line_at, options, reading=f"{column} reading", interval="interval", fix=fix
        )
        return energy * unit.factor
    if unit.kind == "temperature":
        lo, hi = TEMPERATURE_RANGE_C
        bad = measured[(values[measured] < lo) | (values[measured] > hi)]
        if bad.size:
            k = bad[0]
            # the unit that brings every reading of the column into range, where one does
            converted = {
                u.name: (raw[measured] + u.offset) * u.factor
                for u in _UNITS.values()
                if u.kind == "temperature" and u is not unit
            }
            fits = [name for name, c in converted.items() if lo <= c.min() and c.max() <= hi]
            hint = f"give the column's unit with --unit '{column}={fits[0]}'" if fits else "check the column"
            raise SiteError(
                f"{path}:{lines[k]}: {column}={raw[k]:g} read in {unit.name} is {values[k]:.1f} degC, outside "
                f"[{lo:g}, {hi:g}]: {hint} (degC, degF or K), or leave the cell empty if the sensor failed"
            )
    else:
        negative = measured[values[measured] < 0]
        if negative.size:
            raise SiteError(
                f"{path}:{lines[negative[0]]}: {column}={raw[negative[0]]:g} is negative: give the energy (or power) "
                "of the interval, or leave the cell empty"
            )
    out = np.full(size, np.nan)
    out[slots] = values
    return out


def _hourly(series: np.ndarray, per_hour: int, how: str) -> np.ndarray:
    """Hourly values of an interval series: ``"mean"`` of the hour's measured intervals (NaN if none), or
    ``"sum"`` of all of them (NaN if any is missing)."""
    x = series.reshape(-1, per_hour)
    if how == "sum":
        return np.where(np.isfinite(x).all(axis=1), x.sum(axis=1), np.nan)
    count = np.isfinite(x).sum(axis=1)
    return np.where(count > 0, np.nansum(x, axis=1) / np.maximum(count, 1), np.nan)


def _fill_short_gaps(t: np.ndarray, max_hours: int = MAX_FILLED_GAP_HOURS) -> tuple[np.ndarray, int]:
    """``(t with runs of at most max_hours NaN between two measured hours linearly interpolated, hours filled)``."""
    t = t.copy()
    known = np.flatnonzero(np.isfinite(t))
    filled = 0
    for a, b in zip(known[:-1], known[1:]):
        if 1 < b - a <= max_hours + 1:
            t[a + 1 : b] = np.interp(np.arange(a + 1, b), [a, b], [t[a], t[b]])
            filled += int(b - a - 1)
    return t, filled


def _gap_note(path: Path, missing: np.ndarray, before: np.ndarray, first: dt.datetime, what: str) -> str | None:
    """One line naming how many hours (from ``first``) miss ``what`` and the first of them, or None; ``before``:
    each hour's last export line before it."""
    if not missing.any():
        return None
    h = int(np.argmax(missing))
    return (
        f"{path}: {int(missing.sum())} hour(s) without {what}, the first from {_fmt(first + dt.timedelta(hours=h))} "
        f"standard time (after line {before[h]}); they stay gaps, masked in comparisons"
    )


def _read_hourly(
    path: Path, options: ImportOptions, zone: zoneinfo.ZoneInfo | None, weather: str
) -> tuple[dt.datetime, int, dict[str, str], np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """``(Monday 00:00 of the first week, interval minutes, {column: unit read}, temperature degC, consumption kWh,
    each hour's last export line (0: none), electricity kWh or None)``, hourly in local standard time over whole
    weeks from that Monday (``zone``: the export's clock, ``options.time_zone``)."""
    header, rows = _read_rows(path)
    columns = _columns(path, header, options)
    for line, cells in rows:
        if len(cells) != len(header):
            raise SiteError(f"{path}:{line}: {len(cells)} cells, the header has {len(header)}: fix the row")
    lines = np.array([line for line, _ in rows])
    stamps = [
        _parse_stamp(path, line, cells[columns[0][0]], options, last=i == len(rows) - 1)
        for i, (line, cells) in enumerate(rows)
    ]
    standard = _standard_stamps(path, list(lines), stamps, zone, weather)
    end = options.stamped == "end"
    monday, step, slots = _grid(path, list(lines), standard, end)
    if not end:
        _check_start_stamped(path, list(lines), stamps, standard, step)
    per_hour = 60 // step
    hours = -(-(int(slots[-1]) // per_hour + 1) // cat.HOURS_PER_WEEK) * cat.HOURS_PER_WEEK
    if options.cumulative and all(unit.kind != "energy" for _, _, unit in columns[2:]):
        raise SiteError(f"{path}:1: --cumulative, but no consumption column is in an energy unit (Wh, kWh, ...)")

    read: dict[str, str] = {}
    hourly: list[np.ndarray] = []
    for index, column, unit in columns[1:]:
        raw = np.array([_parse_value(path, line, column, cells[index]) for line, cells in rows])
        if unit.kind == "energy" and options.cumulative:
            unit = dataclasses.replace(unit, kind="register")
        elif unit.kind == "energy":
            fix = "pass --cumulative"
            _check_not_a_register(path, raw, lines, column=column, per_day=24 * per_hour, interval="interval", fix=fix)
        read[column] = unit.name + (" register" if unit.kind == "register" else "")
        series = _series(path, lines, raw, column, unit, slots, hours * per_hour, end)
        hourly.append(_hourly(series, per_hour, "sum" if unit.kind in ("energy", "register") else "mean"))
    slot_line = np.zeros(hours * per_hour, int)
    slot_line[slots] = lines
    hour_line = slot_line.reshape(hours, per_hour).max(axis=1)
    meters = len(columns) - 2 - len(options.electricity_columns)  # the consumption's columns, then the electricity's
    electricity = np.sum(hourly[1 + meters :], axis=0) if options.electricity_columns else None
    return monday, step, read, hourly[0], np.sum(hourly[1 : 1 + meters], axis=0), hour_line, electricity


def _measured_weeks(measured: np.ndarray) -> tuple[int, int, list[tuple[int, int]]]:
    """The first and last week (from the export's first Monday) of the measured hours ``measured`` (indices), less
    a week at either end measured for under a day (an export's closing midnight row; an hour that daylight saving
    time moved across a Monday), as ``(first, last, [(week, measured hours), ...])``, those left out last."""
    per_week = np.bincount(measured // cat.HOURS_PER_WEEK)
    first, last, edges = int(measured[0]) // cat.HOURS_PER_WEEK, int(measured[-1]) // cat.HOURS_PER_WEEK, []
    while last > first and per_week[first] < cat.HOURS_PER_DAY:
        edges.append((first, int(per_week[first])))
        first += 1
    while last > first and per_week[last] < cat.HOURS_PER_DAY:
        edges.append((last, int(per_week[last])))
        last -= 1
    return first, last, edges


def _edge_note(path: Path, hours: int, monday: dt.date) -> str:
    """What :func:`_measured_weeks` left out, as a note of the import."""
    return (
        f"{path}: the week of {monday:%Y-%m-%d} holds {hours} measured hour(s), under a day: left out (an export's "
        "closing midnight row, or an hour daylight saving time moved across a Monday)"
    )


def import_export(
    export: str | os.PathLike,
    out: str | os.PathLike,
    *,
    name: str,
    weather: str,
    floor_area_m2: float,
    number_of_floors: int,
    options: ImportOptions | None = None,
    settings: str | os.PathLike | None = None,
    known: Mapping[str, float] | None = None,
    end_uses: tuple[str, ...] = cat.DEFAULT_END_USES,
    electricity_end_uses: tuple[str, ...] = (),
) -> ImportReport:
    """Write the site folder ``out`` from the BMS export ``export`` (see the module docstring).

    Only the weeks from the first to the last measured hour are written, less a first or last week measured for
    under a day (a note says so); hours without a value stay gaps (with
    ``options.fill_temperature_gaps``, temperature gaps of up to :data:`MAX_FILLED_GAP_HOURS` hours are
    interpolated) and :attr:`ImportReport.notes` names the first.

    Args:
        export: the CSV export (a header, then one row per reading).
        out: the site folder to write; it must not exist, or be empty.
        name, weather, floor_area_m2, number_of_floors, known, end_uses: as :func:`buildenv.sites.write_site`
            (``weather`` an EPW short name or a path, written absolute).
        electricity_end_uses: what ``options.electricity_columns`` sum (required with them).
        options: how to read the export (:class:`ImportOptions`; None: the defaults).
        settings: a ``settings.csv`` (site format) for the imported weeks; None writes the typical settings
            (:func:`buildenv.defaults.default_week`).

    Returns:
        the :class:`ImportReport`.

    Raises:
        SiteError: the first problem, at its line of the export (or of ``settings``); nothing is written.
        WeatherError, CatalogueError: an unknown weather; a floor area or floor count outside the catalogue.
    """
    from buildenv.defaults import default_week
    from buildenv.sites.writer import write_site
    from buildenv.weather.epw import resolve_epw, shipped_weather

    options = options or ImportOptions()
    path, folder = Path(export).expanduser(), Path(out).expanduser()
    weather = weather if weather in shipped_weather() else str(resolve_epw(weather))
    cat.get("floor_area_m2").check(floor_area_m2)
    cat.get("number_of_floors").check(number_of_floors)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise SiteError(f"{folder}: exists and is not an empty folder: give a new site folder")
    if options.stamped not in ("start", "end"):
        raise SiteError(f"stamped must be 'start' or 'end', got {options.stamped!r}")
    zone = _time_zone(options.time_zone) if options.time_zone else None
    if bool(options.electricity_columns) != bool(electricity_end_uses):
        raise SiteError(
            "a second meter needs its columns (--electricity-column) and its end uses (--electricity-meter): give both"
        )
    twice = [use for use in electricity_end_uses if use in end_uses]
    if twice:
        raise SiteError(f"--electricity-meter: {', '.join(twice)} also in --meter: each end use on one meter")

    monday, step, read, temperature, consumption, hour_line, electricity = _read_hourly(path, options, zone, weather)
    measured = np.flatnonzero(np.isfinite(temperature) | np.isfinite(consumption))
    if not measured.size:
        raise SiteError(
            f"{path}: no hour has a temperature or a consumption: check the columns, their units and --cumulative"
        )
    week = cat.HOURS_PER_WEEK
    first_week, last_week, edges = _measured_weeks(measured)
    measured = measured[(measured >= first_week * week) & (measured < (last_week + 1) * week)]
    keep = slice(first_week * week, (last_week + 1) * week)
    temperature, consumption, hour_line = temperature[keep], consumption[keep], hour_line[keep]
    electricity = None if electricity is None else electricity[keep]
    start = monday + dt.timedelta(weeks=first_week)
    weeks = last_week - first_week + 1
    second = set(options.electricity_columns)
    for series, uses, names in (
        (consumption, end_uses, [c for c in list(read)[1:] if c not in second]),
        (electricity, electricity_end_uses, list(options.electricity_columns)),
    ):
        if series is None:
            continue
        sums = ", ".join(repr(c) for c in names).replace("{", "{{").replace("}", "}}")
        what, fix = f"the hourly sum of {sums}, {{:g}} kWh,", "check the columns' units, --unit COLUMN=UNIT"
        _check_size(
            path,
            series,
            hour_line,
            floor_area_m2,
            tuple(uses),
            what,
            fix,
            indoor_c=temperature,
            weather=weather,
            start=start.date(),
        )

    filled = 0
    if options.fill_temperature_gaps:
        temperature, filled = _fill_short_gaps(temperature)
    span = slice(int(measured[0]) - first_week * week, int(measured[-1]) - first_week * week + 1)
    before = np.concatenate([[1], np.maximum.accumulate(hour_line)[:-1]])[span]
    first = start + dt.timedelta(hours=span.start)
    missing_t, missing_q = ~np.isfinite(temperature[span]), ~np.isfinite(consumption[span])
    notes = [
        *(_edge_note(path, hours, monday + dt.timedelta(weeks=w)) for w, hours in edges),
        _gap_note(path, missing_t, before, first, "temperature"),
        _gap_note(path, missing_q, before, first, "consumption"),
    ]

    if settings is None:
        day_settings = default_week(weeks)[0]
    else:
        day_settings = _read_settings(Path(settings).expanduser(), start.date(), weeks)
    source = {"export": path.name, "interval_minutes": step, "stamped": options.stamped, "columns": read}
    if options.time_zone:
        source["time_zone"] = options.time_zone
    site = write_site(
        folder,
        name=name,
        weather=weather,
        start=start.date(),
        floor_area_m2=floor_area_m2,
        number_of_floors=number_of_floors,
        settings=day_settings,
        temperature_c=temperature.reshape(weeks, week),
        consumption_kwh=consumption.reshape(weeks, week),
        source=source,
        known=known,
        consumption_end_uses=tuple(end_uses),
        electricity_kwh=None if electricity is None else electricity.reshape(weeks, week),
        electricity_end_uses=tuple(electricity_end_uses),
    )
    return ImportReport(
        site=str(site),
        start=start.date().isoformat(),
        weeks=weeks,
        interval_minutes=step,
        columns=read,
        missing_temperature_hours=int(missing_t.sum()),
        missing_consumption_hours=int(missing_q.sum()),
        filled_temperature_hours=filled,
        settings=str(settings) if settings is not None else "typical (buildenv.defaults.default_week)",
        notes=[note for note in notes if note],
    )
