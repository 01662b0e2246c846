"""How metamodels do on buildings they never saw: their own test split, a fresh campaign, an unseen climate.

A week held out of training by the ``weather_weeks`` split still comes from a building (an EnergyPlus run)
whose other weeks were trained on; a calibrated site's building is always new. This bench scores each
checkpoint, in one run, on

- ``own test``: the checkpoint's own held-out weeks on its training dataset (``--data``, optional);
- ``fresh buildings``: every week of an independent campaign (``--fresh``, another seed: buildings, settings
  and occupancy never seen; made with ``buildenv simulate`` if the folder does not exist yet);
- ``unseen climate``: the weeks of the climates the checkpoint kept out of training, in the fresh campaign;
- ``settings draws``: every week of a campaign of new buildings each simulated under several settings (``--pairs``,
  made with ``buildenv simulate --settings-draws 4`` if missing), with the response to settings: the savings of each
  week against the same week under its group's first settings, predicted against simulated.

    .venv/bin/python bench/metamodel_generalisation.py --model shipped=default \
        --model new=data/runs/new.pt --fresh data/campaign-cp-fresh-seed1 [--fresh-weeks 4160 --fresh-seed 1] \
        [--pairs data/campaign-pairs-4160-s28 --pairs-seed 28]

Writes ``bench/results/metamodel_generalisation.{md,json}`` (``--name`` changes the stem).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import harness
import numpy as np
from harness import machine

from buildenv.campaign.dataset import open_dataset
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.training import evaluate_metamodel, score

COLUMNS = [
    ("loss", "loss", 1.0, 4),
    ("R2_T per week", "r2_t", 1.0, 4),
    ("R2_T pooled", "r2_t_pooled", 1.0, 4),
    ("R2_Q per week", "r2_q", 1.0, 4),
    ("R2_Q pooled", "r2_q_pooled", 1.0, 4),
    ("RMSE_T degC", "rmse_t_celsius", 1.0, 3),
    ("CV(RMSE)_Q %", "cv_rmse_q_percent", 1.0, 2),
    ("RMSE_T day 1 / days 2-7", "day1_ratio", 1.0, 2),
    ("savings error p90, points", "response_savings_error_p90_abs_points", 1.0, 2),
    ("savings error mean, points", "response_savings_error_mean_abs_points", 1.0, 2),
    ("savings Spearman", "response_savings_spearman", 1.0, 3),
]


def simulate(out: Path, weeks: int, seed: int, weeks_per_run: int, *extra: str) -> None:
    """Make the campaign ``out`` with ``buildenv simulate`` unless it is already complete."""
    if (out / "manifest.json").is_file():
        return
    words = ["simulate", "--weeks", str(weeks), "--seed", str(seed), "--weeks-per-run", str(weeks_per_run)]
    subprocess.run([str(Path(sys.executable).with_name("buildenv")), *words, *extra, "--out", str(out)], check=True)


def with_day1_ratio(scores: dict) -> dict:
    """``scores`` with ``day1_ratio``: the first day's RMSE_T over the mean of the other six days'."""
    by_day = np.asarray(scores["rmse_t_celsius_by_day"], float)
    return scores | {"day1_ratio": float(by_day[0] / by_day[1:].mean())}


def fresh_scores(checkpoint: str, fresh: Path) -> dict[str, dict]:
    """Scores on every week of ``fresh`` and, apart, on the weeks of climates the checkpoint never saw."""
    surrogate = sg.load_metamodel(None if checkpoint == "default" else checkpoint)
    unseen = surrogate.checkpoint.metadata.get("holdout_climates") or []
    with open_dataset(fresh) as ds:
        x, y = sg.encode_dataset(
            ds,
            np.arange(len(ds)),
            context_hours=surrogate.context_hours,
            temperature_before=surrogate.uses_temperature_before,
        )
        climate = ds.weather_index[:]
        unseen_ids = [ds.weather_names.index(c) for c in unseen if c in ds.weather_names]
    out = {"fresh buildings": score(surrogate, x, y) | {"weeks": len(x)}}
    apart = np.isin(climate, unseen_ids)
    if apart.any():
        out["unseen climate"] = score(surrogate, x[apart], y[apart]) | {"weeks": int(apart.sum()), "climates": unseen}
    return out


def main() -> None:
    """Score every ``--model`` on every test set and write the table."""
    parser = harness.parser(__doc__)
    parser.add_argument(
        "--model",
        action="append",
        required=True,
        metavar="LABEL=CHECKPOINT",
        help="a checkpoint path or 'default' (repeatable)",
    )
    parser.add_argument("--data", help="the checkpoints' training dataset, for their own test split")
    parser.add_argument("--fresh", required=True, help="campaign of new buildings (made if missing)")
    parser.add_argument("--fresh-weeks", type=int, default=4160)
    parser.add_argument("--fresh-seed", type=int, default=1)
    parser.add_argument("--fresh-weeks-per-run", type=int, default=13, help="13: four buildings a year of weeks")
    parser.add_argument("--pairs", help="campaign of new buildings under 4 settings draws each (made if missing)")
    parser.add_argument("--pairs-seed", type=int, default=28)
    parser.add_argument("--name", default="metamodel_generalisation")
    args = parser.parse_args()
    fresh = Path(args.fresh)
    simulate(fresh, args.fresh_weeks, args.fresh_seed, args.fresh_weeks_per_run)
    if args.pairs:
        pair_words = ("--settings-draws", "4", "--zoning", "core_perimeter", "--floor-area-scale", "log")
        simulate(Path(args.pairs), args.fresh_weeks, args.pairs_seed, args.fresh_weeks_per_run, *pair_words)
    manifest = json.loads((fresh / "manifest.json").read_text())
    results: dict[str, dict] = {}
    for item in args.model:
        label, _, checkpoint = item.partition("=")
        print(f"== {label}: {checkpoint}", flush=True)
        row: dict[str, dict] = {}
        if args.data:
            own = evaluate_metamodel(None if checkpoint == "default" else checkpoint, args.data)
            if own["subset"] == "test":
                row["own test"] = own
        row.update(fresh_scores(checkpoint, fresh))
        if args.pairs:
            row["settings draws"] = evaluate_metamodel(
                None if checkpoint == "default" else checkpoint, args.pairs, "all"
            )
        results[label] = {"checkpoint": checkpoint, "scores": {k: with_day1_ratio(v) for k, v in row.items()}}
    date = time.strftime("%Y-%m-%d")
    header = "| model | test set | weeks | " + " | ".join(c[0] for c in COLUMNS) + " |"
    lines = [
        "# Metamodels on buildings they never saw",
        "",
        f"Torch machine: {machine()}.",
        "",
        f"Fresh buildings: `{args.fresh}`, a campaign of {manifest.get('config', {}).get('weeks', '?')} weeks "
        f"(seed {manifest.get('config', {}).get('seed', '?')}, "
        f"{manifest.get('config', {}).get('weeks_per_run', '?')} weeks per EnergyPlus run) over every "
        "shipped climate; unseen climate: its weeks of the climates the checkpoint kept out of training. "
        "Definitions in `buildenv/metrics.py`."
        + (
            f" Settings draws: `{args.pairs}`, new buildings (log-spaced floor areas, core + perimeter) each "
            "simulated under 4 settings draws; the savings of each week against the same week under its group's "
            "first settings, predicted against simulated, in percent points."
            if args.pairs
            else ""
        ),
        "",
        header,
        "|---" * (len(COLUMNS) + 3) + "|",
    ]
    for label, result in results.items():
        for part, s in result["scores"].items():
            lines.append(
                f"| {label} | {part} | {s['weeks']} | "
                + " | ".join(
                    "-" if s.get(key) is None else f"{s[key] * scale:.{digits}f}" for _, key, scale, digits in COLUMNS
                )
                + " |"
            )
    lines += [""] + [f"- {label}: `{r['checkpoint']}`" for label, r in results.items()]
    harness.write_results(
        args.name, lines, {"date": date, "machine": machine(), "fresh": args.fresh, "models": results}, echo=True
    )


if __name__ == "__main__":
    main()
