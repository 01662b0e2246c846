"""NSGA-II convergence on BuildingWeek-v0: hypervolume after G generations against a 10x longer run.

One seeded run of ``factor x max(G)`` generations is made; pymoo draws the same random numbers whatever the
termination, so the first G generations of it *are* the G-generation run, and its hypervolume and wall time
after generation G are read from the run's history. For each G the gap is
``1 - HV(G) / HV(factor x G)``. Target: within 1 % in under 2 minutes on 2 cores.

Writes ``bench/results/nsga2_convergence.{md,json}``.
"""

from __future__ import annotations

import datetime as dt
import os
import platform

import gymnasium as gym
import harness

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from agents.nsga2 import pareto_front

PAPER_WEEK = 46  # the default site's first held-out week (2019-11-25)


def main() -> None:
    """Run the long NSGA-II and write the convergence table."""
    parser = harness.parser(__doc__)
    parser.add_argument(
        "--generations",
        default="150,300,500,1000,1500",
        help="comma-separated G to report (the run lasts factor x the largest)",
    )
    parser.add_argument("--factor", type=int, default=10)
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--week", type=int, default=PAPER_WEEK)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    gens = sorted(int(g) for g in args.generations.split(","))
    env = gym.make("BuildingWeek-v0")
    load = os.getloadavg()[0]
    run = pareto_front(
        env, args.week, population=args.population, generations=args.factor * gens[-1], seed=args.seed, progress=True
    )
    rows = []
    for g in gens:
        long = args.factor * g
        hv, hv_long = run.history[g - 1], run.history[long - 1]
        rows.append(
            {
                "generations": g,
                "evaluations": g * args.population,
                "seconds": round(run.history_seconds[g - 1], 1),
                "hypervolume": hv,
                "generations_long": long,
                "seconds_long": round(run.history_seconds[long - 1], 1),
                "hypervolume_long": hv_long,
                "gap_percent": round(100.0 * (1.0 - hv / hv_long), 3),
            }
        )
    command = "python bench/nsga2_convergence.py " + " ".join(
        f"--{k} {v}"
        for k, v in (
            ("generations", args.generations),
            ("factor", args.factor),
            ("population", args.population),
            ("week", args.week),
            ("seed", args.seed),
        )
    )
    result = {
        "date": dt.date.today().isoformat(),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "load_average_at_start": load,
        "command": command,
        "week": args.week,
        "rows": rows,
    }
    lines = [
        f"# NSGA-II convergence (week {args.week}, population {args.population}, seed {args.seed})",
        "",
        f"One run of {args.factor * gens[-1]} generations; G generations are its first G (same seed, same "
        "random stream). Target: gap within 1 % in under 2 minutes.",
        "",
        "| G | evaluations | seconds | HV(G) | 10 G seconds | HV(10 G) | gap % | target met |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ok = r["gap_percent"] <= 1.0 and r["seconds"] <= 120
        lines.append(
            f"| {r['generations']} | {r['evaluations']:,} | {r['seconds']} | {r['hypervolume']:.4f} | "
            f"{r['seconds_long']} | {r['hypervolume_long']:.4f} | {r['gap_percent']:.2f} | "
            f"{'yes' if ok else 'no'} |"
        )
    harness.write_results("nsga2_convergence", lines, result, echo=True)


if __name__ == "__main__":
    main()
