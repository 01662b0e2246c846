"""The response check: does the model answer a change of settings as the building does?

Random weekly settings (and any chosen ones) run through the calibrated metamodel and through the site's EnergyPlus
model on one week; each setting's savings against the historical settings and its comfort are compared. An
optimiser is only as good as this agreement: a model that ranks settings wrongly or misjudges their size chooses
settings whose savings do not materialise.

The same settings also run on the EnergyPlus shoebox at the calibrated parameters, the simulator the metamodel
imitates, which splits the savings error in two: the metamodel against its shoebox (a better metamodel closes it)
and the shoebox against the building (the model's structure and what calibration could identify).
"""

from __future__ import annotations

import datetime as dt
import time
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from scipy.stats import spearmanr

from buildenv import catalogue as cat
from buildenv.sites.suite import check_calibrated_sites


@dataclass
class ResponseCheck:
    """Predicted and realised responses of settings on one week.

    Attributes:
        week: week of the site's year.
        predicted_savings, realised_savings: ``(N,)`` savings against the historical settings, percent.
        predicted_comfort, realised_comfort: ``(N,)`` comfort term, K (lower is better).
        actions: ``(N, A)`` the settings checked (A: the action size).
        summary: ``week``, the figures of :func:`summarise` over the random settings (only ``settings``: 0
            without any) and the settings their error follows (``savings_error_drivers``, :func:`error_drivers`),
            ``seconds_energyplus``, with the shoebox those of :func:`split_error` and each part's drivers
            (``metamodel_vs_shoebox_drivers``, ``shoebox_vs_building_drivers``), and with chosen
            settings ``"chosen"``: one :func:`chosen_figures` entry each (with the shoebox's savings,
            ``shoebox_savings_percent``).
        shoebox_savings: ``(N,)`` savings on the EnergyPlus shoebox at the calibrated parameters, percent (``None``
            when not run).
    """

    week: int
    predicted_savings: np.ndarray
    realised_savings: np.ndarray
    predicted_comfort: np.ndarray
    realised_comfort: np.ndarray
    actions: np.ndarray
    summary: dict
    shoebox_savings: np.ndarray | None = None


def first_heldout_week(env) -> int:
    """The week to check when none is given: the site's first held-out (not calibrated-on) measured week, else
    its last measured week (a week of the site's year)."""
    base = env.unwrapped
    site = base.site
    held = (site.calibration or {}).get("heldout_weeks") or [site.weeks - 1]
    return base.site_model.week_of(site.start + dt.timedelta(days=7 * int(held[0])))


def energyplus_env(env: gym.Env) -> gym.Env:
    """``BuildingWeek-v0`` on the EnergyPlus model of ``env``'s current site (the first before any reset), with
    ``env``'s other arguments, every week of the site allowed: what its metamodel's predictions are checked
    against."""
    base = env.unwrapped
    kwargs = {k: v for k, v in base.arguments.items() if k not in ("backend", "weeks", "site", "sites")}
    return gym.make("BuildingWeek-v0", **kwargs, site=str(base.site.path), weeks="all", backend="energyplus")


def random_actions(env, n: int, seed: int = 0) -> np.ndarray:
    """``(n, A)`` actions drawn uniformly over the environment's action space with ``seed``."""
    space = env.action_space
    rng = np.random.default_rng(seed)
    return rng.uniform(space.low, space.high, (n, *space.shape)).astype(np.float32)


def _spearman(a, b) -> float:
    """Spearman rank correlation of two series, 3 decimals (NaN with fewer than 3 values)."""
    return round(float(spearmanr(a, b).statistic), 3) if len(a) > 2 else float("nan")


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
        "savings_spearman": _spearman(pred_s, real_s),
        "comfort_error_mean_abs_k": round(float(np.abs(cerr).mean()), 3),
        "comfort_spearman": _spearman(pred_c, real_c),
    }


def chosen_figures(pred_s: float, real_s: float, pred_c: float, real_c: float) -> dict[str, float]:
    """One chosen setting's predicted and realised savings (percent) and comfort (K), and its savings error
    (points: predicted - realised)."""
    return {
        "predicted_savings_percent": round(float(pred_s), 2),
        "realised_savings_percent": round(float(real_s), 2),
        "savings_error_points": round(float(pred_s - real_s), 2),
        "predicted_comfort_k": round(float(pred_c), 3),
        "realised_comfort_k": round(float(real_c), 3),
    }


