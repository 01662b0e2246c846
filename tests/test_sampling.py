"""Sampling catalogue variables on their grids."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.campaign.sampling import METHODS, sample_group, sample_weeks

SAMPLED_GROUPS = ("theta_build", "settings", "occupancy")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("group", SAMPLED_GROUPS)
def test_values_lie_on_catalogue_grids(group, method):
    x = sample_group(group, 257, np.random.default_rng(11), method)
    variables = cat.GROUPS[group]
    assert x.shape == (257, len(variables))
    for i, v in enumerate(variables):
        grid = v.grid()
        on_grid = np.isclose(x[:, i, None], grid[None, :], rtol=0, atol=1e-9).any(axis=1)
        assert on_grid.all(), (v.name, x[~on_grid, i][:5])
        assert x[:, i].min() >= v.min and x[:, i].max() <= v.max
    cat.check_values(group, x)


def test_uniform_reaches_every_grid_value():
    x = sample_group("settings", 2000, np.random.default_rng(5), "uniform")
    for i, v in enumerate(cat.SETTINGS):
        values, counts = np.unique(x[:, i], return_counts=True)
        np.testing.assert_allclose(values, v.grid())
        # roughly uniform: every value within 35 % of its expected count
        expected = 2000 / len(v.grid())
        assert np.all(np.abs(counts - expected) < 0.35 * expected), (v.name, counts)


@pytest.mark.parametrize("method", METHODS)
def test_deterministic_for_a_seed(method):
    a = sample_group("theta_build", 50, np.random.default_rng(42), method)
    b = sample_group("theta_build", 50, np.random.default_rng(42), method)
    c = sample_group("theta_build", 50, np.random.default_rng(43), method)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_methods_differ():
    a = sample_group("settings", 60, np.random.default_rng(1), "uniform")
    b = sample_group("settings", 60, np.random.default_rng(1), "lhs")
    assert not np.array_equal(a, b)


def test_lhs_gives_near_equal_shares():
    n = 300
    x = sample_group("settings", n, np.random.default_rng(7), "lhs")
    for i, v in enumerate(cat.SETTINGS):
        grid = v.grid()
        values, counts = np.unique(x[:, i], return_counts=True)
        np.testing.assert_allclose(values, grid)  # every grid value appears
        expected = n / len(grid)
        if len(grid) == 3:
            assert np.all(np.abs(counts - 100) <= 1), (v.name, counts)
        assert np.all(np.abs(counts - expected) < 2), (v.name, counts, expected)
        assert counts.sum() == n


def test_lhs_grids_dividing_n_exact_over_seeds():
    # a grid of g values with g dividing n gets n / g +/- 1 LHS points per value, for every seed
    n = 300
    cols = [i for i, v in enumerate(cat.THETA_BUILD) if n % len(v.grid()) == 0]
    names = {cat.THETA_NAMES[c] for c in cols}
    assert {"number_of_floors", "infiltration_ach", "heating_power_w_m2", "roof_insulation_m"} <= names
    for seed in range(5):
        x = sample_group("theta_build", n, np.random.default_rng(seed), "lhs")
        for c in cols:
            grid = cat.THETA_BUILD[c].grid()
            values, counts = np.unique(x[:, c], return_counts=True)
            np.testing.assert_allclose(values, grid)
            assert np.all(np.abs(counts - n // len(grid)) <= 1), (cat.THETA_NAMES[c], counts)


def test_unknown_method_raises():
    with pytest.raises(ValueError, match="sobol"):
        sample_group("settings", 3, np.random.default_rng(0), "sobol")


def test_zero_samples():
    for method in METHODS:
        x = sample_group("occupancy", 0, np.random.default_rng(0), method)
        assert x.shape == (0, 2)


@pytest.mark.parametrize("method", METHODS)
def test_sample_weeks_shapes_and_ranges(method):
    settings, occupancy = sample_weeks(6, np.random.default_rng(9), method)
    assert settings.shape == (6, 7, 13)
    assert occupancy.shape == (6, 5, 2)
    cat.check_values("settings", settings)
    cat.check_values("occupancy", occupancy)
    # days are drawn independently: not every day of a week is the same
    assert not np.all(settings == settings[:, :1])


def test_sample_weeks_deterministic():
    a = sample_weeks(3, np.random.default_rng(123))
    b = sample_weeks(3, np.random.default_rng(123))
    c = sample_weeks(3, np.random.default_rng(124))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
