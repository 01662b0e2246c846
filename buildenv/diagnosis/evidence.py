"""Held-out evidence for a candidate effect, from the site's own residuals.

A candidate is scored on the held-out weeks only: the residuals (measured - model) of both series, standardised
by the base model's fit-week residual standard deviations, before and after the effect joins the model. Hourly
residuals are far from independent (a mild afternoon misses for hours, a model that misses the same evening every
day misses it every day), and whether a candidate's footprint (the change it makes to the residuals) explains them
more than by chance depends on how both are correlated in time: the F-test counts the **effective** number of
values, the hours over Bartlett's variance inflation (:func:`variance_inflation`) over the hourly lags of a day and
the daily lags of the held-out days, each series' weighted by the share of the footprint in it. A smooth footprint
against a residual with a long memory, or a daily footprint against a daily miss, gets few effective values and
needs a larger gain for the same significance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from buildenv import catalogue as cat

SERIES = ("temperature", "consumption")


def autocorrelations(x: np.ndarray, lags: int) -> np.ndarray:
    """``(lags + 1,)`` uncentred autocorrelations ``mean(x_t x_t+k) / mean(x_t^2)`` at lags 0..``lags`` along the
    last axis of ``x`` (a constant correlates 1 at every lag), pairs taken within each row, NaN skipped; zeros
    where everything is 0 or nothing is measured."""
    x = np.asarray(x, float)
    out = np.zeros(lags + 1)
    var = np.nanmean(x**2) if np.isfinite(x).any() else 0.0
    if not var > 0:
        return out
    length = x.shape[-1]
    for k in range(min(lags, length - 1) + 1):
        products = x[..., : length - k] * x[..., k:]
        ok = np.isfinite(products)
        out[k] = products[ok].mean() / var if ok.sum() > 2 else 0.0
    return out


def variance_inflation(residuals: np.ndarray, footprint: np.ndarray) -> float:
    """Bartlett's inflation of the variance of a residual's product with a footprint (at least 1; 1 for independent
    hours), taken as separable into the hours of a day and the days: ``(1 + 2 sum_j rho_r(j) rho_f(j)) (1 + 2
    sum_m (1 - m / days) rho_r(24 m) rho_f(24 m))``, the hourly lags 1-23 h taken within each week, the daily
    lags along the held-out days one after the other (each hour with the same hour ``m`` days on), so that a miss
    repeated every day counts once and lags such as 24 m + j count as their two parts.

    Args:
        residuals: ``(weeks, 168)`` standardised held-out residuals left with the candidate in the model (what it
            does not explain; NaN where not measured).
        footprint: ``(weeks, 168)`` what the candidate changes in them.
    """
    hours = cat.HOURS_PER_DAY
    within = autocorrelations(residuals, hours - 1)[1:] * autocorrelations(footprint, hours - 1)[1:]
    by_day = [np.asarray(a, float).reshape(-1, hours).T for a in (residuals, footprint)]  # (24, days)
    days = by_day[0].shape[1]
    weights = 1.0 - np.arange(1, days) / days
    across = autocorrelations(by_day[0], days - 1)[1:] * autocorrelations(by_day[1], days - 1)[1:]
    return float(max(1.0 + 2.0 * within.sum(), 1.0) * max(1.0 + 2.0 * (weights * across).sum(), 1.0))


@dataclass
class Evidence:
    """A candidate's held-out test (:func:`heldout_test`).

    Attributes:
        gain: share of the standardised squared held-out error removed, both series pooled.
        p_value: one-sided F-test of that gain with ``k`` new parameters over ``n_eff`` effective values.
        k: parameters the candidate adds.
        n: measured held-out values, both series.
        n_eff: effective values: the hours of both series over their variance inflations, each weighted by the
            share of the footprint's energy in its series.
        inflation: ``{series: variance inflation}`` (:func:`variance_inflation`).
        gain_by_series: ``{series: gain}``.
        sse_by_series: ``{series: [before, after]}`` standardised sums of squares.
        sse_by_day: ``{series: [[before, after], ...]}`` the same for each held-out day (a day with nothing
            measured counts 0).
    """

    gain: float
    p_value: float
    k: int
    n: int
    n_eff: float
    inflation: dict[str, float] = field(default_factory=dict)
    gain_by_series: dict[str, float] = field(default_factory=dict)
    sse_by_series: dict[str, list[float]] = field(default_factory=dict)
    sse_by_day: dict[str, list[list[float]]] = field(default_factory=dict)


def heldout_test(before: dict[str, np.ndarray], after: dict[str, np.ndarray], k: int) -> Evidence:
    """The held-out gain of a candidate and its F-test.

    Args:
        before, after: ``{series: (weeks, 168)}`` standardised held-out residuals of the model without and with
            the candidate (NaN where nothing was measured).
        k: parameters the candidate adds (at least 1).
    Returns:
        :class:`Evidence`; a gain of 0 and p = 1 where the model without it has no error.
    """
    k = max(int(k), 1)
    sse = {s: (float(np.nansum(before[s] ** 2)), float(np.nansum(after[s] ** 2))) for s in SERIES}
    n_by = {s: int(np.isfinite(before[s]).sum()) for s in SERIES}
    tau = {s: variance_inflation(after[s], before[s] - after[s]) for s in SERIES}
    energy = {s: float(np.nansum((before[s] - after[s]) ** 2)) for s in SERIES}
    n = sum(n_by.values())
    pooled = sum(tau[s] * energy[s] for s in SERIES) / sum(energy.values()) if sum(energy.values()) > 0 else 1.0
    n_eff = max(n / pooled, k + 2.0)
    sse_b, sse_a = sum(b for b, _ in sse.values()), sum(a for _, a in sse.values())
    gain = 1.0 - sse_a / sse_b if sse_b > 0 else 0.0
    f = (sse_b - sse_a) / k / max(sse_a / (n_eff - k), 1e-12)
    p = float(stats.f.sf(f, k, n_eff - k)) if f > 0 else 1.0
    return Evidence(
        gain=float(gain),
        p_value=p,
        k=k,
        n=n,
        n_eff=round(float(n_eff), 1),
        inflation={s: round(t, 2) for s, t in tau.items()},
        gain_by_series={s: round(1.0 - a / b, 4) if b > 0 else 0.0 for s, (b, a) in sse.items()},
        sse_by_series={s: [round(b, 3), round(a, 3)] for s, (b, a) in sse.items()},
        sse_by_day={s: _daily(before[s], after[s]) for s in SERIES},
    )


def _daily(before: np.ndarray, after: np.ndarray) -> list[list[float]]:
    """``[[before, after], ...]`` standardised sums of squares of each day of ``(weeks, 168)`` residuals."""
    days = [np.nansum(np.asarray(r, float).reshape(-1, cat.HOURS_PER_DAY) ** 2, axis=1) for r in (before, after)]
    return [[round(float(b), 3), round(float(a), 3)] for b, a in zip(*days)]
