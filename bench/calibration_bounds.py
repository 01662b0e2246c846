"""Which of the default site's calibrated parameters the catalogue's ranges hold back, checked on EnergyPlus.

Calibrating the metamodel to the default site leaves many building parameters at a bound of their catalogue
range (``at_bounds`` of ``buildenv calibrate``, :func:`buildenv.calibration.parameters_at_bounds`). The
metamodel knows nothing past those ranges, but the EnergyPlus shoebox it imitates does: this script runs the
shoebox on the site's fit and held-out weeks with the saved calibration, then with each parameter at a bound
moved past it by 10 % and 20 % of its range (kept above zero), then with those moves of 10 % made together. A
parameter whose move improves the held-out weeks is one the range holds back; one whose move changes nothing
sits on a flat direction of the cost; one whose move makes it worse was at its best at the bound.
Writes ``bench/results/calibration_bounds.{md,json}``.

    .venv/bin/python bench/calibration_bounds.py [--site buildenv/data/sites/default]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
from pathlib import Path

import numpy as np
from tqdm import tqdm

from buildenv import catalogue as cat
from buildenv.calibration import free_theta, load_calibration, parameters_at_bounds
from buildenv.calibration_energyplus import ShoeboxPool, parameters_of, score_energyplus
from buildenv.env import DEFAULT_SITE
from buildenv.site import load_site

RESULTS = Path(__file__).parent / "results"
MOVES = (0.1, 0.2)
METRICS = ("r2_t", "rmse_t_celsius", "r2_q", "cv_rmse_q_percent")


def shoebox_scores(site, calibration: dict, params: np.ndarray, pool: ShoeboxPool) -> dict[str, dict[str, float]]:
    """Metrics of the parameter vector ``params`` (free theta_build, occupancy) simulated by the EnergyPlus
    shoebox on the calibration's fit and held-out weeks (:func:`score_energyplus`)."""
    scores = score_energyplus(site, params, calibration["fit_weeks"], calibration["heldout_weeks"], pool)
    return {key: {m: round(float(metrics[m]), 4) for m in METRICS} for key, metrics in scores.items()}


def main() -> None:
    """Score the saved calibration and its parameters at a bound moved past it; write the page."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--site", type=Path, default=DEFAULT_SITE)
    parser.add_argument("--name", default="calibration_bounds")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    site, calibration = load_site(args.site), load_calibration(args.site)
    params = parameters_of(calibration)
    at = parameters_at_bounds(calibration["theta"], calibration["known"])
    plan: list[tuple[str, str, np.ndarray]] = [("as calibrated", "-", params)]
    together = params.copy()
    for entry in at:
        var, j = cat.get(entry["name"]), free_theta().index(entry["name"])
        sign = -1.0 if entry["bound"] == "min" else 1.0
        for share in MOVES:
            value = entry["limit"] + sign * share * (var.max - var.min)
            if value <= 0.0:  # no building has a zero or negative one
                continue
            moved = params.copy()
            moved[j] = value
            plan.append((entry["name"], f"{entry['limit']:g} -> {value:g}", moved))
            if share == MOVES[0]:
                together[j] = value
    plan.append(("all that can move, 10 % past", "-", together))
    with ShoeboxPool(1, within_catalogue=False) as pool:
        rows = [{"parameter": name, "change": change, **shoebox_scores(site, calibration, p, pool)}
                for name, change, p in tqdm(plan, desc="EnergyPlus shoebox runs")]
    data = {"date": dt.date.today().isoformat(), "machine": platform.platform(), "load_average": round(load, 2),
            "site": str(args.site), "metamodel_heldout": {m: calibration["heldout"][m] for m in METRICS},
            "at_bounds": at, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(data, indent=1) + "\n")
    (RESULTS / f"{args.name}.md").write_text(markdown(data))
    print(markdown(data))


def markdown(data: dict) -> str:
    """The results page."""
    h = data["metamodel_heldout"]
    lines = [f"# Calibrated parameters at a bound of the catalogue: {data['site']}", "",
             f"{data['date']}, {data['machine']}, 1-min load average at start {data['load_average']}; "
             "`python bench/calibration_bounds.py`.", "",
             f"The site's saved calibration (the metamodel's; held-out R2_T {h['r2_t']:.3f}, R2_Q {h['r2_q']:.3f}, "
             f"CV(RMSE)_Q {h['cv_rmse_q_percent']:.1f} %) has {len(data['at_bounds'])} of "
             f"{len(free_theta())} estimated building parameters at a bound: "
             + ", ".join(f"{e['name']} at its {e['bound']} ({e['limit']:g})" for e in data["at_bounds"]) + ".", "",
             "The EnergyPlus shoebox run with those parameters, then with one of them moved past its bound "
             "(by 10 % and 20 % of its range, kept above zero), then all that can move by 10 %:", "",
             "| parameter | change | fit R2_T | fit R2_Q | held-out R2_T | held-out RMSE_T K | held-out R2_Q | "
             "held-out CV(RMSE)_Q % |", "|---|---|---|---|---|---|---|---|"]
    for r in data["rows"]:
        f, o = r["fit"], r["heldout"]
        lines.append(f"| {r['parameter']} | {r['change']} | {f['r2_t']:.3f} | {f['r2_q']:.3f} | {o['r2_t']:.3f} | "
                     f"{o['rmse_t_celsius']:.3f} | {o['r2_q']:.3f} | {o['cv_rmse_q_percent']:.1f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
