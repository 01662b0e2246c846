"""``BuildingWeek-v0``: choose a week of building-management settings for a calibrated building.

``import buildenv`` registers it; then ``gymnasium.make("BuildingWeek-v0")`` runs the shipped metamodel on
the shipped, calibrated default site and ``gymnasium.make_vec("BuildingWeek-v0", num_envs=N)`` gives the
native batched version (one metamodel call for all N environments), with gymnasium's three autoreset modes.
Both render the last week (``render_mode="rgb_array"`` or ``"ansi"``, :mod:`buildenv.env.render`), pickle and
deep-copy at any time (the traced metamodel is left out and traced again on first use) and raise
:class:`ResetNeededError` (a ``gymnasium.error.ResetNeeded``) when stepped before ``reset`` or after the end.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime as dt
import math
import numbers
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from buildenv import catalogue as cat
from buildenv.env import actions as act
from buildenv.env import contexts as ctx
from buildenv.env import objectives as obj
from buildenv.env import render as rnd
from buildenv.env import tariff as tar
from buildenv.env.observations import BOUND, OBSERVATION_KINDS, forecast, observation_size, observe
from buildenv.env.registration import ENV_ID
from buildenv.errors import BuildingEnvError
from buildenv.sites.week_simulator import SiteModel

DEFAULT_SITE = Path(__file__).resolve().parents[1] / "data" / "sites" / "default"
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
    "price": None,
    "render_mode": None,
}
RENDER_MODES = ("rgb_array", "ansi")
VECTOR_ARGUMENTS = ("num_envs", "autoreset_mode", "max_episode_steps")


class ResetNeededError(BuildingEnvError, gym.error.ResetNeeded):
    """``step()`` or ``render()`` before ``reset()``, or ``step()`` after the episode ended: gymnasium's
    ``ResetNeeded`` (what its ``OrderEnforcing`` wrapper raises) and a :class:`BuildingEnvError`."""


def _whole(name: str, value: Any, minimum: int = 1) -> int:
    """``value`` as an int of at least ``minimum`` (an int, or a float with no fraction); else one clear error."""
    whole = isinstance(value, numbers.Integral) or (isinstance(value, float) and value.is_integer())
    if isinstance(value, bool) or not whole or int(value) < minimum:
        raise BuildingEnvError(f"{ENV_ID}: {name}={value!r}; give a whole number, {minimum} or more")
    return int(value)


def _finite(name: str, value: Any, minimum: float | None = None) -> float:
    """``value`` as a finite float (of at least ``minimum``); else one clear error."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or (minimum is not None and x < minimum):
        at_least = "" if minimum is None else f" >= {minimum:g}"
        raise BuildingEnvError(f"{ENV_ID}: {name}={value!r}; give a finite number{at_least}")
    return x


def _autoreset_mode(value: Any) -> AutoresetMode:
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


def _with_length(spec, length: int):
    """``spec`` with ``max_episode_steps`` filled in with the episode length where gymnasium left it None."""
    if spec is not None and spec.max_episode_steps is None:
        spec = dataclasses.replace(spec, max_episode_steps=int(length))
    return spec


