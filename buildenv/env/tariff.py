"""Time-of-use electricity tariffs: what an hour of HVAC energy costs in BuildingWeek-v0 (``price=``).

A :class:`Tariff` has two prices, currency per kWh: ``peak`` in the peak hours ``[start, end)`` (whole hours of
the local clock, 0-24) of the peak days, ``offpeak`` in every other hour. The peak days are ``"weekdays"``
(Monday to Friday, default), ``"all"`` or a list of days (names ``"monday"``..``"sunday"`` or ISO weekday
indices 0-6, Monday 0); dates in ``holidays`` are off-peak all day. :meth:`Tariff.hourly` lays the prices on a
week's actual dates, ``(168,)`` from Monday 00:00, in the weather file's hours (local standard time; daylight
saving time is not applied). The currency is whatever the prices are in; only ratios reach the reward.

:func:`tariff_from` turns the environment's ``price=`` argument into a :class:`Tariff`: None (no tariff), a
preset name (:data:`PRESETS`: ``"tou"``, a typical two-rate commercial tariff, 0.25 peak 08-20 on weekdays, 0.10
otherwise; ``"flat"``, 0.15 every hour), a dict of :class:`Tariff`'s fields, or a :class:`Tariff`. Bad values
raise :class:`buildenv.errors.BuildingEnvError` with one line saying which and what to give.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import numbers
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
    """A two-rate time-of-use tariff.

    Attributes:
        peak: price in the peak hours of the peak days, currency per kWh (> 0).
        offpeak: price in every other hour, currency per kWh (> 0).
        peak_hours: ``(start, end)`` whole hours, ``0 <= start < end <= 24``; hour h of a day is peak when
            ``start <= h < end``.
        peak_days: ISO weekday indices (Monday 0) with peak hours.
        holidays: dates priced off-peak all day.
    """

    peak: float
    offpeak: float
    peak_hours: tuple[int, int] = (8, 20)
    peak_days: tuple[int, ...] = _DAY_SETS["weekdays"]
    holidays: tuple[dt.date, ...] = ()

    def hourly(self, monday: dt.date) -> np.ndarray:
        """Prices ``(168,)`` (currency per kWh) of the week from ``monday`` 00:00, hour by hour."""
        start, end = self.peak_hours
        hours = np.arange(cat.HOURS_PER_DAY)
        peak_hour = (hours >= start) & (hours < end)
        prices = np.full((len(cat.DAYS), cat.HOURS_PER_DAY), self.offpeak, dtype=float)
        for d in range(len(cat.DAYS)):
            day = monday + dt.timedelta(days=d)
            if day.weekday() in self.peak_days and day not in self.holidays:
                prices[d, peak_hour] = self.peak
        return prices.reshape(-1)


def _price(name: str, value: Any, where: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or x <= 0:
        raise BuildingEnvError(f"{where}: {name}={value!r}; give a positive price, currency per kWh")
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


def _dates(value: Any, where: str) -> tuple[dt.date, ...]:
    try:
        if isinstance(value, (str, dt.date)):
            raise TypeError
        return tuple(d if isinstance(d, dt.date) else dt.date.fromisoformat(d) for d in value)
    except (TypeError, ValueError):
        raise BuildingEnvError(
            f"{where}: holidays={value!r}; give a list of dates (datetime.date or 'YYYY-MM-DD')"
        ) from None


def tariff_from(price: str | Mapping[str, Any] | Tariff | None, where: str = "price") -> Tariff | None:
    """The :class:`Tariff` of a ``price=`` argument (see the module docstring); None for None.

    Raises:
        BuildingEnvError: an unknown preset, an unknown key, a price not > 0, peak hours outside 0-24 or not
            ``start < end``, unknown peak days or holidays that are not dates (one line each).
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
    fields = [f.name for f in dataclasses.fields(Tariff)]
    unknown = sorted(set(price) - set(fields))
    missing = [k for k in ("peak", "offpeak") if k not in price]
    if unknown or missing:
        what = f"unknown key(s) {', '.join(map(str, unknown))}" if unknown else f"missing {', '.join(missing)}"
        raise BuildingEnvError(f"{where}: price has {what}; give peak and offpeak, optionally {', '.join(fields[2:])}")
    return Tariff(
        peak=_price("peak", price["peak"], where),
        offpeak=_price("offpeak", price["offpeak"], where),
        peak_hours=_hours(price.get("peak_hours", (8, 20)), where),
        peak_days=_days(price.get("peak_days", "weekdays"), where),
        holidays=_dates(price.get("holidays", ()), where),
    )


def weekly_cost(hvac_wh_m2: np.ndarray, prices: np.ndarray, floor_area_m2: float) -> np.ndarray:
    """Cost (currency) of hourly HVAC energy ``(..., 168)`` (Wh/m2 in each hour) at hourly prices ``(..., 168)``
    (currency per kWh) over ``floor_area_m2`` -> ``(...)``."""
    return (np.asarray(hvac_wh_m2) * np.asarray(prices)).sum(-1) * float(floor_area_m2) / 1000.0
