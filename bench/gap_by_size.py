"""How large an unmodelled effect must be for the diagnosis to name it: the headline's effect cases by injected size.

The blind checks draw each effect's magnitude uniformly from the range real buildings show
(:attr:`buildenv.diagnosis.effects.Effect.magnitude_range`, ``bench/gap_check.py``), so the headline's share named right
mixes effects the sensors barely see with effects they cannot miss. This page splits every effect's cases counted by
the headline (``bench/results/gap_check.json`` by default, judged as ``bench/gap_headline.py`` judges them)
by injected size:
``|magnitude - the magnitude at which the injection changes nothing|`` in the effect's own unit (the heating
capacity limit as % of the design capacity removed, the sensor bias as |K|). For each effect it gives

- its cases in four bins of equal count (size quartiles; an effect drawn from four sizes or fewer, the holidays,
  by size), each with the effects named right, named another effect and named nothing;
- the smallest size from which at least 90 % of the cases at that size or larger are named right (at least
  ``--least`` cases), or none where no size reaches it: the size the diagnosis reliably sees;
- a figure of the same bins (``bench/results/<name>.png``).

It reads the records only; it is a description of recorded first steps, not a rule. Run from the repository root::

    python bench/gap_by_size.py

Writes ``bench/results/<name>.{md,json,png}`` (default name ``gap_by_size``).
"""

from __future__ import annotations

from pathlib import Path

import harness
import numpy as np
from harness import RESULTS, add_sources, judged_sources, replay_scope
from harness import percent as _percent

from buildenv.diagnosis.blind_check import NONE
from buildenv.diagnosis.effects import NO_EFFECT_MAGNITUDE, get_effect

SHARE = 0.9  # the share named right that "reliably seen" asks for


def injected_size(effect: str, magnitude: float) -> float:
    """An injection's size in the effect's magnitude unit: its distance from the magnitude that changes nothing."""
    return abs(magnitude - NO_EFFECT_MAGNITUDE[effect])


def size_bins(sizes: np.ndarray) -> list[tuple[float, float]]:
    """``(low, high)`` bounds, inclusive, of four bins of equal count over ``sizes`` (quartiles), or one bin per
    size when there are four distinct sizes or fewer."""
    distinct = np.unique(sizes)
    if len(distinct) <= 4:
        return [(float(s), float(s)) for s in distinct]
    edges = np.quantile(sizes, [0.0, 0.25, 0.5, 0.75, 1.0])
    return [(float(edges[i]), float(edges[i + 1])) for i in range(4)]


def in_bin(size: float, bounds: tuple[float, float], last: bool) -> bool:
    """Whether ``size`` falls in a bin: from its low bound, below its high bound (up to it for the last bin)."""
    low, high = bounds
    return low <= size <= high if (last or low == high) else low <= size < high


def bin_label(b: dict) -> str:
    """A bin's sizes as the page and the figure show them: ``low-high``, or the one size it holds."""
    return f"{b['low']:.3g}" if b["low"] == b["high"] else f"{b['low']:.3g}-{b['high']:.3g}"


def reliable_size(cases: list[tuple[float, str]], effect: str, least: int) -> float | None:
    """The smallest injected size from which at least :data:`SHARE` of the cases that large or larger name
    ``effect``, over at least ``least`` cases; None where no size does. ``cases`` are ``(size, named)`` pairs."""
    ordered = sorted(cases)
    for i, (size, _) in enumerate(ordered):
        above = ordered[i:]
        if len(above) < least:
            return None
        if sum(named == effect for _, named in above) >= SHARE * len(above):
            return size
    return None


def effect_rows(cases: dict[str, list[tuple[float, str, str]]], least: int) -> dict[str, dict]:
    """Per effect of ``{effect: [(size, named, site)]}``: the unit of its size, its bins (bounds, cases, named
    right, named another effect, named nothing), its cases and those named right, the smallest size named right
    and the size from which it is reliably named (:func:`reliable_size`)."""
    out = {}
    for effect in sorted(cases):
        rows = cases[effect]
        sizes = np.array([size for size, _, _ in rows])
        bounds = size_bins(sizes)
        bins = []
        for k, b in enumerate(bounds):
            named = [n for size, n, _ in rows if in_bin(size, b, k == len(bounds) - 1)]
            bins.append(
                {
                    "low": b[0],
                    "high": b[1],
                    "cases": len(named),
                    "right": sum(n == effect for n in named),
                    "wrong": sum(n not in (effect, NONE) for n in named),
                    "nothing": sum(n == NONE for n in named),
                }
            )
        catalogued = get_effect(effect)
        unit, (low, high) = catalogued.magnitude_unit, catalogued.magnitude_range
        if effect == "heating_capacity_limit":
            unit = "% of the design heating capacity removed"
        elif low < NO_EFFECT_MAGNITUDE[effect] < high:
            unit += ", either sign"
        out[effect] = {
            "unit": unit,
            "bins": bins,
            "cases": len(rows),
            "right": sum(n == effect for _, n, _ in rows),
            "reliable": reliable_size([(s, n) for s, n, _ in rows], effect, least),
            "smallest_right": min((s for s, n, _ in rows if n == effect), default=None),
        }
    return out


