"""Night plug loads named by their estimate alone under the lights' share floor, replayed on the headline's sites.

A first step judges ``night_plug_loads`` by the night electricity both night shares of the base model add up to
(``night_electricity_w_m2``, its estimate ceiling 3.61 W/m2), and its held-out test pins the lights' night share at
0 %. A candidate whose lights' share stays under one catalogue step (10 %) is implausible for that test, which would
compare the calibrated building with itself; the estimate alone used the same floor, so a small load the calibration
carried on the equipment's night share was named nothing even with a night electricity beyond every clean site's.
:func:`buildenv.gap.plausible_alone` lets the estimate alone name such a candidate when the sensor bias candidate
refits at 0 K or colder (a sensor reading warm is carried as heat at night too). This shows, on every site the
headline counts (``bench/gap_headline.py``'s sources, judged as it judges them, first step only):

- per kind of site (clean cases, clean twins, each injected effect), the largest night electricity and how many
  sites carry one beyond the ceiling on a lights' share under the floor, bias refit warm / cold;
- each site named otherwise with the floor kept (the rule before) and without the bias condition, and the net;
- the same split by seeds: 0-11, whose clean sites set the ceiling, and the later ones, which it did not see.

An in-sample replay of recorded first steps; fresh seeds test it. Run from the repository root::

    .venv/bin/python bench/gap_night_alone.py --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_night_alone``).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict
from collections.abc import Callable

from gap_floor_replay import net_change
from gap_headline import (SITE, add_sources, judge, judged_sources, judged_with, replay_scope,  # noqa: F401
                          write_results)
from gap_night_first import carried, changed_rows, kind

import buildenv.gap as gap
from buildenv.effects import get_effect

NIGHT = get_effect(gap.NIGHT_LOADS)
CEILING_SEEDS = 11  # the night electricity's ceiling was measured on clean sites of seeds 0-11 (NIGHT_CEILING_SOURCE)


def under_floor(record: dict) -> bool:
    """Whether a record's night candidate refit its lights' night share under the plausibility floor."""
    return not NIGHT.plausible(record["estimates"].get(gap.NIGHT_LOADS, {}))


def by_kind(records: dict[str, tuple[dict, str, str]]) -> dict[str, dict]:
    """Per kind of site: how many, the largest night electricity, and the sites beyond the ceiling under the floor
    with the bias refit warm (> 0 K) and cold (or zero, or not tested)."""
    rows: dict[str, dict] = defaultdict(lambda: {"sites": 0, "largest": 0.0, "warm": 0, "cold": 0})
    for site, (record, truth, _) in records.items():
        size, bias = carried(record)
        if size is None:
            continue
        row = rows[kind(site, truth)]
        row["sites"] += 1
        row["largest"] = max(row["largest"], size)
        if size > NIGHT.estimate_ceiling and under_floor(record):
            row["warm" if bias is not None and bias > 0.0 else "cold"] += 1
    return dict(sorted(rows.items()))


def _floor_kept(name: str, parameters: dict, estimates: dict) -> bool:
    return get_effect(name).plausible(dict(parameters))


def _no_bias_condition(name: str, parameters: dict, estimates: dict) -> bool:
    return get_effect(name).plausible(dict(parameters)) or (name == gap.NIGHT_LOADS and NIGHT.judged_on in parameters)


def renamed(records: dict[str, tuple[dict, str, str]], rule: Callable[[str, dict, dict], bool],
            before: dict[str, str]) -> list[dict]:
    """The sites whose first step names something else with ``rule`` standing in for
    :func:`buildenv.gap.plausible_alone`, each with its night electricity, lights' share and bias refit."""
    rows = changed_rows(records, before, judged_with(records, "plausible_alone", rule))
    return [r | {"light_night_percent": records[r["site"]][0]["estimates"].get(gap.NIGHT_LOADS, {})
                 .get(NIGHT.building_parameter)} for r in rows]


