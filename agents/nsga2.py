"""NSGA-II (pymoo) over one week: the energy-comfort Pareto front and the point of equal comfort.

The pymoo ``Problem`` is vectorised: a whole population is scored by one call of the environment's batched
``evaluate``. Objectives (both minimised): ``energy_term`` (HVAC energy relative to the historical
settings) and ``comfort_k`` (the comfort term, K). The initial population holds the historical settings,
actions with every setting at one same point of its range (all at the minimum ... all at the maximum) and
random actions, so the front is searched from today's operation and from its ends inwards.

Hypervolume is measured in the (energy_term, comfort_k) plane against :data:`HV_REFERENCE`
(1.5 x the historical energy, 3 K), a point every sensible setting dominates.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

HV_REFERENCE = (1.5, 3.0)
# the initial population: the historical settings, CONSTANT_STARTS actions with every setting at the same point
# of its range (from all at the minimum to all at the maximum, the ends of the front), the rest random
CONSTANT_STARTS = 21
# distribution indices of the SBX crossover and polynomial mutation: wider steps than pymoo's usual 15 and 20,
# which converge far more slowly on this problem (docs/optimisers.md)
SBX_ETA, PM_ETA = 5, 5


@dataclass
class ParetoResult:
    """A Pareto front of one week.

    Attributes:
        week: week of the year.
        actions: ``(M, A)`` non-dominated actions (A: the action size).
        energy_term: ``(M,)`` energy relative to the historical settings.
        comfort_k: ``(M,)`` comfort term, K.
        hypervolume: of the front against :data:`HV_REFERENCE`.
        evaluations: weeks scored.
        seconds: wall time.
        history: hypervolume after each generation.
        history_seconds: wall time since the start at the end of each generation, s.
    """

    week: int
    actions: np.ndarray
    energy_term: np.ndarray
    comfort_k: np.ndarray
    hypervolume: float
    evaluations: int
    seconds: float
    history: list[float]
    history_seconds: list[float]


def hypervolume(energy_term: np.ndarray, comfort_k: np.ndarray) -> float:
    """Hypervolume of points (minimised objectives) against :data:`HV_REFERENCE`."""
    from pymoo.indicators.hv import HV

    points = np.column_stack([energy_term, comfort_k])
    inside = (points < np.array(HV_REFERENCE)).all(axis=1)
    return float(HV(ref_point=np.array(HV_REFERENCE))(points[inside])) if inside.any() else 0.0


def pareto_front(
    env, week: int, population: int = 100, generations: int = 1000, seed: int = 0, progress: bool = False
) -> ParetoResult:
    """Run NSGA-II on one week of a ``BuildingWeek-v0`` environment.

    Args:
        env: the environment (its ``unwrapped.evaluate`` scores populations).
        week: week of the year.
        population: NSGA-II population size.
        generations: number of generations (evaluations = population x generations).
        seed: seed of the run.
        progress: show a progress bar.
    Returns:
        the final :class:`ParetoResult`, its points sorted by ``energy_term``.
    """
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.callback import Callback
    from pymoo.core.problem import Problem
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.optimize import minimize
    from tqdm import tqdm

    base = env.unwrapped
    n_var = int(np.prod(base.action_space.shape))

    class WeekProblem(Problem):
        def __init__(self) -> None:
            super().__init__(n_var=n_var, n_obj=2, xl=-1.0, xu=1.0)

        def _evaluate(self, x, out, *args, **kwargs):
            scores = base.evaluate(x, week=week)
            out["F"] = np.column_stack([scores["energy_term"], scores["comfort_k"]])

    bar = tqdm(total=generations, desc=f"NSGA-II week {week}", disable=not progress, leave=False)

    class Track(Callback):
        def __init__(self) -> None:
            super().__init__()
            self.hv: list[float] = []
            self.seconds: list[float] = []

        def notify(self, algorithm):
            f = algorithm.opt.get("F")
            self.hv.append(hypervolume(f[:, 0], f[:, 1]))
            self.seconds.append(time.perf_counter() - started)
            bar.update(1)

    rng = np.random.default_rng(seed)
    start = rng.uniform(-1.0, 1.0, (population, n_var))
    start[0] = base.historical_action
    corners = min(CONSTANT_STARTS, population - 1)
    start[1 : 1 + corners] = np.linspace(-1.0, 1.0, corners)[:, None]
    track = Track()
    started = time.perf_counter()
    algorithm = NSGA2(
        pop_size=population,
        sampling=start,
        crossover=SBX(prob=0.9, eta=SBX_ETA),
        mutation=PM(eta=PM_ETA),
        eliminate_duplicates=True,
    )
    result = minimize(WeekProblem(), algorithm, ("n_gen", generations), seed=seed, callback=track, verbose=False)
    bar.close()
    seconds = time.perf_counter() - started
    order = np.argsort(result.F[:, 0])
    f, x = result.F[order], np.atleast_2d(result.X)[order]
    return ParetoResult(
        int(week),
        x.astype(np.float32),
        f[:, 0],
        f[:, 1],
        hypervolume(f[:, 0], f[:, 1]),
        int(result.algorithm.evaluator.n_eval),
        seconds,
        track.hv,
        track.seconds,
    )


def equal_comfort_choice(front: ParetoResult, comfort_reference_k: float) -> int:
    """Index of the front point that uses least energy with comfort no worse than ``comfort_reference_k``
    (the paper's "point of closest equivalent comfort"); the most comfortable point if none is as good.

    The metamodel evaluates in float32: the same settings give comfort values a few 1e-8 K apart alone and
    inside a batch, so a point within 1e-6 K of the reference counts as equally comfortable."""
    ok = np.flatnonzero(front.comfort_k <= comfort_reference_k + 1e-6)
    if ok.size == 0:
        return int(np.argmin(front.comfort_k))
    return int(ok[np.argmin(front.energy_term[ok])])
