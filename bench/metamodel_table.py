"""The paper's Table 1 for our five metamodels: same data, same split, same training budget.

Each model is trained by ``buildenv train`` (through :func:`buildenv.metamodel.training.train_metamodel`) on the same
``--weeks`` training weeks of a campaign, with the ``weather_weeks`` split (test weeks' weather never seen
in training) or, with ``--split buildings``, the ``buildings`` split (test weeks' buildings never seen in
training), the paper's loss, Adam with a cosine learning rate and ``--epochs`` epochs; then scored on the
test weeks. Runs are kept in ``--runs`` and reused by a rerun. With ``--minutes M`` every model gets the same
training time instead of the same epochs (``buildenv train --minutes``: M minutes of wall clock, validation
included, the cosine decay spread over them): the comparison a user training on this machine faces.
Run it alone on the machine: a budget shared with other jobs buys less.

    .venv/bin/python bench/metamodel_table.py --data data/campaign-40000 [--weeks 10000] [--epochs 10] \
        [--minutes M] [--batch-size 64] [--split weather_weeks|buildings] [--name STEM]

Writes ``bench/results/metamodel_table.{md,json,png}`` (``--name``: another stem); the PNG plots each model's
test loss against its inference speed, all timed in turn in one run.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import harness
from harness import (
    PREVIOUS_TRANSFORMER,
    RESULTS,
    inference_speeds,
    machine,
    mean_std,
    run_tag,
    shipped_transformer,
    trained,
)

SHIPPED = shipped_transformer()  # loads the default checkpoint: once, not once per variant
MODELS: dict[str, tuple[str, dict]] = {
    "Transformer": ("transformer", SHIPPED),
    "BiGRU": ("bigru", {}),
    "LSTM": ("lstm", {}),
    "ConvGRU": ("convgru", {}),
    "FFN": ("ffn", {}),
    "Transformer (paper, hourly tokens)": ("transformer", {}),
    "Transformer (previous default)": ("transformer", PREVIOUS_TRANSFORMER),
    "Transformer 2+2 layers + thermal states": ("transformer", {**PREVIOUS_TRANSFORMER, "hourly_state": 16}),
    "Transformer + 2 state stages": ("transformer", {**SHIPPED, "hourly_state_layers": 2}),
    "Transformer + 3 state stages": ("transformer", {**SHIPPED, "hourly_state_layers": 3}),
    "Transformer + 4 state stages": ("transformer", {**SHIPPED, "hourly_state_layers": 4}),
    "Transformer + 6 state stages": ("transformer", {**SHIPPED, "hourly_state_layers": 6}),
    "Transformer 2+2 layers + 3 state stages": ("transformer", {**SHIPPED, "layers": 2, "hourly_state_layers": 3}),
    "Transformer + head 128": ("transformer", {**SHIPPED, "hourly_head": 128}),
    "Transformer + 3 state stages + head 128": (
        "transformer",
        {**SHIPPED, "hourly_head": 128, "hourly_state_layers": 3},
    ),
    "Transformer with 32 states": ("transformer", {**SHIPPED, "hourly_state": 32}),
    "Transformer with 4-hour tokens": ("transformer", {**SHIPPED, "patch_hours": 4}),
    "Transformer with 12-hour tokens + head 128": ("transformer", {**SHIPPED, "patch_hours": 12, "hourly_head": 128}),
    "Transformer with 12-hour tokens + head 96": ("transformer", {**SHIPPED, "patch_hours": 12, "hourly_head": 96}),
    "Transformer with 12-hour tokens + 2 state stages": (
        "transformer",
        {**SHIPPED, "patch_hours": 12, "hourly_state_layers": 2},
    ),
    "Transformer with 12-hour tokens + 3 state stages": (
        "transformer",
        {**SHIPPED, "patch_hours": 12, "hourly_state_layers": 3},
    ),
    "Transformer with 12-hour tokens + 2 state stages + head 96": (
        "transformer",
        {**SHIPPED, "patch_hours": 12, "hourly_head": 96, "hourly_state_layers": 2},
    ),
    "Transformer with 12-hour tokens + 3 state stages + head 128": (
        "transformer",
        {**SHIPPED, "patch_hours": 12, "hourly_head": 128, "hourly_state_layers": 3},
    ),
    "Transformer with 24-hour tokens + 3 state stages": (
        "transformer",
        {**SHIPPED, "patch_hours": 24, "hourly_state_layers": 3},
    ),
}
SPLIT_MEANING = {
    "weather_weeks": "the test weeks' climate and week of year never occur in training",
    "buildings": "the test weeks' buildings, i.e. EnergyPlus runs, never occur in training",
}
ROWS = [
    ("Loss (x1e-2)", "loss", 100.0),
    ("MSE_T (x1e-2)", "mse_t", 100.0),
    ("MSE_Q (x1e-2)", "mse_q", 100.0),
    ("MSE_T occ (x1e-2)", "mse_t_occ", 100.0),
    ("MSE_Q occ (x1e-2)", "mse_q_occ", 100.0),
    ("R2_T (x1e-3)", "r2_t", 1000.0),
    ("R2_Q (x1e-3)", "r2_q", 1000.0),
    ("RMSE_T (degC)", "rmse_t_celsius", 1.0),
    ("CV(RMSE)_Q (%)", "cv_rmse_q_percent", 1.0),
]


def parse_columns(text: str) -> list[str]:
    """Column labels of ``--models``, comma-separated; a label with a comma of its own (``Transformer (paper,
    hourly tokens)``) is read whole."""
    columns, pending = [], ""
    for piece in text.split(","):
        pending = f"{pending},{piece}" if pending else piece.strip()
        if pending in MODELS:
            columns.append(pending)
            pending = ""
    if pending:
        raise SystemExit(f"--models: unknown column {pending!r}; known: {', '.join(MODELS)}")
    return columns


def fastest_epoch(log: Path, budget: bool = False) -> float | None:
    """Shortest epoch of a run's training log (seconds): the per-epoch cost least disturbed by other jobs. A
    budget run's last epoch is cut by the budget and left out (``None`` when it had no other)."""
    with log.open(newline="") as f:
        seconds = [float(row["seconds"]) for row in csv.DictReader(f)]
    seconds = seconds[:-1] if budget else seconds
    return min(seconds) if seconds else None


