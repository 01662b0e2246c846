"""Sites from the reference building, and calibration: known parameters recovered, gaps masked."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.calibration import problem as cal
from buildenv.calibration.calibrate import calibrate_site
from buildenv.energyplus.idf import read_idf
from buildenv.energyplus.reference import (
    REFERENCE_BUILDINGS,
    STAND_IN_VERSION,
    add_sensor_noise,
    detect_schedule_map,
    historical_settings,
    make_reference_site,
    reference_idf,
)
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site, write_site

START = dt.date(2019, 11, 4)


@pytest.mark.parametrize("building", sorted(REFERENCE_BUILDINGS))
def test_every_shipped_reference_office_maps_all_roles(building):
    mapping = detect_schedule_map(read_idf(reference_idf(building)))
    for role in ("heating_setpoint", "cooling_setpoint", "hvac_availability", "outdoor_air"):
        assert getattr(mapping, role), (building, role)


def test_reference_site_reads_like_sensors(tmp_path):
    path = make_reference_site(tmp_path / "site", "medium_office", "usa_il_chicago", START, weeks=1, seed=3)
    site = load_site(path)
    assert site.weeks == 1 and site.number_of_floors == 3
    assert site.floor_area_m2 == pytest.approx(4982, rel=0.01)  # the DOE medium office's occupied floor area
    t, q = site.temperature_c[0], site.consumption_kwh[0]
    assert np.isfinite(t).all() and 15 < t.min() and t.max() < 30
    weekday_day = q[:120].reshape(5, 24)[:, 10:16].mean()
    night = q[:120].reshape(5, 24)[:, 1:4].mean()
    assert weekday_day > 2 * night > 0  # lights and plug loads of an occupied office
    assert np.allclose(t * 10, np.round(t * 10), atol=1e-6)  # the sensor's 0.1 K resolution
    assert site.source["building"] == "medium_office" and site.truth == {
        "building": "medium_office",
        "effects": [],
        "stand_in": STAND_IN_VERSION,
    }
    # [bms]: what the stand-in maps; its ventilation up to the design outdoor air (0.7 1/h on the grid)
    assert "supply_air_c" not in site.controllable and len(site.controllable) == len(cat.SETTING_NAMES) - 1
    assert site.setting_limits == {"ventilation_ach": (0.45, 0.7)}  # the code minimum for its occupants, its design
    # its history records the supply air its VAV loops delivered (12.8 degC), as a BMS trend would
    assert set(site.settings[..., cat.SETTING_NAMES.index("supply_air_c")].ravel()) == {13.0}


def _synthetic_site(
    tmp_path, surrogate, params, weeks=2, gaps=None, known=None, effects=(), declared=(), noise_seed=None
):
    """A site whose 'measurements' are the metamodel's own prediction for known parameters (those of
    ``effects`` follow theta and occupancy in ``params``); its site.toml declares ``declared``. With
    ``noise_seed`` they carry the reference stand-in's sensor noise and meter resolution (0.1 K, 1 %)."""
    settings = historical_settings(weeks)
    write_site(
        tmp_path,
        name="synthetic",
        weather="usa_il_chicago",
        start=START,
        floor_area_m2=5000,
        number_of_floors=3,
        settings=settings,
        temperature_c=np.full((weeks, 168), 20.0),
        consumption_kwh=np.full((weeks, 168), 10.0),
    )
    site = load_site(tmp_path)
    problem = cal.build_problem(site, list(range(weeks)), effects, context_hours=surrogate.context_hours)
    t, q = cal.predict(problem, surrogate, params)
    q_kwh = q * site.floor_area_m2 / 1000.0
    if noise_seed is not None:
        t, q_kwh = add_sensor_noise(
            SimpleNamespace(temperature_c=t, consumption_kwh=q_kwh, electricity_kwh=None), noise_seed
        )
    if gaps is not None:
        t, q_kwh = t.copy(), q_kwh.copy()
        t[gaps], q_kwh[gaps] = np.nan, np.nan
    write_site(
        tmp_path,
        name="synthetic",
        weather="usa_il_chicago",
        start=START,
        floor_area_m2=5000,
        number_of_floors=3,
        settings=settings,
        temperature_c=t,
        consumption_kwh=q_kwh,
        known=known,
        effects=declared,
    )
    return load_site(tmp_path)


def _truth() -> np.ndarray:
    theta = {
        "infiltration_ach": 0.5,
        "capacitance_kj_per_k_m3": 120,
        "heating_power_w_m2": 50,
        "cooling_power_w_m2": 60,
        "occupant_density_per_m2": 0.05,
        "plug_load_w_m2": 9.0,  # 0.06 workstations of 150 W per m2
        "lighting_power_w_m2": 10.0,
        "heat_recovery_effectiveness": 0.0,
        "minimum_supply_air_ach": 0.0,
        "night_cycle_heating_share": 0.0,
        "economiser_share": 0.0,
        "infiltration_fans_on_share": 1.0,
        "light_night_percent": 20,
        "pc_night_percent": 25,
        "wall_insulation_north_m": 0.1,
        "wall_insulation_east_m": 0.1,
        "wall_insulation_south_m": 0.1,
        "wall_insulation_west_m": 0.1,
        "roof_insulation_m": 0.1,
        "window_to_wall_north_percent": 40,
        "window_to_wall_east_percent": 40,
        "window_to_wall_south_percent": 40,
        "window_to_wall_west_percent": 40,
    }
    occupancy = [8, 18] * len(cat.WEEKDAYS)
    return np.array([theta[n] for n in cal.free_theta()] + occupancy, float)


