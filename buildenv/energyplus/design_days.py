"""A reference model sized for the climate it runs in: design days and location derived from the site's EPW.

The shipped reference offices carry the design days of their own city (Chicago, Denver). Run in another climate they
would keep that city's heating and cooling capacities. :func:`climate_design_days` replaces the model's
``Site:Location`` and its heating and cooling ``SizingPeriod:DesignDay`` with those of the weather file, defined as
ASHRAE defines annual design conditions but read off the file's own hours:

- heating: the dry-bulb temperature exceeded in 99.6 % of the hours, no daily range, saturated air;
- cooling: the dry-bulb temperature exceeded in 0.4 % of the hours with the mean dew point of the hottest 1 % of
  hours, and the mean daily range of the hottest month;
- each on the 21st of the month holding most of its extreme hours, with the file's mean station pressure and the
  mean wind speed of those hours.

A model whose own location lies within :data:`SAME_LOCATION_KM` of the weather station keeps its design days.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from buildenv.energyplus.idf import IdfObject, of_type

#: a weather station this close to the model's own location is taken as the model's own climate, km
SAME_LOCATION_KM = 50.0
HEATING_PERCENTILE, COOLING_PERCENTILE = 0.4, 99.6
#: share of the hottest (coldest) hours whose coincident conditions define the design day, percent
COINCIDENT_PERCENT = 1.0


def _distance_km(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance between two points given in degrees, km."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * 6371.0 * math.asin(math.sqrt(a))


@functools.lru_cache(maxsize=32)
def design_conditions(epw: Path) -> dict:
    """The design conditions of an EPW (module docstring): ``{"location": {...}, "heating": {...}, "cooling": {...}}``
    with temperatures in degC, pressure in Pa and wind speed in m/s."""
    import pvlib

    data, meta = pvlib.iotools.read_epw(str(epw), coerce_year=2001)
    t = data["temp_air"].to_numpy(float)
    dew = data["temp_dew"].to_numpy(float)
    wind = data["wind_speed"].to_numpy(float)
    month = data.index.month.to_numpy()
    pressure = float(np.nanmean(data["atmospheric_pressure"].to_numpy(float)))
    cold = t <= np.percentile(t, COINCIDENT_PERCENT)
    hot = t >= np.percentile(t, 100.0 - COINCIDENT_PERCENT)
    cold_month, hot_month = int(np.bincount(month[cold]).argmax()), int(np.bincount(month[hot]).argmax())
    days = t[: len(t) // 24 * 24].reshape(-1, 24)
    day_month = month[: len(t) // 24 * 24].reshape(-1, 24)[:, 0]
    daily_range = float(np.mean(days.max(axis=1)[day_month == hot_month] - days.min(axis=1)[day_month == hot_month]))
    heating_db = float(np.percentile(t, HEATING_PERCENTILE))
    return {
        "location": {
            "name": f"{meta['city']} {meta['state-prov']} {meta['country']} (weather file)",
            "latitude": float(meta["latitude"]),
            "longitude": float(meta["longitude"]),
            "time_zone": float(meta["TZ"]),
            "elevation_m": float(meta["altitude"]),
        },
        "heating": {
            "month": cold_month,
            "dry_bulb_c": round(heating_db, 1),
            "dew_point_c": round(heating_db, 1),
            "daily_range_k": 0.0,
            "wind_m_s": round(float(np.mean(wind[cold])), 1),
            "pressure_pa": round(pressure),
        },
        "cooling": {
            "month": hot_month,
            "dry_bulb_c": round(float(np.percentile(t, COOLING_PERCENTILE)), 1),
            "dew_point_c": round(float(np.mean(dew[hot])), 1),
            "daily_range_k": round(daily_range, 1),
            "wind_m_s": round(float(np.mean(wind[hot])), 1),
            "pressure_pa": round(pressure),
        },
    }


def _design_day(template: IdfObject, name: str, c: dict) -> IdfObject:
    """``template`` (a SizingPeriod:DesignDay) with the conditions ``c`` of :func:`design_conditions`."""
    o = list(template) + [""] * max(0, 27 - len(template))
    o[1], o[2], o[3] = name, str(c["month"]), "21"
    o[5], o[6] = f"{c['dry_bulb_c']:.1f}", f"{c['daily_range_k']:.1f}"
    o[9], o[10] = "DewPoint", f"{c['dew_point_c']:.1f}"
    o[11:15] = ["", "", "", ""]
    o[15], o[16] = str(c["pressure_pa"]), f"{c['wind_m_s']:.1f}"
    return o


def climate_design_days(objects: list[IdfObject], epw: Path) -> list[IdfObject]:
    """``objects`` with the location and the heating and cooling design days of the weather file ``epw``.

    Unchanged when the model's ``Site:Location`` is within :data:`SAME_LOCATION_KM` of the station, or when the model
    lacks a location or a heating or cooling design day.
    """
    location = of_type(objects, "Site:Location")
    days = of_type(objects, "SizingPeriod:DesignDay")
    heating = [d for d in days if len(d) > 4 and d[4].lower() == "winterdesignday"]
    cooling = [d for d in days if len(d) > 4 and d[4].lower() == "summerdesignday"]
    if not location or not heating or not cooling:
        return objects
    c = design_conditions(Path(epw))
    loc = c["location"]
    if (
        _distance_km(float(location[0][2]), float(location[0][3]), loc["latitude"], loc["longitude"])
        <= SAME_LOCATION_KM
    ):
        return objects
    out = []
    for o in objects:
        kind = o[0].lower()
        if kind == "site:location":
            o = ["Site:Location", loc["name"], *(str(loc[k]) for k in ("latitude", "longitude", "time_zone"))]
            o.append(str(loc["elevation_m"]))
        elif kind == "sizingperiod:designday":
            if o is heating[0]:
                o = _design_day(o, "buildenv heating 99.6 % from the weather file", c["heating"])
            elif o is cooling[0]:
                o = _design_day(o, "buildenv cooling 0.4 % from the weather file", c["cooling"])
            else:
                continue  # further design days of the model's own city
        out.append(o)
    return out