def _seed(site: str) -> int:
    return int(SITE.match(site).group(1))


def rule_against(rows: list[dict]) -> str:
    """What the rule nets against a variant whose renamed sites are ``rows`` (:func:`renamed`)."""
    return net_change([r | {"before": r["after"], "after": r["before"]} for r in rows])


def _row(label: str, row: dict) -> str:
    bias = "-" if row["bias_k"] is None else f"{row['bias_k']:+.2f}"
    share = "-" if row["light_night_percent"] is None else f"{row['light_night_percent']:.1f}"
    return (f"| {label} | {row['site']} | {row['true']} | {row['before']} | {row['after']} | "
            f"{row['night_electricity_w_m2']:.2f} | {share} | {bias} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_sources(parser)
    parser.add_argument("--name", default="gap_night_alone")
    args = parser.parse_args()
    records, before, right, sources = judged_sources(args)
    kinds = by_kind(records)
    changes = {"floor kept (before)": renamed(records, _floor_kept, before),
               "no bias condition": renamed(records, _no_bias_condition, before)}
    command = "python bench/gap_night_alone.py" + sources + f" --name {args.name}"
    ceiling = NIGHT.estimate_ceiling
    floor = NIGHT.carried_limit()
    lines = [f"# Gap diagnosis: night plug loads named by the estimate alone under the lights' share floor "
             f"({time.strftime('%Y-%m-%d')})", "", f"Command: `{command}`.", "",
             f"{replay_scope(records, right)} Rule now (`buildenv.gap.plausible_alone`): a first step that names "
             f"nothing names night plug loads by a night electricity beyond the {ceiling:g} W/m2 estimate ceiling "
             f"whatever the lights' night share, under its {floor:g} % floor too, when the sensor bias candidate "
             "refits at 0 K or colder.", "",
             "## Night electricity carried by the first step's model (W/m2), by site", "",
             f"*Under the floor*: sites beyond {ceiling:g} W/m2 with the lights' share under {floor:g} %, as *bias "
             "refit warm (> 0 K) / cold, zero or not tested*.", "",
             "| sites | count | largest | under the floor |", "|---|---|---|---|"]
    lines += [f"| {name} | {row['sites']} | {row['largest']:.2f} | {row['warm']} / {row['cold']} |"
              for name, row in kinds.items()]
    lines += ["", "## Sites named otherwise", "", "*Named now*: with the rule; *named then*: with the variant.", "",
              "| variant | site | injected | named now | named then | night electricity | lights' share (%) | "
              "bias refit (K) |", "|---|---|---|---|---|---|---|---|"]
    for label, rows in changes.items():
        lines += [_row(label, r) for r in rows]
        lines.append(f"| {label} | **the rule against it** | | | | | | {rule_against(rows)} |")
    kept = changes["floor kept (before)"]
    split = {part: [r for r in kept if (_seed(r["site"]) <= CEILING_SEEDS) == (part == "ceiling's seeds")]
             for part in ("ceiling's seeds", "later seeds")}
    lines += ["", f"## By seeds (the rule against the floor kept): 0-{CEILING_SEEDS}, whose clean sites set the "
              f"ceiling, and {CEILING_SEEDS + 1} on", "", "| seeds | sites | the rule against the floor kept |",
              "|---|---|---|"]
    for part, rows in split.items():
        seeds = [s for s in records if (_seed(s) <= CEILING_SEEDS) == (part == "ceiling's seeds")]
        lines.append(f"| {part} | {len(seeds)} | {rule_against(rows)} |")
    write_results(args.name, lines, {
        "command": command, "ceiling_w_m2": ceiling, "floor_percent": floor, "sites": len(records),
        "right_now": right, "by_kind": kinds, "renamed": changes,
        "rule_against": {label: rule_against(rows) for label, rows in changes.items()},
        "by_seeds": {part: rule_against(rows) for part, rows in split.items()}})


if __name__ == "__main__":
    main()