@pytest.fixture(scope="module")
def surrogate():
    return load_metamodel()


def test_calibration_recovers_known_parameters(tmp_path, surrogate):
    truth = _truth()
    # one November week cannot tell an economiser from thermal mass (both take the edge off a mild afternoon's
    # cooling): the air handling unit's type is declared, as its engineer knows it
    site = _synthetic_site(tmp_path, surrogate, truth, known={"economiser_share": 0.0})
    # two independent CMA-ES runs, the best kept (`--restarts`): one run can settle in a local optimum
    result = calibrate_site(site, surrogate, weeks=[0], method="cmaes", seed=0, max_evaluations=6000, restarts=2)
    assert result["fit"]["r2_t"] > 0.97 and result["fit"]["r2_q"] > 0.97
    assert result["heldout"]["cv_rmse_q_percent"] < 10.0
    # the parameters that drive the two series: occupied hours (a period covers the whole hours h with
    # start <= h < end, so 7.2 and 8 mean the same), the electric gains, air leakage and thermal mass; plug
    # loads and lighting differ only in their night shares, so one week tells their sum, not each
    occ = np.ceil(np.asarray(result["occupancy"]))
    assert np.abs(occ - np.array([[8, 18]] * 5)).max() <= 1.0
    got = result["theta"]
    assert got["plug_load_w_m2"] + got["lighting_power_w_m2"] == pytest.approx(19.0, abs=1.9)
    assert got["infiltration_ach"] == pytest.approx(0.5, abs=0.1)
    assert got["capacitance_kj_per_k_m3"] == pytest.approx(120, abs=30)
    assert (tmp_path / "calibration.json").is_file() and load_site(tmp_path).calibration["method"] == "cmaes"
    ranges = cal.parameter_ranges({}, surrogate)
    for entry in result["at_bounds"]:  # estimates only, each within its tolerance of the bound it names
        lo, hi = ranges[entry["name"]]  # the catalogue's range within the metamodel's
        assert entry["name"] not in cal.KNOWN_GEOMETRY and entry["limit"] == {"min": lo, "max": hi}[entry["bound"]]
        assert abs(result["theta"][entry["name"]] - entry["limit"]) <= cal.AT_BOUND_SHARE * (hi - lo) + 1e-5


def test_parameters_at_a_bound_of_the_catalogue_are_reported(surrogate):
    ranges = cal.parameter_ranges({}, surrogate)  # the ranges the shipped metamodel was trained on
    theta = {n: sum(ranges.get(n, (cat.get(n).min, cat.get(n).max))) / 2 for n in cat.THETA_NAMES}
    theta.update(
        capacitance_kj_per_k_m3=24.0,  # 4 of a 280 range from its minimum: at it (2 % = 5.6)
        heating_power_w_m2=147.0,  # 3 of a 145 range from its maximum: not (2 % = 2.9)
        pc_night_percent=70.0,
        light_night_percent=0.0,
        floor_area_m2=1000.0,
    )
    found = cal.parameters_at_bounds(theta, {"light_night_percent": 0.0}, surrogate)  # known: not an estimate
    assert [(e["name"], e["bound"], e["limit"]) for e in found] == [
        ("capacitance_kj_per_k_m3", "min", 20.0),
        ("pc_night_percent", "max", 70.0),
    ]  # geometry is not either
    assert found[0]["value"] == 24.0
    note = cal.at_bounds_note(
        {"at_bounds": found, "known": ["light_night_percent"], "not_read": sorted(surrogate.implied)}
    )
    assert "\n" not in note and note.startswith("note: 2 of 21 estimated building parameters")
    assert "capacitance_kj_per_k_m3 at its min 20" in note and "pc_night_percent at its max 70" in note
    assert cal.at_bounds_note({"at_bounds": [], "known": []}) is None


def test_calibrate_command_prints_its_parameters_at_a_bound(tmp_path, surrogate, capsys):
    from buildenv.cli.main import main

    _synthetic_site(tmp_path, surrogate, _truth(), weeks=1)
    assert main(["calibrate", "--site", str(tmp_path), "--evaluations", "200", "--quiet", "--json"]) == 0
    out, err = capsys.readouterr()
    result = json.loads(out)  # standard JSON: no NaN
    assert {e["name"] for e in result["at_bounds"]} <= set(cal.free_theta())
    lines = err.strip().splitlines()
    assert lines[-1] == result["verdict"]["line"] and lines[-1].startswith("Guideline 14: ")  # the last line
    if result["at_bounds"]:
        assert lines[-2] == cal.at_bounds_note(result)
    else:
        assert "note:" not in err
    assert json.loads((tmp_path / "calibration.json").read_text())["verdict"] == result["verdict"]


def test_declared_known_parameters_stay_fixed_and_leave_the_search(tmp_path, surrogate):
    known = {"pc_night_percent": 25.0, "window_to_wall_south_percent": 40.0, "heating_power_w_m2": 50.0}
    site = _synthetic_site(tmp_path, surrogate, _truth(), known=known)
    problem = cal.build_problem(site, [0], context_hours=surrogate.context_hours)
    fixed = [problem.names.index(n) for n in known]
    assert problem.free.sum() == problem.dim - len(known) and not problem.free[fixed].any()
    z = np.random.default_rng(0).random((4, problem.free.sum()))
    params = problem.from_unit(z)
    np.testing.assert_array_equal(params[:, fixed], np.broadcast_to([25.0, 40.0, 50.0], (4, 3)))
    np.testing.assert_allclose(problem.to_unit(params[1]), z[1])
    for method, kwargs in (("cmaes", {"max_evaluations": 400}), ("adam", {})):
        result = calibrate_site(site, surrogate, weeks=[0], method=method, seed=0, save=False, **kwargs)
        assert {n: result["theta"][n] for n in known} == known and result["known"] == sorted(known)


