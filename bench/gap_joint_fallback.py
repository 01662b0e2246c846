"""Candidates the base calibration absorbed, tested by joint calibration, on the blind checks' records.

A candidate whose refit estimate lies beyond every clean site's (its clean-site ceiling) carries the evidence of
size the diagnosis names effects by, yet some such candidates gain nothing held out: the base calibration had
already moved the building parameters to explain the effect (a wind infiltration taken as a higher constant air
change rate), so the refit started from it has nothing left to gain. The diagnosis then tests such a candidate by
joint calibration (:func:`buildenv.gap.joint_test`: the site calibrated from scratch with and without it) when
nothing else qualifies, and names it when that test's held-out gain is significant (the step's Bonferroni
threshold) with a plausible estimate still beyond its ceiling (:func:`buildenv.gap.joint_test_qualifies`).

This replays that rule on the recorded first steps of the blind checks (cases, clean cases and the clean twins'
records), each seed judged with clean-site ceilings measured on the other seeds' clean sites, as
``bench/gap_clean_ceiling.py`` judges them. Only the records that trigger the fallback
(:func:`buildenv.gap.absorbed_candidate`, given the record's first step) need a joint test; each is run on the
recorded site with the check's settings and kept in ``--folder``, so a rerun resumes.

    .venv/bin/python bench/gap_joint_fallback.py --page bench/results/gap_check_tb_seed0.json ... \\
        --twin-records bench/results/gap_clean_ceiling.json --jobs 2

Writes ``bench/results/<name>.{md,json}``. The records predate the night electricity (``night_plug_loads`` is judged
on it since 2026-11-28 and the records keep the lights' share only), so a rerun now judges that candidate by the
10 % bar; ``bench/gap_night_electricity.py`` replays this fallback under the old and the new night rule.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from gap_check_bar import check_folder, recorded_settings
from gap_check_compare import tally
from gap_check_rejudge import first_named
from gap_clean_ceiling import ceilings, clean_records, oriented, read_twin_records
from gap_first_half import run_side_by_side

from buildenv.gap import absorbed_candidate, joint_test_qualifies
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def run_joint_test(site_dir: str, candidate: str, settings: dict, out: str) -> None:
    """The joint test of ``candidate`` on one recorded site with the check's ``settings`` (a DiagnosisSettings
    dict), written to ``out``. One thread: several run side by side."""
    from buildenv.gap import joint_calibration_tests
    from buildenv.site import load_site
    from buildenv.surrogate import load_metamodel

    settings = recorded_settings(settings)
    started = time.perf_counter()
    test = joint_calibration_tests(load_site(site_dir), load_metamodel("default"), (candidate,), settings)[0]
    Path(out).write_text(json.dumps(test | {"seconds": round(time.perf_counter() - started, 1)}, default=float)
                         + "\n")


def triggered(row: dict, alpha: float, min_gain: float, ceilings_of: dict[str, float]) -> list[str]:
    """The candidates of a record's first step the diagnosis would test by joint calibration: none when a
    candidate qualifies, else those :func:`buildenv.gap.absorbed_candidate` picks, best refit gain first."""
    if first_named(row, alpha, min_gain, ceilings_of) != NONE:
        return []
    return [n for n in sorted(row["scores"], key=lambda n: -row["scores"][n])
            if absorbed_candidate(n, row["estimates"][n], ceilings_of)]


def main() -> None:
    """Find the triggered records, run (or resume) their joint tests and write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result")
    parser.add_argument("--twin-records", action="append", default=[],
                        help="a json with 'twin_records': {page: [twin records]} (bench/gap_clean_ceiling.py's)")
    parser.add_argument("--folder", default="out/gap-joint-fallback", help="one json per joint test")
    parser.add_argument("--jobs", type=int, default=1, help="joint tests side by side, one thread each")
    parser.add_argument("--name", default="gap_joint_fallback")
    args = parser.parse_args()
    started = time.perf_counter()
    pages = {p: json.loads(Path(p).read_text()) for p in args.page}
    twins = read_twin_records(args.twin_records)
    seed = {p: pages[p]["plan"]["seed"] for p in pages}
    clean = {p: clean_records(pages[p], twins.get(p, []), f"seed {seed[p]}") for p in pages}
    folder = Path(args.folder)
    folder.mkdir(parents=True, exist_ok=True)
    records, todo, page_ceilings = [], [], {}
    for p, page in pages.items():
        settings = page["plan"]["settings"]
        alpha, min_gain = settings["alpha"], settings["min_gain"]
        ceilings_of = page_ceilings[p] = {n: oriented(n, v) for n, (v, _) in
                                          ceilings([r for q in pages if seed[q] != seed[p] for r in clean[q]]).items()}
        rows = [(r, "") for r in page["cases"]] + [(t, "_twin") for t in twins.get(p, [])]
        for row, suffix in rows:
            site = f"case_{row['case']:03d}{suffix}"
            record = {"page": p, "seed": seed[p], "site": site, "true": NONE if suffix else row["true"],
                      "magnitude": None if suffix else row["magnitude"],
                      "checks": first_named(row, alpha, min_gain, ceilings_of), "tests": []}
            for name in triggered(row, alpha, min_gain, ceilings_of):
                out = folder / f"seed{seed[p]}_{site}_{name}.json"
                record["tests"].append({"candidate": name, "refit_gain": row["scores"][name],
                                        "refit_estimate": row["estimates"][name],
                                        "threshold": alpha / len(row["p_values"]), "out": out})
                if not out.exists():
                    todo.append((str(check_folder(page) / site), name, settings, str(out)))
            records.append(record)
    if todo:
        print(f"{len(todo)} joint tests to run, {args.jobs} at a time")
        run_side_by_side(run_joint_test, todo, args.jobs)
    for record in records:
        record["fallback"] = record["checks"]
        for test in record["tests"]:
            test["joint"] = json.loads(test.pop("out").read_text())
            test["qualifies"] = joint_test_qualifies(test["candidate"], test["joint"], test["threshold"],
                                                     page_ceilings[record["page"]])
            if record["fallback"] == NONE and test["qualifies"]:
                record["fallback"] = test["candidate"]
    write_page(args, records, time.perf_counter() - started)


