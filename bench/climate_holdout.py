"""Is the unseen climate harder because it is unseen? Newark scored by models that did and did not train on it.

The shipped default never saw Newark (``--holdout-climate usa_nj_newark``) and errs more there than on the
held-out weather weeks of the climates it trained on (README: RMSE_T 1.2x). That ratio mixes two things: what
a model loses on a climate it never trained on, and how hard Newark's weeks are for any model. This benchmark
tells them apart with a controlled pair, trained identically on the same campaign:

- **A**, Newark held out entirely (as the default);
- **B**, Newark in training like every other climate.

The ``weather_weeks`` split with a held-out climate is the split without it, less that climate's weeks
(:meth:`buildenv.dataset.Dataset.split`), so B's test weeks are A's test weeks plus Newark's held-out weather
weeks, and no model trained on any of them: the Newark test weeks have weather neither saw, in a climate only
B saw. Both draw the same number of training weeks (``--max-weeks``) for the same epochs, with seed 0 (the
split's seed, which is the default's, also seeds the weights and batches).

Scored on B's test weeks, per climate, in physical units (so that the two models' own normalisations do not
enter): RMSE_T in degC pooled over the climate's test hours and CV(RMSE) of the summed consumption, for A, B
and the shipped default (whose training campaign has the same (climate, week) pairs, so these are its held-out
weather weeks too). The paired figures: on Newark's test weeks, A's per-week squared temperature error minus
B's, with a bootstrap range over weeks; the same on the other climates' test weeks, the control for how much
two runs differ anyway.

**M, trained on morphed weather as well** (``--morphed-data DIR``): a campaign over the 16 real climates and a
morphed copy of each (``buildenv morph-weather --out-dir``, then ``buildenv simulate --epw`` with all 32), the
held-out climate and its morph kept out of training. M draws the same number of training weeks as A, about half
of them real. It is scored against A on every week of the held-out climate (neither saw it) and on the test
weeks of the other climates whose (climate, week of year) pair M's own split left out of its training and
validation, so that neither saw their weather either.

    .venv/bin/python bench/climate_holdout.py --data data/campaign-cp-40000-s7 [--holdout usa_nj_newark]
        [--epochs 20] [--max-weeks 29000] [--runs data/bench-runs/climate-holdout]
        [--morphed-data data/campaign-cp-40000-morph11] [--name metamodel_climate_holdout]

Finished runs are reused and unfinished ones resume. Writes ``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import torch
from _training_runs import RESULTS, machine, run_tag, shipped_transformer, trained

from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import week_scores
from buildenv.weather import resolve_epw
from buildenv.weather_morph import morph_source


def _errors(surrogate: sg.Surrogate, ds, idx: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`week_errors` of a model on dataset weeks ``idx``, encoded for it."""
    return week_errors(surrogate, *sg.encode_dataset(ds, idx, context_hours=surrogate.context_hours,
                                                        temperature_before=surrogate.uses_temperature_before))


