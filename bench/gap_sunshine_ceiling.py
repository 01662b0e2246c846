"""Blinds' clean-site ceiling as it grows with the sunshine of the fit weeks, measured and replayed on the
headline's sites.

A calibration absorbs some of the model's structural misses into the blinds candidate (the share of the
irradiance inputs removed) even where nothing blocks the sun, and how much depends on the weather the fit weeks
saw: the blind checks' clean sites fitted on sunny October weeks calibrate blinds up to 0.58, those fitted on
November weeks at most 0.33. A constant ceiling is set by the sunniest sites and leaves most injected blinds of
the darker weeks under it. This page measures, on every clean site the headline counts:

- per fit-week irradiance (the fit weeks' mean global horizontal irradiance, W/m2,
  :func:`buildenv.gap.fit_irradiance_w_m2`): the clean sites' largest blinds estimate and ratio to the
  irradiance, the injected blinds' estimates and how many each ceiling names;
- the largest ratio over all clean sites, and over the first half of the seeds only;
- the headline's sites judged with the catalogue's constant ceiling and with the sunshine ceiling (the ratio
  times the site's irradiance, not below the lowest measured: :meth:`buildenv.effects.Effect.in_sunshine`), every
  naming that changes, and the second half of the seeds judged with the ratio of the first half (the ratio read
  off half the seeds, tested on the other half).

Run from the repository root::

    .venv/bin/python bench/gap_sunshine_ceiling.py --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_sunshine_ceiling``). In-sample for the catalogue's
ratio (it is the largest over these sites), first step only; fresh seeds run with it live are the test.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections import Counter

from gap_check_rejudge import naming
from gap_headline import ALPHA, SITE, add_sources, judged_sources, replay_scope, write_results

from buildenv.effects import MIN_GAIN, ceilings_in_sunshine, get_effect
from buildenv.gap_check import NONE

BLINDS = get_effect("solar_shading")
SIZE = BLINDS.size_name


def seed_of(site: str) -> int:
    """The blind check's seed of a headline site key (``seed12_case_003_twin`` -> 12)."""
    return int(SITE.match(site).group(1))


def largest_ratio(records: dict[str, tuple[dict, str, str]], seeds: set[int] | None = None) -> float:
    """The largest blinds estimate per W/m2 of fit-week irradiance over the clean sites of ``records`` (those of
    ``seeds`` only, where given)."""
    return max(r["estimates"][BLINDS.name][SIZE] / r["fit_irradiance_w_m2"] for site, (r, truth, _) in records.items()
               if truth == NONE and (seeds is None or seed_of(site) in seeds))


def judged(record: dict, ratio: float | None) -> str:
    """The effect a record's first step names with blinds' ceilings at ``ratio`` per W/m2 of its fit-week
    irradiance (not below the catalogue's lowest), or with the constant catalogue ceilings (None)."""
    if ratio is None:
        return naming({k: v for k, v in record.items() if k != "fit_irradiance_w_m2"}, ALPHA, MIN_GAIN,
                      estimate_ceilings=True)[0]
    ceiling = ratio * max(record["fit_irradiance_w_m2"], BLINDS.sunshine_ceiling[1])
    clean = ceilings_in_sunshine(None) | {BLINDS.name: ceiling}
    estimate = ceilings_in_sunshine(None, "estimate") | {BLINDS.name: ceiling}
    return naming(record, ALPHA, MIN_GAIN, clean, estimate)[0]


def counts(records: dict[str, tuple[dict, str, str]], named: dict[str, str], seeds: set[int] | None = None) -> dict:
    """Effect cases named right and clean sites recognised among ``records`` (of ``seeds`` where given)."""
    chosen = [(site, truth) for site, (_, truth, _) in records.items() if seeds is None or seed_of(site) in seeds]
    effects = [named[s] == t for s, t in chosen if t != NONE]
    clean = [named[s] == t for s, t in chosen if t == NONE]
    return {"effects": len(effects), "effects_right": sum(effects), "clean": len(clean), "clean_right": sum(clean)}


