"""How many hours before the week the metamodel should see: accuracy by day of the week, and speed.

The default sees the day before each week (24 context hours). A Monday's state also depends on the weekend
and on Friday, which that day does not show. This trains the shipped architecture with each ``--context``
(``buildenv train --context-hours``) on the same dataset, split and seeds, scores it on the held-out weather
weeks (the temperature RMSE of each day of the week, day 1 the Monday), then times ``predict`` of each, and
EnergyPlus, in the same run.

    .venv/bin/python bench/metamodel_context.py --data data/campaign-cp-10400-r13 [--contexts 24,48,72]
        [--seeds 0,1] [--epochs 30] [--runs data/bench-runs/context] [--name metamodel_context]

Finished runs are reused and unfinished ones resume (:func:`harness.trained`). Writes
``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import harness
import numpy as np
import torch
from harness import energyplus_weeks_per_second, shipped_transformer, speed_lines, surrogate_weeks_per_second, trained

from buildenv.jsonio import dumps

METRICS = ("loss", "r2_t_pooled", "r2_t", "rmse_t_celsius", "cv_rmse_q_percent")


def main() -> None:
    """Train, score, time and write the results."""
    parser = harness.parser(__doc__)
    parser.add_argument("--data", required=True, help="campaign directory (buildenv simulate --out)")
    parser.add_argument("--contexts", default="24,48,72", help="context hours to compare (whole days)")
    parser.add_argument("--seeds", default="0,1", help="seeds of the split and the weights, one run each")
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--batch-size", type=int, default=64)
    parser.add_argument("--runs", default="data/bench-runs/context", help="where the runs' checkpoints go")
    parser.add_argument("--eplus-weeks", type=int, default=1040, help="weeks EnergyPlus simulates for the timing")
    parser.add_argument("--weeks", type=int, default=4096, help="weeks per metamodel timing")
    parser.add_argument("--name", default="metamodel_context")
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 1)
    config = shipped_transformer()
    contexts = [int(c) for c in args.contexts.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    runs = Path(args.runs)
    rows = []
    for seed in seeds:
        for ctx in contexts:
            result = trained(
                f"ctx{ctx}_seed{seed}_e{args.epochs}",
                runs,
                args.data,
                "transformer",
                config,
                seed=seed,
                context_hours=ctx,
                epochs=args.epochs,
                batch_size=args.batch_size,
                progress=False,
            )
            test = result["test"]
            rows.append(
                {
                    "context_hours": ctx,
                    "seed": seed,
                    "train_weeks": result["train_weeks"],
                    "test_weeks": result["test_weeks"],
                    "seconds": result["seconds"],
                    **{m: round(test[m], 5) for m in METRICS},
                    "rmse_t_by_day": [round(v, 4) for v in test["rmse_t_celsius_by_day"]],
                }
            )
            print(dumps(rows[-1], where="a row", nonfinite="null"))
    eplus = energyplus_weeks_per_second(args.eplus_weeks, "core_perimeter")
    speed = {
        ctx: surrogate_weeks_per_second(args.weeks, 128, 3, str(runs / f"ctx{ctx}_seed{seeds[0]}_e{args.epochs}.pt"))
        for ctx in contexts
    }
    print({"energyplus": round(eplus, 1), **{c: round(v, 1) for c, v in speed.items()}})
    result = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "command": "bench/metamodel_context.py "
        + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items()),
        "config": config,
        "runs": rows,
        "energyplus_weeks_per_second": round(eplus, 2),
        "weeks_per_second": {str(c): round(v, 1) for c, v in speed.items()},
    }
    harness.write_results(args.name, _page(result, contexts, seeds, speed, eplus), result)


def _page(result: dict, contexts: list[int], seeds: list[int], speed: dict, eplus: float) -> str:
    rows = result["runs"]
    first = rows[0]
    lines = [
        "# Context hours of the metamodel: the first day's error and the speed",
        "",
        f"The shipped architecture (`{json.dumps(result['config'])}`) trained with each context on the same "
        f"campaign ({first['train_weeks']} training weeks for seed {first['seed']}), held-out weather weeks "
        "scored (`weather_weeks` split; each seed its own split). RMSE_T in degC; day 1 is the Monday.",
        "",
        "| context h | seed | test loss | R2_T pooled | R2_T per week | RMSE_T | RMSE_T day 1 | RMSE_T days 2-7 "
        "| CV(RMSE)_Q % | training s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        day = r["rmse_t_by_day"]
        rest = np.sqrt(np.mean(np.square(day[1:])))  # the days' RMSEs pooled (equal hours per day)
        lines.append(
            f"| {r['context_hours']} | {r['seed']} | {r['loss']:.4f} | {r['r2_t_pooled']:.4f} | "
            f"{r['r2_t']:.4f} | {r['rmse_t_celsius']:.4f} | {day[0]:.3f} | {rest:.3f} "
            f"| {r['cv_rmse_q_percent']:.2f} | {r['seconds']:.0f} |"
        )
    lines += speed_lines(speed, eplus, "context h")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
