"""Weather: EPW files read into the catalogue's W_k channels.

EPW files are parsed with :func:`pvlib.iotools.read_epw`. Row ``h`` of the result covers hour ``[h, h+1)``
of the year (EPW's hour-ending value ``h+1``), the same hour EnergyPlus reports as time step ``h``.
The 16 TMY3 files shipped by ``pyenergyplus-lbnl`` are available by short name (``usa_il_chicago``, ...);
any EPW path works too.

Derived channels: ``IBEAM_H = DNI * cos(zenith)`` and ``IBEAM_N = DNI * max(0, cos(angle of incidence on a
vertical north-facing surface))``, with the sun position of the middle of the hour (pvlib, NREL SPA).
"""

from __future__ import annotations

import calendar
import datetime as dt
import functools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import WeatherError

HOURS_PER_YEAR = 8760
#: Days of each month of a 365-day EPW year.
DAYS_PER_MONTH = np.array([31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31])


def month_of_hour() -> np.ndarray:
    """``(8760,)`` month (0 = January) of each hour of a 365-day EPW year."""
    return np.repeat(np.arange(12), DAYS_PER_MONTH * 24)


def epw_day_of_year(day: dt.date) -> int:
    """Day index 0..364 of ``day`` in a 365-day EPW year: Feb 29 -> Feb 28, later leap-year days shift back."""
    index = (day - dt.date(day.year, 1, 1)).days
    if calendar.isleap(day.year) and index >= 59:  # 59 = Feb 29
        index -= 1
    return index


def epw_hours(start: dt.date, weeks: int) -> np.ndarray:
    """Row of a 365-day EPW year (8760 hourly rows) for every hour of ``weeks`` weeks from ``start``,
    ``(weeks, 168)`` int in ``0 .. 8759``: each day matched to the same calendar day of the EPW year
    (:func:`epw_day_of_year`), a week that runs past Dec 31 continuing at the start of the EPW year."""
    days = np.array(
        [[epw_day_of_year(start + dt.timedelta(days=7 * k + d)) for d in range(7)] for k in range(weeks)], dtype=int
    )
    return (days[:, :, None] * 24 + np.arange(24)).reshape(weeks, 7 * 24)


def shipped_weather() -> dict[str, str]:
    """Short name -> absolute path of the TMY3 EPW files shipped with pyenergyplus-lbnl."""
    from pyenergyplus import dataset

    return dict(sorted(dataset.weather_files.items()))


def resolve_epw(name_or_path: str | os.PathLike) -> Path:
    """Turn a short name (``usa_il_chicago``) or a path into an existing EPW path.

    Raises:
        WeatherError: the name is unknown and no such file exists (the message lists the short names).
    """
    text = str(name_or_path)
    shipped = shipped_weather()
    if text in shipped:
        return Path(shipped[text])
    path = Path(text).expanduser()
    if path.is_file():
        return path.resolve()
    if path.suffix.lower() == ".epw" or os.sep in text:
        raise WeatherError(f"weather file not found: {text}")
    raise WeatherError(f"unknown weather {text!r}: give an EPW path or one of {', '.join(shipped)}")


