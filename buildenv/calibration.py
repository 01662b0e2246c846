"""Calibrating the metamodel to a site: theta_build and occupancy estimated from two measured series.

**What is estimated.** Every theta_build variable except the site's known geometry (floor area, storeys,
fixed) and the parameters its ``[known]`` table declares (fixed too: they keep their place in the parameter
vector with both bounds at the known value, and the optimisers search only the others), and one weekly
occupancy schedule O (start and end hour of each weekday) shared by all weeks (a held-out week's occupancy is
unknown, so a per-week estimate could not be used on it). Bounds come from the catalogue; the search runs in
``[0, 1]`` per parameter and maps linearly onto ``[min, max]`` (values between catalogue steps are allowed:
the metamodel is continuous in them).

**Cost** (the paper's): ``w_T (1 - R2_T) + w_Q (1 - R2_Q)`` over the calibration weeks' measured hours,
with ``w_T = w_Q = 1`` (:data:`WEIGHTS`); R2 is ``sklearn.metrics.r2_score`` of the measured series, pooled
over the calibration weeks. Missing hours (gaps) are left out of every sum.

**Consumption mapping.** The site's heat consumption (kWh per hour) divided by its floor area is compared
with the metamodel's Q_HEAT_OFFICE + Q_AHU_H + Q_EQP + Q_LIGHT (Wh/m2 per hour), as the paper's appendix.

**Methods.** ``cmaes``: CMA-ES (pycma), each generation's population evaluated in one batched metamodel call.
``adam``: the metamodel is differentiable, so gradient descent (Adam) on a smooth version of the same cost
from several random starts, the best kept; occupancy hours enter the hourly schedule through a sigmoid ramp
of width :data:`RAMP_HOURS` instead of a step (exact again at the end, when the cost is re-scored).

**Metrics** (:func:`site_metrics`; ASHRAE Guideline 14 for CV(RMSE) and NMBE with ``n - p`` degrees of
freedom, ``p = 1`` as Guideline 14 uses for calibrated simulation): ``r2_t, r2_q, rmse_t_celsius,
rmse_q_wh_m2, mse_t, mse_q, mse_t_occ, mse_q_occ, cv_rmse_q_percent, nmbe_q_percent`` where the MSEs are of the series
standardised by the measured calibration weeks' mean and standard deviation, and ``*_occ`` counts the hours
the calibrated occupancy marks as occupied.

**Declared effects** (``effects=``, ``buildenv calibrate --effect NAME``): effects of the effects catalogue
(:mod:`buildenv.effects`) that the owner knows the building has, such as the night cycle of a VAV system with
terminal reheat (``night_cycle_cold_air``), are added to the model in a second stage: theta_build and
occupancy are calibrated first, then the effects' parameters with them kept (:func:`fit_declared_effects`).
Calibrating all of them together overfits the fit weeks: on the default site (fit weeks 0-2, held-out 3-5)
with ``night_cycle_cold_air``, together gave fit cost 0.198 but held-out R2_T 0.907 and CV(RMSE) 16.6 %
(seed 0; 0.894 and 15.1 % with seed 1); the two stages give fit cost 0.215, held-out R2_T 0.913 and
CV(RMSE) 13.6 % (without the effect: 0.850 and 13.7 %). Rechecked with the site's three declared effects and
the 160,000-week default metamodel (2026-11-26, seed 0, 6,000 evaluations per run): together, fit cost 0.098
and held-out R2_T 0.947, CV(RMSE) 10.8 % (three runs, the best kept: 0.085, 0.952 and 10.6 %); the two stages
as shipped give 0.123, 0.955 and 9.5 %. The saved calibration lists them under
``declared_effects`` with their parameters under ``effects``, which BuildingWeek-v0 and the optimisers
simulate with and the gap diagnosis takes as known (not as candidates).

**Parameters at a bound** (:func:`parameters_at_bounds`, ``at_bounds`` in the result): the estimated building
parameters within :data:`AT_BOUND_SHARE` of their range from one end of it. The metamodel was trained inside
the catalogue's ranges and calibration cannot go further, so a parameter there is one the fit wanted to take
further: the building may lie outside the range, or the parameter is standing in for something the model
lacks (an unmodelled effect, another HVAC structure), or the cost is flat along it. On the default site 11 of
the 17 estimated parameters calibrate at a bound; docs/calibration.md ("Parameters at the catalogue's bounds")
says which of them the EnergyPlus shoebox confirms.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv import effects_model as em
from buildenv import surrogate as sg
from buildenv.effects import EffectError, check_declarable, get_effect
from buildenv.errors import BuildenvError
from buildenv.schedules import hourly_schedules
from buildenv.threads import one_blas_thread

WEIGHTS = {"temperature": 1.0, "consumption": 1.0}
SITE_CONSUMPTION_OUTPUTS = cat.HEAT_CONSUMPTION_OUTPUTS
GUIDELINE14_P = 1
RAMP_HOURS = 0.5
KNOWN_GEOMETRY = ("floor_area_m2", "number_of_floors")
#: A parameter this share of its catalogue range (or less) from one end of it is reported at that bound.
AT_BOUND_SHARE = 0.02
#: runs_note: CMA-ES runs within this share of the best run's cost whose held-out RMSE_T differ by this ratio.
RUNS_COST_TOLERANCE = 0.05
RUNS_DISAGREEMENT = 1.5
SIGMA0 = 0.3  # CMA-ES initial step, in units of the unit box's side
CMAES_TOLFUN = 1e-6


class CalibrationError(BuildenvError):
    """A calibration cannot run on the given site or weeks."""


@dataclass
class Problem:
    """What calibration fits: the site's weeks, encoded once, and the parameters' bounds."""

    x_base: np.ndarray  # (weeks, context + 168, C) encoded inputs with placeholder theta/occupancy
    temperature_c: np.ndarray  # (weeks, 168) measured, NaN where missing
    consumption_wh_m2: np.ndarray  # (weeks, 168) measured, NaN where missing
    theta_known: dict[str, float]
    names: list[str]  # free parameters: theta names, occupancy "occupancy_<day>_<start|end>", then effects
    lo: np.ndarray
    hi: np.ndarray
    effects: tuple[str, ...] = ()  # model-side effects (buildenv.effects_model) whose parameters follow
    absent: np.ndarray | None = None  # (weeks, 7) absence shares of the days (the holidays effect; 0 = normal)

    @property
    def free(self) -> np.ndarray:
        """``(dim,)`` booleans: the parameters the optimisers search (a known one has ``lo == hi``)."""
        return self.hi > self.lo

    def from_unit(self, z: np.ndarray) -> np.ndarray:
        """Physical ``(pop, dim)`` parameters from ``(pop, free parameters)`` points of the unit box."""
        z = np.atleast_2d(z)
        params = np.repeat(self.lo[None], len(z), axis=0)
        params[:, self.free] += z * (self.hi - self.lo)[self.free]
        return params

    def to_unit(self, params: np.ndarray) -> np.ndarray:
        """The unit-box point ``(free parameters,)`` of physical parameters ``(dim,)``."""
        free = self.free
        return (np.asarray(params, float)[free] - self.lo[free]) / (self.hi - self.lo)[free]

    @property
    def n_base(self) -> int:
        """Number of theta + occupancy parameters (the effects' follow)."""
        return len(self.names) - len(em.parameter_names(self.effects))

    @property
    def dim(self) -> int:
        """Number of free parameters."""
        return len(self.names)


def free_theta() -> list[str]:
    """theta_build names calibration can estimate, in catalogue order (all but the known geometry; a site's
    ``[known]`` ones stay in the list, fixed by their bounds)."""
    return [n for n in cat.THETA_NAMES if n not in KNOWN_GEOMETRY]


def parameter_names() -> list[str]:
    """Names of the calibrated parameters, in vector order."""
    occ = [f"{name}_{day}" for day in cat.WEEKDAYS for name in (v.name for v in cat.GROUPS["occupancy"])]
    return free_theta() + occ


def build_problem(site, weeks: list[int], effects: tuple[str, ...] = (), absent: np.ndarray | None = None,
                  context_hours: int = sg.CONTEXT_HOURS, temperature_before: bool = False) -> Problem:
    """Encode a site's weeks, each with the days before it as context.

    The context of a week is the last days of the week before: its settings, the calibrated occupancy and the
    weather file's hours before the week. Before the first measured week the building ran too, under
    settings the site does not record; they are taken to be the first week's own (its last days), as
    :class:`buildenv.site_model.SiteModel` does for every week and as the reference-building stand-in's
    warm-up week runs them. (A metamodel that sees several days before Monday reads a weekend there; the
    week's Monday repeated, what EnergyPlus's warm-up gives a run's first week, would tell it the building
    was heated all weekend.)

    Args:
        site: a :class:`buildenv.site.Site`.
        weeks: the site's weeks (0-based).
        effects: model-side effects (:mod:`buildenv.effects_model`) whose parameters are calibrated too.
        absent: ``(site weeks, 7)`` absence shares of the days (rows of ``weeks`` are used).
        context_hours: the metamodel's (:attr:`buildenv.surrogate.Surrogate.context_hours`).
        temperature_before: encode the temperature measured over each week's context hours (the end of the
            site's previous measured week; unknown before its first), for a metamodel that reads it
            (:attr:`buildenv.surrogate.Surrogate.uses_temperature_before`). The sensor's bias, where the model
            has one, is taken off it (:func:`buildenv.effects_model.transform_inputs`).
    """
    if not weeks:
        raise CalibrationError("no weeks to calibrate on")
    bad = [w for w in weeks if not 0 <= w < site.weeks]
    if bad:
        raise CalibrationError(f"week(s) {bad} not in {site.path} (it has weeks 0..{site.weeks - 1})")
    idx = np.asarray(weeks)
    weather = site.weather_hours()[idx]
    weather_before = site.weather_hours(shift_hours=-cat.HOURS_PER_WEEK)[idx]
    prev = np.maximum(idx - 1, 0)  # the first week's settings stand for the unrecorded week before it
    n = len(idx)
    lo_t, hi_t = cat.bounds("theta_build")
    theta = (lo_t + hi_t) / 2.0
    known = site.theta_known()
    occ = np.broadcast_to(np.array([v.min for v in cat.GROUPS["occupancy"]]), (n, len(cat.WEEKDAYS), 2))
    ground = sg.ground_hours(sg.weather_ground_c(site.weather), site.epw_hours()[idx, 0], context_hours)
    before = None
    if temperature_before:
        before = np.full((n, context_hours), np.nan, dtype=np.float32)
        after_first = idx >= 1
        before[after_first] = np.asarray(site.temperature_c)[idx[after_first] - 1, -context_hours:]
    x = sg.encode_weeks(np.broadcast_to(theta, (n, len(theta))), site.settings[idx], occ, weather,
                        (site.settings[prev], occ, weather_before), context_hours=context_hours, ground_c=ground,
                        temperature_before_c=before)
    free = free_theta()
    lo = np.array([known.get(v, cat.get(v).min) for v in free]
                  + [v.min for _ in cat.WEEKDAYS for v in cat.GROUPS["occupancy"]])
    hi = np.array([known.get(v, cat.get(v).max) for v in free]
                  + [v.max for _ in cat.WEEKDAYS for v in cat.GROUPS["occupancy"]])
    e_lo, e_hi = em.bounds(effects)
    return Problem(x, site.temperature_c[idx], site.consumption_wh_m2()[idx], known,
                   parameter_names() + em.parameter_names(effects), np.concatenate([lo, e_lo]),
                   np.concatenate([hi, e_hi]), tuple(effects), None if absent is None else np.asarray(absent)[idx])


def _split(problem: Problem, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physical ``(pop, 19)`` theta and ``(pop, 5, 2)`` occupancy from ``(pop, dim)`` physical parameters."""
    free = free_theta()
    theta = np.empty((len(params), len(cat.THETA_NAMES)))
    for j, name in enumerate(cat.THETA_NAMES):
        theta[:, j] = problem.theta_known[name] if name in KNOWN_GEOMETRY else params[:, free.index(name)]
    occ = params[:, len(free):problem.n_base].reshape(len(params), len(cat.WEEKDAYS), 2)
    return theta, occ


def encode_candidates(problem: Problem, params: np.ndarray) -> np.ndarray:
    """Encoded inputs ``(pop * weeks, context + 168, C)`` of every candidate on every calibration week."""
    theta, occ = _split(problem, params)
    pop, weeks = len(params), len(problem.x_base)
    x = np.repeat(problem.x_base[None], pop, axis=0)  # (pop, weeks, context + 168, C)
    t0 = sg.INPUT_CHANNELS.index(cat.THETA_NAMES[0])
    x[..., t0:t0 + len(cat.THETA_NAMES)] = theta[:, None, None, :]
    occ_fraction = hourly_schedules(np.zeros((pop, 7, len(cat.GROUPS["settings"]))), occ)["occupancy_fraction"]
    c = sg.INPUT_CHANNELS.index("occupancy_fraction")
    ctx = sg.context_of(problem.x_base)
    x[:, :, ctx:, c] = occ_fraction[:, None, :]
    x[:, :, :ctx, c] = occ_fraction[:, None, -ctx:]  # context: the last days of the week before (build_problem)
    x = x.reshape(pop * weeks, *x.shape[2:])
    if problem.effects:
        em.transform_inputs(x, _effect_values(problem, params, weeks))
    if problem.absent is not None:
        em.absent_days_inputs(x, np.tile(problem.absent, (pop, 1)))
    return x


def _effect_values(problem: Problem, params: np.ndarray, repeat: int = 1) -> dict[str, np.ndarray]:
    """``{effect: (pop * repeat, k)}`` of physical parameter vectors ``(pop, dim)``."""
    return em.split_parameters(problem.effects, np.repeat(params[:, problem.n_base:], repeat, axis=0))


def simulate(problem: Problem, surrogate: sg.Surrogate,
             params: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate candidates on every problem week in one batched metamodel call, effects included.

    Args:
        params: ``(pop, dim)`` physical parameter vectors.
    Returns:
        building outputs ``(pop, weeks, 168, 8)``, the temperature the sensor reads (degC) and the site
        consumption (Wh/m2), both ``(pop, weeks, 168)``.
    """
    pop, weeks = len(params), len(problem.x_base)
    x = encode_candidates(problem, params)
    out = surrogate.predict_encoded(x)
    values = _effect_values(problem, params, weeks)
    out = em.transform_outputs(out, x, values)
    t, q = model_series(problem, out)
    t = em.sensor_temperature(t, values)
    shape = (pop, weeks, cat.HOURS_PER_WEEK)
    return out.reshape(*shape, -1), t.reshape(shape), q.reshape(shape)


def model_series(problem: Problem, outputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Temperature (degC) and site consumption (Wh/m2) ``(..., 168)`` from metamodel outputs ``(..., 168, 8)``."""
    q = [cat.OUTPUT_NAMES.index(n) for n in SITE_CONSUMPTION_OUTPUTS]
    return outputs[..., cat.OUTPUT_NAMES.index("T_INT_OFFICE")], outputs[..., q].sum(-1)


def _r2(y: np.ndarray, p: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """R2 of each candidate's ``p (pop, weeks, 168)`` against ``y (weeks, 168)`` over ``mask`` hours."""
    yv = y[mask]
    ss_tot = ((yv - yv.mean()) ** 2).sum()
    ss_res = ((p[:, mask] - yv) ** 2).sum(-1)
    return 1.0 - ss_res / max(ss_tot, 1e-12)


def costs(problem: Problem, t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The paper's cost of each candidate from its temperature and consumption ``(pop, weeks, 168)``."""
    mt, mq = np.isfinite(problem.temperature_c), np.isfinite(problem.consumption_wh_m2)
    return (WEIGHTS["temperature"] * (1 - _r2(problem.temperature_c, t, mt))
            + WEIGHTS["consumption"] * (1 - _r2(problem.consumption_wh_m2, q, mq)))


def evaluate(problem: Problem, surrogate: sg.Surrogate, params: np.ndarray) -> np.ndarray:
    """Costs ``(pop,)`` of physical parameter vectors ``(pop, dim)`` in one batched metamodel call."""
    _, t, q = simulate(problem, surrogate, params)
    return costs(problem, t, q)


def predict(problem: Problem, surrogate: sg.Surrogate, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sensor temperature (degC) and consumption (Wh/m2) ``(weeks, 168)`` of one parameter vector."""
    _, t, q = simulate(problem, surrogate, params[None])
    return t[0], q[0]


def cmaes_strategy(dim: int, seed: int = 0, max_evaluations: float = np.inf, sigma0: float = SIGMA0,
                   x0: np.ndarray | None = None, stds: np.ndarray | None = None):
    """The CMA-ES (pycma) of every calibration: ``dim`` parameters in the unit box, started at its centre.

    Args:
        dim: number of parameters.
        seed: seed of the optimiser (pycma gets ``seed + 1``: pycma reads 0 as "seed from the clock").
        max_evaluations: budget of cost evaluations (``inf``: none, stop on ``tolfun`` only).
        sigma0: initial step size, in units of the box side.
        x0: start point in the unit box (default: its centre).
        stds: per-parameter multipliers of ``sigma0`` (default: all 1).
    """
    import cma

    options = {"bounds": [0.0, 1.0], "seed": seed + 1, "verbose": -9, "maxfevals": max_evaluations,
               "tolfun": CMAES_TOLFUN}
    if stds is not None:
        options["CMA_stds"] = list(np.asarray(stds, float))
    start = np.full(dim, 0.5) if x0 is None else np.clip(np.asarray(x0, float), 0.0, 1.0)
    return cma.CMAEvolutionStrategy(start, sigma0, options)


def calibrate_cmaes(problem: Problem, surrogate: sg.Surrogate, seed: int = 0, max_evaluations: int = 6000,
                    sigma0: float = SIGMA0, progress: bool = False, start: np.ndarray | None = None,
                    stds: np.ndarray | None = None, restarts: int = 1, anchor: float = 0.0,
                    anchored: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """CMA-ES on the unit box of the free parameters (:attr:`Problem.free`). Returns the best physical
    parameters ``(dim,)`` and ``{"evaluations", "cost", "run_costs", "run_parameters"}`` (each run's best
    physical parameters, ``(restarts, dim)``).

    ``start`` (physical parameters, ``(dim,)``) and ``stds`` (per-parameter step multipliers, ``(dim,)``)
    warm-start a refit. ``restarts`` independent runs (seeds ``seed``, ``seed + 1``, ...), each with
    ``max_evaluations``, and the one with the lowest cost is kept: the cost has more than one basin (a site
    whose internal loads are declared known converged to 0.314 from two seeds and to 0.260 from two others,
    the held-out R2 of temperature 0.38 against 0.81).

    ``anchor`` > 0 (with a ``start``) searches the cost plus ``anchor`` times the squared distance from
    ``start`` of the ``anchored`` parameters (boolean ``(dim,)``, default all), each measured in its range
    (the unit box): a refit then moves a parameter only as far as the fit pays for it. The returned
    ``cost`` is the plain cost of the best point; ``run_costs`` are the costs each run searched (pull
    included), by which the best run is chosen. Without a ``start`` there is nothing to pull towards and
    ``anchor`` is not used.
    """
    if restarts < 1:
        raise CalibrationError(f"restarts must be at least 1 (got {restarts})")
    if anchor < 0:
        raise CalibrationError(f"anchor must be at least 0 (got {anchor})")
    if int(problem.free.sum()) == 1:
        return _minimise_one(problem, surrogate, max_evaluations)
    x0 = None if start is None else problem.to_unit(start)
    weights = None
    if anchor > 0 and x0 is not None:
        mask = np.ones(len(problem.lo), bool) if anchored is None else np.asarray(anchored, bool)
        weights = anchor * mask[problem.free].astype(float)
    bar = _bar(progress, max_evaluations * restarts, "CMA-ES")
    best, best_cost, evaluations, run_costs, run_parameters = None, np.inf, 0, [], []
    for run in range(restarts):
        es = cmaes_strategy(int(problem.free.sum()), seed + run, max_evaluations, sigma0, x0,
                            None if stds is None else np.asarray(stds, float)[problem.free])
        while not es.stop():
            z = np.asarray(es.ask())
            f = evaluate(problem, surrogate, problem.from_unit(z))
            if weights is not None:
                f = f + ((z - x0) ** 2 * weights).sum(-1)
            es.tell(list(z), f.tolist())
            bar.update(len(z))
            bar.set_postfix(cost=f"{min(best_cost, es.result.fbest):.4f}")
        evaluations += int(es.result.evaluations)
        run_costs.append(float(es.result.fbest))
        run_parameters.append(problem.from_unit(np.asarray(es.result.xbest))[0])
        if es.result.fbest < best_cost:
            best_cost, best = float(es.result.fbest), run_parameters[-1]
    bar.close()
    if weights is not None:  # the plain cost of the point the anchored search chose
        best_cost = float(evaluate(problem, surrogate, best[None])[0])
    return best, {"evaluations": evaluations, "cost": best_cost, "run_costs": run_costs,
                  "run_parameters": np.array(run_parameters)}


def _minimise_one(problem: Problem, surrogate: sg.Surrogate, max_evaluations: int) -> tuple[np.ndarray, dict]:
    """One free parameter: Brent's bounded minimisation over its whole range (pycma does not run in one
    dimension: its step-size bookkeeping raises "not yet initialized" within a few generations)."""
    from scipy.optimize import minimize_scalar

    j = int(np.flatnonzero(problem.free)[0])
    base = problem.lo.copy()

    def cost(u: float) -> float:
        x = base.copy()
        x[j] = problem.lo[j] + u * (problem.hi[j] - problem.lo[j])
        return float(evaluate(problem, surrogate, x[None])[0])

    res = minimize_scalar(cost, bounds=(0.0, 1.0), method="bounded",
                          options={"maxiter": max(int(min(max_evaluations, 10_000)), 1), "xatol": 1e-4})
    best = base.copy()
    best[j] = problem.lo[j] + float(res.x) * (problem.hi[j] - problem.lo[j])
    return best, {"evaluations": int(res.nfev), "cost": float(res.fun), "run_costs": [float(res.fun)],
                  "run_parameters": best[None]}


def _bar(enabled: bool, total: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False)


def guideline14(measured: np.ndarray, predicted: np.ndarray, p: int = GUIDELINE14_P) -> tuple[float, float]:
    """ASHRAE Guideline 14 CV(RMSE) and NMBE in percent over the finite measured hours."""
    ok = np.isfinite(measured)
    y, yhat = measured[ok], predicted[ok]
    dof = max(len(y) - p, 1)
    mean = y.mean()
    return (float(100.0 * np.sqrt(((y - yhat) ** 2).sum() / dof) / mean),
            float(100.0 * (y - yhat).sum() / (dof * mean)))


def site_metrics(temperature: np.ndarray, consumption: np.ndarray, pred_t: np.ndarray, pred_q: np.ndarray,
                 occupied: np.ndarray, scale: dict[str, tuple[float, float]]) -> dict[str, float]:
    """Metrics of predictions against measurements (see the module docstring); arrays ``(weeks, 168)``."""
    out: dict[str, float] = {}
    for key, y, p in (("t", temperature, pred_t), ("q", consumption, pred_q)):
        ok = np.isfinite(y)
        mean, std = scale[key]
        z = ((p - y) / std) ** 2
        out[f"r2_{key}"] = float(_r2(y, p[None], ok)[0])
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


def default_weeks(n_weeks: int) -> tuple[list[int], list[int]]:
    """Calibration and held-out weeks when none are given: the first half (rounded up) fits, the rest checks."""
    n_fit = max(1, (n_weeks + 1) // 2)
    return list(range(n_fit)), list(range(n_fit, n_weeks))


@one_blas_thread()  # buildenv.threads: numpy's BLAS threads would fight the metamodel's
def calibrate_site(site, surrogate: sg.Surrogate, weeks: list[int] | None = None, method: str = "cmaes",
                   seed: int = 0, max_evaluations: int = 6000, progress: bool = False, save: bool = True,
                   restarts: int = 1, effects: tuple[str, ...] | None = None) -> dict:
    """Calibrate the metamodel to a site and score it on calibration and held-out weeks.

    Args:
        site: a :class:`buildenv.site.Site`.
        surrogate: the metamodel.
        weeks: calibration weeks (0-based); the site's other weeks are held out. Default :func:`default_weeks`.
        method: ``cmaes`` or ``adam``.
        seed: seed of the optimiser.
        max_evaluations: budget of cost evaluations (one evaluation = one candidate on every calibration week)
            of each CMA-ES run.
        restarts: independent CMA-ES runs, the best kept (:func:`calibrate_cmaes`).
        progress: progress bar.
        save: write ``calibration.json`` into the site folder.
        effects: declared effects (module docstring), fitted after the building and occupancy; None (default)
            takes the site's own (``site.toml``'s ``effects``, :attr:`buildenv.site.Site.effects`), ``()`` none.
    Returns:
        ``{"fit": metrics, "heldout": metrics, "parameters": {...}, "occupancy": [[start, end] x 5], "method",
        "seconds", "evaluations", "cost", "fit_weeks", "heldout_weeks", "guideline14_p"}``, and with
        ``effects``: ``"declared_effects": [names]``, ``"effects": {effect: {parameter: value}}`` and
        ``"cost_without_effects"``. ``"at_bounds"`` lists the estimated parameters at a bound of their range
        (:func:`parameters_at_bounds`). With CMA-ES ``restarts`` > 1 and held-out weeks, ``"runs"`` has each
        run's ``seed``, ``cost`` (of the building and occupancy fit, before the declared effects are fitted) and
        the held-out ``heldout_rmse_t_celsius`` (degC) and ``heldout_r2_t`` of its parameters without the
        declared effects (:func:`runs_note`).
    """
    effects = check_declared_effects(site.effects if effects is None else effects)
    started = time.perf_counter()
    fit_weeks, heldout = default_weeks(site.weeks) if weeks is None else (
        sorted(weeks), [w for w in range(site.weeks) if w not in weeks])
    problem = build_problem(site, fit_weeks, context_hours=surrogate.context_hours,
                            temperature_before=surrogate.uses_temperature_before)
    if method == "cmaes":
        best, info = calibrate_cmaes(problem, surrogate, seed, max_evaluations, progress=progress, restarts=restarts)
        run_parameters = info.pop("run_parameters")
    elif method == "adam":
        from buildenv.calibration_gradient import calibrate_adam

        best, info = calibrate_adam(problem, surrogate, seed, progress=progress)
    else:
        raise CalibrationError(f"unknown calibration method {method!r}; choose cmaes or adam")
    declared: dict = {}
    if effects:
        declared["cost_without_effects"] = info["cost"]
        problem = build_problem(site, fit_weeks, effects, context_hours=surrogate.context_hours,
                                temperature_before=surrogate.uses_temperature_before)
        best, stage = fit_declared_effects(problem, surrogate, best, seed)
        info = {**info, "evaluations": info["evaluations"] + stage["evaluations"], "cost": stage["cost"]}
        values = em.split_parameters(effects, best[None, problem.n_base:])
        declared.update(declared_effects=list(effects),
                        effects={e: {p.name: round(float(v), 5) for p, v in zip(get_effect(e).parameters,
                                                                                  values[e][0])}
                                 for e in effects})
    seconds = time.perf_counter() - started
    theta, occ = _split(problem, best[None])
    result = {"method": method, "seconds": round(seconds, 2), **info, "fit_weeks": fit_weeks,
              "heldout_weeks": heldout, "guideline14_p": GUIDELINE14_P,
              "theta": dict(zip(cat.THETA_NAMES, np.round(theta[0], 5).tolist())),
              "known": sorted(site.known),
              "occupancy": np.round(occ[0], 3).tolist(),
              "at_bounds": parameters_at_bounds(dict(zip(cat.THETA_NAMES, theta[0].tolist())), site.known),
              "metamodel": _metamodel_name(surrogate),
              "catalogue_hash": cat.catalogue_hash(), **declared}
    scale = _scale(problem)
    for key, ws in (("fit", fit_weeks), ("heldout", heldout)):
        if ws:
            result[key] = score_weeks(site, surrogate, ws, best, scale, effects)
            result[key]["seconds"], result[key]["evaluations"] = result["seconds"], result["evaluations"]
    if method == "cmaes" and restarts > 1 and heldout:
        result["runs"] = _score_runs(site, surrogate, heldout, info["run_costs"], run_parameters, scale, seed)
    if save:
        from buildenv.site import save_calibration

        save_calibration(site.path, result)
    return result


def _score_runs(site, surrogate: sg.Surrogate, heldout: list[int], run_costs: list[float],
                run_parameters: np.ndarray, scale: dict[str, tuple[float, float]], seed: int) -> list[dict]:
    """``calibrate_site``'s ``runs``: each CMA-ES run's seed, cost and held-out RMSE_T (degC) and R2_T of its
    parameters without the declared effects, the held-out weeks encoded once."""
    problem = build_problem(site, heldout, context_hours=surrogate.context_hours,
                            temperature_before=surrogate.uses_temperature_before)
    runs = []
    for k, (cost, params) in enumerate(zip(run_costs, run_parameters)):
        metrics = score_series(problem, *predict(problem, surrogate, params), params, scale)
        runs.append({"seed": seed + k, "cost": round(cost, 5),
                     **{f"heldout_{m}": round(metrics[m], 4) for m in ("rmse_t_celsius", "r2_t")}})
    return runs


def parameters_at_bounds(theta: dict[str, float], known=()) -> list[dict]:
    """The estimated building parameters that calibrated at a bound of their catalogue range.

    Args:
        theta: calibrated theta_build ``{name: value}`` in catalogue units (``calibration.json``'s ``theta``).
        known: names the site fixed (its ``[known]`` table); they and the known geometry are not estimates.
    Returns:
        ``[{"name", "value", "bound": "min" | "max", "limit"}]`` in catalogue order, for each estimated
        parameter within :data:`AT_BOUND_SHARE` of its range from that end.
    """
    out = []
    for name, value in theta.items():
        if name in KNOWN_GEOMETRY or name in known:
            continue
        var = cat.get(name)
        tol = AT_BOUND_SHARE * (var.max - var.min)
        for bound, limit in (("min", var.min), ("max", var.max)):
            if abs(float(value) - limit) <= tol:
                out.append({"name": name, "value": round(float(value), 5), "bound": bound, "limit": limit})
    return out


def at_bounds_note(result: dict) -> str | None:
    """One line for the user about a calibration's parameters at a bound (``result["at_bounds"]``), or None."""
    found = result.get("at_bounds") or []
    if not found:
        return None
    estimated = len([n for n in free_theta() if n not in result.get("known", [])])
    listed = ", ".join(f"{e['name']} at its {e['bound']} {e['limit']:g}" for e in found)
    return (f"note: {len(found)} of {estimated} estimated building parameters calibrated at a bound of the "
            f"catalogue's range ({listed}); the metamodel cannot go past them, so each is a value the fit wanted "
            "further, one standing in for something the model lacks, or one the fit does not depend on")


def runs_note(result: dict) -> str | None:
    """One line for the user when CMA-ES runs of one calibration (``result["runs"]``, ``--restarts``) fit the
    calibration weeks about as well as the best run (cost within :data:`RUNS_COST_TOLERANCE` of it) but
    predict the held-out weeks' temperature differently (RMSE_T of the worst over the best at least
    :data:`RUNS_DISAGREEMENT`), or None: the calibration weeks then do not determine the model. Measured on a site
    whose fit weeks were milder than its held-out ones (docs/calibration.md): three runs at costs 0.319-0.329,
    heating power 10 or 100 W/m2, held-out RMSE_T 1.32 and 1.21 against 0.61 K."""
    runs = result.get("runs") or []
    if len(runs) < 2:
        return None
    best = min(r["cost"] for r in runs)
    close = [r for r in runs if r["cost"] <= best * (1.0 + RUNS_COST_TOLERANCE)]
    rmse = [r["heldout_rmse_t_celsius"] for r in close]
    if len(close) < 2 or max(rmse) < RUNS_DISAGREEMENT * min(rmse):
        return None
    return (f"note: {len(close)} of {len(runs)} CMA-ES runs fit the calibration weeks as well as the best (cost "
            f"within {RUNS_COST_TOLERANCE:.0%}) but predict the held-out weeks' temperature differently (RMSE_T "
            f"{min(rmse):.2f} to {max(rmse):.2f} K): the calibration weeks do not determine the model; fit weeks "
            "that span the held-out weeks' weather (--weeks, e.g. every other week) or declare what is known "
            "([known] in site.toml)")


def check_declared_effects(effects) -> tuple[str, ...]:
    """The declared effects as a tuple of catalogue names (:func:`buildenv.effects.check_declarable`); raises
    :class:`CalibrationError` for a name that is not in the catalogue, given twice, or ``holidays``."""
    try:
        return check_declarable(effects)
    except EffectError as exc:
        raise CalibrationError(f"--effect: {exc}") from None


#: Cost evaluations of the declared effects' stage (:func:`fit_declared_effects`, CMA-ES whichever method
#: calibrated the building). On the default site it stopped on its tolerance well within them: after 288
#: evaluations with ``night_cycle_cold_air`` (at cost 0.2151, where Nelder-Mead from three starts also ended)
#: and 526 with ``evening_departure`` too.
DECLARED_EFFECTS_EVALUATIONS = 1500


def fit_declared_effects(problem: Problem, surrogate: sg.Surrogate, base: np.ndarray, seed: int = 0,
                         max_evaluations: int = DECLARED_EFFECTS_EVALUATIONS) -> tuple[np.ndarray, dict]:
    """Second calibration stage: the parameters of ``problem.effects`` with theta_build and occupancy kept at
    ``base`` (their calibrated values, ``(problem.n_base,)``), by CMA-ES started at the effects' "no effect"
    values. Returns the full parameter vector ``(problem.dim,)`` and ``{"evaluations", "cost"}``."""
    n = problem.n_base
    start = np.concatenate([np.asarray(base, float)[:n]] + [em.none_parameters(e) for e in problem.effects])
    return fit_last_parameters(problem, surrogate, start, n, seed, max_evaluations)


def fit_last_parameters(problem: Problem, surrogate: sg.Surrogate, start: np.ndarray, fixed: int, seed: int = 0,
                        max_evaluations: int = DECLARED_EFFECTS_EVALUATIONS) -> tuple[np.ndarray, dict]:
    """Calibrate the parameters after the first ``fixed`` ones, those kept at ``start`` (physical, ``(dim,)``,
    also the search's start). Returns the full parameter vector and ``{"evaluations", "cost"}``."""
    lo, hi = problem.lo.copy(), problem.hi.copy()
    lo[:fixed] = hi[:fixed] = np.asarray(start, float)[:fixed]
    best, info = calibrate_cmaes(dataclasses.replace(problem, lo=lo, hi=hi), surrogate, seed, max_evaluations,
                                 start=start)
    return best, {"evaluations": info["evaluations"], "cost": info["cost"]}


def _scale(problem: Problem) -> dict[str, tuple[float, float]]:
    t, q = problem.temperature_c, problem.consumption_wh_m2
    return {"t": (float(np.nanmean(t)), float(np.nanstd(t)) or 1.0),
            "q": (float(np.nanmean(q)), float(np.nanstd(q)) or 1.0)}


def score_weeks(site, surrogate: sg.Surrogate, weeks: list[int], params: np.ndarray,
                scale: dict[str, tuple[float, float]], effects: tuple[str, ...] = (),
                absent: np.ndarray | None = None) -> dict[str, float]:
    """Metrics of the parameters ``params`` (physical, problem order) on some of the site's weeks (with the
    model-side ``effects`` whose parameters follow in ``params``, and the ``absent`` days of the site)."""
    problem = build_problem(site, weeks, effects, absent, surrogate.context_hours, surrogate.uses_temperature_before)
    return score_series(problem, *predict(problem, surrogate, params), params, scale)


def score_outputs(problem: Problem, outputs: np.ndarray, params: np.ndarray,
                  scale: dict[str, tuple[float, float]]) -> dict[str, float]:
    """Metrics (:func:`site_metrics`) of simulated outputs ``(weeks, 168, 8)`` of ``params`` on the problem's weeks."""
    return score_series(problem, *model_series(problem, outputs), params, scale)


def score_series(problem: Problem, t: np.ndarray, q: np.ndarray, params: np.ndarray,
                 scale: dict[str, tuple[float, float]]) -> dict[str, float]:
    """Metrics (:func:`site_metrics`) of a predicted temperature (degC) and consumption (Wh/m2) ``(weeks, 168)``."""
    occupied = problem_occupancy(problem, params)
    return {**site_metrics(problem.temperature_c, problem.consumption_wh_m2, t, q, occupied, scale),
            "weeks": len(problem.x_base)}


def problem_occupancy(problem: Problem, params: np.ndarray) -> np.ndarray:
    """``(weeks, 168)`` booleans: hours the parameters' occupancy marks as occupied."""
    _, occ = _split(problem, params[None])
    frac = hourly_schedules(np.zeros((1, 7, len(cat.GROUPS["settings"]))), occ)["occupancy_fraction"][0]
    return np.broadcast_to(frac > 0, problem.temperature_c.shape)


def calibrated_parameters(calibration: dict, effects: tuple[str, ...] = ()) -> np.ndarray:
    """The parameter vector (problem order: free theta_build, occupancy hours, then the parameters of
    ``effects``) of a saved calibration (``calibration.json``'s ``theta`` in catalogue units, ``occupancy`` in h
    and ``effects`` in the effects' units). A parameter an effect gained after the calibration was saved takes
    its "no effect" value."""
    return np.array([calibration["theta"][n] for n in free_theta()]
                    + list(np.asarray(calibration["occupancy"], float).ravel())
                    + [calibration["effects"][e].get(p.name, p.none) for e in effects
                       for p in get_effect(e).parameters])


def load_calibration(site_path: str | Path) -> dict:
    """The ``calibration.json`` of a site folder."""
    path = Path(site_path) / "calibration.json"
    if not path.is_file():
        raise CalibrationError(f"{site_path} is not calibrated yet: run `buildenv calibrate --site {site_path}`")
    return json.loads(path.read_text())


def _metamodel_name(surrogate: sg.Surrogate) -> str | None:
    """How a calibration records its metamodel: ``"default"`` for the shipped one, else its path."""
    if surrogate.path is None:
        return None
    return "default" if Path(surrogate.path).resolve() == sg.DEFAULT_CHECKPOINT else str(surrogate.path)
