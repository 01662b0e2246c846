"""What the metamodel's first-day excess depends on: the week before, beyond the context it reads.

The shipped metamodel reads 48 hours before each week (inputs and the indoor temperature measured over them) and
still errs more on Monday than on the rest of the week (README, "the first day"). Part of that is intrinsic
(weeks that start an EnergyPlus run, whose state the warm-up fixes, have a Monday 1.2x their rest); the rest is the
state the previous week left. This script asks which features of the previous week, within and beyond the
context, go with the Monday's error, on a campaign's continuing weeks (weeks with a simulated week before them,
the indoor temperature of the hours before the week known):

- ``t_last48_c``: mean indoor temperature over the context's 48 hours (the metamodel sees it);
- ``t_days1_5_minus_last48_k``: mean indoor temperature of the previous week's first 5 days minus the above
  (what the context does not show: the building's state over the working week before);
- ``heat_prev_wh_m2``: mean hourly heat consumption of the previous week (``HEAT_CONSUMPTION_OUTPUTS``);
- ``tout_prev_minus_week_k``: mean outdoor temperature of the previous week minus the week's;
- ``setpoint_change_k``: mean heating setpoint of Monday 00-08 h minus that of the previous Sunday.

For each week the Monday's residual (prediction - simulation of the indoor temperature) is summarised as its
mean over Monday 00-08 h, the hours where it is largest, and each feature is tested alone and all together by
5-fold cross-validated R2 of a linear fit (a share of that residual's variance a linear correction could remove).

    .venv/bin/python bench/first_day_memory.py --data data/campaign-5200 [--checkpoint default] [--weeks all]

Writes ``bench/results/first_day_memory.{md,json}`` (about a minute for 5,200 weeks on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _training_runs import RESULTS, machine

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.schedules import hourly_schedules
from buildenv.training import checkpoint_split

T = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
Q = [cat.OUTPUT_NAMES.index(n) for n in cat.HEAT_CONSUMPTION_OUTPUTS]
TAMB = cat.WEATHER_NAMES.index("TAMB")
MORNING = slice(0, 9)  # Monday 00-08 h


def features(ds, idx: np.ndarray, prev: np.ndarray, context_hours: int) -> dict[str, np.ndarray]:
    """The module docstring's features of weeks ``idx`` whose previous weeks are ``prev`` (dataset rows; the
    campaign's arrays are read whole)."""
    outputs, weather = ds.outputs[:].astype(np.float64), ds.weather[:]
    setpoint = hourly_schedules(ds.settings[:], ds.occupancy[:])["heating_setpoint_c"]
    before = outputs[prev]
    last = before[:, -context_hours:, T].mean(1)
    return {"t_last48_c": last,
            "t_days1_5_minus_last48_k": before[:, :5 * cat.HOURS_PER_DAY, T].mean(1) - last,
            "heat_prev_wh_m2": before[..., Q].sum(-1).mean(1),
            "tout_prev_minus_week_k": weather[prev][..., TAMB].mean(1) - weather[idx][..., TAMB].mean(1),
            "setpoint_change_k": setpoint[idx][:, MORNING].mean(1) - setpoint[prev][:, -cat.HOURS_PER_DAY:].mean(1)}


def by_day(residual: np.ndarray) -> np.ndarray:
    """RMSE (degC) of each day of the week, Monday first, of hourly residuals ``(weeks, 168)``."""
    return np.sqrt((residual.reshape(len(residual), 7, cat.HOURS_PER_DAY) ** 2).mean((0, 2)))


def monday_over_rest(daily: np.ndarray) -> float:
    """Monday's RMSE over the RMSE of Tuesday-Sunday together."""
    return round(float(daily[0] / np.sqrt((daily[1:] ** 2).mean())), 3)