def test_restarts_keep_the_best_of_independent_runs(tmp_path, surrogate):
    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=1)
    problem = cal.build_problem(site, [0], context_hours=surrogate.context_hours)
    _, single = cal.calibrate_cmaes(problem, surrogate, seed=0, max_evaluations=120)
    best, info = cal.calibrate_cmaes(problem, surrogate, seed=0, max_evaluations=120, restarts=3)
    assert len(info["run_costs"]) == 3 and info["run_costs"][0] == single["cost"]  # run 0 is the single run
    assert info["cost"] == min(info["run_costs"]) and info["evaluations"] >= 3 * 100
    assert cal.evaluate(problem, surrogate, best[None])[0] == pytest.approx(info["cost"], abs=1e-6)
    runs = info["run_parameters"]
    assert runs.shape == (3, problem.dim)
    np.testing.assert_allclose(cal.evaluate(problem, surrogate, runs), info["run_costs"], atol=1e-6)
    np.testing.assert_array_equal(runs[int(np.argmin(info["run_costs"]))], best)
    with pytest.raises(cal.CalibrationError, match="restarts must be at least 1"):
        cal.calibrate_cmaes(problem, surrogate, restarts=0)


def test_a_calibration_with_restarts_scores_each_run_on_the_heldout_weeks(tmp_path, surrogate):
    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=2)
    result = calibrate_site(site, surrogate, seed=3, max_evaluations=150, restarts=2, save=False)
    assert [r["seed"] for r in result["runs"]] == [3, 4] and min(r["cost"] for r in result["runs"]) == pytest.approx(
        result["cost"], abs=1e-5
    )
    best = min(result["runs"], key=lambda r: r["cost"])  # no effects: the kept run is the result's model
    assert best["heldout_rmse_t_celsius"] == pytest.approx(result["heldout"]["rmse_t_celsius"], abs=1e-4)
    assert "runs" not in calibrate_site(site, surrogate, max_evaluations=150, save=False)


def test_runs_that_fit_alike_but_predict_the_heldout_weeks_apart_are_noted():
    def runs(*rows):
        return {"runs": [{"seed": k, "cost": c, "heldout_rmse_t_celsius": e} for k, (c, e) in enumerate(rows)]}

    note = cal.runs_note(runs((0.319, 1.32), (0.324, 1.21), (0.329, 0.61)))  # the October twin's three runs
    assert "\n" not in note and note.startswith("note: 3 of 3 CMA-ES runs") and "RMSE_T 0.61 to 1.32 K" in note
    assert cal.runs_note(runs((0.222, 0.57), (0.203, 0.54), (0.203, 0.54))) is None  # the default site's: agree
    assert cal.runs_note(runs((0.20, 0.40), (0.30, 1.30))) is None  # the one that predicts apart fits worse
    assert cal.runs_note(runs((0.20, 0.40), (0.209, 0.59))) is None  # under 1.5x apart
    assert cal.runs_note(runs((0.20, 0.40), (0.209, 0.61))) is not None
    assert cal.runs_note(runs((0.20, 0.40))) is None and cal.runs_note({}) is None


def test_anchored_refit_stays_near_its_start_unless_the_fit_pays(tmp_path, surrogate):
    truth = _truth()
    site = _synthetic_site(tmp_path, surrogate, truth, weeks=1)
    problem = cal.build_problem(site, [0], context_hours=surrogate.context_hours)
    start = problem.from_unit(np.full(int(problem.free.sum()), 0.5))[0]  # far from the truth
    stds = np.full(len(start), 0.25)
    free, _ = cal.calibrate_cmaes(problem, surrogate, seed=0, max_evaluations=300, start=start, stds=stds)
    held, info = cal.calibrate_cmaes(
        problem, surrogate, seed=0, max_evaluations=300, start=start, stds=stds, anchor=300.0
    )
    move = lambda p: float(np.abs(problem.to_unit(p) - problem.to_unit(start)).max())  # noqa: E731
    assert move(held) < 0.1 < move(free)  # a strong pull keeps every parameter near the start (CMA-ES budget)
    assert cal.evaluate(problem, surrogate, held[None])[0] == pytest.approx(info["cost"], abs=1e-6)  # plain cost
    loose = np.zeros(len(start), bool)
    loose[np.flatnonzero(problem.free)[0]] = True  # only the first free parameter pulled: the others move
    part, _ = cal.calibrate_cmaes(
        problem, surrogate, seed=0, max_evaluations=300, start=start, stds=stds, anchor=300.0, anchored=loose
    )
    assert abs(problem.to_unit(part)[0] - 0.5) < 0.05 and move(part) > 0.05
    with pytest.raises(cal.CalibrationError, match="anchor must be at least 0"):
        cal.calibrate_cmaes(problem, surrogate, start=start, anchor=-1.0)


