"""The building parameters' prior: effective hours of residuals, the prior's weight, and calibration under it."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv.calibration.prior import PRIOR_SD_SHARE, effective_hours, prior_anchor


def _ar1(rho: float, weeks: int = 8, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = rng.normal(size=(weeks, 168))
    out = np.empty_like(e)
    out[:, 0] = e[:, 0]
    for h in range(1, 168):
        out[:, h] = rho * out[:, h - 1] + np.sqrt(1 - rho**2) * e[:, h]
    return out


def test_independent_residuals_count_every_hour_and_correlated_ones_fewer():
    white = effective_hours(_ar1(0.0))
    assert white == pytest.approx(8 * 168, rel=0.1)
    # an AR(1) process of lag-1 correlation rho has an integrated autocorrelation time (1 + rho) / (1 - rho)
    correlated = effective_hours(_ar1(0.9))
    assert correlated == pytest.approx(8 * 168 * 0.1 / 1.9, rel=0.5)
    assert correlated < white / 5


def test_unmeasured_hours_are_left_out_and_a_perfect_fit_counts_its_hours():
    r = _ar1(0.0)
    r[:, :84] = np.nan
    assert effective_hours(r) == pytest.approx(8 * 84, rel=0.25)
    assert effective_hours(np.zeros((2, 168))) == 2 * 168
    assert effective_hours(np.full((1, 168), np.nan)) == 1.0


def test_the_prior_weighs_less_where_the_data_say_more():
    observed = [20 + 2 * np.sin(np.arange(8 * 168) / 24 * 2 * np.pi).reshape(8, 168) for _ in range(2)]
    noise = _ar1(0.9, seed=2)
    loose, record = prior_anchor(observed, [o + noise for o in observed])
    tight, _ = prior_anchor(observed, [o + noise / 2 for o in observed])  # a quarter of the cost, as many hours
    assert tight == pytest.approx(loose / 4, rel=0.05)
    assert record["sd_share"] == PRIOR_SD_SHARE and record["anchor"] == pytest.approx(loose, rel=1e-3)
    assert [set(c) for c in record["channels"]] == [{"effective_hours", "cost"}] * 2
    # independently: cost = noise variance / signal variance (2 for a sine of amplitude 2), hours = N (1 - rho) /
    # (1 + rho) for AR(1) residuals, and one standard deviation of the prior weighs half a unit of log-likelihood
    cost = float(np.var(noise)) / 2.0
    hours = 8 * 168 * 0.1 / 1.9
    assert loose == pytest.approx(1.0 / (hours / cost * PRIOR_SD_SHARE**2), rel=0.5)


def test_the_pull_towards_the_centre_moves_what_the_fit_leaves_free(tmp_path):
    from test_calibration import _synthetic_site, _truth

    from buildenv.calibration import problem as cal
    from buildenv.metamodel.surrogate import load_metamodel

    surrogate = load_metamodel()
    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=1, noise_seed=1)
    problem = cal.build_problem(site, [0], context_hours=surrogate.context_hours, metamodel=surrogate)
    fit, first = cal.calibrate_cmaes(problem, surrogate, seed=0, max_evaluations=1500)
    theta = np.array([n in cal.free_theta() for n in problem.names])
    centre = problem.from_unit(np.full(int(problem.free.sum()), 0.5))[0]
    pulled, info = cal.calibrate_cmaes(
        problem, surrogate, seed=0, max_evaluations=1500, start=fit, anchor=0.2, anchored=theta, towards=centre
    )

    def spread(params):
        return float(np.abs(problem.to_unit(params) - 0.5)[theta[problem.free]].mean())

    assert spread(pulled) < spread(fit) - 0.02  # towards the centre, not the start
    assert info["cost"] < first["cost"] + 0.05  # at a price the fit can afford


def test_a_calibration_under_the_prior_records_it_and_never_ends_worse_than_its_first_fit(tmp_path):
    from test_calibration import _synthetic_site, _truth

    from buildenv.calibration import problem as cal
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.metamodel.surrogate import load_metamodel

    surrogate = load_metamodel()
    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=2, noise_seed=1)
    plain = calibrate_site(site, surrogate, weeks=[0], seed=0, max_evaluations=1500, prior=False, save=False)
    map_ = calibrate_site(site, surrogate, weeks=[0], seed=0, max_evaluations=1500, save=False)
    assert plain["prior"] is None
    record = map_["prior"]
    assert record["anchor"] > 0 and record["cost_without_prior"] == pytest.approx(plain["cost"], abs=1e-4)
    assert map_["evaluations"] > plain["evaluations"] and map_["run_costs"] == [pytest.approx(map_["cost"])]
    ranges = cal.parameter_ranges(site.theta_known(), surrogate)

    def objective(result):  # the cost plus the prior, as the second search weighs it
        dz = [(result["theta"][n] - (lo + hi) / 2) / (hi - lo) for n, (lo, hi) in ranges.items() if hi > lo]
        return result["cost"] + record["anchor"] * float(np.sum(np.square(dz)))

    assert objective(map_) <= objective(plain) + 1e-6  # (theta is saved to 5 decimals)
    assert record["kept_first_fit"] == (map_["theta"] == plain["theta"])
