"""A week of BMS settings as a vector in [-1, 1]: the action of BuildingWeek-v0 and what optimisers search.

The 84 components are the 12 settings of :data:`buildenv.catalogue.SETTINGS` for each day Monday..Sunday,
day-major (names: :func:`action_names`). Component ``a`` maps linearly onto the catalogue range,
``min + (a + 1) / 2 * (max - min)``, then onto the catalogue step (hours are whole hours, setpoints go by
0.5 K, ventilation by 0.3 air changes per hour), as a BMS accepts them. Components outside [-1, 1] are
clipped (and counted); NaN or infinite components are an error.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildingEnvError

ACTION_SIZE = len(cat.DAYS) * len(cat.SETTINGS)


def action_names() -> tuple[str, ...]:
    """Names of the 84 action components (``cooling_start_hour_monday``, ...)."""
    return cat.weekly_names("settings")


def decode(action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physical settings ``(..., 7, 12)`` and the number of clipped components ``(...)`` of actions ``(..., 84)``.

    Raises:
        BuildingEnvError: a component is NaN or infinite, or the last axis is not 84 long.
    """
    a = np.asarray(action, dtype=float)
    if a.shape[-1:] != (ACTION_SIZE,):
        raise BuildingEnvError(f"an action has {ACTION_SIZE} components (12 settings x 7 days), got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        first = int(np.flatnonzero(bad.reshape(-1, ACTION_SIZE).any(0))[0])
        value = a.reshape(-1)[bad.reshape(-1)][0]
        raise BuildingEnvError(f"action component {first} ({action_names()[first]}) is {value}")
    clipped = ((a < -1.0) | (a > 1.0)).sum(-1)
    a = np.clip(a, -1.0, 1.0).reshape(*a.shape[:-1], len(cat.DAYS), len(cat.SETTINGS))
    lo, hi = cat.bounds("settings")
    values = lo + (a + 1.0) / 2.0 * (hi - lo)
    settings = np.stack([var.snap(values[..., j]) for j, var in enumerate(cat.SETTINGS)], axis=-1)
    return settings, clipped


def encode(settings: np.ndarray) -> np.ndarray:
    """Actions ``(..., 84)`` of physical settings ``(..., 7, 12)`` (validated against the catalogue).

    ``decode(encode(s))`` gives back ``s`` for settings on the catalogue grid.
    """
    settings = np.asarray(settings, dtype=float)
    if settings.shape[-2:] != (len(cat.DAYS), len(cat.SETTINGS)):
        raise BuildingEnvError(f"settings have shape (..., 7, 12) (day, setting), got {settings.shape}")
    cat.check_values("settings", settings, "settings")
    lo, hi = cat.bounds("settings")
    a = 2.0 * (settings - lo) / (hi - lo) - 1.0
    return a.reshape(*settings.shape[:-2], ACTION_SIZE).astype(np.float32)


def settings_table(settings: np.ndarray) -> dict[str, dict[str, float]]:
    """``{day: {setting name: value}}`` of one week's settings ``(7, 12)`` (for JSON and reports)."""
    s = np.asarray(settings, dtype=float).reshape(len(cat.DAYS), len(cat.SETTINGS))
    return {day: {name: float(s[d, j]) for j, name in enumerate(cat.SETTING_NAMES)} for d, day in enumerate(cat.DAYS)}
