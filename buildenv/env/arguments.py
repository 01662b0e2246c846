"""The arguments of ``BuildingWeek-v0`` and of its vector env: their defaults (:data:`ARGUMENTS`), the choices
some of them allow, and the checks that turn an unknown argument or a bad value into one clear
:class:`buildenv.errors.BuildingEnvError` line.

Both environments check their arguments here (through :class:`buildenv.env.building.Building`) before anything is
loaded; :func:`split_weeks` says which weeks of the year ``weeks=`` names.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from gymnasium.vector import AutoresetMode

from buildenv.env import objectives as obj
from buildenv.env.observations import OBSERVATION_KINDS
from buildenv.env.registration import ENV_ID
from buildenv.errors import BuildingEnvError

BACKENDS = ("metamodel", "energyplus")
WEEK_SPLITS = ("train", "test", "all")
ARGUMENTS: dict[str, Any] = {
    "site": "default",
    "metamodel": "default",
    "comfort_weight": 1.0,
    "target_temperature_c": obj.T_STAR_C,
    "comfort": "rms",
    "comfort_band_k": 1.0,
    "observation": "compact",
    "episode_weeks": 1,
    "weeks": "train",
    "sites": "all",
    "backend": "metamodel",
    "forecast_noise": 0.0,
    "weather_years": 1,
    "price": None,
    "strict_calibration": False,
    "render_mode": None,
}
RENDER_MODES = ("rgb_array", "ansi")
VECTOR_ARGUMENTS = ("num_envs", "autoreset_mode", "max_episode_steps")


def checked_arguments(kwargs: dict[str, Any], extra: tuple[str, ...] = ()) -> dict[str, Any]:
    """``kwargs`` with the defaults of :data:`ARGUMENTS` filled in; an argument neither there nor in ``extra`` (the
    vector env's own), a ``comfort``, ``observation``, ``backend`` or ``render_mode`` not among its choices, or a
    ``strict_calibration`` that is not a bool raises one clear :class:`BuildingEnvError`."""
    unknown = sorted(set(kwargs) - set(ARGUMENTS))
    if unknown:
        raise BuildingEnvError(
            f"{ENV_ID}: unknown argument(s) {', '.join(unknown)}; allowed: {', '.join((*ARGUMENTS, *extra))}"
        )
    args = {**ARGUMENTS, **kwargs}
    for key, allowed in (("comfort", obj.COMFORT_KINDS), ("observation", OBSERVATION_KINDS), ("backend", BACKENDS)):
        if args[key] not in allowed:
            raise BuildingEnvError(f"{ENV_ID}: {key}={args[key]!r}; choose one of {', '.join(allowed)}")
    if not isinstance(args["strict_calibration"], bool):
        raise BuildingEnvError(f"{ENV_ID}: strict_calibration={args['strict_calibration']!r}; pass True or False")
    if args["render_mode"] is not None and args["render_mode"] not in RENDER_MODES:
        raise BuildingEnvError(
            f"{ENV_ID}: render_mode={args['render_mode']!r}; choose None or one of {', '.join(RENDER_MODES)} "
            "(gymnasium.make turns 'human' into 'rgb_array' shown in a window)"
        )
    return args


def whole(name: str, value: Any, minimum: int = 1) -> int:
    """``value`` as an int of at least ``minimum`` (an int, or a float with no fraction); else one clear error."""
    whole = isinstance(value, numbers.Integral) or (isinstance(value, float) and value.is_integer())
    if isinstance(value, bool) or not whole or int(value) < minimum:
        raise BuildingEnvError(f"{ENV_ID}: {name}={value!r}; give a whole number, {minimum} or more")
    return int(value)


def weather_years(value: Any) -> list[int]:
    """The weather years ``weather_years=`` names: a whole number N gives years ``0..N-1``, a list its years
    (0 is the site's own weather file, k >= 1 the k-th morph of it, :func:`buildenv.weather.morph.weather_year`);
    else one clear error."""
    if isinstance(value, (list, tuple)):
        years = [whole("weather_years", v, 0) for v in value] if value else []
        if not years or len(set(years)) != len(years):
            raise BuildingEnvError(f"{ENV_ID}: weather_years={value!r}; give distinct year numbers, 0 or more")
        return sorted(years)
    return list(range(whole("weather_years", value)))


def finite(name: str, value: Any, minimum: float | None = None) -> float:
    """``value`` as a finite float (of at least ``minimum``); else one clear error."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or (minimum is not None and x < minimum):
        at_least = "" if minimum is None else f" >= {minimum:g}"
        raise BuildingEnvError(f"{ENV_ID}: {name}={value!r}; give a finite number{at_least}")
    return x


def as_autoreset_mode(value: Any) -> AutoresetMode:
    """An :class:`gymnasium.vector.AutoresetMode` from itself, its value (``"NextStep"``) or its name."""
    if isinstance(value, AutoresetMode):
        return value
    for mode in AutoresetMode:
        if isinstance(value, str) and value.lower().replace("_", "") in (
            mode.value.lower(),
            mode.name.lower().replace("_", ""),
        ):
            return mode
    choices = ", ".join(f"AutoresetMode.{m.name}" for m in AutoresetMode)
    raise BuildingEnvError(f"{ENV_ID}: autoreset_mode={value!r}; choose one of {choices}")


def with_length(spec, length: int):
    """``spec`` with ``max_episode_steps`` filled in with the episode length where gymnasium left it None."""
    if spec is not None and spec.max_episode_steps is None:
        spec = dataclasses.replace(spec, max_episode_steps=int(length))
    return spec


def split_weeks(n_weeks: int, split: str | list[int], site: str = "") -> list[int]:
    """Weeks of the year in a split: ``test`` is every fourth block of four weeks (weeks 12-15, 28-31 and
    44-47), ``train`` the others, ``all`` every week; a list of week indices is taken as given. ``site`` (its name)
    is what an error names.

    Raises:
        BuildingEnvError: an unknown split, or an empty list or one with indices outside ``0..n_weeks - 1``.
    """
    on = f" on site {site!r}" if site else ""
    if not isinstance(split, str):
        weeks = sorted({int(w) for w in split})
        bad = [w for w in weeks if not 0 <= w < n_weeks]
        if bad or not weeks:
            raise BuildingEnvError(f"{ENV_ID}: weeks={list(split)}{on}: give week indices in 0..{n_weeks - 1}")
        return weeks
    if split not in WEEK_SPLITS:
        raise BuildingEnvError(
            f"{ENV_ID}: weeks={split!r}{on}: choose one of {', '.join(WEEK_SPLITS)} or a list of week indices"
        )
    test = [k for k in range(n_weeks) if (k // 4) % 4 == 3]
    return {"test": test, "train": [k for k in range(n_weeks) if k not in test], "all": list(range(n_weeks))}[split]
