"""Reading and checking the timestamps of ``measurements.csv``: each row's hour in local standard time.

:func:`_parse_timestamp` reads one cell (on the hour; ``24:00`` only with ``stamped = "end"``); :func:`_hours`
converts the rows' timestamps to hours since the first Monday 00:00 in local standard time (from the clock of
``[measurements] time_zone`` where declared, whose standard time must be the EPW's; back an hour where
``stamped = "end"``), checks their order, duplicates and daylight-saving gaps (:func:`_check_step`) and that the
data cover whole weeks, and names the likely cause: a daylight-saving clock (with the IANA zones whose clocks
change then, :func:`_zones_changing`), end-of-hour stamps, missing rows. Every problem raises
:class:`~buildenv.errors.SiteError` as ``"<file>:<line>: <what is wrong>"``.

``buildenv site import`` (:mod:`buildenv.sites.importer`) reads an export's timestamps with the same functions:
:func:`_parse_timestamp` with ``export=True``, :func:`_standard_times` (order and daylight-saving checks, any
interval) and :func:`_offset_mismatch_error`, its messages naming the command's flags (:class:`_ZoneWording`).
"""

from __future__ import annotations

import calendar
import datetime as dt
import difflib
import functools
import re
import zoneinfo
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, SiteError
from buildenv.sites.measurement_options import _MeasurementOptions

