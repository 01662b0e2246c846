"""``BuildingWeek-v0``: choose a week of building-management settings for a calibrated building.

``import buildenv`` registers it; then ``gymnasium.make("BuildingWeek-v0")`` runs the shipped metamodel on
the shipped, calibrated default site and ``gymnasium.make_vec("BuildingWeek-v0", num_envs=N)`` gives the
native batched version (one metamodel call for all N environments).
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from buildenv import catalogue as cat
from buildenv.env import actions as act
from buildenv.env import objectives as obj
from buildenv.env.observations import BOUND, OBSERVATION_KINDS, observation_size, observe
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
    "backend": "metamodel",
    "render_mode": None,
}


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
    """What the single and the vector environment share: arguments, the calibrated site model, scoring."""

    def __init__(self, **kwargs: Any) -> None:
        unknown = sorted(set(kwargs) - set(ARGUMENTS))
        if unknown:
            raise BuildingEnvError(
                f"{ENV_ID}: unknown argument(s) {', '.join(unknown)}; allowed: {', '.join(ARGUMENTS)}"
            )
        args = {**ARGUMENTS, **kwargs}
        self.args = args
        for key, allowed in (("comfort", obj.COMFORT_KINDS), ("observation", OBSERVATION_KINDS), ("backend", BACKENDS)):
            if args[key] not in allowed:
                raise BuildingEnvError(f"{ENV_ID}: {key}={args[key]!r}; choose one of {', '.join(allowed)}")
        if args["render_mode"] is not None:
            raise BuildingEnvError(
                f"{ENV_ID}: render_mode={args['render_mode']!r}; it has no rendering "
                "(plot the info's settings and series instead)"
            )
        self.episode_weeks = int(args["episode_weeks"])
        if self.episode_weeks < 1:
            raise BuildingEnvError(f"{ENV_ID}: episode_weeks={args['episode_weeks']}; give 1 or more")
        self.comfort_weight = float(args["comfort_weight"])
        self.target_c = float(args["target_temperature_c"])
        self.site = _load_site(args["site"])
        from buildenv.metamodel.surrogate import load_metamodel

        self.surrogate = load_metamodel(args["metamodel"])
        self.model = SiteModel.from_site(self.site, self.surrogate)
        occupants = float(self.model.theta[cat.THETA_NAMES.index("occupant_density_per_m2")])
        self.actions = act.ActionMap.for_site(self.site, self.surrogate.domain, self.model.historical, occupants)
        self.occupied = self.model.occupied_hours()
        self.pool = split_weeks(self.model.weeks, args["weeks"])
        pool = set(self.pool)
        self.starts = [k for k in self.pool if all(k + j in pool for j in range(self.episode_weeks))]
        if not self.starts:
            raise BuildingEnvError(f"{ENV_ID}: no {self.episode_weeks} consecutive weeks in weeks={args['weeks']!r}")
        if args["backend"] == "energyplus":
            from buildenv.env.energyplus_backend import reference_building

            reference_building(self.site)  # fail now, not at the first step
        self._historical: dict[int, tuple[float, float]] = {}
        n_obs = observation_size(args["observation"])
        self.observation_space = spaces.Box(-BOUND, BOUND, (n_obs,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.actions.size,), np.float32)

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

    def historical(self, weeks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Energy (Wh/m2 per hour) and comfort (K) of the historical settings in ``weeks``, cached."""
        missing = sorted({int(w) for w in weeks} - set(self._historical))
        if missing:
            out = self.outputs(
                np.broadcast_to(self.model.historical, (len(missing), *self.model.historical.shape)),
                np.array(missing),
                None,
            )
            for w, e, c in zip(missing, obj.hvac_energy(out), self.comfort(out)):
                self._historical[w] = (float(e), float(c))
        pairs = np.array([self._historical[int(w)] for w in weeks]).reshape(len(weeks), 2)
        return pairs[:, 0], pairs[:, 1]

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
        comfort = self.comfort(out)
        hist_energy, hist_comfort = self.historical(weeks)
        ratio = obj.energy_ratio(energy, hist_energy)
        kwh = cat.HOURS_PER_WEEK * self.model.floor_area_m2 / 1000.0
        return {
            "reward": -(ratio + self.comfort_weight * comfort),
            "energy_term": ratio,
            "comfort_k": comfort,
            "energy_wh_m2": energy,
            "energy_kwh": energy * kwh,
            "energy_historical_kwh": hist_energy * kwh,
            "comfort_historical_k": hist_comfort,
            "savings_percent": 100.0 * (1.0 - ratio),
            "mean_temperature_occupied_c": obj.indoor_temperature(out)[:, self.occupied].mean(-1),
            "clipped_components": clipped,
            "settings": settings,
            "temperature_c": obj.indoor_temperature(out),
            "hvac_wh_m2": obj.hvac_energy_hourly(out),
        }

    def observe(self, weeks: np.ndarray) -> np.ndarray:
        """Observations ``(N, obs)`` of the weeks' starts."""
        weeks = np.asarray(weeks, dtype=int)
        return observe(
            self.model.weather(weeks), weeks, self.model.occupancy, self.model.theta, self.args["observation"]
        )

    def pick_week(self, rng: np.random.Generator, options: dict | None) -> int:
        """The first week of a new episode: ``options["week"]`` if given (it must be a valid start), else drawn."""
        if options and "week" in options:
            week = int(options["week"])
            if week not in self.starts:
                raise BuildingEnvError(
                    f"{ENV_ID}: week {week} cannot start an episode of weeks="
                    f"{self.args['weeks']!r} (valid starts: {self.starts})"
                )
            return week
        return int(self.starts[int(rng.integers(len(self.starts)))])

    def week_info(self, week: int) -> dict[str, Any]:
        """``{"week", "week_start"}`` of a week."""
        return {"week": int(week), "week_start": self.model.week_starts[int(week)].isoformat()}


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
    ``Box(-10, 10, (75,), float32)`` (``observation="compact"``): the week's daily weather forecast, the
    occupancy schedule, the week of the year (sine, cosine) and the calibrated building parameters, scaled to
    order one; ``"forecast"`` appends the hourly forecast, ``(1419,)`` (:mod:`buildenv.env.observations`).

    ## Rewards
    ``-(energy_term + comfort_weight * comfort_term)``. ``energy_term`` (the paper's Delta_Q^opt): the week's
    mean hourly HVAC energy over the same week's under the historical settings (1.0 = as today).
    ``comfort_term`` (Delta_T^opt, K): deviation from ``target_temperature_c`` over the occupied hours, by
    ``comfort`` (:mod:`buildenv.env.objectives`). ``info`` adds physical values (``energy_kwh``,
    ``energy_historical_kwh``, ``savings_percent``, ``comfort_k``, ``comfort_historical_k``,
    ``mean_temperature_occupied_c``), the decoded ``settings`` and ``reward_vector = [-energy, -comfort]``.

    ## Starting State
    ``reset(seed=...)`` draws the first week uniformly from the valid starts in ``weeks``;
    ``reset(options={"week": k})`` picks week ``k``. The week before runs the historical settings.
    Deterministic given the seed.

    ## Episode End
    Terminates after ``episode_weeks`` consecutive weeks (default 1: one step); never truncated.

    ## Arguments
    ``site`` ("default", a site folder or a calibrated :class:`buildenv.sites.Site`), ``metamodel``
    ("default" or a checkpoint path), ``comfort_weight`` (1.0 per K), ``target_temperature_c`` (22.5 degC),
    ``comfort`` ("rms", "band", "mean_abs"), ``comfort_band_k`` (1.0 K), ``observation`` ("compact"),
    ``episode_weeks`` (1), ``weeks`` ("train"; "test" is weeks 12-15, 28-31 and 44-47; "all"; or a list),
    ``backend`` ("metamodel", or "energyplus": the site's reference building, for verification). Unknown
    arguments are rejected. ``env.unwrapped.evaluate(actions)`` scores ``(N, 7 x k)`` actions in one call.

    ## Version History
    * v0: first version.
    """

    metadata = {"render_modes": []}

    def __init__(self, **kwargs: Any) -> None:
        self._b = _Building(**kwargs)
        self.observation_space = self._b.observation_space
        self.action_space = self._b.action_space
        self.render_mode = None
        self._week: int | None = None
        self._step_in_episode = 0
        self._previous: np.ndarray | None = None

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode on a week drawn from the site's year (see the class docstring)."""
        super().reset(seed=seed)
        self._week = self._b.pick_week(self.np_random, options)
        self._step_in_episode = 0
        self._previous = None
        return self._b.observe([self._week])[0], self._b.week_info(self._week)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Apply one week of settings; returns the next week's observation and this week's reward."""
        if self._week is None:
            raise BuildingEnvError(f"{ENV_ID}: call reset() before step()")
        prev = None if self._previous is None else self._previous[None]
        scores = self._b.score(np.asarray(action)[None], np.array([self._week]), prev)
        info = {**_single(scores, 0), **self._b.week_info(self._week)}
        self._previous = scores["settings"][0]
        self._step_in_episode += 1
        terminated = self._step_in_episode >= self._b.episode_weeks
        if not terminated:
            self._week += 1
        return self._b.observe([self._week])[0], float(scores["reward"][0]), terminated, False, info

    # ------------------------------------------------------------------ helpers for people and optimisers
    def evaluate(self, actions: np.ndarray, week: int | None = None) -> dict[str, np.ndarray]:
        """Score many weekly settings on one week in one batched call (the environment's state is unchanged).

        Args:
            actions: ``(N, 7 x k)`` actions (see Action Space).
            week: week of the year, after a week under the historical settings; default the current
                episode's week, after the settings the episode applied the week before (if any).
        Returns:
            ``{"reward", "energy_term", "comfort_k", "energy_kwh", "energy_historical_kwh", "savings_percent",
            "comfort_historical_k", "mean_temperature_occupied_c", "energy_wh_m2", "clipped_components"}``,
            each ``(N,)``; ``"settings"`` ``(N, 7, 12)``; the hourly ``"temperature_c"`` (degC) and
            ``"hvac_wh_m2"`` (Wh/m2 in the hour) ``(N, 168)``.
        """
        actions = np.atleast_2d(np.asarray(actions))
        prev = None
        if week is None:
            if self._week is None:
                raise BuildingEnvError(f"{ENV_ID}: call reset() or pass week= to evaluate()")
            week = self._week
            if self._previous is not None:  # mid-episode: the week after the settings just applied
                prev = np.broadcast_to(self._previous, (len(actions), *self._previous.shape))
        return self._b.score(actions, np.full(len(actions), int(week)), prev)

    def decode(self, action: np.ndarray) -> np.ndarray:
        """Physical settings ``(..., 7, 12)`` of actions ``(..., 7 x k)`` (:meth:`.ActionMap.decode`)."""
        return self._b.actions.decode(action)[0]

    def encode(self, settings: np.ndarray) -> np.ndarray:
        """Actions ``(..., 7 x k)`` of physical settings ``(..., 7, 12)`` (the controllable ones)."""
        return self._b.actions.encode(settings)

    @property
    def action_names(self) -> tuple[str, ...]:
        """Names of the action components (``heating_comfort_c_monday``, ...)."""
        return self._b.actions.names()

    @property
    def site(self):
        """The :class:`buildenv.sites.Site` the environment runs."""
        return self._b.site

    @property
    def arguments(self) -> dict[str, Any]:
        """The environment's arguments (defaults filled in)."""
        return dict(self._b.args)

    @property
    def historical_action(self) -> np.ndarray:
        """The action nearest the site's historical settings ``(7 x k,)`` (a historical value outside its action
        range gets the nearest end; the energy term is measured against the historical settings themselves)."""
        return self._b.actions.encode(self._b.model.historical)

    @property
    def week(self) -> int | None:
        """The current week of the year (None before reset)."""
        return self._week

    @property
    def weeks(self) -> list[int]:
        """Weeks an episode can start on."""
        return list(self._b.starts)

    @property
    def site_model(self) -> SiteModel:
        """The calibrated site model (theta, occupancy, weather, metamodel)."""
        return self._b.model

    @property
    def occupied_hours(self) -> np.ndarray:
        """``(168,)`` booleans: the occupied hours comfort is counted over."""
        return self._b.occupied

    def week_start(self, week: int) -> dt.date:
        """Monday of a week of the year."""
        return self._b.model.week_starts[int(week)]


class BuildingWeekVectorEnv(VectorEnv):
    """N copies of :class:`BuildingWeekEnv` stepped in one metamodel call (``gymnasium.make_vec``).

    Sub-environments that finish an episode reset in the same step (``AutoresetMode.SAME_STEP``): the
    returned observation is the new episode's, the finished one's is in ``info["final_obs"]`` and its info
    in ``info["final_info"]``. Accepts the arguments of :class:`BuildingWeekEnv` plus ``num_envs``.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        self._b = _Building(**kwargs)
        self.num_envs = int(num_envs)
        self.single_observation_space = self._b.observation_space
        self.single_action_space = self._b.action_space
        self.observation_space = spaces.Box(
            -BOUND, BOUND, (self.num_envs, *self._b.observation_space.shape), np.float32
        )
        self.action_space = spaces.Box(-1.0, 1.0, (self.num_envs, self._b.actions.size), np.float32)
        self.render_mode = None
        self._weeks = np.zeros(self.num_envs, dtype=int)
        self._steps = np.zeros(self.num_envs, dtype=int)
        self._previous: np.ndarray | None = None

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Reset every sub-environment (``options["week"]`` puts them all on that week)."""
        super().reset(seed=seed if not isinstance(seed, list) else seed[0])
        self._weeks = np.array([self._b.pick_week(self.np_random, options) for _ in range(self.num_envs)])
        self._steps[:] = 0
        self._previous = None
        return self._b.observe(self._weeks), {"week": self._weeks.copy(), "_week": np.ones(self.num_envs, bool)}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Apply a week of settings in every sub-environment, one batched call."""
        actions = np.asarray(actions)
        scores = self._b.score(actions, self._weeks, self._previous)
        self._previous = scores["settings"].copy()
        self._steps += 1
        terminated = self._steps >= self._b.episode_weeks
        info: dict[str, Any] = {k: np.asarray(v) for k, v in scores.items() if k not in _SERIES}
        info["reward_vector"] = np.stack([-scores["energy_term"], -scores["comfort_k"]], axis=-1).astype(np.float32)
        info["week"] = self._weeks.copy()
        for key in list(info):
            info[f"_{key}"] = np.ones(self.num_envs, bool)
        self._weeks = np.where(terminated, self._weeks, self._weeks + 1)
        obs = self._b.observe(self._weeks)
        if terminated.any():
            info["final_obs"] = np.where(terminated[:, None], obs, 0.0).astype(np.float32)
            info["_final_obs"] = terminated.copy()
            for i in np.flatnonzero(terminated):
                self._weeks[i] = self._b.pick_week(self.np_random, None)
                self._steps[i] = 0
                self._previous[i] = self._b.model.historical
            obs = np.where(terminated[:, None], self._b.observe(self._weeks), obs)
        return (
            obs.astype(np.float32),
            scores["reward"].astype(np.float32),
            terminated,
            np.zeros(self.num_envs, bool),
            info,
        )

    def evaluate(self, actions: np.ndarray, week: int) -> dict[str, np.ndarray]:
        """Score actions ``(N, 7 x k)`` on one week (as :meth:`BuildingWeekEnv.evaluate`)."""
        return self._b.score(np.atleast_2d(actions), np.full(len(np.atleast_2d(actions)), int(week)))

    @property
    def historical_action(self) -> np.ndarray:
        """The action nearest the site's historical settings ``(7 x k,)`` (a historical value outside its action
        range gets the nearest end; the energy term is measured against the historical settings themselves)."""
        return self._b.actions.encode(self._b.model.historical)
