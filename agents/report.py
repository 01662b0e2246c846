"""Figures and the markdown report of an optimisation: Pareto front, before/after week, summary table."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from buildenv.plotting import save_figure, shade_occupancy


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pareto(front, points: dict[str, tuple[float, float]], path: Path, title: str = "") -> Path:
    """The energy-comfort front (energy relative to historical, comfort K) with named points marked.

    Args:
        front: an :class:`agents.nsga2.ParetoResult`.
        points: ``{label: (energy_term, comfort_k)}`` (historical, chosen, other methods).
        path: PNG to write.
        title: figure title.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.plot(front.energy_term, front.comfort_k, "o-", ms=3, lw=1, color="tab:blue", label="NSGA-II Pareto front")
    markers = iter(["s", "*", "^", "D", "v", "P"])
    for label, (e, c) in points.items():
        ax.plot([e], [c], next(markers, "o"), ms=10, label=label)
    ax.set_xlabel("HVAC energy relative to the historical settings (Delta_Q^opt ratio)")
    ax.set_ylabel("comfort: RMS deviation from T* over occupied hours (K)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    return save_figure(fig, path, dpi=120)


def plot_before_after(verification, path: Path, target_c: float = 22.5, title: str = "") -> Path:
    """Indoor temperature and HVAC energy of the week under the historical and the chosen settings, as the
    metamodel predicted them (dashed) and as EnergyPlus realised them (solid); occupied hours shaded."""
    plt = _pyplot()
    fig, (ax_t, ax_q) = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    hours = np.arange(len(verification.occupied))
    for ax in (ax_t, ax_q):
        shade_occupancy(ax, verification.occupied)
    for i, (label, color) in enumerate((("historical", "tab:gray"), ("chosen", "tab:red"))):
        for source, style in ((verification.realised, "-"), (verification.predicted, "--")):
            kind = "EnergyPlus" if source is verification.realised else "metamodel"
            ax_t.plot(hours, source["temperature_c"][i], style, color=color, lw=1.2, label=f"{label}, {kind}")
            ax_q.plot(hours, source["hvac_wh_m2"][i], style, color=color, lw=1.2, label=f"{label}, {kind}")
    ax_t.axhline(target_c, color="k", lw=0.8, ls=":", label="T*")
    ax_t.set_ylabel("indoor temperature (degC)")
    ax_q.set_ylabel("HVAC energy (Wh/m2 in the hour)")
    ax_q.set_xlabel("hour of the week (Monday 00:00 = 0; occupied hours shaded green)")
    ax_t.legend(fontsize=7, ncol=3)
    ax_t.set_title(title, fontsize=10)
    return save_figure(fig, path, dpi=120)


def markdown_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    """A markdown table: ``columns`` are ``(header, key, format)``; missing values print as "-"."""
    head = "| " + " | ".join(h for h, _, _ in columns) + " |\n|" + "---|" * len(columns) + "\n"
    body = ""
    for row in rows:
        cells = ["-" if row.get(k) is None else format(row[k], f) if f else str(row[k]) for _, k, f in columns]
        body += "| " + " | ".join(cells) + " |\n"
    return head + body
