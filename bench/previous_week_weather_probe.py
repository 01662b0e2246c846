"""Does the previous week's weather, beyond the context, shorten the first day's excess error? (issue 3)

``bench/first_day_memory.py`` found one linear lead for the Monday's residual of the shipped default: the mean
outdoor temperature of the week before, less the week's (CV R2 0.07-0.10 on the s7 campaign's held-out weeks). The
default's 48 context hours show only the last two days of it. This probe gives the default one more input channel,
zero-initialised (:func:`metamodels.models.with_more_inputs`): the mean outdoor temperature of the 168 hours before
the week (degC, the same value on every hour; on a week that starts an EnergyPlus run, whose warm-up repeats the
first day, the first day's mean). It fine-tunes it and a control with the default's own inputs the same way (the
training weeks of the checkpoint's split of ``--data``, same epochs, learning rate and seed; the temperature
before the week known wherever the campaign has it, none hidden) and scores both day by day on the split's test
weeks and held-out climate, apart for weeks that continue a run and those that start one
(``context_temperature_probe.day_errors``).

    .venv/bin/python bench/previous_week_weather_probe.py --data data/campaign-cp-40000-s7 [--epochs 10 --lr 3e-4]

Writes ``bench/results/{--name}.{md,json}``.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import time
from pathlib import Path

import numpy as np
from _training_runs import RESULTS, machine
from context_temperature_probe import day_errors, day_table, encode, fine_tune, fit_lines

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import checkpoint_split

CHANNEL = "outdoor_mean_previous_week_c"
TAMB = cat.WEATHER_NAMES.index("TAMB")
TEMPERATURE_BEFORE = len(sg.INPUT_CHANNELS)


def previous_week_outdoor_c(ds, idx: np.ndarray, tamb: np.ndarray) -> np.ndarray:
    """``(len(idx),)`` mean outdoor temperature (degC) of the 168 hours before each week ``idx`` of a campaign whose
    hourly outdoor temperatures are ``tamb`` ``(weeks, 168)``; the week's first day's on a week that starts a run
    (EnergyPlus's warm-up repeats it)."""
    previous = ds.previous_week()[idx]
    return np.where(previous >= 0, tamb[np.maximum(previous, 0)].mean(1),
                    tamb[idx][:, :cat.HOURS_PER_DAY].mean(1)).astype(np.float32)


def with_channel(week: dict, value: np.ndarray) -> dict:
    """``week`` (:func:`context_temperature_probe.encode`) with :data:`CHANNEL` appended to its inputs."""
    extra = np.broadcast_to(value[:, None, None], week["x"].shape[:2] + (1,))
    return {**week, "x": np.concatenate([week["x"], extra], axis=-1)}


def predict(ck, x: np.ndarray, batch: int = 256) -> np.ndarray:
    """Outputs ``(N, 168, 8)`` of checkpoint ``ck`` for physical inputs ``x`` holding exactly its channels (the
    probe's extra one included, which :class:`buildenv.surrogate.Surrogate` does not encode)."""
    import torch

    from metamodels.normalisation import StandardisedModel

    model = StandardisedModel(ck.model.eval(), ck.input_norm, ck.output_norm, sg.context_of(x)).eval()
    with torch.no_grad():
        return np.concatenate([model(torch.from_numpy(np.ascontiguousarray(x[i:i + batch]))).numpy()
                               for i in range(0, len(x), batch)])


def fit_record(log: Path) -> dict:
    """Best validation loss, its epoch, epochs run and seconds from a fine-tune's CSV log."""
    rows = [line.split(",") for line in log.read_text().splitlines()[1:]]
    best = min(rows, key=lambda r: float(r[2]))
    return {"best_val_loss": float(best[2]), "best_epoch": int(best[0]), "epochs_run": len(rows),
            "seconds": round(sum(float(r[3]) for r in rows), 1)}


def main() -> None:
    """Fine-tune both variants, score them, write the page."""
    from metamodels.checkpoint import Checkpoint, load_checkpoint
    from metamodels.models import with_more_inputs
    from metamodels.normalisation import Standardiser

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="a campaign with weeks cut from longer runs")
    parser.add_argument("--base", default="default", help="a metamodel that reads the temperature before the week")
    parser.add_argument("--epochs", type=int, default=10)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--work", default="out/previous-week-weather-probe")
    parser.add_argument("--name", default="previous_week_weather_probe")
    parser.add_argument("--reuse", action="store_true", help="score the fine-tunes already in --work")
    args = parser.parse_args()
    started, load = time.perf_counter(), os.getloadavg()[0]
    base = sg.load_metamodel(args.base)
    if not base.uses_temperature_before:
        raise SystemExit(f"--base {args.base} does not read the temperature before the week (the probe adds a "
                         "channel after those)")
    ck, ctx = base.checkpoint, base.context_hours
    with open_dataset(args.data) as ds:
        parts = checkpoint_split(ds, ck.metadata)
        tamb = ds.weather[:][..., TAMB].astype(np.float64)  # read once, for every part
        weeks = {k: with_channel(encode(ds, np.sort(parts[k]), ctx),
                                 previous_week_outdoor_c(ds, np.sort(parts[k]), tamb))
                 for k in ("train", "val", "test", "holdout_climate")}
    for week in weeks.values():  # an unknown temperature before the week reads as its training mean
        value = week["x"][..., TEMPERATURE_BEFORE]
        value[np.isnan(value)] = ck.input_norm.mean[TEMPERATURE_BEFORE]
    scored = ("test", "holdout_climate")
    results = {"shipped default": {k: day_errors(predict(ck, weeks[k]["x"][..., :-1]), weeks[k])
                                   for k in scored}}
    train = weeks["train"]
    outdoor = Standardiser.fit(train["x"][:, :1, -1:])
    norm = Standardiser(np.concatenate([ck.input_norm.mean, outdoor.mean]).astype(np.float32),
                        np.concatenate([ck.input_norm.std, outdoor.std]).astype(np.float32))
    wide = with_more_inputs(copy.deepcopy(ck.model), ck.name, ck.config, ck.inputs, ck.outputs, 1)
    channels = list(ck.metadata["input_channels"])
    variants = {
        "control (the default's inputs)": (Checkpoint(ck.name, ck.config, copy.deepcopy(ck.model), ck.input_norm,
                                                      ck.output_norm, dict(ck.metadata)), lambda w: w["x"][..., :-1]),
        "with the previous week's outdoor mean": (
            Checkpoint(ck.name, ck.config, wide, norm, ck.output_norm,
                       {**ck.metadata, "input_channels": channels + [CHANNEL]}), lambda w: w["x"])}
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    fits = {}
    for i, (label, (model, inputs)) in enumerate(variants.items()):
        out = work / f"variant{i}.pt"
        if not args.reuse:
            fine_tune(model, inputs, train, weeks["val"], args.epochs, args.lr, out)
        model = load_checkpoint(out)  # its best epoch
        fits[label] = fit_record(out.with_name(out.name + ".csv"))
        results[label] = {k: day_errors(predict(model, inputs(weeks[k])), weeks[k]) for k in scored}
        print(label, json.dumps(fits[label]), flush=True)
    record = {"date": time.strftime("%Y-%m-%d"), "machine": machine(), "load_average_at_start": load,
              "command": f"python bench/previous_week_weather_probe.py --data {args.data} --base {args.base} "
                         f"--epochs {args.epochs} --lr {args.lr:g} --name {args.name}"
                         + (" --reuse (the fine-tunes of the run before, scored again)" if args.reuse else ""),
              "weeks": {k: len(w["y"]) for k, w in weeks.items()},
              "holdout_climates": ck.metadata.get("holdout_climates"), "fits": fits, "results": results,
              "seconds": round(time.perf_counter() - started, 1)}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(record, indent=1) + "\n")
    (RESULTS / f"{args.name}.md").write_text(page(record))
    print(page(record))


def page(r: dict) -> str:
    """The results page."""
    climates = ", ".join(r["holdout_climates"] or [])
    sets = {"test": "held-out weather weeks", "holdout_climate": f"held-out climate ({climates})"}
    lines = ["# The previous week's outdoor temperature as an input: the first day", "",
             f"{r['date']}, {r['machine']}, 1-min load average at start {r['load_average_at_start']:.2f}; "
             f"`{r['command']}` ({r['seconds']:.0f} s). Weeks: "
             + ", ".join(f"{k} {v:,}" for k, v in r["weeks"].items()) + ".", "",
             "RMSE_T (degC) of each day of the week (Monday first), the first day's ratio to days 2-7 and the week's "
             "RMSE_T, apart for weeks that continue an EnergyPlus run and weeks that start one "
             "(`bench/previous_week_weather_probe.py`).", ""]
    for key, title in sets.items():
        lines += day_table(title, r["results"], key) + [""]
    lines += fit_lines(r["fits"], "the base")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
