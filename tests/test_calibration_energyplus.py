"""Calibrating the EnergyPlus shoebox directly: runs placed on the site's calendar, the same cost, a budget."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.calibration import energyplus as ce
from buildenv.calibration import problem as cal
from buildenv.energyplus.reference import historical_settings
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.sites import load_site, write_site

# 2018-01-01 is a Monday and the first row of the EPW year: 2018-01-08 is the shoebox's week of year 1
START = dt.date(2018, 1, 8)
WEATHER = "usa_il_chicago"
AREA = 5000.0


def _site(tmp_path, weeks: int, start: dt.date = START, temperature=None, consumption_wh_m2=None):
    shape = (weeks, 168)
    t = np.full(shape, 21.0) if temperature is None else temperature
    q = np.full(shape, 10.0) if consumption_wh_m2 is None else consumption_wh_m2
    write_site(
        tmp_path,
        name="synthetic",
        weather=WEATHER,
        start=start,
        floor_area_m2=AREA,
        number_of_floors=3,
        settings=historical_settings(weeks),
        temperature_c=t,
        consumption_kwh=q * AREA / 1000.0,
    )
    return load_site(tmp_path)


def _params(problem: cal.Problem) -> np.ndarray:
    """A fixed candidate: the box centre with whole occupancy hours (8 to 18)."""
    mid = (problem.lo + problem.hi) / 2.0
    mid[-10:] = [8.0, 18.0] * 5
    return mid


def test_plan_adds_the_week_before_as_warm_up(tmp_path):
    site = _site(tmp_path, 4)
    first = ce.plan_site_run(site, [0, 1])
    assert first.first_day == 7 and first.weeks == 2 and first.keep == (0, 1)  # no week before the site's first
    later = ce.plan_site_run(site, [2, 3])
    assert later.first_day == 14 and later.weeks == 3 and later.keep == (1, 2)  # week 1 warms up
    np.testing.assert_array_equal(later.settings, site.settings[1:4])
    with pytest.raises(cal.CalibrationError, match="not in"):
        ce.plan_site_run(site, [4])


def test_a_run_across_new_year_goes_on_in_january_in_the_sites_order(tmp_path):
    site = _site(tmp_path, 3, start=dt.date(2018, 12, 17))  # weeks 1-2 (Dec 24 - Jan 6) past Dec 31
    problem = cal.build_problem(site, [0])
    theta, occ = cal._split(problem, _params(problem)[None])
    across = ce.simulate_site_run(ce.plan_site_run(site, [0, 1, 2]), theta[0], occ[0])
    before = ce.simulate_site_run(ce.plan_site_run(site, [0, 1]), theta[0], occ[0])
    np.testing.assert_allclose(across[:2], before, atol=0.1)  # December as a run that stops before it
    people = across[2, :, cat.OUTPUT_NAMES.index("Q_PEOPLE")].reshape(7, 24).sum(axis=1)
    assert (people[:5] > 0).all() and (people[5:] == 0).all()  # the week after Dec 31: Monday first
    assert (across[2, :, cat.OUTPUT_NAMES.index("Q_HEAT_OFFICE")] > 0).any()
    with pytest.raises(cal.CalibrationError, match="more than a year"):
        ce.plan_site_run(_site(tmp_path / "year", 54), [1, 53])


def test_schedules_land_on_the_sites_day(tmp_path):
    site = _site(tmp_path, 1, start=dt.date(2019, 11, 4))  # EPW day 307, not a week-of-year boundary
    problem = cal.build_problem(site, [0])
    theta, occ = cal._split(problem, _params(problem)[None])
    from buildenv.energyplus.shoebox import SCHEDULE_COLUMNS, theta_dict

    rows = ce.schedule_rows(theta_dict(theta[0]), ce.plan_site_run(site, [0]), occ[0])
    occupied = rows[:, SCHEDULE_COLUMNS.index("occupancy_fraction")]
    monday = 307 * 24
    np.testing.assert_array_equal(occupied[monday : monday + 24], (np.arange(24) >= 8) & (np.arange(24) < 18))
    assert occupied[monday + 5 * 24 : monday + 7 * 24].sum() == 0  # the weekend


def test_site_run_matches_the_shoebox_simulator_and_scores_its_own_output_perfectly(tmp_path):
    site = _site(tmp_path / "a", 2)
    problem = cal.build_problem(site, [1])
    params = _params(problem)
    theta, occ = cal._split(problem, params[None])
    # week 1 of the site (with week 0 as warm-up) is the shoebox's weeks 1-2 of the year, second week
    ours = ce.simulate_site_run(ce.plan_site_run(site, [1]), theta[0], occ[0])
    reference = simulate_weeks(theta[0], site.settings, np.repeat(occ, 2, axis=0), WEATHER, 1).outputs[1:]
    np.testing.assert_allclose(ours, reference, rtol=1e-6, atol=1e-6)
    # a site measured by the shoebox itself: the cost of the true parameters is 0, of others not
    t, q = cal.model_series(problem, reference)
    measured = _site(tmp_path / "b", 2, temperature=np.concatenate([t, t]), consumption_wh_m2=np.concatenate([q, q]))
    other = params.copy()
    other[:-10] = problem.lo[:-10]  # the lightest, leakiest, least equipped building of the box
    with ce.ShoeboxPool(1) as pool:
        f = ce.evaluate_energyplus(
            cal.build_problem(measured, [1]), ce.plan_site_run(measured, [1]), pool, np.stack([params, other])
        )
    assert f[0] < 1e-4 and f[1] > 0.05


def test_pool_replaces_retired_workers(tmp_path):
    site = _site(tmp_path, 1)
    problem = cal.build_problem(site, [0])
    theta, occ = cal._split(problem, np.repeat(_params(problem)[None], 3, axis=0))
    with ce.ShoeboxPool(2, tasks_per_worker=1) as pool:  # every run on a fresh worker
        out = pool.simulate(ce.plan_site_run(site, [0]), theta, occ)
    assert out.shape == (3, 1, 168, 8) and np.allclose(out[0], out[2])


def test_budgeted_cmaes_runs_one_generation_and_scores_both_sets(tmp_path):
    site = _site(tmp_path, 2)
    result = ce.calibrate_energyplus_cmaes(site, weeks=[0], seed=0, wall_seconds=0.01, workers=2)
    popsize = 4 + int(3 * np.log(cal.build_problem(site, [0]).free.sum()))  # pycma's default
    assert result["generations"] == 1 and result["evaluations"] == len(result["history"]) * popsize
    assert result["fit_weeks"] == [0] and result["heldout_weeks"] == [1]
    for key in ("fit", "heldout"):
        assert np.isfinite([result[key][m] for m in ("r2_t", "r2_q", "cv_rmse_q_percent", "nmbe_q_percent")]).all()
    np.testing.assert_allclose(ce.parameters_of(result)[-10:], np.ravel(result["occupancy"]))
    with pytest.raises(cal.CalibrationError, match="positive"):
        ce.calibrate_energyplus_cmaes(site, weeks=[0], wall_seconds=0)


def test_warm_start_past_the_catalogue_range(tmp_path):
    site = _site(tmp_path, 2)
    problem = cal.build_problem(site, [0])
    start = _params(problem)
    j = problem.names.index("capacitance_kj_per_k_m3")
    start[j] = 15.0  # under the catalogue's 20: only simulated with the range widened
    result = ce.calibrate_energyplus_cmaes(
        site,
        weeks=[0],
        seed=0,
        wall_seconds=0.01,
        workers=2,
        start=start,
        sigma0=1e-6,
        ranges={"capacitance_kj_per_k_m3": (10.0, 300.0)},
    )
    assert result["start"] == "given" and result["ranges"] == {"capacitance_kj_per_k_m3": [10.0, 300.0]}
    assert result["theta"]["capacitance_kj_per_k_m3"] == pytest.approx(15.0, abs=1e-3)
    np.testing.assert_allclose(ce.parameters_of(result), start, atol=1e-3)
    assert np.isfinite(result["heldout"]["r2_t"])
    for kwargs, match in (
        ({"ranges": {"floor_area_m2": (100.0, 200.0)}}, "not a free building parameter"),
        ({"ranges": {"roof_insulation_m": (0.2, 0.1)}}, "not below"),
        ({"start": start[:-1]}, "shape"),
    ):
        with pytest.raises(cal.CalibrationError, match=match):
            ce.calibrate_energyplus_cmaes(site, weeks=[0], wall_seconds=1, **kwargs)


def test_a_run_with_a_warm_up_week_starts_from_any_settled_warm_up(tmp_path, monkeypatch):
    from buildenv.energyplus import runner

    site = _site(tmp_path, 2)
    problem = cal.build_problem(site, [0])
    theta, occ = cal._split(problem, _params(problem)[None])
    limits = []
    original = runner.run_energyplus

    def recording(*args, warmup_limit_k=runner.WARMUP_TEMPERATURE_LIMIT_K, **kwargs):
        limits.append(warmup_limit_k)
        return original(*args, warmup_limit_k=warmup_limit_k, **kwargs)

    monkeypatch.setattr(runner, "run_energyplus", recording)
    ce.simulate_site_run(ce.plan_site_run(site, [1]), theta[0], occ[0])  # week 0 runs first, discarded
    ce.simulate_site_run(ce.plan_site_run(site, [0]), theta[0], occ[0])  # week 0 measured: its warm-up must hold
    assert limits == [np.inf, runner.WARMUP_TEMPERATURE_LIMIT_K]
