"""Reading ``measurements.csv`` into hourly temperature and consumption arrays, whole weeks from a Monday.

:func:`_read_measurements` reads the file in three passes: each row's cells (header and its units, syntax,
temperature range, negative consumption) and each meter's column (not an undeclared meter register), then the
timestamps (:mod:`.timestamps`), then each meter's series (:mod:`.consumption`). A header in other units (Wh,
MWh or GJ, degF or K) and a temperature that looks like degF or K are named with the conversion that reads them
right. Every problem raises :class:`~buildenv.errors.SiteError` as ``"<file>:<line>: <what is wrong>"`` (line 1
is the header).
"""

from __future__ import annotations

import datetime as dt
import logging
import math
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.sites.cells import _check_width, _parse_value, _rows, _separator_hint
from buildenv.sites.consumption import _check_not_a_register, _check_not_negative, _consumption
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.model import ELECTRICITY_COLUMN, MEASUREMENT_COLUMNS, TEMPERATURE_RANGE_C
from buildenv.sites.timestamps import _TIMESTAMP, _hours, _parse_timestamp

log = logging.getLogger(__name__)

_TEMPERATURE_UNITS = {"f": "degF", "degf": "degF", "fahrenheit": "degF", "k": "K", "kelvin": "K", "degk": "K"}
_ENERGY_UNITS = {
    "wh": "Wh",
    "mwh": "MWh",
    "gwh": "GWh",
    "j": "J",
    "kj": "kJ",
    "mj": "MJ",
    "gj": "GJ",
    "btu": "Btu",
    "kbtu": "kBtu",
    "mmbtu": "MMBtu",
    "therm": "therm",
    "therms": "therm",
    "w": "W",
    "kw": "kW",
    "mw": "MW",
}


def _check_measurement_header(path: Path, header: list[str]) -> tuple[str, ...]:
    """The columns of a valid header: :data:`MEASUREMENT_COLUMNS`, with :data:`ELECTRICITY_COLUMN` after them when
    the site has a second meter."""
    for columns in (MEASUREMENT_COLUMNS, (*MEASUREMENT_COLUMNS, ELECTRICITY_COLUMN)):
        if tuple(header) == columns:
            return columns
    for column in header:
        low = column.lower()
        for prefix, units, expected in (
            ("indoor_temperature_", _TEMPERATURE_UNITS, "indoor_temperature_c (degC)"),
            ("heat_consumption_", _ENERGY_UNITS, "heat_consumption_kwh (kWh)"),
            ("electricity_", _ENERGY_UNITS, f"{ELECTRICITY_COLUMN} (kWh)"),
        ):
            if low.startswith(prefix) and low != expected.split()[0]:
                unit = low[len(prefix) :]
                label = f" is in {units[unit]}" if unit in units else f" has unit {unit!r}"
                raise SiteError(
                    f"{path}:1: wrong unit: column {column!r}{label}; expected {expected}: "
                    "convert the values and rename the column"
                )
    if header and _TIMESTAMP.fullmatch(header[0]):
        raise SiteError(f"{path}:1: missing header: the first line must be {','.join(MEASUREMENT_COLUMNS)}")
    raise SiteError(
        f"{path}:1: header is {','.join(header)!r}, expected the columns "
        f"{','.join(MEASUREMENT_COLUMNS)!r} (and {ELECTRICITY_COLUMN} for a second meter){_separator_hint(header)}"
    )


def _check_temperature(path: Path, line: int, value: float) -> None:
    lo, hi = TEMPERATURE_RANGE_C
    if lo <= value <= hi:
        return
    hint = ""
    if 50 < value < 130:
        hint = f"; looks like degF ({value:g} degF = {(value - 32) / 1.8:.1f} degC)"
    elif 240 < value < 340:
        hint = f"; looks like K ({value:g} K = {value - 273.15:.1f} degC)"
    raise SiteError(
        f"{path}:{line}: indoor_temperature_c={value:g} is outside [{lo:g}, {hi:g}] degC{hint}; "
        "fix the unit or leave the cell empty if the sensor failed"
    )