def test_gradient_calibration_fits_too(tmp_path, surrogate):
    site = _synthetic_site(tmp_path, surrogate, _truth())
    result = calibrate_site(site, surrogate, weeks=[0], method="adam", seed=0, save=False)
    assert result["fit"]["r2_t"] > 0.95 and result["fit"]["r2_q"] > 0.95


@pytest.mark.parametrize("method", ["cmaes", "adam"])
def test_calibration_encodes_the_context_its_metamodel_was_trained_with(tmp_path, surrogate, method):
    """A metamodel that sees three days before each week (``buildenv train --context-hours 72``; here the
    default's weights, which take any length) is calibrated on inputs encoded with three days."""
    assert surrogate.context_hours != 72
    checkpoint = dataclasses.replace(
        surrogate.checkpoint, metadata={**surrogate.checkpoint.metadata, "context_hours": 72}
    )
    three_days = sg.Surrogate(checkpoint)
    site = _synthetic_site(tmp_path, three_days, _truth())
    problem = cal.build_problem(site, [0, 1], context_hours=72)
    assert problem.x_base.shape[1] == 72 + 168
    with pytest.raises(sg.CheckpointError, match="72"):
        cal.predict(cal.build_problem(site, [0, 1]), three_days, _truth())
    result = calibrate_site(site, three_days, weeks=[0], method=method, seed=0, max_evaluations=1500, save=False)
    assert result["fit"]["r2_t"] > 0.9 and result["fit"]["r2_q"] > 0.9


def _reading_temperature_before(surrogate: sg.Surrogate) -> sg.Surrogate:
    """The metamodel given the temperature measured before the week as two more inputs, with zero weights (it
    predicts what ``surrogate`` does), as ``buildenv train --init ... --temperature-before`` starts."""
    import copy

    from metamodels.checkpoint import Checkpoint
    from metamodels.models import with_more_inputs
    from metamodels.normalisation import Standardiser

    ck = surrogate.checkpoint
    net = with_more_inputs(copy.deepcopy(ck.model), ck.name, ck.config, ck.inputs, ck.outputs, 2)
    norm = Standardiser(
        np.r_[ck.input_norm.mean, 21.0, 0.7].astype(np.float32), np.r_[ck.input_norm.std, 2.0, 0.45].astype(np.float32)
    )
    meta = {**ck.metadata, "input_channels": list(sg.ALL_CHANNELS)}
    return sg.Surrogate(Checkpoint(ck.name, ck.config, net, norm, ck.output_norm, meta))


@pytest.mark.parametrize("method", ["cmaes", "adam"])
def test_calibration_feeds_the_temperature_measured_before_each_week(tmp_path, surrogate, method):
    """A metamodel that reads the temperature measured before the week (the shipped default does) gets the end
    of the site's previous measured week (unknown before the first), less the sensor bias the model carries."""
    from buildenv.diagnosis import model_effects as em

    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=3)  # simulated with nothing known before
    reading = surrogate if surrogate.uses_temperature_before else _reading_temperature_before(surrogate)
    ctx = surrogate.context_hours
    value, known = len(sg.INPUT_CHANNELS), len(sg.INPUT_CHANNELS) + 1
    problem = cal.build_problem(site, [0, 2], context_hours=ctx, temperature_before=True)
    np.testing.assert_array_equal(problem.x_base[1, :ctx, value], site.temperature_c[1, -ctx:].astype(np.float32))
    assert (problem.x_base[1, :ctx, known] == 1).all() and (problem.x_base[1, ctx:, known] == 0).all()
    assert (problem.x_base[0, :, known] == 0).all() and np.isnan(problem.x_base[0, :, value]).all()
    plain = cal.build_problem(site, [0, 2], context_hours=ctx)
    np.testing.assert_array_equal(problem.x_base[..., :value], plain.x_base)
    if not surrogate.uses_temperature_before:  # zero weights: the widened model predicts what it did
        np.testing.assert_allclose(
            cal.predict(problem, reading, _truth())[0], cal.predict(plain, surrogate, _truth())[0], rtol=0, atol=1e-3
        )
    unbiased = em.transform_inputs(problem.x_base.copy(), {"temperature_sensor_bias": np.array([[0.5]])})
    np.testing.assert_allclose(unbiased[1, :ctx, value], problem.x_base[1, :ctx, value] - 0.5, rtol=1e-6)
    result = calibrate_site(site, reading, weeks=[0, 1], method=method, seed=0, max_evaluations=1500, save=False)
    assert result["fit"]["r2_t"] > 0.9 and result["fit"]["r2_q"] > 0.9


def test_masked_gaps_change_nothing_else(tmp_path, surrogate):
    truth = _truth()
    full = _synthetic_site(tmp_path / "full", surrogate, truth)
    gaps = np.zeros((2, 168), bool)
    gaps[0, 30:40] = gaps[1, 100:130] = True
    gapped = _synthetic_site(tmp_path / "gapped", surrogate, truth, gaps=gaps)
    assert not gapped.temperature_mask[gaps].any() and gapped.temperature_mask[~gaps].all()
    rng = np.random.default_rng(0)
    problem_full, problem_gap = (
        cal.build_problem(site, [0, 1], context_hours=surrogate.context_hours) for site in (full, gapped)
    )
    params = problem_full.lo + rng.random((6, problem_full.dim)) * (problem_full.hi - problem_full.lo)
    out = load_metamodel().predict_encoded(cal.encode_candidates(problem_full, params)).reshape(6, 2, 168, -1)
    # the cost over the gapped site equals the cost over the full site restricted to the measured hours
    masked = cal.Problem(
        **{
            **problem_full.__dict__,
            "temperature_c": np.where(gaps, np.nan, problem_full.temperature_c),
            "consumption_wh_m2": np.where(gaps, np.nan, problem_full.consumption_wh_m2),
        }
    )
    series = cal.model_series(problem_full, out)
    np.testing.assert_allclose(cal.costs(problem_gap, *series), cal.costs(masked, *series), rtol=1e-4)
    assert np.isfinite(cal.costs(problem_gap, *series)).all()


