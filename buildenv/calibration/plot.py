"""The paper's calibration figure: measured vs calibrated temperature and consumption, occupancy shaded."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from buildenv.calibration.problem import build_problem, calibrated_parameters, predict_meters, problem_occupancy
from buildenv.metamodel import surrogate as sg
from buildenv.plotting import save_figure, shade_occupancy


def plot_calibration(site, surrogate: sg.Surrogate, result: dict, path: Path) -> Path:
    """Plot every week of the site: measured (black) and calibrated metamodel (colour), held-out weeks marked.

    Top: occupied-zone mean temperature (degC); below: the consumption the site meters (Wh/m2 per hour), and its
    second meter's where it has one.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    weeks = list(range(site.weeks))
    problem = build_problem(
        site,
        weeks,
        tuple(result.get("declared_effects", ())),
        context_hours=surrogate.context_hours,
        temperature_before=surrogate.uses_temperature_before,
        metamodel=surrogate,
    )
    params = calibrated_parameters(result, problem.effects)
    t, q, e = predict_meters(problem, surrogate, params)
    occupied = problem_occupancy(problem, params).reshape(-1).astype(float)
    hours = np.arange(len(weeks) * 168)
    panels = [
        (problem.temperature_c, t, "indoor temperature (degC)"),
        (problem.consumption_wh_m2, q, "consumption (Wh/m2)"),
    ]
    if e is not None:
        panels.append((problem.electricity_wh_m2, e, "electricity (Wh/m2)"))
    size = (min(4 + 3 * len(weeks), 24), 3 * len(panels))
    fig, axes = plt.subplots(len(panels), 1, figsize=size, sharex=True)
    ax_t = axes[0]
    for ax, (measured, model, label) in zip(axes, panels):
        shade_occupancy(ax, occupied)
        ax.plot(hours, measured.reshape(-1), color="black", lw=1.0, label="measured")
        ax.plot(hours, model.reshape(-1), color="tab:red", lw=1.0, label="calibrated metamodel")
        for w in result.get("heldout_weeks", []):
            ax.axvspan(w * 168, (w + 1) * 168, color="tab:blue", alpha=0.06, lw=0)
        for w in weeks[1:]:
            ax.axvline(w * 168, color="grey", lw=0.5)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fit, held = result.get("fit", {}), result.get("heldout", {})
    declared = f" with {', '.join(problem.effects)}" if problem.effects else ""
    title = (
        f"{site.name}{declared}: fit R2_T {fit.get('r2_t', float('nan')):.3f} R2_Q {fit.get('r2_q', float('nan')):.3f}"
    )
    if held:
        title += (
            f"; held-out (blue) R2_T {held['r2_t']:.3f} R2_Q {held['r2_q']:.3f}, "
            f"CV(RMSE) {held['cv_rmse_q_percent']:.1f} %, NMBE {held['nmbe_q_percent']:.1f} %"
        )
    ax_t.set_title(title, fontsize=9)
    ax_t.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("hour (weeks start Monday 00:00; occupied hours shaded green)")
    return save_figure(fig, path, dpi=110)
