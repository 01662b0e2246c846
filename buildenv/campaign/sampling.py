"""Sampling catalogue variables on their grids: uniform (the paper's choice) or Latin hypercube."""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

METHODS = ("uniform", "lhs")


#: Scales a campaign may draw the floor area on: ``linear`` (each grid value equally likely) or ``log`` (uniform in
#: its logarithm: each decade of floor area, 300-3,000 m2 as 3,000-30,000 m2, in equal shares).
FLOOR_AREA_SCALES = ("linear", "log")


def sample_group(
    group: str, n: int, rng: np.random.Generator, method: str = "uniform", log_scaled: tuple[str, ...] = ()
) -> np.ndarray:
    """Draw ``n`` vectors of a group's variables on their catalogue grids.

    Args:
        group: catalogue group with stepped variables (``theta_build``, ``settings``, ``occupancy``).
        n: number of vectors.
        rng: random generator (the only source of randomness).
        method: ``uniform`` (each grid value equally likely, independently) or ``lhs`` (Latin hypercube over
            the unit cube, mapped onto the grids, so each variable's grid values appear in near-equal shares).
        log_scaled: names of the group's variables drawn uniformly in their logarithm between their bounds, then
            rounded to their grid (their minimum must be above 0).
    Returns:
        ``(n, len(group))`` array in catalogue order and physical units.
    """
    variables = cat.GROUPS[group]
    grids = [v.grid() for v in variables]
    if method == "uniform":
        u = rng.random((n, len(variables)))
    elif method == "lhs":
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=len(variables), seed=rng).random(n) if n > 0 else np.zeros((0, len(variables)))
    else:
        raise ValueError(f"unknown sampling method {method!r}; choose one of {', '.join(METHODS)}")
    columns = []
    for i, (variable, grid) in enumerate(zip(variables, grids)):
        if variable.name in log_scaled:
            columns.append(variable.snap(variable.min * (variable.max / variable.min) ** u[:, i]))
        else:
            columns.append(grid[np.minimum((u[:, i] * len(grid)).astype(int), len(grid) - 1)])
    return np.stack(columns, axis=1) if n else np.zeros((0, len(variables)))


#: Share of days set back entirely (``hvac_operating`` 0), Monday..Sunday: weekend shutdowns are common, a weekday
#: off (a holiday) is rarer; the other settings are drawn on every day alike.
DAY_OFF_SHARE = (0.15, 0.15, 0.15, 0.15, 0.15, 0.5, 0.5)


def sample_weeks(n_weeks: int, rng: np.random.Generator, method: str = "uniform") -> tuple[np.ndarray, np.ndarray]:
    """Weekly settings ``(n_weeks, 7, 13)`` and occupancy ``(n_weeks, 5, 2)``, every day drawn independently; a
    day is set back entirely with :data:`DAY_OFF_SHARE` of its weekday."""
    settings = sample_group("settings", n_weeks * 7, rng, method).reshape(n_weeks, 7, -1)
    occupancy = sample_group("occupancy", n_weeks * 5, rng, method).reshape(n_weeks, 5, -1)
    settings[..., cat.SETTING_NAMES.index("hvac_operating")] = rng.random((n_weeks, 7)) >= np.array(DAY_OFF_SHARE)
    return settings, occupancy


def theta_around(
    centres: np.ndarray, n: int, rng: np.random.Generator, spread: float, fixed: tuple[str, ...] = ()
) -> np.ndarray:
    """Draw ``n`` buildings around given ones (the calibrations of sites a metamodel will be used on).

    Each draw takes one of ``centres`` at random and moves every theta_build variable by a normal step of
    ``spread`` times its catalogue range, kept within the range and rounded to its grid; ``fixed`` variables (the
    known geometry) keep the centre's value, rounded to the grid.

    Args:
        centres: ``(m, len(theta_build))`` buildings in catalogue order and physical units.
        n: number of buildings.
        rng: random generator (the only source of randomness).
        spread: standard deviation of each step, as a share of the variable's range.
        fixed: names of the variables not moved.
    Returns:
        ``(n, len(theta_build))`` array in catalogue order and physical units.
    """
    variables = cat.GROUPS["theta_build"]
    centres = np.asarray(centres, dtype=float).reshape(-1, len(variables))
    picked = centres[rng.integers(0, len(centres), n)]
    steps = rng.normal(0.0, spread, (n, len(variables)))
    columns = []
    for i, variable in enumerate(variables):
        moved = 0.0 if variable.name in fixed else steps[:, i] * (variable.max - variable.min)
        columns.append(variable.snap(picked[:, i] + moved))
    return np.stack(columns, axis=1) if n else np.zeros((0, len(variables)))
