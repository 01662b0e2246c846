"""Does the unseen climate's penalty go if the metamodel is told the ground temperature? A against G.

``bench/results/metamodel_climate_holdout.md`` found that a model which never trained on Newark errs 1.26x one
that did, mostly in the level of each week, and ``ground_temperature_probe.md`` that the shoebox's ground
(annual mean + 0.3 x (last month's mean - annual mean), ``buildenv.energyplus.shoebox.ground_temperatures_c``)
moves that level by the right amount. The metamodel has no input for it. G is model A of that benchmark (the
shipped architecture, 48 context hours, the same 29,000 training weeks of the same split, 20 epochs, seed 0,
Newark held out) with one input channel more: the ground temperature under the slab in each hour (degC), from
the campaign's weather file, as EnergyPlus had it. Both are scored on every Newark week and on the other
climates' test weeks, paired per week.

G's inputs are the product's encoding (``buildenv.surrogate.encode_dataset``, whose last channel is this
ground temperature since this measurement made it one); A, trained without it, is given the other channels.

    .venv/bin/python bench/ground_input.py --data data/campaign-cp-40000-s7
        [--runs data/bench-runs/climate-holdout] [--name metamodel_ground_input]

Needs A of ``bench/climate_holdout.py`` (same ``--runs``). Writes ``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import torch
from _training_runs import RESULTS, machine, run_tag, shipped_transformer
from climate_holdout import level_and_shape, level_and_shape_rows, paired, week_errors

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import standardised_tensors, training_split
from metamodels.checkpoint import Checkpoint, load_checkpoint
from metamodels.models import build
from metamodels.normalisation import Standardiser
from metamodels.train import TrainConfig, fit


def main() -> None:
    """Train G (or resume it), score A and G, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True)
    parser.add_argument("--holdout", default="usa_nj_newark")
    parser.add_argument("--epochs", type=int, default=20)
    parser.add_argument("--max-weeks", type=int, default=29000)
    parser.add_argument("--context-hours", type=int, default=48)
    parser.add_argument("--runs", default="data/bench-runs/climate-holdout")
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                        help="torch threads (1 when another job holds a core: more than the free cores thrash)")
    parser.add_argument("--name", default="metamodel_ground_input")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config, ctx, runs = shipped_transformer(), args.context_hours, Path(args.runs)
    suffix = f"{run_tag(config)}-{args.max_weeks}-e{args.epochs}-c{ctx}"
    a_path, g_path = runs / f"A-{suffix}.pt", runs / f"G-{suffix}.pt"
    if not a_path.exists():
        raise SystemExit(f"{a_path} missing: run bench/climate_holdout.py with the same --runs first")
    started = time.perf_counter()
    with open_dataset(args.data) as ds:
        parts = training_split(ds, "weather_weeks", 0, [args.holdout], args.max_weeks)
        test = ds.split("weather_weeks", seed=0)["test"]
        held = ds._h5["weather_index"][:][test] == ds.weather_names.index(args.holdout)
        sets = {"holdout_test": test[held], "holdout_all": parts["holdout_climate"], "others": test[~held]}
        if not g_path.exists():
            x_tr, y_tr = sg.encode_dataset(ds, parts["train"], context_hours=ctx)
            x_va, y_va = sg.encode_dataset(ds, parts["val"], context_hours=ctx)
            torch.manual_seed(0)
            net = build("transformer", x_tr.shape[-1], y_tr.shape[-1], **config)
            meta = {**sg.metadata(ctx), "split": "weather_weeks", "split_seed": 0, "holdout_climates": [args.holdout]}
            ck = Checkpoint("transformer", dict(config), net, Standardiser.fit(x_tr), Standardiser.fit(y_tr), meta)
            cfg = TrainConfig(seed=0, epochs=args.epochs, patience=args.epochs,
                              temperature_channels=sg.TEMPERATURE_CHANNELS,
                              consumption_channels=sg.CONSUMPTION_CHANNELS)
            mask = torch.tensor([False] * ctx + [True] * cat.HOURS_PER_WEEK)
            fit(ck, *standardised_tensors(x_tr, y_tr, ck), *standardised_tensors(x_va, y_va, ck), mask, cfg,
                g_path, True)
            del x_tr, y_tr, x_va, y_va
        models = {"A": sg.Surrogate(load_checkpoint(a_path), jit=False),
                  "G": sg.Surrogate(load_checkpoint(g_path), jit=False)}
        errors = {}
        for part, idx in sets.items():
            x, y = sg.encode_dataset(ds, idx, context_hours=ctx)
            errors[part] = {"A": week_errors(models["A"], x, y), "G": week_errors(models["G"], x, y)}
    result = {"date": time.strftime("%Y-%m-%d"), "machine": machine(), "seconds": round(time.perf_counter() - started),
              "command": "bench/ground_input.py " + " ".join(f"--{k.replace('_', '-')} {v}"
                                                             for k, v in vars(args).items()),
              "config": config, "holdout": args.holdout, "train_weeks": int(len(parts["train"])), "parts": {}}
    for part, errs in errors.items():
        result["parts"][part] = {"weeks": int(len(sets[part])),
                                 "rmse_t": {k: round(float(np.sqrt(e["sq_t"].mean())), 4) for k, e in errs.items()},
                                 "cv_q": {k: round(float(e["cv_q"].mean()), 3) for k, e in errs.items()},
                                 "error_split": {k: level_and_shape(e, slice(None)) for k, e in errs.items()},
                                 "g_minus_a": paired(errs["G"]["sq_t"], errs["A"]["sq_t"], args.resamples, 0)}
    print(json.dumps({k: v["g_minus_a"] for k, v in result["parts"].items()}))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (RESULTS / f"{args.name}.md").write_text(_page(result))