def split_error(predicted, shoebox, realised) -> dict[str, float]:
    """The savings error (points) split at the shoebox: the metamodel against the shoebox and the shoebox against
    the building, each as 90th percentile of the absolute and mean (bias), and the shoebox's Spearman with the
    building."""
    to_shoebox = np.asarray(predicted) - np.asarray(shoebox)
    to_building = np.asarray(shoebox) - np.asarray(realised)
    return {
        "metamodel_vs_shoebox_p90_abs_points": round(float(np.percentile(np.abs(to_shoebox), 90)), 2),
        "metamodel_vs_shoebox_bias_points": round(float(to_shoebox.mean()), 2),
        "shoebox_vs_building_p90_abs_points": round(float(np.percentile(np.abs(to_building), 90)), 2),
        "shoebox_vs_building_bias_points": round(float(to_building.mean()), 2),
        "shoebox_spearman": _spearman(shoebox, realised),
    }


def error_drivers(settings: np.ndarray, error: np.ndarray, alpha: float = 0.05) -> list[dict]:
    """The settings an error follows across the checked settings: the Spearman rank correlation of each setting's
    mean over the week with the error, those significant at ``alpha`` over the settings that vary (Bonferroni),
    strongest first. A lever the model answers wrongly shows here (a positive correlation: the higher the setting,
    the more the savings are over-predicted).

    Args:
        settings: ``(N, 7, S)`` the checked weekly settings, catalogue order and units.
        error: ``(N,)`` their savings error (points, predicted - realised).
        alpha: family-wise significance level.
    Returns:
        ``[{"setting", "spearman", "p_value"}]``; empty with fewer than 5 settings.
    """
    means = np.asarray(settings, float).mean(axis=1)
    error = np.asarray(error, float)
    varying = [j for j in range(means.shape[1]) if np.ptp(means[:, j]) > 0]
    if len(error) < 5 or not varying or np.ptp(error) == 0:
        return []
    found = []
    for j in varying:
        test = spearmanr(means[:, j], error)
        if test.pvalue < alpha / len(varying):
            found.append(
                {
                    "setting": cat.SETTING_NAMES[j],
                    "spearman": round(float(test.statistic), 3),
                    "p_value": float(f"{test.pvalue:.2g}"),
                }
            )
    return sorted(found, key=lambda d: -abs(d["spearman"]))


def shoebox_savings(env, week: int, settings: np.ndarray, workers: int | None = None) -> np.ndarray | None:
    """Savings (percent, against the historical settings, as the environment scores them) of settings ``(N, 7, 13)``
    on the EnergyPlus shoebox the metamodel was trained on (its zoning) at the site's calibrated parameters in
    ``week`` (the week before under the historical settings, as the environment simulates it); declared effects are
    left out. ``None`` when the week is not one of the site's measured weeks after its first (the week before runs
    as warm-up) or a run cannot stay inside one year."""
    import dataclasses

    from buildenv.calibration.energyplus import ShoeboxPool, plan_site_run
    from buildenv.calibration.problem import CalibrationError
    from buildenv.env import objectives as obj

    base = env.unwrapped
    site, model = base.site, base.site_model
    w = (model.week_starts[int(week)] - site.start).days // 7
    if w < 1:
        return None
    try:
        run = plan_site_run(site, [w], model.surrogate.zoning)
    except CalibrationError:
        return None
    historical = np.asarray(model.historical, float)
    run = dataclasses.replace(run, settings=np.stack([historical] * run.weeks))
    runs = [run] + [dataclasses.replace(run, settings=np.concatenate([run.settings[:-1], s[None]])) for s in settings]
    n = len(runs)
    occupancy = np.broadcast_to(model.occupancy, (n, *model.occupancy.shape))
    with ShoeboxPool(workers) as pool:
        outputs = pool.simulate_runs(runs, np.broadcast_to(model.theta, (n, len(cat.THETA_NAMES))), occupancy)
    energy = np.array([obj.hvac_energy(o[-1:])[0] for o in outputs])
    return 100.0 * (1.0 - obj.energy_ratio(energy[1:], energy[0]))