def test_declared_effect_is_fitted_after_the_building_and_kept_in_the_site_model(tmp_path, surrogate):
    from buildenv.calibration.plot import plot_calibration
    from buildenv.sites.week_simulator import SiteModel

    effect = ("night_cycle_cold_air",)
    site = _synthetic_site(tmp_path, surrogate, np.r_[_truth(), 0.15, 0.3, 5.0], effects=effect, declared=effect)
    result = calibrate_site(site, surrogate, weeks=[0], seed=0, max_evaluations=2500)  # site.toml's effect
    fitted = result["effects"]["night_cycle_cold_air"]
    assert result["declared_effects"] == list(effect) and result["cost"] < result["cost_without_effects"]
    assert fitted["cooling_k_per_wh_m2"] > 0.05  # its reheat share trades against the building's heating
    # the held-out week is scored with the effect: better than the same building without it
    problem = cal.build_problem(site, [1], effect, context_hours=surrogate.context_hours)
    params = cal.calibrated_parameters(result, effect)
    without = cal.score_series(
        problem, *cal.predict(problem, surrogate, np.r_[params[:-3], 0.0, 0.0, 0.0]), params, cal._scale(problem)
    )
    assert result["heldout"]["r2_t"] > without["r2_t"]
    saved = load_site(tmp_path)
    assert saved.calibration["effects"] == result["effects"]
    model = SiteModel.from_site(saved, surrogate)
    assert set(model.effects) == set(effect)  # BuildingWeek-v0 simulates it
    assert plot_calibration(saved, surrogate, saved.calibration, tmp_path / "c.png").is_file()
    # both give the metamodel the ground temperature of the site's weather file in the site's calendar hours
    ctx = surrogate.context_hours
    expected = sg.weather_ground_c(saved.weather)[(saved.epw_hours()[:, :1] + np.arange(-ctx, 168)) % 8760]
    np.testing.assert_array_equal(cal.build_problem(saved, [0, 1], context_hours=ctx).x_base[..., -1], expected)
    np.testing.assert_array_equal(model.ground(np.array([model.week_of(START), model.week_of(START) + 1])), expected)
    from buildenv.energyplus.shoebox import ground_temperatures_c
    from buildenv.weather.epw import load_weather

    np.testing.assert_allclose(expected, ground_temperatures_c(load_weather(saved.weather))[10])  # November's


@pytest.mark.parametrize("bias_k", [0.0, 1.2])
def test_declared_effects_stage_keeps_the_building(tmp_path, surrogate, bias_k):
    # one free parameter: a bounded scalar search (pycma fails in one dimension; see _minimise_one)
    effect = ("temperature_sensor_bias",)
    site = _synthetic_site(tmp_path, surrogate, np.r_[_truth(), bias_k], weeks=1, effects=effect)
    problem = cal.build_problem(site, [0], effect, context_hours=surrogate.context_hours)
    base = _truth()
    params, info = cal.fit_declared_effects(problem, surrogate, base, seed=0, max_evaluations=200)
    np.testing.assert_array_equal(params[: problem.n_base], base)
    assert abs(params[-1] - bias_k) < 0.2 and info["evaluations"] <= 200


@pytest.mark.parametrize(
    "effects, message",
    [
        (("draughts",), "unknown effect 'draughts'"),
        (("holidays",), "cannot be declared"),
        (("heat_recovery", "heat_recovery"), "declared twice"),
    ],
)
def test_declaring_a_wrong_effect_is_a_clear_error(effects, message):
    with pytest.raises(cal.CalibrationError, match=message):
        cal.check_declared_effects(effects)


def test_the_problem_sums_the_outputs_of_the_sites_metered_end_uses(tmp_path):
    arrays = {
        "settings": historical_settings(1),
        "temperature_c": np.full((1, 168), 22.0),
        "consumption_kwh": np.full((1, 168), 10.0),
    }
    common = {"name": "s", "weather": "usa_il_chicago", "start": START, "floor_area_m2": 5000, "number_of_floors": 3}
    plain = load_site(write_site(tmp_path / "plain", **common, **arrays))
    cooled = write_site(tmp_path / "cooled", **common, **arrays, consumption_end_uses=("cooling", "lighting"))
    cooled = load_site(cooled)
    outputs = np.random.default_rng(0).random((2, 1, 168, len(cat.OUTPUT_NAMES)))
    col = {n: outputs[..., cat.OUTPUT_NAMES.index(n)] for n in cat.OUTPUT_NAMES}
    _, q_plain = cal.model_series(cal.build_problem(plain, [0]), outputs)
    _, q_cooled = cal.model_series(cal.build_problem(cooled, [0]), outputs)
    np.testing.assert_allclose(q_plain, col["Q_HEAT_OFFICE"] + col["Q_AHU_H"] + col["Q_EQP"] + col["Q_LIGHT"])
    np.testing.assert_allclose(q_cooled, col["Q_AC_OFFICE"] + col["Q_AHU_C"] + col["Q_LIGHT"])


