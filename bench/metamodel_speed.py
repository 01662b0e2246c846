"""Simulated weeks per second: metamodels vs the EnergyPlus shoebox, measured in one run on this machine.

EnergyPlus: ``buildenv simulate`` of ``--eplus-weeks`` weeks (one-year runs, all cores), timed end to end, for
each zoning of the shoebox (the single zone of the paper, the core + perimeter zones of the default).
Metamodels: batched inference (``torch.inference_mode``, all cores, ``--batch`` weeks per model call) of
each architecture/configuration on ``--weeks`` encoded weeks, eager PyTorch, best of ``--repeats``
timings. Speed does not depend on the weights, so untrained models are timed; accuracy belongs to
``bench/results/metamodel_table.md``. Then the product path end to end: :meth:`Surrogate.predict` of
the shipped default checkpoint from catalogue arrays (encoding included, traced model), the call the
environment and calibration make, against the shoebox of the zoning that default was trained on, with its
model calls spread over worker threads (the default) and with torch alone (``workers=1``). The
architecture table's ratios are against the paper's single zone.

A shared machine has slow spells that last minutes, and EnergyPlus and the metamodel need not meet the same one:
the product path and EnergyPlus are timed in ``--rounds`` alternating rounds, each round's ratio is taken
within it, and the page gives every round and their median.

    .venv/bin/python bench/metamodel_speed.py [--eplus-weeks 1040] [--weeks 4096] [--batch 64] [--repeats 3] \
        [--rounds 3]

Writes ``bench/results/metamodel_speed.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import harness
import numpy as np
import torch
from harness import energyplus_weeks_per_second, inference_speed, predict_weeks_per_second, product_arrays

from buildenv.energyplus.shoebox import ZONINGS
from buildenv.metamodel import surrogate as sg
from metamodels.models import build

CONFIGS: list[tuple[str, dict]] = [
    ("transformer", {}),  # the paper's: hourly tokens, 4+4 layers
    ("transformer", {"patch_hours": 4}),
    ("transformer", {"patch_hours": 6}),
    ("transformer", {"patch_hours": 8}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64}),
    ("transformer", {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64, "hourly_state": 16}),
    ("bigru", {}),
    ("lstm", {}),
    ("convgru", {}),
    ("ffn", {}),
]


def main() -> None:
    """Measure and write the results."""
    parser = harness.parser(__doc__)
    parser.add_argument("--eplus-weeks", type=int, default=1040)
    parser.add_argument("--weeks", type=int, default=4096, help="weeks per timing")
    parser.add_argument("--batch", type=int, default=sg.INFERENCE_BATCH, help="weeks per model call")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--rounds",
        type=int,
        default=3,
        help="alternating rounds of EnergyPlus and the product path (each round's ratio within it)",
    )
    parser.add_argument(
        "--checkpoint",
        action="append",
        metavar="LABEL=PATH",
        help="also time the product path of this checkpoint (repeatable; the shipped default always)",
    )
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 1)
    products = ([("shipped default", None)] if sg.DEFAULT_CHECKPOINT.is_file() else []) + [
        (item.partition("=")[0], item.partition("=")[2]) for item in args.checkpoint or []
    ]
    loaded = [(label, path, sg.load_metamodel(path)) for label, path in products]
    arrays = [product_arrays(surrogate, args.weeks) for _, _, surrogate in loaded]
    rounds = []
    for number in range(args.rounds):
        eplus_round = {z: energyplus_weeks_per_second(args.eplus_weeks, z) for z in ZONINGS}
        speeds = []
        for (_label, _, surrogate), weeks in zip(loaded, arrays):
            speeds.append(
                {
                    name: predict_weeks_per_second(surrogate, weeks, args.batch, args.repeats, workers)
                    for name, workers in (("workers", None), ("torch_alone", 1))
                }
            )
        rounds.append({"energyplus_weeks_per_second": eplus_round, "product_path": speeds})
        print(
            f"round {number + 1}: EnergyPlus { ({z: round(v, 1) for z, v in eplus_round.items()}) }, "
            + "; ".join(
                f"{label} {s['workers']:.0f} weeks/s ({s['torch_alone']:.0f} torch alone)"
                for (label, _, _), s in zip(loaded, speeds)
            )
        )
    eplus_by_zoning = {z: float(np.median([r["energyplus_weeks_per_second"][z] for r in rounds])) for z in ZONINGS}
    eplus = eplus_by_zoning["single"]
    rows = []
    for name, config in CONFIGS:
        speed = inference_speed(name, config, args.batch, args.weeks, args.repeats)
        params = sum(p.numel() for p in build(name, len(sg.INPUT_CHANNELS), 8, **config).parameters())
        rows.append(
            {
                "model": name,
                "config": config,
                "parameters": params,
                "weeks_per_second": round(speed, 1),
                "speedup_vs_energyplus": round(speed / eplus, 1),
            }
        )
        print(f"{name:12s} {json.dumps(config):45s} {speed:9.1f} weeks/s  x{speed / eplus:6.1f}")
    result = {
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "torch": torch.__version__,
        "command": "bench/metamodel_speed.py "
        + " ".join(
            f"--{k.replace('_', '-')} {x}"
            for k, v in vars(args).items()
            if v is not None
            for x in (v if isinstance(v, list) else [v])
        ),
        "energyplus_weeks_per_second": round(eplus, 2),
        "energyplus_weeks_per_second_by_zoning": {z: round(v, 2) for z, v in eplus_by_zoning.items()},
        "rounds": rounds,
        "models": rows,
        "product_path": [],
    }
    for i, (label, path, surrogate) in enumerate(loaded):
        entry = {
            "label": label,
            "checkpoint": path or "default",
            "config": surrogate.checkpoint.config,
            "zoning": surrogate.zoning,
        }
        for name in ("workers", "torch_alone"):
            ratios = [r["product_path"][i][name] / r["energyplus_weeks_per_second"][surrogate.zoning] for r in rounds]
            speeds = [r["product_path"][i][name] for r in rounds]
            entry[name] = {
                "weeks_per_second": round(float(np.median(speeds)), 1),
                "speedup_vs_energyplus": round(float(np.median(ratios)), 1),
                "speedup_by_round": [round(x, 1) for x in ratios],
            }
        result["product_path"].append(entry)
        print(
            f"{label}: load_metamodel().predict (encoding included, traced): median "
            f"x{entry['workers']['speedup_vs_energyplus']} the {surrogate.zoning} shoebox "
            f"(rounds {entry['workers']['speedup_by_round']}); "
            f"torch alone x{entry['torch_alone']['speedup_vs_energyplus']}"
        )
    harness.write_results("metamodel_speed", page_lines(result, args), result)


def page_lines(result: dict, args: argparse.Namespace) -> list[str]:
    """The Markdown page of a :func:`main` result."""
    zonings = list(result["energyplus_weeks_per_second_by_zoning"])
    lines = ["# Metamodel vs EnergyPlus speed", "", f"torch {result['torch']}.", ""]
    for entry in result["product_path"]:
        w, alone = entry["workers"], entry["torch_alone"]
        lines += [
            f"**The product path, {entry['label']}** (`buildenv.load_metamodel({entry['checkpoint']!r}).predict("
            f"theta, settings, occupancy, weather, ground_c=ground)`, `{json.dumps(entry['config'])}`, "
            f"{args.weeks} weeks from catalogue arrays in calls of {args.batch}, encoding and standardisation "
            f"included, traced model): **{w['speedup_vs_energyplus']}x the {entry['zoning']} EnergyPlus shoebox "
            f"it was trained on**, the median of {len(w['speedup_by_round'])} rounds "
            f"({', '.join(f'{x}x' for x in w['speedup_by_round'])}), {w['weeks_per_second']} weeks/s; "
            f"with torch alone (`workers=1`) {alone['speedup_vs_energyplus']}x "
            f"({', '.join(f'{x}x' for x in alone['speedup_by_round'])}), {alone['weeks_per_second']} "
            "weeks/s.",
            "",
        ]
    lines += [
        "EnergyPlus and the product path, round by round (weeks/s; the product path best of "
        f"{args.repeats} timings; EnergyPlus `buildenv simulate` of {args.eplus_weeks} weeks on all cores):",
        "",
        "| round | "
        + " | ".join(f"EnergyPlus {z}" for z in zonings)
        + " | "
        + " | ".join(f"{e['label']}, workers | torch alone" for e in result["product_path"])
        + " |",
        "|---" * (1 + len(zonings) + 2 * len(result["product_path"])) + "|",
    ]
    for number, r in enumerate(result["rounds"], 1):
        lines.append(
            f"| {number} | "
            + " | ".join(f"{r['energyplus_weeks_per_second'][z]:.1f}" for z in zonings)
            + " | "
            + " | ".join(f"{s['workers']:.0f} | {s['torch_alone']:.0f}" for s in r["product_path"])
            + " |"
        )
    lines += [
        "",
        f"Architectures, inference of {args.weeks} encoded weeks (192 hours x {len(sg.INPUT_CHANNELS)} "
        f"inputs) in calls of {args.batch} weeks, eager PyTorch, all cores, best of the repeats (x EnergyPlus: "
        f"against the single zone's median, {result['energyplus_weeks_per_second']} weeks/s):",
        "",
        "| model | config | parameters | weeks/s | x EnergyPlus |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['model']} | `{json.dumps(r['config'])}` | {r['parameters']} | {r['weeks_per_second']} | "
        f"{r['speedup_vs_energyplus']} |"
        for r in result["models"]
    ]
    return lines


if __name__ == "__main__":
    main()
