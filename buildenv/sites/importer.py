"""Importing a raw BMS export as a site folder (``buildenv site import``).

A BMS export is a CSV file with a timestamp column, an indoor temperature column and one or more consumption
columns: often sub-hourly, on a local clock that keeps daylight saving, stamped at the end of each interval, in degF
or K, in Wh, MWh or GJ (or power in kW), or as meter register readings. :func:`import_export` finds the columns
(:func:`_columns`: named by :class:`ImportOptions` or guessed from the header when only one fits), converts each
timestamp to local standard time (:func:`_standard_stamps`) and each value to degC, kWh or kW (:func:`_series`),
resamples to hours (:func:`_hourly`: temperature and power the mean of the hour's readings, energy the sum of its
intervals, missing unless every interval is there) and writes whole weeks with
:func:`buildenv.sites.writer.write_site`, which writes atomically and loads the result back: a failed import leaves
no folder. Every problem it cannot fix raises :class:`~buildenv.errors.SiteError` as ``"<export>:<line>: <what is
wrong>; <what to do>"`` (line 1 is the header); hours without a value stay gaps and :attr:`ImportReport.notes`
names the first.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
import difflib
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.sites.cells import _parse_value
from buildenv.sites.consumption import _consumption
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.model import TEMPERATURE_RANGE_C
from buildenv.sites.reader import _read_settings, _zone
from buildenv.sites.timestamps import _SPRING_MONTHS, _fmt, _standard_time, _zones_changing

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
            power unit.
        units: ``{column: unit}`` (degC, degF, K; Wh, kWh, MWh, MJ, GJ; W, kW, MW) where the name does not say it.
        time_format: a ``strptime`` format of the timestamps; None reads ``YYYY-MM-DD HH:MM[:SS]`` (``T`` or
            ``/`` allowed, ``24:00`` read as the next day's 00:00).
        time_zone: the IANA zone whose clock (daylight saving included) the export keeps; None: standard time.
        stamped: ``"start"`` or ``"end"`` of the interval a row covers.
        cumulative: the energy columns hold meter register readings.
        fill_temperature_gaps: interpolate temperature gaps of at most :data:`MAX_FILLED_GAP_HOURS` hours.
    """

    time_column: str | None = None
    temperature_column: str | None = None
    consumption_columns: tuple[str, ...] = ()
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
    """``[(index, name, unit)]`` of the timestamp (unit None), temperature and consumption columns."""
    for name in options.units:
        _pick(path, header, name, "", "--unit", set())  # a unit for a column the export does not have
    time = _pick(path, header, options.time_column, "time|date|stamp", "--time-column", set())
    temp = _pick(path, header, options.temperature_column, "temp", "--temperature-column", {time})
    energy = ("energy", "power")
    chosen = [_pick(path, header, name, "", "--consumption-column", set()) for name in options.consumption_columns]
    if not chosen:
        for i, name in enumerate(header):
            unit = _unit_of(path, name, options.units, energy)
            if i not in (time, temp) and unit is not None and unit.kind in energy:
                chosen.append(i)
    if not chosen:
        listing = ", ".join(repr(h) for h in header)
        raise SiteError(f"{path}:1: no column names an energy unit: give --consumption-column one of {listing}")
    out: list[tuple[int, str, _Unit | None]] = [(time, header[time], None)]
    for i, kinds in [(temp, ("temperature",))] + [(i, energy) for i in chosen]:
        name = header[i]
        unit = _unit_of(path, name, options.units, kinds)
        if unit is None or unit.kind not in kinds:
            what = "no unit in its name" if unit is None else f"{unit.name} is not a unit of {' or '.join(kinds)}"
            example = "degF" if kinds[0] == "temperature" else "kWh"
            raise SiteError(f"{path}:1: column {name!r}: {what}; give its unit with --unit '{name}={example}'")
        out.append((i, name, unit))
    return out


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header and ``[(line, cells)]`` of a CSV file separated by ``,``, ``;`` or tabs (the header's most
    frequent), blank lines skipped, cells stripped."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SiteError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start}); save the export as UTF-8") from exc
    except OSError as exc:
        raise SiteError(f"{path}: cannot read: {exc}") from exc
    first = next((line for line in text.splitlines() if line.strip()), "")
    delimiter = max(",;\t", key=first.count)
    reader = csv.reader(text.splitlines(), delimiter=delimiter)
    rows = []
    try:
        for cells in reader:
            if any(c.strip() for c in cells):
                rows.append((reader.line_num, [c.strip() for c in cells]))
    except csv.Error as exc:
        raise SiteError(f"{path}:{reader.line_num}: malformed CSV: {exc}") from exc
    if len(rows) < 3:
        raise SiteError(f"{path}: {max(len(rows) - 1, 0)} data row(s): expected a header and the readings")
    return rows[0][1], rows[1:]


