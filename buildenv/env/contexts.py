"""Many buildings as contexts of ``BuildingWeek-v0``: which sites ``site=`` and ``sites=`` name.

``site=`` is one site (a folder, ``"default"``, a calibrated :class:`buildenv.sites.Site`) or a context set: a list or
tuple of sites, the shipped library (``"library"``, :data:`buildenv.sites.library.SHIPPED_LIBRARY`) or a library
folder (one holding ``library.toml``, :mod:`buildenv.sites.library`). ``sites=`` chooses among a set's sites:
``"all"`` (default), ``"train"`` or ``"test"`` (a library's own split, recorded in its index; a list has none) or a
list of the sites' names. Each episode draws its site uniformly under the environment's seed, then its week.

:func:`resolve` gives the chosen sites as :class:`Context` rows; :func:`check_alike` refuses a set whose sites would
give different action spaces (other settings, or other ranges of them); :func:`by_site` and :func:`gather` split a
batch by site and put it back together, so the vector env calls each site's model once per step.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from buildenv import catalogue as cat
from buildenv.env.registration import ENV_ID
from buildenv.errors import BuildingEnvError
from buildenv.sites.library import SHIPPED_LIBRARY, is_library, read_library

if TYPE_CHECKING:
    from buildenv.env.actions import ActionMap

SITE_SPLITS = ("train", "test", "all")
LIBRARY = "library"


@dataclass(frozen=True)
class Context:
    """One site of the environment: its name (what ``info["site"]`` and ``render`` say), what loads it (a folder,
    ``"default"`` or a :class:`buildenv.sites.Site`) and its library part (None outside a library)."""

    name: str
    source: Any
    part: str | None = None


def is_set(site: Any) -> bool:
    """Whether ``site=`` names several sites (a list or tuple, ``"library"`` or a library folder)."""
    if isinstance(site, (list, tuple)):
        return True
    if isinstance(site, str) and site == LIBRARY:
        return True
    return isinstance(site, (str, os.PathLike)) and is_library(site)


def _name(site: Any) -> str:
    """A site's name: its folder's name (``"default"`` for the shipped site)."""
    from buildenv.sites import Site

    if isinstance(site, Site):
        return Path(site.path).name if site.path else str(site.name)
    if site is None or (isinstance(site, str) and site == "default"):
        return "default"
    path = Path(site).expanduser()
    return (path.parent if path.suffix == ".toml" else path).resolve().name


def listing(names: Sequence[str], most: int = 6) -> str:
    """``a, b, c`` (the first ``most`` and how many more)."""
    shown = ", ".join(names[:most])
    return shown + (f", ... ({len(names)} sites)" if len(names) > most else "")


def _path(site: Any) -> str | None:
    """A site's folder as a full path (None for ``"default"`` and a :class:`buildenv.sites.Site` without a path)."""
    from buildenv.sites import Site

    if isinstance(site, Site):
        return str(Path(site.path).resolve()) if site.path else None
    if isinstance(site, (str, os.PathLike)) and not (isinstance(site, str) and site == "default"):
        path = Path(site).expanduser()
        return str((path.parent if path.suffix == ".toml" else path).resolve())
    return None


def _from_list(sites: Sequence[Any]) -> list[Context]:
    """The contexts of a list of sites, named by folder (by the full path where two folders share a name)."""
    if not sites:
        raise BuildingEnvError(f"{ENV_ID}: site=[]; give at least one site")
    names = [_name(s) for s in sites]
    clash = {n for n in names if names.count(n) > 1 and n != "default"}
    names = [(_path(s) or n) if n in clash else n for n, s in zip(names, sites)]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise BuildingEnvError(f"{ENV_ID}: site= lists {twice[0]!r} twice; give each site once")
    return [Context(name, site) for name, site in zip(names, sites)]


def _from_library(site: Any) -> list[Context]:
    """The contexts of the shipped library (``"library"``) or a library folder."""
    shipped = isinstance(site, str) and site == LIBRARY
    folder = SHIPPED_LIBRARY if shipped else Path(site)
    if shipped and not is_library(folder):
        raise BuildingEnvError(
            f"{ENV_ID}: site='library': the shipped library is not built ({folder} has no library.toml); "
            f"build it with buildenv suite library --suite DIR --out {folder}"
        )
    return [Context(s.name, s.folder, s.part) for s in read_library(folder)]


