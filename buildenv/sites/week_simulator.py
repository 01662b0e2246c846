"""A calibrated site as a week simulator: any week of the site's weather year, any settings, one batched call.

:class:`SiteModel` takes theta_build and the weekly occupancy from the site's calibration (``calibration.json``,
:mod:`buildenv.calibration.problem`), the weather W_k from the site's weather file, and turns settings I_k into
hourly outputs with the metamodel.

**Calendar.** Week ``k`` starts on the ``k``-th Monday of the year the site's measurements start in (0-based):
the weeks wholly inside that year (51 or 52, :func:`year_weeks`), then, for a site measured across a new year, the
weeks after them up to its last measured one (:func:`model_weeks`). Each day takes the weather of the same calendar
day of the EPW year (:func:`buildenv.weather.epw.epw_day_of_year`), so the site's measured weeks are among them.

**Context.** The metamodel reads its context hours before each week
(:attr:`buildenv.metamodel.surrogate.Surrogate.context_hours`): their weather is the EPW's, their settings
the previous week's, i.e. the historical settings unless the caller passes the settings actually applied the
week before (consecutive weeks of an episode).

**Historical settings** are the settings in force during the site's first measured week.
"""

from __future__ import annotations

import datetime as dt
import logging
from dataclasses import dataclass, field, replace

import numpy as np

from buildenv import catalogue as cat
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import get_effect
from buildenv.errors import BuildingEnvError
from buildenv.metamodel.surrogate import INFERENCE_BATCH, encode_weeks, weather_ground_c
from buildenv.schedules import hourly_schedules
from buildenv.weather.epw import epw_day_of_year

log = logging.getLogger(__name__)


def year_weeks(year: int) -> list[dt.date]:
    """Mondays of the weeks that lie wholly inside ``year`` (51 or 52 dates)."""
    first = dt.date(year, 1, 1)
    monday = first + dt.timedelta(days=(7 - first.weekday()) % 7)
    starts = []
    while (monday + dt.timedelta(days=6)).year == year:
        starts.append(monday)
        monday += dt.timedelta(days=7)
    return starts


def model_weeks(first_measured: dt.date, measured_weeks: int) -> list[dt.date]:
    """Mondays of a site model's weeks: :func:`year_weeks` of ``first_measured``'s year, continued week by week to
    the last of ``measured_weeks`` measured weeks from ``first_measured`` (a Monday) where they run past it."""
    starts = year_weeks(first_measured.year)
    last = first_measured + dt.timedelta(weeks=measured_weeks - 1)
    while starts[-1] < last:
        starts.append(starts[-1] + dt.timedelta(weeks=1))
    return starts


def _epw_rows(day0: dt.date, starts: list[dt.date]) -> np.ndarray:
    """Hour rows of the EPW year ``(days, 24)`` of each day from ``day0`` to the end of the last week in ``starts``
    (each day takes the same calendar day of the EPW year)."""
    days = [day0 + dt.timedelta(days=d) for d in range((starts[-1] - day0).days + 7)]
    return np.array([epw_day_of_year(d) for d in days])[:, None] * cat.HOURS_PER_DAY + np.arange(24)


