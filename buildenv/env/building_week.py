"""``BuildingWeek-v0``: choose a week of building-management settings for a calibrated building.

``import buildenv`` registers it; then ``gymnasium.make("BuildingWeek-v0")`` runs the shipped metamodel on
the shipped, calibrated default site and ``gymnasium.make_vec("BuildingWeek-v0", num_envs=N)`` gives the
native batched version (one metamodel call for all N environments, :mod:`buildenv.env.vector`), with gymnasium's
three autoreset modes. Both render the last week (``render_mode="rgb_array"`` or ``"ansi"``,
:mod:`buildenv.env.render`), pickle and deep-copy at any time (the traced metamodel is left out and traced again on
first use) and raise :class:`ResetNeededError` (a ``gymnasium.error.ResetNeeded``) when stepped before ``reset`` or
after the end. Both score on :mod:`buildenv.env.building` and check their arguments in :mod:`buildenv.env.arguments`.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import gymnasium as gym
import numpy as np

from buildenv.env import contexts as ctx
from buildenv.env.arguments import RENDER_MODES, split_weeks, with_length
from buildenv.env.building import DEFAULT_SITE, SERIES, Building, ResetNeededError, SiteScorer
from buildenv.env.registration import ENV_ID
from buildenv.env.vector import BuildingWeekVectorEnv
from buildenv.errors import BuildingEnvError
from buildenv.sites.week_simulator import SiteModel

# what callers import from here; the vector env, the scoring core and the argument checks have their own modules
__all__ = ["DEFAULT_SITE", "BuildingWeekEnv", "BuildingWeekVectorEnv", "ResetNeededError", "split_weeks"]


def _single(scores: dict[str, np.ndarray], i: int) -> dict[str, Any]:
    """The step info of environment ``i`` from batched scores (physical units)."""
    info = {k: (v[i] if k == "settings" else float(v[i])) for k, v in scores.items() if k not in SERIES}
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
    change (``[bms] controllable`` in ``site.toml``; all 13, ``(91,)``, when a site says nothing; 11 on the default
    site, whose supply air temperature the BMS cannot set) for
    each day Monday..Sunday, day-major (``env.unwrapped.action_names``), each mapped linearly onto its catalogue
    range within the site's limits and what the metamodel was trained on (:class:`buildenv.env.actions.ActionMap`)
    and snapped to its step; the other settings stay at the site's historical values.
    ``env.unwrapped.decode(action)`` gives the physical ``(7, 13)`` settings, ``encode(settings)``
    the action. Components outside [-1, 1] are clipped and counted in ``info["clipped_components"]``; NaN or
    infinite ones raise :class:`buildenv.errors.BuildingEnvError`.

    ## Observation Space
    ``Box(-10, 10, (77,), float32)`` (``observation="compact"``): the week's daily weather forecast (42), the
    occupancy schedule (10), the week of the year (sine, cosine) and the 23 calibrated building parameters, scaled
    to order one; ``"forecast"`` appends the hourly forecast (168 x 8), ``(1421,)`` (:mod:`buildenv.env.observations`).

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
    cost is floored at the cost of 0.5 Wh/m2 in every hour). The cost prices the energy bought: cooling
    delivered / ``cooling_cop`` (3.0) + heating delivered / ``heating_efficiency`` (1.0); a ``time_zone`` makes
    the peak hours follow the local clock (daylight saving). ``info`` adds ``cost`` and ``cost_historical``
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
    ``forecast_noise`` (0.0 K: the true weather; see Observation Space), ``weather_years`` (1: the site's own
    weather file; N: also N - 1 morphs of it, each (site, year) a context named ``"<site>:year<k>"``; or a list of
    years, :mod:`buildenv.weather.morph`), ``price`` (None: relative energy; see
    Rewards), ``render_mode`` (None, "rgb_array", "ansi"). Unknown arguments and bad values (``comfort_weight=nan``,
    ``episode_weeks=2.7``, ...) are rejected with one line each. ``env.unwrapped.evaluate(actions)`` scores
    ``(N, 7 x k)`` actions in one call.

    ## Version History
    * v0: first version.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 2}

    def __init__(self, **kwargs: Any) -> None:
        self._b = Building(**kwargs)
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
        self._spec = with_length(spec, self._b.episode_weeks)

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
            each ``(N,)``; ``"settings"`` ``(N, 7, 13)``; the hourly ``"temperature_c"`` (degC) and
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
        """Physical settings ``(..., 7, 13)`` of actions ``(..., 7 x k)`` (:meth:`.ActionMap.decode`)."""
        return self._here.actions.decode(action)[0]

    def encode(self, settings: np.ndarray) -> np.ndarray:
        """Actions ``(..., 7 x k)`` of physical settings ``(..., 7, 13)`` (the controllable ones)."""
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
    def _here(self) -> SiteScorer:
        """The current episode's site (the first before reset)."""
        return self._b.contexts[self._site]
