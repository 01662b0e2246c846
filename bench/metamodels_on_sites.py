"""Metamodels compared where they are used: calibrating reference-office sites, scored on held-out weeks.

A metamodel closer to the EnergyPlus shoebox is not necessarily one that calibrates a real building better:
what is left is the shoebox's own mismatch with the building. This bench calibrates the same sites with each
checkpoint (``buildenv.calibration.calibrate_site``, CMA-ES, seed 0, the first half of the weeks fit, nothing
saved into the sites) and tabulates the held-out metrics side by side.

    .venv/bin/python bench/metamodels_on_sites.py --model shipped=default --model other=data/runs/other.pt

Sites: the shipped default site and three reference offices made with the unchanged ``buildenv site
reference`` command (kept under ``out/model-sites``). Writes ``bench/results/metamodels_on_sites.{md,json}``
(``--name`` changes the stem).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from _training_runs import RESULTS, machine

from buildenv import calibration as cal
from buildenv import surrogate as sg
from buildenv.site import load_site

OTHER_SITES = (("medium_office", "usa_ok_oklahoma"), ("medium_office", "usa_az_phoenix"),
               ("large_office", "usa_az_phoenix"))
METRICS = ("r2_t", "r2_q", "rmse_t_celsius", "cv_rmse_q_percent", "nmbe_q_percent")


def sites(out: Path) -> dict[str, str]:
    """``{label: site folder}``: the default site and the reference offices (made when missing)."""
    found = {"default site (medium_office, Chicago, 6 weeks)": "buildenv/data/sites/default"}
    for building, epw in OTHER_SITES:
        path = out / f"{building}_{epw}"
        if not (path / "site.toml").is_file():
            subprocess.run([sys.executable, "-m", "buildenv.cli", "site", "reference", "--building", building,
                            "--epw", epw, "--start", "01-14", "--weeks", "4", "--out", str(path)], check=True)
        found[f"{building}, {epw}, 4 weeks from 01-14"] = str(path)
    return found


def main() -> None:
    """Calibrate every site with every model and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", action="append", required=True, help="LABEL=CHECKPOINT (default: the shipped one)")
    parser.add_argument("--out", default="out/model-sites", help="folder of the reference sites")
    parser.add_argument("--name", default="metamodels_on_sites")
    args = parser.parse_args()
    models = dict(m.split("=", 1) for m in args.model)
    started, load = time.perf_counter(), os.getloadavg()[0]
    rows = []
    for label, checkpoint in models.items():
        surrogate = sg.load_metamodel(None if checkpoint == "default" else checkpoint)
        for site_label, path in sites(Path(args.out)).items():
            result = cal.calibrate_site(load_site(path), surrogate, save=False, effects=())  # plain model
            rows.append({"model": label, "checkpoint": checkpoint, "site": site_label, "cost": result["cost"],
                         "seconds": result["seconds"], **{k: result["heldout"][k] for k in METRICS}})
            print(json.dumps(rows[-1]), flush=True)
    command = "python bench/metamodels_on_sites.py " + " ".join(f'--model "{m}"' for m in args.model)
    record = {"date": dt.date.today().isoformat(), "machine": machine(), "load_average_at_start": load,
              "command": command,
              "seconds": round(time.perf_counter() - started, 1), "rows": rows}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(record, indent=1) + "\n")
    lines = ["# Metamodels compared on calibrated sites (held-out weeks)", "",
             f"{record['date']}, {record['machine']}, 1-min load average at start {load:.2f}. Command: `{command}`.", "",
             "Each site calibrated by each model (CMA-ES, 6,000 evaluations, seed 0, first half of the weeks fit); "
             "held-out metrics of the site's other weeks.", "",
             "| site | model | fit cost | R2_T | R2_Q | RMSE_T degC | CV(RMSE)_Q % | NMBE_Q % |", "|---|---|---|---|---|---|---|---|"]
    for site_label in dict.fromkeys(r["site"] for r in rows):
        for r in (r for r in rows if r["site"] == site_label):
            lines.append(f"| {site_label} | {r['model']} | {r['cost']:.4f} | {r['r2_t']:.3f} | {r['r2_q']:.3f} | "
                         f"{r['rmse_t_celsius']:.3f} | {r['cv_rmse_q_percent']:.1f} | {r['nmbe_q_percent']:.1f} |")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