#: Months whose Sundays see clocks go forward (north: March, April; south: September, October) or back.
_SPRING_MONTHS = (3, 4, 9, 10)
_AUTUMN_MONTHS = (10, 11, 3, 4)
#: Zone areas whose IANA names a hint may suggest (not Etc/, US/, ...), in the order it prefers them.
_ZONE_AREAS = ("America", "Europe", "Australia", "Pacific", "Asia", "Africa", "Atlantic", "Indian")
_TIMESTAMP = re.compile(r"(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2})(?::(\d{2}))?")
#: An export's timestamp (``export=True``): '/' between the date's parts and a one-digit hour allowed too.
_EXPORT_TIMESTAMP = re.compile(r"(\d{4})[-/](\d{2})[-/](\d{2})[T ](\d{1,2}):(\d{2})(?::(\d{2}))?")
_TIMESTAMP_WITH_ZONE = re.compile(r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(?::\d{2})?(?:\.\d+)?\s*(?:Z|[+-]\d{2}:?\d{2})")


def _parse_timestamp(
    path: Path, line: int, text: str, *, stamped_end: bool = False, export: bool = False
) -> dt.datetime:
    """A timestamp cell ``text`` (``path``:``line``) as a naive datetime; ``24:00`` is the next day's 00:00.

    ``measurements.csv`` (``export=False``): ``YYYY-MM-DD HH:MM[:SS]`` (or with a ``T``) on the hour, ``24:00``
    only for rows stamped at the end of their hour (``stamped_end``). A BMS export (``export=True``, ``buildenv
    site import``): also ``/`` between the date's parts, a one-digit hour and any minute and second; ``24:00``
    only with ``--stamped end``. Raises SiteError ``"<path>:<line>: ..."`` naming the fix (an export's: its
    flags): unreadable, with a UTC offset, ``24:00`` for rows stamped at their start (the site's: or a register's
    reading, which ``stamped_end`` reads as the next day's 00:00), not on the hour.
    """
    m = (_EXPORT_TIMESTAMP if export else _TIMESTAMP).fullmatch(text)
    if m is None:
        if _TIMESTAMP_WITH_ZONE.fullmatch(text):
            fix = "give local standard time without an offset, as 'YYYY-MM-DD HH:MM'"
            if export:
                fix = "give the format with --time-format, %z for the offset, e.g. '%Y-%m-%dT%H:%M%z'"
            raise SiteError(f"{path}:{line}: timestamp {text!r} has a UTC offset: {fix}")
        if export:
            raise SiteError(
                f"{path}:{line}: cannot read timestamp {text!r}: expected 'YYYY-MM-DD HH:MM[:SS]'; give the "
                "export's format with --time-format, e.g. '%m/%d/%Y %H:%M'"
            )
        raise SiteError(
            f"{path}:{line}: cannot read timestamp {text!r}: expected 'YYYY-MM-DD HH:MM' "
            "(or with a 'T'), local standard time of the start of the hour"
        )
    year, month, day, hour, minute, second = (int(g) if g else 0 for g in m.groups())
    end_of_day = hour == 24 and not minute and not second
    try:
        stamp = dt.datetime(year, month, day, 0 if end_of_day else hour, minute, second)
    except ValueError as exc:
        raise SiteError(f"{path}:{line}: cannot read timestamp {text!r}: {exc}") from exc
    if end_of_day and not stamped_end:
        if export:
            fix = (
                "the rows are stamped at the end of their interval (24:00 for the one that ends the day); "
                "pass --stamped end"
            )
        else:
            fix = (
                "if the rows are stamped at the end of their hour (24:00 for 23:00-24:00), declare it in site.toml: "
                '[measurements] stamped = "end"; if the column holds meter register readings (this one the reading '
                "at the day's end), declare [measurements] cumulative = true"
            )
        raise SiteError(f"{path}:{line}: timestamp {text!r} is 24:00, the end of a day: {fix}")
    if (minute or second) and not export:
        raise SiteError(
            f"{path}:{line}: timestamp {text!r} is not on the hour: each row is the hour starting "
            "at HH:00 (resample sub-hourly data: mean temperature, summed kWh)"
        )
    return stamp + dt.timedelta(days=1) if end_of_day else stamp


def named_time_zone(name: str) -> tuple[zoneinfo.ZoneInfo | None, str]:
    """The IANA time zone ``name`` and ``""``, or ``None`` and a hint naming the closest known zone
    (`` (did you mean 'America/Chicago'?)``, ``""`` when none is close)."""
    try:
        return zoneinfo.ZoneInfo(name), ""
    except (zoneinfo.ZoneInfoNotFoundError, ValueError, OSError):
        close = difflib.get_close_matches(name, sorted(zoneinfo.available_timezones()), n=1)
        return None, f" (did you mean {close[0]!r}?)" if close else ""


def _fmt(stamp: dt.datetime) -> str:
    return stamp.strftime("%Y-%m-%d %H:%M")


_HOUR = dt.timedelta(hours=1)


@dataclass(frozen=True)
class _ZoneWording:
    """How timestamp messages name the option that declares the clock's zone.

    Attributes:
        option: its name (``time_zone``; ``--time-zone``).
        named: it as a message cites it, with where it is set (``time_zone, site.toml:12``; ``--time-zone``).
        declare: how to declare a zone, a format taking its IANA name; None where the timestamps carry their UTC
            offsets (no daylight-saving hints).
    """

    option: str
    named: str
    declare: str | None


def _site_wording(options: _MeasurementOptions) -> _ZoneWording:
    """The site reader's :class:`_ZoneWording` (``[measurements] time_zone`` of ``site.toml``)."""
    return _ZoneWording(
        "time_zone",
        f"time_zone, {options.where}",
        'declare the zone of the BMS clock in site.toml, [measurements] time_zone = "{}" (an IANA name)',
    )


def _hours(
    path: Path, lines: list[int], stamps: list[dt.datetime], options: _MeasurementOptions, weather: str | None
) -> tuple[dt.datetime, np.ndarray, int]:
    """``(first Monday 00:00, hour of each row since then in local standard time, weeks)`` of the timestamps.

    Order, duplicates and gaps are checked in standard time (converted from ``options.time_zone`` where
    declared), whole weeks on the file's clock or in standard time: with a time zone, an export of whole weeks
    of the local clock in summer starts an hour before the first Monday in standard time (that row gets hour
    -1) and ends an hour before the last Sunday's 23:00 (that hour stays missing). With ``options.cumulative``
    (start stamps) the last row may be the Monday 00:00 after whole weeks: the register's reading that closes the
    last hour (its hour is ``weeks x 168``).

    Raises SiteError ``"<path>:<line>: ..."`` at the first row that breaks these rules, and
    ``"<site.toml>:<line>: [measurements] time_zone ..."`` where the zone's standard time is not the EPW
    ``weather``'s (:func:`_offset_mismatch_error`: the hours would be off the weather's).
    """
    zone = options.time_zone
    wording = _site_wording(options)
    shift = _HOUR if options.stamped_end else dt.timedelta(0)
    standard = _standard_time(stamps[0], zone, None) if zone is not None else stamps[0]
    if standard is None:
        raise _skipped_hour_error(path, lines[0], stamps[0], zone, wording)
    for start in (standard - shift, stamps[0] - shift):  # in standard time, on the clock
        if start.weekday() == 0 and start.hour == 0:
            break
    else:
        raise _first_row_error(path, lines, stamps, options)
    if zone is not None and weather:
        mismatch = _offset_mismatch_error(
            f"{options.where}: [measurements] time_zone {zone.key!r}",
            zone,
            start.year,
            weather,
            "give the zone of the BMS clock (time_zone), or the weather file of the building's place (weather)",
        )
        if mismatch is not None:
            raise mismatch

    standards = _standard_times(path, lines, stamps, zone, weather, wording)
    hours = [int((s - shift - start).total_seconds()) // 3600 for s in standards]

    week = cat.HOURS_PER_WEEK
    clock = int((stamps[-1] - shift - start).total_seconds()) // 3600
    for last in (hours[-1], clock):  # in standard time, on the clock
        if last % week == week - 1:
            return start, np.asarray(hours), last // week + 1
    if options.cumulative and not options.stamped_end and hours[-1] > 0 and hours[-1] % week == 0:
        return start, np.asarray(hours), hours[-1] // week  # the register's reading that closes the last hour
    raise _last_row_error(path, lines[-1], stamps[-1], start, clock, options)


def _standard_times(
    path: Path,
    lines: list[int],
    stamps: list[dt.datetime],
    zone: zoneinfo.ZoneInfo | None,
    weather: str | None,
    wording: _ZoneWording,
) -> list[dt.datetime]:
    """Each row's timestamp (naive, on ``zone``'s clock; None: local standard time already) in local standard
    time, in order; a repeated hour of the clock (clocks going back) is read as the next hour of standard time.

    Each row is checked against the previous one (:func:`_check_step`): SiteError ``"<path>:<line>: ..."`` at the
    first row whose time the clock skips, that repeats or goes back, or (without ``zone``) that follows an hour
    missing where some zone's clock goes forward; the hints name the zones whose clocks change then (those of
    the EPW ``weather`` first) and the fix in ``wording``'s terms. Rows may be any whole interval apart.
    """
    out: list[dt.datetime] = []
    for i, (line, stamp) in enumerate(zip(lines, stamps)):
        standard = stamp if zone is None else _standard_time(stamp, zone, out[-1] if out else None)
        if standard is None:
            raise _skipped_hour_error(path, line, stamp, zone, wording)
        if out:
            _check_step(path, line, stamp, standard, (lines[i - 1], stamps[i - 1], out[-1]), zone, weather, wording)
        out.append(standard)
    return out


def _epw_offset_mismatch(zone: zoneinfo.ZoneInfo, year: int, weather: str) -> tuple[float, float] | None:
    """``(zone's standard time, the EPW's)``, hours from UTC, where ``zone``'s standard time in ``year`` is not
    that of the EPW ``weather`` (the hours of the data would be off the weather's); None where they agree or the
    EPW's header cannot be read."""
    tz_h, _ = _epw_location(weather)
    offset = _standard_offset(zone, year)
    if tz_h is None or offset == dt.timedelta(hours=tz_h):
        return None
    return offset.total_seconds() / 3600, tz_h


def _offset_mismatch_error(named: str, zone: zoneinfo.ZoneInfo, year: int, weather: str, fix: str) -> SiteError | None:
    """The error where ``zone``'s standard time in ``year`` is not the EPW ``weather``'s
    (:func:`_epw_offset_mismatch`), else None: ``"<named> keeps standard time UTC-5 h, the weather file (...)
    UTC-6 h: ...; <fix>"``, ``named`` the option with where it is set (``site.toml:12: [measurements] time_zone
    'America/New_York'``; ``bms.csv: --time-zone America/New_York``)."""
    mismatch = _epw_offset_mismatch(zone, year, weather)
    if mismatch is None:
        return None
    ours, theirs = mismatch
    return SiteError(
        f"{named} keeps standard time UTC{ours:+g} h, the weather file ({weather}) UTC{theirs:+g} h: the data "
        f"would be {abs(ours - theirs):g} h off the weather's; {fix}"
    )


def _skipped_hour_error(
    path: Path, line: int, stamp: dt.datetime, zone: zoneinfo.ZoneInfo, wording: _ZoneWording
) -> SiteError:
    return SiteError(
        f"{path}:{line}: timestamp {_fmt(stamp)} does not exist on the clock of {zone.key} ({wording.named}), "
        f"which goes forward over it: a file in local standard time needs no {wording.option}; a file on that "
        "clock has no such row"
    )


def _first_row_error(
    path: Path, lines: list[int], stamps: list[dt.datetime], options: _MeasurementOptions
) -> SiteError:
    """The error for a first row that is not the hour from a Monday 00:00."""
    stamp = stamps[0]
    if options.stamped_end:
        begins = stamp - _HOUR
        return SiteError(
            f'{path}:{lines[0]}: the first row, {_fmt(stamp)}, stamped at the end of its hour (stamped = "end", '
            f"{options.where}), covers the hour from {calendar.day_name[begins.weekday()]} {begins:%H:%M}: data "
            "must start with the hour from a Monday 00:00 (drop the rows before the next Monday 01:00, or add "
            "empty rows from the previous Monday 01:00)"
        )
    message = (
        f"{path}:{lines[0]}: the first timestamp {_fmt(stamp)} is a {calendar.day_name[stamp.weekday()]} at "
        f"{stamp:%H:%M}: data must start on a Monday at 00:00"
    )
    end = '[measurements] stamped = "end"'
    if stamp.weekday() == 0 and stamp.hour == 1:
        last = stamps[-1]
        if last.hour == 0 and len(stamps) > 1:
            return SiteError(
                f"{message}; this file runs to {calendar.day_name[last.weekday()]} {_fmt(last)} (line {lines[-1]}): "
                f"its rows are stamped at the end of their hour (01:00 for 00:00-01:00); declare it in site.toml: "
                f"{end}"
            )
        return SiteError(
            f"{message}: if the rows are stamped at the end of their hour (01:00 for 00:00-01:00), declare it in "
            f"site.toml: {end}; if the hour from 00:00 was not measured, add the row {_fmt(stamp - _HOUR)} with "
            "empty cells"
        )
    return SiteError(
        f"{message} (drop the rows before the next Monday, or add empty rows from the previous Monday 00:00)"
    )


def _last_row_error(
    path: Path, line: int, stamp: dt.datetime, start: dt.datetime, elapsed: int, options: _MeasurementOptions
) -> SiteError:
    """The error for data that do not end with the hour to a Monday 00:00 (whole weeks)."""
    shift = _HOUR if options.stamped_end else dt.timedelta(0)
    week_end = start + dt.timedelta(hours=(elapsed // cat.HOURS_PER_WEEK + 1) * cat.HOURS_PER_WEEK - 1) + shift
    ending = "ending on a Sunday at 23:00"
    if options.stamped_end:
        ending = 'ending with the row Monday 00:00 (stamped = "end": the hour from Sunday 23:00)'
    message = (
        f"{path}:{line}: the data end at {calendar.day_name[stamp.weekday()]} {_fmt(stamp)}: they must cover "
        f"whole weeks, {ending}; add rows up to {_fmt(week_end)} with empty cells for the hours not measured"
    )
    if not options.stamped_end and stamp.hour == 0 and elapsed % cat.HOURS_PER_WEEK == 0:
        message += (
            " (or, if the rows are stamped at the end of their hour, 00:00 for 23:00-24:00, declare it in "
            'site.toml: [measurements] stamped = "end")'
        )
    return SiteError(message)


def _check_step(
    path: Path,
    line: int,
    stamp: dt.datetime,
    standard: dt.datetime,
    previous: tuple[int, dt.datetime, dt.datetime],
    zone: zoneinfo.ZoneInfo | None,
    weather: str | None,
    wording: _ZoneWording,
) -> None:
    """A row's timestamp (``stamp`` on the clock, ``standard`` in standard time) against the previous row's
    ``(line, stamp, standard)``: later, and (without ``zone``) no daylight-saving change.

    Raises SiteError ``"<path>:<line>: ..."`` at a duplicate or a time earlier than the previous; where the clock
    went back by less than an hour (hourly rows: a duplicate; sub-hourly ones: to the repeated hour's start) on a
    Sunday some zone's clock repeats that hour, or an hour is missing where one goes forward, it names the zone
    to declare (``wording.declare``; no such hint where that is None or ``zone`` is given).
    """
    previous_line, previous_stamp, previous_standard = previous
    declare = wording.declare
    hints = zone is None and declare is not None
    if standard <= previous_standard:
        message = f"{path}:{line}: duplicate timestamp {_fmt(stamp)} (also on line {previous_line})"
        if standard < previous_standard:
            message = (
                f"{path}:{line}: timestamp {_fmt(stamp)} is earlier than the previous row's "
                f"{_fmt(previous_stamp)} (line {previous_line})"
            )
        autumn = stamp.weekday() == 6 and stamp.hour <= 3 and stamp.month in _AUTUMN_MONTHS
        if hints and autumn and previous_stamp - stamp < _HOUR:
            zones = _zones_changing(stamp, "fold", weather)
            if zones:
                raise SiteError(
                    f"{message}, on a {calendar.month_name[stamp.month]} Sunday, the hour clocks go back (e.g. in "
                    f"{zones[0]}): the timestamps look like local daylight-saving time; "
                    + declare.format(zones[0])
                    + ", which reads the repeated hour as the next hour of standard time"
                )
        if standard < previous_standard:
            raise SiteError(f"{message}: sort the rows by time")
        if zone is not None:
            raise SiteError(f"{message}: the same hour of {zone.key}'s clock twice; remove one")
        if declare is None or not autumn:  # a clock going back is a hint only where clocks go back
            raise SiteError(f"{message}: remove one")
        raise SiteError(
            f"{message}; if the BMS exports daylight-saving time, "
            + declare.format("America/Chicago")
            + " or export in local standard time"
        )
    missing = previous_stamp.replace(minute=0, second=0, microsecond=0) + _HOUR  # the next hour on the clock
    if hints and missing + _HOUR <= standard < missing + 2 * _HOUR:
        if missing.weekday() == 6 and missing.hour <= 3 and missing.month in _SPRING_MONTHS:
            # the hour a clock skips, or (an export that moved its rows on an hour late) the one after it
            zones = _zones_changing(missing, "gap", weather) or _zones_changing(missing - _HOUR, "gap", weather)
            if zones:
                raise SiteError(
                    f"{path}:{line}: no row for {_fmt(missing)}, on the {calendar.month_name[missing.month]} Sunday "
                    f"clocks go forward (e.g. in {zones[0]}): the timestamps look like local daylight-saving time, "
                    "those from here an hour ahead of standard time; "
                    + declare.format(zones[0])
                    + " to convert them to standard time (autumn's repeated hour too), or, if that hour was not "
                    f"measured, add the row {_fmt(missing)} with empty cells"
                )


def _clock_change(stamp: dt.datetime, zone: zoneinfo.ZoneInfo) -> str | None:
    """``"gap"`` if local time ``stamp`` does not exist in ``zone`` (clocks go forward over it), ``"fold"`` if
    it happens twice (clocks go back), else None."""
    early, late = stamp.replace(tzinfo=zone, fold=0), stamp.replace(tzinfo=zone, fold=1)
    if early.utcoffset() == late.utcoffset():
        return None
    back = early.astimezone(dt.timezone.utc).astimezone(zone).replace(tzinfo=None)
    return "fold" if back == stamp else "gap"


@functools.lru_cache(maxsize=256)
def _standard_offset(zone: zoneinfo.ZoneInfo, year: int) -> dt.timedelta:
    """The UTC offset of ``zone``'s standard time in ``year``: the smaller of January's and July's (daylight
    saving puts clocks ahead; so does Ireland's summer 'standard' time, which tzdata counts the other way)."""
    return min(dt.datetime(year, month, 1, 12, tzinfo=zone).utcoffset() for month in (1, 7))


def _standard_time(stamp: dt.datetime, zone: zoneinfo.ZoneInfo, after: dt.datetime | None) -> dt.datetime | None:
    """Local clock time ``stamp`` of ``zone`` as the zone's local standard time (naive); None if the clock
    skips it. A repeated hour (clocks going back) is its first occurrence unless that is not after ``after``
    (the previous row's standard time)."""
    offset = _standard_offset(zone, stamp.year)
    found = []
    for fold in (0, 1):
        utc = stamp.replace(tzinfo=zone, fold=fold).astimezone(dt.timezone.utc)
        if utc.astimezone(zone).replace(tzinfo=None) == stamp:
            found.append(utc.replace(tzinfo=None) + offset)
    if not found:
        return None
    later = [s for s in found if after is None or s > after]
    return min(later or found)


@functools.lru_cache(maxsize=32)
def _epw_location(weather: str) -> tuple[float | None, str]:
    """``(standard time zone, hours from UTC; place)`` from the EPW header of ``weather``; ``(None, "")`` if
    unreadable (only hints use it)."""
    from buildenv.weather.epw import resolve_epw

    try:
        with resolve_epw(weather).open(encoding="latin-1") as handle:
            fields = handle.readline().split(",")
        return float(fields[8]), fields[1]
    except (BuildenvError, OSError, ValueError, IndexError, ImportError):
        return None, ""


def _zones_changing(stamp: dt.datetime, change: str, weather: str | None) -> list[str]:
    """IANA zones whose clocks skip (``change="gap"``) or repeat (``"fold"``) local time ``stamp``; those with the
    weather file's standard time first, then one named after its place, then by :data:`_ZONE_AREAS`."""
    tz_h, place = _epw_location(weather) if weather else (None, "")
    place = place.lower()
    ranked = []
    for name in zoneinfo.available_timezones():
        area = name.split("/")[0]
        if area not in _ZONE_AREAS:
            continue
        try:
            zone = zoneinfo.ZoneInfo(name)
        except (zoneinfo.ZoneInfoNotFoundError, ValueError, OSError):  # pragma: no cover - a broken tzdata entry
            continue
        if _clock_change(stamp, zone) != change:
            continue
        same_time = tz_h is not None and _standard_offset(zone, stamp.year) == dt.timedelta(hours=tz_h)
        same_place = bool(place) and name.rsplit("/", 1)[-1].replace("_", " ").lower() in place
        ranked.append((not same_time, not same_place, _ZONE_AREAS.index(area), name))
    return [name for *_, name in sorted(ranked)]