@dataclass
class SiteModel:
    """A calibrated building over one calendar year of weather (build with :meth:`from_site`).

    Attributes:
        surrogate: the metamodel (:class:`buildenv.metamodel.surrogate.Surrogate`).
        theta: calibrated theta_build, catalogue order, ``(23,)``.
        occupancy: calibrated weekday occupancy ``(5, 2)`` (arrival, departure hour).
        historical: the site's historical settings ``(7, 13)``.
        week_starts: the Monday of every week of the year.
        weather_days: weather of every day of the year plus the week before, ``(days, 24, 9)``, catalogue
            units.
        ground_days: ground temperature under the slab on the same days ``(days, 24)``, degC
            (:func:`buildenv.metamodel.surrogate.weather_ground_c`).
        floor_area_m2: conditioned floor area.
        name: the site's name.
        effects: the calibration's building effects (:data:`buildenv.diagnosis.model_effects.BUILDING_EFFECTS`),
            ``{effect: (1, k) parameters}``; sensor effects and absent days are not simulated.
    """

    surrogate: object
    theta: np.ndarray
    occupancy: np.ndarray
    historical: np.ndarray
    week_starts: list[dt.date]
    weather_days: np.ndarray
    ground_days: np.ndarray
    floor_area_m2: float
    name: str = ""
    effects: dict = field(default_factory=dict)
    _day0: dt.date = field(default=dt.date(2000, 1, 1), repr=False)

    @classmethod
    def from_site(cls, site, surrogate, strict_calibration: bool = False) -> SiteModel:
        """The calibrated model of a :class:`buildenv.sites.Site` (which must carry a calibration); warns when the
        calibration was made with another metamodel than ``surrogate``, and once when it fails ASHRAE Guideline 14
        (:func:`buildenv.calibration.verdict.check_calibration`; an error with ``strict_calibration``).

        Raises:
            BuildingEnvError: the site has not been calibrated.
            buildenv.calibration.verdict.CalibrationFailed: it fails Guideline 14 and ``strict_calibration``.
        """
        from buildenv.weather.epw import load_weather

        calib = site.calibration
        if not calib:
            raise BuildingEnvError(f"site {site.path} is not calibrated: run `buildenv calibrate --site {site.path}`")
        from buildenv.calibration.problem import metamodel_mismatch
        from buildenv.calibration.verdict import check_calibration

        check_calibration(calib, str(site.path), strict_calibration)
        mismatch = metamodel_mismatch(calib, surrogate)
        if mismatch:
            log.warning("site %s: %s", site.path, mismatch)
        theta = np.array([calib["theta"][n] for n in cat.THETA_NAMES], dtype=float)
        occupancy = np.asarray(calib["occupancy"], dtype=float).reshape(len(cat.WEEKDAYS), 2)
        starts = model_weeks(site.start, site.weeks)
        day0 = starts[0] - dt.timedelta(days=7)
        hourly = np.asarray(load_weather(site.weather).hourly)
        rows = _epw_rows(day0, starts)
        effects = {
            name: np.array([[values[p.name] for p in get_effect(name).parameters]], dtype=float)
            for name, values in (calib.get("effects") or {}).items()
            if name in em.BUILDING_EFFECTS
        }
        return cls(
            surrogate,
            theta,
            occupancy,
            np.asarray(site.settings[0], float),
            starts,
            hourly[rows],
            weather_ground_c(site.weather)[rows],
            float(site.floor_area_m2),
            site.name,
            effects,
            day0,
        )

    def with_weather(self, weather) -> SiteModel:
        """The same building on the same calendar under another year of weather (a
        :class:`buildenv.weather.epw.Weather`, such as a morph of the site's): every day's weather and ground
        temperature taken from it."""
        from buildenv.energyplus.shoebox import hourly_ground_temperature_c

        rows = _epw_rows(self._day0, self.week_starts)
        ground = hourly_ground_temperature_c(weather)
        return replace(self, weather_days=np.asarray(weather.hourly)[rows], ground_days=ground[rows])

    @property
    def weeks(self) -> int:
        """Number of weeks of the model (:func:`model_weeks`)."""
        return len(self.week_starts)

    def week_of(self, monday: dt.date) -> int:
        """Index of the week starting on ``monday``."""
        if monday not in self.week_starts:
            first, last = self.week_starts[0], self.week_starts[-1]
            raise BuildingEnvError(f"{monday} is not the Monday of a week of the site's model ({first}..{last})")
        return self.week_starts.index(monday)

    def _days(self, weeks: np.ndarray) -> np.ndarray:
        """Index into ``weather_days`` of each week's Monday ``(N,)``."""
        weeks = np.asarray(weeks, dtype=int)
        if ((weeks < 0) | (weeks >= self.weeks)).any():
            raise BuildingEnvError(f"week index out of range 0..{self.weeks - 1}: {weeks.min()}..{weeks.max()}")
        return 7 * weeks + 7

    def weather(self, weeks: np.ndarray) -> np.ndarray:
        """Hourly weather of weeks ``(N,)`` -> ``(N, 168, 9)`` (catalogue weather channels and units)."""
        return self._weeks_of_days(self._days(weeks))

    def _weeks_of_days(self, mondays: np.ndarray) -> np.ndarray:
        """Weather ``(N, 168, 9)`` of the 7 days from each index ``mondays`` (a broadcast view if all agree)."""
        if len(mondays) and (mondays == mondays[0]).all():
            one = self.weather_days[mondays[0] : mondays[0] + 7].reshape(1, cat.HOURS_PER_WEEK, -1)
            return np.broadcast_to(one, (len(mondays), *one.shape[1:]))
        d = mondays[:, None] + np.arange(7)
        return self.weather_days[d].reshape(len(d), cat.HOURS_PER_WEEK, -1)

    def ground(self, weeks: np.ndarray) -> np.ndarray:
        """Ground temperature under the slab (degC) of weeks ``(N,)`` and the metamodel's context hours before
        each, ``(N, context_hours + 168)``."""
        days = self._days(weeks)[:, None] + np.arange(-self.surrogate.context_hours // cat.HOURS_PER_DAY, 7)
        return self.ground_days[days].reshape(len(days), -1)

    def simulate(self, settings: np.ndarray, weeks: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
        """Hourly outputs ``(N, 168, 8)`` (Wh/m2 per hour, degC) of settings ``(N, 7, 13)`` in weeks ``(N,)``.

        ``previous`` is the settings of each preceding week ``(N, 7, 13)``; ``None`` means the historical ones.
        """
        settings = np.asarray(settings, dtype=float)
        n = len(settings)
        weeks = np.broadcast_to(np.asarray(weeks, dtype=int), (n,))
        prev_settings = np.broadcast_to(self.historical, settings.shape) if previous is None else previous
        theta = np.broadcast_to(self.theta, (n, len(self.theta)))
        occ = np.broadcast_to(self.occupancy, (n, *self.occupancy.shape))
        prev_weather = self._weeks_of_days(self._days(weeks) - 7)
        previous_week = (prev_settings, occ, prev_weather)
        ground = self.ground(weeks)
        if not self.effects:
            return self.surrogate.predict(theta, settings, occ, self.weather(weeks), previous_week, ground_c=ground)
        out = np.empty((n, cat.HOURS_PER_WEEK, len(cat.OUTPUT_NAMES)), dtype=np.float32)
        weather = self.weather(weeks)
        for start in range(0, n, INFERENCE_BATCH):  # the extended model: effects act on inputs and outputs
            part = slice(start, start + INFERENCE_BATCH)
            x = encode_weeks(
                theta[part],
                settings[part],
                occ[part],
                weather[part],
                tuple(a[part] for a in previous_week),
                context_hours=self.surrogate.context_hours,
                ground_c=ground[part],
            )
            x = em.transform_inputs(x, self.effects)
            out[part] = em.transform_outputs(self.surrogate.predict_encoded(x), x, self.effects)
        return out

    def occupied_hours(self) -> np.ndarray:
        """``(168,)`` booleans: the hours the calibrated occupancy marks as occupied."""
        frac = hourly_schedules(np.zeros((1, 7, len(cat.SETTINGS))), self.occupancy[None])["occupancy_fraction"]
        return frac[0] > 0
