"""Sim-to-real gap localisation: where (and when) a calibrated model still misses the measurements.

Part 1 of the gap diagnosis (:mod:`buildenv.diagnosis.gap`); it takes arrays and never runs a model. For each series
(indoor temperature, degC; heat consumption, Wh/m2 per hour) it studies the residual ``measured - predicted``
(positive: warmer / more than the model says) and reports:

- **Where the squared error concentrates**: per group of hours (hour of day x weekday; occupied / unoccupied;
  heating start-up (first :data:`STARTUP_HOURS` hours of a comfort period) / on / off; cold / mild and windy /
  calm at the medians; sunny / overcast daytime / night; day; week) its share of hours and of the SSE, mean
  residual, RMSE and concentration ratio ``share of SSE / share of hours``.
- **Hotspots**: groups and windows of 1 to :data:`MAX_WINDOW_HOURS` hours of the day (weekdays, weekends) with a
  concentration ratio of at least ``min_concentration`` and a significantly larger mean squared residual than
  the other hours (F-test, degrees of freedom scaled by ``(1 - a) / (1 + a)``, ``a`` the lag-1 autocorrelation
  of the squared residuals; Bonferroni over the candidates), ranked by excess share ``share of SSE - share of
  hours``; a candidate overlapping a listed hotspot by more than half (Jaccard index), or with half of its
  squared error in listed hotspots' hours, is skipped.
- **Residual tests**: bias (t-test with ``n_eff = n (1 - r1) / (1 + r1)``), whiteness (lag-1 and lag-24
  autocorrelation, Ljung-Box over 24 lags) and drivers: ``corr(residual[t], driver[t - lag])`` for lags 0-3 h with
  wind, irradiance, outdoor temperature, occupancy transitions and heating starts, flagged when
  ``|r| > 2 / sqrt(n_eff)`` with Bartlett's effective number of pairs (so that smooth or daily series do not
  correlate by chance).

Autocorrelations skip missing hours and never pair hours across a gap between weeks; transitions treat each week
as periodic. Every number in the result is a plain JSON type (NaN becomes ``None``).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy import stats

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError

#: Hours of each heating comfort period counted as its start-up.
STARTUP_HOURS = 3
#: Longest window of consecutive hours of the day considered as a hotspot candidate.
MAX_WINDOW_HOURS = 6
#: Lags (hours) of the cross-correlations with the candidate drivers.
DRIVER_LAGS = (0, 1, 2, 3)
#: Lags of the Ljung-Box whiteness test.
LJUNG_BOX_LAGS = 24
#: Lags summed in Bartlett's effective number of pairs of a cross-correlation (two days: daily cycles count).
BARTLETT_LAGS = 48

SERIES_UNITS = {"temperature": "K", "consumption": "Wh/m2"}
DRIVER_LABELS = {
    "wind_speed": "wind speed",
    "global_solar": "global horizontal irradiance",
    "outdoor_temperature": "outdoor temperature",
    "occupancy_transition": "occupancy arrival/departure hours",
    "heating_start": "heating start hours",
}


class LocalisationError(BuildenvError, ValueError):
    """The arrays given to :func:`localise` do not have the documented shapes."""


# ----------------------------------------------------------------------------------------------------------------
# Public API


def localise(
    measured_t: np.ndarray,
    measured_q: np.ndarray,
    predicted_t: np.ndarray,
    predicted_q: np.ndarray,
    weather: np.ndarray,
    occupied: np.ndarray,
    heating_on: np.ndarray,
    week_starts: Sequence[dt.date | str],
    *,
    sunny_w_m2: float = 200.0,
    daylight_w_m2: float = 10.0,
    alpha: float = 0.01,
    min_concentration: float = 1.25,
    max_hotspots: int = 5,
) -> dict:
    """Localise the residuals of a calibrated model in time, schedule and weather (see the module docstring).

    Args:
        measured_t: ``(weeks, 168)`` measured indoor temperature (degC); NaN = not measured (skipped).
        measured_q: ``(weeks, 168)`` measured heat consumption (Wh/m2 in the hour); NaN = not measured.
        predicted_t: ``(weeks, 168)`` model temperature (degC).
        predicted_q: ``(weeks, 168)`` model heat consumption (Wh/m2 in the hour).
        weather: ``(weeks, 168, 9)`` hourly weather in :data:`buildenv.catalogue.WEATHER` order (W/m2, %, degC,
            m/s, deg).
        occupied: ``(weeks, 168)`` booleans, occupied hours of the calibrated schedule.
        heating_on: ``(weeks, 168)`` booleans, heating comfort period of the BMS settings.
        week_starts: the Monday (``datetime.date`` or ISO string) of each week; hours start Monday 00:00.
        sunny_w_m2: global horizontal irradiance (W/m2) from which a daytime hour counts as sunny.
        daylight_w_m2: global horizontal irradiance (W/m2) below which an hour counts as night.
        alpha: family-wise significance level of the hotspot tests (Bonferroni-corrected).
        min_concentration: smallest concentration ratio (share of SSE / share of hours) of a hotspot.
        max_hotspots: most hotspots listed per series.
    Returns:
        A JSON-able dict::

            {"weeks": [ISO Monday, ...], "hours": weeks * 168,
             "thresholds": {"outdoor_temperature_median_celsius", "wind_speed_median_m_s", "sunny_w_m2",
                            "daylight_w_m2", "startup_hours", "alpha", "min_concentration"},
             "temperature": SERIES, "consumption": SERIES}

        with ``SERIES``::

            {"unit": "K" | "Wh/m2", "hours": measured hours, "missing_hours": int,
             "bias": mean residual, "rmse": float, "std": float, "sse": float,
             "by_hour_weekday": {"days": [monday..sunday], "hours": 7x24 ints, "mean_residual": 7x24,
                                 "share_sse": 7x24, "concentration": 7x24},
             "groups": {"occupancy": {"occupied": GROUP, "unoccupied": GROUP},
                        "heating": {"startup": GROUP, "heating_on": GROUP, "heating_off": GROUP},
                        "outdoor_temperature": {"cold": GROUP, "mild": GROUP},
                        "solar": {"sunny": GROUP, "overcast": GROUP, "night": GROUP},
                        "wind": {"windy": GROUP, "calm": GROUP},
                        "day": {"monday": GROUP, ...}, "week": {ISO Monday: GROUP, ...}},
             "hotspots": [{"rank", "kind": "group" | "window", "name", "label", "description", "hours",
                           "share_hours", "share_sse", "excess_share", "mean_residual", "rmse",
                           "concentration", "p_value"}, ...],
             "tests": {"bias": {"mean", "std", "n", "lag1_autocorrelation", "n_eff", "t", "p_value",
                                "significant"},
                       "whiteness": {"lag1_autocorrelation", "lag24_autocorrelation", "ljung_box_q",
                                     "ljung_box_lags", "p_value", "white"},
                       "drivers": {name: {"label", "lags": [0..3], "correlation": [...], "n_eff", "threshold",
                                          "significant": [...], "best_lag", "best_correlation"}},
                       "strongest_driver": name | None},
             "summary": one paragraph}

        ``GROUP`` = ``{"label", "hours", "share_hours", "share_sse", "mean_residual", "rmse",
        "concentration"}``; residuals in K (temperature) or Wh/m2 (consumption); shares are fractions (0-1).
        Undefined values (a group with no measured hour) are ``None``.
    Raises:
        LocalisationError: an array does not have the shape above.
    """
    arrays = _check(measured_t, measured_q, predicted_t, predicted_q, weather, occupied, heating_on, week_starts)
    measured_t, measured_q, predicted_t, predicted_q, weather, occupied, heating_on = arrays
    n_weeks = measured_t.shape[0]
    mondays = [_iso(d) for d in week_starts]
    segments = _segments(week_starts, n_weeks)
    ctx = _context(weather, occupied, heating_on, mondays, sunny_w_m2, daylight_w_m2)
    out = {
        "weeks": mondays,
        "hours": n_weeks * cat.HOURS_PER_WEEK,
        "thresholds": {
            "outdoor_temperature_median_celsius": ctx["tamb_median"],
            "wind_speed_median_m_s": ctx["wind_median"],
            "sunny_w_m2": float(sunny_w_m2),
            "daylight_w_m2": float(daylight_w_m2),
            "startup_hours": STARTUP_HOURS,
            "alpha": float(alpha),
            "min_concentration": float(min_concentration),
        },
    }
    for name, y, p in (("temperature", measured_t, predicted_t), ("consumption", measured_q, predicted_q)):
        out[name] = _series(name, y - p, ctx, segments, alpha, min_concentration, max_hotspots)
    return _jsonable(out)


def residual_tests(
    residual: np.ndarray, drivers: dict[str, np.ndarray], week_starts: Sequence[dt.date | str], alpha: float = 0.05
) -> dict:
    """Bias, whiteness and driver cross-correlation tests of one residual series (module docstring).

    Args:
        residual: ``(weeks, 168)`` measured - predicted; NaN hours are skipped.
        drivers: name -> ``(weeks, 168)`` hourly candidate driver (any unit).
        week_starts: the Monday of each week (gaps between weeks break the autocorrelation pairs).
        alpha: significance level of the bias and whiteness tests.
    Returns:
        ``{"bias": {...}, "whiteness": {...}, "drivers": {...}, "strongest_driver": name | None}`` as in
        :func:`localise`.
    """
    residual = np.asarray(residual, float)
    segments = _segments(week_starts, residual.shape[0])
    return _jsonable(_tests(residual, {k: np.asarray(v, float) for k, v in drivers.items()}, segments, alpha))


def plot_localisation(
    result: dict,
    path: str | Path,
    measured_t: np.ndarray | None = None,
    measured_q: np.ndarray | None = None,
    predicted_t: np.ndarray | None = None,
    predicted_q: np.ndarray | None = None,
    occupied: np.ndarray | None = None,
) -> Path:
    """Plot a localisation result to one PNG.

    Top row: the mean residual (measured - predicted) by hour of day x weekday of each series, diverging
    colormap centred at 0 (K for temperature, Wh/m2 for consumption); white cells had no measured hour.
    When the arrays are given, two more rows: the hourly residual of each series over all the weeks with the
    occupied hours shaded green (as :mod:`buildenv.calibration.plot`) and week boundaries in grey.

    Args:
        result: the dict of :func:`localise`.
        path: PNG file to write (its folder is created).
        measured_t, predicted_t: ``(weeks, 168)`` temperatures (degC), optional.
        measured_q, predicted_q: ``(weeks, 168)`` consumption (Wh/m2 in the hour), optional.
        occupied: ``(weeks, 168)`` booleans, optional (shading).
    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    from buildenv.plotting import save_figure, shade_occupancy

    series = {"temperature": (measured_t, predicted_t), "consumption": (measured_q, predicted_q)}
    with_series = all(a is not None for pair in series.values() for a in pair)
    rows = 3 if with_series else 1
    fig = plt.figure(figsize=(13, 3.6 + 2.6 * (rows - 1)))
    grid = fig.add_gridspec(rows, 2, height_ratios=[1.4] + [1.0] * (rows - 1))
    for col, name in enumerate(("temperature", "consumption")):
        ax = fig.add_subplot(grid[0, col])
        res = result[name]
        mean = np.array([[np.nan if v is None else v for v in row] for row in res["by_hour_weekday"]["mean_residual"]])
        span = float(np.nanmax(np.abs(mean))) if np.isfinite(mean).any() else 0.0
        span = span if span > 0 else 1.0
        image = ax.imshow(
            np.ma.masked_invalid(mean),
            aspect="auto",
            cmap="RdBu_r",
            norm=TwoSlopeNorm(vcenter=0.0, vmin=-span, vmax=span),
            interpolation="nearest",
        )
        ax.set_yticks(range(7), [d[:3].capitalize() for d in cat.DAYS])
        ax.set_xticks(range(0, 24, 3), [f"{h:02d}" for h in range(0, 24, 3)])
        ax.set_xlabel("hour of day")
        bar = fig.colorbar(image, ax=ax)
        bar.set_label(f"mean residual ({res['unit']})")
        rmse = res.get("rmse")
        ax.set_title(f"{name}: measured - predicted" + (f", RMSE {rmse:.3g} {res['unit']}" if rmse else ""), fontsize=9)
    if with_series:
        for row, (name, (y, p)) in enumerate(series.items(), start=1):
            ax = fig.add_subplot(grid[row, :])
            r = (np.asarray(y, float) - np.asarray(p, float)).reshape(-1)
            hours = np.arange(r.size)
            if occupied is not None:
                shade_occupancy(ax, np.asarray(occupied, float).reshape(-1))
            ax.plot(hours, r, color="black", lw=0.8)
            ax.axhline(0.0, color="tab:red", lw=0.8)
            for w in range(1, r.size // cat.HOURS_PER_WEEK):
                ax.axvline(w * cat.HOURS_PER_WEEK, color="grey", lw=0.5)
            ax.set_xlim(0, r.size)
            ax.set_ylabel(f"{name} residual ({result[name]['unit']})", fontsize=8)
            ax.grid(alpha=0.3)
        ax.set_xlabel("hour (weeks start Monday 00:00; occupied hours shaded green)")
    return save_figure(fig, path, dpi=100)


# ----------------------------------------------------------------------------------------------------------------
# Input, calendar and context


def _check(measured_t, measured_q, predicted_t, predicted_q, weather, occupied, heating_on, week_starts):
    series = [np.asarray(a, float) for a in (measured_t, measured_q, predicted_t, predicted_q)]
    shape = series[0].shape
    if len(shape) != 2 or shape[1] != cat.HOURS_PER_WEEK:
        raise LocalisationError(f"measured_t has shape {shape}; expected (weeks, {cat.HOURS_PER_WEEK})")
    names = ("measured_t", "measured_q", "predicted_t", "predicted_q")
    for name, a in zip(names, series):
        if a.shape != shape:
            raise LocalisationError(f"{name} has shape {a.shape}; expected {shape} like measured_t")
    weather = np.asarray(weather, float)
    if weather.shape != (*shape, len(cat.WEATHER_NAMES)):
        raise LocalisationError(
            f"weather has shape {weather.shape}; expected {(*shape, len(cat.WEATHER_NAMES))} "
            f"in catalogue order {cat.WEATHER_NAMES}"
        )
    flags = []
    for name, a in (("occupied", occupied), ("heating_on", heating_on)):
        a = np.asarray(a)
        if a.shape != shape:
            raise LocalisationError(f"{name} has shape {a.shape}; expected {shape}")
        flags.append(a.astype(bool))
    if len(week_starts) != shape[0]:
        raise LocalisationError(f"week_starts has {len(week_starts)} dates for {shape[0]} weeks")
    return (*series, weather, *flags)


def _iso(day: dt.date | str) -> str:
    return day.isoformat() if hasattr(day, "isoformat") else str(day)


def _segments(week_starts: Sequence[dt.date | str], n_weeks: int) -> np.ndarray:
    """``(weeks * 168,)`` ids of runs of consecutive weeks (a new id after a gap between Mondays)."""
    ids = np.zeros(n_weeks, int)
    for w in range(1, n_weeks):
        try:
            a, b = (dt.date.fromisoformat(_iso(week_starts[i])[:10]) for i in (w - 1, w))
            consecutive = (b - a).days == 7
        except ValueError:
            consecutive = True
        ids[w] = ids[w - 1] + (0 if consecutive else 1)
    return np.repeat(ids, cat.HOURS_PER_WEEK)


def _starts(flag: np.ndarray) -> np.ndarray:
    """Hours where a boolean ``(weeks, 168)`` series switches on (each week periodic)."""
    return flag & ~np.roll(flag, 1, axis=1)


def heating_startup(heating_on: np.ndarray, hours: int = STARTUP_HOURS) -> np.ndarray:
    """The first ``hours`` hours of each heating comfort period.

    Args:
        heating_on: ``(weeks, 168)`` booleans, heating comfort period; each week is treated as periodic (a period
            running from Sunday night into Monday starts on Sunday; a week heated at every hour has no start-up).
        hours: length of the start-up (h).
    Returns:
        ``(weeks, 168)`` booleans.
    """
    heating_on = np.asarray(heating_on, bool)
    run = np.zeros(heating_on.shape, int)
    prev = np.zeros(heating_on.shape[0], int)
    for _ in range(2):  # second pass carries runs over the Sunday -> Monday wrap
        for h in range(heating_on.shape[1]):
            prev = np.where(heating_on[:, h], prev + 1, 0)
            run[:, h] = prev
    # a week heated all week round has no start: runs then exceed 168 everywhere
    return heating_on & (run >= 1) & (run <= hours)


def _context(
    weather: np.ndarray,
    occupied: np.ndarray,
    heating_on: np.ndarray,
    mondays: list[str],
    sunny_w_m2: float,
    daylight_w_m2: float,
) -> dict:
    """Group masks ``(weeks, 168)``, their labels, thresholds and drivers shared by both series."""
    w = {name: weather[..., i] for i, name in enumerate(cat.WEATHER_NAMES)}
    tamb, wind, glob = w["TAMB"], w["WIND_SPEED"], w["IGLOB_H"]
    tamb_median = float(np.nanmedian(tamb)) if np.isfinite(tamb).any() else float("nan")
    wind_median = float(np.nanmedian(wind)) if np.isfinite(wind).any() else float("nan")
    startup = heating_startup(heating_on)
    shape = occupied.shape
    hour_of_week = np.broadcast_to(np.arange(cat.HOURS_PER_WEEK), shape)
    day = hour_of_week // cat.HOURS_PER_DAY
    week = np.broadcast_to(np.arange(shape[0])[:, None], shape)
    groups: dict[str, dict[str, tuple[str, np.ndarray]]] = {
        "occupancy": {"occupied": ("occupied hours", occupied), "unoccupied": ("unoccupied hours", ~occupied)},
        "heating": {
            "startup": (f"heating start-up (first {STARTUP_HOURS} h of each heating period)", startup),
            "heating_on": ("heating on after start-up", heating_on & ~startup),
            "heating_off": ("heating off", ~heating_on),
        },
        "outdoor_temperature": {
            "cold": (f"cold hours (outdoor <= {tamb_median:.1f} degC, the median)", tamb <= tamb_median),
            "mild": (f"mild hours (outdoor > {tamb_median:.1f} degC, the median)", tamb > tamb_median),
        },
        "solar": {
            "sunny": (f"sunny daytime (global horizontal >= {sunny_w_m2:g} W/m2)", glob >= sunny_w_m2),
            "overcast": (
                f"overcast daytime ({daylight_w_m2:g}-{sunny_w_m2:g} W/m2 global horizontal)",
                (glob >= daylight_w_m2) & (glob < sunny_w_m2),
            ),
            "night": (f"night (global horizontal < {daylight_w_m2:g} W/m2)", glob < daylight_w_m2),
        },
        "wind": {
            "windy": (f"windy hours (wind > {wind_median:.1f} m/s, the median)", wind > wind_median),
            "calm": (f"calm hours (wind <= {wind_median:.1f} m/s, the median)", wind <= wind_median),
        },
        "day": {d: (f"{d.capitalize()}s", day == i) for i, d in enumerate(cat.DAYS)},
        "week": {m: (f"week of {m}", week == i) for i, m in enumerate(mondays)},
    }
    arrivals, departures = _starts(occupied), _starts(~occupied)
    drivers = {
        "wind_speed": wind,
        "global_solar": glob,
        "outdoor_temperature": tamb,
        "occupancy_transition": (arrivals | departures).astype(float),
        "heating_start": _starts(heating_on).astype(float),
    }
    return {
        "groups": groups,
        "drivers": drivers,
        "day": day,
        "hour": hour_of_week % cat.HOURS_PER_DAY,
        "startup": startup,
        "occupied": occupied,
        "tamb_median": tamb_median,
        "wind_median": wind_median,
    }


# ----------------------------------------------------------------------------------------------------------------
# Decomposition of the squared error


def _group_stats(r: np.ndarray, ok: np.ndarray, mask: np.ndarray, n_total: int, sse_total: float) -> dict:
    m = mask & ok
    n = int(m.sum())
    if n == 0:
        return {
            "hours": 0,
            "share_hours": 0.0,
            "share_sse": 0.0,
            "mean_residual": None,
            "rmse": None,
            "concentration": None,
        }
    rg = r[m]
    sse = float((rg**2).sum())
    share_h = n / n_total
    share_e = sse / sse_total if sse_total > 0 else float("nan")
    return {
        "hours": n,
        "share_hours": share_h,
        "share_sse": share_e,
        "mean_residual": float(rg.mean()),
        "rmse": float(np.sqrt(sse / n)),
        "concentration": share_e / share_h,
    }


def _grid(r: np.ndarray, ok: np.ndarray, ctx: dict, n_total: int, sse_total: float) -> dict:
    hours = np.zeros((7, 24), int)
    sums = np.zeros((7, 24))
    sq = np.zeros((7, 24))
    d, h = ctx["day"][ok], ctx["hour"][ok]
    np.add.at(hours, (d, h), 1)
    np.add.at(sums, (d, h), r[ok])
    np.add.at(sq, (d, h), r[ok] ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(hours > 0, sums / hours, np.nan)
        share = sq / sse_total if sse_total > 0 else np.full((7, 24), np.nan)
        conc = np.where(hours > 0, share / (hours / max(n_total, 1)), np.nan)
    return {
        "days": list(cat.DAYS),
        "hours": hours.tolist(),
        "mean_residual": mean.tolist(),
        "share_sse": share.tolist(),
        "concentration": conc.tolist(),
    }


def _windows(ctx: dict) -> list[tuple[str, str, np.ndarray]]:
    """Hotspot candidates: windows of consecutive hours of the day on weekdays and on weekends."""
    out = []
    for kind, days in (("weekday", ctx["day"] < 5), ("weekend", ctx["day"] >= 5)):
        for length in range(1, MAX_WINDOW_HOURS + 1):
            for start in range(0, cat.HOURS_PER_DAY - length + 1):
                mask = days & (ctx["hour"] >= start) & (ctx["hour"] < start + length)
                label = f"{kind} {start:02d}:00-{start + length:02d}:00"
                out.append((label, label, mask))
    return out


def _hotspots(
    name: str,
    r: np.ndarray,
    ok: np.ndarray,
    ctx: dict,
    segments: np.ndarray,
    alpha: float,
    min_concentration: float,
    max_hotspots: int,
) -> list[dict]:
    n_total = int(ok.sum())
    r2 = np.where(ok, r, 0.0) ** 2
    sse_total = float(r2.sum())
    if n_total < 3 or sse_total <= 0:
        return []
    a = max(_acf(np.where(ok, r**2, np.nan).reshape(-1), segments, 1)[0], 0.0)
    a = min(a, 0.99)
    c = (1.0 - a) / (1.0 + a)
    candidates = [
        ("group", f"{g}/{k}", label, mask)
        for g, members in ctx["groups"].items()
        for k, (label, mask) in members.items()
    ]
    candidates += [("window", key, label, mask) for key, label, mask in _windows(ctx)]
    threshold = alpha / len(candidates)
    scored = []
    for kind, key, label, mask in candidates:
        m = mask & ok
        n_g = int(m.sum())
        n_rest = n_total - n_g
        if n_g == 0 or n_rest == 0:
            continue
        sse_g = float(r2[m].sum())
        share_h, share_e = n_g / n_total, sse_g / sse_total
        if share_e / share_h < min_concentration:
            continue
        rest = (sse_total - sse_g) / n_rest
        f = np.inf if rest <= 0 else (sse_g / n_g) / rest
        p = float(stats.f.sf(f, max(c * n_g, 1.0), max(c * n_rest, 1.0))) if np.isfinite(f) else 0.0
        if p >= threshold:
            continue
        scored.append((share_e - share_h, kind, key, label, m, n_g, share_h, share_e, p))
    scored.sort(key=lambda s: -s[0])  # stable: groups precede windows on ties
    chosen: list[dict] = []
    masks: list[np.ndarray] = []
    unit = SERIES_UNITS[name]
    covered = np.zeros(r.shape, bool)
    for excess, kind, key, label, m, n_g, share_h, share_e, p in scored:
        if len(chosen) >= max_hotspots:
            break
        if any((m & o).sum() / (m | o).sum() > 0.5 for o in masks) or r2[m & covered].sum() >= 0.5 * r2[m].sum():
            continue
        masks.append(m)
        covered |= m
        mean = float(r[m].mean())
        context = _context_note(r2, m, ctx, key)
        direction = "higher" if mean > 0 else "lower"
        description = (
            f"{label}{context}: {100 * share_e:.0f} % of the squared error in {100 * share_h:.0f} % of "
            f"the hours, measured {direction} than predicted by {abs(mean):.2g} {unit} on average"
        )
        chosen.append(
            {
                "rank": len(chosen) + 1,
                "kind": kind,
                "name": key,
                "label": label,
                "description": description,
                "hours": n_g,
                "share_hours": share_h,
                "share_sse": share_e,
                "excess_share": excess,
                "mean_residual": mean,
                "rmse": float(np.sqrt(r2[m].mean())),
                "concentration": share_e / share_h,
                "p_value": p,
            }
        )
    return chosen


def _context_note(r2: np.ndarray, m: np.ndarray, ctx: dict, key: str) -> str:
    """``", mostly heating start-up"``: the heating / occupancy states holding >= 75 % of a hotspot's error."""
    sse = r2[m].sum()
    notes = []
    for group in ("heating", "occupancy"):
        if sse <= 0 or key.startswith(group + "/"):
            continue
        for label, mask in ctx["groups"][group].values():
            if r2[m & mask].sum() / sse >= 0.75:
                short = label.split(" (")[0]
                notes.append(short if (m <= mask).all() else f"mostly {short}")
    return "".join(f", {n}" for n in notes)


# ----------------------------------------------------------------------------------------------------------------
# Residual tests


def _acf(x: np.ndarray, segments: np.ndarray, max_lag: int) -> np.ndarray:
    """Autocorrelations ``r_1..r_max_lag`` of a flat series with NaN gaps (pairs within a segment only)."""
    ok = np.isfinite(x)
    n = int(ok.sum())
    out = np.full(max_lag, np.nan)
    if n < 3:
        return out
    xc = np.where(ok, x - x[ok].mean(), 0.0)
    var = float((xc**2).sum()) / n
    if var <= 0:
        return np.zeros(max_lag)
    for k in range(1, max_lag + 1):
        pair = ok[k:] & ok[:-k] & (segments[k:] == segments[:-k])
        if pair.sum() < 2:
            continue
        out[k - 1] = float((xc[k:] * xc[:-k])[pair].sum()) / pair.sum() / var
    return out


def _lagged_corr(r: np.ndarray, d: np.ndarray, segments: np.ndarray, lag: int) -> tuple[float, int]:
    """Pearson correlation of ``r[t]`` with ``d[t - lag]`` over flat series (same segment, both finite)."""
    if lag:
        a, b, same = r[lag:], d[:-lag], segments[lag:] == segments[:-lag]
    else:
        a, b, same = r, d, np.ones(r.size, bool)
    ok = np.isfinite(a) & np.isfinite(b) & same
    n = int(ok.sum())
    if n < 3:
        return float("nan"), n
    a, b = a[ok], b[ok]
    if a.std() == 0 or b.std() == 0:
        return float("nan"), n
    return float(np.corrcoef(a, b)[0, 1]), n


def _tests(residual: np.ndarray, drivers: dict[str, np.ndarray], segments: np.ndarray, alpha: float) -> dict:
    r = residual.reshape(-1)
    ok = np.isfinite(r)
    n = int(ok.sum())
    acf = _acf(r, segments, LJUNG_BOX_LAGS)
    r1 = float(np.clip(np.nan_to_num(acf[0]), 0.0, 0.99))
    out: dict = {}
    if n >= 3:
        mean, std = float(r[ok].mean()), float(r[ok].std(ddof=1))
        n_eff = max(n * (1.0 - r1) / (1.0 + r1), 2.0)
        t = mean / (std / np.sqrt(n_eff)) if std > 0 else (np.inf if mean else 0.0)
        p = float(2.0 * stats.t.sf(abs(t), n_eff - 1.0)) if np.isfinite(t) else 0.0
        out["bias"] = {
            "mean": mean,
            "std": std,
            "n": n,
            "lag1_autocorrelation": float(acf[0]),
            "n_eff": n_eff,
            "t": float(t),
            "p_value": p,
            "significant": bool(p < alpha),
        }
        lags = np.arange(1, LJUNG_BOX_LAGS + 1)
        good = np.isfinite(acf) & (n - lags > 0)
        q = float(n * (n + 2) * np.sum(acf[good] ** 2 / (n - lags[good])))
        p_lb = float(stats.chi2.sf(q, int(good.sum()))) if good.any() else float("nan")
        out["whiteness"] = {
            "lag1_autocorrelation": float(acf[0]),
            "lag24_autocorrelation": float(acf[23]),
            "ljung_box_q": q,
            "ljung_box_lags": int(good.sum()),
            "p_value": p_lb,
            "white": bool(p_lb >= alpha),
        }
    else:
        out["bias"] = {"mean": None, "n": n, "significant": False}
        out["whiteness"] = {"white": None, "p_value": None}
    out["drivers"] = {}
    best_name, best_value = None, 0.0
    acf_r = np.nan_to_num(_acf(r, segments, BARTLETT_LAGS))
    for name, driver in drivers.items():
        d = driver.reshape(-1)
        acf_d = np.nan_to_num(_acf(d, segments, BARTLETT_LAGS))
        corr: list[float] = []
        n_pairs = 0
        for lag in DRIVER_LAGS:
            c, n_pairs = _lagged_corr(r, d, segments, lag)
            corr.append(c)
        inflation = max(1.0 + 2.0 * float(np.sum(acf_r * acf_d)), 1.0)
        n_eff = max(n_pairs / inflation, 1.0)
        threshold = 2.0 / np.sqrt(n_eff)
        sig = [bool(np.isfinite(c) and abs(c) > threshold) for c in corr]
        finite = [abs(c) if np.isfinite(c) else -1.0 for c in corr]
        i = int(np.argmax(finite))
        entry = {
            "label": DRIVER_LABELS.get(name, name),
            "lags": list(DRIVER_LAGS),
            "correlation": corr,
            "n_eff": n_eff,
            "threshold": threshold,
            "significant": sig,
            "best_lag": DRIVER_LAGS[i],
            "best_correlation": corr[i],
            "best_significant": sig[i],
        }
        out["drivers"][name] = entry
        if sig[i] and abs(corr[i]) > best_value:
            best_name, best_value = name, abs(corr[i])
    out["strongest_driver"] = best_name
    return out


# ----------------------------------------------------------------------------------------------------------------
# One series and its summary


def _series(
    name: str,
    residual: np.ndarray,
    ctx: dict,
    segments: np.ndarray,
    alpha: float,
    min_concentration: float,
    max_hotspots: int,
) -> dict:
    ok = np.isfinite(residual)
    r = np.where(ok, residual, np.nan)
    n = int(ok.sum())
    unit = SERIES_UNITS[name]
    base = {"unit": unit, "hours": n, "missing_hours": int(residual.size - n)}
    if n == 0:
        return {
            **base,
            "bias": None,
            "rmse": None,
            "std": None,
            "sse": 0.0,
            "by_hour_weekday": None,
            "groups": {},
            "hotspots": [],
            "tests": {},
            "summary": f"{name}: no measured hour.",
        }
    rv = r[ok]
    sse = float((rv**2).sum())
    base.update({"bias": float(rv.mean()), "rmse": float(np.sqrt(sse / n)), "std": float(rv.std()), "sse": sse})
    base["by_hour_weekday"] = _grid(r, ok, ctx, n, sse)
    base["groups"] = {
        g: {k: {"label": label, **_group_stats(r, ok, mask, n, sse)} for k, (label, mask) in members.items()}
        for g, members in ctx["groups"].items()
    }
    base["hotspots"] = _hotspots(name, r, ok, ctx, segments, alpha, min_concentration, max_hotspots)
    base["tests"] = _tests(r, ctx["drivers"], segments, alpha=0.05)
    base["summary"] = _summary(name, base)
    return base


def _summary(name: str, s: dict) -> str:
    unit, tests = s["unit"], s["tests"]
    bias = tests["bias"]
    parts = [f"{name}: RMSE {s['rmse']:.3g} {unit} over {s['hours']} measured hours"]
    if bias.get("significant"):
        sign = "higher" if bias["mean"] > 0 else "lower"
        parts.append(
            f"measured {sign} than predicted by {abs(bias['mean']):.2g} {unit} on average "
            f"(significant, p = {bias['p_value']:.2g})"
        )
    else:
        parts.append(f"no significant bias ({bias['mean']:+.2g} {unit})")
    white = tests["whiteness"]
    if white.get("white"):
        parts.append("residual white (Ljung-Box)")
    else:
        parts.append(
            f"residual not white (lag-1 autocorrelation {white['lag1_autocorrelation']:.2f}, "
            f"Ljung-Box p = {white['p_value']:.2g})"
        )
    top = tests["strongest_driver"]
    if top:
        d = tests["drivers"][top]
        parts.append(f"strongest driver {d['label']} (r = {d['best_correlation']:+.2f} at lag {d['best_lag']} h)")
    else:
        parts.append("no significant driver")
    if s["hotspots"]:
        h = s["hotspots"][0]
        parts.append(
            f"error concentrates in {h['label']} ({100 * h['share_sse']:.0f} % of the squared error in "
            f"{100 * h['share_hours']:.0f} % of the hours)"
        )
    else:
        parts.append("no hour group concentrates the error")
    return "; ".join(parts) + "."


def _jsonable(x):
    """Plain Python types; NaN/inf become None."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return x
