"""The temperature sensor bias sized from what clean sites calibrate: the reading, its ceilings, the rule replayed.

Calibrated with a sensor bias on a site where none was injected, the diagnosis still fits one: the calibrated
model reads the reference office warm, so clean sites calibrate -0.55 to 0.00 K, and an injected bias is refitted
about that much lower. Sized from zero, a +0.6 K sensor came out at +0.2 to +0.4 K, under the 0.4 K floor, while
clean sites went past the ceiling on the negative side. Since 2026-11-30 the bias is sized from the clean sites'
median instead (:attr:`buildenv.effects.Effect.clean_reading`). This script

- measures that reading (the median estimate over the clean sites of seeds up to ``--last-seed``) and the
  ceilings sized from it: the gain route's and the estimate-alone rule's on the same sites, and that of sites
  declaring their internal loads known on ``--declared``'s; and checks them against the catalogue's (the reading
  to the millikelvin, the ceilings rounded outwards to 3 significant digits);
- shows the estimate by injected effect, and on the bias cases the estimate less the injected bias;
- judges the first step of every site the headline counts (``bench/gap_headline.py``'s sources) with the bias
  sized from zero (its ceilings measured from zero on the same sites) and as the catalogue sizes it, and lists
  every site named otherwise. Seeds after ``--last-seed`` did not set the reading: they are the held-out replay.
  A site where the catalogue's rule calls for a joint test of the bias that the record did not run is marked: it
  names what the rest of its record does (a new diagnosis would test the bias first). ``--again FOLDER`` lists
  sites diagnosed again with the reading (``bench/gap_wind_centred.py --effects temperature_sensor_bias --folder
  FOLDER``), joint test included; ``--again`` of a page's ``.json`` keeps the rows that page listed.

Run from the repository root::

    .venv/bin/python bench/gap_bias_reading.py --sources-of bench/results/gap_headline.json --last-seed 28 \\
        --declared bench/results/gap_declared_ceiling.json --again bench/results/gap_bias_reading.json

(the two bias sites of seed 55 diagnosed again were first listed from ``--again out/gap-bias-reading-55``).

Writes ``bench/results/<name>.{md,json}`` (default ``gap_bias_reading``). It reads the records only.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time
from pathlib import Path

from gap_check_rejudge import ALONE
from gap_clean_ceiling import round_up
from gap_estimate_alone import seed_of
from gap_headline import add_sources, judge, judged_sources, replay_scope, write_results

import buildenv.effects as effects
from buildenv.gap import absorbed_candidate
from buildenv.gap_check import NONE

BIAS = "temperature_sensor_bias"


def declared_estimates(path: str) -> list[float]:
    """The bias estimates (K) of the clean sites of a ``bench/gap_clean_ceiling.py --declared`` json: its pages'
    clean cases and the clean twins it keeps."""
    page = json.loads(Path(path).read_text())
    rows = [r for twins in page["twin_records"].values() for r in twins]
    for source in page["pages"]:
        rows += [c for c in json.loads(Path(source).read_text())["cases"] if c["true"] == NONE]
    return [r["estimates"][BIAS]["bias_k"] for r in rows if BIAS in r["estimates"]]


def measured_from_zero(path: str) -> float:
    """The largest ``|bias_k|`` (K) on clean sites that a ceiling page measured (``bench/gap_clean_ceiling.py``'s
    json): the ceilings the catalogue had before the reading. (``bench/gap_estimate_alone.py``'s page measures from
    the reading since it was regenerated on 2026-12-01, so the estimate ceiling from zero is measured here.)"""
    measured = json.loads(Path(path).read_text())["measured"][BIAS]
    return measured["furthest"] if isinstance(measured, dict) else measured[0]


def judged_with(records: dict[str, tuple[dict, str, str]], effect: effects.Effect) -> dict[str, tuple[str, str]]:
    """``{site: (named, how)}`` of every record's first step with the catalogue's bias replaced by ``effect``."""
    kept = effects.EFFECTS[BIAS]
    effects.EFFECTS[BIAS] = effect
    try:
        return {site: judge(record) for site, (record, _, _) in records.items()}
    finally:
        effects.EFFECTS[BIAS] = kept


def untested_joint(record: dict, how: str) -> bool:
    """Whether the catalogue's rule calls for a joint test of the bias on this record's first step (nothing
    qualified by its held-out gain, and the bias estimate is plausible and beyond its ceiling) that it did not run."""
    estimate = record["estimates"].get(BIAS)
    return how != "held-out gain" and estimate is not None and BIAS not in record.get("joint_tests", {}) \
        and absorbed_candidate(BIAS, estimate)


def diagnosed_again(folders: list[str], records: dict[str, tuple[dict, str, str]]) -> list[dict]:
    """The sites of ``folders`` (``<site>.json`` diagnosis records, e.g. ``bench/gap_wind_centred.py``'s) with
    their injected effect from ``records``, refit bias (K), joint test of the bias (or None) and first named
    effect. A ``.json`` page this script wrote stands for the folders it read: its rows are kept as they are, so
    the page regenerates on a checkout without ``out/``."""
    rows = []
    for folder in folders:
        if folder.endswith(".json"):
            rows += json.loads(Path(folder).read_text())["again"]
            continue
        if not Path(folder).is_dir():
            raise SystemExit(f"--again {folder}: no such folder of diagnosis records (or give the page's .json)")
        for path in sorted(Path(folder).glob("seed*_case_*.json")):
            record, site = json.loads(path.read_text()), path.stem
            rows.append({"site": site, "true": records[site][1], "magnitude": records[site][0].get("magnitude"),
                         "bias_k": record["estimates"][BIAS]["bias_k"],
                         "joint": record.get("joint_tests", {}).get(BIAS), "named": record["named"]})
    return rows


def counts(rows: list[tuple[str, str]], truths: list[str]) -> dict[str, int]:
    """Effect cases named right and named another effect, and clean sites named nothing, of ``(named, how)``."""
    out = {"cases": 0, "right": 0, "wrong": 0, "clean": 0, "clean_right": 0}
    for (named, _), truth in zip(rows, truths):
        if truth == NONE:
            out["clean"] += 1
            out["clean_right"] += named == NONE
        else:
            out["cases"] += 1
            out["right"] += named == truth
            out["wrong"] += named not in (truth, NONE)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_sources(parser)
    parser.add_argument("--last-seed", type=int, required=True,
                        help="the clean sites of seeds 0 to this one set the reading and the ceilings")
    parser.add_argument("--declared", required=True,
                        help="a bench/gap_clean_ceiling.py --declared json (sites declaring their loads known)")
    parser.add_argument("--zero-ceiling", default="bench/results/gap_clean_ceiling_all.json",
                        help="the page that measured the gain route's ceiling from zero")
    parser.add_argument("--again", action="append", default=[], metavar="FOLDER|PAGE",
                        help="records of sites diagnosed again with the reading (bench/gap_wind_centred.py --folder), "
                             "or a page's .json whose rows are kept")
    parser.add_argument("--name", default="gap_bias_reading")
    args = parser.parse_args()
    effect = effects.EFFECTS[BIAS]
    records, now_named, right, sources = judged_sources(args)
    clean = {site: record["estimates"][BIAS]["bias_k"] for site, (record, truth, _) in records.items()
             if truth == NONE and BIAS in record["estimates"] and seed_of(site) <= args.last_seed}
    reading = statistics.median(clean.values())
    furthest = max(clean, key=lambda s: abs(clean[s] - effect.clean_reading))
    ceiling = abs(clean[furthest] - effect.clean_reading)
    declared = declared_estimates(args.declared)
    declared_ceiling = max(abs(v - effect.clean_reading) for v in declared)
    from_zero = dataclasses.replace(effect, clean_reading=0.0,
                                    clean_ceiling=round_up(measured_from_zero(args.zero_ceiling)),
                                    estimate_ceiling=round_up(max(abs(v) for v in clean.values())),
                                    declared_ceiling=round_up(measured_from_zero(args.declared)))
    now = {site: judge(record) for site, (record, _, _) in records.items()}
    before = judged_with(records, from_zero)
    assert {s: n for s, (n, _) in now.items()} == now_named

    def check(typed: float | None, rounded: float) -> str:
        return f"{typed:g}" + ("" if typed == rounded else f" (measured gives {rounded:g})")

    command = (f"python bench/gap_bias_reading.py{sources} --last-seed {args.last_seed} --declared {args.declared}"
               + "".join(f" --again {f}" for f in args.again) + f" --name {args.name}")
    lines = [f"# Gap diagnosis: the temperature sensor bias sized from what clean sites calibrate "
             f"({time.strftime('%Y-%m-%d')})", "", f"Command: `{command}`.", "",
             replay_scope(records, right) + f" The reading and the ceilings: the {len(clean)} clean sites of seeds "
             f"0-{args.last_seed}; later seeds are the held-out replay.", "",
             "## The reading and the ceilings sized from it", "",
             "| quantity | measured | where | catalogue |", "|---|---|---|---|",
             f"| clean reading (median bias_k, K) | {reading:.4f} | {len(clean)} clean sites, "
             f"{min(clean.values()):.3f} to {max(clean.values()):.3f} K | "
             f"{check(effect.clean_reading, round(reading, 3))} |",
             f"| ceiling, gain route and estimate alone (K) | {ceiling:.4f} | {furthest} | "
             f"{check(effect.clean_ceiling, round_up(ceiling))}, "
             f"{check(effect.estimate_ceiling, round_up(ceiling))} |",
             f"| ceiling on sites declaring their loads known (K) | {declared_ceiling:.4f} | {len(declared)} clean "
             f"sites of {args.declared}, {min(declared):.3f} to {max(declared):.3f} K | "
             f"{check(effect.declared_ceiling, round_up(declared_ceiling))} |",
             "", f"Sized from zero, the ceilings were {from_zero.clean_ceiling:g} K (gain route, "
             f"{args.zero_ceiling}), {from_zero.estimate_ceiling:g} K (estimate alone, the same "
             f"{len(clean)} clean sites, as bench/gap_estimate_alone.py measured it before the reading)"
             f" and {from_zero.declared_ceiling:g} K (declaring): the rule replayed below as 'from zero'.", "",
             "## The bias estimate (K) by injected effect", "",
             "| injected | sites | 10th percentile | median | 90th percentile |", "|---|---|---|---|---|"]
    by_truth: dict[str, list[float]] = {}
    for record, truth, _ in records.values():
        if BIAS in record["estimates"]:
            by_truth.setdefault(truth, []).append(record["estimates"][BIAS]["bias_k"])
    for truth in sorted(by_truth, key=lambda t: (t == BIAS, t == NONE, t)):
        values = sorted(by_truth[truth])
        quantile = statistics.quantiles(values, n=10)
        lines.append(f"| {truth} | {len(values)} | {quantile[0]:.3f} | {statistics.median(values):.3f} | "
                     f"{quantile[-1]:.3f} |")
    offsets = [record["estimates"][BIAS]["bias_k"] - record["magnitude"] for record, truth, _ in records.values()
               if truth == BIAS and BIAS in record["estimates"]]
    deciles = statistics.quantiles(offsets, n=10)
    lines += ["", f"On the {len(offsets)} bias cases the estimate less the injected bias has median "
              f"{statistics.median(offsets):.3f} K (10th-90th percentile {deciles[0]:.3f} to {deciles[-1]:.3f} K).",
              "",
              "## The rule replayed", "",
              "| seeds | effect cases | named right: from zero, now | named another effect: from zero, now "
              "| clean sites | named nothing: from zero, now |", "|---|---|---|---|---|---|"]
    groups = {f"0-{args.last_seed} (set the reading)": lambda s: seed_of(s) <= args.last_seed,
              f"{args.last_seed + 1}- (held out)": lambda s: seed_of(s) > args.last_seed, "all": lambda s: True}
    tallies = {}
    for label, inside in groups.items():
        sites = [s for s in records if inside(s)]
        truths = [records[s][1] for s in sites]
        a, b = counts([before[s] for s in sites], truths), counts([now[s] for s in sites], truths)
        tallies[label] = {"from_zero": a, "now": b}
        lines.append(f"| {label} | {a['cases']} | {a['right']}, {b['right']} | {a['wrong']}, {b['wrong']} | "
                     f"{a['clean']} | {a['clean_right']}, {b['clean_right']} |")
    changed = [s for s in records if before[s][0] != now[s][0] or untested_joint(records[s][0], now[s][1])]
    lines += ["", "## Sites named otherwise, or calling for an untested joint test", "",
              "| site | injected | magnitude | bias estimate (K) | from zero | now |", "|---|---|---|---|---|---|"]
    rows = []
    for site in sorted(changed, key=lambda s: (seed_of(s), s)):
        record, truth, _ = records[site]
        estimate = record["estimates"].get(BIAS, {}).get("bias_k")
        untested = untested_joint(record, now[site][1])
        rows.append({"site": site, "true": truth, "magnitude": record.get("magnitude"), "bias_k": estimate,
                     "from_zero": before[site][0], "now": now[site][0], "untested_joint": untested})
        shown = "" if estimate is None else f"{estimate:.3f}"
        magnitude = record.get("magnitude")
        lines.append(f"| {site} | {truth} | {'' if truth == NONE else f'{magnitude:.3g}'} | {shown} | "
                     f"{before[site][0]}{' (estimate alone)' if before[site][1] == ALONE else ''} | {now[site][0]}"
                     f"{' (estimate alone)' if now[site][1] == ALONE else ''}"
                     f"{' (joint test of the bias not run)' if untested else ''} |")
    again = diagnosed_again(args.again, records)
    if again:
        lines += ["", "## Diagnosed again with the reading", "",
                  "| site | injected | magnitude | refit bias (K) | joint test of the bias: gain, p, estimate (K) | "
                  "named now |", "|---|---|---|---|---|---|"]
        for row in again:
            joint = row["joint"]
            test = "not run" if joint is None else \
                f"{joint['gain']:.1%}, {joint['p_value']:.2g}, {joint['estimate']['bias_k']:.3f}"
            lines.append(f"| {row['site']} | {row['true']} | {row['magnitude']:.3g} | {row['bias_k']:.3f} | {test} | "
                         f"{row['named']} |")
    write_results(args.name, lines, {
        "command": command, "reading": reading, "ceiling": ceiling, "furthest": furthest,
        "declared_ceiling": declared_ceiling, "clean_sites": len(clean), "declared_sites": len(declared),
        "from_zero": {"clean_ceiling": from_zero.clean_ceiling, "declared_ceiling": from_zero.declared_ceiling},
        "tallies": tallies, "sites": rows, "again": again})


if __name__ == "__main__":
    main()