def response_check(
    env, week: int, n: int = 20, seed: int = 0, extra: np.ndarray | None = None, shoebox: bool = True
) -> ResponseCheck:
    """Run ``n`` random settings (and ``extra`` ``(M, A)`` ones) on the metamodel and on the site's EnergyPlus model.

    Args:
        env: the metamodel ``BuildingWeek-v0`` of a site made by ``buildenv site reference`` (its arguments are
            reused for the EnergyPlus backend).
        week: week of the site's year.
        n: random settings, drawn with ``seed`` (:func:`random_actions`).
        extra: further settings to check, e.g. an optimiser's choice: scored apart from the random ones
            (``summary["chosen"]``).
        shoebox: run them on the shoebox at the calibrated parameters too (:func:`shoebox_savings`).
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
    started = time.perf_counter()
    realised = energyplus_env(env).unwrapped.evaluate(actions, week=week)
    seconds = time.perf_counter() - started
    ps, rs = predicted["savings_percent"], realised["savings_percent"]
    pc, rc = predicted["comfort_k"], realised["comfort_k"]
    summary: dict = {"week": int(week), "settings": 0}
    settings = predicted["settings"][:n]
    if n > 0:
        summary.update(summarise(ps[:n], rs[:n], pc[:n], rc[:n]))
        summary["savings_error_drivers"] = error_drivers(settings, ps[:n] - rs[:n])
    summary["seconds_energyplus"] = round(seconds, 1)
    sb = shoebox_savings(env, week, predicted["settings"]) if shoebox else None
    if sb is not None and n > 0:
        summary.update(split_error(ps[:n], sb[:n], rs[:n]))
        summary["metamodel_vs_shoebox_drivers"] = error_drivers(settings, ps[:n] - sb[:n])
        summary["shoebox_vs_building_drivers"] = error_drivers(settings, sb[:n] - rs[:n])
    if len(actions) > n:
        summary["chosen"] = [
            {
                **chosen_figures(ps[i], rs[i], pc[i], rc[i]),
                **({} if sb is None else {"shoebox_savings_percent": round(float(sb[i]), 2)}),
            }
            for i in range(n, len(actions))
        ]
    return ResponseCheck(int(week), ps, rs, pc, rc, actions, summary, sb)


#: the any-office targets of the response check: 90th-percentile savings error (points) and Spearman of savings
TARGET_P90_POINTS, TARGET_SPEARMAN = 5.0, 0.9
#: the any-office target of an optimiser's chosen settings: savings realised within this many points of predicted
TARGET_CHOSEN_POINTS = 3.0


def check_suite(
    suite,
    parts=("held_out",),
    n: int = 20,
    seed: int = 0,
    metamodel: str = "default",
    progress: bool = True,
    chosen: Callable[[gym.Env, int], np.ndarray] | None = None,
) -> list[dict]:
    """The response check on every calibrated site of a suite folder (:mod:`buildenv.sites.suite`) in ``parts``,
    on each site's first held-out week. Rows are also written to ``<suite>/response.json`` after each site, with
    ``errors``: the sites that could not be checked, and why (:func:`buildenv.sites.suite.check_calibrated_sites`).
    ``chosen(env, week)`` gives settings ``(M, A)`` an optimiser chose for the site's week, checked beside the
    random ones; a row then holds their figures (``"chosen"``) and whether the first was realised within
    :data:`TARGET_CHOSEN_POINTS`.

    Raises:
        BuildenvError: no calibrated site in ``parts`` (run ``buildenv suite calibrate`` first).
    """

    def one_site(record: dict) -> list[dict]:
        env = gym.make("BuildingWeek-v0", site=record["site"], metamodel=metamodel, weeks="all")
        week = first_heldout_week(env)
        check = response_check(env, week, n=n, seed=seed, extra=None if chosen is None else chosen(env, week))
        row = dict(check.summary)
        if n > 0:
            row["meets_target"] = bool(
                row["savings_error_p90_abs_points"] <= TARGET_P90_POINTS and row["savings_spearman"] >= TARGET_SPEARMAN
            )
        if "chosen" in row:
            row["chosen_meets_target"] = bool(abs(row["chosen"][0]["savings_error_points"]) <= TARGET_CHOSEN_POINTS)
        return [row]

    return check_calibrated_sites(suite, parts, one_site, "response.json", "response", progress)
