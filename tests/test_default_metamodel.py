"""The shipped default metamodel loads and predicts weeks that EnergyPlus simulates fresh in this test."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.metamodel.surrogate import DEFAULT_CHECKPOINT, ground_hours, load_metamodel, weather_ground_c
from buildenv.metrics import r2_score

# The metamodel targets (README, "Where things stand": R2_Q >= 0.95), held on two fresh EnergyPlus weeks of one random
# building each; the temperature bounds are looser than the pooled target, one building being a small sample.
MIN_R2_T_POOLED, MIN_R2_Q_POOLED, MAX_RMSE_T_C = 0.93, 0.95, 0.6


def _sample_in_domain(group: str, n: int, rng: np.random.Generator, surrogate) -> np.ndarray:
    """``(n, len(group))`` values drawn uniformly on the catalogue grids within the ranges ``surrogate`` was
    trained on (:attr:`~buildenv.metamodel.surrogate.Surrogate.domain`), the variables it does not read at the
    value it learnt (:attr:`~buildenv.metamodel.surrogate.Surrogate.implied`)."""
    columns = []
    for v in cat.GROUPS[group]:
        if v.name in surrogate.implied:
            columns.append(np.full(n, surrogate.implied[v.name]))
            continue
        lo, hi = surrogate.domain.get(v.name, (v.min, v.max))
        earlier = surrogate.earlier.ranges.get(v.name) if surrogate.earlier else None
        grid = v.grid() if earlier is None or v.step is None else np.arange(earlier[0], earlier[1] + 1e-9, earlier[2])
        columns.append(rng.choice(grid[(grid >= lo - 1e-9) & (grid <= hi + 1e-9)], n))
    return np.stack(columns, axis=1)


def test_default_checkpoint_ships_with_the_package():
    assert DEFAULT_CHECKPOINT.is_file()
    surrogate = load_metamodel("default")
    meta = surrogate.checkpoint.metadata
    # made with this catalogue, or with one it replaced and read through that one
    assert meta["catalogue_hash"] == cat.catalogue_hash() or meta["catalogue_hash"] in cat.EARLIER_CATALOGUES
    assert surrogate.earlier is cat.EARLIER_CATALOGUES.get(meta["catalogue_hash"])
    assert meta["train_weeks"] >= 10000
    assert surrogate.checkpoint.name == "transformer"


@pytest.mark.parametrize("epw,start_week,seed", [("usa_il_chicago", 2, 11), ("usa_fl_miami", 28, 12)])
def test_default_metamodel_predicts_fresh_energyplus_weeks(epw, start_week, seed):
    rng = np.random.default_rng(seed)
    surrogate = load_metamodel()
    theta = _sample_in_domain("theta_build", 1, rng, surrogate)[0]
    settings = _sample_in_domain("settings", 2 * 7, rng, surrogate).reshape(2, 7, -1)
    occupancy = _sample_in_domain("occupancy", 2 * 5, rng, surrogate).reshape(2, 5, -1)
    cat.check_values("theta_build", theta)
    cat.check_values("settings", settings)
    sim = simulate_weeks(theta, settings, occupancy, epw, start_week=start_week, zoning=surrogate.zoning)
    # week 2 with week 1 as its context, as in a campaign; week 1 with its own first day
    pred = surrogate.predict(
        np.repeat(theta[None], 2, 0),
        settings,
        occupancy,
        sim.weather,
        previous=(settings[[0, 0]], occupancy[[0, 0]], sim.weather[[0, 0]]),
        has_previous=np.array([False, True]),
        ground_c=ground_hours(weather_ground_c(epw), (start_week + np.arange(2)) * 168, surrogate.context_hours),
    )
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    std = surrogate.checkpoint.output_norm.std
    r2_t = float(r2_score(sim.outputs[..., t].ravel(), pred[..., t].ravel()))
    r2_q = float(r2_score((sim.outputs[..., q] / std[q]).ravel(), (pred[..., q] / std[q]).ravel()))
    rmse_t = float(np.sqrt(((sim.outputs[..., t] - pred[..., t]) ** 2).mean()))
    assert r2_t >= MIN_R2_T_POOLED and r2_q >= MIN_R2_Q_POOLED and rmse_t <= MAX_RMSE_T_C, (r2_t, r2_q, rmse_t)
