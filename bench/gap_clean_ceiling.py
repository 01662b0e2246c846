"""Clean-site ceilings of the diagnosis' candidate effects, and the naming rule they give, on blind checks.

On a site with no effect injected, a calibrated candidate still takes some size: it absorbs part of the
model's structural misses. The largest size any clean site gave a candidate is its clean-site ceiling
(:attr:`buildenv.effects.Effect.clean_ceiling`; for an effect the metamodel carries through a building
parameter, that parameter's value furthest from where the effect vanishes: the lowest heating power, the
largest lights' night share); from it the diagnosis names an effect by its estimate (beyond the ceiling, at
any significant held-out gain) instead of by the ``min_gain`` bar (:func:`buildenv.gap.candidate_qualifies`).
This script

- measures the ceilings on the clean sites of the given pages (their clean cases, and the clean twins of their
  effect cases) and checks them against the catalogue's (rounded outwards to 3 significant digits);
- judges every page's first steps again with five rules: the 10 % bar for every effect (the rule before
  2026-11-28), the ceilings measured on the *other* seeds' clean sites (each seed judged as if it were new: the
  honest estimate) with the carried effects at the bar (the rule of that morning) and for every effect, and the
  catalogue's ceilings, again with the carried effects at the bar and for every effect (in-sample for the pages
  that set them);
- judges ``--fresh`` pages (blind checks diagnosed after the ceilings were set) with the catalogue's ceilings
  and the bar: the held-out check.

    .venv/bin/python bench/gap_clean_ceiling.py --page bench/results/gap_check_tb_seed0.json ... \\
        --twin-records bench/results/gap_check_bar.json [--fresh bench/results/gap_check_tb_seed6.json] \\
        [--twins bench/results/gap_check_tb_seed6.json] [--no-diagnose] --name gap_clean_ceiling

``--declared`` measures the ceilings of sites that declare building parameters known
(:attr:`buildenv.effects.Effect.declared_ceiling`): the pages' sites must declare some, their ceilings are checked
against the catalogue's declared ones, and the rule "the catalogue's ceilings (now)" judges with those, beside
the ceilings of sites declaring nothing (what a diagnosis used on such sites before 2026-11-29).

``--twin-records`` reads clean twins kept in a page's json (``bench/gap_check_bar.py`` keeps them);
``--twins PAGE`` reads (or, without ``--no-diagnose``, diagnoses) a page's twins from its check folder, as
``bench/gap_check_bar.py`` does. Run it from the repository root. Writes ``bench/results/NAME.{md,json}``; the
json keeps every twin record it read. The ceiling of ``night_plug_loads`` is on the night electricity since
2026-11-28, which the records do not keep: ``bench/gap_night_electricity.py`` measures it on recalibrated sites.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from functools import partial
from pathlib import Path

import numpy as np
from gap_check_bar import _cell, bar_named, judge, twin_records
from gap_check_rejudge import first_named

from buildenv.effects import EFFECTS, MIN_GAIN, declared_ceilings, get_effect
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def size(name: str, estimate: dict[str, float]) -> float | None:
    """A candidate's estimate as its clean-site ceiling judges it, oriented so that larger is further from no
    effect: ``|first parameter - clean reading|`` (:meth:`buildenv.effects.Effect.size`), or for an effect the
    metamodel carries its building parameter, negated where the effect vanishes at the top of the parameter's
    range (a lower heating power is a stronger limit). None when the estimate lacks it (a site that declared the
    building parameter known calibrates the model-side addition instead, which has no ceiling)."""
    effect = get_effect(name)
    if effect.judged_on is not None:  # a derived quantity (night_plug_loads: bench/gap_night_electricity.py)
        return float(estimate[effect.judged_on]) if effect.judged_on in estimate else None
    if effect.building_parameter is not None:
        if effect.building_parameter not in estimate:
            return None
        return oriented(name, float(estimate[effect.building_parameter]))
    if effect.size_name not in estimate:
        return None
    return effect.size(estimate)


def oriented(name: str, value: float) -> float:
    """A ceiling or size in the catalogue's units turned into :func:`size`'s orientation, or back (the same map)."""
    effect = get_effect(name)
    return effect.strength(value) if effect.building_parameter is not None else value


def clean_sizes(records: list[dict]) -> dict[str, list[tuple[float, str]]]:
    """``{effect: [(size, where), ...]}`` over clean records in their order (a record names its page and case in
    ``_at``), sizes as :func:`size` orients them; records without a size are left out."""
    out: dict[str, list[tuple[float, str]]] = {}
    for row in records:
        for name, estimate in row["estimates"].items():
            value = size(name, estimate)
            if value is not None:
                out.setdefault(name, []).append((value, row["_at"]))
    return out


def ceilings(records: list[dict]) -> dict[str, tuple[float, str]]:
    """``{effect: (largest size, where)}`` over clean records (:func:`clean_sizes`; of equal sizes, the last)."""
    return {name: max(reversed(sizes), key=lambda s: s[0]) for name, sizes in clean_sizes(records).items()}


def round_up(value: float, digits: int = 3) -> float:
    """``value`` rounded up to ``digits`` significant digits (0 stays 0; -54.877 gives -54.8)."""
    if value == 0:
        return 0.0
    scale = 10 ** (digits - 1 - math.floor(math.log10(abs(value))))
    return math.ceil(value * scale - 1e-9) / scale


def read_twin_records(paths: list[str]) -> dict[str, list[dict]]:
    """``{page: [clean twin records]}`` from jsons keeping a ``twin_records`` map (this script's,
    ``bench/gap_check_bar.py``'s); a later file's page replaces an earlier one's."""
    twins: dict[str, list[dict]] = {}
    for path in paths:
        twins.update({p: list(rows) for p, rows in json.loads(Path(path).read_text())["twin_records"].items()})
    return twins


def clean_records(page: dict, twins: list[dict], at: str) -> list[dict]:
    """A page's clean cases and its clean twins, each tagged with where it comes from."""
    rows = [r | {"_at": f"{at} case {r['case']}"} for r in page["cases"] if r["true"] == NONE]
    return rows + [t | {"_at": f"{at} twin of case {t['case']}"} for t in twins]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True,
                        help="a bench/gap_check.py result whose clean sites set the ceilings")
    parser.add_argument("--fresh", action="append", default=[],
                        help="a result diagnosed after the ceilings were set: judged with the catalogue's")
    parser.add_argument("--twin-records", action="append", default=[],
                        help="a json with 'twin_records': {page: [twin records]} (bench/gap_check_bar.py's)")
    parser.add_argument("--twins", action="append", default=[],
                        help="a page whose clean twins are read (or diagnosed) from its check folder")
    parser.add_argument("--no-diagnose", action="store_true", help="read the --twins records only")
    parser.add_argument("--note", default="", help="a paragraph for the page (where the runs ran)")
    parser.add_argument("--declared", action="store_true",
                        help="the pages' sites declare building parameters known: measure Effect.declared_ceiling")
    parser.add_argument("--name", default="gap_clean_ceiling")
    args = parser.parse_args()
    started = time.perf_counter()
    pages = {p: json.loads(Path(p).read_text()) for p in dict.fromkeys(args.page + args.fresh)}
    twins = read_twin_records(args.twin_records)
    for page in args.twins:
        twins[page] = twin_records(pages[page], not args.no_diagnose)
    alpha = next(iter(pages.values()))["plan"]["settings"]["alpha"]
    seed = {p: pages[p]["plan"]["seed"] for p in pages}
    clean = {p: clean_records(pages[p], twins.get(p, []), f"seed {seed[p]}") for p in args.page}
    measured = ceilings([r for p in args.page for r in clean[p]])
    declaring = sum(bool(page["plan"].get("known_parameters")) for page in pages.values())
    if declaring != (len(pages) if args.declared else 0):
        raise SystemExit("--declared needs every page's sites to declare building parameters known, and only then: "
                         f"{declaring} of {len(pages)} do")
    catalogue_ceilings = (declared_ceilings() if args.declared else
                          {e.name: e.clean_ceiling for e in EFFECTS.values() if e.clean_ceiling is not None})
    catalogue = {n: oriented(n, v) for n, v in catalogue_ceilings.items()}
    mismatched = sorted(n for n in set(measured) | set(catalogue)
                        if catalogue.get(n) != (round_up(measured[n][0]) if n in measured else None))

    def other_seeds(p: str) -> dict[str, float]:
        return {n: oriented(n, v)
                for n, (v, _) in ceilings([r for q in args.page if seed[q] != seed[p] for r in clean[q]]).items()}

    def sized_only(ceilings_of: dict[str, float]) -> dict[str, float]:
        return {n: v for n, v in ceilings_of.items() if get_effect(n).building_parameter is None}

    # the rules judged with the other seeds' ceilings, for the pages that set the ceilings only
    leave_one_out = ("ceilings from the other seeds' clean sites, carried effects at the bar",
                     "ceilings from the other seeds' clean sites")
    rules = {"10 % bar, every effect": lambda p: partial(bar_named, alpha=alpha, bar=MIN_GAIN),
             leave_one_out[0]: lambda p: partial(first_named, alpha=alpha, min_gain=MIN_GAIN,
                                                 clean_ceilings=sized_only(other_seeds(p))),
             leave_one_out[1]: lambda p: partial(first_named, alpha=alpha, min_gain=MIN_GAIN,
                                                 clean_ceilings=other_seeds(p)),
             "the catalogue's ceilings, carried effects at the bar":
                 lambda p: partial(first_named, alpha=alpha, min_gain=MIN_GAIN,
                                   clean_ceilings=sized_only(catalogue_ceilings)),
             "the catalogue's ceilings (now)": lambda p: partial(first_named, alpha=alpha, min_gain=MIN_GAIN,
                                                                 clean_ceilings=catalogue_ceilings
                                                                 if args.declared else True)}
    if args.declared:
        rules["the ceilings of sites declaring nothing"] = lambda p: partial(first_named, alpha=alpha,
                                                                            min_gain=MIN_GAIN)
    groups = {"seeds that set the ceilings": args.page}
    if args.fresh:
        groups["fresh seeds (held out)"] = args.fresh
    table, per_page = {}, {}
    for group, members in groups.items():
        names = [r for r in rules if members == args.page or r not in leave_one_out]
        per_page.update({p: {r: judge(pages[p]["cases"], twins.get(p, []), rules[r](p)) for r in names}
                         for p in members})
        table[group] = {r: _total([per_page[p][r] for p in members]) for r in names}
    seeds_table = ["## Each seed (right, wrong, clean sites recognised)", "",
                   "| page | seed | " + " | ".join(rules) + " |", "|---|---|" + "---|" * len(rules)]
    for p, by_rule in per_page.items():
        cells = [f"{t['named_right']}/{t['effect_cases']}, {t['named_wrong']}, "
                 f"{t['clean_recognised'] + t['twins_recognised']}/{t['clean_cases'] + t['twins']}"
                 if (t := by_rule.get(r)) else "-" for r in rules]
        seeds_table.append(f"| {Path(p).stem} | {seed[p]} | " + " | ".join(cells) + " |")
    effect_rows = {group: _by_effect(pages, {p: per_page[p] for p in members}) for group, members in groups.items()}
    command = ("python bench/gap_clean_ceiling.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --twin-records {p}" for p in args.twin_records)
               + "".join(f" --fresh {p}" for p in args.fresh) + "".join(f" --twins {p}" for p in args.twins)
               + (" --no-diagnose" if args.no_diagnose else "") + (" --declared" if args.declared else "")
               + f" --name {args.name}")
    lines = [f"# Clean-site ceilings and the naming rule they give ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}` ({time.perf_counter() - started:.0f} s).", "",
             *([args.note, ""] if args.note else []),
             "Every record's first step judged again (`bench/gap_check_rejudge.py`): significance at the recorded "
             "alpha over the step's candidates, the plausibility floors, then either the gain bar or, for an "
             "effect with a clean-site ceiling, an estimate beyond it. Shrinkage as in `gap_check_bar.md`.", "",
             "## Ceilings", "",
             f"Measured on {sum(len(clean[p]) for p in args.page)} clean sites (clean cases and clean twins of "
             + ("sites declaring " + ", ".join(f"{k} = {v:g}" for k, v in
                                               pages[args.page[0]]["plan"]["known_parameters"].items())
                + " known; catalogue: `Effect.declared_ceiling`; " if args.declared else "")
             + "the pages above). Own cases: the injected effect's own estimates in its effect cases.", "",
             "| effect | judged on | floor (practice, or a step from where it vanishes) | furthest on a clean site | where | catalogue | own cases: "
             "min, median, max | own cases beyond |", "|---|---|---|---|---|---|---|---|"]
    for name, (value, where) in sorted(measured.items()):
        effect = get_effect(name)
        own = [s for p in pages for r in pages[p]["cases"] if r["true"] == name
               for s in [size(name, r["estimates"].get(name, {}))] if s is not None]
        beyond = f"{sum(s > catalogue.get(name, np.inf) for s in own)}/{len(own)}" if own else "-"
        own = sorted(oriented(name, s) for s in own)
        spread = f"{own[0]:.3g}, {np.median(own):.3g}, {own[-1]:.3g}" if own else "-"
        floor = effect.carried_limit() if effect.building_parameter is not None else effect.smallest
        shown = oriented(name, catalogue[name]) if name in catalogue else "-"
        lines.append(f"| {name} | {effect.building_parameter or effect.size_name} | "
                     f"{floor if floor is not None else '-'} | {oriented(name, value):.4g} | {where} | {shown} | "
                     f"{spread} | {beyond} |")
    lines += ["", "Furthest: the largest size, or for an effect judged through a building parameter the value furthest "
              "from where the effect vanishes (the lowest heating power, the largest lights' night share). Catalogue "
              "= furthest rounded outwards to 3 significant digits: "
              + ("yes, every effect." if not mismatched else f"**no** for {', '.join(mismatched)}."), ""]
    head = ["rule", "injected effect named first", "named another effect", "clean cases recognised",
            "clean twins recognised", "all clean sites", "median shrinkage (first step)"]
    for group, by_rule in table.items():
        lines += [f"## {group}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += [f"| {r} | " + " | ".join(_cell(t)) + " |" for r, t in by_rule.items()]
        lines.append("")
    lines += [*seeds_table, ""]
    for group, rows in effect_rows.items():
        lines += [f"## By effect, {group} (effect cases named right)", "",
                  "| effect | cases | " + " | ".join(rules) + " |", "|---|---|" + "---|" * len(rules)]
        lines += [f"| {name} | {row['cases']} | " + " | ".join(str(row.get(r, "-")) for r in rules) + " |"
                  for name, row in rows.items()]
        lines.append("")
    lines += ["## Records named differently by the rules", "",
              "| page | case | injected | magnitude | " + " | ".join(rules) + " |",
              "|---|---|---|---|" + "---|" * len(rules)]
    for p, by_rule in per_page.items():
        for key, kind in (("named", "case"), ("twins_named", "twin")):
            for case in next(iter(by_rule.values()))[key]:
                names = [by_rule[r][key][case] if r in by_rule else "-" for r in rules]
                if len({n for n in names if n != "-"}) > 1:
                    row = next(r for r in pages[p]["cases"] if r["case"] == case)
                    what = row["true"] if kind == "case" else f"clean twin of {row['true']}"
                    magnitude = f"{row['magnitude']:.3g}" if kind == "case" else "-"
                    lines.append(f"| {Path(p).stem} | {case} | {what} | {magnitude} | " + " | ".join(names) + " |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "note": args.note,
         # in the catalogue's units (measured_oriented: as size() orients them, a heating power negated)
         "measured": {n: (oriented(n, v), at) for n, (v, at) in measured.items()}, "measured_oriented": measured,
         "catalogue": catalogue_ceilings,
         "mismatched": mismatched, "groups": table, "pages": per_page, "by_effect": effect_rows,
         "twin_records": twins}, indent=1, default=float) + "\n")
    print("\n".join(lines))
    if mismatched:
        raise SystemExit(f"the catalogue's clean-site ceilings differ from the records' for {', '.join(mismatched)}")


def _total(counts: list[dict]) -> dict:
    """Counts of several pages added (the median shrinkage over their right namings is not kept: None)."""
    keys = ("effect_cases", "named_right", "named_wrong", "ranked_first", "clean_cases", "clean_recognised",
            "twins", "twins_recognised")
    shrink = [s for c in counts for s in c["shrinkages"]]
    return {k: sum(c[k] for c in counts) for k in keys} | {
        "median_first_step_shrinkage": float(np.median(shrink)) if shrink else None, "shrinkages": shrink}


def _by_effect(pages: dict[str, dict], per_page: dict[str, dict]) -> dict[str, dict]:
    """``{effect: {"cases": n, rule: named right}}`` over every page's effect cases."""
    rows: dict[str, dict] = {}
    for p, by_rule in per_page.items():
        for r in pages[p]["cases"]:
            if r["true"] == NONE:
                continue
            row = rows.setdefault(r["true"], {"cases": 0})
            row["cases"] += 1
            for rule, t in by_rule.items():
                row[rule] = row.get(rule, 0) + (t["named"][r["case"]] == r["true"])
    return dict(sorted(rows.items()))


if __name__ == "__main__":
    main()
