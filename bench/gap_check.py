"""The withheld-effect check of the gap diagnosis: confusion matrix, top-1, false alarms, "not enough data", wrong
effects, shrinkage and time, per part of the suite.

Runs :func:`buildenv.diagnosis.blind_check.run_check` (resumable: the cases already in ``--out`` are read back, not
redone) and merges its cases into ``bench/results/<name>.json`` (default ``gap_check``), which holds every seed's
cases of one setup (matrix, part, weeks, diagnosis settings, base effects) at their latest run
(:func:`harness.slim_case`); ``<name>.md`` scores them all, per part with ``--matrix suite``, then lists this run's
cases. Targets: the injected effect named first in >= 90 % of the effect cases, no effect named on >= 90 % of the
clean ones, the effect's gap shrinking by >= 50 % on held-out weeks, one diagnosis of a 4-week site in under 5
minutes on 2 cores. The diagnosis's options and defaults are those of ``buildenv diagnose-check``.
"""

from __future__ import annotations

import json
import sys
import time

import harness
import numpy as np

from buildenv.cli.sites import add_known_argument, parse_known
from buildenv.diagnosis.blind_check import NONE, REFUSED, WEEKS, run_check, summarise
from buildenv.diagnosis.effects import CHECKED_DIAGNOSIS, DIAGNOSIS_SPLITS, get_effect
from buildenv.diagnosis.gap import DiagnosisSettings
from buildenv.jsonio import dumps
from buildenv.metamodel.surrogate import load_metamodel

ABOUT = "Every case of the runs of bench/gap_check.py of one setup at its latest run, slimmed (bench/harness.py)."
PARTS = ("development", "held_out")


def arguments():
    """The check's options: the plan, the diagnosis (as ``buildenv diagnose-check``'s) and the page."""
    p = harness.parser(__doc__, first_line=True)
    p.add_argument("--cases", type=int, default=16)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="out/diagnose-check", help="folder of the cases (a rerun resumes)")
    p.add_argument("--matrix", choices=("stand_in", "suite"), default="stand_in")
    p.add_argument("--part", choices=("development", "held_out", "both"), default="both", help="with --matrix suite")
    p.add_argument("--weeks", type=int, default=WEEKS, help="weeks each site measures (fit and held out: --split)")
    p.add_argument("--effects", default="", help="comma-separated effects injected (default: the whole catalogue)")
    p.add_argument("--base-effects", default="auto", help="auto, none, or comma-separated effects every case models")
    add_known_argument(p)
    p.add_argument("--checkpoint", default="diagnosis", help="metamodel checkpoint of the diagnosis")
    p.add_argument("--evaluations", type=int, default=DiagnosisSettings.evaluations)
    p.add_argument("--alpha", type=float, default=DiagnosisSettings.alpha, help="significance level of a step")
    p.add_argument("--max-effects", type=int, default=CHECKED_DIAGNOSIS["max_effects"])
    p.add_argument("--base-restarts", type=int, default=CHECKED_DIAGNOSIS["base_restarts"])
    p.add_argument("--split", choices=DIAGNOSIS_SPLITS, default=CHECKED_DIAGNOSIS["split"])
    p.add_argument("--refit-step", type=float, default=DiagnosisSettings.refit_step)
    p.add_argument("--effect-first", type=int, default=DiagnosisSettings.effect_first_evaluations)
    p.add_argument("--refit-restarts", type=int, default=DiagnosisSettings.refit_restarts)
    p.add_argument("--refit-anchor", type=float, default=DiagnosisSettings.refit_anchor)
    p.add_argument("--name", default="gap_check", help="stem of the result files in bench/results")
    p.add_argument("--note", default="", help="a line on this run for the page")
    return p


def main() -> None:
    """Run (or resume) the check, merge its cases and write the page."""
    args = arguments().parse_args()
    effects = tuple(get_effect(e.strip()).name for e in args.effects.split(",") if e.strip()) or None
    base = args.base_effects
    base = base if base == "auto" else [get_effect(e.strip()).name for e in base.split(",") if e.strip() != "none"]
    settings = DiagnosisSettings(
        evaluations=args.evaluations,
        alpha=args.alpha,
        max_effects=args.max_effects,
        base_restarts=args.base_restarts,
        split=args.split,
        refit_step=args.refit_step,
        effect_first_evaluations=args.effect_first,
        refit_restarts=args.refit_restarts,
        refit_anchor=args.refit_anchor,
    )
    started = time.perf_counter()
    result = run_check(
        args.out,
        args.cases,
        args.seed,
        surrogate=load_metamodel(args.checkpoint),
        settings=settings,
        base_effects=base,
        effects=effects,
        progress=True,
        known_parameters=parse_known(args.known),
        weeks=args.weeks,
        matrix=args.matrix,
        part=args.part,
    )
    run = harness.provenance()
    source = {
        "source": f"seed{args.seed}_{args.part + '_' if args.matrix == 'suite' else ''}{run['date']}",
        "seed": args.seed,
        "command": run["command"],
        "date": run["date"],
        "machine": run["machine"],
        "seconds": round(time.perf_counter() - started, 1),
        "note": args.note,
    }
    merged = merge_run(args.name, result, source)
    lines = [*page(merged), "", *run_lines(result, source)]
    harness.write_results(args.name, lines, harness.checks_json(merged, merged["sites"]), echo=True)


