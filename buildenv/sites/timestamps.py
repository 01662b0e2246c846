"""Reading and checking the timestamps of ``measurements.csv``: each row's hour in local standard time.

:func:`_parse_timestamp` reads one cell (on the hour; ``24:00`` only with ``stamped = "end"``); :func:`_hours`
converts the rows' timestamps to hours since the first Monday 00:00 in local standard time (from the clock of
``[measurements] time_zone`` where declared, back an hour where ``stamped = "end"``), checks their order, duplicates
and daylight-saving gaps (:func:`_check_step`) and that the data cover whole weeks, and names the likely cause: a
daylight-saving clock (with the IANA zones whose clocks change then, :func:`_zones_changing`), end-of-hour stamps,
missing rows. Every problem raises :class:`~buildenv.errors.SiteError` as ``"<file>:<line>: <what is wrong>"``.
"""

from __future__ import annotations

import calendar
import datetime as dt
import functools
import logging
import re
import zoneinfo
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, SiteError
from buildenv.sites.measurement_options import _MeasurementOptions

log = logging.getLogger(__name__)

#: Months whose Sundays see clocks go forward (north: March, April; south: September, October) or back.
_SPRING_MONTHS = (3, 4, 9, 10)
_AUTUMN_MONTHS = (10, 11, 3, 4)
#: Zone areas whose IANA names a hint may suggest (not Etc/, US/, ...), in the order it prefers them.
_ZONE_AREAS = ("America", "Europe", "Australia", "Pacific", "Asia", "Africa", "Atlantic", "Indian")
_TIMESTAMP = re.compile(r"(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2})(?::(\d{2}))?")
_TIMESTAMP_WITH_ZONE = re.compile(r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(?::\d{2})?(?:\.\d+)?\s*(?:Z|[+-]\d{2}:?\d{2})")


def _parse_timestamp(path: Path, line: int, text: str, *, stamped_end: bool = False) -> dt.datetime:
    """A cell as a naive datetime on the hour; ``24:00`` (the end of a day) only for rows stamped at the end of
    their hour."""
    m = _TIMESTAMP.fullmatch(text)
    if m is None:
        if _TIMESTAMP_WITH_ZONE.fullmatch(text):
            raise SiteError(
                f"{path}:{line}: timestamp {text!r} has a UTC offset: give local standard time "
                "without an offset, as 'YYYY-MM-DD HH:MM'"
            )
        raise SiteError(
            f"{path}:{line}: cannot read timestamp {text!r}: expected 'YYYY-MM-DD HH:MM' "
            "(or with a 'T'), local standard time of the start of the hour"
        )
    year, month, day, hour, minute, second = (int(g) if g else 0 for g in m.groups())
    end_of_day = hour == 24 and not minute and not second
    if end_of_day and not stamped_end:
        raise SiteError(
            f"{path}:{line}: timestamp {text!r} is 24:00, the end of a day: the rows are stamped at the end of "
            'their hour (24:00 for 23:00-24:00); declare it in site.toml: [measurements] stamped = "end"'
        )
    try:
        stamp = dt.datetime(year, month, day, 0 if end_of_day else hour, minute, second)
    except ValueError as exc:
        raise SiteError(f"{path}:{line}: cannot read timestamp {text!r}: {exc}") from exc
    if minute or second:
        raise SiteError(
            f"{path}:{line}: timestamp {text!r} is not on the hour: each row is the hour starting "
            "at HH:00 (resample sub-hourly data: mean temperature, summed kWh)"
        )
    return stamp + dt.timedelta(days=1) if end_of_day else stamp


def _fmt(stamp: dt.datetime) -> str:
    return stamp.strftime("%Y-%m-%d %H:%M")


_HOUR = dt.timedelta(hours=1)


def _hours(
    path: Path, lines: list[int], stamps: list[dt.datetime], options: _MeasurementOptions, weather: str | None
) -> tuple[dt.datetime, np.ndarray, int]:
    """``(first Monday 00:00, hour of each row since then in local standard time, weeks)`` of the timestamps.

    Order, duplicates and gaps are checked in standard time (converted from ``options.time_zone`` where
    declared), whole weeks on the file's clock or in standard time: with a time zone, an export of whole weeks
    of the local clock in summer starts an hour before the first Monday in standard time (that row gets hour
    -1) and ends an hour before the last Sunday's 23:00 (that hour stays missing).
    """
    zone = options.time_zone
    shift = _HOUR if options.stamped_end else dt.timedelta(0)
    standard = _standard_time(stamps[0], zone, None) if zone is not None else stamps[0]
    if standard is None:
        raise _skipped_hour_error(path, lines[0], stamps[0], options)
    for start in (standard - shift, stamps[0] - shift):  # in standard time, on the clock
        if start.weekday() == 0 and start.hour == 0:
            break
    else:
        raise _first_row_error(path, lines, stamps, options)
    if zone is not None and weather:
        tz_h, _ = _epw_location(weather)
        offset = _standard_offset(zone, start.year)
        if tz_h is not None and offset != dt.timedelta(hours=tz_h):
            log.warning(
                "%s: time_zone %r keeps standard time UTC%+g h, the weather file (%s) UTC%+g h: the measurements "
                "are converted to the zone's standard time, not the weather's",
                options.where,
                zone.key,
                offset.total_seconds() / 3600,
                weather,
                tz_h,
            )

    hours: list[int] = []
    previous: tuple[int, dt.datetime, dt.datetime] | None = None  # line, stamp, standard time
    for line, stamp in zip(lines, stamps):
        if previous is not None:  # the first row's standard time is known
            standard = stamp if zone is None else _standard_time(stamp, zone, previous[2])
            if standard is None:
                raise _skipped_hour_error(path, line, stamp, options)
            _check_step(path, line, stamp, standard, previous, zone, weather)
        hours.append(int((standard - shift - start).total_seconds()) // 3600)
        previous = (line, stamp, standard)

    week = cat.HOURS_PER_WEEK
    clock = int((stamps[-1] - shift - start).total_seconds()) // 3600
    for last in (hours[-1], clock):  # in standard time, on the clock
        if last % week == week - 1:
            return start, np.asarray(hours), last // week + 1
    raise _last_row_error(path, lines[-1], stamps[-1], start, clock, options)


def _skipped_hour_error(path: Path, line: int, stamp: dt.datetime, options: _MeasurementOptions) -> SiteError:
    zone = options.time_zone
    return SiteError(
        f"{path}:{line}: timestamp {_fmt(stamp)} does not exist on the clock of {zone.key} (time_zone, "
        f"{options.where}), which goes forward over it: a file in local standard time needs no time_zone; a "
        "file on that clock has no such row"
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
) -> None:
    """A row's timestamp against the previous row's: later, and (without a time zone) no daylight-saving jump."""
    previous_line, previous_stamp, previous_standard = previous
    declare = 'declare the zone of the BMS clock in site.toml, [measurements] time_zone = "{}" (an IANA name)'
    if standard == previous_standard:
        message = f"{path}:{line}: duplicate timestamp {_fmt(stamp)} (also on line {previous_line})"
        if zone is not None:
            raise SiteError(f"{message}: the same hour of {zone.key}'s clock twice; remove one")
        if stamp.weekday() == 6 and stamp.hour <= 3 and stamp.month in _AUTUMN_MONTHS:
            zones = _zones_changing(stamp, "fold", weather)
            if zones:
                raise SiteError(
                    f"{message}, on a {calendar.month_name[stamp.month]} Sunday, the hour clocks go back (e.g. in "
                    f"{zones[0]}): the timestamps look like local daylight-saving time; "
                    + declare.format(zones[0])
                    + ", which reads the repeated hour as the next hour of standard time"
                )
        raise SiteError(
            f"{message}; if the BMS exports daylight-saving time, "
            + declare.format("America/Chicago")
            + " or export in local standard time"
        )
    if standard < previous_standard:
        raise SiteError(
            f"{path}:{line}: timestamp {_fmt(stamp)} is earlier than the previous row's "
            f"{_fmt(previous_stamp)} (line {previous_line}): sort the rows by time"
        )
    if zone is None and standard - previous_standard == 2 * _HOUR:
        missing = previous_stamp + _HOUR
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
