"""The site model: :class:`Site` (a loaded, validated site) and the site format's names and limits.

Holds the file names (:data:`DESCRIPTOR`, ...), the CSV columns (:data:`MEASUREMENT_COLUMNS`,
:data:`SETTINGS_COLUMNS`), the ``site.toml`` keys and the plausibility limits that :mod:`buildenv.sites.reader`
(with :mod:`~buildenv.sites.measurements` and :mod:`~buildenv.sites.consumption`) checks and
:mod:`buildenv.sites.writer` writes. A site folder holds (for users: ``docs/site-format.md``)::

    site.toml          descriptor: name, weather (EPW short name or path), [geometry], optional effects, [known],
                       [meters], [bms], [source], measurements (file name, or a table: file, time_zone,
                       stamped, cumulative)
    measurements.csv   timestamp,indoor_temperature_c,heat_consumption_kwh[,electricity_kwh]
                       (hourly, whole weeks from a Monday)
    settings.csv       date + the 13 catalogue settings                      (one row per day of those weeks)
    calibration.json   optional, written by calibration (:func:`buildenv.sites.writer.save_calibration`)
    truth.json         optional, true parameters of a synthetic stand-in site

Conventions:

- Timestamps are local *standard* time (no daylight-saving shift, like the EPW file) of the START of the
  hour; weeks start Monday 00:00. ``[measurements]`` may declare otherwise: ``time_zone`` (the file keeps
  that zone's clock, daylight saving included), ``stamped = "end"`` (a row stamps the end of its hour),
  ``cumulative = true`` (the consumption column holds meter register readings); the reader converts.
- ``indoor_temperature_c`` is the occupied zone's mean air temperature over the hour, degC; it is compared
  with the catalogue output ``T_INT_OFFICE``.
- ``heat_consumption_kwh`` is the energy used during the hour, kWh, by the end uses ``[meters] consumption``
  lists (default heating + lighting + plug loads; heating and cooling as energy delivered); it is compared with
  the sum of their outputs (:data:`buildenv.catalogue.END_USE_OUTPUTS`, Wh/m2 in the hour) times floor area /
  1000.
- ``electricity_kwh`` (optional, with ``[meters] electricity``): a second meter, the energy used during the hour by
  the end uses it lists (its own, none metered twice); calibration fits each meter (a site that meters heat and
  electricity apart: ``consumption = ["heating"]``, ``electricity = ["lighting", "plug_loads"]``).
- Missing rows and empty / ``NaN`` cells are gaps: the hour is NaN and masked, never interpolated.
  Temperature and consumption have separate masks.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.weather.epw import epw_day_of_year, epw_hours

DESCRIPTOR = "site.toml"
CALIBRATION_FILE = "calibration.json"
TRUTH_FILE = "truth.json"
DEFAULT_MEASUREMENTS = "measurements.csv"
DEFAULT_SETTINGS = "settings.csv"
MEASUREMENT_COLUMNS: tuple[str, ...] = ("timestamp", "indoor_temperature_c", "heat_consumption_kwh")
#: The optional second meter's column of ``measurements.csv`` (after :data:`MEASUREMENT_COLUMNS`).
ELECTRICITY_COLUMN = "electricity_kwh"
SETTINGS_COLUMNS: tuple[str, ...] = ("date", *cat.SETTING_NAMES)
TOP_LEVEL_KEYS: tuple[str, ...] = (
    "name",
    "weather",
    "measurements",
    "settings",
    "effects",
    "geometry",
    "known",
    "meters",
    "bms",
    "source",
)
GEOMETRY_KEYS: tuple[str, ...] = cat.GEOMETRY_NAMES
#: Building parameters a site may declare known in ``[known]`` (calibration then keeps them fixed).
KNOWN_KEYS: tuple[str, ...] = tuple(n for n in cat.THETA_NAMES if n not in GEOMETRY_KEYS)
#: Keys of ``[meters]``: ``consumption``, the end uses the consumption series sums; ``electricity``, those of the
#: optional second meter (:data:`ELECTRICITY_COLUMN`).
METER_KEYS: tuple[str, ...] = ("consumption", "electricity")
#: Keys of a ``[measurements]`` table (``measurements`` may instead be the file name alone): ``file``, the CSV;
#: ``time_zone``, the IANA zone whose clock (daylight saving included) the timestamps keep; ``stamped``,
#: ``"start"`` (default) or ``"end"`` of the hour a row covers; ``cumulative``, the consumption column holds
#: readings of a meter register.
MEASUREMENTS_KEYS: tuple[str, ...] = ("file", "time_zone", "stamped", "cumulative")
#: Keys of ``[bms]``: ``controllable``, the settings the BMS can change; ``limits``, their ranges in operation.
BMS_KEYS: tuple[str, ...] = ("controllable", "limits")

#: Plausible indoor air temperature, degC; a value outside is a unit or sensor error.
TEMPERATURE_RANGE_C: tuple[float, float] = (-20.0, 50.0)
#: Largest plausible consumption in one hour, kWh per m2 of floor area.
MAX_KWH_PER_M2_PER_HOUR = 1.0
#: Smallest plausible peak of a consumption series that includes lighting or plug loads, as a share of the
#: catalogue's least installed power of those end uses (the minima of ``lighting_power_w_m2`` and
#: ``plug_load_w_m2``): in its busiest hour a building uses at least that share of it (a nearly empty building
#: with efficient lights). A file in MWh (1000 times too small) peaks below it even at the catalogue's highest
#: powers; one in GJ (278 times) does unless the building peaks far above them.
MIN_PEAK_SHARE_OF_LEAST_POWER = 0.1


@dataclass(eq=False)
class Site:
    """A loaded, validated site (build one with :func:`buildenv.sites.load_site`).

    Attributes:
        path: the site folder.
        name: free text from ``site.toml``.
        weather: an EPW short name (see :func:`buildenv.weather.epw.shipped_weather`) or an absolute EPW path.
        start: Monday of the first measured week (local standard time).
        floor_area_m2: conditioned floor area, m2 (known, fixed during calibration).
        number_of_floors: number of storeys (known, fixed during calibration).
        settings: BMS settings in force, ``(weeks, 7, 13)``, Monday..Sunday, catalogue order of the
            ``settings`` group (units of :data:`buildenv.catalogue.SETTINGS`: h, degC, 1/h).
        temperature_c: occupied-zone mean air temperature of each hour, degC, ``(weeks, 168)``, NaN where
            missing.
        consumption_kwh: consumption of the metered end uses (:attr:`consumption_end_uses`) in each hour, kWh,
            ``(weeks, 168)``, NaN where missing.
        source: the free ``[source]`` table of ``site.toml`` (what produced the data), not interpreted.
        known: the ``[known]`` table: building parameters the owner knows (design documents, BMS), in catalogue
            units, ``{theta_build name: value}``; calibration keeps them fixed like the geometry.
        effects: the ``effects`` list: effects of :mod:`buildenv.diagnosis.effects` the owner knows the building
            has; calibration fits them (declared effects) and the gap diagnosis takes them as part of the base
            model, not as candidates.
        consumption_end_uses: ``[meters] consumption``: the end uses (keys of
            :data:`buildenv.catalogue.END_USE_OUTPUTS`) the consumption series sums; default heating + lighting +
            plug loads.
        electricity_kwh: the second meter's consumption (:attr:`electricity_end_uses`) in each hour, kWh,
            ``(weeks, 168)``, NaN where missing; None: the site has one meter.
        electricity_end_uses: ``[meters] electricity``: the end uses the second meter sums (none of
            :attr:`consumption_end_uses`); empty without a second meter.
        controllable: ``[bms] controllable``: the settings (names of :data:`buildenv.catalogue.SETTING_NAMES`,
            catalogue order) the building's BMS can change; BuildingWeek-v0 and the optimisers act on these
            only, the others stay at the site's historical values. Default all 13.
        setting_limits: ``[bms] limits``: ``{controllable setting: (min, max)}`` in catalogue units, the range
            operators may use, inside the catalogue's; a setting without one has the catalogue's range.
        calibration: parsed ``calibration.json`` or None.
        truth: parsed ``truth.json`` (true parameters of a synthetic site) or None.
    """

    path: Path
    name: str
    weather: str
    start: dt.date
    floor_area_m2: float
    number_of_floors: int
    settings: np.ndarray
    temperature_c: np.ndarray
    consumption_kwh: np.ndarray
    source: dict = field(default_factory=dict)
    known: dict[str, float] = field(default_factory=dict)
    effects: tuple[str, ...] = ()
    consumption_end_uses: tuple[str, ...] = cat.DEFAULT_END_USES
    electricity_kwh: np.ndarray | None = None
    electricity_end_uses: tuple[str, ...] = ()
    controllable: tuple[str, ...] = cat.SETTING_NAMES
    setting_limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    calibration: dict | None = None
    truth: dict | None = None

    @property
    def weeks(self) -> int:
        """Number of measured weeks."""
        return int(self.temperature_c.shape[0])

    @property
    def temperature_mask(self) -> np.ndarray:
        """``(weeks, 168)`` bool, True where the indoor temperature was measured."""
        return np.isfinite(self.temperature_c)

    @property
    def consumption_mask(self) -> np.ndarray:
        """``(weeks, 168)`` bool, True where the consumption was measured."""
        return np.isfinite(self.consumption_kwh)

    def consumption_wh_m2(self) -> np.ndarray:
        """Consumption per m2 of floor area, Wh/m2 in each hour, ``(weeks, 168)``, NaN where missing.

        The unit of the catalogue outputs: compare with the sum of :meth:`consumption_outputs`.
        """
        return self.consumption_kwh * 1000.0 / self.floor_area_m2

    def consumption_outputs(self) -> tuple[str, ...]:
        """Catalogue outputs the consumption series sums (those of :attr:`consumption_end_uses`), catalogue
        order."""
        return cat.consumption_outputs(self.consumption_end_uses)

    def meters(self) -> list[tuple[str, np.ndarray, tuple[str, ...]]]:
        """Every meter of the site, the consumption first: ``[(column, Wh/m2 in each hour (weeks, 168), catalogue
        outputs it sums)]``."""
        out = [(MEASUREMENT_COLUMNS[2], self.consumption_wh_m2(), self.consumption_outputs())]
        if self.electricity_kwh is not None:
            wh_m2 = self.electricity_kwh * 1000.0 / self.floor_area_m2
            out.append((ELECTRICITY_COLUMN, wh_m2, cat.consumption_outputs(self.electricity_end_uses)))
        return out

    def setting_ranges(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``, each ``(13,)`` in catalogue order and units: the catalogue's range of every setting,
        narrowed to :attr:`setting_limits` where the site gives one."""
        lo = np.array([v.min for v in cat.SETTINGS])
        hi = np.array([v.max for v in cat.SETTINGS])
        for name, (low, high) in self.setting_limits.items():
            i = cat.SETTING_NAMES.index(name)
            lo[i], hi[i] = low, high
        return lo, hi

    def week_starts(self) -> list[dt.date]:
        """The Monday of each measured week (``weeks`` dates)."""
        return [self.start + dt.timedelta(days=7 * k) for k in range(self.weeks)]

    def start_hour_of_year(self, week: int) -> int:
        """Row of an EPW year (8760 hourly rows) where week ``week`` (0-based) starts.

        Hours since Jan 1 00:00 of the year the week's Monday falls in, counted on a 365-day year: in a
        leap year, days after Feb 28 are shifted back one day (EPW TMY files have no Feb 29; Feb 29 itself
        gets Feb 28's row). Range ``0 .. 8736``.
        """
        if not 0 <= week < self.weeks:
            raise SiteError(f"{self.path}: week {week} out of range 0..{self.weeks - 1}")
        return epw_day_of_year(self.start + dt.timedelta(days=7 * week)) * cat.HOURS_PER_DAY

    def epw_hours(self) -> np.ndarray:
        """Row of the EPW year for every measured hour, ``(weeks, 168)`` int in ``0 .. 8759``.

        Each day is matched to the same calendar day of the EPW year (Feb 29 to Feb 28); a week that runs
        past Dec 31 continues at the start of the EPW year.
        """
        return epw_hours(self.start, self.weeks)

    def weather_hours(self, shift_hours: int = 0) -> np.ndarray:
        """The site's weather over the measured weeks, ``(weeks, 168, len(catalogue.WEATHER_NAMES))``
        (``shift_hours`` later; -168: the week before each, the context of a site's first week included).

        Taken from ``buildenv.weather.epw.load_weather(self.weather).hourly`` (catalogue channels and units) at
        :meth:`epw_hours`: week ``k`` starts at :meth:`start_hour_of_year` and wraps to the start of the EPW
        year past Dec 31.

        Raises:
            WeatherError: the EPW file is missing or unreadable.
        """
        from buildenv.weather.epw import load_weather

        hourly = np.asarray(load_weather(self.weather).hourly)
        return hourly[(self.epw_hours() + shift_hours) % len(hourly)]

    def theta_known(self) -> dict[str, float]:
        """The building parameters the site fixes, catalogue units: the geometry (``floor_area_m2`` in m2,
        ``number_of_floors``) and whatever ``[known]`` declares."""
        return {
            "floor_area_m2": float(self.floor_area_m2),
            "number_of_floors": float(self.number_of_floors),
            **{k: float(v) for k, v in self.known.items()},
        }