def _page(result: dict) -> str:
    held = result["holdout"]
    labels = {"holdout_test": f"{held}, its held-out weather weeks", "holdout_all": f"{held}, every week",
              "others": "other climates, held-out weather weeks"}
    lines = [f"# The ground temperature as an input: the unseen climate with and without it ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"A: the shipped architecture `{json.dumps(result['config'])}` trained on {result['train_weeks']:,} weeks "
             f"with {held} held out (`bench/climate_holdout.py`). G: the same weeks, epochs and seed, with the ground "
             "temperature under the slab as one more input channel. Neither saw any week scored here. RMSE_T in "
             "degC; paired: G minus A, per-week squared temperature error (degC2), 95 % bootstrap range over weeks.",
             "", "| test weeks | weeks | RMSE_T A | RMSE_T G | CV_Q % A | CV_Q % G | G - A | range | RMSE ratio G/A "
             "| range | G lower on |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for part, label in labels.items():
        r, p = result["parts"][part], result["parts"][part]["g_minus_a"]
        lines.append(f"| {label} | {r['weeks']} | {r['rmse_t']['A']:.3f} | {r['rmse_t']['G']:.3f} | "
                     f"{r['cv_q']['A']:.2f} | {r['cv_q']['G']:.2f} | {p['a_minus_b_degc2']:+.5f} | "
                     f"{p['a_minus_b_range_95'][0]:+.5f} to {p['a_minus_b_range_95'][1]:+.5f} | "
                     f"{p['rmse_ratio']:.3f} | "
                     f"{p['rmse_ratio_range_95'][0]:.3f}-{p['rmse_ratio_range_95'][1]:.3f} | "
                     f"{100 * p['share_a_lower']:.0f} % |")
    lines += ["", f"The error on {labels['holdout_test']}: the weeks' level missed and their shape missed (degC2; "
              "mean error degC):", ""]
    lines += level_and_shape_rows(result["parts"]["holdout_test"]["error_split"])
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
