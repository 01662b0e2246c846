"""The default metamodel given the ground temperature as an input: fine-tuned candidates against the shipped one.

``bench/results/metamodel_ground_input.md`` found, on a controlled pair trained from scratch, that the ground
temperature under the slab as one more input removes the price of an unseen climate. This bench measures what
it gives the shipped default. Candidates start from a checkpoint made without it (``buildenv train --init``,
which adds the channel with zero weights, so training starts from the checkpoint's own predictions) and are
fine-tuned on the 40,000-week campaign the shipped default was fine-tuned on, with the same split (weather
weeks, seed 0, Newark held out). Each is scored, with the shipped default, on

- ``held-out weather weeks``: the campaign's test weeks (weather weeks no model trained on, buildings new);
- ``Newark``: every week of the climate no model trained on;
- ``fresh buildings``: every week of an independent campaign (``--fresh``, seed 1; Newark included).

The paired columns are per-week RMSE_T ratios against the first ``--model`` (sqrt of the mean squared error
ratio), with 2.5-97.5 % bootstrap ranges over the weeks. The weeks carry the temperature before the week (the
previous week's simulated one, unknown on a run's first week), which only a model trained with it reads; such a
model is also scored with it unknown everywhere (``LABEL, temperature before unknown``), as where nothing was
measured before the week.

    .venv/bin/python bench/ground_default.py --data data/campaign-cp-40000-s7 --fresh data/campaign-cp-fresh-seed1 \
        --model shipped=default --model ground=CKPT [--model ...] [--name metamodel_ground_default]

Writes ``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import time

import numpy as np
from _training_runs import RESULTS, machine
from climate_holdout import paired, week_errors

from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import checkpoint_split, score

COLUMNS = (("loss", "loss", 4), ("R2_T pooled", "r2_t_pooled", 4), ("R2_Q pooled", "r2_q_pooled", 4),
           ("RMSE_T degC", "rmse_t_celsius", 3), ("CV(RMSE)_Q %", "cv_rmse_q_percent", 2))


def test_sets(data: str, fresh: str, meta: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Encoded inputs (the longest context of the models, every channel, the temperature before the week
    included) and outputs of the three test sets."""
    sets = {}
    ctx = meta["context_hours"]
    with open_dataset(data) as ds:
        parts = checkpoint_split(ds, meta)
        for name, idx in (("held-out weather weeks", parts["test"]), ("Newark", parts["holdout_climate"])):
            sets[name] = sg.encode_dataset(ds, idx, context_hours=ctx, temperature_before=True)
    with open_dataset(fresh) as ds:
        sets["fresh buildings"] = sg.encode_dataset(ds, np.arange(len(ds)), context_hours=ctx,
                                                    temperature_before=True)
    return sets


def own_inputs(x: np.ndarray, model: sg.Surrogate, given: bool) -> np.ndarray:
    """Inputs encoded with the longest context, cut to ``model``'s context hours (the last hours before the week
    are the same either way: the previous week's end, or the first day repeated), without the temperature
    before the week unless ``given``."""
    x = x[:, sg.context_of(x) - model.context_hours:]
    return x if given else x[..., :len(sg.INPUT_CHANNELS)]


def scored_variants(models: dict[str, sg.Surrogate]) -> dict[str, tuple[sg.Surrogate, bool]]:
    """``{label: (model, whether it is given the temperature before the week)}``: every model as it is, and
    those that read the temperature before the week once more without it."""
    variants = {label: (m, True) for label, m in models.items()}
    variants.update({f"{label}, temperature before unknown": (m, False)
                     for label, m in models.items() if m.uses_temperature_before})
    return variants


