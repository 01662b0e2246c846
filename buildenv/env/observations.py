"""What an operator knows before the week: the observation of BuildingWeek-v0.

``compact`` (default, 77 values, every one roughly in [-3, 5]):

- weather forecast, per day Monday..Sunday (6 x 7 = 42): mean, minimum and maximum outdoor temperature
  (degC / 20), mean global horizontal irradiance (W/m2 / 300), mean wind speed (m/s / 10), mean relative
  humidity (% / 100);
- occupancy schedule (10): arrival and departure hour of each weekday, scaled onto [-1, 1] by the
  catalogue range;
- calendar (2): sine and cosine of the week's angle in the year (week of the year / 52 x 2 pi);
- calibrated building parameters (23): theta_build scaled onto [-1, 1] by the catalogue ranges.

``forecast``: ``compact`` followed by the full hourly forecast, 168 hours x 8 channels (DNI, IBEAM_H,
IBEAM_N, IDIFF_H, IGLOB_H / 300; RHUM / 100; TAMB / 20; WIND_SPEED / 10), hour-major: 77 + 1,344 = 1,421 values.

Every value is clipped into [-10, 10] (the observation space's bounds).

:func:`forecast` makes the forecast imperfect (the environment's ``forecast_noise``, off by default): the true
week's weather plus errors that grow with lead time, drawn from the environment's own generator.
"""

from __future__ import annotations

from collections.abc import Sequence

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
IRRADIANCE_CHANNELS = ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H")
#: relative error of the irradiance forecast (1 = 100 %) per K of ``forecast_noise``, at the week's end: with
#: 2 K, 30 %, of the order of day-ahead-to-week-ahead errors of daily irradiation under changing cloud cover
IRRADIANCE_ERROR_PER_K = 0.15
#: relative error of the wind speed forecast per K of ``forecast_noise``, at the week's end
WIND_ERROR_PER_K = 0.15
#: error of the relative humidity forecast, %-points per K of ``forecast_noise``, at the week's end (on top of
#: the humidity the temperature error implies)
HUMIDITY_ERROR_PER_K = 5.0


def _saturation_hpa(t_c: np.ndarray) -> np.ndarray:
    """Saturation vapour pressure over water (hPa) at ``t_c`` (degC), Magnus formula (WMO constants)."""
    return 6.112 * np.exp(17.62 * t_c / (243.12 + t_c))


def forecast(weather: np.ndarray, noise_k: float, rngs: Sequence[np.random.Generator]) -> np.ndarray:
    """Forecasts ``(N, 168, 9)`` of N true weeks of weather ``(N, 168, 9)``: the truth plus errors from ``rngs``.

    Each error is a random walk over the week's hours (Gaussian increments), so that its standard deviation
    grows with lead time, ``s * sqrt((h + 1) / 168)`` at hour h: ``s * sqrt((d + 1) / 7)`` at the end of day d
    (Monday 0), ``s`` at the end of Sunday, and successive hours' and days' errors are correlated as real
    forecast errors are (a forecast too warm on Tuesday is likely too warm on Wednesday):

    - outdoor temperature (TAMB): ``+ e_T``, ``s = noise_k`` K;
    - irradiance (DNI, IBEAM_H, IBEAM_N, IDIFF_H, IGLOB_H): ``x max(0, 1 + e_I)``, ``s = IRRADIANCE_ERROR_PER_K x
      noise_k``, one factor for all five (they stay consistent, night stays dark);
    - wind speed: ``x max(0, 1 + e_W)``, ``s = WIND_ERROR_PER_K x noise_k``;
    - relative humidity: the humidity at the forecast temperature with the true vapour pressure (a forecast 2 K
      too warm reads about 12 % drier) ``+ e_H``, ``s = HUMIDITY_ERROR_PER_K x noise_k`` %-points, clipped
      into [0, 100];
    - wind direction (not observed): unchanged.

    Args:
        weather: true hourly weather ``(N, 168, 9)`` (catalogue channels and units).
        noise_k: ``s`` of the temperature error at the week's end, K (>= 0); 0 returns ``weather`` as it is
            and draws nothing.
        rngs: N generators, one per week; each draws 4 x 168 standard normals (row i from ``rngs[i]``), so a
            week's forecast depends only on its own generator.
    Returns:
        ``(N, 168, 9)`` float64.
    """
    weather = np.asarray(weather, dtype=float)
    if noise_k == 0.0:
        return weather
    if len(rngs) != len(weather):
        raise ValueError(f"forecast: {len(rngs)} generators for {len(weather)} weeks")
    hours = weather.shape[1]
    z = np.stack([rng.standard_normal((4, hours)) for rng in rngs])  # (N, 4, 168)
    walk = np.cumsum(z, axis=-1) / np.sqrt(hours)  # standard deviation sqrt((h + 1) / 168)
    e_t, e_i, e_w, e_h = (
        walk[:, k] * s * noise_k
        for k, s in enumerate((1.0, IRRADIANCE_ERROR_PER_K, WIND_ERROR_PER_K, HUMIDITY_ERROR_PER_K))
    )
    out = weather.copy()
    col = cat.WEATHER_NAMES.index
    t_true = weather[..., col("TAMB")]
    out[..., col("TAMB")] = t_true + e_t
    irradiance = [col(c) for c in IRRADIANCE_CHANNELS]
    out[..., irradiance] = weather[..., irradiance] * np.maximum(0.0, 1.0 + e_i)[..., None]
    out[..., col("WIND_SPEED")] = weather[..., col("WIND_SPEED")] * np.maximum(0.0, 1.0 + e_w)
    rh = weather[..., col("RHUM")] * _saturation_hpa(t_true) / _saturation_hpa(t_true + e_t)
    out[..., col("RHUM")] = np.clip(rh + e_h, 0.0, 100.0)
    return out


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
        theta: ``(23,)`` theta_build.
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
