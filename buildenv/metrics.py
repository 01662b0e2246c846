"""Accuracy metrics of predicted weeks, computed in one place.

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

Two pooled scores complement the per-week ones (:func:`pooled_scores`): ``r2_t_pooled`` and ``r2_q_pooled``
are ``r2_score`` over every test hour of every week taken as one series (what ``r2_score(y.ravel(),
p.ravel())`` gives on the test set). A week whose indoor temperature barely moves (tight setpoints) has a
tiny per-week variance, so a 0.2 K error costs it a large per-week R2; the pooled score measures the same
errors against the spread of temperatures across weeks. Both are reported; neither is hidden.

:func:`daily_errors` splits the errors by day of the week (day 1 starts from the previous week's state,
which the model sees only through its context hours).
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


def week_metrics(y_true: np.ndarray, y_pred: np.ndarray, occupied: np.ndarray, mean: np.ndarray,
                 std: np.ndarray, alpha: float = 1.0, beta: float = 0.3) -> dict[str, np.ndarray]:
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
    return {"r2_t_pooled": float(r2_score(y_true[..., t].ravel(), y_pred[..., t].ravel())),
            "r2_q_pooled": float(r2_score(zt.ravel(), zp.ravel()))}


def daily_errors(y_true: np.ndarray, y_pred: np.ndarray, mean: np.ndarray, std: np.ndarray) -> dict[str, list[float]]:
    """Errors by day of the week (7 values each, day 1 first), pooled over weeks.

    ``rmse_t_celsius_by_day``: temperature RMSE (degC); ``mse_q_by_day``: standardised consumption MSE.
    """
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    days = (len(y_true), cat.HOURS_PER_WEEK // 24, 24)
    err_t = (y_pred[..., t] - y_true[..., t]).reshape(days)
    err_q = (((y_pred[..., q] - y_true[..., q]) / std[q]) ** 2).mean(-1).reshape(days)
    return {"rmse_t_celsius_by_day": np.sqrt((err_t ** 2).mean((0, 2))).round(4).tolist(),
            "mse_q_by_day": err_q.mean((0, 2)).round(5).tolist()}


def summarise(per_week: dict[str, np.ndarray]) -> dict[str, float]:
    """Mean of each metric over weeks, plus ``<name>_std`` and ``weeks``."""
    out: dict[str, float] = {}
    for name, values in per_week.items():
        out[name] = float(np.mean(values))
        out[f"{name}_std"] = float(np.std(values))
    out["weeks"] = int(len(next(iter(per_week.values()))))
    return out