def main() -> None:
    """Score every ``--model`` on the three test sets, paired against the first, and write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="the fine-tuning campaign (its split's test weeks)")
    parser.add_argument("--fresh", required=True, help="an independent campaign, scored whole")
    parser.add_argument("--model", action="append", required=True, metavar="LABEL=CHECKPOINT")
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--name", default="metamodel_ground_default")
    parser.add_argument("--title", default="The default with the ground temperature as an input")
    args = parser.parse_args()
    started = time.perf_counter()
    models = {label: sg.load_metamodel(path) for label, path in (m.split("=", 1) for m in args.model)}
    first = next(iter(models))
    longest = max(models.values(), key=lambda m: m.context_hours)
    sets = test_sets(args.data, args.fresh, {**models[first].checkpoint.metadata,
                                             "context_hours": longest.context_hours})
    command = f"bench/ground_default.py --data {args.data} --fresh {args.fresh} " + " ".join(
        f"--model {shlex.quote(m)}" for m in args.model) + f" --name {args.name} --title {shlex.quote(args.title)}"
    result = {"title": args.title, "date": time.strftime("%Y-%m-%d"), "machine": machine(), "command": command,
              "models": {label: {"path": str(m.path), "uses_ground": m.uses_ground,
                                 "uses_temperature_before": m.uses_temperature_before,
                                 "initialised_from": m.checkpoint.metadata.get("initialised_from")}
                         for label, m in models.items()}, "sets": {}}
    variants = scored_variants(models)
    for name, (x, y) in sets.items():
        inputs = {label: own_inputs(x, m, given) for label, (m, given) in variants.items()}
        errors = {label: week_errors(m, inputs[label], y) for label, (m, _) in variants.items()}
        result["sets"][name] = {
            "weeks": int(len(x)),
            "scores": {label: score(m, inputs[label], y) for label, (m, _) in variants.items()},
            "paired": {label: paired(errors[label]["sq_t"], errors[first]["sq_t"], args.resamples, 0)
                       for label in variants if label != first}}
    result["seconds"] = round(time.perf_counter() - started)
    print(json.dumps({n: {k: v["rmse_ratio"] for k, v in s["paired"].items()} for n, s in result["sets"].items()}))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (RESULTS / f"{args.name}.md").write_text(page(result))


def page(result: dict) -> str:
    """The Markdown page of a result."""
    first = next(iter(result["models"]))
    title = result.get("title", "The default with the ground temperature as an input")
    lines = [f"# {title} ({result['date']})", "",
             f"{result['machine']}. Command: `{result['command']}` ({result['seconds']} s).", "",
             "Models:", ""]
    for label, m in result["models"].items():
        init = m["initialised_from"] or {}
        lines.append(f"- **{label}**: `{m['path']}`, ground temperature "
                     f"{'an input' if m['uses_ground'] else 'not an input'}"
                     + (", temperature before the week an input" if m.get("uses_temperature_before") else "")
                     + (f", fine-tuned from `{init.get('checkpoint')}`" if init else "") + ".")
    lines += ["", f"RMSE_T ratio: per-week paired against {first}, sqrt(mean squared error ratio), 2.5-97.5 % "
              "bootstrap range over the weeks. Day 1 / days 2-7: RMSE_T of the Monday against the rest (degC).", ""]
    for name, block in result["sets"].items():
        lines += [f"## {name} ({block['weeks']:,} weeks)", "",
                  "| model | " + " | ".join(c[0] for c in COLUMNS) + " | day 1 / days 2-7 | RMSE_T ratio |",
                  "|---" * (len(COLUMNS) + 3) + "|"]
        for label, s in block["scores"].items():
            days = s["rmse_t_celsius_by_day"]
            p = block["paired"].get(label)
            ratio = f"{p['rmse_ratio']:.3f} ({p['rmse_ratio_range_95'][0]:.3f}-{p['rmse_ratio_range_95'][1]:.3f})" \
                if p else "1"
            lines.append(f"| {label} | " + " | ".join(f"{s[key]:.{d}f}" for _, key, d in COLUMNS)
                         + f" | {days[0]:.3f} / {np.mean(days[1:]):.3f} | {ratio} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
