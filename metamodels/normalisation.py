"""Per-channel standardisation, fitted on the training split only and saved with the model."""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
import torch

#: Values per float64 chunk when fitting (256 MiB), so that fitting never copies the whole training set to float64
FIT_CHUNK_VALUES = 32 * 1024 * 1024


@dataclass
class Standardiser:
    """``(x - mean) / std`` per channel (last axis). ``std`` is floored so constant channels stay finite."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, data: np.ndarray, min_std: float = 1e-6) -> Standardiser:
        """Fit on ``data`` of shape ``(..., channels)`` (float64 accumulation; pass the training split only).

        NaN values (an input unknown in some samples) are left out of their channel's statistics; a channel
        with no value at all gets mean 0 and deviation 1."""
        flat = np.asarray(data).reshape(-1, data.shape[-1])
        rows = max(1, FIT_CHUNK_VALUES // flat.shape[1])  # two passes in float64 chunks: a bounded extra memory
        chunks = [slice(i, i + rows) for i in range(0, len(flat), rows)]
        count = sum((~np.isnan(flat[c])).sum(0) for c in chunks)
        mean = sum(np.nansum(flat[c], 0, dtype=np.float64) for c in chunks) / np.maximum(count, 1)
        var = sum(np.nansum((flat[c] - mean) ** 2, 0) for c in chunks) / np.maximum(count, 1)
        std = np.where(count > 0, np.maximum(np.sqrt(var), min_std), 1.0)
        return cls(mean.astype(np.float32), std.astype(np.float32))

    def transform(self, x: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
        """Standardise (numpy or torch, any leading shape)."""
        if isinstance(x, torch.Tensor):
            return (x - torch.as_tensor(self.mean, device=x.device)) / torch.as_tensor(self.std, device=x.device)
        return (np.asarray(x, dtype=np.float32) - self.mean) / self.std

    def inverse(self, z: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
        """Back to physical units."""
        if isinstance(z, torch.Tensor):
            return z * torch.as_tensor(self.std, device=z.device) + torch.as_tensor(self.mean, device=z.device)
        return np.asarray(z, dtype=np.float32) * self.std + self.mean

    def state(self) -> dict[str, list[float]]:
        """JSON-serialisable form."""
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_state(cls, state: dict[str, list[float]]) -> Standardiser:
        """Inverse of :meth:`state`."""
        return cls(np.asarray(state["mean"], dtype=np.float32), np.asarray(state["std"], dtype=np.float32))


class StandardisedModel(torch.nn.Module):
    """A network wrapped for inference on physical inputs: standardise the inputs, run it, drop the first
    ``skip_steps`` steps of its outputs and bring the rest back to physical units, all in one module so
    that a traced copy runs the whole chain in float32 on every core (numpy would standardise on one)."""

    def __init__(self, model: torch.nn.Module, inputs: Standardiser, outputs: Standardiser, skip_steps: int = 0):
        super().__init__()
        self.model = model
        self.skip_steps = int(skip_steps)
        self.skips_inside = "skip_hours" in inspect.signature(model.forward).parameters
        for name, value in (
            ("in_mean", inputs.mean),
            ("in_std", inputs.std),
            ("out_mean", outputs.mean),
            ("out_std", outputs.std),
        ):
            self.register_buffer(name, torch.as_tensor(np.asarray(value, dtype=np.float32)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(batch, steps, inputs)`` physical -> ``(batch, steps - skip_steps, outputs)`` physical."""
        x = (x - self.in_mean) / self.in_std
        if self.skips_inside:  # the model does not compute the dropped steps' outputs at all
            y = self.model(x, self.skip_steps)
        else:
            y = self.model(x)[:, self.skip_steps :]
        return y * self.out_std + self.out_mean
