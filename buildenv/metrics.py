"""Accuracy metrics of predicted weeks, a week's summary and the site metrics (Guideline 14), in one place.

Conventions (the paper's Table 1, stated once):

- Every metric is computed per week, then averaged over weeks (``*_std``: standard deviation over weeks).
- T is ``T_INT_OFFICE``; Q is the 7 consumption outputs.
- ``mse_t``, ``mse_q``, ``loss``: in *standardised* units (each output channel minus its training mean,
  divided by its training standard deviation), as the metamodel is trained; ``mse_q`` averages over hours
  and the 7 Q channels. ``*_occ``: the same over occupied hours only.
- ``r2_t``: ``sklearn.metrics.r2_score`` definition on the week's 168 hourly temperatures (degC).
  ``r2_q``: the same definition on the week's 168 x 7 standardised consumptions taken as one series (a
  per-channel average would be undefined for channels that are zero all week, e.g. heating in July).
- ``rmse_t_celsius``: RMSE of the temperature in degC.
- ``cv_rmse_q_percent``: RMSE of the hourly total consumption (sum of the 7 Q outputs, Wh/m2) divided by
  its mean over the week, in percent (the ASHRAE Guideline 14 statistic without the degrees-of-freedom
  correction, which belongs to calibration).

:func:`pooled_scores` gives ``r2_t_pooled`` and ``r2_q_pooled``: ``r2_score`` over every hour of every week as
one series, which measures errors against the spread across weeks (a week whose temperature barely moves has
a tiny per-week variance). :func:`daily_errors` splits the errors by day of the week. :func:`week_summary`
totals one week; :func:`site_metrics` scores predictions against a site's measurements. :func:`response_scores`
scores the response to settings: the same weeks under several settings, their savings predicted against simulated.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat


def r2_score(y_true: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
    """Coefficient of determination along the last axis, as sklearn's ``r2_score`` for one output.

    ``1 - SS_res / SS_tot``; when ``SS_tot`` is 0 the score is 1.0 for a perfect prediction and 0.0
    otherwise (sklearn's ``force_finite``). Shapes ``(..., n)`` -> ``(...)``.
    """
    y_true, y_pred = np.asarray(y_true, np.float64), np.asarray(y_pred, np.float64)
    ss_res = ((y_true - y_pred) ** 2).sum(-1)
    ss_tot = ((y_true - y_true.mean(-1, keepdims=True)) ** 2).sum(-1)
    safe = np.where(ss_tot > 0, ss_tot, 1.0)
    return np.where(ss_tot > 0, 1.0 - ss_res / safe, np.where(ss_res == 0, 1.0, 0.0))


def week_metrics(
    y_true: np.ndarray,
    y_pred: np.ndarray,
    occupied: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    alpha: float = 1.0,
    beta: float = 0.3,
) -> dict[str, np.ndarray]:
    """Per-week metrics.

    Args:
        y_true, y_pred: ``(weeks, 168, 8)`` physical outputs (catalogue order).
        occupied: ``(weeks, 168)`` booleans.
        mean, std: ``(8,)`` standardisation statistics of the training split.
        alpha, beta: weights of the paper's loss.
    Returns:
        ``{name: (weeks,) array}`` for every metric of the module docstring.
    """
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    zt, zp = (y_true - mean) / std, (y_pred - mean) / std
    sq = (zp - zt) ** 2
    occ = np.asarray(occupied, bool)
    n_occ = np.maximum(occ.sum(1), 1)
    mse_t, mse_q = sq[..., t].mean(1), sq[..., q].mean((1, 2))
    total_true, total_pred = y_true[..., q].sum(-1), y_pred[..., q].sum(-1)
    rmse_total = np.sqrt(((total_pred - total_true) ** 2).mean(1))
    return {
        "loss": alpha * np.log1p(np.sqrt(mse_t)) + beta * np.log1p(np.sqrt(mse_q)),
        "mse_t": mse_t,
        "mse_q": mse_q,
        "mse_t_occ": (sq[..., t] * occ).sum(1) / n_occ,
        "mse_q_occ": (sq[..., q].mean(-1) * occ).sum(1) / n_occ,
        "r2_t": r2_score(y_true[..., t], y_pred[..., t]),
        "r2_q": r2_score(zt[..., q].reshape(len(zt), -1), zp[..., q].reshape(len(zp), -1)),
        "rmse_t_celsius": np.sqrt(((y_pred[..., t] - y_true[..., t]) ** 2).mean(1)),
        "cv_rmse_q_percent": 100.0 * rmse_total / np.maximum(total_true.mean(1), 1e-9),
    }


def pooled_scores(y_true: np.ndarray, y_pred: np.ndarray, mean: np.ndarray, std: np.ndarray) -> dict[str, float]:
    """``r2_t_pooled`` (degC) and ``r2_q_pooled`` (standardised Q channels) over all weeks and hours at once."""
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    zt, zp = (y_true[..., q] - mean[q]) / std[q], (y_pred[..., q] - mean[q]) / std[q]
    return {
        "r2_t_pooled": float(r2_score(y_true[..., t].ravel(), y_pred[..., t].ravel())),
        "r2_q_pooled": float(r2_score(zt.ravel(), zp.ravel())),
    }


def daily_errors(y_true: np.ndarray, y_pred: np.ndarray, mean: np.ndarray, std: np.ndarray) -> dict[str, list[float]]:
    """Errors by day of the week (7 values each, day 1 first), pooled over weeks.

    ``rmse_t_celsius_by_day``: temperature RMSE (degC); ``mse_q_by_day``: standardised consumption MSE.
    """
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    days = (len(y_true), cat.HOURS_PER_WEEK // 24, 24)
    err_t = (y_pred[..., t] - y_true[..., t]).reshape(days)
    err_q = (((y_pred[..., q] - y_true[..., q]) / std[q]) ** 2).mean(-1).reshape(days)
    return {
        "rmse_t_celsius_by_day": np.sqrt((err_t**2).mean((0, 2))).round(4).tolist(),
        "mse_q_by_day": err_q.mean((0, 2)).round(5).tolist(),
    }


def summarise(per_week: dict[str, np.ndarray]) -> dict[str, float]:
    """Mean of each metric over weeks, plus ``<name>_std`` and ``weeks``."""
    out: dict[str, float] = {}
    for name, values in per_week.items():
        out[name] = float(np.mean(values))
        out[f"{name}_std"] = float(np.std(values))
    out["weeks"] = int(len(next(iter(per_week.values()))))
    return out


def response_scores(
    true_energy: np.ndarray, pred_energy: np.ndarray, groups: np.ndarray, floor: float
) -> dict[str, float | int | None]:
    """The savings of one setting against another on the same week, predicted against simulated.

    Args:
        true_energy, pred_energy: ``(N,)`` weekly HVAC energy (Wh/m2 per hour), simulated and predicted.
        groups: ``(N,)`` one integer per week that is the same for the same building and week under other
            settings; each week is compared with its group's first.
        floor: smallest reference energy a saving is divided by (Wh/m2 per hour).
    Returns:
        ``response_pairs`` (weeks compared), ``response_savings_error_mean_abs_points``, ``..._p90_abs_points``,
        ``response_savings_bias_points`` (predicted - simulated savings, percent points) and
        ``response_savings_spearman`` over every pair (``None`` under three pairs or with constant savings);
        ``{"response_pairs": 0}`` when no group has two weeks.
    """
    from scipy.stats import spearmanr

    _, first, inverse = np.unique(groups, return_index=True, return_inverse=True)
    reference = first[inverse]
    pair = reference != np.arange(len(groups))
    if not pair.any():
        return {"response_pairs": 0}

    def savings(energy: np.ndarray) -> np.ndarray:
        ref = energy[reference[pair]]
        return 100.0 * (1.0 - energy[pair] / np.maximum(ref, floor))

    sim, pred = savings(np.asarray(true_energy, float)), savings(np.asarray(pred_energy, float))
    err = pred - sim
    rho = float(spearmanr(pred, sim).statistic) if pair.sum() > 2 else float("nan")
    return {
        "response_pairs": int(pair.sum()),
        "response_savings_error_mean_abs_points": float(np.abs(err).mean()),
        "response_savings_error_p90_abs_points": float(np.percentile(np.abs(err), 90)),
        "response_savings_bias_points": float(err.mean()),
        "response_savings_spearman": rho if np.isfinite(rho) else None,
    }


def week_summary(outputs: np.ndarray, occupancy_fraction: np.ndarray, floor_area_m2: float) -> dict[str, float]:
    """Totals and means of one week.

    Args:
        outputs: ``(168, 8)`` hourly outputs (Wh/m2 per hour, degC).
        occupancy_fraction: ``(168,)`` hourly occupancy (0-1).
        floor_area_m2: floor area used to turn Wh/m2 into kWh.
    Returns:
        ``{"<OUTPUT>_kwh": weekly total for each energy output, "heat_consumption_kwh": the paper's measured
        heat consumption (Q_HEAT_OFFICE + Q_AHU_H + Q_EQP + Q_LIGHT), "t_int_occupied_mean_c",
        "t_int_unoccupied_mean_c", "t_int_min_c", "t_int_max_c"}``.
    """
    out = {name: outputs[:, i] for i, name in enumerate(cat.OUTPUT_NAMES)}
    occupied = np.asarray(occupancy_fraction) > 0
    summary: dict[str, float] = {}
    for name in cat.OUTPUT_NAMES:
        if name not in cat.TEMPERATURE_OUTPUTS:
            summary[f"{name}_kwh"] = float(out[name].sum() * floor_area_m2 / 1000.0)
    summary["heat_consumption_kwh"] = float(sum(summary[f"{n}_kwh"] for n in cat.HEAT_CONSUMPTION_OUTPUTS))
    t_int = out["T_INT_OFFICE"]
    summary["t_int_occupied_mean_c"] = float(t_int[occupied].mean()) if occupied.any() else float("nan")
    summary["t_int_unoccupied_mean_c"] = float(t_int[~occupied].mean()) if (~occupied).any() else float("nan")
    summary["t_int_min_c"] = float(t_int.min())
    summary["t_int_max_c"] = float(t_int.max())
    return summary


# Site metrics: predictions against a site's measurements, hours ``(weeks, 168)``; NaN marks a missing hour.

GUIDELINE14_P = 1  # parameters counted in ASHRAE Guideline 14's n - p degrees of freedom
#: ASHRAE Guideline 14's limits for a calibrated model on hourly data: CV(RMSE) and |NMBE|, percent
GUIDELINE14_HOURLY_CV_PERCENT, GUIDELINE14_HOURLY_NMBE_PERCENT = 30.0, 10.0
#: ... and on monthly data
GUIDELINE14_MONTHLY_CV_PERCENT, GUIDELINE14_MONTHLY_NMBE_PERCENT = 15.0, 5.0
#: months a monthly CV(RMSE) needs; with fewer, only the bias of the monthly totals is judged
MONTHLY_CV_MIN_MONTHS = 3


def r2_masked(y: np.ndarray, p: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """R2 of each candidate's ``p (pop, weeks, 168)`` against ``y (weeks, 168)`` over ``mask`` hours."""
    yv = y[mask]
    ss_tot = ((yv - yv.mean()) ** 2).sum()
    ss_res = ((p[:, mask] - yv) ** 2).sum(-1)
    return 1.0 - ss_res / max(ss_tot, 1e-12)


def guideline14(measured: np.ndarray, predicted: np.ndarray, p: int = GUIDELINE14_P) -> tuple[float, float]:
    """ASHRAE Guideline 14 CV(RMSE) and NMBE in percent over the finite measured hours."""
    ok = np.isfinite(measured)
    y, yhat = measured[ok], predicted[ok]
    dof = max(len(y) - p, 1)
    mean = y.mean()
    return (
        float(100.0 * np.sqrt(((y - yhat) ** 2).sum() / dof) / mean),
        float(100.0 * (y - yhat).sum() / (dof * mean)),
    )


def guideline14_monthly(measured: np.ndarray, predicted: np.ndarray, months: np.ndarray) -> dict[str, float | None]:
    """Guideline 14 on monthly totals of the measured hours: ``nmbe_q_monthly_percent`` (the bias of the totals,
    100 sum(y - yhat) / sum(y)), ``cv_rmse_q_monthly_percent`` (``None`` for fewer than
    :data:`MONTHLY_CV_MIN_MONTHS` months) and ``months``. ``months``: a label of each hour's calendar month
    (e.g. 12 x year + month), the shape of ``measured``."""
    ok = np.isfinite(measured)
    labels = np.unique(months[ok])
    y = np.array([measured[ok & (months == m)].sum() for m in labels])
    yhat = np.array([predicted[ok & (months == m)].sum() for m in labels])
    cv = None
    if len(y) >= MONTHLY_CV_MIN_MONTHS:
        dof = len(y) - GUIDELINE14_P
        cv = float(100.0 * np.sqrt(((y - yhat) ** 2).sum() / dof) / y.mean())
    nmbe = float(100.0 * (y - yhat).sum() / y.sum()) if len(y) else float("nan")
    return {"cv_rmse_q_monthly_percent": cv, "nmbe_q_monthly_percent": nmbe, "months": len(y)}


def site_metrics(
    temperature: np.ndarray,
    consumption: np.ndarray,
    pred_t: np.ndarray,
    pred_q: np.ndarray,
    occupied: np.ndarray,
    scale: dict[str, tuple[float, float]],
) -> dict[str, float]:
    """Predictions against measurements (R2, standardised MSE, RMSE, Guideline 14); arrays ``(weeks, 168)``."""
    out: dict[str, float] = {}
    for key, y, p in (("t", temperature, pred_t), ("q", consumption, pred_q)):
        ok = np.isfinite(y)
        mean, std = scale[key]
        z = ((p - y) / std) ** 2
        out[f"r2_{key}"] = float(r2_masked(y, p[None], ok)[0])
        out[f"mse_{key}"] = float(z[ok].mean())
        occ = ok & occupied
        out[f"mse_{key}_occ"] = float(z[occ].mean()) if occ.any() else float("nan")
    ok = np.isfinite(temperature)
    out["rmse_t_celsius"] = float(np.sqrt(((pred_t - temperature)[ok] ** 2).mean()))
    ok_q = np.isfinite(consumption)
    out["rmse_q_wh_m2"] = float(np.sqrt(((pred_q - consumption)[ok_q] ** 2).mean()))
    out["cv_rmse_q_percent"], out["nmbe_q_percent"] = guideline14(consumption, pred_q)
    out["hours"] = int(np.isfinite(consumption).sum())
    return out