@pytest.mark.slow
def test_a_site_metering_cooling_calibrates_on_its_cooling(tmp_path, surrogate):
    """A July stand-in whose meter sums heating + cooling + lighting + plug loads: calibrated on the outputs of
    those end uses it fits its consumption; the same series taken as the default meter (no cooling) does not."""
    uses = ("heating", "cooling", "lighting", "plug_loads")
    july = dt.date(2019, 7, 1)
    site = load_site(make_reference_site(tmp_path / "site", "medium_office", "usa_il_chicago", july, 2, end_uses=uses))
    assert site.consumption_end_uses == uses
    assert site.source["consumption_meter"].startswith("heating coils + cooling coils + interior lights")
    result = calibrate_site(site, surrogate, method="cmaes", seed=0, max_evaluations=1000, save=False)
    assert result["fit"]["r2_q"] > 0.85 and result["heldout"]["r2_q"] > 0.8
    heat_only = write_site(
        tmp_path / "heat_only",
        name="the same series, no [meters]",
        weather=site.weather,
        start=site.start,
        settings=site.settings,
        floor_area_m2=site.floor_area_m2,
        number_of_floors=site.number_of_floors,
        temperature_c=site.temperature_c,
        consumption_kwh=site.consumption_kwh,
    )
    wrong = calibrate_site(load_site(heat_only), surrogate, method="cmaes", seed=0, max_evaluations=1000, save=False)
    assert wrong["heldout"]["r2_q"] < 0.3


def test_a_site_metering_heat_and_electricity_apart_calibrates_on_both(tmp_path, surrogate):
    """A stand-in whose heat and electricity are metered apart: the two meters read what the one meter reads, and
    calibration fits and scores each (the cost takes the mean of their 1 - R2, the verdict judges both)."""
    november = dt.date(2019, 11, 4)
    split = make_reference_site(
        tmp_path / "split",
        "small_office",
        "usa_il_chicago",
        november,
        2,
        end_uses=("heating",),
        electricity_end_uses=("lighting", "plug_loads"),
    )
    one = load_site(make_reference_site(tmp_path / "one", "small_office", "usa_il_chicago", november, 2))
    split = load_site(split)
    assert split.source["electricity_meter"] == "interior lights + interior equipment"
    np.testing.assert_array_equal(split.temperature_c, one.temperature_c)  # the same run and noise
    total = split.consumption_kwh + split.electricity_kwh
    assert np.nansum(total) == pytest.approx(np.nansum(one.consumption_kwh), rel=0.005)
    for method in ("adam", "cmaes"):
        result = calibrate_site(split, surrogate, method=method, seed=0, max_evaluations=600, save=False)
        for part in ("fit", "heldout"):
            assert {"cv_rmse_e_percent", "nmbe_e_percent", "r2_e", "nmbe_e_monthly_percent"} <= set(result[part])
        assert "electricity CV(RMSE)" in result["verdict"]["line"]
    problem = cal.build_problem(
        split, [0], context_hours=surrogate.context_hours, temperature_before=surrogate.uses_temperature_before
    )
    params = cal.calibrated_parameters(result)[None]
    off = dataclasses.replace(problem, electricity_wh_m2=problem.electricity_wh_m2 + 5.0)
    assert cal.evaluate(off, surrogate, params)[0] > cal.evaluate(problem, surrogate, params)[0]
    with pytest.raises(cal.CalibrationError, match="second meter"):
        cal.costs(problem, *(series[None] for series in cal.predict(problem, surrogate, params[0])))


def test_a_meter_that_reads_one_value_throughout_is_refused_in_one_line(tmp_path, surrogate):
    arrays = {
        "settings": historical_settings(2),
        "temperature_c": np.full((2, 168), 22.0),
        "consumption_kwh": 20.0 + 10.0 * np.sin(np.arange(2 * 168) / 5.0).reshape(2, 168),
    }
    common = {"name": "s", "weather": "usa_il_chicago", "start": START, "floor_area_m2": 5000, "number_of_floors": 3}
    site = write_site(
        tmp_path / "gas",
        **common,
        **arrays,
        consumption_end_uses=("lighting", "plug_loads"),
        electricity_kwh=np.zeros((2, 168)),
        electricity_end_uses=("heating",),
    )
    with pytest.raises(
        cal.CalibrationError, match=r"electricity_kwh reads 0 kWh in every hour of the calibration weeks"
    ):
        calibrate_site(load_site(site), surrogate, save=False)


def test_a_calibration_records_its_metamodel_and_using_it_with_another_is_warned_about(surrogate, caplog):
    from buildenv.env.building_week import DEFAULT_SITE
    from buildenv.sites.week_simulator import SiteModel

    diagnosis = load_metamodel("diagnosis")
    record = cal.metamodel_record(surrogate)
    assert record["metamodel"] == "default" and record["metamodel_id"] == sg.checkpoint_identity(sg.DEFAULT_CHECKPOINT)
    assert cal.metamodel_mismatch(record, surrogate) is None
    assert "recalibrate" in cal.metamodel_mismatch(record, diagnosis)
    earlier = {"metamodel": "default"}  # written before calibrations recorded an identity: the earlier default
    assert cal.metamodel_mismatch(earlier, diagnosis) is None
    assert "the earlier default metamodel ('diagnosis')" in cal.metamodel_mismatch(earlier, surrogate)
    assert cal.metamodel_mismatch({"metamodel": None}, surrogate) is None  # made in memory: cannot tell
    site = load_site(DEFAULT_SITE)
    assert site.calibration["metamodel_id"] == record["metamodel_id"]  # the shipped site is the default's
    with caplog.at_level("WARNING"):
        SiteModel.from_site(site, surrogate)
        assert "recalibrate" not in caplog.text
        SiteModel.from_site(site, diagnosis)
    assert f"site {site.path}: calibration made with default, used with diagnosis" in caplog.text


