"""The calibration problem: theta_build and occupancy of the metamodel fitted to a site's two measured series.

**Estimated.** Every theta_build variable except the known geometry (:data:`KNOWN_GEOMETRY`) and the
parameters of the site's ``[known]`` table (kept in the vector with both bounds at the known value), and one
weekly occupancy schedule (start and end hour of each weekday) shared by all weeks. Bounds come from the
catalogue; the optimisers search ``[0, 1]`` per free parameter, mapped linearly onto ``[min, max]``.

**Cost** (the paper's): ``w_T (1 - R2_T) + w_Q (1 - R2_Q)`` (:data:`WEIGHTS`), R2 pooled over the
calibration weeks' measured hours; missing hours are left out. With :attr:`Problem.daily_weight` ``w_D`` > 0 it
adds ``w_D (1 - R2_D)``, the R2 of the meter's daily totals over the fully measured days: an hourly R2 lets a fit
trade the level of a day's energy (a bias, what a day off uses against a working day) for the shape of its hours,
and ASHRAE Guideline 14's NMBE and the savings of a change of settings are sums over days. The site's consumption
(kWh per hour) per floor area is compared with the sum of the metamodel outputs of the end uses its meter sums
(:meth:`buildenv.sites.Site.consumption_outputs`, Wh/m2 per hour; :attr:`Problem.consumption_idx`). A site with a
second meter (``electricity_kwh``) has ``1 - R2_Q`` replaced by the mean of both meters' (its outputs:
:attr:`Problem.electricity_idx`); its metrics carry ``_e`` keys beside the ``_q`` ones.

**Optimisers.** :func:`calibrate_cmaes` (CMA-ES, each generation one batched metamodel call);
:func:`buildenv.calibration.gradient.calibrate_adam` (Adam, occupancy switched over a sigmoid ramp of
:data:`RAMP_HOURS`). Declared effects (:mod:`buildenv.diagnosis.effects`) are fitted in a second stage with
the building and occupancy kept (:func:`fit_declared_effects`): fitting all together overfits the fit weeks.

**Reports.** :func:`parameters_at_bounds` (estimates within :data:`AT_BOUND_SHARE` of a catalogue bound),
:func:`at_bounds_note` and :func:`runs_note` (lines for the user). :func:`score_weeks`, :func:`score_outputs`
and :func:`score_series` compute :func:`buildenv.metrics.site_metrics` (R2, RMSE and the ASHRAE Guideline 14
CV(RMSE) and NMBE, all in :mod:`buildenv.metrics`). A site's whole calibration, fit then held-out scores, is
:func:`buildenv.calibration.calibrate.calibrate_site`.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import EffectError, check_declarable, get_effect
from buildenv.errors import BuildenvError
from buildenv.metamodel import surrogate as sg
from buildenv.metrics import guideline14_monthly, r2_masked, site_metrics
from buildenv.schedules import hourly_schedules

WEIGHTS = {"temperature": 1.0, "consumption": 1.0}
#: w_D of a site calibration (:func:`buildenv.calibration.calibrate.calibrate_site`): the hourly terms' weight
DAILY_WEIGHT = 1.0
RAMP_HOURS = 0.5
KNOWN_GEOMETRY = cat.GEOMETRY_NAMES
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
    effects: tuple[str, ...] = ()  # model-side effects (buildenv.diagnosis.model_effects) whose parameters follow
    absent: np.ndarray | None = None  # (weeks, 7) absence shares of the days (the holidays effect; 0 = normal)
    # indices into catalogue.OUTPUT_NAMES of the outputs the site's consumption meter sums (Site.consumption_outputs)
    consumption_idx: tuple[int, ...] = tuple(cat.OUTPUT_NAMES.index(n) for n in cat.consumption_outputs())
    electricity_wh_m2: np.ndarray | None = None  # (weeks, 168) the site's second meter, measured; None: none
    electricity_idx: tuple[int, ...] = ()  # indices into catalogue.OUTPUT_NAMES of the outputs it sums
    daily_weight: float = 0.0  # w_D of the meters' daily totals in the cost (0: the paper's cost)

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


def build_problem(
    site,
    weeks: list[int],
    effects: tuple[str, ...] = (),
    absent: np.ndarray | None = None,
    context_hours: int = sg.CONTEXT_HOURS,
    temperature_before: bool = False,
    metamodel: sg.Surrogate | None = None,
    daily_weight: float = 0.0,
) -> Problem:
    """Encode a site's weeks, each with the days before it as context.

    The context of a week is the last days of the week before: its settings, the calibrated occupancy and the
    weather file's hours before the week. Before the first measured week the building ran too, under
    settings the site does not record; they are taken to be the first week's own (its last days), as
    :class:`buildenv.sites.week_simulator.SiteModel` does for every week and as the reference-building
    stand-in's warm-up week runs them (so the context ends in a weekend, not a repeated Monday).

    Args:
        site: a :class:`buildenv.sites.Site`.
        weeks: the site's weeks (0-based).
        effects: model-side effects (:mod:`buildenv.diagnosis.model_effects`) whose parameters are calibrated too.
        absent: ``(site weeks, 7)`` absence shares of the days (rows of ``weeks`` are used).
        context_hours: the metamodel's (:attr:`buildenv.metamodel.surrogate.Surrogate.context_hours`).
        temperature_before: encode the temperature measured over each week's context hours (unknown before
            the site's first week), for a metamodel that reads it (``Surrogate.uses_temperature_before``);
            a modelled sensor bias is taken off it (:func:`buildenv.diagnosis.model_effects.transform_inputs`).
        metamodel: the metamodel the problem is for: its bounds stay inside the ranges it was trained on
            (:attr:`~buildenv.metamodel.surrogate.Surrogate.domain`) and the variables it does not read are held
            at the value it learnt (:attr:`~buildenv.metamodel.surrogate.Surrogate.implied`); ``None``: the
            catalogue's ranges.
        daily_weight: weight of the meters' daily totals in the cost (:attr:`Problem.daily_weight`; 0: the
            paper's cost).
    """
    if not weeks:
        raise CalibrationError("no weeks to calibrate on")
    twice = sorted(w for w, n in Counter(weeks).items() if n > 1)
    if twice:
        raise CalibrationError(f"week(s) {twice} given twice; give each week once")
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
    x = sg.encode_weeks(
        np.broadcast_to(theta, (n, len(theta))),
        site.settings[idx],
        occ,
        weather,
        (site.settings[prev], occ, weather_before),
        context_hours=context_hours,
        ground_c=ground,
        temperature_before_c=before,
    )
    ranges = parameter_ranges(known, metamodel)
    free = free_theta()
    occupancy = [(v.min, v.max) for _ in cat.WEEKDAYS for v in cat.GROUPS["occupancy"]]
    lo = np.array([ranges[v][0] for v in free] + [r[0] for r in occupancy])
    hi = np.array([ranges[v][1] for v in free] + [r[1] for r in occupancy])
    e_lo, e_hi = em.bounds(effects)
    second = site.meters()[1:]
    return Problem(
        x,
        site.temperature_c[idx],
        site.consumption_wh_m2()[idx],
        known,
        parameter_names() + em.parameter_names(effects),
        np.concatenate([lo, e_lo]),
        np.concatenate([hi, e_hi]),
        tuple(effects),
        None if absent is None else np.asarray(absent)[idx],
        consumption_idx=tuple(cat.OUTPUT_NAMES.index(n) for n in site.consumption_outputs()),
        electricity_wh_m2=second[0][1][idx] if second else None,
        electricity_idx=tuple(cat.OUTPUT_NAMES.index(n) for n in second[0][2]) if second else (),
        daily_weight=float(daily_weight),
    )


def parameter_ranges(known: dict[str, float], metamodel: sg.Surrogate | None = None) -> dict[str, tuple[float, float]]:
    """``{name: (min, max)}`` of the theta_build variables calibration estimates (:func:`free_theta`): the
    catalogue's range within what ``metamodel`` was trained on, a single value for a ``known`` one or one the
    metamodel does not read."""
    domain = {} if metamodel is None else metamodel.domain
    fixed = {} if metamodel is None else metamodel.implied
    out = {}
    for name in free_theta():
        var = cat.get(name)
        lo, hi = domain.get(name, (var.min, var.max))
        value = known.get(name, fixed.get(name))
        out[name] = (value, value) if value is not None else (max(var.min, lo), min(var.max, hi))
    return out


def _split(problem: Problem, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physical ``(pop, 21)`` theta and ``(pop, 5, 2)`` occupancy from ``(pop, dim)`` physical parameters."""
    free = free_theta()
    theta = np.empty((len(params), len(cat.THETA_NAMES)))
    for j, name in enumerate(cat.THETA_NAMES):
        theta[:, j] = problem.theta_known[name] if name in KNOWN_GEOMETRY else params[:, free.index(name)]
    occ = params[:, len(free) : problem.n_base].reshape(len(params), len(cat.WEEKDAYS), 2)
    return theta, occ


