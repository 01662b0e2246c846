"""Hourly encoding of the weekly settings (I_k) and occupancy (O_k).

The same function feeds EnergyPlus (through Schedule:File columns) and the metamodel (as input channels),
so the simulator and the metamodel always see identical hourly schedules.

Conventions: a week starts Monday 00:00; hour ``h`` of a day covers ``[h, h+1)``. A period "from start to
end" is in force for hours ``start <= h < end``; on a day whose ``hvac_operating`` is 0 no period is in force (the
setbacks hold all day, the air handling unit is off). Weekends are unoccupied. Where a day's heating setpoint
in force would not be below its cooling setpoint (the catalogue ranges overlap: heating comfort 22-24 degC,
cooling comfort 20-24 degC), the cooling setpoint is raised to heating + ``DEADBAND_K``, as a BMS
interlock does; the encoded cooling setpoint is the one in force.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

DEADBAND_K = 0.5

#: Hourly channels derived from settings and occupancy, in this order.
HOURLY_CHANNELS: tuple[str, ...] = (
    "heating_setpoint_c",  # heating setpoint in force, degC
    "cooling_setpoint_c",  # cooling setpoint in force, degC
    "heating_comfort_on",  # 1 during the heating comfort period, else 0
    "cooling_comfort_on",  # 1 during the cooling comfort period, else 0
    "ventilation_on",  # 1 while the air handling unit runs, else 0
    "ventilation_ach",  # outdoor air supplied, air changes per hour (0 when off)
    "supply_air_c",  # AHU supply air temperature setpoint of the day, degC
    "occupancy_fraction",  # share of the design occupants present, 0-1
)


def _index(name: str, group: str) -> int:
    return [v.name for v in cat.GROUPS[group]].index(name)


def _period_mask(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(weeks, days) start/end hours -> (weeks, days, 24) mask of hours in [start, end)."""
    hours = np.arange(cat.HOURS_PER_DAY)
    return (hours >= start[..., None]) & (hours < end[..., None])


def hourly_schedules(settings: np.ndarray, occupancy: np.ndarray) -> dict[str, np.ndarray]:
    """Expand daily settings and weekday occupancy into hourly series.

    Args:
        settings: I_k, shape ``(weeks, 7, 13)`` (day, setting in catalogue order), physical units; ``(weeks, 7, 13)``
            from before ``hvac_operating`` reads every day as operating.
        occupancy: O_k, shape ``(weeks, 5, 2)`` (weekday, [start hour, end hour]).

    Returns:
        ``{channel: array (weeks, 168)}`` for every name in :data:`HOURLY_CHANNELS`.
    """
    settings = cat.upgrade_settings(settings)
    occupancy = np.asarray(occupancy, dtype=float)
    if settings.ndim == 2:
        settings = settings[None]
    if occupancy.ndim == 2:
        occupancy = occupancy[None]
    weeks = settings.shape[0]

    def col(name: str) -> np.ndarray:
        return settings[..., _index(name, "settings")]

    day_on = (col("hvac_operating") >= 0.5)[..., None]
    heat_on = _period_mask(col("heating_start_hour"), col("heating_end_hour")) & day_on
    cool_on = _period_mask(col("cooling_start_hour"), col("cooling_end_hour")) & day_on
    vent_on = _period_mask(col("ventilation_start_hour"), col("ventilation_end_hour")) & day_on
    heat_sp = np.where(heat_on, col("heating_comfort_c")[..., None], col("heating_setback_c")[..., None])
    cool_sp = np.where(cool_on, col("cooling_comfort_c")[..., None], col("cooling_setback_c")[..., None])
    cool_sp = np.maximum(cool_sp, heat_sp + DEADBAND_K)
    vent_ach = np.where(vent_on, col("ventilation_ach")[..., None], 0.0)
    supply = np.broadcast_to(col("supply_air_c")[..., None], heat_sp.shape)

    occ = np.zeros((weeks, 7, cat.HOURS_PER_DAY))
    occ[:, :5] = _period_mask(
        occupancy[..., _index("occupancy_start_hour", "occupancy")],
        occupancy[..., _index("occupancy_end_hour", "occupancy")],
    )
    series = {
        "heating_setpoint_c": heat_sp,
        "cooling_setpoint_c": cool_sp,
        "heating_comfort_on": heat_on,
        "cooling_comfort_on": cool_on,
        "ventilation_on": vent_on,
        "ventilation_ach": vent_ach,
        "supply_air_c": supply,
        "occupancy_fraction": occ,
    }
    return {k: np.asarray(v, dtype=float).reshape(weeks, cat.HOURS_PER_WEEK) for k, v in series.items()}


def hourly_encoding(settings: np.ndarray, occupancy: np.ndarray) -> np.ndarray:
    """The hourly schedules stacked as channels: shape ``(weeks, 168, len(HOURLY_CHANNELS))``."""
    series = hourly_schedules(settings, occupancy)
    return np.stack([series[name] for name in HOURLY_CHANNELS], axis=-1)


def usage_fraction(occupancy_fraction: np.ndarray, night_percent: float) -> np.ndarray:
    """Lighting or equipment use as a fraction of the occupied level: 1 when occupied, night% / 100 otherwise."""
    night = float(night_percent) / 100.0
    return night + (1.0 - night) * np.asarray(occupancy_fraction, dtype=float)
