"""Loads left on at night judged on the night electricity of the calibrated model, replayed on the blind checks.

The metamodel carries a night load through two building parameters, the lights' and the equipment's night shares
(``light_night_percent``, ``pc_night_percent``), and a calibration trades one for the other. Until 2026-11-28 the
diagnosis judged ``night_plug_loads`` on the lights' share alone, against its clean-site ceiling (22.2 %): a load
the equipment's share took back stayed under it. It now judges it on the electric power both shares leave on
outside occupied hours (:func:`buildenv.effects.night_electricity_w_m2`, W/m2), which the meter fixes whichever
share carries it.

The blind-check records keep the lights' share only, so the sites' base models were calibrated again with the
checks' settings and their first step's control kept (``bench/gap_base_theta.py``; a carried effect's estimate is
read from that control). This replays the first steps of seeds 0-11 (cases, clean cases, clean twins' records)
twice, each seed judged with clean-site ceilings measured on the other seeds, the joint-calibration fallback
included (its tests read from ``--joint``, as ``bench/gap_joint_fallback.py`` ran them):

- *lights' share*: the rule before, the record's lights' share against the other seeds' largest;
- *night electricity*: the recalibrated control's night electricity against the other seeds' largest.

A site not recalibrated (its folder not kept, or not reached) is judged on its lights' share under both rules.

    .venv/bin/python bench/gap_night_electricity.py --page bench/results/gap_check_tb_seed0.json ... \\
        --twin-records bench/results/gap_clean_ceiling.json --theta out/gap-base-theta --joint out/gap-joint-fallback

Writes ``bench/results/<name>.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from gap_check_compare import tally
from gap_check_rejudge import first_named
from gap_clean_ceiling import ceilings, clean_records, oriented, read_twin_records

from buildenv.effects import EFFECTS, get_effect, night_electricity_w_m2
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"
NIGHT = "night_plug_loads"
SLOT = get_effect(NIGHT).judged_on
RULES = ("lights' share", "night electricity")


def recalibrated(folder: Path, key: str) -> float | None:
    """The night electricity (W/m2) of a site's recalibrated first-step control, or None when not recalibrated."""
    path = folder / f"{key}.json"
    return night_electricity_w_m2(json.loads(path.read_text())["control"]["parameters"]) if path.is_file() else None


def joint_tests(folder: Path, key: str) -> dict:
    """The joint-calibration tests ``bench/gap_joint_fallback.py`` ran on a site, by candidate."""
    return {name: json.loads(path.read_text()) for name in EFFECTS if (path := folder / f"{key}_{name}.json").is_file()}


def judged_as(row: dict, value: float) -> dict:
    """A record with ``value`` in the slot its night estimate is compared on (:attr:`Effect.judged_on`): the
    lights' share under the rule before, the night electricity under the new one."""
    if NIGHT not in row["estimates"]:
        return row
    return row | {"estimates": row["estimates"] | {NIGHT: row["estimates"][NIGHT] | {SLOT: value}}}


def share(row: dict) -> float | None:
    """The lights' night share a record calibrated (%), or None."""
    return row["estimates"].get(NIGHT, {}).get(get_effect(NIGHT).building_parameter)