_STAMP = re.compile(r"(\d{4})[-/](\d{2})[-/](\d{2})[T ](\d{1,2}):(\d{2})(?::(\d{2}))?")


def _parse_stamp(path: Path, line: int, text: str, time_format: str | None) -> dt.datetime:
    """A timestamp cell as a naive datetime (``24:00`` is the next day's 00:00)."""
    try:
        if time_format:
            return dt.datetime.strptime(text, time_format)
        m = _STAMP.fullmatch(text)
        if m is None:
            raise ValueError("not YYYY-MM-DD HH:MM")
        year, month, day, hour, minute, second = (int(g or 0) for g in m.groups())
        day_end = hour == 24 and minute == second == 0
        stamp = dt.datetime(year, month, day, 0 if day_end else hour, minute, second)
        return stamp + dt.timedelta(days=1) if day_end else stamp
    except ValueError as exc:
        expected = f"format {time_format!r} ({exc})" if time_format else "'YYYY-MM-DD HH:MM[:SS]'"
        raise SiteError(
            f"{path}:{line}: cannot read timestamp {text!r}: expected {expected}; give the export's format "
            "with --time-format, e.g. '%m/%d/%Y %H:%M'"
        ) from None


def _standard_stamps(
    path: Path, lines: list[int], stamps: list[dt.datetime], zone_name: str | None, weather: str
) -> list[dt.datetime]:
    """Each row's timestamp in local standard time (from ``zone_name``'s clock; a repeated autumn reading is read
    as the next one), checked to rise; SiteError at the row whose time does not exist, repeats or goes back, or
    (without a zone) at the first reading after an hour missing where clocks go forward."""
    zone = _zone(zone_name, "--time-zone") if zone_name else None
    out: list[dt.datetime] = []
    for i, (line, stamp) in enumerate(zip(lines, stamps)):
        standard = stamp if zone is None else _standard_time(stamp, zone, out[-1] if out else None)
        if standard is None:
            raise SiteError(
                f"{path}:{line}: {_fmt(stamp)} does not exist on the clock of {zone.key} (--time-zone), which goes "
                "forward over it: is the zone right? an export in standard time needs no --time-zone"
            )
        if out and standard <= out[-1]:
            what = "repeats" if standard == out[-1] else "is earlier than"
            raise SiteError(
                f"{path}:{line}: timestamp {_fmt(stamp)} {what} the previous row's (line {lines[i - 1]}): sort the "
                "rows and remove duplicates; if the export keeps daylight saving, give --time-zone (an IANA name)"
            )
        if zone is None and out and standard - out[-1] > dt.timedelta(hours=1):
            missing = out[-1].replace(minute=0) + dt.timedelta(hours=1)
            spring = missing.weekday() == 6 and missing.hour <= 3 and missing.month in _SPRING_MONTHS
            if spring and standard >= missing + dt.timedelta(hours=1):
                zones = _zones_changing(missing, "gap", weather)
                if zones:
                    raise SiteError(
                        f"{path}:{line}: no reading from {_fmt(missing)} for an hour, on the Sunday clocks go forward "
                        f"(e.g. in {zones[0]}): give the export's zone, --time-zone {zones[0]}, or if it keeps "
                        "standard time, add the missing readings with empty cells"
                    )
        out.append(standard)
    return out


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


def _check_not_a_register(path: Path, lines: np.ndarray, raw: np.ndarray, column: str, per_day: int) -> None:
    """SiteError if an energy column never falls over a day or more of readings while rising well beyond its
    largest step: meter register readings, to be read with ``--cumulative``."""
    measured = np.flatnonzero(np.isfinite(raw))
    if measured.size < per_day:
        return
    rise = np.diff(raw[measured])
    if (rise >= 0).all() and rise.sum() > 0 and rise.sum() >= 5 * rise.max():
        raise SiteError(
            f"{path}:{lines[measured[0]]}: {column} never falls, from {raw[measured[0]]:g} here to "
            f"{raw[measured[-1]]:g} on line {lines[measured[-1]]}: meter register readings? pass --cumulative"
        )


