"""Fine-tuning the shipped metamodel with a longer context: the first day's error, the pooled R2_T, the speed.

Retraining the default with ``--context-hours 72`` from scratch takes its 160,000-week campaign and hours of
training. This starts from the shipped weights instead (``buildenv train --init default``) and trains them
further on a smaller, new campaign, once per context; the 24-hour run is the control (the same further
training, no longer context), so that what the context buys is told apart from what more training buys.

The test weeks are the campaign's held-out weather weeks (the ``weather_weeks`` split, seed 0, Newark held
out): the same weather weeks the default was scored on, because the split draws from the sorted set of
(climate, week of year) pairs and a campaign of this size holds every pair (checked here), so the default
never trained on them either. Their buildings are new to every model. Scored on them: the default as
shipped, then each fine-tuned run; then the speed of each against EnergyPlus in the same run.

    .venv/bin/python bench/metamodel_finetune_context.py --data data/campaign-cp-40000-s7 [--contexts 24,48,72]
        [--epochs 15] [--lr 3e-4] [--runs data/bench-runs/finetune] [--name metamodel_finetune_context]

Finished runs are reused and unfinished ones resume (``bench/_training_runs.py``). Writes
``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch
from _training_runs import RESULTS, speed_lines, trained
from metamodel_speed import energyplus_weeks_per_second, surrogate_weeks_per_second

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import score

METRICS = ("loss", "r2_t_pooled", "r2_q_pooled", "r2_t", "rmse_t_celsius", "cv_rmse_q_percent")
HOLDOUT = "usa_nj_newark"


def _summary(scores: dict) -> dict:
    day = scores["rmse_t_celsius_by_day"]
    return {**{m: round(scores[m], 5) for m in METRICS}, "rmse_t_by_day": [round(v, 4) for v in day],
            "rmse_t_day1": round(day[0], 4), "rmse_t_days2_7": round(float(np.sqrt(np.mean(np.square(day[1:])))), 4)}


def _default_scores(data: str, init: str) -> tuple[dict, dict, int]:
    """The starting checkpoint as it is, on the test weeks and on the held-out climate, and the number of
    (climate, week of year) pairs in the campaign."""
    surrogate = sg.load_metamodel(init)
    with open_dataset(data) as ds:
        pairs = len(np.unique(ds._h5["weather_index"][:].astype(np.int64) * 100 + ds._h5["week_of_year"][:]))
        if pairs != len(ds.weather_names) * cat.WEEKS_PER_YEAR:
            raise SystemExit(f"{data} holds {pairs} (climate, week) pairs, not all "
                             f"{len(ds.weather_names) * cat.WEEKS_PER_YEAR}: its weather_weeks split would not be "
                             "the default's; simulate more weeks")
        parts = ds.split("weather_weeks", seed=0, holdout_climates=[HOLDOUT])
        test = sg.encode_dataset(ds, parts["test"], context_hours=surrogate.context_hours,
                                  temperature_before=surrogate.uses_temperature_before)
        apart = sg.encode_dataset(ds, parts["holdout_climate"], context_hours=surrogate.context_hours,
                                  temperature_before=surrogate.uses_temperature_before)
    return score(surrogate, *test), score(surrogate, *apart), pairs


def main() -> None:
    """Fine-tune, score, time and write the results."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="a new campaign (buildenv simulate --out), not the default's")
    parser.add_argument("--init", default="default", help="checkpoint to start from")
    parser.add_argument("--contexts", default="24,48,72", help="context hours to compare (whole days)")
    parser.add_argument("--epochs", type=int, default=15)
    parser.add_argument("--lr", type=float, default=3e-4, help="initial learning rate (cosine to 0)")
    parser.add_argument("--batch-size", type=int, default=64)
    parser.add_argument("--runs", default="data/bench-runs/finetune", help="where the runs' checkpoints go")
    parser.add_argument("--eplus-weeks", type=int, default=1040, help="weeks EnergyPlus simulates for the timing")
    parser.add_argument("--weeks", type=int, default=4096, help="weeks per metamodel timing")
    parser.add_argument("--name", default="metamodel_finetune_context")
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 1)
    contexts = [int(c) for c in args.contexts.split(",")]
    runs = Path(args.runs)
    test, apart, pairs = _default_scores(args.data, args.init)
    rows = [{"run": f"{args.init} as is", "context_hours": sg.load_metamodel(args.init).context_hours,
             "test": _summary(test), "newark": _summary(apart)}]
    print(json.dumps(rows[-1]))
    tags = {}
    for ctx in contexts:
        tags[ctx] = f"ft{ctx}_e{args.epochs}_lr{args.lr:g}"
        result = trained(tags[ctx], runs, args.data, "transformer", None, seed=0, holdout_climates=[HOLDOUT],
                         context_hours=ctx, init=args.init, epochs=args.epochs, lr=args.lr,
                         batch_size=args.batch_size, progress=False)
        rows.append({"run": f"fine-tuned, {ctx} h", "context_hours": ctx, "train_weeks": result["train_weeks"],
                     "test_weeks": result["test_weeks"], "seconds": result["seconds"],
                     "best_epoch": result["fit"]["best_epoch"], "test": _summary(result["test"]),
                     "newark": _summary(result["holdout_climate"])})
        print(json.dumps(rows[-1]))
    eplus = energyplus_weeks_per_second(args.eplus_weeks, "core_perimeter")
    speed = {"as is": surrogate_weeks_per_second(args.weeks, 128, 3, args.init)}
    speed.update({f"{c} h": surrogate_weeks_per_second(args.weeks, 128, 3, str(runs / f"{tags[c]}.pt"))
                  for c in contexts})
    print({"energyplus": round(eplus, 1), **{c: round(v, 1) for c, v in speed.items()}})
    result = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.platform()}, {os.cpu_count()} cores",
              "command": "bench/metamodel_finetune_context.py " + " ".join(f"--{k.replace('_', '-')} {v}"
                                                                           for k, v in vars(args).items()),
              "init": args.init, "weather_week_pairs": pairs, "runs": rows, "energyplus_weeks_per_second": round(eplus, 2),
              "weeks_per_second": {c: round(v, 1) for c, v in speed.items()}}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (RESULTS / f"{args.name}.md").write_text(_page(result, speed, eplus))