def _select(contexts: list[Context], sites: Any, split: bool) -> list[Context]:
    """The contexts ``sites=`` chooses (see the module docstring)."""
    if isinstance(sites, str):
        if sites not in SITE_SPLITS:
            raise BuildingEnvError(
                f"{ENV_ID}: sites={sites!r}; choose one of {', '.join(SITE_SPLITS)} or a list of site names"
            )
        if sites == "all":
            return contexts
        if not split:
            raise BuildingEnvError(
                f"{ENV_ID}: sites={sites!r}: a list of sites has no train/test split (a library's library.toml "
                "has); give sites= the list of the sites to use"
            )
        chosen = [c for c in contexts if c.part == sites]
        if not chosen:
            raise BuildingEnvError(f"{ENV_ID}: sites={sites!r}: the library has no {sites} site")
        return chosen
    if isinstance(sites, (list, tuple)) and sites and all(isinstance(s, str) for s in sites):
        names = [c.name for c in contexts]
        unknown = [s for s in sites if s not in names]
        if unknown:
            raise BuildingEnvError(
                f"{ENV_ID}: sites=: unknown site(s) {', '.join(map(repr, unknown))}; the sites are {listing(names)}"
            )
        return [contexts[names.index(s)] for s in dict.fromkeys(sites)]
    raise BuildingEnvError(f"{ENV_ID}: sites={sites!r}; give one of {', '.join(SITE_SPLITS)} or a list of site names")


def resolve(site: Any, sites: Any = "all") -> tuple[list[Context], bool]:
    """The sites ``site=`` and ``sites=`` choose, and whether they are a context set (a list or a library, whose
    episodes draw a site and whose ``info`` names it; False for one site, which behaves as it always has).

    Raises:
        BuildingEnvError: ``sites=`` other than ``"all"`` with one site, ``"train"``/``"test"`` with a list,
            unknown names, an empty list, a site listed twice, ``"library"`` before the library is built.
        buildenv.errors.SiteError: a library whose index is broken.
    """
    if not is_set(site):
        if not (isinstance(sites, str) and sites == "all"):
            raise BuildingEnvError(
                f"{ENV_ID}: sites={sites!r} chooses among several sites, but site= is one; give site= a list of "
                "sites or 'library'"
            )
        return [Context(_name(site), site)], False
    if isinstance(site, (list, tuple)):
        return _select(_from_list(site), sites, split=False), True
    return _select(_from_library(site), sites, split=True), True


def check_alike(actions: Sequence[tuple[str, ActionMap]]) -> None:
    """Refuse sites whose action spaces differ: ``actions`` is ``(name, action map)`` per site; each must act on the
    same settings over the same ranges (``lo``, ``hi``), so that one action means the same settings on every site
    (the observation space depends on the environment's arguments only, the same for every site).

    Raises:
        BuildingEnvError: one line naming the first site that differs from the first site, and how (the settings
            it lacks or adds, or the first setting whose range differs, with both ranges).
    """
    first_name, first_map = actions[0]
    first = tuple(first_map.controllable)
    for name, action_map in actions[1:]:
        controllable = tuple(action_map.controllable)
        if controllable == first:
            for j in first:
                ranges = [(float(m.lo[j]), float(m.hi[j])) for m in (action_map, first_map)]
                if not np.allclose(*ranges, rtol=1e-9, atol=1e-9):
                    (lo, hi), (lo0, hi0) = ranges
                    raise BuildingEnvError(
                        f"{ENV_ID}: site {name!r} gives {cat.SETTING_NAMES[j]} the range [{lo:g}, {hi:g}] where site "
                        f"{first_name!r} gives [{lo0:g}, {hi0:g}]; every site of a context set needs the same ranges "
                        "of its controllable settings, so that an action means the same settings on each ([bms] "
                        "limits in site.toml, within the metamodel's range)"
                    )
            continue
        lacks = [cat.SETTING_NAMES[j] for j in first if j not in controllable]
        adds = [cat.SETTING_NAMES[j] for j in controllable if j not in first]
        how = (
            "; ".join([f"lacks {', '.join(lacks)}"] * bool(lacks) + [f"adds {', '.join(adds)}"] * bool(adds))
            or "orders them differently"
        )
        raise BuildingEnvError(
            f"{ENV_ID}: site {name!r} gives another action space than site {first_name!r}: it acts on "
            f"{len(controllable)} settings ({len(cat.DAYS) * len(controllable)} actions) where {first_name!r} acts on "
            f"{len(first)} ({how}); every site of a context set needs the same [bms] controllable settings "
            "within the metamodel's range (site.toml)"
        )


def by_site(sites: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """``(site, positions)`` for each site in ``sites`` ``(N,)``, ascending: the positions of the rows it holds."""
    sites = np.asarray(sites, dtype=int)
    return [(int(s), np.flatnonzero(sites == s)) for s in np.unique(sites)]


def gather(parts: list[tuple[np.ndarray, dict[str, np.ndarray]]], n: int) -> dict[str, np.ndarray]:
    """One dict of ``(n, ...)`` arrays from per-site dicts of their rows ``(positions, {key: (k, ...)})``; the one
    part itself when it holds every row in order."""
    if len(parts) == 1 and np.array_equal(parts[0][0], np.arange(n)):
        return parts[0][1]
    out: dict[str, np.ndarray] = {}
    for key, first in parts[0][1].items():
        first = np.asarray(first)
        array = np.empty((n, *first.shape[1:]), dtype=first.dtype)
        for positions, values in parts:
            array[positions] = values[key]
        out[key] = array
    return out
