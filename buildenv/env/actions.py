"""A week of BMS settings as a vector in [-1, 1]: the action of BuildingWeek-v0 and what optimisers search.

The components are the settings of :data:`buildenv.catalogue.SETTINGS` the site's BMS can change
(:class:`ActionMap`; all 13, 91 components, unless its ``[bms]`` says otherwise) for each day Monday..Sunday,
day-major (names: :meth:`ActionMap.names`; all 13: :func:`action_names`); the others stay at the site's
historical values. Outdoor air stays at or above what ASHRAE 62.1 requires for the site's occupants
(:func:`code_minimum_ventilation_ach`) unless the site's ``[bms]`` limits say otherwise. Component ``a`` maps
linearly onto the setting's range,
``min + (a + 1) / 2 * (max - min)`` (the catalogue's, within what the metamodel was trained on: :func:`bounds`),
then onto the catalogue step (hours are whole hours, setpoints go by
0.5 K, outdoor air by 0.05 air changes per hour), as a BMS accepts them. Components outside [-1, 1] are
clipped (and counted); NaN or infinite components are an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from buildenv import catalogue as cat
from buildenv.energyplus.ventilation_code import code_minimum_ventilation_ach
from buildenv.errors import BuildingEnvError

ACTION_SIZE = len(cat.DAYS) * len(cat.SETTINGS)


def action_names() -> tuple[str, ...]:
    """Names of the 91 action components (``cooling_start_hour_monday``, ...)."""
    return cat.weekly_names("settings")


def bounds(domain: dict[str, tuple[float, float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds ``(13,)`` of the settings: the catalogue's ranges, narrowed to ``domain``
    (``{name: (min, max)}``, a metamodel's :attr:`~buildenv.metamodel.surrogate.Surrogate.domain`) where given."""
    lo, hi = cat.bounds("settings")
    for j, name in enumerate(cat.SETTING_NAMES):
        if domain and name in domain:
            lo[j], hi[j] = max(lo[j], domain[name][0]), min(hi[j], domain[name][1])
    return lo, hi


