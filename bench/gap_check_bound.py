"""How much a held-out attribution could name: the gap each blind case's effect left after calibration.

A diagnosis judges an extension of the model by the held-out error it removes from the calibrated base model.
Where the base calibration absorbed the injected effect into theta_build (blinds into smaller windows, a night
plug load into the night shares), the calibrated model predicts the case's held-out weeks no worse than the
clean twin's calibrated model predicts the twin: the gap left (:func:`buildenv.gap_check.gap_left`, ``1 -
SSE_twin / SSE_case``, both series standardised) is zero or less. A held-out test then has nothing the effect
added to find: what a candidate gains on such a case it gains on the clean building too
(``bench/effect_on_twin.py`` measures that), and a case whose gap left is under the diagnosis' naming bar
(``min_gain`` as each record was judged: 15 % until 2026-11-28) can only clear the bar with gains of that kind.
The gap left is itself measured through two CMA-ES calibrations, so it moves by several points from one record
of a site to the next.

Every blind site (plan seed, weeks, split, case) was diagnosed by several recorded checks, with other metamodels
or rules. A site counts as findable when any of its records left a gap, so the bounds below are generous to the
diagnosis. Only records with a clean twin (``gap_left``) are read, and a record repeated on a page that holds the
first cases of a longer check counts once. The shares below are therefore about the most
held-out attribution can name on these draws, not a proof: a site with no gap left can still be named by chance.

    .venv/bin/python bench/gap_check_bound.py [--name gap_check_bound] [RESULT.json ...]

Without files it reads every ``bench/results/gap_check*.json``. Writes ``bench/results/<name>.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from collections import defaultdict
from pathlib import Path

from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def site_key(page: dict, row: dict) -> tuple:
    """The blind site a recorded case was made as: plan seed, weeks, split, case and its draws."""
    plan = page["plan"]
    split = plan.get("settings", {}).get("split") or "first_half"
    return (plan["seed"], plan.get("weeks", 4), split, row["case"], row["true"], row["start"],
            round(float(row["magnitude"]), 4))


def collect(paths: list[Path]) -> tuple[dict, list[dict]]:
    """``({site key: [records]}, per-file tallies)`` of the effect cases that have a clean twin."""
    sites: dict[tuple, list[dict]] = defaultdict(list)
    files = []
    for path in paths:
        page = json.loads(path.read_text())
        rows = [r for r in page.get("cases", []) if r["true"] != NONE and r.get("gap_left")]
        if not rows:
            continue
        bar = page["plan"]["settings"]["min_gain"]
        for r in rows:
            records = sites[site_key(page, r)]
            if any(x["share"] == r["gap_left"]["share"] and x["named"] == r["named"] for x in records):
                continue  # the same diagnosis on a page that holds the first cases of a longer check
            records.append({"share": r["gap_left"]["share"], "named": r["named"],
                            "correct": bool(r["correct"]), "bar": bar})
        files.append({"file": path.name, "date": page.get("date"), "command": page.get("command", ""),
                      "effect_cases": len(rows), "left": sum(r["gap_left"]["share"] >= bar for r in rows),
                      "named": sum(bool(r["correct"]) for r in rows),
                      "named_where_left": sum(bool(r["correct"]) and r["gap_left"]["share"] >= bar for r in rows)})
    return sites, files


def by_effect(sites: dict[tuple, list[dict]]) -> dict[str, dict]:
    """Per injected effect: distinct sites, those whose gap left was <= 0 (or under the bar) in every record,
    those named first in at least one record, and the largest gap left of each site (median over sites)."""
    out: dict[str, dict] = {}
    for key, records in sites.items():
        best = max(r["share"] for r in records)
        e = out.setdefault(key[4], {"sites": 0, "records": 0, "never_a_gap": 0, "never_over_bar": 0,
                                    "named_in_a_record": 0, "best_shares": []})
        e["sites"] += 1
        e["records"] += len(records)
        e["never_a_gap"] += best <= 0.0
        e["never_over_bar"] += best < records[0]["bar"]
        e["named_in_a_record"] += any(r["correct"] for r in records)
        e["best_shares"].append(best)
    for e in out.values():
        shares = sorted(e.pop("best_shares"))
        e["median_best_share"] = round(shares[len(shares) // 2], 4)
    return dict(sorted(out.items()))


def reach(effects: dict[str, dict]) -> dict:
    """Shares of the effect sites whose effect left a gap in some record (> 0, and at least the naming bar)."""
    n = sum(e["sites"] for e in effects.values())
    return {"effect_sites": n,
            "share_with_a_gap": 1.0 - sum(e["never_a_gap"] for e in effects.values()) / n,
            "share_over_the_bar": 1.0 - sum(e["never_over_bar"] for e in effects.values()) / n,
            "named_in_a_record": sum(e["named_in_a_record"] for e in effects.values()) / n}


def page(effects: dict[str, dict], files: list[dict], summary: dict, command: str) -> str:
    """The markdown page."""
    pct = lambda x: f"{100 * x:.0f} %"  # noqa: E731
    lines = ["# How much of each blind case's held-out error its effect left after calibration "
             f"({time.strftime('%Y-%m-%d')})",
             "", f"{platform.platform()}; `{command}`. Reads the recorded blind checks that calibrated each case's "
             "clean twin (`gap_left`); `bench/gap_check_bound.py` states the method.", "",
             "| | value |", "|---|---|",
             f"| distinct effect sites (plan seed, weeks, split, case) | {summary['effect_sites']} |",
             f"| records read | {sum(f['effect_cases'] for f in files)} effect cases in {len(files)} checks, "
             f"{sum(e['records'] for e in effects.values())} distinct diagnoses |",
             "| **effect sites whose effect left a gap (> 0) in some record**: about the most held-out attribution "
             f"can name | **{pct(summary['share_with_a_gap'])}** |",
             "| effect sites whose effect left at least the naming bar its record was judged at in some record | "
             f"{pct(summary['share_over_the_bar'])} |",
             f"| sites whose effect some record named first | {pct(summary['named_in_a_record'])} |", "",
             "## Per injected effect (distinct sites; a site's gap left is its largest over its records)", "",
             "| effect | sites | records | no gap left in any record | under the bar in every record | "
             "named first in a record | median largest gap left |", "|---|---|---|---|---|---|---|"]
    for name, e in effects.items():
        lines.append(f"| {name} | {e['sites']} | {e['records']} | {e['never_a_gap']} | {e['never_over_bar']} | "
                     f"{e['named_in_a_record']} | {e['median_best_share']:+.2f} |")
    lines += ["", "## Per recorded check", "", "| check | date | effect cases | gap left >= bar | named first | "
              "named first where a gap was left |", "|---|---|---|---|---|---|"]
    for f in files:
        lines.append(f"| {f['file']} | {f['date']} | {f['effect_cases']} | {f['left']} | {f['named']} | "
                     f"{f['named_where_left']} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    """Read the recorded checks and write the bounds page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="*", type=Path, help="result files of bench/gap_check.py (default: all)")
    parser.add_argument("--name", default="gap_check_bound", help="stem of the result files")
    args = parser.parse_args()
    paths = args.results or sorted(p for p in RESULTS.glob("gap_check*.json") if not p.stem.startswith(args.name))
    sites, files = collect(paths)
    if not sites:
        sys.exit("gap_check_bound: no recorded blind check with clean twins (gap_left) among the files given")
    effects = by_effect(sites)
    summary = reach(effects)
    command = "python bench/gap_check_bound.py" + (f" --name {args.name}" if args.name != "gap_check_bound" else "")
    (RESULTS / f"{args.name}.md").write_text(page(effects, files, summary, command))
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"date": time.strftime("%Y-%m-%d"), "summary": summary, "effects": effects, "checks": files}, indent=1) + "\n")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
