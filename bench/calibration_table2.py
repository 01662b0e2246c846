"""The paper's Table 2 on the default site: calibrating the metamodel vs. calibrating EnergyPlus directly.

On a copy of the default site (``buildenv/data/sites/default``: the DOE medium office in Chicago, weeks 0-2
fit, 3-5 held out), in this order:

1. the metamodel, CMA-ES (``calibrate_site(method="cmaes")``, its default 6,000 evaluations); its wall time
   ``T`` is the budget of the EnergyPlus runs;
2. the metamodel, Adam (``calibrate_site(method="adam")``);
3. the parameters each of them found, re-simulated by the EnergyPlus shoebox (does the metamodel's
   calibration hold for the simulator it imitates?);
4. the EnergyPlus shoebox, the same CMA-ES, budget ``T``
   (:func:`buildenv.calibration.energyplus.calibrate_energyplus_cmaes`);
5. the same with a longer budget, ``min(long_factor x T, long_cap)``.

Every row is scored with the same metrics (:func:`buildenv.metrics.site_metrics`) on the predictions of
the model it calibrated (metamodel or EnergyPlus). Writes ``bench/results/calibration_table2.{md,json}`` (a
hand-written ``## Findings`` section at the end of the old page is kept).

Run:  .venv/bin/python bench/calibration_table2.py [--seed 0] [--long-factor 10] [--long-cap 600]
      [--conditions "what else ran on the machine"]
"""

from __future__ import annotations

import datetime as dt
import json
import shlex
import shutil
import sys
import tempfile
import time
from pathlib import Path

import harness
from harness import RESULTS, CpuMeter, cpu_sentence
from harness import machine_details as machine

DEFAULT_SITE = Path(__file__).resolve().parent.parent / "buildenv" / "data" / "sites" / "default"
METRICS = ("r2_t", "r2_q", "rmse_t_celsius", "cv_rmse_q_percent", "nmbe_q_percent")


FINDINGS = "## Findings"


def cost_of(metrics: dict) -> float:
    """The calibration cost ``(1 - R2_T) + (1 - R2_Q)`` over the fit weeks (weights 1, as calibration.WEIGHTS)."""
    return (1.0 - metrics["r2_t"]) + (1.0 - metrics["r2_q"])


def row(name: str, model: str, budget, result: dict, fit: dict, heldout: dict) -> dict:
    """One table row."""
    return {
        "method": name,
        "predictions_by": model,
        "budget_s": budget,
        "seconds": result.get("seconds"),
        "evaluations": result.get("evaluations"),
        "generations": result.get("generations"),
        "cost": round(cost_of(fit), 4),
        "fit": fit,
        "heldout": heldout,
    }


def run(seed: int, long_factor: float, long_cap: float, workers: int | None, evaluations: int = 6000) -> dict:
    """Run the five calibrations on a temporary copy of the default site; return every row and setting."""
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.calibration.energyplus import (
        calibrate_energyplus_cmaes,
        parameters_of,
        score_energyplus,
    )
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site

    rows = []
    with tempfile.TemporaryDirectory(prefix="buildenv-table2-") as tmp:
        path = shutil.copytree(DEFAULT_SITE, Path(tmp) / "site", ignore=shutil.ignore_patterns("calibration.*"))
        site = load_site(path)
        t0 = time.perf_counter()
        surrogate = load_metamodel()
        load_seconds = time.perf_counter() - t0
        found = {}
        for method, label in (("cmaes", "metamodel, CMA-ES"), ("adam", "metamodel, Adam (8 starts x 150 steps)")):
            result = calibrate_site(
                site, surrogate, method=method, seed=seed, max_evaluations=evaluations, save=False, effects=()
            )  # the plain model: the shoebox has no effects
            found[method] = result
            rows.append(row(label, "metamodel", None, result, result["fit"], result["heldout"]))
        budget = found["cmaes"]["seconds"]
        for method, label in (("cmaes", "metamodel CMA-ES parameters"), ("adam", "metamodel Adam parameters")):
            result = found[method]
            t0 = time.perf_counter()
            scores = score_energyplus(
                site, parameters_of(result), result["fit_weeks"], result["heldout_weeks"], zoning=surrogate.zoning
            )
            rerun = {
                "seconds": result["seconds"],
                "evaluations": result["evaluations"],
                "scoring_seconds": round(time.perf_counter() - t0, 2),
            }
            rows.append(row(f"{label}, re-simulated", "EnergyPlus", None, rerun, scores["fit"], scores["heldout"]))
        long_budget = round(min(long_factor * budget, long_cap), 1)
        for wall, label in (
            (budget, "EnergyPlus shoebox, CMA-ES, budget T"),
            (long_budget, f"EnergyPlus shoebox, CMA-ES, budget {long_budget / budget:.1f} T"),
        ):
            result = calibrate_energyplus_cmaes(
                site, seed=seed, wall_seconds=wall, workers=workers, zoning=surrogate.zoning
            )
            r = row(label, "EnergyPlus", wall, result, result["fit"], result["heldout"])
            r.update(
                history=result["history"],
                scoring_seconds=result["scoring_seconds"],
                workers=result["workers"],
                theta=result["theta"],
                occupancy=result["occupancy"],
            )
            rows.append(r)
        for r, method in zip(rows[:2], ("cmaes", "adam")):
            r.update(theta=found[method]["theta"], occupancy=found[method]["occupancy"])
    return {
        "rows": rows,
        "budget_T_s": budget,
        "long_budget_s": long_budget,
        "metamodel_load_s": round(load_seconds, 2),
        "fit_weeks": found["cmaes"]["fit_weeks"],
        "heldout_weeks": found["cmaes"]["heldout_weeks"],
    }


