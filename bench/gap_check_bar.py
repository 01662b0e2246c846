"""The diagnosis' naming bar (``min_gain``) measured on blind checks and on their clean twins.

A candidate effect was named when it was significant, plausible and its held-out gain reached ``min_gain``
(:func:`buildenv.gap.candidate_qualifies` with ``clean_ceilings=False``, the rule this page replays; from
2026-11-28 an effect with a clean-site ceiling is judged by its estimate instead, ``bench/gap_clean_ceiling.py``).
The bar trades named effects against false alarms, so it is measured on both: on the effect cases of
recorded blind checks (``bench/gap_check.py`` pages), whose first step every record keeps, and on clean sites.
A check has only one or two clean cases a seed; every effect case has a clean twin (same period, same sensor
noise, nothing injected), and ``--twins PAGE`` diagnoses those twins blind
(:func:`buildenv.gap_check.diagnose_twin`, ``twin_NNN.json`` beside the check's case files, a rerun skips
those done), so one seed gives about 14 more clean sites.

Each bar judges every record's first step again, as ``bench/gap_check_rejudge.py`` does. For an effect
named right it gives the shrinkage of the effect's gap: the recorded one where the check named it, else what
the first step alone gives, the candidate's held-out squared error of the effect's series (recorded,
standardised) against the base model's and the clean twin's, as ``run_case`` computes it from the final model
(the same figure where one effect is selected; not replayed for an effect the base model carries).

    .venv/bin/python bench/gap_check_bar.py --page bench/results/gap_check_tb_seed0.json ... \\
        [--twins bench/results/gap_check_tb_seed3.json ...] [--no-diagnose] [--held-out 5] --name gap_check_bar

Run it from the repository root: a check's folder is read from its page's command.

Writes ``bench/results/NAME.{md,json}``; the json keeps the twins' records too (the check folders are not
committed).
"""

from __future__ import annotations

import argparse
import json
import shlex
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from gap_check_rejudge import first_named

from buildenv.effects import get_effect
from buildenv.gap import SERIES, DiagnosisSettings
from buildenv.gap_check import NONE, StandIn, _mse, diagnose_twin, ranked_first

RESULTS = Path(__file__).resolve().parent / "results"
BARS = (0.05, 0.08, 0.10, 0.12, 0.15)
CASE_KEYS = ("case", "true", "magnitude", "start", "noise_seed", "effect_seed")


def check_folder(page: dict) -> Path:
    """The ``--out`` folder of the check a page was made from (its recorded command)."""
    words = shlex.split(page["command"])
    return Path(words[words.index("--out") + 1])


def recorded_settings(settings: dict) -> DiagnosisSettings:
    """The diagnosis settings a check recorded (its plan's ``settings``, lists back to tuples)."""
    return DiagnosisSettings(**{k: tuple(v) if isinstance(v, list) else v for k, v in settings.items()})


def twin_records(page: dict, diagnose: bool, progress: bool = True) -> list[dict]:
    """The clean twins' diagnoses of a check's effect cases, those missing made first when ``diagnose``."""
    from buildenv.surrogate import load_metamodel

    out, plan = check_folder(page), page["plan"]
    settings = recorded_settings(plan["settings"])
    stand_in = StandIn(plan["building"], plan["epw"], plan.get("known_parameters", {}), plan["weeks"],
                       settings.split)
    surrogate, rows = None, []
    for row in page["cases"]:
        if row["true"] == NONE:
            continue
        path = out / f"twin_{row['case']:03d}.json"
        if not path.is_file():
            if not diagnose:
                continue
            surrogate = surrogate or load_metamodel()
            twin = diagnose_twin(out, {k: row[k] for k in CASE_KEYS}, surrogate, settings, stand_in)
            path.write_text(json.dumps(twin, indent=1, default=float) + "\n")
            if progress:
                print(f"seed {plan['seed']} twin of case {row['case']}: {twin['named']} ({twin['seconds']} s)")
        rows.append(json.loads(path.read_text()))
    return rows


