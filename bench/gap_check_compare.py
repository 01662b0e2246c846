"""Two diagnosis rules on the same blind cases: which names more injected effects, which raises more false alarms.

Each ``--pair A.json,B.json`` is two results of ``bench/gap_check.py`` on the same plan (same seed, same known
effects, so the same sites): A with the reference rule, B with the alternative. The cases must agree on the
injected effect, its magnitude and its period, else the script stops.

    .venv/bin/python bench/gap_check_compare.py --name gap_check_judging --a-label pooled \\
        --b-label "effect series" --pair bench/results/gap_check.json,bench/results/gap_check_paired_es_seed0.json

Writes ``bench/results/<name>.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def paired_rows(a: dict, b: dict) -> list[dict]:
    """One row per case of two results of the same plan (raises when the plans differ). A check of N cases holds
    the first N cases of a longer one with the same seed: the cases both hold are compared."""
    rows = []
    common = min(len(a["cases"]), len(b["cases"]))
    for ra, rb in zip(a["cases"][:common], b["cases"][:common]):
        if (ra["true"], ra["magnitude"], ra["start"]) != (rb["true"], rb["magnitude"], rb["start"]):
            raise SystemExit(f"case {ra['case']}: the two results were not made on the same sites")
        rows.append({"case": ra["case"], "true": ra["true"], "magnitude": ra["magnitude"], "a": ra["named"],
                     "b": rb["named"]})
    return rows


def tally(rows: list[dict], key: str) -> dict:
    """Right first names on effect cases and clean cases recognised, for rule ``key`` (``a`` or ``b``)."""
    effect = [r for r in rows if r["true"] != NONE]
    clean = [r for r in rows if r["true"] == NONE]
    return {"effect_cases": len(effect), "named_right": sum(r[key] == r["true"] for r in effect),
            "named_wrong": sum(r[key] not in (r["true"], NONE) for r in effect),
            "clean_cases": len(clean), "clean_recognised": sum(r[key] == NONE for r in clean)}


def main() -> None:
    """Read the pairs, tally both rules, write the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pair", action="append", required=True, help="A.json,B.json (repeatable)")
    parser.add_argument("--a-label", default="A")
    parser.add_argument("--b-label", default="B")
    parser.add_argument("--name", default="gap_check_compare", help="stem of the result files")
    args = parser.parse_args()
    sets = []
    for pair in args.pair:
        path_a, path_b = pair.split(",")
        a, b = json.loads(Path(path_a).read_text()), json.loads(Path(path_b).read_text())
        sets.append({"a": path_a, "b": path_b, "seed": a["plan"]["seed"], "base_effects": a["base_effects"],
                     "rows": paired_rows(a, b)})
    every = [r for s in sets for r in s["rows"]]
    totals = {"a": tally(every, "a"), "b": tally(every, "b")}
    label = {"a": args.a_label, "b": args.b_label}
    lines = [f"# Blind check: {args.a_label} against {args.b_label} on the same cases ({time.strftime('%Y-%m-%d')})",
             "", "Command: `.venv/bin/python bench/gap_check_compare.py --name " + args.name
             + f" --a-label \"{args.a_label}\" --b-label \"{args.b_label}\" "
             + " ".join(f"--pair {p}" for p in args.pair) + "`.", "",
             "| rule | injected effect named first | named another effect | clean sites recognised |",
             "|---|---|---|---|"]
    for key in ("a", "b"):
        t = totals[key]
        lines.append(f"| {label[key]} | {t['named_right']}/{t['effect_cases']} | {t['named_wrong']}/{t['effect_cases']}"
                     f" | {t['clean_recognised']}/{t['clean_cases']} |")
    lines += ["", "| seed | known effects | " + " | ".join(f"{label[k]}: right, clean" for k in ("a", "b")) + " |",
              "|---|---|---|---|"]
    for s in sets:
        ta, tb = tally(s["rows"], "a"), tally(s["rows"], "b")
        lines.append(f"| {s['seed']} | {', '.join(s['base_effects']) or 'none'} | "
                     f"{ta['named_right']}/{ta['effect_cases']}, {ta['clean_recognised']}/{ta['clean_cases']} | "
                     f"{tb['named_right']}/{tb['effect_cases']}, {tb['clean_recognised']}/{tb['clean_cases']} |")
    lines += ["", "Cases where the two rules disagree:", "",
              f"| seed | case | injected | magnitude | {label['a']} | {label['b']} |", "|---|---|---|---|---|---|"]
    for s in sets:
        for r in s["rows"]:
            if r["a"] != r["b"]:
                magnitude = "-" if r["magnitude"] is None else f"{r['magnitude']:.2f}"
                lines.append(f"| {s['seed']} | {r['case']} | {r['true']} | {magnitude} | {r['a']} | {r['b']} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps({"labels": label, "totals": totals, "sets": sets},
                                                          indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
