"""What an effect the base calibration absorbs does to the calibrated building parameters.

Some blind cases of ``buildenv diagnose-check`` leave no gap a candidate can close: the base calibration moves
the building parameters until the injected effect is explained. This script calibrates such cases and their
clean twins (the same site without the effect, which the check makes beside each case) exactly as the
diagnosis' base model is calibrated (the check's known effects declared, 3 CMA-ES restarts, the check's fit
weeks), and compares: the held-out R2_T, the parameters each calibrated at a bound of its catalogue range
(:func:`buildenv.calibration.parameters_at_bounds`) and the parameters that moved most between twin and case,
as a share of their range. Calibrations are kept in ``--work`` and reused.

``--joint CANDIDATES`` instead tests each candidate effect on every case and twin with two joint calibrations
from scratch (:func:`buildenv.gap.joint_calibration_tests`: the known effects in both, the candidate in the
second; building parameters, occupancy and effects searched together), judged on the held-out weeks like a
diagnosis candidate. An effect the building parameters absorbed in the base calibration should gain on its
case and not on its twin. Results are kept in ``--work`` as ``joint_*.json`` and reused.
Writes ``bench/results/{name}.{md,json}``.

    .venv/bin/python bench/absorbed_effects.py [--check out/diagnose-check-seed0-8weeks-alternate]
        [--cases 1,3,8,9] [--split alternate] [--joint wind_infiltration --name absorbed_effects_joint]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import platform
import shutil
from pathlib import Path

from buildenv import catalogue as cat
from buildenv.calibration import KNOWN_GEOMETRY, calibrate_site, load_calibration, parameters_at_bounds
from buildenv.gap import DiagnosisSettings, joint_calibration_tests, split_weeks
from buildenv.site import load_site
from buildenv.surrogate import load_metamodel

RESULTS = Path(__file__).parent / "results"
KNOWN_EFFECTS = ("night_cycle_cold_air", "evening_departure")
LARGEST = 3
JOINT_RESTARTS = 3  # CMA-ES runs of each --joint calibration, as the blind checks' base calibrations


def calibrated(source: Path, work: Path, split: str, surrogate) -> dict:
    """The base calibration of the site folder ``source`` (made in a copy under ``work`` once, then reused)."""
    copy = work / source.name
    if not (copy / "calibration.json").is_file():
        shutil.rmtree(copy, ignore_errors=True)
        shutil.copytree(source, copy)
        site = load_site(copy)
        calibrate_site(site, surrogate, weeks=split_weeks(site.weeks, split)[0], effects=KNOWN_EFFECTS,
                       restarts=3)
    return load_calibration(copy)


def joint_tests(source: Path, work: Path, split: str, candidates: tuple[str, ...], surrogate) -> dict:
    """:func:`buildenv.gap.joint_calibration_tests` of ``candidates`` on the site folder ``source`` (known effects
    declared, 3 CMA-ES restarts): ``{candidate: test}``, kept in ``work`` and reused."""
    path = work / f"joint_{source.name}_{'+'.join(candidates)}_{split}.json"
    if not path.is_file():
        settings = DiagnosisSettings(base_effects=KNOWN_EFFECTS, base_restarts=JOINT_RESTARTS, split=split)
        work.mkdir(parents=True, exist_ok=True)
        tests = joint_calibration_tests(load_site(source), surrogate, candidates, settings)
        path.write_text(json.dumps({t["candidate"]: t for t in tests}, indent=1, default=float) + "\n")
    return json.loads(path.read_text())


def compare(case: dict, twin: dict) -> dict:
    """At-bound parameters of a case and its twin, and the parameters that moved most between them."""
    at_case = {e["name"]: e["bound"] for e in parameters_at_bounds(case["theta"], case["known"])}
    at_twin = {e["name"]: e["bound"] for e in parameters_at_bounds(twin["theta"], twin["known"])}
    moves = sorted(((abs(case["theta"][n] - twin["theta"][n]) / (cat.get(n).max - cat.get(n).min), n)
                    for n in case["theta"] if n not in KNOWN_GEOMETRY), reverse=True)[:LARGEST]
    return {"heldout_r2_t": {"case": case["heldout"]["r2_t"], "twin": twin["heldout"]["r2_t"]},
            "at_bounds_case": at_case, "at_bounds_twin": at_twin,
            "at_bounds_common": sorted(set(at_case) & set(at_twin)),
            "largest_moves": [{"name": n, "share_of_range": round(share, 3), "twin": twin["theta"][n],
                               "case": case["theta"][n]} for share, n in moves]}


def main() -> None:
    """Calibrate the cases and their twins, compare, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", type=Path, default=Path("out/diagnose-check-seed0-8weeks-alternate"))
    parser.add_argument("--cases", default="1,3,8,9")
    parser.add_argument("--split", default="alternate")
    parser.add_argument("--work", type=Path, default=Path("out/absorbed-effects"))
    parser.add_argument("--name", default="absorbed_effects")
    parser.add_argument("--joint", default=None, metavar="CANDIDATES",
                        help="comma-separated effects to test by joint calibration instead")
    args = parser.parse_args()
    surrogate = load_metamodel()
    rows = []
    for i in (int(c) for c in args.cases.split(",")):
        source = args.check / f"case_{i:03d}"
        truth = json.loads((source / "truth.json").read_text())["effects"][0]
        if args.joint:
            candidates = tuple(args.joint.split(","))
            case, twin = (joint_tests(args.check / f"case_{i:03d}{suffix}", args.work, args.split, candidates,
                                      surrogate) for suffix in ("", "_twin"))
            rows += [{"case": i, "effect": truth["name"], "magnitude": truth["magnitude"], "candidate": c,
                      "case_test": case[c], "twin_test": twin[c]} for c in candidates]
            continue
        case = calibrated(source, args.work, args.split, surrogate)
        twin = calibrated(args.check / f"case_{i:03d}_twin", args.work, args.split, surrogate)
        rows.append({"case": i, "effect": truth["name"], "magnitude": truth["magnitude"], "unit": truth["unit"],
                     **compare(case, twin)})
    data = {"date": dt.date.today().isoformat(), "machine": platform.platform(), "check": str(args.check),
            "split": args.split, "known_effects": list(KNOWN_EFFECTS), "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(data, indent=1) + "\n")
    page = joint_markdown(data, args) if args.joint else markdown(data, args)
    (RESULTS / f"{args.name}.md").write_text(page)
    print(page)


def joint_markdown(data: dict, args: argparse.Namespace) -> str:
    """The results page of ``--joint``."""
    lines = ["# Absorbed effects: candidates tested by joint calibration on blind cases and their clean twins", "",
             f"{data['date']}, {data['machine']}; `python bench/absorbed_effects.py --check {args.check} --cases "
             f"{args.cases} --split {args.split} --joint {args.joint} --name {args.name}`. Every site is calibrated "
             f"from scratch with the known effects ({', '.join(data['known_effects'])}), and again with each "
             "candidate added (building parameters, occupancy and effects searched together; "
             f"{DiagnosisSettings.base_evaluations:,} evaluations x {JOINT_RESTARTS} CMA-ES restarts each, fit weeks "
             f"of the {data['split']} split); each candidate's model is judged "
             "against the first on the held-out weeks like a diagnosis candidate (standardised pooled squared "
             "error; `buildenv.gap.joint_calibration_tests`). A candidate a diagnosis names must gain at least "
             "15 %.", "",
             "| case | injected | candidate | estimate: case / twin | held-out gain case (T, Q) | p case | "
             "held-out gain twin (T, Q) | fit cost case: without -> with |", "|---|---|---|---|---|---|---|---|"]
    for r in data["rows"]:
        c, t = r["case_test"], r["twin_test"]
        est = " / ".join(", ".join(f"{k} {v:.4g}" for k, v in x["estimate"].items()) for x in (c, t))
        gains = [f"{100 * x['gain']:.1f} % ({100 * x['gain_by_series']['temperature']:.0f} %, "
                 f"{100 * x['gain_by_series']['consumption']:.0f} %)" for x in (c, t)]
        lines.append(f"| {r['case']} | {r['effect']} {r['magnitude']:.2f} | {r['candidate']} | {est} | {gains[0]} | "
                     f"{c['p_value']:.2g} | {gains[1]} | {c['cost_without']:.4f} -> {c['cost_with']:.4f} |")
    return "\n".join(lines) + "\n"


def markdown(data: dict, args: argparse.Namespace) -> str:
    """The results page."""
    lines = ["# Absorbed effects: calibrated parameters of blind cases against their clean twins", "",
             f"{data['date']}, {data['machine']}; `python bench/absorbed_effects.py --check {args.check} --cases "
             f"{args.cases} --split {args.split}`. Base calibration as the diagnosis' (known effects "
             f"{', '.join(data['known_effects'])}, 3 CMA-ES restarts, fit weeks of the {data['split']} split).", "",
             "| case | injected | held-out R2_T case / twin | at a bound: case, twin, both | only the case | "
             "only the twin | largest moves twin -> case (share of range) |", "|---|---|---|---|---|---|---|"]
    for r in data["rows"]:
        only_case = {k: v for k, v in r["at_bounds_case"].items() if k not in r["at_bounds_twin"]}
        only_twin = {k: v for k, v in r["at_bounds_twin"].items() if k not in r["at_bounds_case"]}
        moves = ", ".join(f"{m['name']} {m['twin']:.3g} -> {m['case']:.3g} ({m['share_of_range']:.2f})"
                          for m in r["largest_moves"])
        lines.append(f"| {r['case']} | {r['effect']} {r['magnitude']:.2f} | {r['heldout_r2_t']['case']:.3f} / "
                     f"{r['heldout_r2_t']['twin']:.3f} | {len(r['at_bounds_case'])}, {len(r['at_bounds_twin'])}, "
                     f"{len(r['at_bounds_common'])} | "
                     + (", ".join(f"{k} ({v})" for k, v in only_case.items()) or "-") + " | "
                     + (", ".join(f"{k} ({v})" for k, v in only_twin.items()) or "-") + f" | {moves} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
