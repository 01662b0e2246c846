"""The gap diagnosis with the first half of a site's weeks fitted, on the blind checks' own sites.

The clean-site ceilings and the blind checks' figures were measured with the checks' settings
(:data:`buildenv.effects.CHECKED_DIAGNOSIS`: every other week fitted, three base calibrations, at most two
effects). :class:`buildenv.gap.DiagnosisSettings`' own defaults fit the first half (which reuses a site's
``buildenv calibrate`` result), with one base calibration and at most three effects; until 2026-11-28 they were
also ``buildenv diagnose``'s. This diagnoses recorded check sites again with those defaults (the check's declared
base effects kept, as a user declares them with ``--base-effect``) and sets the first effect named beside the one
the check's own record names under the same rule (``bench/gap_check_rejudge.first_named``).

    .venv/bin/python bench/gap_first_half.py --page bench/results/gap_check_tb_seed10.json [--clean-only PAGE] --jobs 2

Resumable: each site's diagnosis is kept in ``--folder`` as ``seed<S>_case_<NNN>.json``. Writes
``bench/results/<name>.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import shutil
import statistics
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from gap_check_bar import check_folder
from gap_check_compare import tally
from gap_check_rejudge import first_named

from buildenv.gap import HOLIDAYS
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def run_side_by_side(function: Callable, jobs: list[tuple], workers: int) -> None:
    """``function(*job)`` for every job, ``workers`` at a time in spawned processes with one thread each (set
    before the workers import numpy and torch, which read it as they start); an error in a job is raised."""
    for var in THREAD_VARIABLES:
        os.environ[var] = "1"
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for future in [pool.submit(function, *job) for job in jobs]:
            future.result()


def diagnose_with_defaults(site_dir: str, base_effects: tuple[str, ...], out: str) -> None:
    """Diagnose a copy of one site with DiagnosisSettings' defaults and ``base_effects``; write the result
    (without the localisation, which is large) to ``out``. One thread: several run side by side."""
    from buildenv.gap import DiagnosisSettings, diagnose
    from buildenv.site import load_site
    from buildenv.surrogate import load_metamodel

    with tempfile.TemporaryDirectory() as tmp:  # the diagnosis may write into the site folder: work on a copy
        copy = Path(tmp) / Path(site_dir).name
        shutil.copytree(site_dir, copy)
        result = diagnose(load_site(copy), load_metamodel("default"), DiagnosisSettings(base_effects=base_effects))
    result.pop("_fit", None)
    result.pop("localisation", None)
    Path(out).write_text(json.dumps(result, default=float) + "\n")


def main() -> None:
    """Diagnose (or resume) the pages' sites with the first half fitted and write the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result")
    parser.add_argument("--clean-only", action="append", default=[], metavar="PAGE",
                        help="of this page, diagnose the clean cases only (it must also be a --page)")
    parser.add_argument("--folder", default="out/gap-first-half", help="one json per diagnosed site")
    parser.add_argument("--jobs", type=int, default=1, help="diagnoses side by side, one thread each")
    parser.add_argument("--note", default="", help="a paragraph for the page (where the runs ran)")
    parser.add_argument("--name", default="gap_first_half")
    args = parser.parse_args()
    started = time.perf_counter()
    folder = Path(args.folder)
    folder.mkdir(parents=True, exist_ok=True)
    rows, todo, missing = [], [], []
    for path in args.page:
        page = json.loads(Path(path).read_text())
        alpha, min_gain, seed = (page["plan"]["settings"]["alpha"], page["plan"]["settings"]["min_gain"],
                                 page["plan"]["seed"])
        for case in page["cases"]:
            if path in args.clean_only and case["true"] != NONE:
                continue
            out = folder / f"seed{seed}_case_{case['case']:03d}.json"
            site = check_folder(page) / f"case_{case['case']:03d}"
            if not out.exists() and not site.is_dir():
                missing.append(str(site))
                continue
            rows.append({"page": Path(path).stem, "seed": seed, "case": case["case"], "true": case["true"],
                         "magnitude": case["magnitude"], "checks": first_named(case, alpha, min_gain),
                         "out": out})
            if not out.exists():
                todo.append((str(site), tuple(page["base_effects"]), str(out)))
    if todo:
        print(f"{len(todo)} sites to diagnose, {args.jobs} at a time")
        run_side_by_side(diagnose_with_defaults, todo, args.jobs)
    for row in rows:
        result = json.loads(row.pop("out").read_text())
        row["first_half"] = (result["selected"] or [NONE])[0]
        row["selected"] = result["selected"]
        row["seconds"] = result["seconds"]
        row["verdict"] = result["verdict"]
    write_page(args, rows, missing, time.perf_counter() - started)