def _series(
    path: Path, lines: np.ndarray, raw: np.ndarray, column: str, unit: _Unit, slots: np.ndarray, size: int, end: bool
) -> np.ndarray:
    """The interval series ``(size,)`` of one column: degC, kWh in the interval, or kW; NaN where missing.

    A ``unit.kind == "register"`` column holds meter readings, taken at the start of each row's interval (at its
    end where ``end``): an interval's energy is the next reading less this one, NaN next to a missing reading.
    SiteError at a temperature outside the plausible range (naming the unit it was read in), a negative energy or
    power, or a falling register reading.
    """
    values = (raw + unit.offset) * unit.factor
    measured = np.flatnonzero(np.isfinite(values))
    if unit.kind == "register":
        readings = np.full(size + 1, np.nan)
        line_at = np.zeros(size + 1, int)
        readings[slots + end], line_at[slots + end] = raw, lines
        falls = np.flatnonzero(np.diff(readings) < 0)
        if falls.size:
            k = falls[0]
            raise SiteError(
                f"{path}:{line_at[k + 1]}: {column} reading {readings[k + 1]:g} is below the previous "
                f"{readings[k]:g} (line {line_at[k]}): a meter reset or replacement? leave this reading empty (the "
                "intervals on either side become gaps)"
            )
        return np.diff(readings) * unit.factor
    if unit.kind == "temperature":
        lo, hi = TEMPERATURE_RANGE_C
        bad = measured[(values[measured] < lo) | (values[measured] > hi)]
        if bad.size:
            k = bad[0]
            raise SiteError(
                f"{path}:{lines[k]}: {column}={raw[k]:g} read in {unit.name} is {values[k]:.1f} degC, outside "
                f"[{lo:g}, {hi:g}]: give the column's unit with --unit '{column}=degF' (degC, degF or K), or leave "
                "the cell empty if the sensor failed"
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
    path: Path, options: ImportOptions, weather: str
) -> tuple[dt.datetime, int, dict[str, str], np.ndarray, np.ndarray, np.ndarray]:
    """``(Monday 00:00 of the first week, interval minutes, {column: unit read}, temperature degC, consumption kWh,
    each hour's last export line (0: none))``, hourly in local standard time over whole weeks from that Monday."""
    header, rows = _read_rows(path)
    columns = _columns(path, header, options)
    for line, cells in rows:
        if len(cells) != len(header):
            raise SiteError(f"{path}:{line}: {len(cells)} cells, the header has {len(header)}: fix the row")
    lines = np.array([line for line, _ in rows])
    stamps = [_parse_stamp(path, line, cells[columns[0][0]], options.time_format) for line, cells in rows]
    standard = _standard_stamps(path, list(lines), stamps, options.time_zone, weather)
    end = options.stamped == "end"
    monday, step, slots = _grid(path, list(lines), standard, end)
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
            _check_not_a_register(path, lines, raw, column, 24 * per_hour)
        read[column] = unit.name + (" register" if unit.kind == "register" else "")
        series = _series(path, lines, raw, column, unit, slots, hours * per_hour, end)
        hourly.append(_hourly(series, per_hour, "sum" if unit.kind in ("energy", "register") else "mean"))
    slot_line = np.zeros(hours * per_hour, int)
    slot_line[slots] = lines
    hour_line = slot_line.reshape(hours, per_hour).max(axis=1)
    return monday, step, read, hourly[0], np.sum(hourly[1:], axis=0), hour_line


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
) -> ImportReport:
    """Write the site folder ``out`` from the BMS export ``export`` (see the module docstring).

    Only the weeks from the first to the last measured hour are written; hours without a value stay gaps (with
    ``options.fill_temperature_gaps``, temperature gaps of up to :data:`MAX_FILLED_GAP_HOURS` hours are
    interpolated) and :attr:`ImportReport.notes` names the first.

    Args:
        export: the CSV export (a header, then one row per reading).
        out: the site folder to write; it must not exist, or be empty.
        name, weather, floor_area_m2, number_of_floors, known, end_uses: as :func:`buildenv.sites.write_site`
            (``weather`` an EPW short name or a path, written absolute).
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

    monday, step, read, temperature, consumption, hour_line = _read_hourly(path, options, weather)
    measured = np.flatnonzero(np.isfinite(temperature) | np.isfinite(consumption))
    if not measured.size:
        raise SiteError(
            f"{path}: no hour has a temperature or a consumption: check the columns, their units and --cumulative"
        )
    week = cat.HOURS_PER_WEEK
    first_week, last_week = int(measured[0]) // week, int(measured[-1]) // week
    keep = slice(first_week * week, (last_week + 1) * week)
    temperature, consumption, hour_line = temperature[keep], consumption[keep], hour_line[keep]
    start = monday + dt.timedelta(weeks=first_week)
    weeks = last_week - first_week + 1
    try:
        _consumption(path, consumption, hour_line, floor_area_m2, _MeasurementOptions(), tuple(end_uses))
    except SiteError as exc:
        sums = ", ".join(repr(c) for c in list(read)[1:])
        raise SiteError(f"{exc} (the hourly sum of {sums} in kWh: check their units, --unit COLUMN=UNIT)") from None

    filled = 0
    if options.fill_temperature_gaps:
        temperature, filled = _fill_short_gaps(temperature)
    span = slice(int(measured[0]) - first_week * week, int(measured[-1]) - first_week * week + 1)
    before = np.concatenate([[1], np.maximum.accumulate(hour_line)[:-1]])[span]
    first = start + dt.timedelta(hours=span.start)
    missing_t, missing_q = ~np.isfinite(temperature[span]), ~np.isfinite(consumption[span])
    notes = [
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
