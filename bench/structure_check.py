"""Which model structure fits the default site: EnergyPlus itself calibrated, zoning x recorded ventilation.

Takes the metamodel out of the question: the EnergyPlus shoebox is calibrated directly to the default site
(:func:`buildenv.calibration_energyplus.calibrate_energyplus_cmaes`, the same CMA-ES, bounds, start and cost
as the metamodel's, weeks 0-2 fit, 3-5 held out) for each combination of

- zoning: ``single`` (the paper's single zone) or ``core_perimeter`` (:mod:`buildenv.energyplus.shoebox`);
- the ventilation the site records: 1.0 air changes per hour (what sites recorded for the reference's design
  minimum outdoor air before it was mapped in physical units) or 0.7 (that design in our units, 0.69,
  on the catalogue's grid; see :mod:`buildenv.reference`). The measurements are the same in both: only the
  settings the model is told change.

Each calibration gets the same wall-clock budget; the held-out metrics are EnergyPlus's own. Writes
``bench/results/structure_check.{md,json}``.

    .venv/bin/python bench/structure_check.py [--seconds 300] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import pandas as pd

from _training_runs import RESULTS, machine

KEYS = ("r2_t", "r2_q", "rmse_t_celsius", "cv_rmse_q_percent", "nmbe_q_percent")


def main() -> None:
    """Run the four calibrations and write the table."""
    from buildenv.calibration_energyplus import calibrate_energyplus_cmaes
    from buildenv.env import DEFAULT_SITE
    from buildenv.site import load_site

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=300.0, help="wall-clock budget of each calibration")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--conditions", default="", help="what else ran on the machine")
    args = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="buildenv-structure-") as tmp:
        for ach in (1.0, 0.7):
            site_dir = shutil.copytree(DEFAULT_SITE, Path(tmp) / f"site-{ach}",
                                       ignore=shutil.ignore_patterns("calibration.*"))
            settings = pd.read_csv(site_dir / "settings.csv")
            settings["ventilation_ach"] = ach
            settings.to_csv(site_dir / "settings.csv", index=False)
            for zoning in ("single", "core_perimeter"):
                started = time.perf_counter()
                r = calibrate_energyplus_cmaes(load_site(site_dir), seed=0, wall_seconds=args.seconds,
                                               workers=args.workers, zoning=zoning)
                rows.append({"zoning": zoning, "ventilation_ach": ach, "evaluations": r["evaluations"],
                             "cost": r["cost"], "seconds": round(time.perf_counter() - started, 1),
                             "fit": {k: r["fit"][k] for k in KEYS}, "heldout": {k: r["heldout"][k] for k in KEYS},
                             "theta": r["theta"]})
                print(zoning, ach, rows[-1]["heldout"], flush=True)
    data = {"machine": machine(), "seconds_budget": args.seconds, "conditions": args.conditions, "rows": rows,
            "command": f"python bench/structure_check.py --seconds {args.seconds:g} --workers {args.workers}"}
    (RESULTS / "structure_check.json").write_text(json.dumps(data, indent=1))
    (RESULTS / "structure_check.md").write_text(render(data))


def render(data: dict) -> str:
    """The markdown page of a result."""
    lines = ["# Which structure fits the default site: EnergyPlus calibrated directly", "",
             f"{data['machine']}; `{data['command']}`. {data['conditions']}", "",
             "| zoning | recorded ventilation 1/h | evaluations | fit cost | held-out CV(RMSE)_Q % | "
             "held-out NMBE_Q % | held-out R2_T | held-out R2_Q | held-out RMSE_T degC |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in data["rows"]:
        h = r["heldout"]
        lines.append(f"| {r['zoning']} | {r['ventilation_ach']:.1f} | {r['evaluations']:,} | {r['cost']:.3f} | "
                     f"{h['cv_rmse_q_percent']:.1f} | {h['nmbe_q_percent']:+.1f} | {h['r2_t']:.3f} | "
                     f"{h['r2_q']:.3f} | {h['rmse_t_celsius']:.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