@dataclass(frozen=True)
class Weather:
    """One year of hourly weather.

    Attributes:
        name: short name or file stem.
        path: EPW path.
        latitude_deg, longitude_deg, timezone_h, elevation_m: site metadata from the EPW header.
        hourly: array ``(8760, len(catalogue.WEATHER_NAMES))`` in catalogue order and units.
    """

    name: str
    path: Path
    latitude_deg: float
    longitude_deg: float
    timezone_h: float
    elevation_m: float
    hourly: np.ndarray

    def channel(self, name: str) -> np.ndarray:
        """One weather channel as an ``(8760,)`` array."""
        return self.hourly[:, cat.WEATHER_NAMES.index(cat.get(name).name)]

    def weeks(self, start_week: int, n_weeks: int) -> np.ndarray:
        """Weeks ``start_week .. start_week + n_weeks - 1`` as ``(n_weeks, 168, channels)``."""
        lo, hi = start_week * cat.HOURS_PER_WEEK, (start_week + n_weeks) * cat.HOURS_PER_WEEK
        if n_weeks < 1 or start_week < 0 or hi > HOURS_PER_YEAR:
            raise WeatherError(f"weeks {start_week}..{start_week + n_weeks - 1} fall outside the year of {self.path}")
        return self.hourly[lo:hi].reshape(n_weeks, cat.HOURS_PER_WEEK, -1)

    def monthly_mean_temperature_c(self) -> np.ndarray:
        """Mean outdoor dry-bulb temperature of each month, degC, shape ``(12,)``."""
        edges = np.concatenate([[0], np.cumsum(DAYS_PER_MONTH * 24)])
        tamb = self.channel("TAMB")
        return np.array([tamb[edges[m] : edges[m + 1]].mean() for m in range(12)])


@functools.lru_cache(maxsize=32)
def _load_cached(path: str, mtime_ns: int, size: int) -> Weather:  # keyed on the file's state too
    import pandas as pd
    import pvlib

    try:
        data, meta = pvlib.iotools.read_epw(path, coerce_year=2001)
    except Exception as exc:  # pvlib raises assorted parser errors on a malformed file
        raise WeatherError(f"cannot read EPW {path}: {exc}") from exc
    if len(data) != HOURS_PER_YEAR:
        raise WeatherError(
            f"{path}: expected {HOURS_PER_YEAR} hourly rows, found {len(data)} "
            "(sub-hourly or leap-year EPW files are not supported)"
        )
    lat, lon, alt = float(meta["latitude"]), float(meta["longitude"]), float(meta.get("altitude", 0.0))
    mid_hour = data.index + pd.Timedelta(minutes=30)
    solpos = pvlib.solarposition.get_solarposition(mid_hour, lat, lon, altitude=alt)
    dni = data["dni"].to_numpy(float)
    dhi = data["dhi"].to_numpy(float)
    ghi = data["ghi"].to_numpy(float)
    cos_zenith = np.cos(np.radians(solpos["apparent_zenith"].to_numpy()))
    beam_h = np.where(cos_zenith > 0, dni * cos_zenith, 0.0)
    aoi_north = pvlib.irradiance.aoi(90.0, 0.0, solpos["apparent_zenith"], solpos["azimuth"]).to_numpy()
    beam_n = dni * np.clip(np.cos(np.radians(aoi_north)), 0.0, None) * (cos_zenith > 0)
    columns = {
        "DNI": dni,
        "IBEAM_H": beam_h,
        "IBEAM_N": beam_n,
        "IDIFF_H": dhi,
        "IGLOB_H": ghi,
        "RHUM": data["relative_humidity"].to_numpy(float),
        "TAMB": data["temp_air"].to_numpy(float),
        "WIND_SPEED": data["wind_speed"].to_numpy(float),
        "WIND_DIR": data["wind_direction"].to_numpy(float),
    }
    hourly = np.stack([columns[name] for name in cat.WEATHER_NAMES], axis=1)
    bad = ~np.isfinite(hourly)
    if bad.any():
        row, colno = np.argwhere(bad)[0]
        raise WeatherError(f"{path}: missing {cat.WEATHER_NAMES[colno]} at data row {row + 1} (line {row + 9})")
    hourly.setflags(write=False)
    name = Path(path).stem
    for short, shipped_path in shipped_weather().items():
        if Path(shipped_path) == Path(path):
            name = short
    return Weather(name, Path(path), lat, lon, float(meta["TZ"]), alt, hourly)


def load_weather(name_or_path: str | os.PathLike) -> Weather:
    """Read an EPW (short name or path) into a :class:`Weather` (cached per process)."""
    path = resolve_epw(name_or_path)
    stat = path.stat()
    return _load_cached(str(path), stat.st_mtime_ns, stat.st_size)