def _f(value, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, int):
        return f"{value:,}"
    return f"{value:.{digits}f}"


def markdown(data: dict) -> str:
    """The results as a Markdown page."""
    m = data["machine"]
    rows = data["rows"]
    lines = [
        f"# Calibration: metamodel vs. EnergyPlus under the same wall-clock budget ({data['date']})",
        "",
        "The paper's Table 2 on our default site: `buildenv/data/sites/default` (DOE RefBldgMediumOfficeNew2004 "
        "in Chicago TMY3 from 4 November 2019, read as sensors with noise), calibration weeks "
        f"{data['fit_weeks']}, held-out weeks {data['heldout_weeks']}, seed {data['seed']}.",
        "",
        f"Machine: {m['cpu']}, {m['cores']} cores, {m['platform']}; EnergyPlus {m['versions']['energyplus']}, "
        f"cma {m['versions']['cma']}, torch {m['versions']['torch']}. 1-minute load average at start: "
        f"{m['load_average_1min_at_start']}.",
        "",
        f"Conditions: {data['conditions'] or 'not recorded'}. {cpu_sentence(data['cpu'])}",
        "",
        f"Command: `{data['command']}`",
        "",
        f"Budget T = the metamodel CMA-ES's wall time = **{data['budget_T_s']:.1f} s** "
        f"({data['rows'][0]['evaluations']:,} evaluations; the metamodel's load, "
        f"{data['metamodel_load_s']:.1f} s, is not counted, nor is the EnergyPlus worker start). The EnergyPlus "
        "rows run the same CMA-ES (same start point, step 0.3, bounds, seed) with each candidate simulated by "
        "EnergyPlus over the 3 fit weeks, 13 candidates a generation on "
        f"{rows[-1]['workers']} worker processes; a generation is not started once the previous one's "
        "duration no longer fits in the budget.",
        "",
        "## Table 2",
        "",
        "Cost = (1 - R2_T) + (1 - R2_Q) over the fit weeks, of the model that makes the predictions. "
        "Held-out: weeks the calibration never saw.",
        "",
        "| method | predictions by | budget s | s used | evaluations | cost | held-out R2_T | held-out R2_Q | "
        "held-out RMSE_T degC | held-out CV(RMSE)_Q % | held-out NMBE_Q % |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        h = r["heldout"]
        lines.append(
            f"| {r['method']} | {r['predictions_by']} | {_f(r['budget_s'], 1)} | {_f(r['seconds'], 1)} | "
            f"{_f(r['evaluations'])} | {_f(r['cost'])} | {_f(h['r2_t'])} | {_f(h['r2_q'])} | "
            f"{_f(h['rmse_t_celsius'], 2)} | {_f(h['cv_rmse_q_percent'], 1)} | "
            f"{_f(h['nmbe_q_percent'], 1)} |"
        )
    lines += [
        "",
        "Fit weeks:",
        "",
        "| method | predictions by | R2_T | R2_Q | RMSE_T degC | CV(RMSE)_Q % | NMBE_Q % |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        f = r["fit"]
        lines.append(
            f"| {r['method']} | {r['predictions_by']} | {_f(f['r2_t'])} | {_f(f['r2_q'])} | "
            f"{_f(f['rmse_t_celsius'], 2)} | {_f(f['cv_rmse_q_percent'], 1)} | {_f(f['nmbe_q_percent'], 1)} |"
        )
    lines += [
        "",
        "The paper's columns (held-out weeks; MSEs of the series standardised by the fit weeks' measured "
        "mean and standard deviation, `occ` = hours the calibrated occupancy marks occupied):",
        "",
        "| method | MSE_T | MSE_Q | MSE_T^occ | MSE_Q^occ | R2_T | R2_Q | time s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        h = r["heldout"]
        lines.append(
            f"| {r['method']} | {h['mse_t']:.3g} | {h['mse_q']:.3g} | {h['mse_t_occ']:.3g} | "
            f"{h['mse_q_occ']:.3g} | {_f(h['r2_t'])} | {_f(h['r2_q'])} | {_f(r['seconds'], 1)} |"
        )
    long, same = rows[-1], rows[-2]
    per_run = same["seconds"] * same["workers"] / same["evaluations"]
    marks = [t for t in (1, 2, 5, 10, 20) if t * data["budget_T_s"] <= long["seconds"] + 1e-9]
    lines += [
        "",
        f"Best cost of the long EnergyPlus run as the budget grows (it is the budget-T run continued; "
        f"{long['generations']} generations of 13):",
        "",
        "| budget | s | evaluations | best cost |",
        "|---|---|---|---|",
    ]
    for t in marks:
        done = [h for h in long["history"] if h[0] <= t * data["budget_T_s"] + 1e-9]
        if done:
            lines.append(f"| {t} T | {done[-1][0]:.1f} | {done[-1][1]:,} | {done[-1][2]:.3f} |")
    lines.append(f"| end | {long['history'][-1][0]:.1f} | {long['history'][-1][1]:,} | {long['history'][-1][2]:.3f} |")
    lines += [
        "",
        "Notes:",
        "",
        '- Each row\'s metrics come from the model it calibrated; the "re-simulated" rows run the '
        "metamodel's calibrated parameters through EnergyPlus instead (no further fitting): the gap to the "
        "metamodel row is the metamodel's own error on this building, not the optimiser's.",
        '- The "s used" and evaluations of the re-simulated rows are those of the metamodel calibration '
        "that found the parameters (re-simulating them takes two EnergyPlus runs, about a second).",
        "- The EnergyPlus rows simulate each candidate from EnergyPlus's warm-up days before week 0 "
        "(the held-out scoring run starts one week early, week 2, and drops it); the metamodel sees the day "
        f"before each week. One candidate (3 weeks + warm-up days) took {per_run:.2f} s of a worker "
        f"({same['workers']} workers in parallel), so within T the same CMA-ES made "
        f"{rows[0]['evaluations'] / same['evaluations']:.0f} times fewer evaluations than on the metamodel.",
        "- Deterministic given the seed except for where the wall-clock budget cuts the EnergyPlus runs "
        "(the budget-T run is the first generations of the long run).",
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the bench and write ``bench/results/calibration_table2.{md,json}``."""
    p = harness.parser(__doc__, first_line=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--long-factor", type=float, default=10.0, help="long EnergyPlus budget in units of T")
    p.add_argument("--long-cap", type=float, default=600.0, help="cap of the long budget, s")
    p.add_argument("--evaluations", type=int, default=6000, help="metamodel CMA-ES budget (its default: 6000)")
    p.add_argument("--workers", type=int, default=None, help="EnergyPlus worker processes (default: all cores)")
    p.add_argument("--conditions", default="", help="what else ran on the machine (written into the page)")
    p.add_argument("--out", type=Path, default=RESULTS)
    p.add_argument(
        "--from-json",
        type=Path,
        default=None,
        help="only re-render the page from a saved calibration_table2.json (no calibration)",
    )
    args = p.parse_args(argv)
    if args.from_json is not None:
        data = json.loads(args.from_json.read_text())
        harness.write_results("calibration_table2", markdown(data), data, out=args.out, keep=FINDINGS)
        return 0
    info = machine()
    meter = CpuMeter().start()
    data = {
        "date": dt.datetime.now().strftime("%Y-%m-%dT%H:%M:%S"),
        "seed": args.seed,
        "command": shlex.join([".venv/bin/python", "bench/calibration_table2.py", *(argv or sys.argv[1:])]),
        "conditions": args.conditions,
        "machine": info,
        **run(args.seed, args.long_factor, args.long_cap, args.workers, args.evaluations),
    }
    data["cpu"] = meter.stop()
    args.out.mkdir(parents=True, exist_ok=True)
    harness.write_results("calibration_table2", markdown(data), data, out=args.out, keep=FINDINGS, echo=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
