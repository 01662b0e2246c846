"""The paper's training loss and the per-example errors behind it.

For one example (a week) with temperature channels T and consumption channels Q, in normalised units::

    Delta_T = sqrt(mean over hours and temperature channels of (T_hat - T)^2)      (an RMSE)
    Delta_Q = sqrt(mean over hours and consumption channels of (Q_hat - Q)^2)
    loss    = alpha * log(1 + Delta_T) + beta * log(1 + Delta_Q)

averaged over the examples of a batch (alpha = 1, beta = 0.3 in the paper). The RMSE sits inside the log,
as the paper's equation reads (its public code put the MSE there). An optional ``mask`` of hours (e.g. the
context hours that precede the week) drops hours from both errors.

:func:`response_loss` scores the response to settings: two weeks of one building and weather under different
settings, the difference of their energies predicted against simulated, as a share of the second's energy (the
savings error, as a fraction).
"""

from __future__ import annotations

import torch

EPS = 1e-12


def _rmse(pred: torch.Tensor, target: torch.Tensor, channels: list[int], mask: torch.Tensor | None) -> torch.Tensor:
    err = (pred[..., channels] - target[..., channels]) ** 2  # (B, H, C)
    if mask is None:
        return torch.sqrt(err.mean(dim=(1, 2)) + EPS)
    weights = mask.to(err.dtype)[..., None].expand_as(err)
    return torch.sqrt((err * weights).sum(dim=(1, 2)) / weights.sum(dim=(1, 2)).clamp_min(1.0) + EPS)


def paper_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    temperature_channels: list[int],
    consumption_channels: list[int],
    alpha: float = 1.0,
    beta: float = 0.3,
    mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """alpha*log(1+RMSE_T) + beta*log(1+RMSE_Q), mean over the batch.

    Args:
        pred, target: ``(batch, hours, outputs)`` in normalised units.
        temperature_channels: output indices of temperatures (T).
        consumption_channels: output indices of consumptions (Q).
        alpha, beta: weights (paper: 1 and 0.3).
        mask: optional ``(batch, hours)`` boolean, True for hours that count.
    Returns:
        A scalar tensor.
    """
    delta_t = _rmse(pred, target, temperature_channels, mask)
    delta_q = _rmse(pred, target, consumption_channels, mask)
    return (alpha * torch.log1p(delta_t) + beta * torch.log1p(delta_q)).mean()


def response_loss(
    pred: torch.Tensor,
    partner_pred: torch.Tensor,
    target: torch.Tensor,
    partner_target: torch.Tensor,
    channels: list[int],
    mean: torch.Tensor,
    std: torch.Tensor,
    floor: float,
    mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """RMS over the batch of the savings error between paired weeks (fraction, dimensionless).

    Args:
        pred, target: ``(batch, hours, outputs)`` normalised predictions and targets of weeks.
        partner_pred, partner_target: the same of each week's partner (same building and weather, other settings).
        channels: output indices summed into the energy (the HVAC energies).
        mean, std: ``(len(channels),)`` the normalisation of those channels (energy = value * std + mean).
        floor: smallest partner energy a difference is divided by (physical units of the channels).
        mask: optional ``(hours,)`` boolean, True for hours that count.
    Returns:
        A scalar tensor: ``sqrt(mean(((E - E_partner)_pred - (E - E_partner)_true) / max(E_partner_true, floor))^2)``.
    """

    def energy(y: torch.Tensor) -> torch.Tensor:
        hourly = (y[..., channels] * std + mean).sum(-1)  # (B, H)
        return hourly[:, mask].mean(-1) if mask is not None else hourly.mean(-1)

    reference = energy(partner_target)
    err = (energy(pred) - energy(partner_pred) - (energy(target) - reference)) / reference.clamp_min(floor)
    return torch.sqrt((err**2).mean() + EPS)