def setup_of(result: dict) -> dict:
    """What every run merged into one file shares: the plan less its cases and seed, the base effects modelled and
    the labels scored (JSON types)."""
    plan = {k: v for k, v in result["plan"].items() if k not in ("cases", "seed", "part")}
    setup = {**plan, "base_effects": result["base_effects"], "labels": result["summary"]["labels"]}
    return json.loads(dumps(setup, where="the check's setup", nonfinite="null"))


def merge_run(name: str, result: dict, source: dict) -> dict:
    """``bench/results/<name>.json`` with a run's cases merged in (those of its seed replaced), its summaries
    (:func:`summaries`) computed again. A file of an earlier diagnosis's records is replaced; one of another setup
    is refused (``SystemExit``, one line: the run's cases stay in its ``--out``)."""
    path = harness.RESULTS / f"{name}.json"
    setup = setup_of(result)
    merged = {"about": ABOUT, "setup": setup, "sources": [], "sites": {}}
    if path.is_file():
        try:
            old = harness.read_checks(path)
        except ValueError as error:
            print(f"{error}: replaced by this run's cases", file=sys.stderr)
        else:
            if old["setup"] != setup:
                differ = sorted(k for k in {*setup, *old["setup"]} if setup.get(k) != old["setup"].get(k))
                raise SystemExit(
                    f"{path}: its runs differ from this one in {', '.join(differ)}; rerun with --name NAME "
                    "(the cases are read back from --out)"
                )
            merged |= {"sources": old["sources"], "sites": old["sites"]}
    seed, part = source["seed"], result["plan"].get("part")
    part_key = f"{part}_" if part else ""

    def same_run(site: str) -> bool:
        s_seed, s_part, _ = harness.SITE.match(site).groups()
        return int(s_seed) == seed and (s_part or None) == part

    sites = {s: r for s, r in merged["sites"].items() if not same_run(s)}
    for case in result["cases"]:
        sites[f"seed{seed}_{part_key}case_{case['case']:03d}"] = harness.slim_case(case) | {"source": source["source"]}
    used = {r["source"] for r in sites.values()}
    merged["sources"] = [s for s in merged["sources"] if s["source"] in used and s["source"] != source["source"]]
    merged["sources"].append(source)
    merged["sites"] = sites
    rows = [harness.expand_case(r) | {"case": site} for site, r in sites.items()]
    merged["summary"] = summaries(rows, setup["labels"])
    return merged


def summaries(rows: list[dict], labels: list[str]) -> dict:
    """``{"all": ..., part: ...}``: :func:`buildenv.diagnosis.blind_check.summarise` of the scored cases, over all
    and over each part of the suite they come from, each with its refused cases, the effect cases whose clean twin
    names the injected effect too, and the seconds per case (median, max)."""
    out = {}
    for part in ("all", *(p for p in PARTS if any(r.get("part") == p for r in rows))):
        mine = [r for r in rows if part in ("all", r.get("part"))]
        scored = [r for r in mine if r.get("status") != REFUSED]
        seconds = [r["seconds"] for r in scored]
        out[part] = {
            **summarise(scored, labels),
            "refused_cases": len(mine) - len(scored),
            "twin_names_the_injected_effect": sum(
                r["true"] != NONE and r["true"] in r.get("twin_named", []) for r in scored
            ),
            "seconds_median": float(np.median(seconds)) if seconds else None,
            "seconds_max": max(seconds, default=None),
        }
    return out


#: The page's rates: (label, summary key, the count it is a share of, target).
RATES = (
    ("injected effect named first (top-1)", "top1_accuracy", "effect_cases", ">= 90 % (8-week sites)"),
    ("another effect named", "wrong_effect_rate", "effect_cases", "<= 5 % (4-week sites)"),
    ('"not enough data to tell" for the injected effect', "not_enough_data_rate", "effect_cases", ""),
    ('right, or "not enough data to tell"', "right_or_not_enough_data_rate", "effect_cases", ""),
    ("injected effect ranked first (best held-out gain, named or not)", "ranked_first_accuracy", "effect_cases", ""),
    ("top-1 where the effect left a gap after calibration", "top1_accuracy_gap_left", "gap_left_cases", ""),
    ("false alarms (an effect named on a clean case)", "false_alarm_rate", "none_cases", "<= 5 %"),
    (
        "mean shrinkage of the effect's gap (found, a gap left)",
        "mean_shrinkage_of_effect_gap",
        "shrinkage_cases_gap_left",
        ">= 50 %",
    ),
    ("median shrinkage of the effect's gap (found)", "median_shrinkage_of_effect_gap", None, ""),
)


