"""The scoring core both ``BuildingWeek-v0`` environments share.

:class:`Building` holds the checked arguments (:mod:`buildenv.env.arguments`), the spaces and the calibrated site,
or the sites of a context set (:mod:`buildenv.env.contexts`), all on one loaded metamodel; :class:`SiteScorer` is
one of those sites: its model, actions and weeks, the scores of a batch of actions on its weeks (with the
historical settings' scores cached), its observations and what ``render()`` shows of a week.
:class:`buildenv.env.building_week.BuildingWeekEnv` and :class:`buildenv.env.vector.BuildingWeekVectorEnv` hold one
:class:`Building` each and keep their episodes' state themselves.
"""

from __future__ import annotations

import copy
import numbers
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from buildenv import catalogue as cat
from buildenv.env import actions as act
from buildenv.env import contexts as ctx
from buildenv.env import objectives as obj
from buildenv.env import render as rnd
from buildenv.env import tariff as tar
from buildenv.env.arguments import RENDER_MODES, checked_arguments, finite, split_weeks, weather_years, whole
from buildenv.env.observations import BOUND, forecast, observation_size, observe
from buildenv.env.registration import ENV_ID
from buildenv.errors import BuildingEnvError
from buildenv.sites.week_simulator import SiteModel

DEFAULT_SITE = Path(__file__).resolve().parents[1] / "data" / "sites" / "default"
SERIES = ("temperature_c", "hvac_wh_m2")  # hourly series: in evaluate()'s result, not in step infos


class ResetNeededError(BuildingEnvError, gym.error.ResetNeeded):
    """``step()`` or ``render()`` before ``reset()``, or ``step()`` after the episode ended: gymnasium's
    ``ResetNeeded`` (what its ``OrderEnforcing`` wrapper raises) and a :class:`BuildingEnvError`."""


class Building:
    """What the single and the vector environment share: arguments, spaces and the calibrated site, or the sites of
    a context set (:mod:`buildenv.env.contexts`), one :class:`SiteScorer` per site and weather year, all on one
    loaded metamodel."""

    def __init__(self, extra: tuple[str, ...] = (), **kwargs: Any) -> None:
        args = checked_arguments(kwargs, extra)
        self.args = args
        self.render_mode: str | None = args["render_mode"]
        self.episode_weeks = whole("episode_weeks", args["episode_weeks"])
        self.comfort_weight = finite("comfort_weight", args["comfort_weight"], 0.0)
        self.target_c = finite("target_temperature_c", args["target_temperature_c"])
        self.band_k = finite("comfort_band_k", args["comfort_band_k"], 0.0)
        self.forecast_noise = finite("forecast_noise", args["forecast_noise"], 0.0)
        self.tariff = tar.tariff_from(args["price"], ENV_ID)
        years = weather_years(args["weather_years"])
        if args["backend"] == "energyplus" and years != [0]:
            raise BuildingEnvError(
                f"{ENV_ID}: weather_years={args['weather_years']!r} with backend='energyplus': the reference "
                "building runs the site's own weather file; give weather_years=1 (or [0])"
            )
        if args["backend"] == "energyplus" and self.tariff is not None:
            raise BuildingEnvError(
                f"{ENV_ID}: price={args['price']!r} with backend='energyplus': the reference building's run gives "
                "its HVAC energy undivided, so cooling cannot be priced through the chiller; leave price out"
            )
        chosen, self.many = ctx.resolve(args["site"], args["sites"])
        from buildenv.metamodel.surrogate import load_metamodel

        self.surrogate = load_metamodel(args["metamodel"])  # loaded once, shared by every site
        self.contexts = [scorer.in_year(k) for scorer in (SiteScorer(self, c) for c in chosen) for k in years]
        self.many = self.many or len(years) > 1  # a context set, or weather years of a site: each episode draws one
        for scorer in self.contexts:
            scorer.label = scorer.name if self.many else ""
        self.names = tuple(c.name for c in self.contexts)
        ctx.check_alike([(c.name, c.actions) for c in self.contexts])
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
        """The first site's action map (every site's acts on the same settings over the same ranges)."""
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
        """What ``render()`` shows of ``week`` of site ``site`` (:meth:`SiteScorer.frame`)."""
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


