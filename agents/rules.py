"""A rule-based weekly schedule, the baseline a careful facility manager would set by hand.

Occupancy-following periods with deep setbacks: on working days heating comfort (22.5 degC, the comfort
target) starts one hour before the calibrated arrival and stops one hour before departure (the building
coasts), cooling comfort (24 degC) and ventilation (1.0 air change per hour, 19 degC supply) cover the
occupied hours; setbacks are 17 degC (heating) and 30 degC (cooling). Weekends are set back entirely
(``hvac_operating`` 0); where the environment cannot act on that (a metamodel that knows operating days only), every
weekend period is as short as the catalogue allows, with 22 degC heating comfort and 0.7 air changes per hour.
Every value is snapped into the catalogue range by the action encoding.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

WORKDAY = {
    "heating_comfort_c": 22.5,
    "heating_setback_c": 17.0,
    "cooling_comfort_c": 24.0,
    "cooling_setback_c": 30.0,
    "supply_air_c": 19.0,
    "ventilation_ach": 1.0,
    "hvac_operating": 1.0,
}
WEEKEND = {
    "heating_comfort_c": 22.0,
    "heating_setback_c": 17.0,
    "cooling_comfort_c": 24.0,
    "cooling_setback_c": 30.0,
    "supply_air_c": 19.0,
    "ventilation_ach": 0.7,
    "hvac_operating": 0.0,
}


def rule_based_settings(occupancy: np.ndarray) -> np.ndarray:
    """Settings ``(7, 13)`` that follow the weekday occupancy ``(5, 2)`` (arrival, departure hours)."""
    settings = np.zeros((len(cat.DAYS), len(cat.SETTINGS)))
    col = {name: j for j, name in enumerate(cat.SETTING_NAMES)}
    for d in range(len(cat.DAYS)):
        if d < len(cat.WEEKDAYS):
            arrive, leave = np.round(occupancy[d])
            hours = {
                "heating_start_hour": arrive - 1,
                "heating_end_hour": leave - 1,
                "cooling_start_hour": arrive,
                "cooling_end_hour": leave,
                "ventilation_start_hour": arrive,
                "ventilation_end_hour": leave,
            }
            values = {**WORKDAY, **hours}
        else:
            values = {
                **WEEKEND,
                **{
                    n: cat.get(n).min if n.endswith("_end_hour") else cat.get(n).max
                    for n in cat.SETTING_NAMES
                    if n.endswith("_hour")
                },
            }
        for name, value in values.items():
            settings[d, col[name]] = cat.get(name).snap(value)
    return settings


def rule_based_action(env) -> np.ndarray:
    """The rule-based schedule of an environment's calibrated occupancy, as an action."""
    base = env.unwrapped
    return base.encode(rule_based_settings(base.site_model.occupancy))
