"""Calibrating a site: the metamodel fitted to a site's fit weeks and scored on its held-out weeks.

:func:`calibrate_site` builds the problem (:mod:`buildenv.calibration.problem`), runs CMA-ES (by default again
under the building parameters' prior, :mod:`buildenv.calibration.prior`) or Adam, fits the declared effects in a
further stage, scores fit and held-out weeks and writes ``calibration.json``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from buildenv import catalogue as cat
from buildenv.calibration.gradient import calibrate_adam
from buildenv.calibration.prior import prior_anchor
from buildenv.calibration.problem import (
    DAILY_WEIGHT,
    CalibrationError,
    _scale,
    _split,
    build_problem,
    calibrate_cmaes,
    check_declared_effects,
    default_weeks,
    evaluate,
    fit_declared_effects,
    metamodel_record,
    parameters_at_bounds,
    predict,
    predict_meters,
    score_series,
    score_weeks,
)
from buildenv.calibration.verdict import calibration_verdict
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import get_effect
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.threads import one_blas_thread
from buildenv.metrics import GUIDELINE14_P

log = logging.getLogger(__name__)


def _warn_outside_domain(site, surrogate: sg.Surrogate) -> None:
    """Log a warning for each value the site fixes (geometry, ``[known]``) outside the range the metamodel was
    trained on, or different from what it learnt for a variable it does not read: its predictions there are
    extrapolated, or ignore the value."""
    domain, implied = surrogate.domain, surrogate.implied
    for name, value in site.theta_known().items():
        lo, hi = domain.get(name, (-np.inf, np.inf))
        if name in implied and not np.isclose(value, implied[name]):
            log.warning(
                "%s: %s=%g is not read by metamodel %s (it learnt %g)",
                site.path,
                name,
                value,
                surrogate.path,
                implied[name],
            )
        elif not lo - 1e-9 <= value <= hi + 1e-9:
            log.warning(
                "%s: %s=%g is outside the range metamodel %s was trained on [%g, %g]; its predictions are extrapolated",
                site.path,
                name,
                value,
                surrogate.path,
                lo,
                hi,
            )


@one_blas_thread()  # buildenv.metamodel.threads: numpy's BLAS threads would fight the metamodel's
def calibrate_site(
    site,
    surrogate: sg.Surrogate,
    weeks: list[int] | None = None,
    method: str = "cmaes",
    seed: int = 0,
    max_evaluations: int = 6000,
    progress: bool = False,
    save: bool = True,
    restarts: int = 1,
    effects: tuple[str, ...] | None = None,
    prior: bool = True,
    daily_weight: float = DAILY_WEIGHT,
) -> dict:
    """Calibrate the metamodel to a site and score it on calibration and held-out weeks.

    Args:
        site: a :class:`buildenv.sites.Site`.
        surrogate: the metamodel.
        weeks: calibration weeks (0-based); the site's other weeks are held out. Default
            :func:`buildenv.calibration.problem.default_weeks`.
        method: ``cmaes`` or ``adam``.
        seed: seed of the optimiser.
        max_evaluations: budget of cost evaluations (one evaluation = one candidate on every calibration week)
            of each CMA-ES run.
        restarts: independent CMA-ES runs, the best kept
            (:func:`buildenv.calibration.problem.calibrate_cmaes`).
        progress: progress bar.
        save: write ``calibration.json`` into the site folder.
        effects: declared effects, fitted after the building and occupancy; None (default)
            takes the site's own (``site.toml``'s ``effects``, :attr:`buildenv.sites.Site.effects`), ``()`` none.
        prior: with CMA-ES, the maximum a posteriori estimate under the building parameters' prior
            (:mod:`buildenv.calibration.prior`, weighted by a first fit without it); ``False``: least squares only.
        daily_weight: weight of the meters' daily totals in the cost (:func:`buildenv.calibration.problem.costs`);
            default :data:`~buildenv.calibration.problem.DAILY_WEIGHT`, 0: the paper's cost.
    Returns:
        ``{"fit", "heldout"}`` metrics (:func:`buildenv.metrics.site_metrics`, with ``weeks``; ``heldout`` only
        when there are held-out weeks), ``"theta": {name: value}`` (catalogue units), ``"occupancy"``
        (``[[start, end] x 5]``, h), ``"known"``, ``"method"``, ``"seconds"``, ``"evaluations"``, ``"cost"``
        (CMA-ES also ``"run_costs"``), ``"fit_weeks"``, ``"heldout_weeks"``, ``"guideline14_p"``,
        ``"metamodel"``, ``"catalogue_hash"``, ``"daily_weight"``, ``"prior"`` (its weight and the residuals'
        effective hours, ``None`` without it) and ``"at_bounds"``
        (:func:`buildenv.calibration.problem.parameters_at_bounds`). With ``effects``:
        ``"declared_effects": [names]``, ``"effects": {effect: {parameter: value}}`` and
        ``"cost_without_effects"``. With CMA-ES ``restarts`` > 1 and held-out weeks, ``"runs"``: each run's
        ``seed``, ``cost`` (before the declared effects) and ``heldout_rmse_t_celsius`` (degC) and
        ``heldout_r2_t`` without the declared effects (:func:`buildenv.calibration.problem.runs_note`).
    Raises:
        CalibrationError: an unknown ``method``, a declared effect that is not declarable, bad ``weeks`` or a
            negative ``daily_weight``.
    """
    if not daily_weight >= 0:
        raise CalibrationError(f"daily_weight={daily_weight}: give a weight of 0 or more (0: the paper's cost)")
    effects = check_declared_effects(site.effects if effects is None else effects)
    _warn_outside_domain(site, surrogate)
    started = time.perf_counter()
    fit_weeks, heldout = (
        default_weeks(site.weeks)
        if weeks is None
        else (sorted(weeks), [w for w in range(site.weeks) if w not in weeks])
    )
    problem = build_problem(
        site,
        fit_weeks,
        context_hours=surrogate.context_hours,
        temperature_before=surrogate.uses_temperature_before,
        metamodel=surrogate,
        daily_weight=daily_weight,
    )
    _check_meters_vary(site, problem, fit_weeks)
    prior_record = None
    if method == "cmaes":
        best, info = calibrate_cmaes(problem, surrogate, seed, max_evaluations, progress=progress, restarts=restarts)
        if prior and int(problem.free.sum()) > 1:  # one parameter is searched without a pull (a line search)
            best, info, prior_record = _with_prior(problem, surrogate, best, info, seed, max_evaluations, restarts)
        run_parameters = info.pop("run_parameters")
    elif method == "adam":
        best, info = calibrate_adam(problem, surrogate, seed, progress=progress)
    else:
        raise CalibrationError(f"unknown calibration method {method!r}; choose cmaes or adam")
    declared: dict = {}
    if effects:
        declared["cost_without_effects"] = info["cost"]
        problem = build_problem(
            site,
            fit_weeks,
            effects,
            context_hours=surrogate.context_hours,
            temperature_before=surrogate.uses_temperature_before,
            metamodel=surrogate,
            daily_weight=daily_weight,
        )
        best, stage = fit_declared_effects(problem, surrogate, best, seed)
        info = {**info, "evaluations": info["evaluations"] + stage["evaluations"], "cost": stage["cost"]}
        values = em.split_parameters(effects, best[None, problem.n_base :])
        declared.update(
            declared_effects=list(effects),
            effects={
                e: {p.name: round(float(v), 5) for p, v in zip(get_effect(e).parameters, values[e][0])} for e in effects
            },
        )
    seconds = time.perf_counter() - started
    theta, occ = _split(problem, best[None])
    result = {
        "method": method,
        "seconds": round(seconds, 2),
        **info,
        "fit_weeks": fit_weeks,
        "heldout_weeks": heldout,
        "guideline14_p": GUIDELINE14_P,
        "theta": dict(zip(cat.THETA_NAMES, np.round(theta[0], 5).tolist())),
        "known": sorted(site.known),
        "not_read": sorted(surrogate.implied),
        "occupancy": np.round(occ[0], 3).tolist(),
        "at_bounds": parameters_at_bounds(dict(zip(cat.THETA_NAMES, theta[0].tolist())), site.known, surrogate),
        **metamodel_record(surrogate),
        "catalogue_hash": cat.catalogue_hash(),
        "daily_weight": float(daily_weight),
        "prior": prior_record,
        **declared,
    }
    scale = _scale(problem)
    for key, ws in (("fit", fit_weeks), ("heldout", heldout)):
        if ws:
            result[key] = score_weeks(site, surrogate, ws, best, scale, effects)
            result[key]["seconds"], result[key]["evaluations"] = result["seconds"], result["evaluations"]
    if method == "cmaes" and restarts > 1 and heldout:
        result["runs"] = _score_runs(site, surrogate, heldout, info["run_costs"], run_parameters, scale, seed)
    result["verdict"] = calibration_verdict(result)
    if save:
        from buildenv.sites import save_calibration

        save_calibration(site.path, result)
    return result


def _check_meters_vary(site, problem, fit_weeks: list[int]) -> None:
    """A CalibrationError if a meter reads one value in every measured hour of the calibration weeks (a gas meter
    in summer): an R2 against it is not defined."""
    for (column, _, _), measured in zip(site.meters(), (problem.consumption_wh_m2, problem.electricity_wh_m2)):
        values = measured[np.isfinite(measured)]
        if values.size and np.ptp(values) == 0:
            raise CalibrationError(
                f"{site.path}: {column} reads {values[0] * site.floor_area_m2 / 1000:g} kWh in every hour of the "
                f"calibration weeks {fit_weeks}: nothing to fit; leave that meter out of the site ([meters]) or "
                "calibrate on weeks it varies"
            )


def _with_prior(problem, surrogate, best, info, seed, max_evaluations, restarts):
    """CMA-ES again from the fit without the prior (``best``), on the cost plus the prior
    (:mod:`buildenv.calibration.prior`, centred on the ranges), its weight read off that fit's residuals; returns the
    new best, the CMA-ES record (evaluations of both runs) and the prior's record."""
    t, q, e = predict_meters(problem, surrogate, best)
    observed, modelled = [problem.temperature_c, problem.consumption_wh_m2], [t, q]
    if e is not None:
        observed, modelled = [*observed, problem.electricity_wh_m2], [*modelled, e]
    anchor, record = prior_anchor(observed, modelled)
    centre = problem.from_unit(np.full(int(problem.free.sum()), 0.5))[0]
    theta = np.array([n in cat.THETA_NAMES for n in problem.names])
    found, second = calibrate_cmaes(
        problem,
        surrogate,
        seed,
        max_evaluations,
        start=best,
        anchor=anchor,
        anchored=theta,
        towards=centre,
        restarts=restarts,
    )
    record["cost_without_prior"] = round(float(info["cost"]), 5)
    # CMA-ES keeps the best point it sampled, not its start: where none beat the first fit under the prior, the
    # first fit is the estimate
    first = float(info["cost"]) + anchor * float((((problem.to_unit(best) - 0.5) ** 2)[theta[problem.free]]).sum())
    record["kept_first_fit"] = first <= min(second["run_costs"])
    if record["kept_first_fit"]:  # the first fit's runs stand, each scored under the prior
        runs = info["run_parameters"]
        pulls = anchor * (((np.stack([problem.to_unit(r) for r in runs]) - 0.5) ** 2)[:, theta[problem.free]]).sum(-1)
        found = best
        second = {
            **second,
            "cost": info["cost"],
            "run_parameters": runs,
            "run_costs": (np.asarray(info["run_costs"]) + pulls).tolist(),
        }
    record["run_costs_with_prior"] = second["run_costs"]
    second["run_costs"] = evaluate(problem, surrogate, second["run_parameters"]).tolist()  # the plain cost, as "cost"
    return found, {**second, "evaluations": info["evaluations"] + second["evaluations"]}, record


def _score_runs(
    site,
    surrogate: sg.Surrogate,
    heldout: list[int],
    run_costs: list[float],
    run_parameters: np.ndarray,
    scale: dict[str, tuple[float, float]],
    seed: int,
) -> list[dict]:
    """``calibrate_site``'s ``runs``: each CMA-ES run's seed, cost and held-out RMSE_T (degC) and R2_T of its
    parameters without the declared effects, the held-out weeks encoded once."""
    problem = build_problem(
        site,
        heldout,
        context_hours=surrogate.context_hours,
        temperature_before=surrogate.uses_temperature_before,
        metamodel=surrogate,
    )
    runs = []
    for k, (cost, params) in enumerate(zip(run_costs, run_parameters)):
        metrics = score_series(problem, *predict(problem, surrogate, params), params, scale)
        runs.append(
            {
                "seed": seed + k,
                "cost": round(cost, 5),
                **{f"heldout_{m}": round(metrics[m], 4) for m in ("rmse_t_celsius", "r2_t")},
            }
        )
    return runs