def _rate(x: float | None, n: int | None = None) -> str:
    return "-" if x is None or n == 0 else f"{100 * x:.0f} %" + (f" of {n}" if n else "")


def page(merged: dict) -> list[str]:
    """The page's scores of every merged case: a table with a column per part, a confusion matrix per part."""
    setup, parts = merged["setup"], merged["summary"]
    seeds = sorted({int(harness.SITE.match(s).group(1)) for s in merged["sites"]})
    suite = setup["matrix"] == "suite"
    where = (
        "the suite's buildings, climates and seasons, judged beyond each clean twin"
        if suite
        else f"{setup['building']} in {setup['epw']}"
    )
    settings = ", ".join(f"{k} {v}" for k, v in setup["settings"].items() if k not in ("base_effects", "seed"))
    lines = [
        "# Gap diagnosis: the withheld-effect check",
        "",
        f"{len(merged['sites'])} cases of {len(seeds)} seeds ({seeds[0]}-{seeds[-1]}), {setup['weeks']}-week sites of "
        f"{where}, one effect (or none) injected at a random magnitude and diagnosed blind "
        f"(`buildenv/diagnosis/blind_check.py`); base effects {', '.join(setup['base_effects']) or 'none'}; "
        f"{settings}. Recorded by {len(merged['sources'])} runs (their commands in the json).",
        "",
        "| | " + " | ".join(parts) + " | target |",
        "|---" * (len(parts) + 2) + "|",
    ]

    def row(label: str, cell, target: str = "") -> str:
        return f"| {label} | " + " | ".join(cell(s) for s in parts.values()) + f" | {target} |"

    lines.append(
        row(
            "cases: with an effect, clean, refused",
            lambda s: f"{s['effect_cases']}, {s['none_cases']}, {s['refused_cases']}",
        )
    )
    lines += [
        row(label, lambda s, k=key, n=count: _rate(s[k], s[n] if n else None), aim) for label, key, count, aim in RATES
    ]
    if suite:
        lines.append(
            row("injected effect named by the clean twin too", lambda s: str(s["twin_names_the_injected_effect"]))
        )
    lines.append(
        row(
            "seconds of one diagnosis, case or twin (median)",
            lambda s: "-" if s.get("median_diagnosis_seconds") is None else f"{s['median_diagnosis_seconds']:.0f}",
            "< 120 (8 weeks)",
        )
    )
    lines.append(
        row(
            "seconds a case (its diagnosis, its footprint and gap left): median, max",
            lambda s: "-" if s["seconds_max"] is None else f"{s['seconds_median']:.0f}, {s['seconds_max']:.0f}",
        )
    )
    for part, s in parts.items():
        names = list(next(iter(s["confusion"].values())))
        lines += ["", f"## Confusion matrix, {part} (rows: injected; columns: the answer)", ""]
        lines += ["| injected \\ answer | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
        lines += [f"| {t} | " + " | ".join(str(c[n]) for n in names) + " |" for t, c in s["confusion"].items()]
    return lines


def run_lines(result: dict, source: dict) -> list[str]:
    """This run's cases, one a row: where (suite), injected, answer, the injected effect's gain, p-value and the
    naming rules it failed, the shrinkage of its gap and the seconds."""
    suite = result["plan"]["matrix"] == "suite"
    lines = [
        f"## This run: seed {source['seed']}",
        "",
        f"`{source['command']}`, {source['seconds']:.0f} s (cases already in its --out read back). {source['note']}",
        "",
        "| case | " + ("site | " if suite else "") + "injected | magnitude | first Monday | answer | selected | "
        "not enough data | injected effect: gain, p, rules failed | shrinkage of its gap | seconds |",
        "|---" * (10 + suite) + "|",
    ]
    for r in result["cases"]:
        where = f"{r['building']}, {r['climate']}, {r['season']} ({r['part']}) | " if suite else ""
        magnitude = "-" if r["magnitude"] is None else f"{r['magnitude']:.3g}"
        if r.get("status") == REFUSED:
            lines.append(
                f"| {r['case']} | {where}{r['true']} | {magnitude} | {r['start']} | refused: {r['reason']} |||||"
            )
            continue
        t = r["true"]
        injected = (
            "-"
            if t not in r["scores"]
            else (
                f"{r['scores'][t]:.3f}, "
                + ("-" if r["p_values"][t] is None else f"{r['p_values'][t]:.2g}")
                + f", {', '.join(r['failed'][t]) or 'none'}"
            )
        )
        shrink = (r.get("shrinkage") or {}).get("of_effect_gap")
        cells = (
            r["named"],
            ", ".join(r["selected"]) or "-",
            ", ".join(r["not_enough_data"]) or "-",
            injected,
            "-" if shrink is None or not np.isfinite(shrink) else f"{100 * shrink:.0f} %",
            f"{r['seconds']:.0f}",
        )
        lines.append(f"| {r['case']} | {where}{t} | {magnitude} | {r['start']} | " + " | ".join(cells) + " |")
    return lines


if __name__ == "__main__":
    main()
