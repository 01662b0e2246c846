"""CMA-ES (pycma) on the scalarised reward of one week, each generation scored in one batched call."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


@dataclass
class WeekResult:
    """The best weekly settings an optimiser found for one week.

    Attributes:
        week: week of the year.
        action: ``(A,)`` action in [-1, 1] (A: the environment's action size).
        scores: the environment's ``evaluate`` scores of ``action`` (reward, energy_term, comfort_k, ...).
        evaluations: weeks the optimiser scored.
        seconds: wall time.
        history: best reward after each generation.
    """

    week: int
    action: np.ndarray
    scores: dict
    evaluations: int
    seconds: float
    history: list[float] = field(default_factory=list)


def scalar_scores(scores: dict, i: int) -> dict[str, float]:
    """Plain floats of candidate ``i`` of an ``evaluate`` result (settings and hourly series left out)."""
    return {k: float(np.asarray(v)[i]) for k, v in scores.items() if np.ndim(v) == 1}


def optimise_week(
    env,
    week: int,
    evaluations: int = 6000,
    population: int = 64,
    sigma0: float = 0.3,
    seed: int = 0,
    x0: np.ndarray | None = None,
) -> WeekResult:
    """Maximise the reward of one week with CMA-ES over the action components.

    Args:
        env: a ``BuildingWeek-v0`` environment (``env.unwrapped.evaluate`` is used).
        week: week of the year.
        evaluations: budget of scored candidate weeks.
        population: CMA-ES population (one batched evaluation per generation).
        sigma0: initial step size in action units ([-1, 1] per component).
        seed: seed of CMA-ES.
        x0: initial mean (default: the site's historical settings).
    """
    import cma

    base = env.unwrapped
    started = time.perf_counter()
    mean0 = np.asarray(base.historical_action if x0 is None else x0, dtype=float)
    es = cma.CMAEvolutionStrategy(
        mean0,
        sigma0,
        {
            "bounds": [-1.0, 1.0],
            "popsize": population,
            "seed": seed + 1,
            "verbose": -9,
            "maxfevals": evaluations,
            "tolfun": 1e-7,
        },
    )
    best_x, best_f, history = mean0, -np.inf, []
    while not es.stop():
        x = np.asarray(es.ask())
        reward = base.evaluate(x, week=week)["reward"]
        es.tell(list(x), (-reward).tolist())
        if reward.max() > best_f:
            best_f, best_x = float(reward.max()), x[int(reward.argmax())]
        history.append(best_f)
    scores = base.evaluate(best_x[None], week=week)
    return WeekResult(
        int(week),
        best_x.astype(np.float32),
        scalar_scores(scores, 0),
        int(es.result.evaluations),
        time.perf_counter() - started,
        history,
    )