@dataclass(frozen=True)
class ActionMap:
    """The actions of one site: the settings its BMS can change (each day, day-major), each mapped onto its range,
    and the week's other settings held at ``base``.

    Attributes:
        controllable: indices into :data:`buildenv.catalogue.SETTING_NAMES` of the settings the action sets.
        lo, hi: ``(13,)`` range of each setting (:func:`bounds`, narrowed by the site's limits).
        base: ``(7, 13)`` settings of the week where the action does not set them (the historical ones).
    """

    controllable: tuple[int, ...]
    lo: np.ndarray
    hi: np.ndarray
    base: np.ndarray

    @classmethod
    def everything(cls, ranges: tuple[np.ndarray, np.ndarray] | None = None) -> ActionMap:
        """Every setting controllable on ``ranges`` (the catalogue's where ``None``): the 91 components."""
        lo, hi = ranges or cat.bounds("settings")
        base = np.tile((np.asarray(lo) + np.asarray(hi)) / 2.0, (len(cat.DAYS), 1))
        return cls(tuple(range(len(cat.SETTINGS))), np.asarray(lo, float), np.asarray(hi, float), base)

    @classmethod
    def for_site(
        cls, site, domain: dict[str, tuple[float, float]], historical: np.ndarray, occupants_per_m2: float = 0.0
    ) -> ActionMap:
        """The actions of a :class:`buildenv.sites.Site`: its controllable settings within its limits and the
        metamodel's ``domain`` (:func:`bounds`; one whose limits lie outside the domain, or that the metamodel learnt at
        one value only, is not an action), the others
        at ``historical`` ``(7, 13)``. Where the site gives no ``ventilation_ach`` limits, outdoor air keeps to the
        code minimum for ``occupants_per_m2`` (:func:`code_minimum_ventilation_ach`)."""
        lo, hi = bounds(domain)
        learnt = hi > lo  # a setting the metamodel learnt at one value only cannot be acted on with it
        site_lo, site_hi = site.setting_ranges()
        if "ventilation_ach" not in site.setting_limits:
            j = cat.SETTING_NAMES.index("ventilation_ach")
            site_lo[j] = max(site_lo[j], code_minimum_ventilation_ach(occupants_per_m2))
        lo, hi = np.maximum(lo, site_lo), np.minimum(hi, site_hi)
        # a setting whose limits lie outside what the metamodel learnt cannot be acted on with it: held historical
        controllable = tuple(j for j in map(cat.SETTING_NAMES.index, site.controllable) if lo[j] <= hi[j] and learnt[j])
        return cls(controllable, lo, np.maximum(lo, hi), np.asarray(historical, float).reshape(len(cat.DAYS), -1))

    @property
    def size(self) -> int:
        """Number of action components: 7 x the controllable settings."""
        return len(cat.DAYS) * len(self.controllable)

    def names(self) -> tuple[str, ...]:
        """Names of the action components (``heating_comfort_c_monday``, ...), day-major."""
        return tuple(f"{cat.SETTING_NAMES[j]}_{day}" for day in cat.DAYS for j in self.controllable)

    def decode(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Physical settings ``(..., 7, 13)`` and the number of clipped components ``(...)`` of actions
        ``(..., size)``.

        Raises:
            BuildingEnvError: a component is NaN or infinite, or the last axis is not :attr:`size` long.
        """
        a = np.asarray(action, dtype=float)
        if a.shape[-1:] != (self.size,):
            raise BuildingEnvError(
                f"an action has {self.size} components ({len(self.controllable)} settings x 7 days), "
                f"got shape {a.shape}"
            )
        bad = ~np.isfinite(a)
        if bad.any():
            first = int(np.flatnonzero(bad.reshape(-1, self.size).any(0))[0])
            value = a.reshape(-1)[bad.reshape(-1)][0]
            raise BuildingEnvError(f"action component {first} ({self.names()[first]}) is {value}")
        clipped = ((a < -1.0) | (a > 1.0)).sum(-1)
        a = np.clip(a, -1.0, 1.0).reshape(*a.shape[:-1], len(cat.DAYS), len(self.controllable))
        c = list(self.controllable)
        values = self.lo[c] + (a + 1.0) / 2.0 * (self.hi[c] - self.lo[c])
        settings = np.array(np.broadcast_to(self.base, (*a.shape[:-2], *self.base.shape)))
        for k, j in enumerate(c):
            var = cat.SETTINGS[j]
            snapped = var.snap(values[..., k])
            if var.step is not None:  # the grid point nearest inside the range (limits need not be on the grid)
                snapped = np.where(snapped < self.lo[j] - 1e-9, snapped + var.step, snapped)
                snapped = np.where(snapped > self.hi[j] + 1e-9, snapped - var.step, snapped)
            settings[..., j] = snapped
        return settings, clipped

    def encode(self, settings: np.ndarray) -> np.ndarray:
        """Actions ``(..., size)`` of physical settings ``(..., 7, 13)`` (validated against the catalogue; the
        settings not controllable are ignored; a value outside its range gets the nearest end, -1 or 1).
        ``decode(encode(s))`` gives back ``s`` for controllable settings on the catalogue grid within the ranges."""
        settings = np.asarray(settings, dtype=float)
        if settings.shape[-2:] != (len(cat.DAYS), len(cat.SETTINGS)):
            raise BuildingEnvError(f"settings have shape (..., 7, 13) (day, setting), got {settings.shape}")
        cat.check_values("settings", settings, "settings")
        c = list(self.controllable)
        span = self.hi[c] - self.lo[c]
        a = np.where(span > 0, 2.0 * (settings[..., c] - self.lo[c]) / np.where(span > 0, span, 1.0) - 1.0, 0.0)
        return np.clip(a, -1.0, 1.0).reshape(*settings.shape[:-2], self.size).astype(np.float32)


def decode(action: np.ndarray, ranges: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Physical settings ``(..., 7, 13)`` and the number of clipped components ``(...)`` of actions ``(..., 91)``,
    every setting controllable on ``ranges`` (:func:`bounds`; the catalogue's where ``None``).

    Raises:
        BuildingEnvError: a component is NaN or infinite, or the last axis is not 91 long.
    """
    return ActionMap.everything(ranges).decode(action)


def encode(settings: np.ndarray, ranges: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Actions ``(..., 91)`` of physical settings ``(..., 7, 13)`` (validated against the catalogue), for
    ``ranges`` as in :func:`decode`. ``decode(encode(s))`` gives back ``s`` for settings on the catalogue grid."""
    return ActionMap.everything(ranges).encode(settings)


def settings_table(settings: np.ndarray) -> dict[str, dict[str, float]]:
    """``{day: {setting name: value}}`` of one week's settings ``(7, 13)`` (for JSON and reports)."""
    s = np.asarray(settings, dtype=float).reshape(len(cat.DAYS), len(cat.SETTINGS))
    return {day: {name: float(s[d, j]) for j, name in enumerate(cat.SETTING_NAMES)} for d, day in enumerate(cat.DAYS)}