def write_page(args: argparse.Namespace, records: list[dict], seconds: float) -> None:
    """``bench/results/<name>.{md,json}``."""
    cases = [r for r in records if not r["site"].endswith("_twin")]
    twins = [r for r in records if r["site"].endswith("_twin")]
    columns = {"checks": "clean-site ceilings (the other seeds'), as recorded",
               "fallback": "the same, and absorbed candidates tested by joint calibration"}
    totals = {key: tally(cases, key) | {"twins": len(twins), "twins_recognised": sum(r[key] == NONE for r in twins)}
              for key in columns}
    tested = [r for r in records if r["tests"]]
    times = sorted(t["joint"]["seconds"] for r in tested for t in r["tests"])
    command = ("python bench/gap_joint_fallback.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --twin-records {p}" for p in args.twin_records)
               + f" --folder {args.folder} --jobs {args.jobs} --name {args.name}")
    lines = [f"# Absorbed candidates tested by joint calibration, replayed on the blind checks "
             f"({time.strftime('%Y-%m-%d')})", "", f"Command: `{command}` ({seconds:.0f} s this run).", "",
             "Each seed is judged with clean-site ceilings measured on the other seeds' clean sites. A record "
             "triggers the fallback when its first step names nothing and a candidate's refit estimate is "
             "beyond its ceiling and plausible (not holidays, not an effect carried by a building parameter). "
             "The joint test calibrates the site from scratch without and with the candidate, with the check's "
             "settings, and names it when its held-out gain is positive and significant at the step's threshold "
             "with a plausible estimate.", "",
             "| rule | injected effect named first | named another effect | clean cases recognised | "
             "clean twins recognised |", "|---|---|---|---|---|"]
    for key, label in columns.items():
        t = totals[key]
        lines.append(f"| {label} | {t['named_right']}/{t['effect_cases']} | {t['named_wrong']} | "
                     f"{t['clean_recognised']}/{t['clean_cases']} | {t['twins_recognised']}/{t['twins']} |")
    lines += ["", f"## The {len(tested)} records that trigger a joint test "
              f"({len(times)} tests, median {times[len(times) // 2] if times else 0:.0f} s each, one thread)", "",
              "| seed | site | injected | magnitude | candidate | refit gain | refit estimate | joint gain (T, Q) | "
              "p | joint estimate | named |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in tested:
        for t in r["tests"]:
            j = t["joint"]
            size = "-" if r["magnitude"] is None else f"{r['magnitude']:.3g}"
            lines.append(
                f"| {r['seed']} | {r['site']} | {r['true']} | {size} | {t['candidate']} | {t['refit_gain']:.1%} | "
                f"{_values(t['refit_estimate'])} | {j['gain']:.1%} ({j['gain_by_series']['temperature']:.0%}, "
                f"{j['gain_by_series']['consumption']:.0%}) | {j['p_value']:.2g} | {_values(j['estimate'])} | "
                f"{'yes' if t['qualifies'] else 'no'} |")
    lines.append("")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines))
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "totals": totals, "records": tested, "cpu_count": os.cpu_count()}, indent=1,
        default=float) + "\n")
    print("\n".join(lines))


def _values(parameters: dict[str, float]) -> str:
    return ", ".join(f"{v:.3g}" for v in parameters.values())


if __name__ == "__main__":
    main()
