"""Metamodels compared where they are used: calibrating reference-office sites, scored on held-out weeks.

A metamodel closer to the EnergyPlus shoebox is not necessarily one that calibrates a real building better:
what is left is the shoebox's own mismatch with the building. This bench calibrates the same sites with each
checkpoint (``buildenv.calibration.problem.calibrate_site``, CMA-ES, the first half of the weeks fit, nothing saved into
the sites) and tabulates the held-out metrics side by side, per CMA-ES seed and their mean.

    .venv/bin/python bench/metamodels_on_sites.py --model shipped=default --model other=data/runs/other.pt

Sites: the shipped default site and three reference offices made with the unchanged ``buildenv site
reference`` command (kept under ``out/model-sites``), and any ``--site LABEL=DIR``. The model calibrated is the
plain one unless ``--site-effects`` (each site's declared effects) or ``--effect`` (added on every site) say
otherwise. Writes ``bench/results/metamodels_on_sites.{md,json}`` (``--name`` changes the stem).
"""

from __future__ import annotations

import datetime as dt
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

import harness
from harness import machine

from buildenv.calibration.calibrate import calibrate_site
from buildenv.jsonio import dumps
from buildenv.metamodel import surrogate as sg
from buildenv.sites import load_site

OTHER_SITES = (
    ("medium_office", "usa_ok_oklahoma"),
    ("medium_office", "usa_az_phoenix"),
    ("large_office", "usa_az_phoenix"),
)
METRICS = ("r2_t", "r2_q", "rmse_t_celsius", "cv_rmse_q_percent", "nmbe_q_percent")


def sites(out: Path) -> dict[str, str]:
    """``{label: site folder}``: the default site and the reference offices (made when missing)."""
    found = {"default site (medium_office, Chicago, 6 weeks)": "buildenv/data/sites/default"}
    for building, epw in OTHER_SITES:
        path = out / f"{building}_{epw}"
        if not (path / "site.toml").is_file():
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "buildenv.cli.main",
                    "site",
                    "reference",
                    "--building",
                    building,
                    "--epw",
                    epw,
                    "--start",
                    "01-14",
                    "--weeks",
                    "4",
                    "--out",
                    str(path),
                ],
                check=True,
            )
        found[f"{building}, {epw}, 4 weeks from 01-14"] = str(path)
    return found


def main() -> None:
    """Calibrate every site with every model and write the table."""
    parser = harness.parser(__doc__, first_line=True)
    parser.add_argument("--model", action="append", required=True, help="LABEL=CHECKPOINT (default: the shipped one)")
    parser.add_argument("--out", default="out/model-sites", help="folder of the reference sites")
    parser.add_argument("--name", default="metamodels_on_sites")
    parser.add_argument("--site", action="append", default=[], metavar="LABEL=DIR", help="another site")
    parser.add_argument("--only-given-sites", action="store_true", help="leave the four standard sites out")
    parser.add_argument("--seeds", default="0", help="CMA-ES seeds, e.g. 0,1,2")
    parser.add_argument("--site-effects", action="store_true", help="calibrate each site's declared effects")
    parser.add_argument("--effect", action="append", default=[], help="an effect calibrated on every site")
    args = parser.parse_args()
    models = dict(m.split("=", 1) for m in args.model)
    seeds = [int(v) for v in args.seeds.split(",")]
    chosen = {} if args.only_given_sites else sites(Path(args.out))
    chosen.update(dict(v.split("=", 1) for v in args.site))
    loaded = {site_label: load_site(path) for site_label, path in chosen.items()}  # read once, every model fits them
    started, load = time.perf_counter(), os.getloadavg()[0]
    rows = []
    for label, checkpoint in models.items():
        surrogate = sg.load_metamodel(None if checkpoint == "default" else checkpoint)
        for site_label, site in loaded.items():
            effects = tuple(dict.fromkeys((site.effects if args.site_effects else ()) + tuple(args.effect)))
            for seed in seeds:
                result = calibrate_site(site, surrogate, seed=seed, save=False, effects=effects)
                rows.append(
                    {
                        "model": label,
                        "checkpoint": checkpoint,
                        "site": site_label,
                        "seed": seed,
                        "effects": list(effects),
                        "cost": result["cost"],
                        "seconds": result["seconds"],
                        **{k: result["heldout"][k] for k in METRICS},
                    }
                )
                print(dumps(rows[-1], where="a row", nonfinite="null"), flush=True)
    command = "python bench/metamodels_on_sites.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    record = {
        "date": dt.date.today().isoformat(),
        "machine": machine(),
        "load_average_at_start": load,
        "command": command,
        "seconds": round(time.perf_counter() - started, 1),
        "rows": rows,
    }
    lines = [
        "# Metamodels compared on calibrated sites (held-out weeks)",
        "",
        f"Torch machine: {record['machine']}.",
        "",
        f"Each site calibrated by each model (CMA-ES, 6,000 evaluations, seeds {args.seeds}, first half of the "
        "weeks fit; effects calibrated: "
        + ("each site's declared ones" if args.site_effects else "none declared")
        + (f", and {', '.join(args.effect)}" if args.effect else "")
        + "); held-out metrics of the site's other "
        "weeks, the mean over the seeds (R2_T of each seed in the last column).",
        "",
        "| site | model | fit cost | R2_T | R2_Q | RMSE_T degC | CV(RMSE)_Q % | NMBE_Q % | R2_T by seed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for site_label in dict.fromkeys(r["site"] for r in rows):
        for label in models:
            mine = [r for r in rows if r["site"] == site_label and r["model"] == label]
            mean = {k: sum(r[k] for r in mine) / len(mine) for k in ("cost",) + METRICS}
            by_seed = " / ".join(f"{r['r2_t']:.3f}" for r in mine)
            lines.append(
                f"| {site_label} | {label} | {mean['cost']:.4f} | {mean['r2_t']:.3f} | {mean['r2_q']:.3f} | "
                f"{mean['rmse_t_celsius']:.3f} | {mean['cv_rmse_q_percent']:.1f} | "
                f"{mean['nmbe_q_percent']:.1f} | {by_seed} |"
            )
    harness.write_results(args.name, lines, record)


if __name__ == "__main__":
    main()
