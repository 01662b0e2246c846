"""The response check: does the model answer a change of settings as the building does?

Random weekly settings (and any chosen ones) run through the calibrated metamodel and through the site's EnergyPlus
model on one week; each setting's savings against the historical settings and its comfort are compared. An
optimiser is only as good as this agreement: a model that ranks settings wrongly or misjudges their size chooses
settings whose savings do not materialise.
"""

from __future__ import annotations

import datetime as dt
import json
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from scipy.stats import spearmanr

from buildenv.errors import BuildenvError
from buildenv.sites.suite import CASE_FIELDS, read_manifest


@dataclass
class ResponseCheck:
    """Predicted and realised responses of settings on one week.

    Attributes:
        week: week of the site's year.
        predicted_savings, realised_savings: ``(N,)`` savings against the historical settings, percent.
        predicted_comfort, realised_comfort: ``(N,)`` comfort term, K (lower is better).
        actions: ``(N, A)`` the settings checked (A: the action size).
        summary: the figures of :func:`summarise`, and ``seconds_energyplus``.
    """

    week: int
    predicted_savings: np.ndarray
    realised_savings: np.ndarray
    predicted_comfort: np.ndarray
    realised_comfort: np.ndarray
    actions: np.ndarray
    summary: dict[str, float]


def first_heldout_week(env) -> int:
    """The week to check when none is given: the site's first held-out (not calibrated-on) measured week, else
    its last measured week (a week of the site's year)."""
    base = env.unwrapped
    site = base.site
    held = (site.calibration or {}).get("heldout_weeks") or [site.weeks - 1]
    return base.site_model.week_of(site.start + dt.timedelta(days=7 * int(held[0])))


def random_actions(env, n: int, seed: int = 0) -> np.ndarray:
    """``(n, A)`` actions drawn uniformly over the environment's action space with ``seed``."""
    space = env.action_space
    rng = np.random.default_rng(seed)
    return rng.uniform(space.low, space.high, (n, *space.shape)).astype(np.float32)


def summarise(pred_s, real_s, pred_c, real_c) -> dict[str, float]:
    """Savings error (points: predicted - realised) as mean absolute, 90th percentile of the absolute and mean
    (bias); Spearman rank correlation of the savings; comfort error (K) as mean absolute and Spearman."""
    err = np.asarray(pred_s) - np.asarray(real_s)
    cerr = np.asarray(pred_c) - np.asarray(real_c)
    return {
        "settings": int(len(err)),
        "savings_error_mean_abs_points": round(float(np.abs(err).mean()), 2),
        "savings_error_p90_abs_points": round(float(np.percentile(np.abs(err), 90)), 2),
        "savings_bias_points": round(float(err.mean()), 2),
        "savings_spearman": round(float(spearmanr(pred_s, real_s).statistic), 3) if len(err) > 2 else float("nan"),
        "comfort_error_mean_abs_k": round(float(np.abs(cerr).mean()), 3),
        "comfort_spearman": round(float(spearmanr(pred_c, real_c).statistic), 3) if len(err) > 2 else float("nan"),
    }


def response_check(env, week: int, n: int = 20, seed: int = 0, extra: np.ndarray | None = None) -> ResponseCheck:
    """Run ``n`` random settings (and ``extra`` ``(M, A)`` ones) on the metamodel and on the site's EnergyPlus model.

    Args:
        env: the metamodel ``BuildingWeek-v0`` of a site made by ``buildenv site reference`` (its arguments are
            reused for the EnergyPlus backend).
        week: week of the site's year.
        n: random settings, drawn with ``seed`` (:func:`random_actions`).
        extra: further settings to check, e.g. an optimiser's choice.
    Returns:
        the :class:`ResponseCheck`.
    Raises:
        BuildingEnvError: the site has no EnergyPlus model.
    """
    base = env.unwrapped
    actions = random_actions(env, n, seed)
    if extra is not None:
        actions = np.concatenate([actions, np.atleast_2d(np.asarray(extra, np.float32))])
    predicted = base.evaluate(actions, week=week)
    kwargs = {k: v for k, v in base.arguments.items() if k not in ("backend", "weeks")}
    started = time.perf_counter()
    real_env = gym.make("BuildingWeek-v0", **kwargs, weeks="all", backend="energyplus")
    realised = real_env.unwrapped.evaluate(actions, week=week)
    seconds = time.perf_counter() - started
    ps, rs = predicted["savings_percent"], realised["savings_percent"]
    pc, rc = predicted["comfort_k"], realised["comfort_k"]
    summary = {"week": int(week), **summarise(ps, rs, pc, rc), "seconds_energyplus": round(seconds, 1)}
    return ResponseCheck(int(week), ps, rs, pc, rc, actions, summary)


#: the any-office targets of the response check: 90th-percentile savings error (points) and Spearman of savings
TARGET_P90_POINTS, TARGET_SPEARMAN = 5.0, 0.9


def check_suite(
    suite,
    parts=("held_out",),
    n: int = 20,
    seed: int = 0,
    metamodel: str = "default",
    progress: bool = True,
) -> list[dict]:
    """The response check on every calibrated site of a suite folder (:mod:`buildenv.sites.suite`) in ``parts``,
    on each site's first held-out week; rows are also written to ``<suite>/response.json``.

    Raises:
        BuildenvError: no calibrated site in ``parts`` (run ``buildenv suite calibrate`` first).
    """
    from tqdm import tqdm

    records = [
        r
        for r in read_manifest(suite)
        if r["status"] in ("made", "reused") and r["part"] in parts and (Path(r["site"]) / "calibration.json").is_file()
    ]
    if not records:
        raise BuildenvError(f"{suite}: no calibrated site in {', '.join(parts)}; run buildenv suite calibrate first")
    rows = []
    for r in tqdm(records, desc="response", unit="site", disable=not progress):
        env = gym.make("BuildingWeek-v0", site=r["site"], metamodel=metamodel, weeks="all")
        check = response_check(env, first_heldout_week(env), n=n, seed=seed)
        s = check.summary
        rows.append(
            {
                **{k: r[k] for k in CASE_FIELDS},
                **s,
                "meets_target": bool(
                    s["savings_error_p90_abs_points"] <= TARGET_P90_POINTS and s["savings_spearman"] >= TARGET_SPEARMAN
                ),
            }
        )
    Path(suite, "response.json").write_text(json.dumps({"rows": rows}, indent=1) + "\n", encoding="utf-8")
    return rows