def main() -> None:
    """Replay the pages under both rules and write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result")
    parser.add_argument("--twin-records", action="append", default=[],
                        help="a json with 'twin_records': {page: [twin records]} (bench/gap_clean_ceiling.py's)")
    parser.add_argument("--theta", default="out/gap-base-theta", help="bench/gap_base_theta.py's folder")
    parser.add_argument("--joint", default="out/gap-joint-fallback", help="bench/gap_joint_fallback.py's folder")
    parser.add_argument("--name", default="gap_night_electricity")
    args = parser.parse_args()
    started = time.perf_counter()
    theta, joint = Path(args.theta), Path(args.joint)
    pages = {p: json.loads(Path(p).read_text()) for p in args.page}
    twins = read_twin_records(args.twin_records)
    seed = {p: pages[p]["plan"]["seed"] for p in pages}
    sites = []  # one per recorded site: page, key, record (with its joint tests), truth, night electricity
    for p, page in pages.items():
        for row, suffix in [(r, "") for r in page["cases"]] + [(t, "_twin") for t in twins.get(p, [])]:
            key = f"seed{seed[p]}_case_{row['case']:03d}{suffix}"
            sites.append({"page": p, "key": key, "row": row | {"joint_tests": joint_tests(joint, key)},
                          "true": NONE if suffix else row["true"], "magnitude": None if suffix else row["magnitude"],
                          "night": recalibrated(theta, key)})
    recorded = {s["key"] for s in sites}
    clean = [s for s in sites if s["true"] == NONE]
    # clean twins recalibrated without a diagnosis record: in the night electricity's ceiling only
    extra = [{"page": p, "key": key, "night": night} for p in pages for row in pages[p]["cases"]
             if row["true"] != NONE for key in [f"seed{seed[p]}_case_{row['case']:03d}_twin"]
             if key not in recorded and (night := recalibrated(theta, key)) is not None]
    records = {p: clean_records(pages[p], twins.get(p, []), f"seed {seed[p]}") for p in pages}
    by_page = {}  # each page's ceilings, from the other seeds' clean sites
    for p in pages:
        others = [r for q in pages if seed[q] != seed[p] for r in records[q]]
        by_page[p] = ({n: oriented(n, v) for n, (v, _) in ceilings(others).items()},
                      max(v for r in others if (v := share(r)) is not None),
                      max((c["night"] for c in clean + extra if seed[c["page"]] != seed[p] and c["night"] is not None),
                          default=float("inf")))  # none measured: nothing is beyond it
    for s in sites:
        p = s["page"]
        ceilings_of, share_ceiling, night_ceiling = by_page[p]
        settings = pages[p]["plan"]["settings"]
        s["ceilings"] = {RULES[0]: share_ceiling, RULES[1]: night_ceiling}
        before = judged_as(s["row"], share(s["row"])) if share(s["row"]) is not None else s["row"]
        s[RULES[0]] = first_named(before, settings["alpha"], settings["min_gain"],
                                  ceilings_of | {NIGHT: share_ceiling})
        if s["night"] is None:  # not recalibrated: judged as before
            s[RULES[1]] = s[RULES[0]]
        else:
            s[RULES[1]] = first_named(judged_as(s["row"], s["night"]), settings["alpha"], settings["min_gain"],
                                      ceilings_of | {NIGHT: night_ceiling})
    write_page(args, pages, sites, extra, time.perf_counter() - started)


def write_page(args: argparse.Namespace, pages: dict, sites: list[dict], extra: list[dict], seconds: float) -> None:
    """``bench/results/<name>.{md,json}``."""
    seed = {p: pages[p]["plan"]["seed"] for p in pages}
    clean_nights = sorted((c["night"], c["key"]) for c in [s for s in sites if s["true"] == NONE] + extra
                          if c["night"] is not None)
    command = ("python bench/gap_night_electricity.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --twin-records {p}" for p in args.twin_records)
               + f" --theta {args.theta} --joint {args.joint} --name {args.name}")
    lines = [f"# Loads left on at night judged on the night electricity, replayed on the blind checks "
             f"({time.strftime('%Y-%m-%d')})", "", f"Command: `{command}` ({seconds:.0f} s; the recalibrations: "
             "`python bench/gap_base_theta.py --page ... --jobs 2`).", "",
             "Each seed is judged with clean-site ceilings measured on the other seeds' clean sites, with the "
             "joint-calibration fallback where `bench/gap_joint_fallback.py` ran its test. *Lights' share*: the "
             "rule before, the record's lights' night share against the other seeds' largest. *Night electricity*: "
             "the night electricity of the recalibrated first-step control (lights and equipment left on outside "
             "occupied hours, W/m2) against the other seeds' largest. A site not recalibrated is judged on its "
             "lights' share under both.", "",
             f"Recalibrated: {sum(s['night'] is not None for s in sites)} of {len(sites)} recorded sites, and "
             f"{len(extra)} clean twins without a diagnosis record (their night electricity counts in the "
             "ceilings only).", "",
             "## Night electricity of the clean sites", "",
             (f"{len(clean_nights)} clean sites: min {clean_nights[0][0]:.2f}, median "
              f"{statistics.median(v for v, _ in clean_nights):.2f}, max {clean_nights[-1][0]:.2f} W/m2 "
              f"({clean_nights[-1][1]}); the five largest: "
              + ", ".join(f"{v:.2f} ({k})" for v, k in clean_nights[-5:]) + "." if clean_nights
              else "No clean site recalibrated."), "",
             "## Totals", "",
             "| seeds | rule | injected effect named first | named another effect | clean cases recognised | "
             "clean twins recognised |", "|---|---|---|---|---|---|"]
    totals = {}
    for label, members in {"0-10": [s for s in sites if seed[s["page"]] <= 10],
                           "11": [s for s in sites if seed[s["page"]] == 11]}.items():
        for rule in RULES:
            cases = [s for s in members if not s["key"].endswith("_twin")]
            twins = [s for s in members if s["key"].endswith("_twin")]
            t = totals.setdefault(label, {})[rule] = tally(cases, rule) | {
                "twins": len(twins), "twins_recognised": sum(s[rule] == NONE for s in twins)}
            lines.append(f"| {label} | {rule} | {t['named_right']}/{t['effect_cases']} | {t['named_wrong']} | "
                         f"{t['clean_recognised']}/{t['clean_cases']} | {t['twins_recognised']}/{t['twins']} |")
    lines += ["", "## Night plug-load cases", "",
              "| site | W/m2 injected | lights' share (record) | night electricity | its ceiling | night test: gain, p "
              "| lights' share | night electricity |", "|---|---|---|---|---|---|---|---|"]
    for s in sorted((s for s in sites if s["true"] == NIGHT), key=lambda s: s["magnitude"]):
        row = s["row"]
        night = "-" if s["night"] is None else f"{s['night']:.2f}"
        lines.append(f"| {s['key']} | {s['magnitude']:.2f} | {share(row):.1f} | {night} | "
                     f"{s['ceilings'][RULES[1]]:.2f} | {row['scores'][NIGHT]:.1%}, {row['p_values'][NIGHT]:.2g} | "
                     f"{s[RULES[0]]} | {s[RULES[1]]} |")
    lines += ["", "## Sites named differently", "", "| site | injected | magnitude | night electricity | "
              + " | ".join(RULES) + " |", "|---|---|---|---|---|---|"]
    for s in sites:
        if s[RULES[0]] != s[RULES[1]]:
            size = "-" if s["magnitude"] is None else f"{s['magnitude']:.3g}"
            lines.append(f"| {s['key']} | {s['true']} | {size} | {s['night']:.2f} | {s[RULES[0]]} | {s[RULES[1]]} |")
    lines.append("")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines))
    keep = [{k: s[k] for k in ("key", "true", "magnitude", "night", "ceilings", *RULES)} for s in sites]
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "totals": totals, "sites": keep, "clean_nights": clean_nights}, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
