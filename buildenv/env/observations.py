"""What an operator knows before the week: the observation of BuildingWeek-v0.

``compact`` (default, 75 values, every one roughly in [-3, 5]):

- weather forecast, per day Monday..Sunday (6 x 7 = 42): mean, minimum and maximum outdoor temperature
  (degC / 20), mean global horizontal irradiance (W/m2 / 300), mean wind speed (m/s / 10), mean relative
  humidity (% / 100);
- occupancy schedule (10): arrival and departure hour of each weekday, scaled onto [-1, 1] by the
  catalogue range;
- calendar (2): sine and cosine of the week's angle in the year (week of the year / 52 x 2 pi);
- calibrated building parameters (21): theta_build scaled onto [-1, 1] by the catalogue ranges.

``forecast``: ``compact`` followed by the full hourly forecast, 168 hours x 8 channels (DNI, IBEAM_H,
IBEAM_N, IDIFF_H, IGLOB_H / 300; RHUM / 100; TAMB / 20; WIND_SPEED / 10), hour-major: 75 + 1,344 values.

Every value is clipped into [-10, 10] (the observation space's bounds).
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

OBSERVATION_KINDS = ("compact", "forecast")
BOUND = 10.0
_SCALE = {
    "DNI": 300.0,
    "IBEAM_H": 300.0,
    "IBEAM_N": 300.0,
    "IDIFF_H": 300.0,
    "IGLOB_H": 300.0,
    "RHUM": 100.0,
    "TAMB": 20.0,
    "WIND_SPEED": 10.0,
}
FORECAST_CHANNELS = tuple(_SCALE)


def observation_size(kind: str) -> int:
    """Length of the observation vector of ``kind``."""
    compact = 6 * len(cat.DAYS) + 2 * len(cat.WEEKDAYS) + 2 + len(cat.THETA_NAMES)
    return compact + (cat.HOURS_PER_WEEK * len(FORECAST_CHANNELS) if kind == "forecast" else 0)


def _unit(values: np.ndarray, group: str) -> np.ndarray:
    lo, hi = cat.bounds(group)
    return 2.0 * (np.asarray(values, dtype=float) - lo) / (hi - lo) - 1.0


def observe(
    weather: np.ndarray, week_of_year: np.ndarray, occupancy: np.ndarray, theta: np.ndarray, kind: str = "compact"
) -> np.ndarray:
    """Observations ``(N, observation_size(kind))`` float32 of N weeks.

    Args:
        weather: hourly weather ``(N, 168, 9)`` (catalogue channels and units).
        week_of_year: ``(N,)`` week index in the year (0-based).
        occupancy: ``(5, 2)`` weekday arrival/departure hours.
        theta: ``(21,)`` theta_build.
        kind: ``compact`` or ``forecast``.
    """
    weather = np.asarray(weather, dtype=float)
    n = len(weather)
    daily = weather.reshape(n, len(cat.DAYS), cat.HOURS_PER_DAY, -1)

    def ch(name: str) -> np.ndarray:
        return daily[..., cat.WEATHER_NAMES.index(name)]

    per_day = np.stack(
        [
            ch("TAMB").mean(-1) / _SCALE["TAMB"],
            ch("TAMB").min(-1) / _SCALE["TAMB"],
            ch("TAMB").max(-1) / _SCALE["TAMB"],
            ch("IGLOB_H").mean(-1) / _SCALE["IGLOB_H"],
            ch("WIND_SPEED").mean(-1) / _SCALE["WIND_SPEED"],
            ch("RHUM").mean(-1) / _SCALE["RHUM"],
        ],
        axis=-1,
    ).reshape(n, -1)
    angle = 2.0 * np.pi * np.asarray(week_of_year, dtype=float) / cat.WEEKS_PER_YEAR
    parts = [
        per_day,
        np.broadcast_to(_unit(occupancy, "occupancy").reshape(-1), (n, occupancy.size)),
        np.stack([np.sin(angle), np.cos(angle)], axis=-1),
        np.broadcast_to(_unit(theta, "theta_build"), (n, len(cat.THETA_NAMES))),
    ]
    if kind == "forecast":
        idx = [cat.WEATHER_NAMES.index(c) for c in FORECAST_CHANNELS]
        scale = np.array([_SCALE[c] for c in FORECAST_CHANNELS])
        parts.append((weather[..., idx] / scale).reshape(n, -1))
    elif kind != "compact":
        raise ValueError(f"unknown observation kind {kind!r}; choose one of {', '.join(OBSERVATION_KINDS)}")
    return np.clip(np.concatenate(parts, axis=-1), -BOUND, BOUND).astype(np.float32)
