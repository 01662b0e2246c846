"""Wall time of a whole simulation campaign at the paper's scale (40,000 weeks) on this machine.

Runs ``buildenv simulate --weeks N --seed S --out DIR`` as a user would (all cores, progress bar off), from
an empty directory, and records the wall-clock time, weeks per second and the dataset size in
``bench/results/campaign_scale.md`` and ``.json``.

    .venv/bin/python bench/campaign_scale.py [--weeks 40000] [--seed 0] [--out data/campaign-40000] [--keep]

Without ``--keep`` the dataset is deleted afterwards; with it, it stays for training.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import harness

from buildenv.jsonio import dumps


def main() -> None:
    """Run the campaign and write the results files."""
    parser = harness.parser(__doc__)
    parser.add_argument("--weeks", type=int, default=40000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="data/campaign-40000")
    parser.add_argument("--keep", action="store_true", help="keep the dataset")
    args = parser.parse_args()
    out = Path(args.out)
    if out.exists():
        sys.exit(f"{out} exists: the benchmark times a campaign from scratch; remove it or pick another --out")
    cmd = [
        str(Path(sys.executable).with_name("buildenv")),
        "simulate",
        "--weeks",
        str(args.weeks),
        "--seed",
        str(args.seed),
        "--out",
        str(out),
        "--quiet",
    ]
    started = time.perf_counter()
    subprocess.run(cmd, check=True)
    seconds = time.perf_counter() - started
    manifest = json.loads((out / "manifest.json").read_text())
    size_mb = (out / "dataset.h5").stat().st_size / 2**20
    from buildenv.energyplus.runner import energyplus_version

    result = {
        "date": time.strftime("%Y-%m-%d"),
        "command": " ".join(["buildenv", *cmd[1:]]),
        "machine": {"platform": platform.platform(), "processor": platform.processor(), "cores": os.cpu_count()},
        "energyplus": energyplus_version(),
        "weeks": args.weeks,
        "runs": manifest["runs"],
        "climates": len(manifest["weather"]),
        "wall_seconds": round(seconds, 1),
        "wall_minutes": round(seconds / 60, 2),
        "weeks_per_second": round(args.weeks / seconds, 2),
        "weeks_per_second_per_core": round(args.weeks / seconds / (os.cpu_count() or 1), 2),
        "dataset_mb": round(size_mb, 1),
    }
    table_row = (
        f"| {args.weeks} | {result['runs']} | {result['climates']} | {result['wall_minutes']} min | "
        f"{result['weeks_per_second']} | {result['weeks_per_second_per_core']} | {result['dataset_mb']} MB |"
    )
    harness.write_results(
        "campaign_scale",
        f"""# Simulation campaign at the paper's scale

EnergyPlus {result["energyplus"]} (pyenergyplus-lbnl); the campaign's command: `{result["command"]}`.

| weeks | EnergyPlus runs | climates | wall time | weeks/s | weeks/s/core | dataset.h5 |
|---|---|---|---|---|---|---|
{table_row}

Target: under 30 minutes on a 2-core machine. The wall time includes planning,
worker start-up, every EnergyPlus run (one building-year of 52 weeks per run) and writing `dataset.h5`.
""",
        result,
    )
    print(dumps(result, where="the result", nonfinite="null", indent=2))
    if not args.keep:
        shutil.rmtree(out)


if __name__ == "__main__":
    main()
