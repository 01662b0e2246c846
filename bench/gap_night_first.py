"""The night-electricity rule replayed on the headline's sites: which sites carry a large night electricity, and
what naming night plug loads first from it changes.

The base calibration carries loads left on at night in the night shares of the lighting and plug loads, and a
first step judges ``night_plug_loads`` by the night electricity those shares add up to. A large night load
(3-5 W/m2 injected, 4.5-8 W/m2 carried) is carried by the lights' night share too, and the model carrying it can
read the held-out temperature worse than the one with no lighting at night, so the held-out gains name something
else. The diagnosis names night
plug loads first when that night electricity is beyond :data:`buildenv.effects.NIGHT_LOAD_FIRST_BEYOND` times its
estimate ceiling and the sensor bias candidate refits cold (:func:`buildenv.gap.night_load_named_first`). This
shows, on every site the headline counts (``bench/gap_headline.py``'s sources, judged as it judges them, first step
only):

- the largest night electricity carried on each kind of site (clean cases, clean twins, each injected effect) and,
  beyond each ``--beyond`` factor, how many sites lie there and which way their sensor bias refits;
- each site whose naming changes with the rule at each factor (and with it off), and what that nets.

It is an in-sample replay of recorded first steps: the factor read off it is tested only by fresh seeds. Run from
the repository root::

    .venv/bin/python bench/gap_night_first.py --beyond 1.25 --beyond 1.5 --beyond 2 \\
        --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_night_first``).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

from gap_floor_replay import net_change
from gap_headline import (add_sources, judge, judged_sources, judged_with, replay_scope,  # noqa: F401 (judge)
                          write_results)

import buildenv.gap as gap
from buildenv.effects import get_effect
from buildenv.gap_check import NONE

NIGHT = get_effect(gap.NIGHT_LOADS)


def carried(record: dict) -> tuple[float | None, float | None]:
    """A record's first-step night electricity (W/m2; None where the night candidate has no such estimate) and its
    sensor bias candidate's refit (K; None where not tested)."""
    return (record["estimates"].get(gap.NIGHT_LOADS, {}).get(NIGHT.ceiling_on),
            record["estimates"].get(gap.SENSOR_BIAS, {}).get("bias_k"))


def kind(site: str, truth: str) -> str:
    """The row a site is counted in: its injected effect, ``clean case`` or ``clean twin``."""
    if truth != NONE:
        return truth
    return "clean twin" if site.endswith("_twin") else "clean case"


def by_kind(records: dict[str, tuple[dict, str, str]], factors: list[float]) -> dict[str, dict]:
    """Per kind of site (:func:`kind`): how many sites, the largest night electricity, and per factor the sites
    beyond it with the bias refit warm (> 0 K) and not."""
    ceiling = NIGHT.estimate_ceiling
    rows: dict[str, dict] = defaultdict(lambda: {"sites": 0, "largest": 0.0,
                                                 "beyond": {f: {"warm": 0, "cold": 0} for f in factors}})
    for site, (record, truth, _) in records.items():
        size, bias = carried(record)
        if size is None:
            continue
        row = rows[kind(site, truth)]
        row["sites"] += 1
        row["largest"] = max(row["largest"], size)
        for f in factors:
            if size > f * ceiling:
                row["beyond"][f]["warm" if bias is not None and bias > 0.0 else "cold"] += 1
    return dict(sorted(rows.items()))


def renamed(records: dict[str, tuple[dict, str, str]], beyond: float | None,
            before: dict[str, str]) -> list[dict]:
    """The sites whose first step names something else with the rule at ``beyond`` times the ceiling (None: off),
    each with its night electricity and bias refit."""
    return changed_rows(records, before, judged_with(records, "NIGHT_LOAD_FIRST_BEYOND", beyond))


def changed_rows(records: dict[str, tuple[dict, str, str]], before: dict[str, str],
                 after: dict[str, str]) -> list[dict]:
    """The sites named otherwise ``after`` than ``before``, each with its night electricity and bias refit, the
    largest night electricity first."""
    rows = []
    for site, (record, truth, _) in records.items():
        if after[site] != before[site]:
            size, bias = carried(record)
            rows.append({"site": site, "true": truth, "before": before[site], "after": after[site],
                         "night_electricity_w_m2": size, "bias_k": bias})
    return sorted(rows, key=lambda r: -(r["night_electricity_w_m2"] or 0.0))


def _row(label: str, row: dict) -> str:
    bias = "-" if row["bias_k"] is None else f"{row['bias_k']:+.2f}"
    return (f"| {label} | {row['site']} | {row['true']} | {row['before']} | {row['after']} | "
            f"{row['night_electricity_w_m2']:.2f} | {bias} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--beyond", type=float, action="append", required=True,
                        help="a factor to replay: night plug loads named first beyond this many times the ceiling")
    add_sources(parser)
    parser.add_argument("--name", default="gap_night_first")
    args = parser.parse_args()
    records, before, right, sources = judged_sources(args)
    factors = sorted(args.beyond)
    kinds = by_kind(records, factors)
    now = gap.NIGHT_LOAD_FIRST_BEYOND
    changes = {f: renamed(records, f, before) for f in factors if f != now}
    if now is not None:
        changes["off"] = renamed(records, None, before)
    command = ("python bench/gap_night_first.py" + "".join(f" --beyond {f:g}" for f in factors) + sources
               + f" --name {args.name}")
    ceiling = NIGHT.estimate_ceiling
    rule = (f"Rule now: beyond {now:g} times the {ceiling:g} W/m2 ceiling ({now * ceiling:.2f} W/m2), with the "
            "sensor bias refit at 0 K or colder." if now is not None else "Rule now: off.")
    lines = [f"# Gap diagnosis: night plug loads named first by the night electricity ({time.strftime('%Y-%m-%d')})",
             "", f"Command: `{command}`.", "", f"{replay_scope(records, right)} {rule}", "",
             "## Night electricity carried by the first step's model (W/m2), by site", "",
             "Beyond a factor: sites whose night electricity is beyond that many times the ceiling, as *bias refit "
             "warm (> 0 K) / cold or zero*.", "",
             "| sites | count | largest | " + " | ".join(f"beyond {f:g}x ({f * ceiling:.2f})" for f in factors)
             + " |", "|---|---|---" + "|---" * len(factors) + "|"]
    for name, row in kinds.items():
        lines.append(f"| {name} | {row['sites']} | {row['largest']:.2f} | "
                     + " | ".join(f"{row['beyond'][f]['warm']} / {row['beyond'][f]['cold']}" for f in factors)
                     + " |")
    lines += ["", "## Sites named otherwise", "",
              "*Named now*: with the rule as it is; *named then*: at the factor (or off).", "",
              "| factor | site | injected | named now | named then | night electricity | bias refit (K) |",
              "|---|---|---|---|---|---|---|"]
    for f, rows in changes.items():
        label = f if isinstance(f, str) else f"{f:g}x"
        lines += [_row(label, r) for r in rows]
        lines.append(f"| {label} | **net** | | | | | {net_change(rows)} |")
    write_results(args.name, lines, {
        "command": command, "beyond_now": now, "ceiling_w_m2": ceiling, "sites": len(records), "right_now": right,
        "by_kind": {name: row | {"beyond": {str(f): v for f, v in row["beyond"].items()}}
                    for name, row in kinds.items()},
        "renamed": {str(f): rows for f, rows in changes.items()}})


if __name__ == "__main__":
    main()
