"""Blind-check sites diagnosed again with the wind term centred on a reference wind speed.

The wind infiltration candidate used to add ``ach_per_m_s x share x wind speed`` to the calibrated air changes, so
its refit had to lower them by the wind term's mean to keep the level; the base calibration had already taken them
near the bottom of their range (0.1 1/h), where they could not go lower. The term is now centred on
:data:`buildenv.effects.WIND_REFERENCE_M_S`. A ceiling measured on clean sites with the old term no longer
holds, so this script diagnoses the chosen sites of recorded blind checks again with the current code (the same
records as ``bench/gap_carried_starts.py``), measures the wind candidate's largest estimate on the clean ones and
judges every site again with it:

    .venv/bin/python bench/gap_wind_centred.py --page bench/results/gap_check_tb_seed12.json ... \\
        --effects wind_infiltration,none --twins-of wind_infiltration,heat_recovery,... \\
        [--shard 0/2] [--no-diagnose] --name gap_wind_centred

``--fresh`` is for checks that ran with the centred term already (seeds 21-30, seeds 0-11 run again): their
clean sites are judged with the catalogue's wind ceiling, measured on other seeds, so the page is that ceiling's
held-out test; from seed 29 on, also with the catalogue's estimate ceilings (``bench/gap_estimate_alone.py``). ``measured`` in the json gives the largest wind estimate and the lowest heating power on the clean
sites diagnosed again (the heating power with the carried starts' search). Run it from the repository root. Writes
``bench/results/NAME.{md,json}`` when run without ``--shard``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gap_carried_starts import (CAPACITY, cell, chosen_sites, diagnosed_rows, heating_power, key, site_arguments,
                                site_folder)
from gap_check_rejudge import first_named
from gap_clean_ceiling import round_up

from buildenv.effects import EFFECTS, MIN_GAIN, WIND_REFERENCE_M_S, declared_ceilings
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"
WIND = "wind_infiltration"


def wind_estimate(record: dict | None) -> float | None:
    """The wind candidate's estimate (1/h per m/s) in a diagnosis record, None where not recorded."""
    if record is None:
        return None
    return record["estimates"].get(WIND, {}).get("ach_per_m_s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    site_arguments(parser, f"{WIND},{NONE}", WIND, "out/gap-wind-centred", "gap_wind_centred")
    parser.add_argument("--declared", action="store_true",
                        help="the pages' sites declare building parameters known: judge with the ceilings of such "
                             "sites (Effect.declared_ceiling)")
    parser.add_argument("--recorded-wind-above", type=float, default=0.0, metavar="ACH_PER_M_S",
                        help="of the cases injected with another effect, only those whose recorded wind estimate "
                             "is at least this (those the centred term may take for a wind)")
    parser.add_argument("--fresh", action="store_true",
                        help="the pages' checks ran with the centred term already: judge with the catalogue's "
                             "wind ceiling (measured on other seeds) instead of one measured on these sites")
    args = parser.parse_args()
    started = time.perf_counter()
    pages, todo = chosen_sites(args)
    todo = [(p, row, twin) for p, row, twin in todo if twin or row["true"] in (WIND, NONE)
            or wind_estimate(row) >= args.recorded_wind_above]
    kept = [(p, row, twin) for p, row, twin in todo if site_folder(pages[p], row, twin).is_dir()]
    gone, todo = len(todo) - len(kept), kept
    rows, missing = diagnosed_rows(args, pages, todo)
    if args.shard:
        return
    clean = [(key(pages[p], row, twin), before, after) for p, row, twin, before, after in rows
             if twin or row["true"] == NONE]
    if not clean:
        raise SystemExit(f"no clean site among the chosen sites, so no wind ceiling to measure (their records are kept "
                         f"in {args.folder})")
    now = max((wind_estimate(after), site) for site, _, after in clean)
    old = max(((wind_estimate(before), site) for site, before, _ in clean if wind_estimate(before) is not None),
              default=None)  # None: no clean site here was diagnosed by its check (twins the check only simulated)
    power = min((heating_power(after), site) for site, _, after in clean if heating_power(after) is not None)
    ceiling = round_up(now[0])
    catalogue = declared_ceilings() if args.declared else \
        {name: e.clean_ceiling for name, e in EFFECTS.items() if e.clean_ceiling is not None}
    judged = catalogue if args.fresh else catalogue | {WIND: ceiling}
    alpha = next(iter(pages.values()))["plan"]["settings"]["alpha"]
    groups: dict[str, dict] = {}
    table = []
    named_now: dict[str, str] = {}  # each site's first step judged with the new wind ceiling
    for p, row, twin, before, after in rows:
        truth = NONE if twin else row["true"]
        label = "clean twins" if twin else ("clean cases" if truth == NONE else truth)
        # fresh checks are judged by today's rules in full, the estimate alone included (not measured on declaring
        # sites, so not there)
        named = named_now[key(pages[p], row, twin)] = first_named(after, alpha, MIN_GAIN, judged,
                                                                  estimate_ceilings=args.fresh and not args.declared)
        g = groups.setdefault(label, {"sites": 0, "right_before": 0, "right_after": 0, "recorded": 0, "wrong": 0})
        g["sites"] += 1
        g["right_after"] += named == truth
        g["wrong"] += named not in (truth, NONE)
        if before is not None:
            g["recorded"] += 1
            g["right_before"] += before["named"] == truth
        if truth == WIND or named == WIND or (before and before["named"] == WIND):
            table.append((key(pages[p], row, twin), truth if not twin else f"none (twin of {row['true']})",
                          row.get("magnitude") if not twin else None, before, after, named))
    command = ("python bench/gap_wind_centred.py " + " ".join(f"--page {p}" for p in args.page)
               + f" --effects {args.effects} --twins-of {args.twins_of} --folder {args.folder}"
               + (f" --recorded-wind-above {args.recorded_wind_above:g}" if args.recorded_wind_above else "")
               + (" --declared" if args.declared else "") + (" --fresh" if args.fresh else "")
               + (" --no-diagnose" if args.no_diagnose else "")
               + f" --name {args.name}")
    seconds = [after["seconds"] for *_, after in rows]
    lines = [f"# Blind-check sites diagnosed again with the wind term centred ({time.strftime('%Y-%m-%d')})",
             "", f"Command: `{command}` ({time.perf_counter() - started:.0f} s this run; the diagnoses "
             f"{sum(seconds):.0f} s, median {sorted(seconds)[len(seconds) // 2] if seconds else 0:.0f} s a site).",
             "", "The wind infiltration candidate now adds `ach_per_m_s x (share x wind speed - "
             f"{WIND_REFERENCE_M_S:g} m/s)` to the calibrated air changes (`buildenv.effects."
             "WIND_REFERENCE_M_S`), where it added `ach_per_m_s x share x wind speed`. Recorded: the verdict the "
             "check recorded (the rules of its day). Now: the current code's diagnosis, its first step judged with "
             "the catalogue's ceilings" + (" of sites declaring building parameters known" if args.declared else "")
             + (", the wind's included: these checks ran with the centred term, so a case's recorded diagnosis "
                "is its diagnosis now (the diagnosis is deterministic), and the clean sites test a ceiling "
                "measured on other seeds"
                if args.fresh else " and the wind's measured below") + " (`bench/gap_check_rejudge.py`).", "",
             f"{len(rows)} sites diagnosed again" + (f", {missing} still missing" if missing else "")
             + (f"; {gone} chosen sites their checks no longer keep are left out (`bench/gap_regenerate_site.py` "
                "makes one again)" if gone else "") + ".", "",
             "## The wind candidate on the clean sites", "",
             f"- {len(clean)} clean sites (clean cases and clean twins).",
             f"- Largest estimate now: {now[0]:.5f} 1/h per m/s ({now[1]}), "
             + (f"so the catalogue's ceiling of {catalogue[WIND]:g} "
                f"{'holds' if now[0] <= catalogue[WIND] else 'does not hold'} here." if args.fresh
                else f"so a ceiling of {ceiling:g}."),
             f"- Largest estimate recorded on the same sites with "
             f"{'the centred term' if args.fresh else 'the old term'}, where the check kept its record: "
             + (f"{old[0]:.5f} ({old[1]})." if old else "none kept (the check simulated these sites only)."),
             f"- Lowest heating power of the capacity candidate now: {power[0]:.2f} W/m2 ({power[1]}); the "
             f"catalogue's ceiling: {catalogue[CAPACITY]:g} W/m2.", "",
             "## Named right", "",
             "| sites | number | named right, recorded | named right, now | named wrong, now |",
             "|---|---|---|---|---|"]
    for label, g in groups.items():
        before = f"{g['right_before']}/{g['recorded']}" if g["recorded"] else "-"
        lines.append(f"| {label} | {g['sites']} | {before} | {g['right_after']}/{g['sites']} | {g['wrong']} |")
    lines += ["", "## Wind cases, and every site where the wind was named", "",
              "| site | injected | magnitude (%/(m/s)) | named, recorded | estimate, recorded | named now | "
              "estimate now | gain now | p now |", "|---|---|---|---|---|---|---|---|---|"]
    for site, injected, magnitude, before, after, named in table:
        lines.append(f"| {site} | {injected} | {'-' if magnitude is None else f'{magnitude:.3g}'} | "
                     f"{before['named'] if before else '-'} | {cell(wind_estimate(before), 4)} | {named} | "
                     f"{cell(wind_estimate(after), 4)} | {after['scores'][WIND]:.3f} | {after['p_values'][WIND]:.1e} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "groups": groups, "reference_m_s": WIND_REFERENCE_M_S,
         "measured": {WIND: list(now), CAPACITY: list(power)}, "recorded_wind_largest": list(old) if old else None,
         "records": {key(pages[p], row, twin): after | {"named_now": named_now[key(pages[p], row, twin)]}
                     for p, row, twin, _, after in rows}},
        indent=1, default=float) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