def _read_measurements(
    path: Path,
    floor_area_m2: float,
    options: _MeasurementOptions | None = None,
    end_uses: tuple[str, ...] = cat.DEFAULT_END_USES,
    weather: str | None = None,
    electricity_end_uses: tuple[str, ...] = (),
) -> tuple[dt.date, np.ndarray, np.ndarray, np.ndarray | None]:
    """Parse ``measurements.csv`` into ``(start Monday, temperature (weeks, 168), consumption (weeks, 168),
    electricity (weeks, 168) or None)``.

    The arrays are in local standard time by the start of the hour, consumption in kWh in the hour;
    ``options`` (``[measurements]``) say how the file departs from that, ``end_uses`` (``[meters]``) what the
    consumption sums (for its plausible size) and ``weather`` (the EPW) where the site's clock stands (its
    standard time must be that of ``options.time_zone``; the hints name zones by it) and, for a meter that includes
    heating or cooling, which weeks need them (:func:`~buildenv.sites.consumption._check_size`). An undeclared
    register is named before the timestamps are checked. ``electricity_end_uses`` (``[meters] electricity``):
    what the :data:`ELECTRICITY_COLUMN` sums; the column is required with them and refused without.

    Raises:
        SiteError: on the first problem, as ``"<file>:<line>: <what is wrong>"``.
    """
    options = options or _MeasurementOptions()
    rows = _rows(path)
    first = next(rows, None)
    if first is None:
        raise SiteError(f"{path}:1: empty file: expected the header {','.join(MEASUREMENT_COLUMNS)}")
    columns = _check_measurement_header(path, first[1])
    meters = columns[2:]
    if bool(electricity_end_uses) != (ELECTRICITY_COLUMN in meters):
        has, lacks = (
            (f"a column {ELECTRICITY_COLUMN}", "site.toml has no [meters] electricity (the end uses it sums)")
            if ELECTRICITY_COLUMN in meters
            else ("no column " + ELECTRICITY_COLUMN, "site.toml's [meters] electricity names a second meter")
        )
        raise SiteError(f"{path}:1: {has}, but {lacks}: give both, or neither")

    lines: list[int] = []
    stamps: list[dt.datetime] = []
    temperature: list[float] = []
    readings: list[list[float]] = [[] for _ in meters]
    for line, cells in rows:  # pass 1: every row's cells
        _check_width(path, line, cells, columns)
        # a register reading is an instant: 24:00 is the next day's 00:00 however its rows are stamped
        stamps.append(_parse_timestamp(path, line, cells[0], stamped_end=options.stamped_end or options.cumulative))
        t = _parse_value(path, line, columns[1], cells[1])
        if not math.isnan(t):
            _check_temperature(path, line, t)
        for k, column in enumerate(meters):
            q = _parse_value(path, line, column, cells[2 + k])
            if not math.isnan(q) and not options.cumulative:
                _check_not_negative(path, line, q, column)
            readings[k].append(q)
        lines.append(line)
        temperature.append(t)
    if not lines:
        raise SiteError(f"{path}:2: no data rows after the header")

    if not options.cumulative:  # before the timestamps: a register's closing reading is no row past the weeks
        for column, values in zip(meters, readings):
            _check_not_a_register(path, np.asarray(values), np.asarray(lines), column=column)

    start, hours, weeks = _hours(path, lines, stamps, options, weather)  # pass 2: the timestamps
    size = weeks * cat.HOURS_PER_WEEK
    keep = (hours >= 0) & (hours < size)
    if (hours < 0).any():
        log.debug("%s: %d row(s) before the first Monday in standard time left out", path, int((hours < 0).sum()))
    index = hours[keep]
    t_out = np.full(size, np.nan)
    line_at = np.zeros(size, int)
    t_out[index] = np.asarray(temperature)[keep]
    line_at[index] = np.asarray(lines)[keep]
    shape = (weeks, cat.HOURS_PER_WEEK)
    series = []
    for column, values, uses in zip(meters, readings, (end_uses, electricity_end_uses)):
        closing: tuple[float, int] = (math.nan, 0)
        if hours[-1] == size:  # a register's reading that closes the last hour (cumulative = true)
            closing = (values[-1], lines[-1])
        q_in = np.full(size, np.nan)
        q_in[index] = np.asarray(values)[keep]
        q_out = _consumption(  # pass 3: each meter's series
            path,
            q_in,
            line_at,
            floor_area_m2,
            options,
            uses,
            closing=closing,
            indoor_c=t_out,
            weather=weather,
            start=start.date(),
            column=column,
        )
        series.append(q_out.reshape(shape))
    return start.date(), t_out.reshape(shape), series[0], series[1] if len(series) > 1 else None
