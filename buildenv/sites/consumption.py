"""Checking the consumption column of ``measurements.csv`` and converting it to kWh in each hour.

:func:`_check_not_negative` checks one cell; :func:`_consumption` takes the hourly series (after the timestamps):
meter register readings differenced where ``[measurements] cumulative = true`` (:func:`_register_differences`),
else recognised as a register that was not declared (:func:`_check_not_a_register`); then each hour checked against
:data:`~buildenv.sites.model.MAX_KWH_PER_M2_PER_HOUR` (too large: Wh?) and the peak against the least a building's
metered lighting and plug loads use (too small: MWh or GJ?, :func:`_check_size`). Every problem raises
:class:`~buildenv.errors.SiteError` as ``"<file>:<line>: <what is wrong>"``. ``buildenv site import`` calls the
same checks on an export's columns, with its column names and flags in the messages.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.model import MAX_KWH_PER_M2_PER_HOUR, MIN_PEAK_SHARE_OF_LEAST_POWER

#: The energy units a consumption column is found in too small, and the factor to kWh as a hint writes it.
_SMALL_UNITS = "MWh (multiply by 1000) or GJ (multiply by 1000/3.6 = 277.78)"


def _check_not_negative(path: Path, line: int, value: float) -> None:
    if value < 0:
        raise SiteError(
            f"{path}:{line}: heat_consumption_kwh={value:g} is negative: give the energy used "
            "during the hour (not a meter difference across a reset); leave it empty if unknown"
        )


def _consumption(
    path: Path,
    values: np.ndarray,
    line_at: np.ndarray,
    floor_area_m2: float,
    options: _MeasurementOptions,
    end_uses: tuple[str, ...],
) -> np.ndarray:
    """The consumption column (hourly, ``line_at``: each hour's CSV line, 0 where none) as kWh in each hour:
    register readings differenced where ``options.cumulative``, else checked not to be a register; then every
    hour checked against :data:`MAX_KWH_PER_M2_PER_HOUR` and the peak against the smallest plausible one."""
    if options.cumulative:
        q, line_of = _register_differences(path, values, line_at, options)
        what = "the register rises by {:g} kWh in the hour to this reading"
    else:
        _check_not_a_register(path, values, line_at)
        q, line_of = values, line_at
        what = "heat_consumption_kwh={:g}"
    _check_size(path, q, line_of, floor_area_m2, end_uses, what)
    return q


def _check_size(
    path: Path,
    q: np.ndarray,
    line_of: np.ndarray,
    floor_area_m2: float,
    end_uses: tuple[str, ...],
    what: str = "heat_consumption_kwh={:g}",
    fix_units: str | None = None,
) -> None:
    """A SiteError if an hour of ``q`` (kWh in each hour, NaN where missing; ``line_of``: each hour's line) is
    above :data:`MAX_KWH_PER_M2_PER_HOUR` x ``floor_area_m2``, or the largest is below the least power of the
    metered ``end_uses``. ``what`` names a value in the message (a format taking it); the unit it looks like is
    named with the reader's conversion, or with ``fix_units`` (an import's flag) where given."""
    limit = MAX_KWH_PER_M2_PER_HOUR * floor_area_m2
    over = np.flatnonzero(q > limit)  # NaN never is
    if over.size:
        value = float(q[over[0]])
        hint = ""
        if value / 1000.0 <= limit:
            hint = f"; looks like Wh: {fix_units}" if fix_units else "; looks like Wh (divide by 1000)"
        raise SiteError(
            f"{path}:{line_of[over[0]]}: {what.format(value)} is above "
            f"{MAX_KWH_PER_M2_PER_HOUR:g} kWh/m2 in one hour ({limit:g} kWh for "
            f"{floor_area_m2:g} m2){hint}"
        )

    powers = {"lighting": "lighting_power_w_m2", "plug_loads": "plug_load_w_m2"}
    metered = [use for use in powers if use in end_uses]
    if metered and np.isfinite(q).any():
        peak_at = int(np.nanargmax(q))
        peak = float(q[peak_at])
        peak_w_m2 = peak * 1000.0 / floor_area_m2
        least_w_m2 = MIN_PEAK_SHARE_OF_LEAST_POWER * sum(cat.get(powers[use]).min for use in metered)
        if 0 < peak_w_m2 < least_w_m2:
            small = f"MWh or GJ: {fix_units}" if fix_units else _SMALL_UNITS
            raise SiteError(
                f"{path}:{line_of[peak_at]}: {what.format(peak)} is the largest in the file, {peak_w_m2:.3g} W/m2 "
                f"for {floor_area_m2:g} m2: below the {least_w_m2:g} W/m2 a building whose meter includes "
                f"{' and '.join(metered)} uses in its busiest hour (a tenth of the catalogue's least installed "
                f"power); looks like {small}"
            )


def _check_not_a_register(
    path: Path,
    values: np.ndarray,
    line_at: np.ndarray,
    *,
    column: str = "heat_consumption_kwh",
    per_day: int = cat.HOURS_PER_DAY,
    interval: str = "hour",
    fix: str = "give the hourly differences, or declare it in site.toml: [measurements] cumulative = true",
) -> None:
    """A SiteError at the first reading if ``values`` (``per_day`` readings a day, NaN where missing;
    ``line_at``: each one's line) never fall over a day or more while rising well beyond their largest step:
    readings of a cumulative meter register, not the energy of each ``interval``. The message names ``column``
    and ``fix`` (the site reader's by default)."""
    measured = np.flatnonzero(np.isfinite(values))
    if measured.size < per_day:
        return
    series = values[measured]
    steps = np.diff(series)
    rise = float(series[-1] - series[0])
    if (steps >= 0).all() and rise > 0 and rise >= 5 * float(steps.max()):
        raise SiteError(
            f"{path}:{line_at[measured[0]]}: {column} never falls, from {series[0]:g} here to "
            f"{series[-1]:g} on line {line_at[measured[-1]]}: a cumulative meter register, not the energy of "
            f"each {interval}; {fix}"
        )


def _register_differences(
    path: Path,
    readings: np.ndarray,
    line_at: np.ndarray,
    options: _MeasurementOptions,
    *,
    reading: str = "the register reading",
    interval: str = "hour",
    fix: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(energy in each interval, the line of the later reading of each)`` from meter register ``readings``, one
    per ``interval`` (``line_at``: each one's line, 0 where none), in the readings' unit.

    A reading is the register at its timestamp (the start of the interval; with ``options.stamped_end``, its
    end): an interval's energy is the next reading less this one, missing where either is; the last interval
    (the first, for end stamps) has no reading to close it and is missing. A falling reading raises SiteError
    at its line, naming it ``reading`` and the fix ``fix`` (by default the site reader's, at ``options.where``).
    """
    earlier, later = readings[:-1], readings[1:]
    steps = later - earlier
    falls = np.flatnonzero(steps < 0)
    if falls.size:
        k = int(falls[0])
        raise SiteError(
            f"{path}:{line_at[k + 1]}: {reading} {later[k]:g} is below the previous {interval}'s "
            f"{earlier[k]:g} (line {line_at[k]}): a meter reset or replacement? leave this reading empty (the "
            f"{interval}s on either side become gaps), "
            + (fix or f"or give the hourly differences without cumulative = true ({options.where})")
        )
    q = np.full(readings.shape, np.nan)
    line_of = np.zeros(readings.shape, int)
    hours = slice(1, None) if options.stamped_end else slice(None, -1)
    q[hours] = steps
    line_of[hours] = line_at[1:]
    return q, line_of