def test_guideline14_monthly_judges_the_monthly_totals():
    from buildenv.metrics import guideline14_monthly

    months = np.repeat([1, 2, 3], 100)
    measured = np.ones(300)
    predicted = np.r_[np.full(100, 0.9), np.full(100, 1.0), np.full(100, 1.1)]
    out = guideline14_monthly(measured, predicted, months)
    assert out["months"] == 3 and out["nmbe_q_monthly_percent"] == pytest.approx(0.0, abs=1e-9)
    assert out["cv_rmse_q_monthly_percent"] == pytest.approx(100 * np.sqrt(2 * 10.0**2 / 2) / 100)  # n - p = 2
    one = guideline14_monthly(measured[:100], predicted[:100], months[:100])
    assert one["cv_rmse_q_monthly_percent"] is None and one["nmbe_q_monthly_percent"] == pytest.approx(10.0)
    measured[:50] = np.nan  # unmeasured hours leave the totals
    assert guideline14_monthly(measured, predicted, months)["nmbe_q_monthly_percent"] == pytest.approx(
        100 * (250 - (45 + 100 + 110)) / 250
    )


def test_the_verdict_passes_or_fails_a_calibration_and_the_site_is_warned_about_once(caplog):
    from buildenv.calibration.verdict import CalibrationFailed, calibration_verdict, check_calibration

    good = {"cv_rmse_q_percent": 12.0, "nmbe_q_percent": 2.0, "nmbe_q_monthly_percent": 2.0, "months": 1}
    result = {"fit": good, "heldout": good, "at_bounds": [{"name": "x"}]}
    verdict = calibration_verdict(result)
    assert verdict["passed"] and verdict["judged_on"] == "heldout" and verdict["at_bounds"] == 1
    assert verdict["line"].startswith("Guideline 14: PASSES (held-out weeks: hourly pass (CV(RMSE) 12.0 %")
    biased = {**good, "nmbe_q_monthly_percent": 7.0}  # within the hourly limits, not the monthly bias
    assert not calibration_verdict({**result, "heldout": biased})["passed"]
    older = {"cv_rmse_q_percent": 58.6, "nmbe_q_percent": -20.0}  # saved before monthly figures: hourly only
    failed = calibration_verdict({"fit": good, "heldout": older})
    assert not failed["passed"] and failed["heldout"]["monthly"] is None and "FAILS" in failed["line"]
    assert calibration_verdict({"fit": good})["judged_on"] == "fit"
    # held-out weeks without a measured consumption are not judged, not failed: the fit weeks are
    unmeasured = {"cv_rmse_q_percent": float("nan"), "nmbe_q_percent": float("nan")}
    fallback = calibration_verdict({"fit": good, "heldout": unmeasured})
    assert fallback["passed"] and fallback["judged_on"] == "fit" and "hourly not judged" in fallback["line"]
    with caplog.at_level("WARNING"):
        check_calibration({"fit": good, "heldout": older}, "/sites/a")
        check_calibration({"fit": good, "heldout": older}, "/sites/a")
        check_calibration(result, "/sites/b")
    assert caplog.text.count("site /sites/a: calibration Guideline 14: FAILS") == 1 and "/sites/b" not in caplog.text
    with pytest.raises(CalibrationFailed, match="recalibrate it or check its data"):
        check_calibration({"fit": good, "heldout": older}, "/sites/a", strict=True)


def test_a_failing_calibration_is_refused_where_asked_and_used_with_a_warning_otherwise(tmp_path, caplog):
    import gymnasium as gym

    import buildenv  # noqa: F401  (registers BuildingWeek-v0)
    from buildenv.calibration.verdict import CalibrationFailed
    from buildenv.cli.main import main
    from buildenv.errors import BuildingEnvError

    site = tmp_path / "site"
    shutil.copytree(Path(buildenv.__file__).parent / "data" / "sites" / "default", site)
    calibration = json.loads((site / "calibration.json").read_text())
    calibration["heldout"].update(cv_rmse_q_percent=58.6, nmbe_q_percent=-20.0)
    (site / "calibration.json").write_text(json.dumps(calibration))
    with caplog.at_level("WARNING"):
        gym.make("BuildingWeek-v0", site=str(site)).reset(seed=0)
    assert f"site {site}: calibration Guideline 14: FAILS" in caplog.text
    with pytest.raises(CalibrationFailed, match="recalibrate it or check its data"):
        gym.make("BuildingWeek-v0", site=str(site), strict_calibration=True).reset(seed=0)
    with pytest.raises(BuildingEnvError, match="strict_calibration='yes'; pass True or False"):
        gym.make("BuildingWeek-v0", site=str(site), strict_calibration="yes")
    # the commands: one line and exit status 2
    assert main(["optimize", "--method", "rules", "--site", str(site), "--json", "--strict-calibration"]) == 2
    assert main(["diagnose", "--site", str(site), "--strict-calibration", "--quiet"]) == 2


