"""Checking the consumption column of ``measurements.csv`` and converting it to kWh in each hour.

:func:`_check_not_negative` checks one cell, :func:`_check_not_a_register` the column in file order (readings of a
register that was not declared); :func:`_consumption` takes the hourly series (after the timestamps): meter
register readings differenced where ``[measurements] cumulative = true`` (:func:`_register_differences`), then
each hour checked against :data:`~buildenv.sites.model.MAX_KWH_PER_M2_PER_HOUR` (too large: Wh?) and the peak
against the least a building's metered lighting and plug loads use and, for a meter that includes heating or
cooling, the least it delivers in the weeks whose weather and indoor temperature need them (too small: MWh or GJ?,
:func:`_check_size`). Every problem raises :class:`~buildenv.errors.SiteError` as ``"<file>:<line>: <what is
wrong>"``. ``buildenv site import`` calls the same checks on an export's columns, with its column names and flags
in the messages.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, SiteError
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.model import MAX_KWH_PER_M2_PER_HOUR, MIN_PEAK_SHARE_OF_LEAST_POWER

#: The energy units a consumption column is found in too small, and the factor to kWh as a hint writes it.
_SMALL_UNITS = "MWh (multiply by 1000) or GJ (multiply by 1000/3.6 = 277.78)"

# A meter of heating or cooling (alone, or with lighting and plug loads, which only add to its peak) is checked in
# the weeks that need what it meters, from the week's mean of the measured indoor temperature (one day at least) and
# the EPW's outdoor dry-bulb temperature in each hour:
# - heating: indoor 17-24 degC on average (the catalogue's least heating setback to its highest comfort setpoint:
#   heated, and not so warm that internal gains alone may hold it). The least heat loss of heated offices in practice
#   is that of passive-house offices, designed to a heating load of 10 W/m2 at about 32 K below indoors: about
#   0.3 W/(m2 K) of floor area, ventilation with heat recovery included. Free heat (people, lights, plug loads and sun
#   by day, the heat the building stored by night) covers up to 3.5 W/m2 of it, the loss of the first 11.7 K: an hour
#   whose outdoor air is colder needs 0.3 W/m2 from the heating for each K beyond. The busiest hour delivers at least
#   the week's mean need, capped at MIN_THERMAL_PEAK_W_M2 (a week 15 K colder throughout needs 1 W/m2; some offices'
#   free heat is more). A mild week needs less: a January week in San Francisco about 0.4 W/m2, in Chicago 1.
# - cooling: outdoor no cooler than indoor on average. The envelope then carries no heat out on average: the cooling
#   removes the internal gains (people at the catalogue's least density, 0.02/m2 at about 70 W sensible, are
#   1.4 W/m2; lights and plug loads at least 0.6 W/m2 in their busiest hour, MIN_PEAK_SHARE_OF_LEAST_POWER) and
#   the sun's: at least MIN_THERMAL_PEAK_W_M2 in the busiest hour.
# Below that, such a meter is read in the wrong unit: an office heating or cooling at a typical 30-100 W/m2 peaks at
# 0.03-0.1 W/m2 in MWh, 0.1-0.4 W/m2 in GJ; in a mild week, heating at 3-15 W/m2 peaks at 0.003-0.05 W/m2.
#: Least energy a meter of heating (cooling) delivers in its busiest hour of the weeks that need heating (cooling),
#: W per m2 of floor area; heating: where the weeks' mean need (:data:`LEAST_HEAT_LOSS_W_M2_K`) is less, that.
MIN_THERMAL_PEAK_W_M2 = 1.0
#: Weeks that may need heating: the measured indoor temperature averages in this range, degC (the catalogue's least
#: heating setback to its highest heating comfort setpoint).
HEATING_WEEK_INDOOR_C = (cat.get("heating_setback_c").min, cat.get("heating_comfort_c").max)
#: Least heat loss of a heated office, W per m2 of floor area and K of indoor less outdoor temperature.
LEAST_HEAT_LOSS_W_M2_K = 0.3
#: Indoor less outdoor temperature, K, whose loss at the least heat loss free heat may cover in an hour: 3.5 W/m2,
#: so that a week 15 K colder throughout needs :data:`MIN_THERMAL_PEAK_W_M2`.
FREE_HEAT_K = 15.0 - MIN_THERMAL_PEAK_W_M2 / LEAST_HEAT_LOSS_W_M2_K
#: Fewest measured indoor temperatures that make a week's mean (one day), hours.
_MIN_MEASURED_HOURS = cat.HOURS_PER_DAY


def _check_not_negative(path: Path, line: int, value: float, column: str = "heat_consumption_kwh") -> None:
    if value < 0:
        raise SiteError(
            f"{path}:{line}: {column}={value:g} is negative: give the energy used "
            "during the hour (not a meter difference across a reset); leave it empty if unknown"
        )


def _consumption(
    path: Path,
    values: np.ndarray,
    line_at: np.ndarray,
    floor_area_m2: float,
    options: _MeasurementOptions,
    end_uses: tuple[str, ...],
    *,
    closing: tuple[float, int] = (np.nan, 0),
    indoor_c: np.ndarray | None = None,
    weather: str | None = None,
    start: dt.date | None = None,
    column: str = "heat_consumption_kwh",
) -> np.ndarray:
    """A meter's ``column`` (hourly over whole weeks, ``line_at``: each hour's CSV line, 0 where none) as kWh
    in each hour: register readings differenced where ``options.cumulative`` (``closing``: the reading at the end
    of the last hour and its line, NaN where none); then every hour checked against
    :data:`MAX_KWH_PER_M2_PER_HOUR` and the peak against the smallest plausible one (:func:`_check_size`, with
    ``indoor_c``, ``weather`` and ``start``). The caller checks that an undeclared register is not one
    (:func:`_check_not_a_register`)."""
    if options.cumulative:
        readings, lines = np.append(values, closing[0]), np.append(line_at, closing[1])
        q, line_of = _register_differences(path, readings, lines, options)
        q, line_of = q[:-1], line_of[:-1]
        what = "the register rises by {:g} kWh in the hour to this reading"
    else:
        q, line_of = values, line_at
        what = column + "={:g}"
    _check_size(path, q, line_of, floor_area_m2, end_uses, what, indoor_c=indoor_c, weather=weather, start=start)
    return q


def _outdoor_c(weather: str, start: dt.date, weeks: int) -> np.ndarray | None:
    """The EPW ``weather``'s outdoor dry-bulb temperature, degC, in each hour of ``weeks`` weeks from Monday
    ``start`` (flat; the EPW rows of :func:`buildenv.weather.epw.epw_hours`), or None where it cannot be read."""
    from buildenv.weather.epw import epw_hours, load_weather

    try:
        outdoor = load_weather(weather).channel("TAMB")
    except (BuildenvError, OSError):
        return None
    return outdoor[epw_hours(start, weeks).ravel()]


def _least_thermal_peak(indoor_c: np.ndarray, outdoor_c: np.ndarray, metered: np.ndarray, use: str) -> np.ndarray:
    """The least a meter of ``use`` (``"heating"`` or ``"cooling"``) delivers in its busiest metered hour of each
    week, W/m2, from ``(weeks, 168)`` indoor (NaN where missing) and outdoor temperatures, degC, over the hours
    ``metered`` (bool); 0 where the week needs none, or has under a day of indoor temperatures or of metered hours
    (see :data:`MIN_THERMAL_PEAK_W_M2`). Returns ``(weeks,)``."""
    measured = np.isfinite(indoor_c).sum(axis=1)
    indoor = np.nansum(indoor_c, axis=1) / np.maximum(measured, 1)
    hours = metered.sum(axis=1)
    if use == "heating":
        low, high = HEATING_WEEK_INDOOR_C
        beyond = np.maximum(indoor[:, None] - FREE_HEAT_K - outdoor_c, 0.0)
        beyond = np.where(metered, beyond, 0.0).sum(axis=1) / np.maximum(hours, 1)  # over the metered hours
        least = np.where((low <= indoor) & (indoor <= high), LEAST_HEAT_LOSS_W_M2_K * beyond, 0.0)
        least = np.minimum(least, MIN_THERMAL_PEAK_W_M2)
    else:
        least = np.where(outdoor_c.mean(axis=1) >= indoor, MIN_THERMAL_PEAK_W_M2, 0.0)
    return np.where((measured >= _MIN_MEASURED_HOURS) & (hours >= _MIN_MEASURED_HOURS), least, 0.0)


def _check_size(
    path: Path,
    q: np.ndarray,
    line_of: np.ndarray,
    floor_area_m2: float,
    end_uses: tuple[str, ...],
    what: str = "heat_consumption_kwh={:g}",
    fix_units: str | None = None,
    *,
    indoor_c: np.ndarray | None = None,
    weather: str | None = None,
    start: dt.date | None = None,
) -> None:
    """A SiteError if an hour of ``q`` (kWh in each hour, NaN where missing; ``line_of``: each hour's line) is
    above :data:`MAX_KWH_PER_M2_PER_HOUR` x ``floor_area_m2``, or the largest is below the least power of the
    metered ``end_uses``; for a meter that includes heating or cooling, and ``q`` over whole weeks from Monday
    ``start`` with their measured ``indoor_c`` (degC, NaN where missing) and the EPW ``weather``, if the largest
    in the weeks that need what it meters is below the least the neediest of them needs
    (:func:`_least_thermal_peak`, W/m2 of ``floor_area_m2``).
    ``what`` names a value in the message (a format taking it); the unit it looks like is named with the
    reader's conversion, or with ``fix_units`` (an import's flag) where given."""
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

    small = f"MWh or GJ: {fix_units}" if fix_units else _SMALL_UNITS
    powers = {"lighting": "lighting_power_w_m2", "plug_loads": "plug_load_w_m2"}
    metered = [use for use in powers if use in end_uses]
    if metered and np.isfinite(q).any():
        peak_at = int(np.nanargmax(q))
        peak = float(q[peak_at])
        peak_w_m2 = peak * 1000.0 / floor_area_m2
        least_w_m2 = MIN_PEAK_SHARE_OF_LEAST_POWER * sum(cat.get(powers[use]).min for use in metered)
        if 0 < peak_w_m2 < least_w_m2:
            raise SiteError(
                f"{path}:{line_of[peak_at]}: {what.format(peak)} is the largest in the file, {peak_w_m2:.3g} W/m2 "
                f"for {floor_area_m2:g} m2: below the {least_w_m2:g} W/m2 a building whose meter includes "
                f"{' and '.join(metered)} uses in its busiest hour (a tenth of the catalogue's least installed "
                f"power); looks like {small}"
            )
    thermal = [use for use in ("heating", "cooling") if use in end_uses]
    if not thermal or indoor_c is None or weather is None or start is None or not np.isfinite(q).any():
        return
    weeks = q.size // cat.HOURS_PER_WEEK
    outdoor_c = _outdoor_c(weather, start, weeks)
    if outdoor_c is None:
        return
    shape = (weeks, cat.HOURS_PER_WEEK)
    for use in thermal:
        metered = np.isfinite(q.reshape(shape))
        least = _least_thermal_peak(indoor_c.reshape(shape), outdoor_c.reshape(shape), metered, use)
        needs = least > 0
        if not needs.any():
            continue
        hours = np.where(np.repeat(needs, cat.HOURS_PER_WEEK), q, np.nan)
        peak_at = int(np.nanargmax(hours))
        peak = float(q[peak_at])
        peak_w_m2 = peak * 1000.0 / floor_area_m2
        bound = float(least[needs].max())
        if 0 < peak_w_m2 < bound:
            weather_of = (
                f"the indoor temperature averages {HEATING_WEEK_INDOOR_C[0]:g}-{HEATING_WEEK_INDOOR_C[1]:g} degC, "
                f"and each K the outdoor air of the weather file falls more than {FREE_HEAT_K:.3g} K below it needs "
                f"{LEAST_HEAT_LOSS_W_M2_K:g} W/m2, the least heat loss beyond free heat"
                if use == "heating"
                else "the outdoor air of the weather file averages no cooler than the indoor temperature"
            )
            raise SiteError(
                f"{path}:{line_of[peak_at]}: {what.format(peak)} is the largest in the {int(needs.sum())} week(s) "
                f"that need {use} ({weather_of}), {peak_w_m2:.3g} W/m2 for {floor_area_m2:g} m2: below the "
                f"{bound:.3g} W/m2 a {use} meter of an office delivers in its busiest hour of such weeks; looks like "
                f"{small}"
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
