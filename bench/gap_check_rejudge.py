"""Recorded blind checks judged again under the catalogue's current plausibility rules.

The first effect a diagnosis names is decided by its first step alone: the candidate with the largest held-out
gain among those that qualify (:func:`buildenv.gap.candidate_qualifies`: significant, a plausible estimate,
and an estimate beyond the effect's clean-site ceiling or, without one, the minimum gain). Every result of
``bench/gap_check.py`` records that step for each case (gains, p-values, estimates), so a change of the
plausibility rules can be replayed on it exactly, without rerunning a calibration. The later steps (the second
effect) are not replayed.

    .venv/bin/python bench/gap_check_rejudge.py --name gap_check_rejudged bench/results/gap_check_known_seed0.json ...

Writes ``bench/results/<name>.{md,json}``. A rule read off these records is only checked in-sample here: a
fresh seed run with ``bench/gap_check.py`` is the test.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Mapping
from pathlib import Path

from gap_check_compare import tally

from buildenv.effects import ceilings_in_sunshine
from buildenv.gap import (NIGHT_LOADS, absorbed_candidate, candidate_qualifies, joint_test_qualifies,
                          named_by_estimate, night_load_named_first)
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"
ALONE = "estimate alone"  # how :func:`naming` says a record names its effect by the estimate alone
NIGHT_FIRST = "night electricity"  # ... and by the night electricity its model carries (night_load_named_first)


def first_named(row: dict, alpha: float, min_gain: float,
                clean_ceilings: bool | Mapping[str, float] = True,
                estimate_ceilings: bool | Mapping[str, float] = False) -> str:
    """The effect a recorded case's first step names under the current plausibility rules (``none`` if none):
    :func:`naming` without the how."""
    return naming(row, alpha, min_gain, clean_ceilings, estimate_ceilings)[0]


def naming(row: dict, alpha: float, min_gain: float, clean_ceilings: bool | Mapping[str, float] = True,
           estimate_ceilings: bool | Mapping[str, float] = False) -> tuple[str, str]:
    """The effect a recorded case's first step names under the current plausibility rules and how: ``(name,
    "held-out gain" | "joint test" | "estimate alone" | "night electricity")``, or ``("none", "")``. A carried
    effect (its estimate is its building parameter) must also make none of its series worse; ``clean_ceilings``: as
    :class:`buildenv.gap.DiagnosisSettings`. When nothing qualifies, the joint tests the record ran
    (:func:`buildenv.gap.joint_fallback`) are judged for the candidates that trigger one under these ceilings; a
    triggered candidate the record did not test names nothing. When nothing is named still, the estimates are
    judged against ``estimate_ceilings`` (:func:`buildenv.gap.named_by_estimate`; off with ``clean_ceilings``
    off, as in a diagnosis). They are off by default, as in the replays written before that rule (2026-11-29),
    which judge records of sites declaring building parameters known too (no estimate ceilings there);
    ``bench/gap_headline.py`` and ``bench/gap_estimate_alone.py`` turn them on. With them on, a night electricity
    far beyond its ceiling names night plug loads ahead of all but a held-out gain of its own, as a diagnosis does
    (:func:`buildenv.gap.night_load_named_first`; :data:`buildenv.effects.NIGHT_LOAD_FIRST_BEYOND` as
    ``buildenv.gap`` holds it). A record with its fit weeks' irradiance (``fit_irradiance_w_m2``, W/m2) has the
    catalogue's ceilings (True) judged at it, as a diagnosis does (:func:`buildenv.effects.ceilings_in_sunshine`)."""
    irradiance = row.get("fit_irradiance_w_m2")
    if clean_ceilings is True and irradiance is not None:
        clean_ceilings = ceilings_in_sunshine(irradiance)
    if estimate_ceilings is True and irradiance is not None:
        estimate_ceilings = ceilings_in_sunshine(irradiance, "estimate")
    name, how = _naming_by_gain(row, alpha, min_gain, clean_ceilings, estimate_ceilings)
    ceilings = False if clean_ceilings is False else estimate_ceilings
    if (name, how) != (NIGHT_LOADS, "held-out gain") and night_load_named_first(row["estimates"], ceilings):
        return NIGHT_LOADS, NIGHT_FIRST
    return name, how