class SiteScorer:
    """One calibrated site of the environment: its model, actions and weeks, and scoring on it under the
    environment's arguments."""

    def __init__(self, shared: Building, context: ctx.Context) -> None:
        self.args, self.tariff, self.episode_weeks = shared.args, shared.tariff, shared.episode_weeks
        self.comfort_weight, self.target_c, self.band_k = shared.comfort_weight, shared.target_c, shared.band_k
        self.forecast_noise = shared.forecast_noise
        args = self.args
        self.name = self.site_name = context.name  # the context's name; its site's (without a weather year)
        self.label = context.name if shared.many else ""  # what info and render name: nothing for a single site
        on = f" on site {self.name!r}" if self.label else ""
        self.site = _load_site(context.source)
        if shared.many:  # one policy over every site: each must be calibrated with the metamodel it runs on
            from buildenv.calibration.problem import metamodel_mismatch

            mismatch = metamodel_mismatch(self.site.calibration or {}, shared.surrogate)
            if mismatch:
                raise BuildingEnvError(f"{ENV_ID}: site {self.name!r} of the context set: {mismatch}")
        self.model = SiteModel.from_site(self.site, shared.surrogate, strict_calibration=args["strict_calibration"])
        occupants = float(self.model.theta[cat.THETA_NAMES.index("occupant_density_per_m2")])
        self.actions = act.ActionMap.for_site(self.site, shared.surrogate.domain, self.model.historical, occupants)
        self.occupied = self.model.occupied_hours()
        self.pool = split_weeks(self.model.weeks, args["weeks"], self.name)
        pool = set(self.pool)
        self.starts = [k for k in self.pool if all(k + j in pool for j in range(self.episode_weeks))]
        if not self.starts:
            raise BuildingEnvError(
                f"{ENV_ID}: no {self.episode_weeks} consecutive weeks in weeks={args['weeks']!r}{on}"
            )
        if args["backend"] == "energyplus":
            from buildenv.energyplus.reference import recorded_schedule_map, stand_in_version
            from buildenv.env.energyplus_backend import reference_building

            reference_building(self.site)  # fail now, not at the first step
            stand_in_version(self.site)
            recorded_schedule_map(self.site)
        self._historical: dict[int, tuple[float, float, float]] = {}

    def in_year(self, year: int) -> SiteScorer:
        """This site under synthetic weather year ``year`` (:func:`buildenv.weather.morph.weather_year`; itself for
        year 0), named ``"<site>:year<k>"``, its historical scores computed afresh."""
        if year == 0:
            return self
        from buildenv.weather.epw import load_weather
        from buildenv.weather.morph import morph_weather, weather_year

        twin = copy.copy(self)
        twin.name = f"{self.name}:year{year}"
        twin.model = self.model.with_weather(morph_weather(load_weather(self.site.weather), weather_year(year)))
        twin._historical = {}
        return twin

    def with_surrogate(self, surrogate) -> SiteScorer:
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
            costs = self.cost(out, np.array(missing))
            for w, e, c, k in zip(missing, obj.hvac_energy(out), self.comfort(out), costs):
                self._historical[w] = (float(e), float(c), float(k))
        rows = np.array([self._historical[int(w)] for w in weeks]).reshape(len(weeks), 3)
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def prices(self, weeks: np.ndarray) -> np.ndarray:
        """Hourly prices ``(N, 168)`` (currency per kWh) of the tariff on the weeks' dates."""
        return np.stack([self.tariff.hourly(self.model.week_starts[int(w)]) for w in weeks]).reshape(len(weeks), -1)

    def cost(self, outputs: np.ndarray, weeks: np.ndarray) -> np.ndarray:
        """HVAC energy cost (currency) of outputs ``(N, 168, 8)`` in ``weeks`` ``(N,)``: the energy bought
        (:meth:`buildenv.env.tariff.Tariff.bought_wh_m2`) at the hours' prices; NaN without a tariff."""
        if self.tariff is None:
            return np.full(len(weeks), np.nan)
        return tar.weekly_cost(self.tariff.bought_wh_m2(outputs), self.prices(weeks), self.model.floor_area_m2)

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
            cost = tar.weekly_cost(self.tariff.bought_wh_m2(out), prices, self.model.floor_area_m2)
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
            week = whole('options["week"]', options["week"], 0)
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