def first_step_shrinkage(row: dict, name: str) -> float | None:
    """Share of the effect's gap on its series that the first step's candidate ``name`` removes (``None``
    where the record lacks what it needs, the case's base model is no worse than its twin's there, or the
    effect is one the base model carries, whose candidate is judged the other way round)."""
    if get_effect(name).building_parameter:
        return None
    series = get_effect(name).series[0]
    try:
        before, twin = _mse(row["heldout_base"], series), _mse(row["twin_heldout_base"], series)
        sse = row["sse_by_series"][name][series][1]  # (control, candidate), standardised
        after = sse / row["heldout_base"]["hours"] * row["residual_sigma"][SERIES.index(series)] ** 2
    except (KeyError, TypeError):
        return None
    return (before - after) / (before - twin) if before - twin > 1e-12 else None


def bar_named(row: dict, alpha: float, bar: float) -> str:
    """The effect a record's first step names with every effect judged by the gain ``bar``."""
    return first_named(row, alpha, bar, clean_ceilings=False)


def judge(rows: list[dict], twins: list[dict], name_of: Callable[[dict], str]) -> dict:
    """Counts of one naming rule (``name_of``: a record's first-step naming) over effect cases, clean cases and
    clean twins."""
    effect = [r for r in rows if r["true"] != NONE]
    named = [name_of(r) for r in effect]
    shrink = [r["shrinkage"]["of_effect_gap"] if r.get("correct") and "shrinkage" in r
              else first_step_shrinkage(r, r["true"]) for r, n in zip(effect, named) if n == r["true"]]
    shrink = [s for s in shrink if s is not None]
    return {"effect_cases": len(effect), "named_right": sum(n == r["true"] for r, n in zip(effect, named)),
            "named_wrong": sum(n not in (NONE, r["true"]) for r, n in zip(effect, named)),
            "ranked_first": sum(ranked_first(r) for r in effect),
            "clean_cases": sum(r["true"] == NONE for r in rows),
            "clean_recognised": sum(name_of(r) == NONE for r in rows if r["true"] == NONE),
            "twins": len(twins), "twins_recognised": sum(name_of(r) == NONE for r in twins),
            "median_first_step_shrinkage": float(np.median(shrink)) if shrink else None, "shrinkages": shrink,
            "named": {r["case"]: n for r, n in zip(effect, named)},
            "twins_named": {r["case"]: name_of(r) for r in twins}}


def replay_check(pages: list[dict]) -> tuple[int, float]:
    """Cases named right with one effect selected: how many, and the largest difference between the recorded
    shrinkage and the first step's replayed one (the replay's own check)."""
    pairs = [(first_step_shrinkage(r, r["true"]), r["shrinkage"]["of_effect_gap"]) for p in pages for r in p["cases"]
             if r.get("correct") and r["true"] != NONE and len(r["selected"]) == 1 and "shrinkage" in r]
    diffs = [abs(a - b) for a, b in pairs if a is not None and np.isfinite(b)]
    return len(diffs), max(diffs, default=float("nan"))


