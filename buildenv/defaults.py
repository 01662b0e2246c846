"""The shipped default building and its typical historical BMS settings.

A 5,000 m2, 3-storey office (about the size of the DOE medium reference office) in Chicago, run with the
settings a facility manager would typically leave in place: heating comfort 22 degC from 07:00 to 18:00
with an 18 degC setback, cooling comfort 24 degC from 08:00 to 19:00 with a 28 degC setback, air handling
unit from 07:00 to 19:00 at 1.0 air change per hour and 19 degC supply, occupants 08:00-18:00 on weekdays.
Weekend days keep the same clock times (the BMS has one weekly program) — only occupancy differs.
Every value is validated against the catalogue when used.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

DEFAULT_EPW = "usa_il_chicago"

DEFAULT_THETA: dict[str, float] = {
    "floor_area_m2": 5000,
    "number_of_floors": 3,
    "infiltration_ach": 0.3,
    "infiltration_fans_on_share": 1.0,
    "heat_recovery_effectiveness": 0.0,
    "minimum_supply_air_ach": 0.0,
    "night_cycle_heating_share": 0.0,
    "economiser_share": 0.0,
    "capacitance_kj_per_k_m3": 150,
    "heating_power_w_m2": 60,
    "cooling_power_w_m2": 80,
    "occupant_density_per_m2": 0.05,
    "plug_load_w_m2": 8.25,
    "lighting_power_w_m2": 10.0,
    "light_night_percent": 10,
    "pc_night_percent": 30,
    "wall_insulation_north_m": 0.1,
    "wall_insulation_east_m": 0.1,
    "wall_insulation_south_m": 0.1,
    "wall_insulation_west_m": 0.1,
    "roof_insulation_m": 0.1,
    "window_to_wall_north_percent": 35,
    "window_to_wall_east_percent": 35,
    "window_to_wall_south_percent": 35,
    "window_to_wall_west_percent": 35,
}

DEFAULT_DAY_SETTINGS: dict[str, float] = {
    "cooling_start_hour": 8,
    "cooling_end_hour": 19,
    "cooling_setback_c": 28,
    "cooling_comfort_c": 24,
    "heating_start_hour": 7,
    "heating_end_hour": 18,
    "heating_setback_c": 18,
    "heating_comfort_c": 22,
    "ventilation_start_hour": 7,
    "ventilation_end_hour": 19,
    "supply_air_c": 19,
    "ventilation_ach": 1.0,
    "hvac_operating": 1,
}

DEFAULT_OCCUPANCY_DAY: dict[str, float] = {"occupancy_start_hour": 8, "occupancy_end_hour": 18}


def default_theta() -> np.ndarray:
    """theta_build of the default building, catalogue order, shape ``(21,)``."""
    return cat.from_mapping("theta_build", DEFAULT_THETA, where="default building")


def default_week(weeks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Historical settings ``(weeks, 7, 13)`` and occupancy ``(weeks, 5, 2)`` of the default building."""
    day = np.array([DEFAULT_DAY_SETTINGS[n] for n in cat.SETTING_NAMES], dtype=float)
    occ = np.array([DEFAULT_OCCUPANCY_DAY[n] for n in cat.OCCUPANCY_NAMES], dtype=float)
    settings = np.tile(day, (weeks, 7, 1))
    occupancy = np.tile(occ, (weeks, 5, 1))
    cat.check_values("settings", settings, "default settings")
    cat.check_values("occupancy", occupancy, "default occupancy")
    return settings, occupancy
