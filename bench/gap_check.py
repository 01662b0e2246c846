"""The withheld-effect check of the gap diagnosis: confusion matrix, accuracy, shrinkage, time.

Runs ``buildenv.diagnosis.blind_check.run_check`` (resumable: cases already in ``--out`` are not redone) and merges
its cases into ``bench/results/<name>.json`` (default ``gap_check``), which holds every seed's sites at their
latest record (:func:`harness.slim_record`); ``<name>.md`` summarises them all, then this run in full. Targets:
the injected effect named first in >= 90 % of cases, the no-effect case recognised in >= 90 %, the effect's gap
shrinking by >= 50 % on held-out weeks, one diagnosis of a 4-week site in under 5 minutes on 2 cores.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import platform
import time

import harness
import numpy as np

from buildenv.cli.sites import add_known_argument, parse_known
from buildenv.diagnosis.blind_check import (
    FIRST_MONDAYS,
    NONE,
    VISIBLE_NOISE_MULTIPLE,
    WEEKS,
    latest_first_monday,
    run_check,
)
from buildenv.diagnosis.effects import DIAGNOSIS_SPLITS, JUDGES, get_effect
from buildenv.diagnosis.gap import DiagnosisSettings, split_weeks
from buildenv.energyplus.reference import CONSUMPTION_NOISE_FRACTION, TEMPERATURE_NOISE_K
from buildenv.metamodel.surrogate import load_metamodel

ABOUT = (
    "Every blind-check site at its latest diagnosis record (runs of bench/gap_check.py, and sites diagnosed "
    "again), slimmed to what judging its first step needs; bench/gap_headline.py judges them."
)


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def _implausible(row: dict, alpha: float) -> str:
    """Candidates of the first step that were significant (``alpha`` Bonferroni over the candidates) but whose
    estimate is smaller than the effect ever is in practice (``Effect.smallest``), so never named."""
    names = [n for n in row.get("implausible", []) if row["p_values"].get(n, 1.0) < alpha / len(row["p_values"])]
    return ", ".join(f"{n} {_primary(row['estimates'][n])}" for n in names) or "-"


def _primary(estimate: dict) -> str:
    return next((f"{k} {v:.3g}" for k, v in estimate.items()), "")


def main() -> None:
    """Run (or resume) the check and write the results."""
    parser = harness.parser(__doc__)
    parser.add_argument("--cases", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="out/diagnose-check")
    parser.add_argument("--evaluations", type=int, default=1500)
    parser.add_argument("--max-effects", type=int, default=2)
    parser.add_argument(
        "--refit-step",
        type=float,
        default=DiagnosisSettings.refit_step,
        help="CMA-ES initial step of the building parameters in a refit (share of their ranges)",
    )
    parser.add_argument(
        "--effect-first",
        type=int,
        default=DiagnosisSettings.effect_first_evaluations,
        help="evaluations of a refit's first stage, the new effect alone (0: joint refit only)",
    )
    parser.add_argument(
        "--refit-restarts",
        type=int,
        default=DiagnosisSettings.refit_restarts,
        help="CMA-ES runs of every refit (control and candidates), the lowest fit cost kept",
    )
    parser.add_argument(
        "--refit-anchor",
        type=float,
        default=DiagnosisSettings.refit_anchor,
        help="pull of every refit towards the model it starts from (0: none)",
    )
    parser.add_argument("--name", default="gap_check", help="stem of the result files in bench/results")
    parser.add_argument(
        "--base-effects",
        default="auto",
        help="effects every case models from the start: auto (diagnose a clean reference site "
        "first), none, or comma-separated names",
    )
    parser.add_argument(
        "--judge",
        choices=JUDGES,
        default="pooled",
        help="score candidates on both series, or on the series each shows in",
    )
    parser.add_argument(
        "--base-restarts", type=int, default=1, help="CMA-ES runs of each base calibration, the lowest fit cost kept"
    )
    parser.add_argument(
        "--checkpoint", default="diagnosis", help="metamodel checkpoint the diagnosis uses (default: 'diagnosis')"
    )
    parser.add_argument(
        "--split",
        choices=DIAGNOSIS_SPLITS,
        default=DiagnosisSettings.split,
        help="fit weeks: the first half, or every other week (buildenv.diagnosis.gap.split_weeks)",
    )
    parser.add_argument(
        "--weeks", type=int, default=WEEKS, help="weeks each site measures (fit and held-out weeks: --split)"
    )
    parser.add_argument(
        "--note", default="", help="a line for the page under its header, e.g. where cases resumed from --out were run"
    )
    parser.add_argument(
        "--effects",
        default="",
        help="comma-separated effects the cases inject, with none between them (default: the whole "
        "catalogue less the known effects)",
    )
    add_known_argument(parser)
    args = parser.parse_args()
    known = parse_known(args.known)
    effects = tuple(e.strip() for e in args.effects.split(",") if e.strip()) or None
    for name in effects or ():
        get_effect(name)  # a misspelt name fails here, before the long check
    started, load = time.perf_counter(), os.getloadavg()[0]
    settings = DiagnosisSettings(
        evaluations=args.evaluations,
        max_effects=args.max_effects,
        judge=args.judge,
        base_restarts=args.base_restarts,
        refit_step=args.refit_step,
        effect_first_evaluations=args.effect_first,
        refit_restarts=args.refit_restarts,
        refit_anchor=args.refit_anchor,
        split=args.split,
    )
    base: str | list[str] = args.base_effects
    if base != "auto":
        base = [] if base == "none" else [e.strip() for e in base.split(",")]
    surrogate = load_metamodel(args.checkpoint)
    result = run_check(
        args.out,
        args.cases,
        args.seed,
        surrogate=surrogate,
        settings=settings,
        base_effects=base,
        progress=True,
        known_parameters=known,
        weeks=args.weeks,
        effects=effects,
    )
    s = result["summary"]
    command = (
        f"python bench/gap_check.py --cases {args.cases} --seed {args.seed} --out {args.out} "
        f"--evaluations {args.evaluations} --max-effects {args.max_effects}"
        + (f" --name {args.name}" if args.name != "gap_check" else "")
        + (f" --judge {args.judge}" if args.judge != "pooled" else "")
        + (f" --base-effects {args.base_effects}" if args.base_effects != "auto" else "")
        + (f" --base-restarts {args.base_restarts}" if args.base_restarts != 1 else "")
        + (f" --refit-step {args.refit_step:g}" if args.refit_step != DiagnosisSettings.refit_step else "")
        + (
            f" --refit-restarts {args.refit_restarts}"
            if args.refit_restarts != DiagnosisSettings.refit_restarts
            else ""
        )
        + (f" --refit-anchor {args.refit_anchor:g}" if args.refit_anchor != DiagnosisSettings.refit_anchor else "")
        + (
            f" --effect-first {args.effect_first}"
            if args.effect_first != DiagnosisSettings.effect_first_evaluations
            else ""
        )
        + "".join(f" --known {k}={v:g}" for k, v in known.items())
        + (f" --effects {','.join(effects)}" if effects else "")
        + (f" --checkpoint {args.checkpoint}" if args.checkpoint != "diagnosis" else "")
        + (f" --weeks {args.weeks}" if args.weeks != WEEKS else "")
        + (f" --split {args.split}" if args.split != DiagnosisSettings.split else "")
    )
    record = {
        "date": dt.date.today().isoformat(),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "load_average_at_start": load,
        "command": command,
        "note": args.note,
        "seconds_this_run": round(time.perf_counter() - started, 1),
        **result,
    }
    labels = s["labels"]
    weeks = result["plan"]["weeks"]
    fit_weeks = split_weeks(weeks, args.split)[0]
    named = sorted(
        {n for row in s["confusion"].values() for n, c in row.items() if c} | set(labels),
        key=lambda n: (n not in labels, labels.index(n) if n in labels else 0, n),
    )
    lines = [
        "# Gap diagnosis: the withheld-effect check",
        "",
        f"{record['date']}, {record['machine']}, 1-min load average at start {load:.2f}; `{command}`.",
        f"Building: {result['plan']['building']} in {result['plan']['epw']}, {weeks}-week sites "
        f"({len(fit_weeks)} fit + {weeks - len(fit_weeks)} held-out weeks, split {args.split}), first Monday "
        f"drawn between {FIRST_MONDAYS[0]} and {FIRST_MONDAYS[1]} (at latest {latest_first_monday(weeks)}, so "
        f"the period ends in {FIRST_MONDAYS[1].year}), one effect "
        + (f"of {', '.join(effects)} " if effects else "")
        + "(or none) injected at a random magnitude, "
        "diagnosed blind (`buildenv/diagnosis/blind_check.py` states the procedure).",
        f"Known effects of the clean stand-in, modelled in every case: {result['base_effects'] or 'none'}.",
        "Building parameters every site declares known (fixed in calibration): "
        + (", ".join(f"{k} = {v:g}" for k, v in known.items()) or "none")
        + ".",
        *([args.note] if args.note else []),
        "",
        "| | value | target |",
        "|---|---|---|",
        f"| cases | {s['cases']} ({s['effect_cases']} with an effect, {s['none_cases']} without) | |",
        f"| injected effect named first (top-1) | {_pct(s['top1_accuracy'])} | >= 90 % |",
        *(
            [
                "| of which named by the estimate alone (no held-out gain; "
                f"`buildenv.diagnosis.gap.named_by_estimate`) | "
                f"{s['named_by_estimate_right']} | |"
            ]
            if "named_by_estimate_right" in s
            else []
        ),
        "| injected effect ranked first (best held-out gain, named or not: attribution alone) | "
        f"{_pct(s.get('ranked_first_accuracy'))} | |",
        f"| top-1 among the {s.get('visible_effect_cases', '-')} cases whose effect shows in the data "
        f"(footprint >= {VISIBLE_NOISE_MULTIPLE * TEMPERATURE_NOISE_K:g} K or "
        f"{VISIBLE_NOISE_MULTIPLE * 100 * CONSUMPTION_NOISE_FRACTION:g} %) | "
        f"{_pct(s.get('top1_accuracy_visible'))} | |",
        f"| top-1 among the {s.get('gap_left_cases') if s.get('gap_left_cases') is not None else '-'} cases "
        f"whose effect left >= {100 * settings.min_gain:.0f} % of the calibrated model's held-out error "
        f"(gap left) | {_pct(s.get('top1_accuracy_gap_left'))} | |",
        f"| no-effect cases recognised | {_pct(s['none_recognised'])} | >= 90 % |",
        f"| false-alarm rate | {_pct(s['false_alarm_rate'])} | |",
        *(
            [f"| no-effect cases named an effect by the estimate alone | {s['named_by_estimate_on_none']} | |"]
            if "named_by_estimate_on_none" in s
            else []
        ),
        "| mean shrinkage of the effect's gap (held-out, the "
        f"{s.get('shrinkage_cases_gap_left', '-')} found cases whose effect left a gap) | "
        f"{_pct(s['mean_shrinkage_of_effect_gap'])} | >= 50 % |",
        f"| median shrinkage of the effect's gap (every found case) | {_pct(s['median_shrinkage_of_effect_gap'])} | |",
        f"| mean shrinkage of the whole gap of the series | {_pct(s['mean_shrinkage_of_total_gap'])} | |",
    ]
    times = [r["seconds"] for r in result["cases"]]
    if times:
        lines.append(
            f"| seconds per case (diagnosis, + twin run) | median {np.median(times):.0f}, "
            f"max {max(times):.0f} | diagnosis < 300 |"
        )
    lines += [
        "",
        "## Confusion matrix (rows: injected, columns: named first)",
        "",
        "| injected \\ named | " + " | ".join(named) + " |",
        "|---" * (len(named) + 1) + "|",
    ]
    for t in labels:
        lines.append(f"| {t} | " + " | ".join(str(s["confusion"][t].get(n, 0)) for n in named) + " |")
    lines += [
        "",
        "## Cases",
        "",
        "| case | injected | magnitude | first Monday | named | selected | "
        "footprint K, % | gap left: T, Q, pooled | gain of the injected effect | shrinkage of its gap | "
        "significant, estimate implausible | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["cases"]:
        gain = r["scores"].get(r["true"])
        sh = r.get("shrinkage", {}).get("of_effect_gap") if r.get("shrinkage") else None
        mag = "-" if r["magnitude"] is None else f"{r['magnitude']:.2f}"
        fp = r.get("footprint")
        fp_text = (
            "-"
            if not fp
            else (
                f"{fp['temperature_k']:.2f}, {fp['consumption_percent']:.1f}"
                + ("" if fp["visible"] else " (not visible)")
            )
        )
        gl = r.get("gap_left")
        gl_text = (
            "-"
            if not gl
            else (
                f"{_pct(gl['by_series']['temperature'])}, {_pct(gl['by_series']['consumption'])}"
                f", {_pct(gl['share'])}" + ("" if gl["left"] else " (none left)")
            )
        )
        lines.append(
            f"| {r['case']} | {r['true']} | {mag} | {r['start']} | {r['named']} | "
            f"{', '.join(r['selected']) or '-'} | {fp_text} | {gl_text} | "
            f"{'-' if gain is None else f'{gain:.3f}'} | "
            f"{'-' if sh is None else f'{100 * sh:.0f} %'} | {_implausible(r, settings.alpha)} | "
            f"{r['seconds']} |"
        )
    merged = merge_run(args.name, record)
    lines = [*summary_lines(merged), "", "## The latest run", "", *lines[3:]]
    harness.write_results(args.name, lines, harness.checks_json(merged["sites"], merged["sources"], ABOUT), echo=True)


def merge_run(name: str, record: dict) -> dict:
    """``bench/results/<name>.json``'s sources and sites with ``record``'s run merged in: its cases replace those
    of its seed (a clean twin diagnosed apart stays)."""
    path = harness.RESULTS / f"{name}.json"
    merged = json.loads(path.read_text()) if path.is_file() else {"sources": [], "sites": {}}
    seed = record["plan"]["seed"]
    source = f"{name}_seed{seed}_{record['date']}"
    merged["sources"] = [s for s in merged["sources"] if s["source"] != source] + [
        {
            "source": source,
            "kind": "run",
            "command": record["command"],
            "date": record["date"],
            "machine": record["machine"],
            "seed": seed,
            "plan": record["plan"],
            "base_effects": record["base_effects"],
        }
    ]
    for case in record["cases"]:
        merged["sites"][f"seed{seed}_case_{case['case']:03d}"] = harness.slim_record(case | {"source": source})
    used = {s["source"] for s in merged["sites"].values()}
    merged["sources"] = [s for s in merged["sources"] if s["source"] in used]
    return merged


def summary_lines(merged: dict) -> list[str]:
    """The page's summary of every seed's sites as their own diagnoses named them (``named`` as recorded)."""
    seeds: dict[int, dict] = {}
    for site, s in merged["sites"].items():
        seed, _, twin = harness.SITE.match(site).groups()
        row = seeds.setdefault(
            int(seed), {"cases": 0, "right": 0, "clean": 0, "clean_right": 0, "twins": 0, "twins_right": 0}
        )
        kind = "twins" if twin else "clean" if s["true"] == NONE else "cases"
        row[kind] += 1
        row[kind + "_right" if kind != "cases" else "right"] += s["named"] == (NONE if kind != "cases" else s["true"])
    total = {
        k: sum(r[k] for r in seeds.values()) for k in ("cases", "right", "clean", "clean_right", "twins", "twins_right")
    }
    runs = [s for s in merged["sources"] if s["kind"] == "run"]
    weeks = sorted({s["plan"]["weeks"] for s in runs})
    return [
        "# Gap diagnosis: the withheld-effect check",
        "",
        f"{len(merged['sites'])} sites of {len(seeds)} seeds ({min(seeds)}-{max(seeds)}): "
        f"{total['cases']} with an injected effect, {total['clean']} clean, {total['twins']} clean twins, "
        f"{'/'.join(map(str, weeks))}-week sites of {', '.join(sorted({s['plan']['building'] for s in runs}))} "
        f"in {', '.join(sorted({s['plan']['epw'] for s in runs}))}, recorded by {len(merged['sources'])} runs "
        "(`gap_check.json` lists them). As each site's own diagnosis named it; `gap_headline.md` judges them "
        "with the current rules.",
        "",
        "| | recorded | target |",
        "|---|---|---|",
        f"| injected effect named first | {harness.percent(total['right'], total['cases'])} | >= 90 % |",
        f"| clean cases recognised | {harness.percent(total['clean_right'], total['clean'])} | >= 90 % |",
        f"| clean twins recognised | {harness.percent(total['twins_right'], total['twins'])} | |",
    ]


if __name__ == "__main__":
    main()