def split_weeks(n_weeks: int, split: str | list[int]) -> list[int]:
    """Weeks of the year in a split: ``test`` is every fourth block of four weeks (weeks 12-15, 28-31 and
    44-47), ``train`` the others, ``all`` every week; a list of week indices is taken as given."""
    if not isinstance(split, str):
        weeks = sorted({int(w) for w in split})
        bad = [w for w in weeks if not 0 <= w < n_weeks]
        if bad or not weeks:
            raise BuildingEnvError(f"weeks={list(split)}: give week indices in 0..{n_weeks - 1}")
        return weeks
    if split not in WEEK_SPLITS:
        raise BuildingEnvError(f"weeks={split!r}: choose one of {', '.join(WEEK_SPLITS)} or a list of week indices")
    test = [k for k in range(n_weeks) if (k // 4) % 4 == 3]
    return {"test": test, "train": [k for k in range(n_weeks) if k not in test], "all": list(range(n_weeks))}[split]


class _Building:
    """What the single and the vector environment share: arguments, spaces and the calibrated site, or the sites of
    a context set (:mod:`buildenv.env.contexts`), one :class:`_Site` each, all on one loaded metamodel."""

    def __init__(self, extra: tuple[str, ...] = (), **kwargs: Any) -> None:
        unknown = sorted(set(kwargs) - set(ARGUMENTS))
        if unknown:
            raise BuildingEnvError(
                f"{ENV_ID}: unknown argument(s) {', '.join(unknown)}; allowed: {', '.join((*ARGUMENTS, *extra))}"
            )
        args = {**ARGUMENTS, **kwargs}
        self.args = args
        for key, allowed in (("comfort", obj.COMFORT_KINDS), ("observation", OBSERVATION_KINDS), ("backend", BACKENDS)):
            if args[key] not in allowed:
                raise BuildingEnvError(f"{ENV_ID}: {key}={args[key]!r}; choose one of {', '.join(allowed)}")
        if args["render_mode"] is not None and args["render_mode"] not in RENDER_MODES:
            raise BuildingEnvError(
                f"{ENV_ID}: render_mode={args['render_mode']!r}; choose None or one of {', '.join(RENDER_MODES)} "
                "(gymnasium.make turns 'human' into 'rgb_array' shown in a window)"
            )
        self.render_mode: str | None = args["render_mode"]
        self.episode_weeks = _whole("episode_weeks", args["episode_weeks"])
        self.comfort_weight = _finite("comfort_weight", args["comfort_weight"], 0.0)
        self.target_c = _finite("target_temperature_c", args["target_temperature_c"])
        self.band_k = _finite("comfort_band_k", args["comfort_band_k"], 0.0)
        self.forecast_noise = _finite("forecast_noise", args["forecast_noise"], 0.0)
        self.tariff = tar.tariff_from(args["price"], ENV_ID)
        chosen, self.many = ctx.resolve(args["site"], args["sites"])
        from buildenv.metamodel.surrogate import load_metamodel

        self.surrogate = load_metamodel(args["metamodel"])  # loaded once, shared by every site
        self.contexts = [_Site(self, context) for context in chosen]
        self.names = tuple(c.name for c in self.contexts)
        ctx.check_alike([(c.name, c.actions.controllable) for c in self.contexts])
        n_obs = observation_size(args["observation"])
        self.observation_space = spaces.Box(-BOUND, BOUND, (n_obs,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.actions.size,), np.float32)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the metamodel's traced module and worker threads (neither pickles); every site keeps
        sharing one metamodel, which the copy traces again on its first call (same outputs)."""
        state = self.__dict__.copy()
        surrogate = copy.copy(self.surrogate)
        surrogate._runner = None
        surrogate._pool = None
        state["surrogate"] = surrogate
        state["contexts"] = [c.with_surrogate(surrogate) for c in self.contexts]
        return state

    @property
    def model(self) -> SiteModel:
        """The first site's model (the only one of a single-site environment)."""
        return self.contexts[0].model

    @property
    def actions(self) -> act.ActionMap:
        """The first site's action map (every site's acts on the same settings; limits may differ)."""
        return self.contexts[0].actions

    def index(self, site: Any) -> int:
        """The index of a site given by name or index; else one clear error."""
        if isinstance(site, numbers.Integral) and not isinstance(site, bool) and 0 <= int(site) < len(self.names):
            return int(site)
        if isinstance(site, str) and site in self.names:
            return self.names.index(site)
        raise BuildingEnvError(
            f"{ENV_ID}: site {site!r} is not one of the environment's sites ({ctx.listing(list(self.names))}); "
            f"give a name or an index 0..{len(self.names) - 1}"
        )

    def pick(self, rng: np.random.Generator, options: dict | None) -> tuple[int, int]:
        """The site and first week of a new episode: ``options["site"]`` and ``options["week"]`` if given, else
        drawn from ``rng`` (a context set's site uniformly, then the week; a single site draws the week only)."""
        if options and "site" in options:
            site = self.index(options["site"])
        else:
            site = int(rng.integers(len(self.contexts))) if self.many else 0
        return site, self.contexts[site].pick_week(rng, options)

    def check_action(self, action: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
        """``action`` as an array of ``shape``; else one clear error."""
        a = np.asarray(action)
        if a.shape != shape or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise BuildingEnvError(
                f"{ENV_ID}: {what} takes an action of shape {shape} ({self.actions.size} = 7 days x "
                f"{len(self.actions.controllable)} settings), got {a.dtype} {a.shape}"
                + ("; evaluate() scores several" if what == "step()" else "")
            )
        return a

    def frame(
        self, site: int, week: int, step: int, scores: dict[str, np.ndarray] | None = None, row: int = 0
    ) -> rnd.WeekFrame:
        """What ``render()`` shows of ``week`` of site ``site`` (:meth:`_Site.frame`)."""
        return self.contexts[site].frame(week, step, scores, row)

    def render(self, frame: rnd.WeekFrame | None) -> np.ndarray | str | None:
        """``frame`` drawn in the render mode (a warning and None without one, as gymnasium's environments)."""
        if self.render_mode is None:
            gym.logger.warn(
                f"{ENV_ID}: render() without a render mode; make the environment with "
                f"render_mode= one of {', '.join(RENDER_MODES)}"
            )
            return None
        if frame is None:
            raise ResetNeededError(f"{ENV_ID}: call reset() before render()")
        return rnd.rgb(frame) if self.render_mode == "rgb_array" else rnd.ansi(frame)


class _Site:
    """One calibrated site of the environment: its model, actions and weeks, and scoring on it under the
    environment's arguments."""

    def __init__(self, shared: _Building, context: ctx.Context) -> None:
        self.args, self.tariff, self.episode_weeks = shared.args, shared.tariff, shared.episode_weeks
        self.comfort_weight, self.target_c, self.band_k = shared.comfort_weight, shared.target_c, shared.band_k
        self.forecast_noise = shared.forecast_noise
        args = self.args
        self.name = context.name
        self.label = context.name if shared.many else ""  # what info and render name: nothing for a single site
        on = f" on site {self.name!r}" if self.label else ""
        self.site = _load_site(context.source)
        self.model = SiteModel.from_site(self.site, shared.surrogate)
        occupants = float(self.model.theta[cat.THETA_NAMES.index("occupant_density_per_m2")])
        self.actions = act.ActionMap.for_site(self.site, shared.surrogate.domain, self.model.historical, occupants)
        self.occupied = self.model.occupied_hours()
        self.pool = split_weeks(self.model.weeks, args["weeks"])
        pool = set(self.pool)
        self.starts = [k for k in self.pool if all(k + j in pool for j in range(self.episode_weeks))]
        if not self.starts:
            raise BuildingEnvError(
                f"{ENV_ID}: no {self.episode_weeks} consecutive weeks in weeks={args['weeks']!r}{on}"
            )
        if args["backend"] == "energyplus":
            from buildenv.env.energyplus_backend import reference_building

            reference_building(self.site)  # fail now, not at the first step
        self._historical: dict[int, tuple[float, float, float]] = {}

    def with_surrogate(self, surrogate) -> _Site:
        """A shallow copy whose model runs ``surrogate`` (for pickling)."""
        twin = copy.copy(self)
        twin.model = copy.copy(self.model)
        twin.model.surrogate = surrogate
        return twin

    # ------------------------------------------------------------------ simulation and scoring
    def outputs(self, settings: np.ndarray, weeks: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """Hourly outputs ``(N, 168, 8)`` from the backend."""
        if self.args["backend"] == "metamodel":
            return self.model.simulate(settings, weeks, previous)
        from buildenv.env.energyplus_backend import as_outputs, run_weeks

        t, q = run_weeks(
            self.site, [self.model.week_starts[w] for w in weeks], settings, previous, self.model.historical
        )
        return as_outputs(t, q)

    def historical(self, weeks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Energy (Wh/m2 per hour), comfort (K) and cost (currency; NaN without a tariff) of the historical
        settings in ``weeks``, cached."""
        missing = sorted({int(w) for w in weeks} - set(self._historical))
        if missing:
            out = self.outputs(
                np.broadcast_to(self.model.historical, (len(missing), *self.model.historical.shape)),
                np.array(missing),
                None,
            )
            costs = self.cost(obj.hvac_energy_hourly(out), np.array(missing))
            for w, e, c, k in zip(missing, obj.hvac_energy(out), self.comfort(out), costs):
                self._historical[w] = (float(e), float(c), float(k))
        rows = np.array([self._historical[int(w)] for w in weeks]).reshape(len(weeks), 3)
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def prices(self, weeks: np.ndarray) -> np.ndarray:
        """Hourly prices ``(N, 168)`` (currency per kWh) of the tariff on the weeks' dates."""
        return np.stack([self.tariff.hourly(self.model.week_starts[int(w)]) for w in weeks]).reshape(len(weeks), -1)

    def cost(self, hvac_wh_m2: np.ndarray, weeks: np.ndarray) -> np.ndarray:
        """HVAC energy cost (currency) of hourly energy ``(N, 168)`` in ``weeks`` ``(N,)``; NaN without a tariff."""
        if self.tariff is None:
            return np.full(len(weeks), np.nan)
        return tar.weekly_cost(hvac_wh_m2, self.prices(weeks), self.model.floor_area_m2)

    def comfort(self, outputs: np.ndarray) -> np.ndarray:
        """Comfort term (K) of outputs ``(N, 168, 8)``."""
        return obj.comfort_deviation(
            obj.indoor_temperature(outputs),
            self.occupied,
            self.target_c,
            self.args["comfort"],
            float(self.args["comfort_band_k"]),
        )

    def score(
        self, actions: np.ndarray, weeks: np.ndarray, previous: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """Everything ``step`` and ``evaluate`` report for actions ``(N, 7 x k)`` in weeks ``(N,)``."""
        settings, clipped = self.actions.decode(actions)
        weeks = np.asarray(weeks, dtype=int)
        out = self.outputs(settings, weeks, previous)
        energy = obj.hvac_energy(out)
        hourly = obj.hvac_energy_hourly(out)
        comfort = self.comfort(out)
        hist_energy, hist_comfort, hist_cost = self.historical(weeks)
        ratio = obj.energy_ratio(energy, hist_energy)
        term = ratio
        priced: dict[str, np.ndarray] = {}
        if self.tariff is not None:
            prices = self.prices(weeks)
            cost = tar.weekly_cost(hourly, prices, self.model.floor_area_m2)
            floor = tar.weekly_cost(np.full_like(prices, obj.ENERGY_FLOOR_WH_M2), prices, self.model.floor_area_m2)
            term = obj.cost_ratio(cost, hist_cost, floor)
            priced = {"cost": cost, "cost_historical": hist_cost}
        kwh = cat.HOURS_PER_WEEK * self.model.floor_area_m2 / 1000.0
        return {
            "reward": -(term + self.comfort_weight * comfort),
            "energy_term": term,
            "comfort_k": comfort,
            "energy_wh_m2": energy,
            "energy_kwh": energy * kwh,
            "energy_historical_kwh": hist_energy * kwh,
            **priced,
            "comfort_historical_k": hist_comfort,
            "savings_percent": 100.0 * (1.0 - ratio),
            "mean_temperature_occupied_c": obj.indoor_temperature(out)[:, self.occupied].mean(-1),
            "clipped_components": clipped,
            "settings": settings,
            "temperature_c": obj.indoor_temperature(out),
            "hvac_wh_m2": hourly,
        }

    def observe(self, weeks: np.ndarray, rngs: list[np.random.Generator]) -> np.ndarray:
        """Observations ``(N, obs)`` of the weeks' starts; with ``forecast_noise`` the weather in row i is a
        forecast drawn from ``rngs[i]`` (:func:`buildenv.env.observations.forecast`), else nothing is drawn."""
        weeks = np.asarray(weeks, dtype=int)
        weather = forecast(self.model.weather(weeks), self.forecast_noise, rngs)
        return observe(weather, weeks, self.model.occupancy, self.model.theta, self.args["observation"]).astype(
            np.float32, copy=False
        )

    def pick_week(self, rng: np.random.Generator, options: dict | None) -> int:
        """The first week of a new episode: ``options["week"]`` if given (it must be a valid start), else drawn."""
        if options and "week" in options:
            week = int(options["week"])
            if week not in self.starts:
                raise BuildingEnvError(
                    f"{ENV_ID}: week {week} cannot start an episode of weeks="
                    f"{self.args['weeks']!r}{' on site ' + repr(self.label) if self.label else ''} "
                    f"(valid starts: {self.starts})"
                )
            return week
        return int(self.starts[int(rng.integers(len(self.starts)))])

    def week_info(self, week: int) -> dict[str, Any]:
        """``{"week", "week_start"}`` of a week, and ``"site"`` (its name) in a context set."""
        info = {"week": int(week), "week_start": self.model.week_starts[int(week)].isoformat()}
        if self.label:
            info["site"] = self.label
        return info

    def frame(self, week: int, step: int, scores: dict[str, np.ndarray] | None = None, row: int = 0) -> rnd.WeekFrame:
        """What ``render()`` shows of ``week``: the week ahead (``scores`` None) or row ``row`` of its scores."""
        outdoor = self.model.weather(np.array([week]))[0][:, cat.WEATHER_NAMES.index("TAMB")]
        common = {
            "week": int(week),
            "monday": self.model.week_starts[int(week)],
            "step": int(step),
            "episode_weeks": self.episode_weeks,
            "occupied": self.occupied,
            "target_c": self.target_c,
            "band_k": self.band_k if self.args["comfort"] == "band" else 0.0,
            "outdoor_c": np.asarray(outdoor, float),
            "comfort": self.args["comfort"],
            "site": self.label,
        }
        if scores is None:
            return rnd.WeekFrame(**common)
        from buildenv.schedules import hourly_schedules

        hourly = hourly_schedules(scores["settings"][row], self.model.occupancy)
        keys = ("reward", "energy_term", "comfort_k", "energy_kwh", "energy_historical_kwh", "comfort_historical_k")
        return rnd.WeekFrame(
            **common,
            temperature_c=np.asarray(scores["temperature_c"][row], float),
            hvac_wh_m2=np.asarray(scores["hvac_wh_m2"][row], float),
            heating_setpoint_c=hourly["heating_setpoint_c"][0],
            cooling_setpoint_c=hourly["cooling_setpoint_c"][0],
            scores={k: float(scores[k][row]) for k in (*keys, "savings_percent", "mean_temperature_occupied_c")},
        )


def _load_site(site):
    from buildenv.sites import Site, load_site

    if isinstance(site, Site):
        return site
    return load_site(DEFAULT_SITE if site in (None, "default") else site)


_SERIES = ("temperature_c", "hvac_wh_m2")  # hourly series: in evaluate()'s result, not in step infos


def _single(scores: dict[str, np.ndarray], i: int) -> dict[str, Any]:
    """The step info of environment ``i`` from batched scores (physical units)."""
    info = {k: (v[i] if k == "settings" else float(v[i])) for k, v in scores.items() if k not in _SERIES}
    info["clipped_components"] = int(scores["clipped_components"][i])
    info["reward_vector"] = np.array([-scores["energy_term"][i], -scores["comfort_k"][i]], dtype=np.float32)
    return info


class BuildingWeekEnv(gym.Env):
    """Choose one week of building-management (BMS) settings for a calibrated office building.

    ## Description
    The building is a calibrated site (``buildenv calibrate``) simulated by a neural metamodel of EnergyPlus;
    by default the shipped site (a DOE medium office in Chicago) and metamodel. Each step applies a whole
    week of settings and returns its energy and comfort, as an operator plans a week ahead from the forecast
    (Cohen et al., "End-to-end deep metamodeling to calibrate and optimize energy loads").

    ## Action Space
    ``Box(-1, 1, (7 x k,), float32)``: the k settings of :data:`buildenv.catalogue.SETTINGS` the site's BMS can
    change (``[bms] controllable`` in ``site.toml``; all 12, ``(84,)``, by default, as on the default site) for
    each day Monday..Sunday, day-major (``env.unwrapped.action_names``), each mapped linearly onto its catalogue
    range within the site's limits and what the metamodel was trained on (:class:`buildenv.env.actions.ActionMap`)
    and snapped to its step; the other settings stay at the site's historical values.
    ``env.unwrapped.decode(action)`` gives the physical ``(7, 12)`` settings, ``encode(settings)``
    the action. Components outside [-1, 1] are clipped and counted in ``info["clipped_components"]``; NaN or
    infinite ones raise :class:`buildenv.errors.BuildingEnvError`.

    ## Observation Space
    ``Box(-10, 10, (77,), float32)`` (``observation="compact"``): the week's daily weather forecast, the
    occupancy schedule, the week of the year (sine, cosine) and the calibrated building parameters, scaled to
    order one; ``"forecast"`` appends the hourly forecast, ``(1421,)`` (:mod:`buildenv.env.observations`).

    The forecast is the true week's weather unless ``forecast_noise`` (K, default 0) is given: then both its
    daily summary and its hourly part are a forecast drawn from the environment's ``np_random`` each time a
    week is observed (reproducible under the seed; the vector env draws sub-environment i's from its own
    generator, as ``SyncVectorEnv`` does): the outdoor temperature error is a random walk over the week's
    hours whose standard deviation grows with lead time to ``forecast_noise * sqrt((d + 1) / 7)`` at the end
    of day d (``forecast_noise`` on Sunday); irradiance and wind speed get multiplicative errors
    (``IRRADIANCE_ERROR_PER_K``, ``WIND_ERROR_PER_K`` = 0.15 per K, clipped at 0), humidity follows the
    temperature error at the true vapour pressure plus its own error (5 %-points per K), clipped into
    [0, 100] (:func:`buildenv.env.observations.forecast`). The reward always uses the true weather.

    ## Rewards
    ``-(energy_term + comfort_weight * comfort_term)``. ``energy_term`` (the paper's Delta_Q^opt): the week's
    mean hourly HVAC energy over the same week's under the historical settings (1.0 = as today).
    ``comfort_term`` (Delta_T^opt, K): deviation from ``target_temperature_c`` over the occupied hours, by
    ``comfort`` (:mod:`buildenv.env.objectives`). ``info`` adds physical values (``energy_kwh``,
    ``energy_historical_kwh``, ``savings_percent``, ``comfort_k``, ``comfort_historical_k``,
    ``mean_temperature_occupied_c``), the decoded ``settings`` and ``reward_vector = [-energy, -comfort]``.

    With a time-of-use tariff, ``price=`` a preset (``"tou"``, ``"flat"``) or a dict such as ``{"peak": 0.25,
    "offpeak": 0.10, "peak_hours": (8, 20), "peak_days": "weekdays"}`` (currency per kWh,
    :mod:`buildenv.env.tariff`), ``energy_term`` is the week's HVAC energy cost at the hourly prices of the
    week's dates over the same week's cost under the historical settings (1.0 = today's cost; the historical
    cost is floored at the cost of 0.5 Wh/m2 in every hour); ``info`` adds ``cost`` and ``cost_historical``
    (currency) and ``savings_percent`` stays the energy saved.

    ## Starting State
    ``reset(seed=...)`` draws the first week uniformly from the valid starts in ``weeks``;
    ``reset(options={"week": k})`` picks week ``k``. The week before runs the historical settings.
    With several sites (``site=`` a list or a library) it first draws the episode's site uniformly
    (``options={"site": name}`` picks one), named in ``info["site"]`` and by ``render``. Deterministic given the
    seed.

    ## Episode End
    Terminates after ``episode_weeks`` consecutive weeks (default 1: one step); never truncated (unless
    ``gymnasium.make(..., max_episode_steps=m)`` adds a shorter time limit). ``env.spec.max_episode_steps`` is
    ``episode_weeks``. ``step`` before ``reset`` or after the end raises :class:`ResetNeededError` (a
    ``gymnasium.error.ResetNeeded``); an action of another shape than the action space's, a
    :class:`BuildingEnvError`.

    ## Rendering
    ``render_mode="rgb_array"``: the last simulated week as an ``(540, 960, 3)`` ``uint8`` picture (indoor and
    outdoor temperature against the comfort target and the setpoints, HVAC energy, occupied hours shaded, the
    days' dates); ``"ansi"``: a few lines (week, energy against the historical settings, comfort, reward). Just
    after ``reset`` it shows the week ahead (the outdoor forecast, nothing simulated yet); before ``reset`` it
    raises :class:`ResetNeededError` (as gymnasium's ``OrderEnforcing`` does).

    ## Arguments
    ``site`` ("default", a site folder or a calibrated :class:`buildenv.sites.Site`; or many: a list of them,
    "library" or a library folder, :mod:`buildenv.env.contexts`), ``sites`` ("all"; a library's "train" or
    "test" part; or a list of site names), ``metamodel``
    ("default" or a checkpoint path), ``comfort_weight`` (1.0 per K), ``target_temperature_c`` (22.5 degC),
    ``comfort`` ("rms", "band", "mean_abs"), ``comfort_band_k`` (1.0 K), ``observation`` ("compact"),
    ``episode_weeks`` (1), ``weeks`` ("train"; "test" is weeks 12-15, 28-31 and 44-47; "all"; or a list),
    ``backend`` ("metamodel", or "energyplus": the site's reference building, for verification),
    ``forecast_noise`` (0.0 K: the true weather; see Observation Space), ``price`` (None: relative energy; see
    Rewards), ``render_mode`` (None, "rgb_array", "ansi"). Unknown arguments and bad values (``comfort_weight=nan``,
    ``episode_weeks=2.7``, ...) are rejected with one line each. ``env.unwrapped.evaluate(actions)`` scores
    ``(N, 7 x k)`` actions in one call.

    ## Version History
    * v0: first version.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 2}

    def __init__(self, **kwargs: Any) -> None:
        self._b = _Building(**kwargs)
        self.observation_space = self._b.observation_space
        self.action_space = self._b.action_space
        self.render_mode = self._b.render_mode
        self._site = 0  # index of the episode's site in a context set (0 before reset)
        self._week: int | None = None
        self._step_in_episode = 0
        self._previous: np.ndarray | None = None
        self._done = False
        self._obs: np.ndarray | None = None
        self._last: tuple[int, int, int, dict[str, np.ndarray] | None] | None = None  # what render() shows

    @property
    def spec(self):
        """The gymnasium ``EnvSpec`` it was made with; ``max_episode_steps`` is ``episode_weeks`` unless a time
        limit says otherwise."""
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, spec) -> None:
        self._spec = _with_length(spec, self._b.episode_weeks)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode on a week drawn from the site's year (see the class docstring)."""
        super().reset(seed=seed)
        self._site, self._week = self._b.pick(self.np_random, options)
        self._step_in_episode = 0
        self._previous = None
        self._done = False
        self._last = (self._site, self._week, 0, None)
        self._obs = self._here.observe([self._week], [self.np_random])[0]
        return self._obs.copy(), self._here.week_info(self._week)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Apply one week of settings; returns the next week's observation and this week's reward.

        Raises:
            ResetNeededError: before ``reset()`` or after the episode terminated.
            BuildingEnvError: an action not of the action space's shape, or with a NaN or infinite component.
        """
        if self._week is None:
            raise ResetNeededError(f"{ENV_ID}: call reset() before step()")
        if self._done:
            raise ResetNeededError(
                f"{ENV_ID}: the episode terminated after {self._b.episode_weeks} week(s); call reset() before step()"
            )
        action = self._b.check_action(action, self.action_space.shape, "step()")
        prev = None if self._previous is None else self._previous[None]
        scores = self._here.score(action[None], np.array([self._week]), prev)
        info = {**_single(scores, 0), **self._here.week_info(self._week)}
        self._previous = scores["settings"][0]
        self._step_in_episode += 1
        self._last = (self._site, self._week, self._step_in_episode, scores)
        terminated = self._step_in_episode >= self._b.episode_weeks
        self._done = terminated
        if not terminated:  # the next week's forecast; a finished episode returns its last week's observation
            self._week += 1
            self._obs = self._here.observe([self._week], [self.np_random])[0]
        return self._obs.copy(), float(scores["reward"][0]), terminated, False, info

    def render(self) -> np.ndarray | str | None:
        """The last simulated week (the week ahead just after ``reset``) as an ``(540, 960, 3)`` ``uint8``
        picture (``render_mode="rgb_array"``) or text (``"ansi"``); see Rendering in the class docstring.

        Raises:
            ResetNeededError: before ``reset()``.
        """
        frame = None if self._last is None else self._b.frame(*self._last)
        return self._b.render(frame)

    # ------------------------------------------------------------------ helpers for people and optimisers
    def evaluate(
        self, actions: np.ndarray, week: int | None = None, site: str | int | None = None
    ) -> dict[str, np.ndarray]:
        """Score many weekly settings on one week in one batched call (the environment's state is unchanged).

        Args:
            actions: ``(N, 7 x k)`` actions (see Action Space).
            week: week of the year, after a week under the historical settings; default the current
                episode's week, after the settings the episode applied the week before (if any).
            site: with several sites, the site (name or index) to score on; default the current episode's (another
                site needs ``week``).
        Returns:
            ``{"reward", "energy_term", "comfort_k", "energy_kwh", "energy_historical_kwh", "savings_percent",
            "comfort_historical_k", "mean_temperature_occupied_c", "energy_wh_m2", "clipped_components"}``,
            each ``(N,)``; ``"settings"`` ``(N, 7, 12)``; the hourly ``"temperature_c"`` (degC) and
            ``"hvac_wh_m2"`` (Wh/m2 in the hour) ``(N, 168)``; with ``price=``, also ``"cost"`` and
            ``"cost_historical"`` (currency) ``(N,)``, and ``"energy_term"`` is the cost ratio.
        """
        actions = np.atleast_2d(np.asarray(actions))
        if site is None and self._week is None and self._b.many:
            raise BuildingEnvError(
                f"{ENV_ID}: call reset() or pass site= to evaluate() (sites: {ctx.listing(self._b.names)})"
            )
        here = self._site if site is None else self._b.index(site)
        prev = None
        if week is None:
            if self._week is None:
                raise BuildingEnvError(f"{ENV_ID}: call reset() or pass week= to evaluate()")
            if here != self._site:
                raise BuildingEnvError(
                    f"{ENV_ID}: evaluate(site={site!r}) scores another site than the episode's; pass week= too"
                )
            week = self._week
            if self._previous is not None:  # mid-episode: the week after the settings just applied
                prev = np.broadcast_to(self._previous, (len(actions), *self._previous.shape))
        return self._b.contexts[here].score(actions, np.full(len(actions), int(week)), prev)

    def decode(self, action: np.ndarray) -> np.ndarray:
        """Physical settings ``(..., 7, 12)`` of actions ``(..., 7 x k)`` (:meth:`.ActionMap.decode`)."""
        return self._here.actions.decode(action)[0]

    def encode(self, settings: np.ndarray) -> np.ndarray:
        """Actions ``(..., 7 x k)`` of physical settings ``(..., 7, 12)`` (the controllable ones)."""
        return self._here.actions.encode(settings)

    @property
    def action_names(self) -> tuple[str, ...]:
        """Names of the action components (``heating_comfort_c_monday``, ...)."""
        return self._b.actions.names()

    @property
    def site(self):
        """The :class:`buildenv.sites.Site` the environment runs (the current episode's in a context set)."""
        return self._here.site

    @property
    def site_name(self) -> str:
        """The name of the current episode's site (its folder's; ``"default"`` for the shipped site)."""
        return self._here.name

    @property
    def site_names(self) -> tuple[str, ...]:
        """The names of the environment's sites (one, or a context set's)."""
        return self._b.names

    @property
    def arguments(self) -> dict[str, Any]:
        """The environment's arguments (defaults filled in)."""
        return dict(self._b.args)

    @property
    def historical_action(self) -> np.ndarray:
        """The action nearest the site's historical settings ``(7 x k,)`` (a historical value outside its action
        range gets the nearest end; the energy term is measured against the historical settings themselves)."""
        return self._here.actions.encode(self._here.model.historical)

    @property
    def week(self) -> int | None:
        """The current week of the year (None before reset)."""
        return self._week

    @property
    def weeks(self) -> list[int]:
        """Weeks an episode can start on (on the current episode's site)."""
        return list(self._here.starts)

    @property
    def site_model(self) -> SiteModel:
        """The calibrated site model (theta, occupancy, weather, metamodel) of the current episode's site."""
        return self._here.model

    @property
    def occupied_hours(self) -> np.ndarray:
        """``(168,)`` booleans: the occupied hours comfort is counted over."""
        return self._here.occupied

    def week_start(self, week: int) -> dt.date:
        """Monday of a week of the year (of the current episode's site)."""
        return self._here.model.week_starts[int(week)]

    @property
    def _here(self) -> _Site:
        """The current episode's site (the first before reset)."""
        return self._b.contexts[self._site]


def _vector_info(values: dict[str, np.ndarray], rows: np.ndarray, n: int) -> dict[str, np.ndarray]:
    """A gymnasium vector info (``{key: (n, ...) array, "_key": (n,) mask}``, as ``VectorEnv._add_info`` lays
    it out) of per-row ``values`` (``{key: (len(rows), ...)}``) for sub-environments ``rows``."""
    info: dict[str, np.ndarray] = {}
    for key, value in values.items():
        value = np.asarray(value)
        if value.dtype == object:
            array = np.full(n, None, dtype=object)
        else:
            array = np.zeros((n, *value.shape[1:]), dtype=value.dtype)
        array[rows] = value
        mask = np.zeros(n, dtype=bool)
        mask[rows] = True
        info[key], info[f"_{key}"] = array, mask
    return info


def _masked(info: dict[str, Any], keep: np.ndarray) -> dict[str, Any]:
    """The entries of vector info ``info`` of the sub-environments ``keep`` (a boolean mask); keys none of them
    has are dropped, as gymnasium's vector envs never add them."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        mask = info[f"_{key}"] & keep
        if not mask.any():
            continue
        array = np.array(value, copy=True)
        array[~mask] = None if array.dtype == object else 0
        out[key], out[f"_{key}"] = array, mask
    return out


def _merged(first: dict[str, Any], second: dict[str, Any]) -> dict[str, Any]:
    """Vector info of two infos of different sub-environments (the second's entries win where both have one)."""
    out = dict(first)
    for key, value in second.items():
        if key.startswith("_"):
            continue
        mask = second[f"_{key}"]
        if key in out:
            array = np.array(out[key], copy=True)
            array[mask] = value[mask]
            out[key], out[f"_{key}"] = array, out[f"_{key}"] | mask
        else:
            out[key], out[f"_{key}"] = value, mask
    return out


class BuildingWeekVectorEnv(VectorEnv):
    """N copies of :class:`BuildingWeekEnv` stepped in one metamodel call (``gymnasium.make_vec``).

    Each sub-environment draws its weeks (and, with ``forecast_noise``, its forecast errors) with its own
    generator, seeded as ``SyncVectorEnv`` seeds its copies (``reset(seed=s)``: sub-environment i gets ``s + i``;
    ``reset(seed=[s0, s1, ...])``: one each, None keeps the generator), so it draws the same weeks and forecasts
    as ``gymnasium.make_vec(..., vectorization_mode="sync")``; with several sites each draws its site first, as the
    single environment does, and a step calls each site's model once, on the rows of the sub-environments on it.
    ``options["week"]`` (``options["site"]``) puts every reset sub-environment on that week (site);
    ``options["reset_mask"]`` resets only those marked.

    Finished episodes reset as ``autoreset_mode`` says (https://farama.org/Vector-Autoreset-Mode):

    * ``AutoresetMode.NEXT_STEP`` (default, what ``gymnasium.wrappers.vector`` observation wrappers need): the
      step that finishes an episode returns its last observation; the next ``step`` resets that
      sub-environment (its action is ignored, reward 0) and returns the new episode's first observation and
      reset info.
    * ``AutoresetMode.SAME_STEP`` (what stable-baselines3 expects): the returned observation and info are the
      new episode's; the finished episode's last observation is in ``info["final_obs"]`` (an object array,
      None for sub-environments that did not finish) and its step info in ``info["final_info"]``.
    * ``AutoresetMode.DISABLED``: finished sub-environments must be reset with
      ``reset(options={"reset_mask": mask})`` before the next ``step``.

    Infos follow gymnasium's vector convention: ``{key: array over sub-environments, "_key": mask}``, with the
    keys, values and dtypes a ``SyncVectorEnv`` of the single environment gives. ``metadata["autoreset_mode"]``
    says the mode. Accepts the arguments of :class:`BuildingWeekEnv` plus ``num_envs``, ``autoreset_mode``
    and ``max_episode_steps`` (a time limit: an episode not terminated by then is truncated; gymnasium passes
    it from the spec). ``render()`` returns one frame per sub-environment. Stepping before ``reset`` raises
    :class:`ResetNeededError`, as does stepping a finished sub-environment in ``DISABLED`` mode.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": list(RENDER_MODES), "render_fps": 2}

    def __init__(
        self,
        num_envs: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        **kwargs: Any,
    ) -> None:
        self.num_envs = _whole("num_envs", num_envs)
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        self.max_episode_steps = None if max_episode_steps is None else _whole("max_episode_steps", max_episode_steps)
        self._b = _Building(extra=VECTOR_ARGUMENTS, **kwargs)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = self._b.render_mode
        n = self.num_envs
        self.single_observation_space = self._b.observation_space
        self.single_action_space = self._b.action_space
        self.observation_space = spaces.Box(-BOUND, BOUND, (n, *self._b.observation_space.shape), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (n, self._b.actions.size), np.float32)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._seeds: list[int | None] = [None] * n
        self._started = False
        self._sites = np.zeros(n, dtype=int)  # each sub-environment's site (index into the context set)
        self._weeks = np.zeros(n, dtype=int)
        self._steps = np.zeros(n, dtype=int)
        self._previous = np.array(np.broadcast_to(self._b.model.historical, (n, *self._b.model.historical.shape)))
        self._done = np.zeros(n, dtype=bool)  # finished, not reset yet (NEXT_STEP, DISABLED)
        self._obs = np.zeros(self.observation_space.shape, np.float32)
        self._last: list[tuple[int, int, int, dict[str, np.ndarray] | None, int]] = [(0, 0, 0, None, 0)] * n

    @property
    def spec(self):
        """The gymnasium ``EnvSpec`` it was made with; ``max_episode_steps`` is the episode length."""
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, spec) -> None:
        limit = self._b.episode_weeks if self.max_episode_steps is None else self.max_episode_steps
        self._spec = _with_length(spec, min(self._b.episode_weeks, limit))

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """The sub-environments' generators (as ``SyncVectorEnv.np_random``)."""
        return tuple(self._rng(i) for i in range(self.num_envs))

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """The seeds the sub-environments' generators were made with (-1 where drawn from the OS)."""
        return tuple(self._seeds)

    def _rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], self._seeds[i] = seeding.np_random()
        return self._rngs[i]

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict]:
        """Reset the sub-environments (those in ``options["reset_mask"]`` if given; see the class docstring)."""
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, numbers.Integral):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise BuildingEnvError(f"{ENV_ID}: reset(seed=...) got {len(seeds)} seeds for num_envs={n}")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(n, dtype=bool)
        elif not isinstance(mask, np.ndarray) or mask.dtype != bool or mask.shape != (n,) or not mask.any():
            raise BuildingEnvError(
                f"{ENV_ID}: options['reset_mask'] must be a numpy bool array of shape ({n},) with a True value"
            )
        elif not self._started and not mask.all():
            raise ResetNeededError(f"{ENV_ID}: the first reset() resets every sub-environment (no reset_mask)")
        for i in np.flatnonzero(mask):
            if seeds[i] is not None:
                self._rngs[i], self._seeds[i] = seeding.np_random(seeds[i])
        rows = np.flatnonzero(mask)
        info = self._reset_rows(rows, options)
        self._started = True
        return self._obs.copy(), info

    def _reset_rows(self, rows: np.ndarray, options: dict | None) -> dict[str, np.ndarray]:
        """Start new episodes in sub-environments ``rows``; their observations go into ``self._obs``; returns
        their reset info (vector layout)."""
        picks = [self._b.pick(self._rng(i), options) for i in rows]  # as each sub-environment's reset draws
        sites = np.array([p[0] for p in picks], dtype=int)
        weeks = np.array([p[1] for p in picks], dtype=int)
        self._sites[rows], self._weeks[rows] = sites, weeks
        self._steps[rows] = 0
        for i, site in zip(rows, sites):
            self._previous[i] = self._b.contexts[site].model.historical
        self._done[rows] = False
        self._observe(rows)
        if self.render_mode is not None:
            for i, site, week in zip(rows, sites, weeks):
                self._last[i] = (int(site), int(week), 0, None, 0)
        infos = [self._b.contexts[s].week_info(w) for s, w in zip(sites, weeks)]
        values = {
            "week": weeks.astype(int),
            "week_start": np.array([d["week_start"] for d in infos] or [], dtype=object),
        }
        if self._b.many:
            values["site"] = np.array([d["site"] for d in infos] or [], dtype=object)
        return _vector_info(values, rows, self.num_envs)

    def _observe(self, rows: np.ndarray) -> None:
        """The observations of sub-environments ``rows``' current weeks into ``self._obs``, one call per site."""
        for site, at in ctx.by_site(self._sites[rows]):
            group = rows[at]
            self._obs[group] = self._b.contexts[site].observe(self._weeks[group], [self._rng(i) for i in group])

    def _score(self, actions: np.ndarray, rows: np.ndarray) -> dict[str, np.ndarray]:
        """Scores of ``actions`` ``(len(rows), 7 x k)`` in sub-environments ``rows``' weeks, one metamodel call
        per site present (:func:`buildenv.env.contexts.gather` puts the rows back in order)."""
        parts = []
        for site, at in ctx.by_site(self._sites[rows]):
            group = rows[at]
            parts.append((at, self._b.contexts[site].score(actions[at], self._weeks[group], self._previous[group])))
        return ctx.gather(parts, len(rows))

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Apply a week of settings in every sub-environment, one batched call (see the class docstring for
        what finished episodes do).

        Raises:
            ResetNeededError: before ``reset()``, or a finished sub-environment not reset (``DISABLED``).
            BuildingEnvError: actions not of shape ``(num_envs, 7 x k)``, or with NaN or infinite components.
        """
        if not self._started:
            raise ResetNeededError(f"{ENV_ID}: call reset() before step()")
        actions = self._b.check_action(actions, self.action_space.shape, "the vector env's step()")
        n, mode = self.num_envs, self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._done.any():
            raise ResetNeededError(
                f"{ENV_ID}: sub-environment(s) {np.flatnonzero(self._done).tolist()} finished (autoreset_mode="
                f"DISABLED); reset them with reset(options={{'reset_mask': mask}}) before step()"
            )
        resetting = self._done.copy() if mode == AutoresetMode.NEXT_STEP else np.zeros(n, dtype=bool)
        rows = np.flatnonzero(~resetting)
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        info: dict[str, Any] = {}
        if len(rows):
            weeks, sites = self._weeks[rows].copy(), self._sites[rows].copy()
            scores = self._score(actions[rows], rows)
            self._previous[rows] = scores["settings"]
            self._steps[rows] += 1
            term = self._steps[rows] >= self._b.episode_weeks
            trunc = (
                np.zeros_like(term) if self.max_episode_steps is None else self._steps[rows] >= self.max_episode_steps
            )
            rewards[rows], terminated[rows], truncated[rows] = scores["reward"], term, trunc
            info = _vector_info(self._step_values(scores, sites, weeks), rows, n)
            if self.render_mode is not None:
                for j, i in enumerate(rows):
                    self._last[i] = (int(sites[j]), int(weeks[j]), int(self._steps[i]), scores, j)
            ahead = rows[~term]  # the next week's forecast; finished episodes keep their last week's observation
            self._weeks[ahead] += 1
            self._observe(ahead)
        done = terminated | truncated
        if mode == AutoresetMode.NEXT_STEP:
            if resetting.any():
                info = _merged(info, self._reset_rows(np.flatnonzero(resetting), None))
            self._done = done
        elif mode == AutoresetMode.SAME_STEP:
            if done.any():
                final_obs = np.full(n, None, dtype=object)
                for i in np.flatnonzero(done):
                    final_obs[i] = self._obs[i].copy()
                finished = _masked(info, done)
                info = _merged(_masked(info, ~done), self._reset_rows(np.flatnonzero(done), None))
                info["final_obs"], info["_final_obs"] = final_obs, done.copy()
                info["final_info"], info["_final_info"] = finished, done.copy()
        else:
            self._done = done
        return self._obs.copy(), rewards, terminated, truncated, info

    def _step_values(
        self, scores: dict[str, np.ndarray], sites: np.ndarray, weeks: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Per-row step info values, with the dtypes a ``SyncVectorEnv`` of :class:`BuildingWeekEnv` gives."""
        values = {k: np.asarray(v, dtype=np.float64) for k, v in scores.items() if k not in _SERIES}
        values["settings"] = np.asarray(scores["settings"])
        values["clipped_components"] = np.asarray(scores["clipped_components"]).astype(int)
        values["reward_vector"] = np.stack([-scores["energy_term"], -scores["comfort_k"]], axis=-1).astype(np.float32)
        values["week"] = np.asarray(weeks).astype(int)
        infos = [self._b.contexts[s].week_info(w) for s, w in zip(sites, weeks)]
        values["week_start"] = np.array([d["week_start"] for d in infos], dtype=object)
        if self._b.many:
            values["site"] = np.array([d["site"] for d in infos], dtype=object)
        return values

    def render(self) -> tuple[np.ndarray | str, ...] | None:
        """One frame per sub-environment (as ``SyncVectorEnv.render``); see :meth:`BuildingWeekEnv.render`."""
        if self.render_mode is not None and not self._started:
            raise ResetNeededError(f"{ENV_ID}: call reset() before render()")
        if self.render_mode is None:
            return self._b.render(None)
        return tuple(self._b.render(self._b.frame(*last)) for last in self._last)

    # ------------------------------------------------------------------ helpers
    def evaluate(self, actions: np.ndarray, week: int, site: str | int | None = None) -> dict[str, np.ndarray]:
        """Score actions ``(N, 7 x k)`` on one week (as :meth:`BuildingWeekEnv.evaluate`); with several sites
        ``site`` (a name or index) says on which."""
        if site is None and self._b.many:
            raise BuildingEnvError(
                f"{ENV_ID}: the vector env's evaluate() needs site= (sites: {ctx.listing(self._b.names)})"
            )
        actions = np.atleast_2d(actions)
        return self._b.contexts[self._b.index(0 if site is None else site)].score(
            actions, np.full(len(actions), int(week))
        )

    @property
    def historical_action(self) -> np.ndarray:
        """The action nearest the site's historical settings ``(7 x k,)`` (a historical value outside its action
        range gets the nearest end; the energy term is measured against the historical settings themselves); with
        several sites one row per sub-environment, of its current site, ``(num_envs, 7 x k)``."""
        if self._b.many:
            return np.stack(
                [self._b.contexts[s].actions.encode(self._b.contexts[s].model.historical) for s in self._sites]
            )
        return self._b.actions.encode(self._b.model.historical)

    @property
    def site_names(self) -> tuple[str, ...]:
        """The names of the environment's sites (one, or a context set's)."""
        return self._b.names