def plot_tradeoff(results: dict[str, dict], columns: list[str], title: str, path: Path) -> None:
    """Test loss (mean over test weeks, +/- its standard error) against inference weeks per second, one point
    per column, written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 5.5))
    fig.subplots_adjust(left=0.08, right=0.58, bottom=0.11, top=0.92)
    for number, label in enumerate(columns, 1):
        test = results[label]["test"]
        loss, error = 100 * test["loss"], 100 * test["loss_std"] / test["weeks"] ** 0.5
        speed = results[label]["inference_weeks_per_second"]
        transformer = MODELS[label][0] == "transformer"
        ax.errorbar(
            speed, loss, yerr=error, fmt="o" if transformer else "s", color="C0" if transformer else "C3", capsize=3
        )
        ax.annotate(str(number), (speed, loss), textcoords="offset points", xytext=(6, -3), fontsize=8)
        fig.text(0.60, 0.90 - 0.05 * number, f"{number}  {label}", fontsize=8, va="top")
    ax.set_xscale("log")
    ax.set_xlabel("inference (weeks/s, this machine, all its cores)")
    ax.set_ylabel("test loss (x1e-2, mean over test weeks +/- standard error)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, which="both")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_curves(logs: dict[str, Path], title: str, path: Path) -> None:
    """Validation loss after each epoch against the training minutes spent by then (a run's CSV log), one line
    per column, written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5))
    for label, log in logs.items():
        with log.open(newline="") as f:
            rows = list(csv.DictReader(f))
        minutes, spent = [], 0.0
        for row in rows:
            spent += float(row["seconds"]) / 60.0
            minutes.append(spent)
        ax.plot(minutes, [100 * float(row["val_loss"]) for row in rows], marker=".", label=label)
    ax.set_xlabel("training time (minutes, this machine, validation included)")
    ax.set_ylabel("validation loss (x1e-2)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    """Train (or reuse) every model and write the table."""
    parser = harness.parser(__doc__)
    parser.add_argument("--data", required=True, help="campaign directory (buildenv simulate --out)")
    parser.add_argument("--weeks", type=int, default=10000, help="training weeks per model")
    parser.add_argument("--epochs", type=int, default=10)
    parser.add_argument(
        "--minutes",
        type=float,
        default=None,
        help="the same training time for every model instead of the same epochs (--epochs is then ignored)",
    )
    parser.add_argument("--batch-size", type=int, default=64, help="training weeks per Adam step, every model")
    parser.add_argument("--runs", default="data/bench-runs/table1", help="where checkpoints are kept")
    parser.add_argument("--models", default=",".join(MODELS), help="comma-separated subset of the columns")
    parser.add_argument("--name", help="results file stem (default metamodel_table[_batchN])")
    parser.add_argument(
        "--split",
        default="weather_weeks",
        choices=["weather_weeks", "buildings"],
        help="buildings: test weeks come from buildings never seen in training",
    )
    parser.add_argument(
        "--trained-on",
        help="where the runs were trained, when not on this machine (stated "
        "in the table; training times are then that machine's)",
    )
    parser.add_argument(
        "--train-only",
        action="store_true",
        help="train the runs and stop (e.g. on a lent GPU, the table written here afterwards)",
    )
    args = parser.parse_args()
    columns = parse_columns(args.models)
    budget = args.minutes is not None
    epochs = 100_000 if budget else args.epochs  # with a budget, time ends the run, not epochs or patience
    results, logs = {}, {}
    for label in columns:
        model, config = MODELS[label]
        tag = (
            f"{model}-{run_tag(config)}-{args.weeks}-"
            + (f"m{args.minutes:g}" if budget else str(args.epochs))
            + (f"-b{args.batch_size}" if args.batch_size != 64 else "")
            + (f"-{args.split}" if args.split != "weather_weeks" else "")
        )
        print(f"== {label}: {model} {json.dumps(config)}", flush=True)
        result = trained(
            tag,
            Path(args.runs),
            args.data,
            model,
            config,
            max_weeks=args.weeks,
            epochs=epochs,
            patience=epochs,
            batch_size=args.batch_size,
            split=args.split,
            progress=False,
            minutes=args.minutes,
        )
        if args.train_only:
            continue
        logs[label] = Path(args.runs) / f"{tag}.pt.csv"
        result["fastest_epoch_seconds"] = fastest_epoch(logs[label], budget=budget)
        results[label] = result
    if args.train_only:
        return
    for label, speed in inference_speeds({label: MODELS[label] for label in columns}).items():
        results[label]["inference_weeks_per_second"] = round(speed, 1)
    first = results[columns[0]]
    header = ["| metric | " + " | ".join(columns) + " |", "|---" * (len(columns) + 1) + "|"]
    body = [
        f"| {name} | "
        + " | ".join(mean_std(results[c], key, scale, 3 if scale == 1000.0 else 2) for c in columns)
        + " |"
        for name, key, scale in ROWS
    ]
    body += [
        "| R2_T pooled | "
        + " | ".join(f"{results[c]['test'].get('r2_t_pooled', float('nan')):.4f}" for c in columns)
        + " |",
        "| R2_Q pooled | "
        + " | ".join(f"{results[c]['test'].get('r2_q_pooled', float('nan')):.4f}" for c in columns)
        + " |",
        "| training time (s) | " + " | ".join(f"{results[c]['fit']['seconds']:.0f}" for c in columns) + " |",
        f"| fastest {'full ' if budget else ''}epoch (s) | "
        + " | ".join(
            "-" if results[c]["fastest_epoch_seconds"] is None else f"{results[c]['fastest_epoch_seconds']:.1f}"
            for c in columns
        )
        + " |",
        "| epochs (best) | "
        + " | ".join(f"{results[c]['fit']['epochs_run']} ({results[c]['fit']['best_epoch']})" for c in columns)
        + " |",
        "| training weeks drawn | "
        + " | ".join(
            f"{results[c]['fit'].get('weeks_seen', results[c]['fit']['epochs_run'] * results[c]['train_weeks']):,}"
            for c in columns
        )
        + " |",
        "| inference (weeks/s) | "
        + " | ".join(f"{results[c]['inference_weeks_per_second']:.0f}" for c in columns)
        + " |",
        "| inference (x first column) | "
        + " | ".join(
            f"{results[c]['inference_weeks_per_second'] / first['inference_weeks_per_second']:.2f}" for c in columns
        )
        + " |",
    ]
    date = time.strftime("%Y-%m-%d")
    lines = [
        "# Table 1: metamodels compared",
        "",
        f"Torch machine: {machine()}.",
        "",
        f"Every model: {first['train_weeks']} training weeks, {first['val_weeks']} validation and "
        f"{first['test_weeks']} test weeks (split `{args.split}`, seed 0: "
        + SPLIT_MEANING[args.split]
        + "), "
        + (
            f"{args.minutes:g} minutes of training each on this machine (wall clock, validation "
            "included; the epoch running when the time is spent is cut there and still validated, so a "
            "slow model's last validation can overrun) with Adam (lr 1e-3, cosine decay over the "
            "minutes"
            if budget
            else f"{args.epochs} epochs of Adam (lr 1e-3, cosine decay"
        )
        + f", batch {args.batch_size}) "
        "on the paper's loss, best validation epoch kept. Mean (std) over test weeks; definitions in "
        "`buildenv/metrics.py` (MSE in standardised units, per-week R2 as `sklearn.metrics.r2_score`, "
        "pooled R2 over all test hours). Training time is the run's wall clock (it grows when other jobs "
        "share the 2 cores); the fastest epoch is the least disturbed measure of a model's training cost (with a "
        "budget, the last, cut epoch is left out); "
        "inference is measured when the table is written (the models timed in turn, best of 3 rounds).",
        "",
        *header,
        *body,
        "",
    ]
    if args.trained_on:
        lines[2:2] = [
            f"Trained on {args.trained_on}; the training times are that machine's, the inference speed this one's.",
            "",
        ]
    lines += [f"- {label}: `{MODELS[label][0]}` `{json.dumps(MODELS[label][1])}`" for label in columns]
    RESULTS.mkdir(exist_ok=True)
    stem = args.name or "metamodel_table" + (f"_batch{args.batch_size}" if args.batch_size != 64 else "")
    plot_tradeoff(
        results,
        columns,
        f"{first['train_weeks']} training weeks, "
        + (f"{args.minutes:g} minutes each, " if budget else f"{args.epochs} epochs, ")
        + f"{first['test_weeks']} test weeks ({args.split})",
        RESULTS / f"{stem}.png",
    )
    lines += ["", f"Loss against inference speed: `{stem}.png`."]
    if budget:
        plot_curves(
            logs,
            f"{first['train_weeks']} training weeks, {args.minutes:g} minutes each, cosine decay over the minutes",
            RESULTS / f"{stem}_curves.png",
        )
        lines += [f"Validation loss against training minutes: `{stem}_curves.png`."]
    harness.write_results(
        stem,
        lines,
        {
            "date": date,
            "machine": machine(),
            "weeks": args.weeks,
            "epochs": None if budget else args.epochs,
            "minutes": args.minutes,
            "batch_size": args.batch_size,
            "models": {c: {"model": MODELS[c][0], "config": MODELS[c][1], **results[c]} for c in columns},
        },
    )
    print("\n".join(header + body))


if __name__ == "__main__":
    main()