def encode_candidates(problem: Problem, params: np.ndarray) -> np.ndarray:
    """Encoded inputs ``(pop * weeks, context + 168, C)`` of every candidate on every calibration week."""
    theta, occ = _split(problem, params)
    pop, weeks = len(params), len(problem.x_base)
    x = np.repeat(problem.x_base[None], pop, axis=0)  # (pop, weeks, context + 168, C)
    t0 = sg.INPUT_CHANNELS.index(cat.THETA_NAMES[0])
    x[..., t0 : t0 + len(cat.THETA_NAMES)] = theta[:, None, None, :]
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
    return em.split_parameters(problem.effects, np.repeat(params[:, problem.n_base :], repeat, axis=0))


def simulate(
    problem: Problem, surrogate: sg.Surrogate, params: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    """Temperature (degC) and site consumption (Wh/m2: the outputs of :attr:`Problem.consumption_idx` summed)
    ``(..., 168)`` from metamodel outputs ``(..., 168, 8)``."""
    q = list(problem.consumption_idx)
    return outputs[..., cat.OUTPUT_NAMES.index("T_INT_OFFICE")], outputs[..., q].sum(-1)


def electricity_series(problem: Problem, outputs: np.ndarray) -> np.ndarray | None:
    """The second meter's model series (Wh/m2: the outputs of :attr:`Problem.electricity_idx` summed) ``(..., 168)``
    from metamodel outputs ``(..., 168, 8)``; None for a site with one meter."""
    if problem.electricity_wh_m2 is None:
        return None
    return outputs[..., list(problem.electricity_idx)].sum(-1)


def daily_r2(measured: np.ndarray, modelled: np.ndarray) -> np.ndarray:
    """R2 of each candidate's daily totals ``modelled (pop, weeks, 168)`` against ``measured (weeks, 168)`` over the
    days measured in every hour (1 where fewer than two such days)."""
    weeks = measured.shape[0]
    whole = np.isfinite(measured).reshape(weeks, 7, 24).all(-1)
    if whole.sum() < 2:
        return np.ones(len(modelled))
    days = np.nan_to_num(measured).reshape(weeks, 7, 24).sum(-1)
    return r2_masked(days, np.asarray(modelled).reshape(len(modelled), weeks, 7, 24).sum(-1), whole)


def costs(problem: Problem, t: np.ndarray, q: np.ndarray, e: np.ndarray | None = None) -> np.ndarray:
    """The cost of each candidate from its temperature and consumption ``(pop, weeks, 168)`` (and, for a site with
    a second meter, that meter's series ``e`` of the same shape): the paper's, plus the daily totals' term when
    ``problem.daily_weight`` > 0 (each meter's, averaged as the hourly ones are)."""
    mt, mq = np.isfinite(problem.temperature_c), np.isfinite(problem.consumption_wh_m2)
    meters = [(problem.consumption_wh_m2, q, mq)]
    if problem.electricity_wh_m2 is not None:
        if e is None:
            raise CalibrationError("the site has a second meter (electricity_kwh): give its model series too")
        meters.append((problem.electricity_wh_m2, e, np.isfinite(problem.electricity_wh_m2)))
    hourly = np.mean([1 - r2_masked(y, p, m) for y, p, m in meters], axis=0)
    cost = WEIGHTS["temperature"] * (1 - r2_masked(problem.temperature_c, t, mt)) + WEIGHTS["consumption"] * hourly
    if problem.daily_weight > 0:
        cost = cost + problem.daily_weight * np.mean([1 - daily_r2(y, p) for y, p, _ in meters], axis=0)
    return cost


def evaluate(problem: Problem, surrogate: sg.Surrogate, params: np.ndarray) -> np.ndarray:
    """Costs ``(pop,)`` of physical parameter vectors ``(pop, dim)`` in one batched metamodel call."""
    out, t, q = simulate(problem, surrogate, params)
    return costs(problem, t, q, electricity_series(problem, out))


def predict(problem: Problem, surrogate: sg.Surrogate, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sensor temperature (degC) and consumption (Wh/m2) ``(weeks, 168)`` of one parameter vector."""
    return predict_meters(problem, surrogate, params)[:2]


def predict_meters(
    problem: Problem, surrogate: sg.Surrogate, params: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`predict` and the second meter's series (Wh/m2, ``(weeks, 168)``; None for a site with one meter)."""
    out, t, q = simulate(problem, surrogate, params[None])
    e = electricity_series(problem, out)
    return t[0], q[0], None if e is None else e[0]


def cmaes_strategy(
    dim: int,
    seed: int = 0,
    max_evaluations: float = np.inf,
    sigma0: float = SIGMA0,
    x0: np.ndarray | None = None,
    stds: np.ndarray | None = None,
):
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

    options = {
        "bounds": [0.0, 1.0],
        "seed": seed + 1,
        "verbose": -9,
        "maxfevals": max_evaluations,
        "tolfun": CMAES_TOLFUN,
    }
    if stds is not None:
        options["CMA_stds"] = list(np.asarray(stds, float))
    start = np.full(dim, 0.5) if x0 is None else np.clip(np.asarray(x0, float), 0.0, 1.0)
    return cma.CMAEvolutionStrategy(start, sigma0, options)


def calibrate_cmaes(
    problem: Problem,
    surrogate: sg.Surrogate,
    seed: int = 0,
    max_evaluations: int = 6000,
    sigma0: float = SIGMA0,
    progress: bool = False,
    start: np.ndarray | None = None,
    stds: np.ndarray | None = None,
    restarts: int = 1,
    anchor: float = 0.0,
    anchored: np.ndarray | None = None,
    towards: np.ndarray | None = None,
) -> tuple[np.ndarray, dict]:
    """CMA-ES on the unit box of the free parameters (:attr:`Problem.free`). Returns the best physical
    parameters ``(dim,)`` and ``{"evaluations", "cost", "run_costs", "run_parameters"}`` (each run's best
    physical parameters, ``(restarts, dim)``).

    ``start`` (physical parameters, ``(dim,)``) and ``stds`` (per-parameter step multipliers, ``(dim,)``)
    warm-start a refit. ``restarts`` independent runs (seeds ``seed``, ``seed + 1``, ...), each with
    ``max_evaluations``, and the one with the lowest cost is kept: the cost can have more than one basin.

    ``anchor`` > 0 (with a ``start``) searches the cost plus ``anchor`` times the squared distance from
    ``start`` of the ``anchored`` parameters (boolean ``(dim,)``, default all), each measured in its range
    (the unit box): a refit then moves a parameter only as far as the fit pays for it. The returned
    ``cost`` is the plain cost of the best point; ``run_costs`` are the costs each run searched (pull
    included), by which the best run is chosen. Without a ``start`` there is nothing to pull towards and
    ``anchor`` is not used. ``towards`` (physical parameters, ``(dim,)``; with a ``start`` and ``anchor``) pulls
    towards another point than the start (a prior's centre).
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
    pull = x0 if towards is None else problem.to_unit(towards)
    bar = _bar(progress, max_evaluations * restarts, "CMA-ES")
    best, best_cost, evaluations, run_costs, run_parameters = None, np.inf, 0, [], []
    for run in range(restarts):
        es = cmaes_strategy(
            int(problem.free.sum()),
            seed + run,
            max_evaluations,
            sigma0,
            x0,
            None if stds is None else np.asarray(stds, float)[problem.free],
        )
        while not es.stop():
            z = np.asarray(es.ask())
            f = evaluate(problem, surrogate, problem.from_unit(z))
            if weights is not None:
                f = f + ((z - pull) ** 2 * weights).sum(-1)
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
    return best, {
        "evaluations": evaluations,
        "cost": best_cost,
        "run_costs": run_costs,
        "run_parameters": np.array(run_parameters),
    }


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

    res = minimize_scalar(
        cost,
        bounds=(0.0, 1.0),
        method="bounded",
        options={"maxiter": max(int(min(max_evaluations, 10_000)), 1), "xatol": 1e-4},
    )
    best = base.copy()
    best[j] = problem.lo[j] + float(res.x) * (problem.hi[j] - problem.lo[j])
    return best, {
        "evaluations": int(res.nfev),
        "cost": float(res.fun),
        "run_costs": [float(res.fun)],
        "run_parameters": best[None],
    }


def _bar(enabled: bool, total: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False)


def default_weeks(n_weeks: int) -> tuple[list[int], list[int]]:
    """Calibration and held-out weeks when none are given: the first half (rounded up) fits, the rest checks."""
    n_fit = max(1, (n_weeks + 1) // 2)
    return list(range(n_fit)), list(range(n_fit, n_weeks))


def parameters_at_bounds(theta: dict[str, float], known=(), metamodel: sg.Surrogate | None = None) -> list[dict]:
    """The estimated building parameters that calibrated at a bound of their range.

    Args:
        theta: calibrated theta_build ``{name: value}`` in catalogue units (``calibration.json``'s ``theta``).
        known: names the site fixed (its ``[known]`` table); they and the known geometry are not estimates.
        metamodel: the metamodel calibrated with: the ranges are those of :func:`parameter_ranges` (the
            catalogue's where ``None``); the variables it does not read are not estimates.
    Returns:
        ``[{"name", "value", "bound": "min" | "max", "limit"}]`` in catalogue order, for each estimated
        parameter within :data:`AT_BOUND_SHARE` of its range from that end.
    """
    ranges = parameter_ranges({}, metamodel)
    out = []
    for name, value in theta.items():
        if name in KNOWN_GEOMETRY or name in known or name not in ranges or ranges[name][0] == ranges[name][1]:
            continue
        lo, hi = ranges[name]
        tol = AT_BOUND_SHARE * (hi - lo)
        for bound, limit in (("min", lo), ("max", hi)):
            if abs(float(value) - limit) <= tol:
                out.append({"name": name, "value": round(float(value), 5), "bound": bound, "limit": limit})
    return out


def at_bounds_note(result: dict) -> str | None:
    """One line for the user about a calibration's parameters at a bound (``result["at_bounds"]``), or None."""
    found = result.get("at_bounds") or []
    if not found:
        return None
    fixed = {*result.get("known", []), *result.get("not_read", [])}  # known, or held where the metamodel is blind
    estimated = len([n for n in free_theta() if n not in fixed])
    listed = ", ".join(f"{e['name']} at its {e['bound']} {e['limit']:g}" for e in found)
    return (
        f"note: {len(found)} of {estimated} estimated building parameters calibrated at a bound of the "
        f"catalogue's range ({listed}); the metamodel cannot go past them, so each is a value the fit wanted "
        "further, one standing in for something the model lacks, or one the fit does not depend on"
    )


def runs_note(result: dict) -> str | None:
    """One line for the user when CMA-ES runs of one calibration (``result["runs"]``, ``--restarts``) fit the
    calibration weeks about as well as the best run (cost within :data:`RUNS_COST_TOLERANCE` of it) but
    predict the held-out weeks' temperature differently (RMSE_T of the worst over the best at least
    :data:`RUNS_DISAGREEMENT`), or None: the calibration weeks then do not determine the model."""
    runs = result.get("runs") or []
    if len(runs) < 2:
        return None
    best = min(r["cost"] for r in runs)
    close = [r for r in runs if r["cost"] <= best * (1.0 + RUNS_COST_TOLERANCE)]
    rmse = [r["heldout_rmse_t_celsius"] for r in close]
    if len(close) < 2 or max(rmse) < RUNS_DISAGREEMENT * min(rmse):
        return None
    return (
        f"note: {len(close)} of {len(runs)} CMA-ES runs fit the calibration weeks as well as the best (cost "
        f"within {RUNS_COST_TOLERANCE:.0%}) but predict the held-out weeks' temperature differently (RMSE_T "
        f"{min(rmse):.2f} to {max(rmse):.2f} K): the calibration weeks do not determine the model; fit weeks "
        "that span the held-out weeks' weather (--weeks, e.g. every other week) or declare what is known "
        "([known] in site.toml)"
    )


def check_declared_effects(effects) -> tuple[str, ...]:
    """The declared effects as a tuple of catalogue names (:func:`buildenv.diagnosis.effects.check_declarable`); raises
    :class:`CalibrationError` for a name that is not in the catalogue, given twice, or ``holidays``."""
    try:
        return check_declarable(effects)
    except EffectError as exc:
        raise CalibrationError(f"--effect: {exc}") from None


#: Cost evaluations of the declared effects' stage (:func:`fit_declared_effects`, CMA-ES whichever method
#: calibrated the building); on the default site it stops on its tolerance well within them.
DECLARED_EFFECTS_EVALUATIONS = 1500


def fit_declared_effects(
    problem: Problem,
    surrogate: sg.Surrogate,
    base: np.ndarray,
    seed: int = 0,
    max_evaluations: int = DECLARED_EFFECTS_EVALUATIONS,
) -> tuple[np.ndarray, dict]:
    """Second calibration stage: the parameters of ``problem.effects`` with theta_build and occupancy kept at
    ``base`` (their calibrated values, ``(problem.n_base,)``), by CMA-ES started at the effects' "no effect"
    values. Returns the full parameter vector ``(problem.dim,)`` and ``{"evaluations", "cost"}``."""
    n = problem.n_base
    start = np.concatenate([np.asarray(base, float)[:n]] + [em.none_parameters(e) for e in problem.effects])
    return fit_last_parameters(problem, surrogate, start, n, seed, max_evaluations)


def fit_last_parameters(
    problem: Problem,
    surrogate: sg.Surrogate,
    start: np.ndarray,
    fixed: int,
    seed: int = 0,
    max_evaluations: int = DECLARED_EFFECTS_EVALUATIONS,
) -> tuple[np.ndarray, dict]:
    """Calibrate the parameters after the first ``fixed`` ones, those kept at ``start`` (physical, ``(dim,)``,
    also the search's start). Returns the full parameter vector and ``{"evaluations", "cost"}``."""
    lo, hi = problem.lo.copy(), problem.hi.copy()
    lo[:fixed] = hi[:fixed] = np.asarray(start, float)[:fixed]
    best, info = calibrate_cmaes(
        dataclasses.replace(problem, lo=lo, hi=hi), surrogate, seed, max_evaluations, start=start
    )
    return best, {"evaluations": info["evaluations"], "cost": info["cost"]}


def _scale(problem: Problem) -> dict[str, tuple[float, float]]:
    series = {"t": problem.temperature_c, "q": problem.consumption_wh_m2, "e": problem.electricity_wh_m2}
    return {k: (float(np.nanmean(v)), float(np.nanstd(v)) or 1.0) for k, v in series.items() if v is not None}


def score_weeks(
    site,
    surrogate: sg.Surrogate,
    weeks: list[int],
    params: np.ndarray,
    scale: dict[str, tuple[float, float]],
    effects: tuple[str, ...] = (),
    absent: np.ndarray | None = None,
) -> dict[str, float]:
    """Metrics of the parameters ``params`` (physical, problem order) on some of the site's weeks (with the
    model-side ``effects`` whose parameters follow in ``params``, and the ``absent`` days of the site)."""
    problem = build_problem(
        site, weeks, effects, absent, surrogate.context_hours, surrogate.uses_temperature_before, surrogate
    )
    t, q, e = predict_meters(problem, surrogate, params)
    months = hour_months(site, weeks)
    out = {**score_series(problem, t, q, params, scale, e), **guideline14_monthly(problem.consumption_wh_m2, q, months)}
    if e is not None:
        monthly = guideline14_monthly(problem.electricity_wh_m2, e, months)
        out |= {k.replace("_q_", "_e_"): v for k, v in monthly.items() if k != "months"}
    return out


def hour_months(site, weeks: list[int]) -> np.ndarray:
    """``(len(weeks), 168)`` calendar-month label (12 x year + month) of every hour of the site's ``weeks``."""
    starts = site.week_starts()
    days = [[starts[w] + dt.timedelta(days=d) for d in range(7)] for w in weeks]
    labels = np.array([[12 * day.year + day.month for day in week] for week in days], dtype=int)
    return np.repeat(labels, cat.HOURS_PER_DAY, axis=1)


def score_outputs(
    problem: Problem, outputs: np.ndarray, params: np.ndarray, scale: dict[str, tuple[float, float]]
) -> dict[str, float]:
    """Metrics (:func:`site_metrics`) of simulated outputs ``(weeks, 168, 8)`` of ``params`` on the problem's weeks."""
    return score_series(problem, *model_series(problem, outputs), params, scale, electricity_series(problem, outputs))


def score_series(
    problem: Problem,
    t: np.ndarray,
    q: np.ndarray,
    params: np.ndarray,
    scale: dict[str, tuple[float, float]],
    e: np.ndarray | None = None,
) -> dict[str, float]:
    """Metrics (:func:`site_metrics`) of a predicted temperature (degC) and consumption (Wh/m2) ``(weeks, 168)``;
    with the second meter's prediction ``e``, its R2, standardised MSE and Guideline 14 too (``_e`` keys)."""
    occupied = problem_occupancy(problem, params)
    out = {**site_metrics(problem.temperature_c, problem.consumption_wh_m2, t, q, occupied, scale)}
    if e is not None and problem.electricity_wh_m2 is not None:
        meter_scale = {**scale, "q": scale["e"]}
        second = site_metrics(problem.temperature_c, problem.electricity_wh_m2, t, e, occupied, meter_scale)
        out |= {k.replace("_q", "_e"): v for k, v in second.items() if "_q" in k}
    return {**out, "weeks": len(problem.x_base)}


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
    return np.array(
        [calibration["theta"][n] for n in free_theta()]
        + list(np.asarray(calibration["occupancy"], float).ravel())
        + [calibration["effects"][e].get(p.name, p.none) for e in effects for p in get_effect(e).parameters]
    )


def load_calibration(site_path: str | Path) -> dict:
    """The ``calibration.json`` of a site folder."""
    path = Path(site_path) / "calibration.json"
    if not path.is_file():
        raise CalibrationError(f"{site_path} is not calibrated yet: run `buildenv calibrate --site {site_path}`")
    calibration = json.loads(path.read_text())
    if isinstance(calibration.get("theta"), dict):
        calibration["theta"] = cat.upgrade_theta(calibration["theta"])
    return calibration


def metamodel_record(surrogate: sg.Surrogate) -> dict:
    """How a calibration records its metamodel: ``metamodel`` (a shipped checkpoint's name or a path) and
    ``metamodel_id`` (:func:`buildenv.metamodel.surrogate.checkpoint_identity`)."""
    return {"metamodel": surrogate.name, "metamodel_id": surrogate.identity}


def metamodel_mismatch(calibration: dict, surrogate: sg.Surrogate) -> str | None:
    """One line saying that ``calibration`` was made with another metamodel than ``surrogate`` (its parameters
    are that model's, not this one's), or ``None`` when it was made with this one or the record cannot tell.
    A calibration recorded as ``"default"`` without an identity was made with the earlier default, shipped
    as ``"diagnosis"``."""
    made = calibration.get("metamodel_id")
    name = calibration.get("metamodel")
    if made is None and name is not None:
        path = sg.SHIPPED_CHECKPOINTS.get("diagnosis" if name == "default" else name, Path(name))
        made = sg.checkpoint_identity(path) if path.is_file() else None
    if made is None or surrogate.identity is None or made == surrogate.identity:
        return None
    earlier_default = name == "default" and "metamodel_id" not in calibration
    label = "the earlier default metamodel ('diagnosis')" if earlier_default else name
    return (
        f"calibration made with {label}, used with {surrogate.name}: its parameters belong to that model; "
        f"recalibrate the site with this metamodel (buildenv calibrate --checkpoint) or use the one it was made with"
    )
