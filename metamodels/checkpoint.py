"""Checkpoint format: weights + model config + normalisation + free-form metadata, in one file.

A checkpoint is a ``torch.save`` of a plain dict (no pickled classes), loaded with ``weights_only=True``::

    {"format": 1, "model": name, "config": {...}, "inputs": int, "outputs": int,
     "state_dict": {...}, "input_norm": {...}, "output_norm": {...}, "metadata": {...},
     "training": {...optional optimiser state, epoch, best score for resuming...}}

``metadata`` belongs to the caller (buildenv stores the catalogue hash and channel names there and refuses a
checkpoint made for another catalogue); this package never interprets it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch import nn

from metamodels.models import build
from metamodels.normalisation import Standardiser

FORMAT = 1


@dataclass
class Checkpoint:
    """A model with everything needed to use it on physical data."""

    name: str
    config: dict
    model: nn.Module
    input_norm: Standardiser
    output_norm: Standardiser
    metadata: dict = field(default_factory=dict)
    training: dict = field(default_factory=dict)

    @property
    def inputs(self) -> int:
        return int(self.input_norm.mean.shape[0])

    @property
    def outputs(self) -> int:
        return int(self.output_norm.mean.shape[0])

    def save(self, path: str | Path) -> Path:
        """Write atomically (temporary file, then rename) and return the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            "format": FORMAT,
            "model": self.name,
            "config": self.config,
            "inputs": self.inputs,
            "outputs": self.outputs,
            "state_dict": self.model.state_dict(),
            "input_norm": self.input_norm.state(),
            "output_norm": self.output_norm.state(),
            "metadata": self.metadata,
            "training": self.training,
        }
        tmp = path.with_name(path.name + ".tmp")
        torch.save(payload, tmp)
        os.replace(tmp, path)
        return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> Checkpoint:
    """Read a checkpoint written by :meth:`Checkpoint.save` (model in eval mode)."""
    payload = torch.load(Path(path), map_location=map_location, weights_only=True)
    if payload.get("format") != FORMAT:
        raise ValueError(f"{path}: unsupported checkpoint format {payload.get('format')!r}")
    model = build(payload["model"], payload["inputs"], payload["outputs"], **payload["config"])
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return Checkpoint(
        payload["model"],
        payload["config"],
        model,
        Standardiser.from_state(payload["input_norm"]),
        Standardiser.from_state(payload["output_norm"]),
        payload.get("metadata", {}),
        payload.get("training", {}),
    )
