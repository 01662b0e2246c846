"""What the EnergyPlus shoebox reaches on a site when the catalogue's ranges are widened: a lead for the next
training campaign.

The metamodel only knows the catalogue's ranges, and calibrating it to the default site leaves most building
parameters at a bound (``bench/results/calibration_bounds.md`` moved them one at a time). Here the EnergyPlus
shoebox itself is calibrated to the site twice with the same CMA-ES, wall-clock budget and seed, both started
from the site's saved metamodel calibration (step 0.1 of each range): once inside the catalogue's ranges, once
with the ranges of :data:`WIDER` (:func:`buildenv.calibration_energyplus.calibrate_energyplus_cmaes` with
``start`` and ``ranges``). The difference is what a metamodel trained on the wider ranges could at best add;
the catalogue itself is unchanged (the shipped metamodel is tied to it by its hash).
Writes ``bench/results/{name}.md`` and ``.json``.

    .venv/bin/python bench/shoebox_wider_ranges.py [--site DIR] [--seconds 600] [--seed 0] [--name shoebox_wider_ranges]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
from pathlib import Path

from buildenv import catalogue as cat
from buildenv.calibration import load_calibration
from buildenv.calibration_energyplus import calibrate_energyplus_cmaes, parameters_of, score_energyplus
from buildenv.env import DEFAULT_SITE
from buildenv.site import load_site

RESULTS = Path(__file__).parent / "results"
FACADES = ("north", "east", "south", "west")


def widened(name: str, low: float | None = None, high: float | None = None) -> tuple[float, float]:
    """The catalogue's range of ``name`` with one or both ends moved out (an end not given stays the catalogue's)."""
    v = cat.get(name)
    return (v.min if low is None else low, v.max if high is None else high)


#: Ranges past the catalogue's, each still one that offices have.
WIDER: dict[str, tuple[float, float]] = {
    # airtight new buildings
    "infiltration_ach": widened("infiltration_ach", low=0.05),
    # EN ISO 13790's "very light" class, 80 kJ/K per m2 of floor, is 23 kJ/K/m3 at the shoebox's 3.5 m storeys;
    # the catalogue (the paper's) starts at 50, the "medium" class
    "capacitance_kj_per_k_m3": widened("capacitance_kj_per_k_m3", low=10.0),
    # oversized plants of older buildings
    "heating_power_w_m2": widened("heating_power_w_m2", high=150.0),
    "cooling_power_w_m2": widened("cooling_power_w_m2", high=150.0),
    # dense open plan, 10 m2 a person
    "occupant_density_per_m2": widened("occupant_density_per_m2", high=0.1),
    "pc_density_per_m2": widened("pc_density_per_m2", 0.01, 0.1),
    # from barely insulated to very well insulated
    **{name: widened(name, 0.02, 0.25) for name in [f"wall_insulation_{f}_m" for f in FACADES] + ["roof_insulation_m"]},
    # punched windows to curtain walls
    **{f"window_to_wall_{f}_percent": widened(f"window_to_wall_{f}_percent", 10.0, 80.0) for f in FACADES},
}
SIGMA0 = 0.1
METRICS = ("r2_t", "rmse_t_celsius", "r2_q", "cv_rmse_q_percent", "nmbe_q_percent")


def outside_catalogue(theta: dict[str, float]) -> dict[str, float]:
    """The building parameters of ``theta`` that lie outside the catalogue's ranges."""
    return {name: value for name, value in theta.items()
            if name in WIDER and not cat.get(name).min <= value <= cat.get(name).max}


def main() -> None:
    """Score the saved calibration on EnergyPlus, calibrate the shoebox within and past the catalogue."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--site", type=Path, default=DEFAULT_SITE)
    parser.add_argument("--seconds", type=float, default=600.0, help="CMA-ES wall-clock budget of each run, s")
    parser.add_argument("--seed", type=int, default=0, help="seed of both CMA-ES runs")
    parser.add_argument("--name", default="shoebox_wider_ranges")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    site, saved = load_site(args.site), load_calibration(args.site)
    start = parameters_of(saved)
    fit, heldout = saved["fit_weeks"], saved["heldout_weeks"]
    rows = {"saved metamodel calibration, run on EnergyPlus": {
        "cost": None, "evaluations": None, **score_energyplus(site, start, fit, heldout)}}
    runs = {}
    for label, ranges in (("shoebox calibrated, catalogue ranges", None), ("shoebox calibrated, wider ranges", WIDER)):
        r = calibrate_energyplus_cmaes(site, weeks=fit, seed=args.seed, wall_seconds=args.seconds, workers=2,
                                       progress=True, start=start, sigma0=SIGMA0, ranges=ranges)
        runs[label] = r
        rows[label] = {"cost": r["cost"], "evaluations": r["evaluations"], "fit": r["fit"], "heldout": r["heldout"]}
    command = "python bench/shoebox_wider_ranges.py" + (f" --site {args.site}" if args.site != DEFAULT_SITE else "") \
        + (f" --seconds {args.seconds:g}" if args.seconds != 600.0 else "") \
        + (f" --seed {args.seed}" if args.seed else "") \
        + (f" --name {args.name}" if args.name != "shoebox_wider_ranges" else "")
    wide = runs["shoebox calibrated, wider ranges"]["theta"]
    record = {"date": dt.date.today().isoformat(), "machine": f"{platform.platform()}, {os.cpu_count()} cores",
              "load_average_at_start": load, "command": command, "site": str(args.site), "fit_weeks": fit,
              "heldout_weeks": heldout, "seed": args.seed, "sigma0": SIGMA0, "wider": WIDER, "rows": rows,
              "theta": {label: r["theta"] for label, r in runs.items()}, "outside_catalogue": outside_catalogue(wide)}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(record, indent=1, default=float) + "\n")
    lines = [f"# The EnergyPlus shoebox calibrated within and past the catalogue's ranges ({args.site.name})", "",
             f"{record['date']}, {record['machine']}, 1-min load average at start {load:.2f}; `{command}`.", "",
             f"CMA-ES (seed {args.seed}, step {SIGMA0} of each range) on the EnergyPlus shoebox, started from the "
             f"site's saved metamodel calibration, {args.seconds:g} s of wall clock each; fit weeks {fit}, "
             f"held-out weeks {heldout}. Wider ranges: "
             + ", ".join(f"{k} {a:g}-{b:g}" for k, (a, b) in WIDER.items()) + ".", "",
             "| model | fit cost | evaluations | fit r2_t | " + " | ".join(f"held-out {m}" for m in METRICS) + " |",
             "|---" * (len(METRICS) + 4) + "|"]
    for label, row in rows.items():
        cost = "-" if row["cost"] is None else f"{row['cost']:.4f}"
        evals = "-" if row["evaluations"] is None else str(row["evaluations"])
        lines.append(f"| {label} | {cost} | {evals} | {row['fit']['r2_t']:.3f} | "
                     + " | ".join(f"{row['heldout'][m]:.3f}" for m in METRICS) + " |")
    lines += ["", "Building parameters of the two shoebox calibrations (catalogue range in brackets):", "",
              "| parameter | range | catalogue ranges | wider ranges |", "|---|---|---|---|"]
    inside = runs["shoebox calibrated, catalogue ranges"]["theta"]
    for name in WIDER:
        v = cat.get(name)
        lines.append(f"| {name} | [{v.min:g}, {v.max:g}] | {inside[name]:.4g} | {wide[name]:.4g}"
                     + (" (outside)" if name in record["outside_catalogue"] else "") + " |")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