def plot(rows: dict[str, dict], path: Path) -> None:
    """Stacked bars, one panel an effect: per size bin, the cases named right, named another effect and named
    nothing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(15, 6.5), sharey=True)
    for ax, (effect, row) in zip(axes.flat, rows.items()):
        labels = [bin_label(b) for b in row["bins"]]
        x = np.arange(len(labels))
        share = {k: np.array([b[k] / b["cases"] for b in row["bins"]]) for k in ("right", "wrong", "nothing")}
        ax.bar(x, share["right"], color="tab:green", label="named right")
        ax.bar(x, share["wrong"], bottom=share["right"], color="tab:red", label="named another effect")
        ax.bar(x, share["nothing"], bottom=share["right"] + share["wrong"], color="0.8", label="named nothing")
        ax.axhline(SHARE, color="k", lw=0.8, ls="--")
        ax.set_xticks(x, labels, fontsize=8)
        ax.set_title(effect.replace("_", " "), fontsize=10)
        ax.set_xlabel(row["unit"], fontsize=7)
    axes[0, 0].set_ylabel("share of the cases")
    axes[1, 0].set_ylabel("share of the cases")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Named first by injected size (bins of equal count; dashed: 90 %)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = harness.parser(__doc__)
    add_sources(parser)
    parser.add_argument(
        "--least", type=int, default=10, help="the fewest cases at or above a size that may call it reliably seen"
    )
    parser.add_argument("--name", default="gap_by_size")
    args = parser.parse_args()
    records, named, right, sources = judged_sources(args)
    cases: dict[str, list[tuple[float, str, str]]] = {}
    for site, (record, truth, _) in records.items():
        if truth != NONE:
            cases.setdefault(truth, []).append((injected_size(truth, record["magnitude"]), named[site], site))
    rows = effect_rows(cases, args.least)
    plot(rows, RESULTS / f"{args.name}.png")
    above = [b for r in rows.values() for b in r["bins"][1:]]  # every bin but each effect's smallest sizes
    above_right, above_cases = sum(b["right"] for b in above), sum(b["cases"] for b in above)
    command = f"python bench/gap_by_size.py{sources} --least {args.least} --name {args.name}"
    lines = [
        "# Gap diagnosis: named first by injected size",
        "",
        replay_scope(records, right) + " Size: the injection's distance from the magnitude that changes "
        "nothing, in the effect's unit. Bins hold equal counts (size quartiles; the holidays by size). "
        f"Figure: `{args.name}.png`.",
        "",
        f"Above each effect's lowest size bin: {_percent(above_right, above_cases)} named right, against "
        f"{_percent(sum(r['right'] for r in rows.values()), sum(r['cases'] for r in rows.values()))} "
        "over all sizes.",
        "",
        "| effect | unit of size | cases | named right | by size bin: named right (named another effect) | "
        f"smallest named right | seen from ({SHARE:.0%} of the cases that large or larger) |",
        "|---|---|---|---|---|---|---|",
    ]
    for effect, row in rows.items():
        bins = "; ".join(
            f"{bin_label(b)}: {b['right']}/{b['cases']}" + (f" ({b['wrong']})" if b["wrong"] else "")
            for b in row["bins"]
        )
        seen = "none" if row["reliable"] is None else f"{row['reliable']:.3g}"
        smallest = "-" if row["smallest_right"] is None else f"{row['smallest_right']:.3g}"
        lines.append(
            f"| {effect} | {row['unit']} | {row['cases']} | {_percent(row['right'], row['cases'])} | "
            f"{bins} | {smallest} | {seen} |"
        )
    sites = [
        {"true": effect, "site": site, "size": size, "named": n}
        for effect in sorted(cases)
        for size, n, site in sorted(cases[effect], key=lambda c: c[2])
    ]
    harness.write_results(
        args.name,
        lines,
        {
            "command": command,
            "least": args.least,
            "share": SHARE,
            "effects": rows,
            "above_lowest_bin": {"right": above_right, "cases": above_cases},
            "sites": sites,
        },
        echo=True,
    )


if __name__ == "__main__":
    main()
