"""The building parameters the base calibration gives the blind checks' sites (effect cases, clean cases, twins).

The blind-check records keep each candidate's estimate but not the base model's building parameters. An effect the
base calibration absorbs (night plug loads into the lighting and equipment night shares, blinds into the glazing,
wind into the constant infiltration) moves those parameters, and some derived quantity may tell such sites from
clean ones better than a candidate's own estimate does. This recalibrates the base model of recorded check sites
with the check's own settings (its plan: split, base calibrations, declared base effects) and keeps its parameters.

    .venv/bin/python bench/gap_base_theta.py --page bench/results/gap_check_tb_seed0.json [--page ...] \
        [--effect night_plug_loads --effect none] [--twins] --jobs 2

Resumable: each site's parameters are kept in ``--folder`` as ``seed<S>_case_<NNN>[_twin].json``. Sites are done
in this order: those named with ``--first``, the effect cases, the clean cases, then the twins. A partial run is
therefore already useful. A site whose folder the check no longer keeps is skipped, and the script says which.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gap_check_bar import check_folder, recorded_settings
from gap_first_half import run_side_by_side

from buildenv.gap_check import NONE


def base_parameters(site_dir: str, settings: dict, out: str) -> None:
    """Calibrate the base model of the site in ``site_dir`` with the check's ``settings`` (its plan's
    DiagnosisSettings as a dict) and its first step's control (the base recalibrated with the refits' budget,
    which a carried effect's estimate is read from), and write ``{"base": fit, "control": fit, "seconds"}`` to
    ``out``, each fit ``{"parameters": {building parameter or occupancy: value}, "effects": {effect: {parameter:
    value}}, "cost", "params": all, in problem order}``. One thread: several run side by side."""
    from buildenv import calibration as cal
    from buildenv.gap import _context, base_fit, refit, with_declared_effects
    from buildenv.site import load_site
    from buildenv.surrogate import load_metamodel

    started = time.perf_counter()
    site = load_site(site_dir)
    diagnosis = recorded_settings(settings)
    ctx = _context(site, load_metamodel("default"), with_declared_effects(site, diagnosis))
    base = base_fit(ctx)
    control = refit(ctx, base, None)  # the first step's control: the trial of a carried effect without
    # carried_starts (night plug loads)
    names = cal.parameter_names()
    record = {key: {"parameters": {n: round(float(v), 5) for n, v in zip(names, fit.params[:len(names)])},
                    "effects": fit.effect_parameters(), "cost": fit.cost, "params": fit.params.tolist()}
              for key, fit in (("base", base), ("control", control))}
    record["seconds"] = round(time.perf_counter() - started, 1)
    Path(out).write_text(json.dumps(record, default=float) + "\n")


def site_jobs(pages: list[dict], effects: set[str], twins: bool, folder: Path, first: list[str]) -> list[tuple]:
    """``(site folder, settings, out file)`` for each site not yet done: the sites named in ``first`` (as
    ``seed<S>_case_<NNN>[_twin]``), then the cases whose true effect is in ``effects`` (all when empty), then
    the twins of every effect case when ``twins``."""
    cases, later = [], []
    for page in pages:
        out, plan = check_folder(page), page["plan"]
        for row in page["cases"]:
            key = f"seed{plan['seed']}_case_{row['case']:03d}"
            if not effects or row["true"] in effects or key in first:
                cases.append((row["true"] == NONE, (str(out / f"case_{row['case']:03d}"), plan["settings"],
                                                    str(folder / f"{key}.json"))))
            if twins and row["true"] != NONE:
                later.append((str(out / f"case_{row['case']:03d}_twin"), plan["settings"],
                              str(folder / f"{key}_twin.json")))
    cases.sort(key=lambda flagged: flagged[0])
    jobs = [job for job in [j for _, j in cases] + later if not Path(job[2]).is_file()]
    missing = [job[0] for job in jobs if not Path(job[0]).is_dir()]
    if missing:
        print(f"{len(missing)} site folders are not kept (skipped): {', '.join(missing)}")
    return [job for job in jobs if Path(job[0]).is_dir()]


def main() -> None:
    """Calibrate (or resume) the base models of the pages' sites."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result")
    parser.add_argument("--effect", action="append", default=[], help="cases with this true effect (none: clean)")
    parser.add_argument("--twins", action="store_true", help="also the clean twins of the effect cases")
    parser.add_argument("--first", action="append", default=[], metavar="KEY",
                        help="a site to do before the others, as seed<S>_case_<NNN>[_twin]")
    parser.add_argument("--folder", default="out/gap-base-theta", help="one json per site")
    parser.add_argument("--jobs", type=int, default=1, help="calibrations side by side, one thread each")
    args = parser.parse_args()
    folder = Path(args.folder)
    folder.mkdir(parents=True, exist_ok=True)
    pages = [json.loads(Path(p).read_text()) for p in args.page]
    jobs = site_jobs(pages, set(args.effect), args.twins, folder, args.first)
    jobs.sort(key=lambda job: Path(job[2]).stem not in args.first)  # stable: the rest keep their order
    print(f"{len(jobs)} base calibrations to make")
    run_side_by_side(base_parameters, jobs, args.jobs)


if __name__ == "__main__":
    main()
