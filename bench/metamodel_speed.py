"""Simulated weeks per second: metamodels vs the EnergyPlus shoebox, measured in one run on this machine.

EnergyPlus: ``buildenv simulate`` of ``--eplus-weeks`` weeks (one-year runs, all cores), timed end to end, for
each zoning of the shoebox (the single zone of the paper, the core + perimeter zones of the default).
Metamodels: batched inference (``torch.inference_mode``, all cores, ``--batch`` weeks per model call) of
each architecture/configuration on ``--weeks`` encoded weeks, eager PyTorch, best of ``--repeats``
timings. Speed does not depend on the weights, so untrained models are timed; accuracy belongs to
``bench/results/metamodels_table1.md``. Then the product path end to end: :meth:`Surrogate.predict` of
the shipped default checkpoint from catalogue arrays (encoding included, traced model), the call the
environment and calibration make, against the shoebox of the zoning that default was trained on. The
architecture table's ratios are against the paper's single zone.

    .venv/bin/python bench/metamodel_speed.py [--eplus-weeks 1040] [--weeks 4096] [--batch 128] [--repeats 3]

Writes ``bench/results/metamodel_speed.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from _training_runs import RESULTS, inference_speed

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.campaign import CampaignConfig, run_campaign
from buildenv.energyplus.shoebox import ZONINGS
from buildenv.sampling import sample_group, sample_weeks
from buildenv.weather import load_weather
from metamodels.models import build

CONFIGS: list[tuple[str, dict]] = [
    ("transformer", {}),  # the paper's: hourly tokens, 4+4 layers
    ("transformer", {"patch_hours": 4}),
    ("transformer", {"patch_hours": 6}),
    ("transformer", {"patch_hours": 8}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64, "hourly_state": 16}),
    ("bigru", {}), ("lstm", {}), ("convgru", {}), ("ffn", {}),
]


def energyplus_weeks_per_second(weeks: int, zoning: str) -> float:
    """Time a real campaign of ``weeks`` weeks of the ``zoning`` shoebox with all cores; weeks per second."""
    out = Path(tempfile.mkdtemp(prefix="bench-eplus-")) / "data"
    try:
        started = time.perf_counter()
        run_campaign(CampaignConfig(weeks=weeks, seed=0, epw=["usa_il_chicago", "usa_fl_miami"],
                                    zoning=zoning), out,
                     progress=False)
        return weeks / (time.perf_counter() - started)
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)


def surrogate_weeks_per_second(weeks: int, batch: int, repeats: int, checkpoint: str | None = None) -> float:
    """Best-of-``repeats`` speed of ``load_metamodel(checkpoint).predict`` on dataset-like catalogue arrays
    (``None``: the shipped default)."""
    rng = np.random.default_rng(0)
    surrogate = sg.load_metamodel(checkpoint)
    theta = sample_group("theta_build", weeks, rng)
    settings, occupancy = sample_weeks(weeks, rng)
    year = load_weather("usa_il_chicago").weeks(0, cat.WEEKS_PER_YEAR)
    weather = year[np.arange(weeks) % cat.WEEKS_PER_YEAR]
    ground = sg.ground_hours(sg.weather_ground_c("usa_il_chicago"), np.arange(weeks) % cat.WEEKS_PER_YEAR * 168,
                             surrogate.context_hours)
    surrogate.predict(theta[:batch], settings[:batch], occupancy[:batch], weather[:batch], ground_c=ground[:batch])
    best = float("inf")
    for _ in range(repeats):
        started = time.perf_counter()
        surrogate.predict(theta, settings, occupancy, weather, batch_size=batch, ground_c=ground)
        best = min(best, time.perf_counter() - started)
    return weeks / best


def main() -> None:
    """Measure and write the results."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--eplus-weeks", type=int, default=1040)
    parser.add_argument("--weeks", type=int, default=4096, help="weeks per timing")
    parser.add_argument("--batch", type=int, default=sg.INFERENCE_BATCH, help="weeks per model call")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--checkpoint", action="append", metavar="LABEL=PATH",
                        help="also time the product path of this checkpoint (repeatable; the shipped default always)")
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 1)
    eplus_by_zoning = {z: energyplus_weeks_per_second(args.eplus_weeks, z) for z in ZONINGS}
    print({z: round(v, 2) for z, v in eplus_by_zoning.items()})
    eplus = eplus_by_zoning["single"]
    rows = []
    for name, config in CONFIGS:
        speed = inference_speed(name, config, args.batch, args.weeks, args.repeats)
        params = sum(p.numel() for p in build(name, len(sg.INPUT_CHANNELS), 8, **config).parameters())
        rows.append({"model": name, "config": config, "parameters": params, "weeks_per_second": round(speed, 1),
                     "speedup_vs_energyplus": round(speed / eplus, 1)})
        print(f"{name:12s} {json.dumps(config):45s} {speed:9.1f} weeks/s  x{speed / eplus:6.1f}")
    result = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.platform()}, {os.cpu_count()} cores",
              "torch": torch.__version__, "command": "bench/metamodel_speed.py " + " ".join(
                  f"--{k.replace('_', '-')} {x}" for k, v in vars(args).items() if v is not None
                  for x in (v if isinstance(v, list) else [v])),
              "energyplus_weeks_per_second": round(eplus, 2),
              "energyplus_weeks_per_second_by_zoning": {z: round(v, 2) for z, v in eplus_by_zoning.items()},
              "models": rows}
    products = ([("shipped default", None)] if sg.DEFAULT_CHECKPOINT.is_file() else []) + [
        (item.partition("=")[0], item.partition("=")[2]) for item in args.checkpoint or []]
    result["product_path"] = []
    for label, path in products:
        speed = surrogate_weeks_per_second(args.weeks, args.batch, args.repeats, path)
        surrogate = sg.load_metamodel(path)
        reference = eplus_by_zoning[surrogate.zoning]
        result["product_path"].append({"label": label, "checkpoint": path or "default",
                                       "config": surrogate.checkpoint.config, "zoning": surrogate.zoning,
                                       "weeks_per_second": round(speed, 1),
                                       "speedup_vs_energyplus": round(speed / reference, 1)})
        print(f"{label}: load_metamodel().predict (encoding included, traced): {speed:9.1f} weeks/s  "
              f"x{speed / reference:6.1f} ({surrogate.zoning} shoebox)")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "metamodel_speed.json").write_text(json.dumps(result, indent=2) + "\n")
    lines = [f"# Metamodel vs EnergyPlus speed ({result['date']})", "",
             f"Machine: {result['machine']}; torch {result['torch']}. Command: `.venv/bin/python "
             f"{result['command']}`.", "",
             f"EnergyPlus shoebox, `buildenv simulate` of {args.eplus_weeks} weeks on all cores: "
             + ", ".join(f"{z} zoning **{v:.1f} weeks/s**" for z, v in eplus_by_zoning.items()) + ".", "",
             f"Metamodels, inference of {args.weeks} encoded weeks (192 hours x {len(sg.INPUT_CHANNELS)} inputs) in "
             f"calls of {args.batch} weeks, eager PyTorch, all cores, best of the repeats (x EnergyPlus: against the "
             "single zone):", "",
             "| model | config | parameters | weeks/s | x EnergyPlus |", "|---|---|---|---|---|"]
    lines += [f"| {r['model']} | `{json.dumps(r['config'])}` | {r['parameters']} | {r['weeks_per_second']} | "
              f"{r['speedup_vs_energyplus']} |" for r in rows]
    for d in result["product_path"]:
        lines += ["", f"The product path, {d['label']}: `buildenv.load_metamodel({d['checkpoint']!r}).predict(theta, "
                  f"settings, occupancy, weather, ground_c=ground)` (`{json.dumps(d['config'])}`), {args.weeks} weeks "
                  "from catalogue arrays, encoding and standardisation included, traced model: "
                  f"**{d['weeks_per_second']} weeks/s, "
                  f"{d['speedup_vs_energyplus']}x the {d['zoning']} EnergyPlus shoebox it was trained on** "
                  f"({d['weeks_per_second'] / eplus:.1f}x the single zone)."]
    (RESULTS / "metamodel_speed.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