def cv_r2(x: np.ndarray, y: np.ndarray, folds: int = 5, seed: int = 0) -> float:
    """5-fold cross-validated R2 of a linear fit (with intercept) of ``y`` on columns ``x``."""
    order = np.random.default_rng(seed).permutation(len(y))
    pred = np.empty_like(y)
    for f in range(folds):
        test = order[f::folds]
        train = np.setdiff1d(order, test)
        a = np.column_stack([np.ones(len(train)), x[train]])
        coef, *_ = np.linalg.lstsq(a, y[train], rcond=None)
        pred[test] = np.column_stack([np.ones(len(test)), x[test]]) @ coef
    return 1.0 - float(((y - pred) ** 2).sum() / ((y - y.mean()) ** 2).sum())


def main() -> None:
    """Score the continuing weeks, fit the features, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="a campaign directory (buildenv simulate)")
    parser.add_argument("--checkpoint", default="default")
    parser.add_argument("--weeks", default="all", choices=("all", "test", "holdout_climate"),
                        help="every week of the campaign, or those of the checkpoint's split (its test weeks, or "
                        "its held-out climate's): the campaign it was trained on, or one drawn like it")
    parser.add_argument("--name", default="first_day_memory")
    args = parser.parse_args()
    model = sg.load_metamodel(args.checkpoint)
    ctx = model.context_hours
    with open_dataset(args.data) as ds:
        previous = ds.previous_week()
        chosen = np.arange(len(ds)) if args.weeks == "all" else \
            checkpoint_split(ds, model.checkpoint.metadata)[args.weeks]
        idx = chosen[previous[chosen] >= 0]
        x, y = sg.encode_dataset(ds, idx, context_hours=ctx, temperature_before=model.uses_temperature_before)
        residual = model.predict_encoded(x)[..., T] - y[..., T]
        feats = features(ds, idx, previous[idx], ctx)
        starts = chosen[previous[chosen] < 0]  # a run's first week: EnergyPlus's warm-up set its state
        xs, ys = sg.encode_dataset(ds, starts, context_hours=ctx, temperature_before=model.uses_temperature_before)
        daily_starts = by_day(model.predict_encoded(xs)[..., T] - ys[..., T])
    daily = by_day(residual)
    target = residual[:, MORNING].mean(1)
    columns = np.column_stack(list(feats.values()))
    rows = {name: cv_r2(columns[:, [j]], target) for j, name in enumerate(feats)}
    rows["all together"] = cv_r2(columns, target)
    result = {"date": time.strftime("%Y-%m-%d"), "machine": machine(),
              "command": f"bench/first_day_memory.py --data {args.data} --checkpoint {args.checkpoint} "
                         f"--weeks {args.weeks} --name {args.name}",
              "continuing_weeks": int(len(idx)), "rmse_t_by_day_c": [round(float(v), 4) for v in daily],
              "monday_over_rest": monday_over_rest(daily), "run_start_weeks": int(len(starts)),
              "run_start_rmse_t_by_day_c": [round(float(v), 4) for v in daily_starts],
              "run_start_monday_over_rest": monday_over_rest(daily_starts),
              "monday_morning_residual_std_c": round(float(target.std()), 4),
              "cv_r2": {k: round(v, 4) for k, v in rows.items()}}
    print(json.dumps(result, indent=1))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    lines = [f"# The first day's error and the week before ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"{result['continuing_weeks']} continuing weeks of `{args.data}` ({args.weeks}), the temperature of "
             "the context hours known. "
             f"RMSE_T by day (degC, Monday first): {', '.join(f'{v:.3f}' for v in daily)}; Monday / the rest "
             f"{result['monday_over_rest']}x. On the {result['run_start_weeks']} weeks that start a run (no week "
             "before them; EnergyPlus's warm-up set their state, the metamodel sees their first day repeated): "
             f"{', '.join(f'{v:.3f}' for v in daily_starts)}; {result['run_start_monday_over_rest']}x. Target: "
             "the mean residual over Monday 00-08 h "
             f"(std {result['monday_morning_residual_std_c']:.3f} degC). Cross-validated R2 of a linear fit on "
             "each feature of the previous week (`bench/first_day_memory.py` defines them):", "",
             "| feature | CV R2 |", "|---|---|"]
    lines += [f"| {k} | {v:.3f} |" for k, v in result["cv_r2"].items()]
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