def write_page(args: argparse.Namespace, rows: list[dict], missing: list[str], seconds: float) -> None:
    """``bench/results/<name>.{md,json}``."""
    columns = {"checks": "the checks' settings: every other week fitted, 3 base runs, 2 effects (as recorded)",
               "first_half": "DiagnosisSettings' defaults: the first half fitted, 1 base run, 3 effects"}
    no_holidays = [r for r in rows if r["true"] != HOLIDAYS]
    totals = {key: {"all": tally(rows, key), "without_holidays": tally(no_holidays, key)} for key in columns}
    median_s = statistics.median(r["seconds"] for r in rows) if rows else None
    command = ("python bench/gap_first_half.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --clean-only {p}" for p in args.clean_only)
               + f" --folder {args.folder} --jobs {args.jobs} --name {args.name}")
    lines = [f"# The diagnosis with the first half fitted, on the blind checks' sites ({time.strftime('%Y-%m-%d')})",
             "", f"Command: `{command}` ({seconds:.0f} s this run; median {median_s:.0f} s a diagnosis with the first "
             "half fitted, one thread, two at once).", "", *([args.note, ""] if args.note else []),
             *([f"Sites no longer kept, so not diagnosed: {', '.join(missing)}.", ""] if missing else []),
             "Both columns are judged by the catalogue's current rule (clean-site ceilings): the checks' column is "
             "the recorded first step judged again (`bench/gap_check_rejudge.py`), the other the first effect the "
             "new diagnosis selected. The checks planned each holiday site's absent days for every other week "
             "fitted (one in a fit week, one held out), so with the first half fitted both may fall in fit weeks "
             "and leave the held-out weeks nothing to show: the holiday cases are also left out in the last "
             "columns.", "",
             "| settings | injected effect named first | named another effect | clean sites recognised | "
             "without the holiday cases: named first | named another |", "|---|---|---|---|---|---|"]
    for key, label in columns.items():
        t, h = totals[key]["all"], totals[key]["without_holidays"]
        lines.append(f"| {label} | {t['named_right']}/{t['effect_cases']} | {t['named_wrong']} | "
                     f"{t['clean_recognised']}/{t['clean_cases']} | {h['named_right']}/{h['effect_cases']} | "
                     f"{h['named_wrong']} |")
    lines += ["", "## Effect cases, and clean sites named by either", "",
              "| page | case | injected | magnitude | checks' settings | first half | first half selected | seconds |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["true"] == NONE and r["checks"] == r["first_half"] == NONE:
            continue
        mark = "" if r["checks"] == r["first_half"] else " *"
        size = "-" if r["magnitude"] is None else f"{r['magnitude']:.3g}"
        lines.append(f"| {r['page']} | {r['case']} | {r['true']} | {size} | {r['checks']} | "
                     f"{r['first_half']}{mark} | {', '.join(r['selected']) or '-'} | {r['seconds']:.0f} |")
    lines += ["", "\\* named differently by the two settings.", ""]
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines))
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "note": args.note, "missing": missing, "totals": totals, "median_seconds": median_s,
         "rows": rows, "cpu_count": os.cpu_count()}, indent=1, default=float) + "\n")
    print("\n".join(lines[:14]))


if __name__ == "__main__":
    main()
