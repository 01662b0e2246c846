"""``BuildingWeekVectorEnv``: the native batched ``BuildingWeek-v0`` (``gymnasium.make_vec("BuildingWeek-v0",
num_envs=N)``), N copies of :class:`buildenv.env.building_week.BuildingWeekEnv` stepped in one metamodel call per
site, with gymnasium's three autoreset modes and its vector info layout (``{key: array, "_key": mask}``).

It scores on the same core as the single environment (:class:`buildenv.env.building.Building`) and keeps each
sub-environment's episode state in arrays; the helpers below build, mask and merge vector infos.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from buildenv.env import contexts as ctx
from buildenv.env.arguments import RENDER_MODES, VECTOR_ARGUMENTS, as_autoreset_mode, whole, with_length
from buildenv.env.building import SERIES, Building, ResetNeededError
from buildenv.env.observations import BOUND
from buildenv.env.registration import ENV_ID
from buildenv.errors import BuildingEnvError


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
    """N copies of :class:`.BuildingWeekEnv` stepped in one metamodel call (``gymnasium.make_vec``).

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
    says the mode. Accepts the arguments of :class:`.BuildingWeekEnv` plus ``num_envs``, ``autoreset_mode``
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
        self.num_envs = whole("num_envs", num_envs)
        self.autoreset_mode = as_autoreset_mode(autoreset_mode)
        self.max_episode_steps = None if max_episode_steps is None else whole("max_episode_steps", max_episode_steps)
        self._b = Building(extra=VECTOR_ARGUMENTS, **kwargs)
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
        self._spec = with_length(spec, min(self._b.episode_weeks, limit))

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """The sub-environments' generators (as ``SyncVectorEnv.np_random``)."""
        return tuple(self._rng(i) for i in range(self.num_envs))

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """The seeds the sub-environments' generators were made with (the OS entropy drawn where no seed was given;
        None before the first reset)."""
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
        """Per-row step info values, with the dtypes a ``SyncVectorEnv`` of :class:`.BuildingWeekEnv` gives."""
        values = {k: np.asarray(v, dtype=np.float64) for k, v in scores.items() if k not in SERIES}
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
        """One frame per sub-environment (as ``SyncVectorEnv.render``); see :meth:`.BuildingWeekEnv.render`."""
        if self.render_mode is not None and not self._started:
            raise ResetNeededError(f"{ENV_ID}: call reset() before render()")
        if self.render_mode is None:
            return self._b.render(None)
        return tuple(self._b.render(self._b.frame(*last)) for last in self._last)

    # ------------------------------------------------------------------ helpers
    def evaluate(self, actions: np.ndarray, week: int, site: str | int | None = None) -> dict[str, np.ndarray]:
        """Score actions ``(N, 7 x k)`` on one week (as :meth:`.BuildingWeekEnv.evaluate`); with several sites
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
        range gets the nearest end; the energy term is measured against the historical settings themselves).

        Raises:
            BuildingEnvError: with several sites (each has its own; use :attr:`historical_actions`); weather years
                of one site share its historical action.
        """
        if len({c.site_name for c in self._b.contexts}) > 1:
            raise BuildingEnvError(
                f"{ENV_ID}: historical_action is one site's; with several sites use historical_actions, one row per "
                "sub-environment (num_envs, 7 x k)"
            )
        return self._b.actions.encode(self._b.model.historical)

    @property
    def historical_actions(self) -> np.ndarray:
        """The historical action of each sub-environment's current site, ``(num_envs, 7 x k)`` (see
        :attr:`historical_action`; the first site's before ``reset``)."""
        return np.stack([self._b.contexts[s].actions.encode(self._b.contexts[s].model.historical) for s in self._sites])

    @property
    def site_historical_actions(self) -> np.ndarray:
        """The historical action of each of the environment's sites, ``(n_sites, 7 x k)`` in the order of
        :attr:`site_names` (one row for a single site)."""
        return np.stack([c.actions.encode(c.model.historical) for c in self._b.contexts])

    @property
    def site_names(self) -> tuple[str, ...]:
        """The names of the environment's sites (one, or a context set's)."""
        return self._b.names
