"""Weight averages of checkpoints that share one network and one normalisation: a fine-tune and its start.

A fine-tune (``buildenv train --init CKPT``) keeps the start's architecture and normalisation statistics, so
the two lie in one weight space, and a point on the line between them is again a model of the same size and
speed. Averaging a fine-tune with the model it started from is known to keep what the fine-tune gained on its
own data while losing less on data unlike it (Wortsman et al., "Robust fine-tuning of zero-shot models",
2022). Here the question is the unseen climate: whether such a point does better on Newark than either end.

    .venv/bin/python bench/weight_average.py --checkpoint default --checkpoint data/runs/s7_ft20.pt \
        --weight 0.5 --out data/runs/avg_default_s7ft20_050.pt

``--weight`` is the second checkpoint's share (the first gets 1 - weight); with more than two checkpoints,
give one weight per checkpoint, summing to 1. The result is scored like any checkpoint, e.g. by
``bench/ground_default.py --model LABEL=OUT``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from buildenv import surrogate as sg
from metamodels.checkpoint import Checkpoint


def _same_normalisation(a: Checkpoint, b: Checkpoint) -> bool:
    return all(torch.equal(torch.as_tensor(x), torch.as_tensor(y))
               for na, nb in ((a.input_norm, b.input_norm), (a.output_norm, b.output_norm))
               for x, y in zip(na.state().values(), nb.state().values()))


def average(paths: list[str], weights: list[float]) -> Checkpoint:
    """The checkpoint whose floating-point weights are ``sum(w_i * theta_i)`` over the given checkpoints.

    Raises ``ValueError`` when the checkpoints differ in network, configuration, channels or normalisation
    statistics (their weights would not mean the same thing), or when the weights do not sum to 1.
    """
    if len(paths) != len(weights) or abs(sum(weights) - 1.0) > 1e-9:
        raise ValueError(f"{len(paths)} checkpoints need as many weights summing to 1, got {weights}")
    ckpts = [sg.load_metamodel(p).checkpoint for p in paths]
    first = ckpts[0]
    for path, other in zip(paths[1:], ckpts[1:]):
        if (other.name, other.config) != (first.name, first.config):
            raise ValueError(f"{path} is a {other.name} {other.config}, not a {first.name} {first.config}")
        if other.metadata.get("input_channels") != first.metadata.get("input_channels") \
                or other.metadata.get("context_hours") != first.metadata.get("context_hours"):
            raise ValueError(f"{path} reads other input channels or context hours than {paths[0]}")
        if not _same_normalisation(first, other):
            raise ValueError(f"{path} has other normalisation statistics than {paths[0]}: not one weight space")
    states = [c.model.state_dict() for c in ckpts]
    mixed = {}
    for key, value in states[0].items():
        if value.is_floating_point():
            mixed[key] = sum(w * s[key].double() for w, s in zip(weights, states)).to(value.dtype)
        else:
            mixed[key] = value
    first.model.load_state_dict(mixed)
    first.metadata = dict(first.metadata, averaged_from=[{"checkpoint": str(p), "weight": w}
                                                         for p, w in zip(paths, weights)])
    first.training = {}
    return first


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--checkpoint", action="append", required=True, help="a path, or 'default'; repeat")
    parser.add_argument("--weight", type=float, action="append", required=True,
                        help="with two checkpoints: the second's share; else one per checkpoint")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    weights = args.weight
    if len(args.checkpoint) == 2 and len(weights) == 1:
        weights = [1.0 - weights[0], weights[0]]
    path = average(args.checkpoint, weights).save(args.out)
    print(f"{path}: {', '.join(f'{w:g} x {p}' for p, w in zip(args.checkpoint, weights))}")


if __name__ == "__main__":
    main()