def _page(result: dict, speed: dict, eplus: float) -> str:
    rows = result["runs"]
    tuned = rows[1]
    lines = [f"# Fine-tuning the default with a longer context ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"Each fine-tuned run starts from the weights and normalisation of `{result['init']}` (`buildenv "
             f"train --init {result['init']}`) and trains on {tuned['train_weeks']:,} weeks of a new campaign"
             + ("; the 24-hour run is the control" if any(r["context_hours"] == 24 for r in rows[1:]) else "")
             + f". Test: {tuned['test_weeks']:,} weeks of held-out weather weeks (the default's, all "
             f"{result['weather_week_pairs']} (climate, week) pairs present) on buildings new to every model; "
             f"Newark: the climate none of them trained on. RMSE_T in degC, day 1 the Monday.", "",
             "| run | test loss | R2_T pooled | R2_Q pooled | RMSE_T | day 1 | days 2-7 | CV(RMSE)_Q % "
             "| Newark loss | Newark R2_T pooled | Newark RMSE_T |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        t, n = r["test"], r["newark"]
        lines.append(f"| {r['run']} | {t['loss']:.4f} | {t['r2_t_pooled']:.4f} | {t['r2_q_pooled']:.4f} | "
                     f"{t['rmse_t_celsius']:.4f} | {t['rmse_t_day1']:.3f} | {t['rmse_t_days2_7']:.3f} | "
                     f"{t['cv_rmse_q_percent']:.2f} | {n['loss']:.4f} | {n['r2_t_pooled']:.4f} | "
                     f"{n['rmse_t_celsius']:.4f} |")
    lines += speed_lines(speed, eplus, "model")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
