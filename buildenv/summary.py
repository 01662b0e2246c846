"""Figures a building engineer reads first from a simulated week."""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat


def week_summary(outputs: np.ndarray, occupancy_fraction: np.ndarray, floor_area_m2: float) -> dict[str, float]:
    """Totals and means of one week.

    Args:
        outputs: ``(168, 8)`` hourly outputs (Wh/m2 per hour, degC).
        occupancy_fraction: ``(168,)`` hourly occupancy (0-1).
        floor_area_m2: floor area used to turn Wh/m2 into kWh.
    Returns:
        ``{"<OUTPUT>_kwh": weekly total for each energy output, "heat_consumption_kwh": the paper's measured
        heat consumption (Q_HEAT_OFFICE + Q_AHU_H + Q_EQP + Q_LIGHT), "t_int_occupied_mean_c",
        "t_int_unoccupied_mean_c", "t_int_min_c", "t_int_max_c"}``.
    """
    out = {name: outputs[:, i] for i, name in enumerate(cat.OUTPUT_NAMES)}
    occupied = np.asarray(occupancy_fraction) > 0
    summary: dict[str, float] = {}
    for name in cat.OUTPUT_NAMES:
        if name not in cat.TEMPERATURE_OUTPUTS:
            summary[f"{name}_kwh"] = float(out[name].sum() * floor_area_m2 / 1000.0)
    summary["heat_consumption_kwh"] = float(sum(summary[f"{n}_kwh"] for n in cat.HEAT_CONSUMPTION_OUTPUTS))
    t_int = out["T_INT_OFFICE"]
    summary["t_int_occupied_mean_c"] = float(t_int[occupied].mean()) if occupied.any() else float("nan")
    summary["t_int_unoccupied_mean_c"] = float(t_int[~occupied].mean()) if (~occupied).any() else float("nan")
    summary["t_int_min_c"] = float(t_int.min())
    summary["t_int_max_c"] = float(t_int.max())
    return summary
