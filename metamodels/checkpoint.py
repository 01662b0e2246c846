"""Checkpoint format: weights + model config + normalisation + free-form metadata, in one file.

A checkpoint is a ``torch.save`` of a plain dict (no pickled classes), loaded with ``weights_only=True``::

    {"format": 1, "model": name, "config": {...}, "inputs": int, "outputs": int,
     "state_dict": {...}, "input_norm": {...}, "output_norm": {...}, "metadata": {...},
     "training": {...optional optimiser state, epoch, best score for resuming...}}

``metadata`` belongs to the caller (buildenv stores the catalogue hash and channel names there and refuses a
checkpoint made for another catalogue); this package never interprets it.

:func:`load_checkpoint` checks the file before trusting it: the CRC-32 of every member of the zip archive
``torch.save`` writes (PyTorch itself does not, so flipped bytes in the weights would load), the keys, that the
weights fit the model, and that they are finite. A file that fails raises :class:`CheckpointFormatError` with
one line: the path and what is wrong.
"""

from __future__ import annotations

import os
import pickle
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from metamodels.models import build
from metamodels.normalisation import Standardiser

FORMAT = 1
#: the keys :meth:`Checkpoint.save` always writes
KEYS = ("format", "model", "config", "inputs", "outputs", "state_dict", "input_norm", "output_norm")


class CheckpointFormatError(ValueError):
    """A file is not a readable checkpoint: missing, empty, truncated, damaged, or written by another tool.

    The message is one line: the path and what is wrong (buildenv's command line prints it as it is).
    """


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
    """Read a checkpoint written by :meth:`Checkpoint.save` (model in eval mode).

    Raises:
        CheckpointFormatError: the file is missing, unreadable, empty, truncated or damaged (a member of its zip
            archive fails its CRC-32), written by another tool (not a dict, a key missing, Python objects beyond
            plain data), of another format, or holds weights that do not fit its model or are not finite.
    """
    path = Path(path)
    payload = _read_payload(path, map_location)
    if not isinstance(payload, dict):
        raise CheckpointFormatError(
            f"{path}: holds a {type(payload).__name__}, not a checkpoint dict: written by another tool?"
        )
    missing = [key for key in KEYS if key not in payload]
    if missing:
        raise CheckpointFormatError(f"{path}: missing key {missing[0]!r}: written by another tool?")
    if payload["format"] != FORMAT:
        raise CheckpointFormatError(
            f"{path}: unsupported checkpoint format {payload['format']!r} (this reads {FORMAT})"
        )
    name, config = payload["model"], payload["config"]
    try:
        model = build(name, payload["inputs"], payload["outputs"], **config)
    except (TypeError, ValueError) as exc:
        raise CheckpointFormatError(
            f"{path}: model {name!r} with config {config!r} cannot be built: {_first_line(exc)}"
        ) from None
    try:
        model.load_state_dict(payload["state_dict"])
    except (RuntimeError, TypeError, AttributeError) as exc:
        raise CheckpointFormatError(
            f"{path}: its weights do not fit a {name} model with {payload['inputs']} inputs, {payload['outputs']} "
            f"outputs and config {config!r}: {_first_line(exc)}"
        ) from None
    for key, tensor in payload["state_dict"].items():
        if torch.is_tensor(tensor) and tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            raise CheckpointFormatError(f"{path}: weight {key!r} holds NaN or infinite values (a diverged training?)")
    norms = []
    for key, size in (("input_norm", payload["inputs"]), ("output_norm", payload["outputs"])):
        try:
            norm = Standardiser.from_state(payload[key])
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointFormatError(
                f"{path}: {key!r} is not a mean and std per channel ({_first_line(exc)})"
            ) from None
        if norm.mean.shape != (size,) or norm.std.shape != (size,):
            raise CheckpointFormatError(f"{path}: {key!r} has {norm.mean.shape} values, the model {size} channels")
        if not (np.isfinite(norm.mean).all() and np.isfinite(norm.std).all()):
            raise CheckpointFormatError(f"{path}: {key!r} holds NaN or infinite values")
        norms.append(norm)
    model.eval()
    metadata, training = payload.get("metadata", {}), payload.get("training", {})
    for key, value in (("metadata", metadata), ("training", training)):
        if not isinstance(value, dict):
            raise CheckpointFormatError(f"{path}: {key!r} is a {type(value).__name__}, not a dict")
    return Checkpoint(name, config, model, norms[0], norms[1], metadata, training)


def _first_line(exc: BaseException, limit: int = 160) -> str:
    """An exception as one short line (its type where its message is empty)."""
    lines = str(exc).strip().splitlines()
    text = lines[0].strip() if lines else type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _read_payload(path: Path, map_location: str | torch.device) -> object:
    """``torch.load`` of ``path`` once its zip archive passed the CRC check; any failure as one line.

    :meth:`Checkpoint.save` writes the zip archive of ``torch.save`` (its format since PyTorch 1.6): a file
    that is not one (an empty, truncated, text or plain pickle file) is refused before ``torch.load`` reads it.
    """
    try:
        size = path.stat().st_size
        is_zip = zipfile.is_zipfile(path)
    except OSError as exc:
        raise CheckpointFormatError(f"{path}: cannot read it ({exc.strerror or _first_line(exc)})") from None
    if size == 0:
        raise CheckpointFormatError(f"{path}: empty file (0 bytes): not a checkpoint (an interrupted copy or save?)")
    if not is_zip:
        raise CheckpointFormatError(
            f"{path}: truncated or not a PyTorch checkpoint (no zip archive in its {size} bytes)"
        )
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError) as exc:
        raise CheckpointFormatError(f"{path}: truncated or damaged zip archive ({_first_line(exc)})") from None
    if bad is not None:
        raise CheckpointFormatError(
            f"{path}: damaged: member {bad!r} fails its CRC-32 check (bytes changed since saved)"
        )
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError:
        raise CheckpointFormatError(
            f"{path}: holds pickled Python objects beyond tensors and plain data: written by another tool?"
        ) from None
    except (RuntimeError, OSError, EOFError, UnicodeDecodeError, KeyError, ValueError, TypeError) as exc:
        raise CheckpointFormatError(
            f"{path}: not a readable PyTorch checkpoint ({type(exc).__name__}: {_first_line(exc)})"
        ) from None
