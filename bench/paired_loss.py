"""Two checkpoints on the same test weeks: the paired difference of their per-week test loss, with a bootstrap range.

A table's mean losses (x1e-2, std over weeks about 8) cannot say whether a difference of 0.2 is more than the
draw of test weeks; pairing the weeks can. Both checkpoints are scored on the test weeks of the first one's split
(split kind, seed and held-out climates from its metadata) of the campaign ``--data``.

    .venv/bin/python bench/paired_loss.py --data data/campaign-cp-40000-s7 A.pt B.pt [--resamples 2000]

Prints one JSON object: the mean loss of each, the mean of A - B, its 2.5-97.5 % bootstrap range over weeks,
and the share of weeks on which A's loss is lower.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from buildenv import surrogate as sg
from buildenv.dataset import open_dataset
from buildenv.training import checkpoint_split, week_scores


def week_losses(surrogate: sg.Surrogate, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The paper's loss of each week, ``(weeks,)``, in the checkpoint's own standardised units."""
    return week_scores(surrogate, x, y, surrogate.predict_encoded(x))["loss"]


def main() -> None:
    """Score both, print the paired comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="the campaign both were trained on")
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    models = [sg.load_metamodel(path) for path in (args.a, args.b)]
    with open_dataset(args.data) as ds:
        test = checkpoint_split(ds, models[0].checkpoint.metadata)
        losses = [week_losses(m, *sg.encode_dataset(ds, test["test"], context_hours=m.context_hours,
                                                    temperature_before=m.uses_temperature_before))
                  for m in models]
    diff = losses[0] - losses[1]
    rng = np.random.default_rng(args.seed)
    means = np.array([diff[rng.integers(0, len(diff), len(diff))].mean() for _ in range(args.resamples)])
    low, high = np.percentile(means, [2.5, 97.5])
    print(json.dumps({"weeks": int(len(diff)), "loss_a": round(float(losses[0].mean()), 5),
                      "loss_b": round(float(losses[1].mean()), 5), "a_minus_b": round(float(diff.mean()), 5),
                      "range_95": [round(float(low), 5), round(float(high), 5)],
                      "a_lower_share": round(float((diff < 0).mean()), 3)}))


if __name__ == "__main__":
    main()