def _naming_by_gain(row: dict, alpha: float, min_gain: float, clean_ceilings: bool | Mapping[str, float],
                    estimate_ceilings: bool | Mapping[str, float]) -> tuple[str, str]:
    """:func:`naming` without the night-electricity rule."""
    threshold = alpha / len(row["p_values"])
    ranked = sorted(row["scores"], key=lambda n: -row["scores"][n])
    for name in ranked:
        if candidate_qualifies(name, row["scores"][name], row["p_values"][name], threshold, min_gain,
                               row["estimates"][name], row.get("gains_by_series", {}).get(name), clean_ceilings):
            return name, "held-out gain"
    joint = row.get("joint_tests", {})  # the joint-calibration fallback, where the record ran it
    for name in ranked:
        if absorbed_candidate(name, row["estimates"][name], clean_ceilings):
            if name in joint and joint_test_qualifies(name, joint[name], threshold, clean_ceilings):
                return name, "joint test"
    alone = named_by_estimate(row["estimates"], row["scores"], False if clean_ceilings is False else estimate_ceilings,
                              row.get("gains_by_series"))
    return (alone[0], ALONE) if alone else (NONE, "")


def main() -> None:
    """Re-judge the given result files and write the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="+", help="result files of bench/gap_check.py")
    parser.add_argument("--name", default="gap_check_rejudged", help="stem of the result files")
    args = parser.parse_args()
    sets = []
    for path in args.results:
        page = json.loads(Path(path).read_text())
        settings = page["plan"]["settings"]
        rows = [{"case": r["case"], "true": r["true"], "magnitude": r["magnitude"], "a": r["named"],
                 "b": first_named(r, settings["alpha"], settings["min_gain"])} for r in page["cases"]]
        sets.append({"result": path, "seed": page["plan"]["seed"], "known": page["plan"].get("known_parameters", {}),
                     "restarts": settings.get("base_restarts", 1), "rows": rows,
                     "recorded": tally(rows, "a"), "rejudged": tally(rows, "b")})
    every = [r for s in sets for r in s["rows"]]
    totals = {"recorded": tally(every, "a"), "rejudged": tally(every, "b")}
    lines = [f"# Recorded blind checks judged again under the current plausibility rules ({time.strftime('%Y-%m-%d')})",
             "", "Command: `.venv/bin/python bench/gap_check_rejudge.py --name " + args.name + " "
             + " ".join(args.results) + "`. First step only (the first effect named).", "",
             "| result | seed | known parameters | base runs | recorded: right, wrong, clean | "
             "now: right, wrong, clean |", "|---|---|---|---|---|---|"]

    def cell(t: dict) -> str:
        return (f"{t['named_right']}/{t['effect_cases']}, {t['named_wrong']}/{t['effect_cases']}, "
                f"{t['clean_recognised']}/{t['clean_cases']}")

    for s in sets:
        known = "declared loads" if s["known"] else "none"
        lines.append(f"| {Path(s['result']).stem} | {s['seed']} | {known} | {s['restarts']} | {cell(s['recorded'])} | "
                     f"{cell(s['rejudged'])} |")
    lines.append(f"| all | | | | {cell(totals['recorded'])} | {cell(totals['rejudged'])} |")
    lines += ["", "Cases named differently:", "", "| result | case | injected | magnitude | recorded | now |",
              "|---|---|---|---|---|---|"]
    for s in sets:
        for r in s["rows"]:
            if r["a"] != r["b"]:
                magnitude = "-" if r["magnitude"] is None else f"{r['magnitude']:.2f}"
                lines.append(f"| {Path(s['result']).stem} | {r['case']} | {r['true']} | {magnitude} | {r['a']} | "
                             f"{r['b']} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps({"totals": totals, "sets": sets}, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
