"""Plots with the paper's conventions: hourly series over a week, occupied hours shaded green."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from buildenv import catalogue as cat


def save_figure(fig, path: str | Path, dpi: int = 110) -> Path:
    """Lay out ``fig``, write it as a PNG at ``path`` (its folder is created), close it and return the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def shade_occupancy(ax, occupancy_fraction: np.ndarray) -> None:
    """Shade the occupied hours (occupancy fraction > 0) of an hourly axis in green."""
    occupied = np.asarray(occupancy_fraction) > 0
    start = None
    for h, on in enumerate(np.append(occupied, False)):
        if on and start is None:
            start = h
        elif not on and start is not None:
            ax.axvspan(start, h, color="tab:green", alpha=0.15, lw=0)
            start = None


def plot_week(
    outputs: np.ndarray, weather: np.ndarray, schedules: dict[str, np.ndarray], path: Path, title: str = ""
) -> Path:
    """Plot one simulated week: temperatures (top) and heating/cooling energies (bottom).

    Args:
        outputs: ``(168, 8)`` hourly outputs in catalogue order.
        weather: ``(168, 9)`` hourly weather in catalogue order.
        schedules: hourly schedules of the week (``buildenv.schedules.hourly_schedules`` for one week,
            arrays of shape ``(168,)``); occupied hours are shaded, setpoints drawn.
        path: PNG file to write.
        title: figure title.
    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hours = np.arange(cat.HOURS_PER_WEEK)
    out = {name: outputs[:, i] for i, name in enumerate(cat.OUTPUT_NAMES)}
    fig, (ax_t, ax_q) = plt.subplots(2, 1, figsize=(12, 6.5), sharex=True)
    for ax in (ax_t, ax_q):
        shade_occupancy(ax, schedules["occupancy_fraction"])
        ax.grid(alpha=0.3)
    ax_t.plot(hours, out["T_INT_OFFICE"], color="black", lw=1.6, label="indoor (T_INT_OFFICE)")
    ax_t.plot(hours, weather[:, cat.WEATHER_NAMES.index("TAMB")], color="tab:gray", lw=1, label="outdoor (TAMB)")
    ax_t.step(
        hours, schedules["heating_setpoint_c"], where="post", color="tab:red", lw=0.8, ls="--", label="heating setpoint"
    )
    ax_t.step(
        hours,
        schedules["cooling_setpoint_c"],
        where="post",
        color="tab:blue",
        lw=0.8,
        ls="--",
        label="cooling setpoint",
    )
    ax_t.set_ylabel("temperature (degC)")
    ax_t.legend(loc="upper right", fontsize=8, ncol=4)
    for name, color in (
        ("Q_HEAT_OFFICE", "tab:red"),
        ("Q_AHU_H", "tab:orange"),
        ("Q_AC_OFFICE", "tab:blue"),
        ("Q_AHU_C", "tab:cyan"),
        ("Q_EQP", "tab:purple"),
        ("Q_LIGHT", "goldenrod"),
    ):
        ax_q.plot(hours, out[name], color=color, lw=1.1, label=name)
    ax_q.set_ylabel("energy in the hour (Wh/m2)")
    ax_q.set_xlabel("hour of the week (Monday 00:00 = 0); green: occupied")
    ax_q.set_xticks(range(0, cat.HOURS_PER_WEEK + 1, 24))
    ax_q.set_xlim(0, cat.HOURS_PER_WEEK)
    ax_q.legend(loc="upper right", fontsize=8, ncol=6)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi=110)
