"""Time-of-use tariffs: what an hour of HVAC costs in BuildingWeek-v0 (``price=``).

A :class:`Tariff` has two prices, currency per kWh of energy bought: ``peak`` in the peak hours ``[start, end)``
(whole hours of the local clock, 0-24) of the peak days, ``offpeak`` in every other hour. The peak days are
``"weekdays"`` (Monday to Friday, default), ``"all"`` or a list of days (names ``"monday"``..``"sunday"`` or ISO
weekday indices 0-6, Monday 0); dates in ``holidays`` are off-peak all day. :meth:`Tariff.hourly` lays the prices on
a week's actual dates, ``(168,)`` from Monday 00:00 in the weather file's hours (local standard time). Without
``time_zone`` the peak window is read in those standard-time hours; with an IANA ``time_zone`` (``"America/Chicago"``)
it follows the local clock, so on daylight saving days it covers the standard-time hours one hour earlier.

The metamodel gives the heating and cooling *delivered*; the tariff prices the energy *bought*
(:meth:`Tariff.bought_wh_m2`): cooling delivered / ``cooling_cop`` (default 3.0, a typical chiller's seasonal
COP) + heating delivered / ``heating_efficiency`` (default 1.0, electric resistance heating; e.g. 0.9 for a gas
boiler when the prices are the gas prices). The currency is whatever the prices are in; only ratios reach the
reward.

:func:`tariff_from` turns the environment's ``price=`` argument into a :class:`Tariff`: None (no tariff), a
preset name (:data:`PRESETS`: ``"tou"``, a typical two-rate commercial tariff, 0.25 peak 08-20 on weekdays, 0.10
otherwise; ``"flat"``, 0.15 every hour), a dict of :class:`Tariff`'s fields, or a :class:`Tariff` (which checks its
fields itself). Bad values raise :class:`buildenv.errors.BuildingEnvError` with one line saying which and what to
give.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import math
import numbers
import zoneinfo
from collections.abc import Mapping
from typing import Any

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildingEnvError

#: named tariffs ``price=`` accepts (currency per kWh)
PRESETS: dict[str, dict[str, Any]] = {
    "tou": {"peak": 0.25, "offpeak": 0.10, "peak_hours": (8, 20), "peak_days": "weekdays"},
    "flat": {"peak": 0.15, "offpeak": 0.15, "peak_hours": (0, 24), "peak_days": "all"},
}
_DAY_SETS = {"weekdays": tuple(range(5)), "all": tuple(range(7)), "weekends": (5, 6)}


@dataclasses.dataclass(frozen=True)
class Tariff:
    """A two-rate time-of-use tariff on the energy bought for HVAC (see the module docstring).

    Attributes:
        peak: price in the peak hours of the peak days, currency per kWh bought (> 0).
        offpeak: price in every other hour, currency per kWh bought (> 0).
        peak_hours: ``(start, end)`` whole hours, ``0 <= start < end <= 24``; hour h of a day is peak when
            ``start <= h < end`` (h of the local clock with ``time_zone``, else of standard time).
        peak_days: ISO weekday indices (Monday 0) with peak hours (or ``"weekdays"``, ``"all"``, day names).
        holidays: dates priced off-peak all day (``datetime.date``, ``datetime``/``pandas.Timestamp`` or
            ``"YYYY-MM-DD"``; kept as dates).
        cooling_cop: cooling delivered per energy bought (> 0; default 3.0, a typical chiller's seasonal COP).
        heating_efficiency: heating delivered per energy bought (> 0; default 1.0, electric heating; 0.9 for a
            gas boiler when the prices are gas prices).
        time_zone: an IANA time zone name (``zoneinfo``) whose clock the peak hours follow, daylight saving
            included; None (default): the weather file's standard time.

    Raises:
        BuildingEnvError: a field out of range (one line; fields are checked and normalised on construction).
    """

    peak: float
    offpeak: float
    peak_hours: tuple[int, int] = (8, 20)
    peak_days: tuple[int, ...] = _DAY_SETS["weekdays"]
    holidays: tuple[dt.date, ...] = ()
    cooling_cop: float = 3.0
    heating_efficiency: float = 1.0
    time_zone: str | None = None

    def __post_init__(self) -> None:
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        for name, value in _checked(values, "Tariff").items():
            object.__setattr__(self, name, value)

    def hourly(self, monday: dt.date) -> np.ndarray:
        """Prices ``(168,)`` (currency per kWh) of the week from ``monday`` 00:00 standard time, hour by hour."""
        return _hourly(self, monday).copy()

    def bought_wh_m2(self, outputs: np.ndarray) -> np.ndarray:
        """Hourly energy bought for HVAC (Wh/m2) ``(..., 168)`` of metamodel outputs ``(..., 168, 8)``: cooling
        delivered / ``cooling_cop`` + heating delivered / ``heating_efficiency``, each output counted from 0 (as
        :func:`buildenv.env.objectives.hvac_energy_hourly`)."""
        outputs = np.asarray(outputs)

        def delivered(use: str) -> np.ndarray:
            idx = [cat.OUTPUT_NAMES.index(n) for n in cat.END_USE_OUTPUTS[use]]
            return np.maximum(outputs[..., idx], 0.0).sum(-1)

        return delivered("cooling") / self.cooling_cop + delivered("heating") / self.heating_efficiency


@functools.lru_cache(maxsize=1024)
def _hourly(tariff: Tariff, monday: dt.date) -> np.ndarray:
    start, end = tariff.peak_hours
    zone = None if tariff.time_zone is None else zoneinfo.ZoneInfo(tariff.time_zone)
    prices = np.full(cat.HOURS_PER_WEEK, tariff.offpeak, dtype=float)
    for h in range(cat.HOURS_PER_WEEK):
        t = dt.datetime.combine(monday, dt.time()) + dt.timedelta(hours=h)  # standard time
        if zone is not None:  # the local clock at that instant
            here = t.replace(tzinfo=zone)
            utc = t - (here.utcoffset() - here.dst())
            t = utc.replace(tzinfo=dt.timezone.utc).astimezone(zone).replace(tzinfo=None)
        if t.weekday() in tariff.peak_days and t.date() not in tariff.holidays and start <= t.hour < end:
            prices[h] = tariff.peak
    prices.flags.writeable = False
    return prices


def _positive(name: str, value: Any, where: str, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or x <= 0:
        raise BuildingEnvError(f"{where}: {name}={value!r}; give {what}")
    return x


def _hours(value: Any, where: str) -> tuple[int, int]:
    bad = BuildingEnvError(f"{where}: peak_hours={value!r}; give (start, end) whole hours with 0 <= start < end <= 24")
    try:
        start, end = value
    except (TypeError, ValueError):
        raise bad from None
    whole = [
        isinstance(h, numbers.Integral) or (isinstance(h, float) and h.is_integer())
        for h in (start, end)
        if not isinstance(h, bool)
    ]
    if len(whole) != 2 or not all(whole) or not 0 <= start < end <= 24:
        raise bad
    return int(start), int(end)


def _days(value: Any, where: str) -> tuple[int, ...]:
    if isinstance(value, str) and value in _DAY_SETS:
        return _DAY_SETS[value]
    days = []
    try:
        for d in [value] if isinstance(value, str) else value:
            if isinstance(d, str) and d.lower() in cat.DAYS:
                days.append(cat.DAYS.index(d.lower()))
            elif isinstance(d, numbers.Integral) and not isinstance(d, bool) and 0 <= d < 7:
                days.append(int(d))
            else:
                raise ValueError
    except (TypeError, ValueError):
        raise BuildingEnvError(
            f"{where}: peak_days={value!r}; give {', '.join(repr(k) for k in _DAY_SETS)} or a list of days "
            "('monday'..'sunday' or 0-6, Monday 0)"
        ) from None
    return tuple(sorted(set(days)))


def _date(d: Any) -> dt.date:
    """A date of a ``date``, a ``datetime`` (``pandas.Timestamp``; its calendar day) or ``"YYYY-MM-DD"``."""
    if isinstance(d, dt.datetime):
        return d.date()
    return d if isinstance(d, dt.date) else dt.date.fromisoformat(d)


def _dates(value: Any, where: str) -> tuple[dt.date, ...]:
    try:
        if isinstance(value, (str, dt.date)):
            raise TypeError
        return tuple(_date(d) for d in value)
    except (TypeError, ValueError):
        raise BuildingEnvError(
            f"{where}: holidays={value!r}; give a list of dates (datetime.date or 'YYYY-MM-DD')"
        ) from None


def _zone(value: Any, where: str) -> str | None:
    try:
        return None if value is None else zoneinfo.ZoneInfo(value).key
    except (zoneinfo.ZoneInfoNotFoundError, ValueError, TypeError):
        raise BuildingEnvError(
            f"{where}: time_zone={value!r} is no IANA time zone; give a name such as 'America/Chicago' or None "
            "(the weather file's standard time)"
        ) from None


def _checked(values: Mapping[str, Any], where: str) -> dict[str, Any]:
    """:class:`Tariff`'s fields from ``values`` (all of them), checked and normalised; one line on a bad one."""
    price = "a positive price, currency per kWh"
    return {
        "peak": _positive("peak", values["peak"], where, price),
        "offpeak": _positive("offpeak", values["offpeak"], where, price),
        "peak_hours": _hours(values["peak_hours"], where),
        "peak_days": _days(values["peak_days"], where),
        "holidays": _dates(values["holidays"], where),
        "cooling_cop": _positive("cooling_cop", values["cooling_cop"], where, "a number > 0 (3.0: a typical chiller)"),
        "heating_efficiency": _positive(
            "heating_efficiency", values["heating_efficiency"], where, "a number > 0 (1.0: electric; 0.9: gas boiler)"
        ),
        "time_zone": _zone(values["time_zone"], where),
    }


def tariff_from(price: str | Mapping[str, Any] | Tariff | None, where: str = "price") -> Tariff | None:
    """The :class:`Tariff` of a ``price=`` argument (see the module docstring); None for None.

    Raises:
        BuildingEnvError: an unknown preset, an unknown key, a price, COP or efficiency not > 0, peak hours outside
            0-24 or not ``start < end``, unknown peak days, holidays that are not dates or an unknown time zone
            (one line each).
    """
    if price is None or isinstance(price, Tariff):
        return price
    if isinstance(price, str):
        if price not in PRESETS:
            raise BuildingEnvError(
                f"{where}: price={price!r} is no preset; choose one of {', '.join(PRESETS)} or give a dict "
                "such as {'peak': 0.25, 'offpeak': 0.10, 'peak_hours': (8, 20), 'peak_days': 'weekdays'}"
            )
        price = PRESETS[price]
    if not isinstance(price, Mapping):
        raise BuildingEnvError(
            f"{where}: price={price!r}; give None, a preset ({', '.join(PRESETS)}) or a dict of "
            f"{', '.join(f.name for f in dataclasses.fields(Tariff))}"
        )
    fields = {f.name: f.default for f in dataclasses.fields(Tariff)}
    unknown = sorted(set(price) - set(fields))
    missing = [k for k in ("peak", "offpeak") if k not in price]
    if unknown or missing:
        what = f"unknown key(s) {', '.join(map(str, unknown))}" if unknown else f"missing {', '.join(missing)}"
        optional = ", ".join(list(fields)[2:])
        raise BuildingEnvError(f"{where}: price has {what}; give peak and offpeak, optionally {optional}")
    return Tariff(**_checked({**fields, **price}, where))


def weekly_cost(bought_wh_m2: np.ndarray, prices: np.ndarray, floor_area_m2: float) -> np.ndarray:
    """Cost (currency) of hourly energy bought ``(..., 168)`` (Wh/m2 in each hour, :meth:`Tariff.bought_wh_m2`)
    at hourly prices ``(..., 168)`` (currency per kWh) over ``floor_area_m2`` -> ``(...)``."""
    return (np.asarray(bought_wh_m2) * np.asarray(prices)).sum(-1) * float(floor_area_m2) / 1000.0