def test_a_week_given_twice_is_refused_not_counted_twice(surrogate):
    from diagnosis_site import DEFAULT_SITE

    from buildenv.sites import load_site

    with pytest.raises(cal.CalibrationError, match=r"week\(s\) \[0\] given twice"):
        cal.build_problem(load_site(DEFAULT_SITE), [0, 0, 1], context_hours=surrogate.context_hours)


def _series_problem(consumption: np.ndarray, daily_weight: float) -> cal.Problem:
    weeks = consumption.shape[0]
    temperature = 21.0 + np.sin(np.arange(weeks * 168) / 24 * 2 * np.pi).reshape(weeks, 168)
    return cal.Problem(
        np.zeros((weeks, 168, 1)), temperature, consumption, {}, [], np.zeros(0), np.zeros(0), daily_weight=daily_weight
    )


def test_the_daily_term_charges_a_fit_whose_days_are_off_but_not_one_whose_hours_scatter():
    rng = np.random.default_rng(0)
    measured = 5.0 + 3.0 * rng.random((2, 168))
    sign = np.tile([1.0, -1.0], 84)  # errors that cancel within each day
    day_sign = np.repeat(np.tile([1.0, -1.0], 7), 24)[:168]  # the same errors, one sign a day
    scattered, shifted = measured + 0.5 * sign, measured + 0.5 * day_sign
    t = np.broadcast_to(_series_problem(measured, 0.0).temperature_c, (2, 2, 168))
    q = np.stack([scattered, shifted])
    plain = cal.costs(_series_problem(measured, 0.0), t, q)
    daily = cal.costs(_series_problem(measured, 1.0), t, q)
    np.testing.assert_allclose(plain[0], plain[1])  # the hourly terms cannot tell them apart
    np.testing.assert_allclose(daily[0], plain[0], atol=1e-9)  # scattered hours leave the days' totals right
    assert daily[1] > plain[1] + 0.5
    gaps = measured.copy()
    gaps[0, 5] = np.nan  # a day with a missing hour is left out of the daily term, not counted as zero
    assert np.isfinite(cal.costs(_series_problem(gaps, 1.0), t, q)).all()


def test_the_gradient_calibrations_meter_cost_is_the_cost_of_the_problem():
    torch = pytest.importorskip("torch")
    from buildenv.calibration.gradient import _meter_cost

    rng = np.random.default_rng(1)
    measured = 5.0 + 3.0 * rng.random((2, 168))
    measured[1, 40] = np.nan
    q = measured[None] + rng.normal(0, 0.5, (3, 2, 168))
    q = np.nan_to_num(q, nan=5.0)
    problem = _series_problem(measured, 1.0)
    t = np.broadcast_to(problem.temperature_c, (3, 2, 168))
    expected = cal.costs(problem, t, q)  # temperature term 0: the model reads it exactly
    got = _meter_cost(
        torch.tensor(np.nan_to_num(measured)), torch.tensor(q), torch.tensor(np.isfinite(measured)), 1.0
    ).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-6)


def test_the_calibrate_command_takes_the_daily_weight_and_records_it(tmp_path, surrogate, capsys):
    from buildenv.cli.main import main

    _synthetic_site(tmp_path, surrogate, _truth(), weeks=2)
    args = ["calibrate", "--site", str(tmp_path), "--evaluations", "100", "--quiet", "--json", "--no-prior"]
    assert main([*args, "--daily-weight", "1"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["daily_weight"] == 1.0 == json.loads((tmp_path / "calibration.json").read_text())["daily_weight"]
    site = load_site(tmp_path)
    problem = cal.build_problem(site, result["fit_weeks"], context_hours=surrogate.context_hours, daily_weight=1.0)
    params = np.array([*(result["theta"][n] for n in cal.free_theta()), *np.ravel(result["occupancy"])])
    assert result["cost"] == pytest.approx(float(cal.evaluate(problem, surrogate, params[None])[0]), abs=1e-4)
    with pytest.raises(SystemExit):
        main([*args, "--daily-weight", "nan"])
    assert "expected a weight of 0 or more" in capsys.readouterr().err


def test_a_first_fit_kept_under_the_prior_keeps_each_of_its_runs(tmp_path, surrogate, monkeypatch):
    import buildenv.calibration.calibrate as calibrate_module

    real = calibrate_module.calibrate_cmaes

    def no_better_under_the_prior(problem, surrogate, seed, max_evaluations, **kwargs):
        best, info = real(problem, surrogate, seed, max_evaluations, **kwargs)
        if kwargs.get("anchor"):  # the search under the prior finds nothing better than the first fit
            far = np.repeat(problem.lo[None], len(info["run_costs"]), axis=0)
            info = {**info, "run_parameters": far, "run_costs": [1e9] * len(far)}
        return best, info

    monkeypatch.setattr(calibrate_module, "calibrate_cmaes", no_better_under_the_prior)
    site = _synthetic_site(tmp_path, surrogate, _truth(), weeks=2)
    result = calibrate_site(site, surrogate, seed=3, max_evaluations=150, restarts=2, save=False)
    assert result["prior"]["kept_first_fit"]
    assert [r["seed"] for r in result["runs"]] == [3, 4]
    assert min(r["cost"] for r in result["runs"]) == pytest.approx(result["cost"], abs=1e-5)