def week_errors(surrogate: sg.Surrogate, x: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
    """Per-week squared temperature error (degC2, mean over the week's hours), the week's mean temperature
    error (degC; its square is the level of the week missed) and CV(RMSE)_Q (%) of a model on encoded weeks
    ``x`` with true outputs ``y``."""
    pred = surrogate.predict_encoded(x)
    per_week = week_scores(surrogate, x, y, pred)
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    offset = (pred[..., t] - y[..., t]).mean(1)
    return {"sq_t": per_week["rmse_t_celsius"] ** 2, "offset_t": offset, "cv_q": per_week["cv_rmse_q_percent"]}


def paired(a: np.ndarray, b: np.ndarray, resamples: int, seed: int) -> dict:
    """Mean of ``a - b`` over weeks with its 2.5-97.5 % bootstrap range, and the RMSE ratio sqrt(mean a / mean b)."""
    rng = np.random.default_rng(seed)
    diff = a - b
    draws = rng.integers(0, len(a), (resamples, len(a)))
    ratios = np.sqrt(a[draws].mean(1) / b[draws].mean(1))
    return {"weeks": int(len(a)), "a_minus_b_degc2": round(float(diff.mean()), 5),
            "a_minus_b_range_95": [round(float(v), 5) for v in np.percentile(diff[draws].mean(1), [2.5, 97.5])],
            "rmse_ratio": round(float(np.sqrt(a.mean() / b.mean())), 4),
            "rmse_ratio_range_95": [round(float(v), 4) for v in np.percentile(ratios, [2.5, 97.5])],
            "share_a_lower": round(float(np.mean(diff < 0)), 3)}


def level_and_shape(errors: dict[str, np.ndarray], rows: np.ndarray) -> dict[str, float]:
    """Mean squared temperature error (degC2) of some weeks, split into the weeks' mean offsets (their level
    missed) and what is left within the weeks (the shape missed), and the mean offset (degC)."""
    sq, offset = errors["sq_t"][rows], errors["offset_t"][rows]
    return {"mse_t": round(float(sq.mean()), 5), "offset_part": round(float(np.mean(offset ** 2)), 5),
            "within_week_part": round(float(np.mean(sq - offset ** 2)), 5),
            "mean_offset": round(float(offset.mean()), 4)}


def _by_climate(errors: dict[str, np.ndarray], climate: np.ndarray, names: list[str]) -> dict[str, dict]:
    """Pooled RMSE_T (degC) and mean CV(RMSE)_Q (%) of each climate's test weeks."""
    return {names[c]: {"weeks": int(np.sum(climate == c)),
                       "rmse_t": round(float(np.sqrt(errors["sq_t"][climate == c].mean())), 4),
                       "cv_q": round(float(errors["cv_q"][climate == c].mean()), 3)}
            for c in np.unique(climate)}


def main() -> None:
    """Train (or reuse) the pairs, score them with the default, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="a campaign holding every (climate, week of year) pair")
    parser.add_argument("--holdout", default="usa_nj_newark", help="the climate A never trains on")
    parser.add_argument("--epochs", type=int, default=20)
    parser.add_argument("--max-weeks", type=int, default=29000, help="training weeks each model draws")
    parser.add_argument("--context-hours", type=int, default=48)
    parser.add_argument("--runs", default="data/bench-runs/climate-holdout")
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--morphed-data", default=None, help="a campaign with morphed climates too: adds model M")
    parser.add_argument("--name", default="metamodel_climate_holdout")
    args = parser.parse_args()
    torch.set_num_threads(os.cpu_count() or 1)
    config = shipped_transformer()
    runs = Path(args.runs)
    models: dict[str, sg.Surrogate] = {"shipped default (Newark unseen)": sg.load_metamodel("default")}
    fits = {}
    for label, held in (("A", [args.holdout]), ("B", None)):
        tag = f"{label}-{run_tag(config)}-{args.max_weeks}-e{args.epochs}-c{args.context_hours}"
        fits[label] = trained(tag, runs, args.data, "transformer", config, seed=0, holdout_climates=held,
                              max_weeks=args.max_weeks, context_hours=args.context_hours, epochs=args.epochs,
                              patience=args.epochs, progress=True, ground_temperature=False)
        models[label] = sg.load_metamodel(str(runs / f"{tag}.pt"))
    with open_dataset(args.data) as ds:
        names = list(ds.weather_names)
        test = ds.split("weather_weeks", seed=0)["test"]
        climate = ds._h5["weather_index"][:][test].astype(np.int64)
        errors = {label: _errors(m, ds, test) for label, m in models.items()}
    held = climate == names.index(args.holdout)
    a, b = errors["A"]["sq_t"], errors["B"]["sq_t"]
    pairs = {"holdout": paired(a[held], b[held], args.resamples, 0),
             "others": paired(a[~held], b[~held], args.resamples, 0)}
    result = {"date": time.strftime("%Y-%m-%d"), "machine": machine(),
              "command": "bench/climate_holdout.py " + " ".join(f"--{k.replace('_', '-')} {v}"
                                                                for k, v in vars(args).items()),
              "config": config, "holdout": args.holdout, "test_weeks": int(len(test)),
              "fits": {k: {"train_weeks": v["train_weeks"], "seconds": v["seconds"],
                           "best_epoch": v["fit"].get("best_epoch")} for k, v in fits.items()},
              "by_climate": {label: _by_climate(e, climate, names) for label, e in errors.items()},
              "holdout_error_split": {label: level_and_shape(e, held) for label, e in errors.items()},
              "newark_over_others": {label: round(float(np.sqrt(e["sq_t"][held].mean() / e["sq_t"][~held].mean())), 4)
                                     for label, e in errors.items()},
              "paired_a_minus_b": pairs}
    if args.morphed_data:
        result["morphed"] = _morphed_arm(args, config, runs, models["A"], models["shipped default (Newark unseen)"])
    print(json.dumps(result["paired_a_minus_b"]))
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (RESULTS / f"{args.name}.md").write_text(_page(result))


def _pairs(data: str | Path, week_idx: np.ndarray) -> set[tuple[str, int]]:
    """(weather file name, week of year) of some weeks of a campaign (the file name, so that a short name and
    the path it stands for compare equal)."""
    with open_dataset(data) as ds:
        names = [resolve_epw(n).name for n in ds.weather_names]
        climate = ds._h5["weather_index"][:][week_idx]
        week = ds._h5["week_of_year"][:][week_idx]
    return {(names[c], int(w)) for c, w in zip(climate, week)}


def _morphed_arm(args, config: dict, runs: Path, a: sg.Surrogate, shipped: sg.Surrogate) -> dict:
    """Train M on the morphed campaign (the held-out climate and its morphs out) and score it against A."""
    source = resolve_epw(args.holdout).name
    with open_dataset(args.morphed_data) as ds:
        held = [n for n in ds.weather_names if resolve_epw(n).name == source or morph_source(n) == source]
        morphs = sum(morph_source(n) is not None for n in ds.weather_names)
        seen = ds.split("weather_weeks", seed=0, holdout_climates=held)
    tag = f"M-{Path(args.morphed_data).name}-{run_tag(config)}-{args.max_weeks}-e{args.epochs}-c{args.context_hours}"
    fit = trained(tag, runs, args.morphed_data, "transformer", config, seed=0, holdout_climates=held,
                  max_weeks=args.max_weeks, context_hours=args.context_hours, epochs=args.epochs,
                  patience=args.epochs, progress=True, ground_temperature=False)
    m = sg.load_metamodel(str(runs / f"{tag}.pt"))
    m_seen = _pairs(args.morphed_data, np.concatenate([seen["train"], seen["val"]]))
    with open_dataset(args.data) as ds:
        parts = ds.split("weather_weeks", seed=0, holdout_climates=[args.holdout])
        names = [resolve_epw(n).name for n in ds.weather_names]
        clim, week = ds._h5["weather_index"][:], ds._h5["week_of_year"][:]
        unseen = np.array([i for i in parts["test"] if (names[clim[i]], int(week[i])) not in m_seen], dtype=np.int64)
        sets = {"holdout": parts["holdout_climate"], "others": unseen}
        errors = {part: {label: _errors(model, ds, idx) for label, model in (("A", a), ("M", m), ("shipped", shipped))}
                  for part, idx in sets.items()}
    out = {"data": args.morphed_data, "held_out": held, "morphed_climates": morphs,
           "fit": {"train_weeks": fit["train_weeks"], "seconds": fit["seconds"]}}
    for part, errs in errors.items():
        out[part] = {"weeks": int(len(sets[part])),
                     "rmse_t": {label: round(float(np.sqrt(e["sq_t"].mean())), 4) for label, e in errs.items()},
                     "cv_q": {label: round(float(e["cv_q"].mean()), 3) for label, e in errs.items()},
                     "error_split": {label: level_and_shape(e, slice(None)) for label, e in errs.items()},
                     "m_minus_a": paired(errs["M"]["sq_t"], errs["A"]["sq_t"], args.resamples, 0)}
    return out


def _page(result: dict) -> str:
    held = result["holdout"]
    labels = list(result["by_climate"])
    lines = [f"# The unseen climate: is {held} harder because it is unseen? ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"A and B: the shipped architecture `{json.dumps(result['config'])}`, trained identically (same "
             f"training weeks drawn, epochs, seed) except that A never sees {held} and B trains on it like every "
             f"other climate. Test: the {result['test_weeks']:,} held-out weather weeks of B's split, whose "
             f"weather no model trained on; {held}'s are a climate only B saw. RMSE_T in degC pooled over each "
             "climate's test hours; CV(RMSE)_Q of the summed consumption, mean over weeks.", "",
             "| climate | weeks | " + " | ".join(f"{lab}: RMSE_T, CV_Q %" for lab in labels) + " |",
             "|---|---|" + "---|" * len(labels)]
    first = result["by_climate"][labels[0]]
    for name in sorted(first, key=lambda n: (n == held, n)):
        cells = [f"{result['by_climate'][lab][name]['rmse_t']:.3f}, {result['by_climate'][lab][name]['cv_q']:.2f}"
                 for lab in labels]
        shown = f"**{name}**" if name == held else name
        lines.append(f"| {shown} | {first[name]['weeks']} | " + " | ".join(cells) + " |")
    lines += ["", f"Where the error on {held}'s test weeks lies: the week's mean temperature error (its level missed) "
              "and what is left within the week (its shape missed), degC2, and the mean error (degC):", ""]
    lines += level_and_shape_rows(result["holdout_error_split"])
    lines += ["", f"RMSE_T of {held}'s test weeks over the other climates' (pooled): "
              + ", ".join(f"{lab} {v:.2f}x" for lab, v in result["newark_over_others"].items()) + ".", "",
              "Paired, A minus B, per-week squared temperature error (degC2) with its 95 % bootstrap range, and the "
              "RMSE_T ratio A/B:", "", "| test weeks | weeks | A - B | range | RMSE ratio A/B | range | A lower on |",
              "|---|---|---|---|---|---|---|"]
    for part, label in (("holdout", f"{held} (unseen by A)"), ("others", "other climates (seen by both)")):
        p = result["paired_a_minus_b"][part]
        lines.append(f"| {label} | {p['weeks']} | {p['a_minus_b_degc2']:+.5f} | "
                     f"{p['a_minus_b_range_95'][0]:+.5f} to {p['a_minus_b_range_95'][1]:+.5f} | "
                     f"{p['rmse_ratio']:.3f} | {p['rmse_ratio_range_95'][0]:.3f}-{p['rmse_ratio_range_95'][1]:.3f} | "
                     f"{100 * p['share_a_lower']:.0f} % |")
    if "morphed" in result:
        lines += _morphed_lines(result["morphed"], held)
    return "\n".join(lines) + "\n"


def _morphed_lines(m: dict, held: str) -> list[str]:
    lines = ["", f"## M: trained on morphed weather as well (`{m['data']}`)", "",
             f"M trains on {m['fit']['train_weeks']:,} weeks drawn from the real climates and "
             f"{m['morphed_climates']} morphed copies (held out: {', '.join(m['held_out'])}), the same number of "
             f"weeks, epochs and seed as A. Scored on every week of {held} (no model saw it) and on the test weeks of "
             "the other climates whose weather M's split also kept out of its training.", "",
             "| test weeks | weeks | RMSE_T A | RMSE_T M | RMSE_T shipped | CV_Q % A | CV_Q % M | M - A (degC2) "
             "| range "
             "| RMSE ratio M/A | range | M lower on |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for part, label in (("holdout", f"{held}, every week"), ("others", "other climates, weather unseen by both")):
        r, p = m[part], m[part]["m_minus_a"]
        lines.append(f"| {label} | {r['weeks']} | {r['rmse_t']['A']:.3f} | {r['rmse_t']['M']:.3f} | "
                     f"{r['rmse_t']['shipped']:.3f} | {r['cv_q']['A']:.2f} | {r['cv_q']['M']:.2f} | "
                     f"{p['a_minus_b_degc2']:+.5f} | {p['a_minus_b_range_95'][0]:+.5f} to "
                     f"{p['a_minus_b_range_95'][1]:+.5f} | {p['rmse_ratio']:.3f} | {p['rmse_ratio_range_95'][0]:.3f}-"
                     f"{p['rmse_ratio_range_95'][1]:.3f} | {100 * p['share_a_lower']:.0f} % |")
    lines += ["", f"The error on every week of {held} split as above (degC2; mean error degC):", ""]
    return lines + level_and_shape_rows(m["holdout"]["error_split"])


def level_and_shape_rows(splits: dict[str, dict]) -> list[str]:
    """Markdown table of :func:`level_and_shape` results, one row per model."""
    lines = ["| model | MSE_T | week level | within the week | mean error |", "|---|---|---|---|---|"]
    return lines + [f"| {lab} | {v['mse_t']:.4f} | {v['offset_part']:.4f} | {v['within_week_part']:.4f} | "
                    f"{v['mean_offset']:+.3f} |" for lab, v in splits.items()]


if __name__ == "__main__":
    main()
