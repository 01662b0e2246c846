"""Gradient-based calibration: Adam through the differentiable metamodel, several starts in one batch.

The parameters live in ``R^dim`` and map onto the catalogue bounds through a sigmoid, so every step stays
in range. The cost is the same as CMA-ES's (:func:`buildenv.calibration.problem.costs`) except that an occupancy
period "from start to end" switches on over a sigmoid ramp of :data:`buildenv.calibration.problem.RAMP_HOURS`
instead of at a whole hour (a step has no gradient). All starts are optimised together, one metamodel
forward and backward pass per step for all of them; the best start is then re-scored with the exact cost.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat
from buildenv.calibration.problem import (
    KNOWN_GEOMETRY,
    RAMP_HOURS,
    WEIGHTS,
    Problem,
    evaluate,
    free_theta,
)
from buildenv.metamodel import surrogate as sg


def _r2_torch(y, p, mask):
    """R2 of each start's ``p (starts, weeks, 168)`` against ``y`` over the ``mask`` hours (torch)."""
    yv = y[mask]
    ss_tot = ((yv - yv.mean()) ** 2).sum().clamp_min(1e-12)
    return 1.0 - ((p[:, mask] - yv) ** 2).sum(-1) / ss_tot


def _meter_cost(y, p, mask, daily_weight: float):
    """A meter's part of the cost for each start (torch, :func:`buildenv.calibration.problem.costs`): ``w_Q (1 - R2)``
    of its hours plus ``daily_weight`` times ``1 - R2`` of its fully measured days' totals."""
    cost = WEIGHTS["consumption"] * (1 - _r2_torch(y, p, mask))
    whole = mask.reshape(mask.shape[0], 7, 24).all(-1)
    if daily_weight > 0 and int(whole.sum()) >= 2:
        days = (y * mask).reshape(mask.shape[0], 7, 24).sum(-1)
        cost = cost + daily_weight * (1 - _r2_torch(days, p.reshape(len(p), mask.shape[0], 7, 24).sum(-1), whole))
    return cost


def calibrate_adam(
    problem: Problem,
    surrogate: sg.Surrogate,
    seed: int = 0,
    starts: int = 8,
    steps: int = 150,
    lr: float = 0.08,
    progress: bool = False,
) -> tuple[np.ndarray, dict]:
    """Adam from ``starts`` random points in the box; returns the best physical parameters and
    ``{"evaluations": starts * steps, "cost": exact cost of the best}``."""
    import torch

    ck = surrogate.checkpoint
    model = ck.model.eval()
    for p in model.parameters():
        p.requires_grad_(False)
    rng = np.random.default_rng(seed)
    z = torch.tensor(rng.normal(0.0, 1.0, (starts, problem.dim)), dtype=torch.float32, requires_grad=True)
    lo, hi = torch.tensor(problem.lo, dtype=torch.float32), torch.tensor(problem.hi, dtype=torch.float32)
    x_base = torch.tensor(surrogate.model_inputs(problem.x_base))  # the channels the model reads
    weeks = x_base.shape[0]
    free = free_theta()
    theta_const = torch.tensor([problem.theta_known.get(n, 0.0) for n in cat.THETA_NAMES], dtype=torch.float32)
    theta_cols = [j for j, n in enumerate(cat.THETA_NAMES) if n not in KNOWN_GEOMETRY]
    # where the model reads each theta variable and the occupancy (and the factor into its units)
    index, scale = surrogate.channel_map()
    t0 = sg.INPUT_CHANNELS.index(cat.THETA_NAMES[0])
    read = [(p, int(i) - t0, float(f)) for p, (i, f) in enumerate(zip(index, scale)) if 0 <= i - t0 < len(theta_const)]
    t_pos, t_src = [r[0] for r in read], [r[1] for r in read]
    t_scale = torch.tensor([r[2] for r in read], dtype=torch.float32)
    c_occ = int(np.flatnonzero(index == sg.INPUT_CHANNELS.index("occupancy_fraction"))[0])
    ctx = sg.context_of(x_base)
    hour = torch.arange(cat.HOURS_PER_DAY, dtype=torch.float32) + 0.5
    in_mean = torch.as_tensor(ck.input_norm.mean, dtype=torch.float32)
    in_std = torch.as_tensor(ck.input_norm.std, dtype=torch.float32)
    out_mean = torch.as_tensor(ck.output_norm.mean, dtype=torch.float32)
    out_std = torch.as_tensor(ck.output_norm.std, dtype=torch.float32)
    y_t = torch.tensor(np.nan_to_num(problem.temperature_c), dtype=torch.float32)
    y_q = torch.tensor(np.nan_to_num(problem.consumption_wh_m2), dtype=torch.float32)
    m_t = torch.tensor(np.isfinite(problem.temperature_c))
    m_q = torch.tensor(np.isfinite(problem.consumption_wh_m2))
    t_idx = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q_idx = list(problem.consumption_idx)  # the outputs the site's consumption meter sums
    second = problem.electricity_wh_m2
    if second is not None:  # a second meter: its outputs and measured hours
        e_idx = list(problem.electricity_idx)
        y_e = torch.tensor(np.nan_to_num(second), dtype=torch.float32)
        m_e = torch.tensor(np.isfinite(second))
    optimiser = torch.optim.Adam([z], lr=lr)

    def forward(params: torch.Tensor) -> torch.Tensor:
        theta = theta_const.repeat(len(params), 1)
        theta[:, theta_cols] = params[:, : len(free)]
        occ = params[:, len(free) :].reshape(len(params), len(cat.WEEKDAYS), 2)
        on = torch.sigmoid((hour - occ[..., :1]) / RAMP_HOURS) * torch.sigmoid((occ[..., 1:] - hour) / RAMP_HOURS)
        week = torch.cat([on.reshape(len(params), -1), torch.zeros(len(params), 2 * cat.HOURS_PER_DAY)], 1)
        x = x_base.expand(len(params), *x_base.shape).clone()
        x[..., t_pos] = (theta[:, t_src] * t_scale)[:, None, None, :]
        x[:, :, ctx:, c_occ] = week[:, None, :]
        x[:, :, :ctx, c_occ] = week[:, None, -ctx:]  # context: the last days of the week before (build_problem)
        y = model(((x - in_mean) / in_std).reshape(-1, *x.shape[2:]))[:, ctx:] * out_std + out_mean
        y = y.reshape(len(params), weeks, cat.HOURS_PER_WEEK, -1)
        meters = _meter_cost(y_q, y[..., q_idx].sum(-1), m_q, problem.daily_weight)
        if second is not None:
            meters = (meters + _meter_cost(y_e, y[..., e_idx].sum(-1), m_e, problem.daily_weight)) / 2
        return WEIGHTS["temperature"] * (1 - _r2_torch(y_t, y[..., t_idx], m_t)) + meters

    from tqdm import tqdm

    for _ in tqdm(range(steps), desc="Adam", disable=not progress, leave=False):
        params = lo + torch.sigmoid(z) * (hi - lo)
        loss = forward(params)
        optimiser.zero_grad()
        loss.sum().backward()
        optimiser.step()
    with torch.no_grad():
        final = (lo + torch.sigmoid(z) * (hi - lo)).numpy().astype(float)
    exact = evaluate(problem, surrogate, final)
    best = int(np.argmin(exact))
    return final[best], {"evaluations": starts * steps, "cost": float(exact[best])}
