"""One effect's plausibility floor replayed on the headline's sites: what a lower (or higher) floor would name.

A diagnosis names an effect only from its plausibility floor (:attr:`buildenv.effects.Effect.smallest`, the
smallest size real buildings show). When an injected effect is refit under its floor, the floor alone may be what
missed it (seed 37's case 1: a 56 % heat exchanger refit at 0.273, under the 0.3 floor). Before moving a floor,
this shows two things on every site the headline counts (``bench/gap_headline.py``'s sources, judged as it
judges them, first step only):

- how far the effect's estimate goes on sites where it was *not* injected, by injected effect (clean sites
  included): where another effect pushes it past a candidate floor, that floor lets the effect compete there;
- each site whose naming changes at each ``--floor``, right or wrong.

It is an in-sample replay of recorded first steps: a floor read off it is tested only by fresh seeds. Run from
the repository root with the headline's sources (or its ``--rediagnosed`` and ``--run`` pages one by one)::

    .venv/bin/python bench/gap_floor_replay.py --effect heat_recovery --floor 0.25 --floor 0.2 --floor 0.15 \\
        --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_floor_<effect>``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from gap_headline import add_sources, judge, judged_sources, replay_scope, write_results

import buildenv.effects as effects
from buildenv.gap_check import NONE


def estimates_by_truth(records: dict[str, tuple[dict, str, str]], effect: effects.Effect) -> dict[str, list[float]]:
    """The effect's refit size (:meth:`buildenv.effects.Effect.size`, as its floor judges it) on each site, by
    injected effect."""
    sizes: dict[str, list[float]] = {}
    for record, truth, _ in records.values():
        values = record["estimates"].get(effect.name)
        if values:
            sizes.setdefault(truth, []).append(effect.size(values))
    return sizes


def renamed(records: dict[str, tuple[dict, str, str]], effect: effects.Effect, floor: float,
            before: dict[str, str]) -> list[dict]:
    """The sites whose first step names something else with the effect's floor at ``floor`` (same units)."""
    effects.EFFECTS[effect.name] = dataclasses.replace(effect, smallest=floor)
    try:
        after = {site: judge(record)[0] for site, (record, _, _) in records.items()}
    finally:
        effects.EFFECTS[effect.name] = effect
    return [{"site": site, "true": truth, "before": before[site], "after": after[site]}
            for site, (_, truth, _) in records.items() if after[site] != before[site]]


def _wrong(row: dict, when: str) -> bool:
    """Whether a renamed site's naming ``when`` ("before" or "after") names an effect that was not injected."""
    return row[when] not in (row["true"], NONE)


def net_change(rows: list[dict]) -> str:
    """What renaming ``rows`` (``{"true", "before", "after"}``) nets: effect cases named right, effect cases named
    another effect, and clean sites named an effect (counted apart: a clean site named is not one fewer right)."""
    cases = [r for r in rows if r["true"] != NONE]
    clean = [r for r in rows if r["true"] == NONE]
    gained = sum(r["after"] == r["true"] for r in cases) - sum(r["before"] == r["true"] for r in cases)
    wrong = sum(_wrong(r, "after") for r in cases) - sum(_wrong(r, "before") for r in cases)
    named = sum(r["after"] != NONE for r in clean) - sum(r["before"] != NONE for r in clean)
    return f"{gained:+d} named right, {wrong:+d} named another effect, {named:+d} clean sites named"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--effect", required=True, choices=sorted(effects.EFFECTS))
    parser.add_argument("--floor", type=float, action="append", required=True,
                        help="a floor to replay, in the units of the effect's first model parameter (repeatable)")
    add_sources(parser)
    parser.add_argument("--name", default="")
    args = parser.parse_args()
    effect = effects.EFFECTS[args.effect]
    if effect.smallest is None:
        parser.error(f"effect {effect.name} has no plausibility floor to replay")
    name = args.name or f"gap_floor_{effect.name}"
    records, before, right, sources = judged_sources(args)
    sizes = estimates_by_truth(records, effect)
    changes = {floor: renamed(records, effect, floor, before) for floor in args.floor}
    columns = sorted({effect.smallest, *args.floor}, reverse=True)  # the floor now and each replayed one
    command = ("python bench/gap_floor_replay.py --effect " + effect.name
               + "".join(f" --floor {f:g}" for f in args.floor) + sources + f" --name {name}")
    lines = [f"# Gap diagnosis: the {effect.name} plausibility floor replayed ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}`.", "",
             replay_scope(records, right) + f" Floor now: {effect.named_from()}.", "",
             f"## The {effect.size_name} estimate by injected effect", "",
             "| injected | sites | largest | " + " | ".join(f">= {f:g}" for f in columns) + " |",
             "|---|---|---|" + "---|" * len(columns)]
    for truth in sorted(sizes, key=lambda t: (t == effect.name, t == NONE, t)):
        values = sizes[truth]
        lines.append(f"| {truth} | {len(values)} | {max(values):.3f} | " + " | ".join(
            str(sum(v >= f for v in values)) for f in columns) + " |")
    lines += ["", "## Sites named otherwise", "", "| floor | site | injected | named now | named with the floor |",
              "|---|---|---|---|---|"]
    for floor, rows in changes.items():
        lines += [f"| {floor:g} | {r['site']} | {r['true']} | {r['before']} | {r['after']} |" for r in rows]
        lines.append(f"| {floor:g} | **net** | | | {net_change(rows)} |")
    write_results(name, lines, {
        "command": command, "effect": effect.name, "floor_now": effect.smallest, "sites": len(records),
        "right_now": right, "estimates": sizes, "renamed": {str(f): rows for f, rows in changes.items()}})


if __name__ == "__main__":
    main()