def _cell(t: dict) -> list[str]:
    share = t["named_right"] / t["effect_cases"] if t["effect_cases"] else float("nan")
    clean = t["clean_recognised"] + t["twins_recognised"], t["clean_cases"] + t["twins"]
    shrink = "-" if t["median_first_step_shrinkage"] is None else f"{100 * t['median_first_step_shrinkage']:.0f} %"
    return [f"{t['named_right']}/{t['effect_cases']} ({100 * share:.0f} %)", f"{t['named_wrong']}",
            f"{t['clean_recognised']}/{t['clean_cases']}",
            f"{t['twins_recognised']}/{t['twins']}" if t["twins"] else "-",
            f"{clean[0]}/{clean[1]}", shrink]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result (.json)")
    parser.add_argument("--twins", action="append", default=[],
                        help="a page whose effect cases' clean twins are diagnosed (or read) too")
    parser.add_argument("--no-diagnose", action="store_true", help="read the twins' records only")
    parser.add_argument("--bars", default=",".join(f"{b:g}" for b in BARS), help="min_gain values, comma-separated")
    parser.add_argument("--held-out", default="",
                        help="seeds kept out of choosing the bar, comma-separated: their cases are also tabulated "
                             "apart from the others' (the twins only under 'all')")
    parser.add_argument("--note", default="", help="a paragraph for the page (where the runs ran)")
    parser.add_argument("--name", default="gap_check_bar")
    args = parser.parse_args()
    started = time.perf_counter()
    pages = {p: json.loads(Path(p).read_text()) for p in dict.fromkeys(args.page + args.twins)}
    twins = {p: twin_records(pages[p], not args.no_diagnose) for p in args.twins}
    bars = [float(b) for b in args.bars.split(",")]
    held = {int(s) for s in args.held_out.split(",") if s}
    alpha = next(iter(pages.values()))["plan"]["settings"]["alpha"]
    groups = {"all": list(pages)}
    if held:
        groups["seeds that chose the bar"] = [p for p in pages if pages[p]["plan"]["seed"] not in held]
        groups[f"held out (seeds {', '.join(map(str, sorted(held)))})"] = [p for p in pages
                                                                          if pages[p]["plan"]["seed"] in held]
    table = {group: {f"{b:g}": judge([r for p in members for r in pages[p]["cases"]],
                                     [t for p in members for t in twins.get(p, [])] if group == "all" else [],
                                     partial(bar_named, alpha=alpha, bar=b)) for b in bars}
             for group, members in groups.items()}
    per_page = {p: {f"{b:g}": judge(pages[p]["cases"], twins.get(p, []), partial(bar_named, alpha=alpha, bar=b))
                    for b in bars} for p in pages}
    count, worst = replay_check(list(pages.values()))
    command = ("python bench/gap_check_bar.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --twins {p}" for p in args.twins) + (" --no-diagnose" if args.no_diagnose else "")
               + (f" --bars {args.bars}" if args.bars != parser.get_default("bars") else "")
               + (f" --held-out {args.held_out}" if args.held_out else "") + f" --name {args.name}")
    head = ["bar", "injected effect named first", "named another effect", "clean cases recognised",
            "clean twins recognised", "all clean sites", "median shrinkage (first step)"]
    lines = [f"# The naming bar on blind checks and clean twins ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}` ({time.perf_counter() - started:.0f} s).", "",
             *([args.note, ""] if args.note else []),
             "Every record's first step judged again at each bar (significance at the recorded alpha over the "
             "step's candidates, the plausibility rules, the bar). Shrinkage: of the effect's gap on its series, over "
             "the effect cases named right: the recorded one where the check named the effect, else the first "
             "step's alone (not replayed for a carried effect, night plug loads or a capacity limit, which are then "
             f"left out); that replay gives the recorded shrinkage of the {count} cases named right with one "
             f"effect selected to within {worst:.1e}.", ""]
    for group, by_bar in table.items():
        lines += [f"## {group}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += [f"| {b} | " + " | ".join(_cell(t)) + " |" for b, t in by_bar.items()]
        lines.append("")
    lines += ["## Each page", "", "| page | seed | " + " | ".join(f"bar {b:g}: right, wrong, clean" for b in bars)
              + " |", "|---|---|" + "---|" * len(bars)]
    for p, by_bar in per_page.items():
        cells = [f"{t['named_right']}/{t['effect_cases']}, {t['named_wrong']}, "
                 f"{t['clean_recognised'] + t['twins_recognised']}/{t['clean_cases'] + t['twins']}"
                 for t in by_bar.values()]
        lines.append(f"| {Path(p).stem} | {pages[p]['plan']['seed']} | " + " | ".join(cells) + " |")
    lines += ["", "## Cases named differently by the bars", "", "| page | case | injected | magnitude | "
              + " | ".join(f"{b:g}" for b in bars) + " |", "|---|---|---|---|" + "---|" * len(bars)]
    for p in per_page:
        for row in pages[p]["cases"] + twins.get(p, []):
            names = [bar_named(row, alpha, b) for b in bars]
            if len(set(names)) > 1:
                what = f"clean twin of {row['twin_of']}" if "twin_of" in row else row["true"]
                magnitude = "-" if row.get("magnitude") is None or "twin_of" in row else f"{row['magnitude']:.2f}"
                lines.append(f"| {Path(p).stem} | {row['case']} | {what} | {magnitude} | " + " | ".join(names) + " |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps({"command": command, "note": args.note, "groups": table,
                                                           "pages": per_page, "replay_check": [count, worst],
                                                           "twin_records": twins}, indent=1, default=float) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
