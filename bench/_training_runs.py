"""Shared by the metamodel accuracy benchmarks: train (or reuse) one run and read its result.

A run is a checkpoint ``<runs>/<tag>.pt`` with its result ``<tag>.json`` beside it; a rerun of a benchmark
reuses finished runs and resumes unfinished ones (``<tag>.pt.last``), so a long benchmark survives a kill.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import time
from pathlib import Path

import torch

from buildenv import surrogate as sg
from buildenv.training import train_metamodel
from metamodels.models import build

RESULTS = Path(__file__).resolve().parent / "results"

# The default shipped until 2026-11-22 (8-hour tokens, 2+2 layers, hourly read-out): the learning curve's model.
PREVIOUS_TRANSFORMER = {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64}


def shipped_transformer() -> dict:
    """Architecture of the metamodel shipped in the package (README, "The default metamodel")."""
    return dict(sg.load_metamodel("default").checkpoint.config)


def run_tag(config: dict) -> str:
    """Short stable name of a model configuration (for run file names)."""
    return hashlib.sha1(json.dumps(config, sort_keys=True).encode()).hexdigest()[:8]


def trained(tag: str, runs: Path, data: str, model: str, config: dict, **options) -> dict:
    """Result of :func:`buildenv.training.train_metamodel` for this run, training it unless already done."""
    runs.mkdir(parents=True, exist_ok=True)
    result_path = runs / f"{tag}.json"
    if result_path.exists():
        return json.loads(result_path.read_text())
    result = train_metamodel(data, model, runs / f"{tag}.pt", model_config=config, **options)
    result_path.write_text(json.dumps(result) + "\n")
    return result


def inference_speed(model: str, config: dict, batch: int = sg.INFERENCE_BATCH, weeks: int = 4096,
                    repeats: int = 3) -> float:
    """Best-of-``repeats`` weeks per second of batched inference (all cores, random encoded weeks, eager
    PyTorch) for an architecture; weights do not matter."""
    return inference_speeds({"": (model, config)}, batch, weeks, repeats)[""]


def inference_speeds(archs: dict[str, tuple[str, dict]], batch: int = sg.INFERENCE_BATCH, weeks: int = 4096,
                     repeats: int = 3) -> dict[str, float]:
    """:func:`inference_speed` of several architectures (label -> (model, config)), timed in turn within each
    of ``repeats`` rounds, so that a slow spell of a shared machine falls on all of them alike."""
    torch.manual_seed(0)
    nets = {label: build(model, len(sg.INPUT_CHANNELS), 8, **config).eval() for label, (model, config) in archs.items()}
    x = torch.randn(weeks, sg.CONTEXT_HOURS + 168, len(sg.INPUT_CHANNELS))
    best = dict.fromkeys(nets, float("inf"))
    with torch.inference_mode():
        for net in nets.values():
            net(x[:batch])
        for _ in range(repeats):
            for label, net in nets.items():
                started = time.perf_counter()
                for start in range(0, weeks, batch):
                    net(x[start:start + batch])
                best[label] = min(best[label], time.perf_counter() - started)
    return {label: weeks / seconds for label, seconds in best.items()}


def machine() -> str:
    """One line describing this machine and torch."""
    return f"{platform.platform()}, {os.cpu_count()} cores, torch {torch.__version__}"


def mean_std(result: dict, key: str, scale: float = 1.0, digits: int = 3) -> str:
    """``"mean (std)"`` of a metric of a result's test block."""
    test = result["test"]
    return f"{test[key] * scale:.{digits}f} ({test[key + '_std'] * scale:.{digits}f})"


def speed_lines(speed: dict, eplus: float, label: str = "model") -> list[str]:
    """Markdown lines of a speed table: ``speed`` ``{name: weeks/s}`` of ``load_metamodel(CKPT).predict``
    against the core + perimeter EnergyPlus shoebox's ``eplus`` weeks/s, timed in the same run."""
    lines = ["", "Speed in the same run, `load_metamodel(CKPT).predict` of 4,096 weeks from catalogue arrays "
             "(encoding included, traced, batches of 128, best of 3), against the core + perimeter EnergyPlus "
             f"shoebox ({eplus:.1f} weeks/s):", "", f"| {label} | weeks/s | x EnergyPlus |", "|---|---|---|"]
    return lines + [f"| {name} | {value:,.0f} | {value / eplus:.0f} |" for name, value in speed.items()]
