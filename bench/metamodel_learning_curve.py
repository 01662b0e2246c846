"""Learning curve of the shipped Transformer architecture: test accuracy vs number of training weeks.

The same architecture, split (``--split``, seed 0) and number of epochs at every size; the training weeks are
seeded random subsets of the training split. Runs are kept in ``--runs`` and reused by a rerun.

    .venv/bin/python bench/metamodel_learning_curve.py --data data/campaign-cp-80000-r13 \
        [--sizes 1000,2500,5000,10000,20000] [--epochs 10] [--split weather_weeks|buildings] [--previous]

Writes ``bench/results/metamodel_learning_curve.{md,json,png}``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import harness
from harness import PREVIOUS_TRANSFORMER, RESULTS, machine, run_tag, shipped_transformer, trained

from buildenv.campaign.dataset import SPLITS


def plot(rows: list[dict], path: Path) -> None:
    """Test R2_T, R2_Q (per-week mean and pooled) and RMSE_T against training weeks, log x axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    weeks = [r["train_weeks"] for r in rows]
    fig, (ax_r2, ax_rmse) = plt.subplots(1, 2, figsize=(10, 4))
    for key, label in (
        ("r2_t", "R2_T (per week)"),
        ("r2_t_pooled", "R2_T (pooled)"),
        ("r2_q", "R2_Q (per week)"),
        ("r2_q_pooled", "R2_Q (pooled)"),
    ):
        ax_r2.plot(weeks, [r["test"][key] for r in rows], marker="o", label=label)
    ax_r2.set(xscale="log", xlabel="training weeks", ylabel="R2 on test weeks", title="Accuracy")
    ax_r2.grid(alpha=0.3)
    ax_r2.legend()
    ax_rmse.plot(weeks, [r["test"]["rmse_t_celsius"] for r in rows], marker="o", color="C3")
    ax_rmse.set(xscale="log", xlabel="training weeks", ylabel="RMSE_T (degC)", title="Indoor temperature error")
    ax_rmse.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    """Train (or reuse) one run per size and write the curve."""
    parser = harness.parser(__doc__)
    parser.add_argument("--data", required=True)
    parser.add_argument("--sizes", default="1000,2500,5000,10000,20000")
    parser.add_argument("--epochs", type=int, default=10)
    parser.add_argument("--runs", default="data/bench-runs/learning-curve")
    parser.add_argument("--split", default="weather_weeks", choices=SPLITS)
    parser.add_argument(
        "--previous",
        action="store_true",
        help="an earlier default's architecture (harness.PREVIOUS_TRANSFORMER) instead of today's",
    )
    args = parser.parse_args()
    config = PREVIOUS_TRANSFORMER if args.previous else shipped_transformer()
    rows = []
    for size in (int(s) for s in args.sizes.split(",")):
        print(f"== {size} training weeks", flush=True)
        split = "" if args.split == "weather_weeks" else f"-{args.split}"
        tag = f"transformer-{run_tag(config)}-{size}-{args.epochs}{split}"
        result = trained(
            tag,
            Path(args.runs),
            args.data,
            "transformer",
            config,
            max_weeks=size,
            split=args.split,
            epochs=args.epochs,
            patience=args.epochs,
            progress=False,
        )
        rows.append(
            {
                "train_weeks": result["train_weeks"],
                "seconds": result["fit"]["seconds"],
                "test": {k: v for k, v in result["test"].items() if not isinstance(v, list)},
            }
        )
    date = time.strftime("%Y-%m-%d")
    RESULTS.mkdir(exist_ok=True)
    plot(rows, RESULTS / "metamodel_learning_curve.png")
    record = {
        "date": date,
        "machine": machine(),
        "config": config,
        "split": args.split,
        "data": args.data,
        "epochs": args.epochs,
        "rows": rows,
    }
    lines = [
        "# Learning curve of the Transformer",
        "",
        f"Torch machine: {machine()}.",
        "",
        f"Config `{json.dumps(config)}`, {args.epochs} epochs at every size, test weeks of the "
        f"`{args.split}` split (seed 0). Plot: `metamodel_learning_curve.png`.",
        "",
        "| training weeks | loss | R2_T | R2_T pooled | R2_Q | R2_Q pooled | RMSE_T (degC) | CV(RMSE)_Q (%) "
        "| training time (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        t = r["test"]
        lines.append(
            f"| {r['train_weeks']} | {t['loss']:.4f} | {t['r2_t']:.4f} | {t.get('r2_t_pooled', 0):.4f} | "
            f"{t['r2_q']:.4f} | {t.get('r2_q_pooled', 0):.4f} | {t['rmse_t_celsius']:.3f} | "
            f"{t['cv_rmse_q_percent']:.1f} | {r['seconds']:.0f} |"
        )
    harness.write_results("metamodel_learning_curve", lines, record)
    print("\n".join(lines[-len(rows) - 2 :]))


if __name__ == "__main__":
    main()