def by_irradiance(records: dict, constant: dict[str, str], sunshine: dict[str, str]) -> list[dict]:
    """Per fit-week irradiance (rounded to 0.1 W/m2): clean sites and their largest blinds estimate and ratio,
    injected blinds, their median estimate and how many each ceiling names."""
    rows = []
    for g in sorted({round(r["fit_irradiance_w_m2"], 1) for r, _, _ in records.values()}):
        here = {s: (r, t) for s, (r, t, _) in records.items() if round(r["fit_irradiance_w_m2"], 1) == g}
        clean = [r["estimates"][BLINDS.name][SIZE] for r, t in here.values() if t == NONE]
        blinds = [s for s, (_, t) in here.items() if t == BLINDS.name]
        rows.append({"irradiance_w_m2": g, "clean_sites": len(clean), "clean_largest": round(max(clean), 3),
                     "clean_largest_ratio": round(max(clean) / g, 5), "blinds": len(blinds),
                     "blinds_median": round(statistics.median(here[s][0]["estimates"][BLINDS.name][SIZE]
                                                              for s in blinds), 3) if blinds else None,
                     "named_constant": sum(constant[s] == BLINDS.name for s in blinds),
                     "named_sunshine": sum(sunshine[s] == BLINDS.name for s in blinds),
                     "sunshine_ceiling": round(BLINDS.in_sunshine(g).clean_ceiling, 3)})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_sources(parser)
    parser.add_argument("--name", default="gap_sunshine_ceiling")
    args = parser.parse_args()
    started = time.perf_counter()
    records, now, right, options = judged_sources(args)
    seeds = sorted({seed_of(s) for s in records})
    first = set(seeds[:len(seeds) // 2])
    second = set(seeds) - first
    per, lowest = BLINDS.sunshine_ceiling
    measured, measured_first = largest_ratio(records), largest_ratio(records, first)
    constant = {s: judged(r, None) for s, (r, _, _) in records.items()}
    sunshine = {s: judged(r, per) for s, (r, _, _) in records.items()}
    from_first = {s: judged(r, measured_first) for s, (r, _, _) in records.items() if seed_of(s) in second}
    rows = by_irradiance(records, constant, sunshine)
    changed = Counter((t, constant[s], sunshine[s]) for s, (_, t, _) in records.items() if constant[s] != sunshine[s])
    tallies = {"constant": counts(records, constant), "sunshine": counts(records, sunshine),
               "second_half_constant": counts(records, constant, second),
               "second_half_from_first": counts(records, from_first, second)}

    def cell(c: dict) -> str:
        return f"{c['effects_right']}/{c['effects']} | {c['clean_right']}/{c['clean']}"

    lines = [f"# Blinds' clean-site ceiling and the sunshine of the fit weeks ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `python bench/gap_sunshine_ceiling.py{options} --name {args.name}` "
             f"({time.perf_counter() - started:.0f} s).", "", replay_scope(records, right), "",
             f"Largest blinds estimate per W/m2 of fit-week irradiance on a clean site: {measured:.6f} over all "
             f"{len(seeds)} seeds ({seeds[0]}-{seeds[-1]}), {measured_first:.6f} over seeds {min(first)}-{max(first)}. "
             f"The catalogue's: {per:g} per W/m2, at least {lowest:g} W/m2 counted "
             f"(`buildenv.effects.Effect.sunshine_ceiling`); its constant ceilings: {BLINDS.clean_ceiling:g} "
             f"(clean-site), {BLINDS.estimate_ceiling:g} (estimate).", "",
             "## By fit-week irradiance", "",
             "| fit-week irradiance (W/m2) | clean sites | largest clean estimate | its ratio per W/m2 | sunshine "
             "ceiling | injected blinds | median estimate | named, constant ceiling | named, sunshine ceiling |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['irradiance_w_m2']:g} | {r['clean_sites']} | {r['clean_largest']:g} | "
                     f"{r['clean_largest_ratio']:g} | {r['sunshine_ceiling']:g} | {r['blinds']} | "
                     f"{'-' if r['blinds_median'] is None else r['blinds_median']} | {r['named_constant']} | "
                     f"{r['named_sunshine']} |")
    lines += ["", "## Replayed", "", "| ceilings | sites | effect cases named right | clean sites recognised |",
              "|---|---|---|---|",
              f"| constant | all | {cell(tallies['constant'])} |",
              f"| sunshine (catalogue ratio) | all | {cell(tallies['sunshine'])} |",
              f"| constant | seeds {min(second)}-{max(second)} | {cell(tallies['second_half_constant'])} |",
              f"| sunshine, ratio of seeds {min(first)}-{max(first)} ({measured_first:.6f}) | seeds "
              f"{min(second)}-{max(second)} | {cell(tallies['second_half_from_first'])} |",
              "", "## Namings that change (constant -> sunshine)", "",
              "| injected | named with the constant ceiling | named with the sunshine ceiling | sites |",
              "|---|---|---|---|"]
    for (truth, before, after), n in sorted(changed.items(), key=lambda kv: -kv[1]):
        lines.append(f"| {truth} | {before} | {after} | {n} |")
    write_results(args.name, lines, {
        "command": f"python bench/gap_sunshine_ceiling.py{options} --name {args.name}",
        "measured_ratio": measured, "measured_ratio_first_half": measured_first, "first_half_seeds": sorted(first),
        "catalogue": {"per_w_m2": per, "lowest_w_m2": lowest}, "by_irradiance": rows, "tallies": tallies,
        "changed": [{"true": t, "constant": b, "sunshine": a, "sites": n} for (t, b, a), n in changed.items()],
        "sites": {s: {"true": t, "constant": constant[s], "sunshine": sunshine[s],
                      "irradiance_w_m2": r["fit_irradiance_w_m2"], "estimate": r["estimates"][BLINDS.name][SIZE]}
                  for s, (r, t, _) in records.items()}})


if __name__ == "__main__":
    main()
