"""The model side of the effects and the gap diagnosis (attribution, JSON shape, the extended site model)."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from diagnosis_site import DEFAULT_SITE

from buildenv.calibration import problem as cal
from buildenv.calibration.calibrate import calibrate_site
from buildenv.catalogue import WEATHER_NAMES
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import (
    EFFECTS,
    EffectError,
    get_effect,
    night_electricity_w_m2,
    parse_effect,
)
from buildenv.diagnosis.evidence import Evidence
from buildenv.diagnosis.gap import DiagnosisSettings, diagnose, save_extended_model
from buildenv.diagnosis.refit import ModelFit, with_declared_effects, without_new_effect
from buildenv.diagnosis.score import stricter_score
from buildenv.diagnosis.split import split_weather
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site, write_site
from buildenv.sites.week_simulator import SiteModel

MODEL_EFFECTS = [e for e in EFFECTS if e != "holidays"]


#: the outputs a heat meter and an electricity meter read
HEAT_AND_POWER = (("Q_HEAT_OFFICE", "Q_AHU_H"), ("Q_EQP", "Q_LIGHT"))


@pytest.fixture(scope="module")
def surrogate():
    return load_metamodel("diagnosis")


@pytest.fixture(scope="module")
def calibrated():
    """The default site as the diagnosis measured it, and its calibrated parameters."""
    site = load_site(DEFAULT_SITE)
    return site, cal.calibrated_parameters(site.calibration)


def _predict(site, surrogate, params, effects=(), values=()):
    problem = cal.build_problem(site, [0, 1], tuple(effects), context_hours=surrogate.context_hours)
    return cal.simulate(problem, surrogate, np.concatenate([params, *values])[None])


def test_catalogue_lists_the_ten_effects_with_magnitudes_and_parameters():
    assert set(EFFECTS) >= {
        "wind_infiltration",
        "temperature_sensor_bias",
        "temperature_sensor_lag",
        "holidays",
        "night_plug_loads",
        "solar_shading",
        "heating_capacity_limit",
        "heat_recovery",
        "night_cycle_cold_air",
        "evening_departure",
    }
    for e in EFFECTS.values():
        lo, hi = e.magnitude_range
        assert lo < hi and e.kind in ("energyplus", "sensor") and e.series
        for p in e.parameters:
            assert p.lo <= p.none <= p.hi
    assert parse_effect("temperature_sensor_bias=2")[1] == 2.0
    with pytest.raises(EffectError, match="did you mean temperature_sensor_bias"):
        get_effect("temperature_sensor_bais")
    with pytest.raises(EffectError, match="outside"):
        parse_effect("heat_recovery=150")


def test_an_effect_is_named_only_at_a_size_seen_in_practice():
    for e in EFFECTS.values():
        if e.smallest is None:
            continue
        if not e.parameters:  # holidays: judged by the absent days it flags in the fit weeks
            assert not e.plausible({"absent_days": 0}) and e.plausible({"absent_days": 1}), e.name
            continue
        none = {p.name: p.none for p in e.parameters}
        assert not e.plausible(none), e.name
        assert e.plausible({**none, e.parameters[0].name: e.parameters[0].hi}), e.name
    recovery = get_effect("heat_recovery")
    assert not recovery.plausible({"effectiveness": 0.108}) and recovery.plausible({"effectiveness": 0.6})
    bias = get_effect("temperature_sensor_bias")  # a class-B sensor's tolerance, on either side
    assert bias.plausible({"bias_k": -0.4}) and bias.plausible({"bias_k": 0.45}) and not bias.plausible({"bias_k": 0.3})
    # a carried effect: a catalogue step away from where it vanishes (the top of the heating power's range)
    plant = get_effect("heating_capacity_limit")
    assert not plant.plausible({"heating_power_w_m2": 99.85}) and plant.plausible({"heating_power_w_m2": 36.0})
    assert plant.plausible({"capacity_w_m2": 99.0, "sag_k_per_wh_m2": 0.0})  # its model side: no floor


def test_effects_at_their_none_values_change_nothing(calibrated, surrogate):
    site, params = calibrated
    base = _predict(site, surrogate, params)
    extended = _predict(site, surrogate, params, MODEL_EFFECTS, [em.none_parameters(e) for e in MODEL_EFFECTS])
    for a, b in zip(base, extended):
        np.testing.assert_array_equal(a, b)


EVENING = np.isin(np.arange(168) % 24, [20, 21]) & (np.arange(168) < 120)  # weekdays, after the occupancy
MORNING = np.isin(np.arange(168) % 24, [9, 10, 11])
AFTER_HEATING = np.arange(168) % 24 == 18  # the default site's settings: heating 7-18, ventilation 7-19


@pytest.mark.parametrize(
    "name, values, check",
    [
        ("temperature_sensor_bias", [1.5], lambda d: np.allclose(d["t"], 1.5, atol=1e-5) and np.all(d["q"] == 0)),
        ("temperature_sensor_lag", [2.0], lambda d: np.abs(d["t"]).max() > 0.2 and np.all(d["q"] == 0)),
        ("night_plug_loads", [3.0], lambda d: np.isclose(d["q"].max(), 3.0, atol=1e-3) and d["q"].min() >= 0),
        ("wind_infiltration", [0.05], lambda d: d["q"].sum() > 0 and d["t"].mean() < 0),
        ("solar_shading", [0.6], lambda d: d["t"].mean() < 0),
        (
            "heating_capacity_limit",
            [15.0, 0.05],
            lambda d: d["q"].max() <= 1e-4 and d["q"].min() < 0 and d["t"].min() < 0,
        ),
        ("heat_recovery", [0.7], lambda d: d["q"].max() <= 1e-4 and d["q"].sum() < 0),
        (
            "night_cycle_cold_air",
            [0.1, 0.2, 0.0],
            lambda d: d["t"].max() <= 1e-5 and d["t"].min() < -0.1 and d["q"].min() >= -1e-4 and d["q"].max() > 0.2,
        ),
        # the ventilation runs an hour past the heating (the default site's 18:00): cold unheated supply air
        (
            "night_cycle_cold_air",
            [0.0, 0.0, 6.0],
            lambda d: (
                np.all(d["t"] == 0)
                and d["q"].max() <= 1e-4
                and d["q"][..., AFTER_HEATING].min() < -1.0
                and np.all(d["q"][..., ~AFTER_HEATING] == 0)
            ),
        ),
        (
            "evening_departure",
            [0.4, 3.0],
            lambda d: (
                d["t"][..., EVENING].mean() > 0.1
                and d["q"][..., EVENING].mean() > 0.5
                and np.abs(d["q"][..., MORNING]).max() < 0.5
            ),
        ),
    ],
)
def test_each_effect_moves_the_prediction_the_expected_way(calibrated, surrogate, name, values, check):
    site, params = calibrated
    _, t0, q0 = _predict(site, surrogate, params)
    _, t1, q1 = _predict(site, surrogate, params, [name], [np.array(values, float)])
    assert check({"t": t1 - t0, "q": q1 - q0})


def _two_weeks_of(site) -> dict:
    """``write_site``'s arguments of a site in ``site``'s building and weather over its first two weeks."""
    keys = ("weather", "start", "floor_area_m2", "number_of_floors")
    return {**{k: getattr(site, k) for k in keys}, "settings": site.settings[:2]}


def test_an_absent_day_is_simulated_without_occupants_and_found_from_both_series(tmp_path, calibrated, surrogate):
    from buildenv.diagnosis.refit import ModelFit, detect_absent_days, make_context
    from buildenv.diagnosis.score import days_lacking

    site, params = calibrated
    absent = np.zeros((site.weeks, 7))
    absent[1, 1] = 1.0  # the second week's Tuesday: nobody came
    problem = cal.build_problem(site, [0, 1], (), absent, context_hours=surrogate.context_hours)
    _, t_abs, q_abs = cal.simulate(problem, surrogate, params[None])
    _, t0, q0 = _predict(site, surrogate, params)
    tuesday = slice(24 + 9, 24 + 17)  # its occupied hours: no lights, plug loads or people, a colder building
    assert (q_abs[0, 1, tuesday] < q0[0, 1, tuesday] - 1.0).all()
    assert t_abs[0, 1, tuesday].mean() < t0[0, 1, tuesday].mean() - 0.2
    for a, b in ((t_abs, t0), (q_abs, q0)):  # the other week is untouched
        np.testing.assert_array_equal(a[0, 0], b[0, 0])
    # the Monday before barely (the metamodel attends 12 hours either way)
    np.testing.assert_allclose(t_abs[0, 1, :24], t0[0, 1, :24], atol=0.1)
    np.testing.assert_allclose(q_abs[0, 1, :24], q0[0, 1, :24], atol=1.0)
    # a site measured as the model says with that day absent (plus sensor noise): that day is found, no other
    rng = np.random.default_rng(0)
    measured_q = q_abs[0] * (1 + 0.01 * rng.standard_normal(q_abs[0].shape))
    write_site(
        tmp_path,
        name="absent",
        **_two_weeks_of(site),
        temperature_c=t_abs[0] + 0.1 * rng.standard_normal(t_abs[0].shape),
        consumption_kwh=measured_q * site.floor_area_m2 / 1000.0,
    )
    measured = load_site(tmp_path)
    ctx = make_context(measured, surrogate, DiagnosisSettings())
    ctx.sigma = (0.3, 2.5)
    found = detect_absent_days(ctx, ModelFit((), params, np.zeros((2, 7)), 0.0, 0), [0, 1])
    assert found[1, 1] > 0.8 and np.count_nonzero(found) == 1
    # that day falls in the held-out week: nothing in the fit week to estimate holidays from, not enough data
    holidays = ModelFit(("holidays",), params, np.zeros((2, 7)), 0.0, 0)
    assert ctx.fit_weeks == [0] and days_lacking(ctx, holidays).startswith(
        "1 absent day(s) in the held-out weeks and none in the fit weeks"
    )


def test_a_site_metering_heat_and_electricity_apart_is_diagnosed_on_its_meters_summed(tmp_path, calibrated, surrogate):
    from buildenv.catalogue import OUTPUT_NAMES
    from buildenv.diagnosis.refit import make_context, measured_consumption, metrics, predict

    site, params = calibrated
    problem = cal.build_problem(site, [0, 1], context_hours=surrogate.context_hours)
    outputs, t, _ = cal.simulate(problem, surrogate, params[None])
    heat, power = (outputs[0][..., [OUTPUT_NAMES.index(n) for n in names]].sum(-1) for names in HEAT_AND_POWER)
    kwh = site.floor_area_m2 / 1000.0
    write_site(
        tmp_path,
        name="two meters",
        **_two_weeks_of(site),
        temperature_c=t[0],
        consumption_kwh=np.maximum(heat, 0.0) * kwh,  # a meter reads no negative heat
        consumption_end_uses=("heating",),
        electricity_kwh=power * kwh,
        electricity_end_uses=("lighting", "plug_loads"),
    )
    split = load_site(tmp_path)
    np.testing.assert_allclose(measured_consumption(split), np.maximum(heat, 0.0) + power, rtol=1e-3, atol=1e-3)
    ctx = make_context(split, surrogate, DiagnosisSettings())
    base = ModelFit((), params, np.zeros((2, 7)), 0.0, 0)
    # the first week (the second's context holds the measured temperature, which this site took from the model)
    t_model, q_model = predict(ctx, base, [0])
    np.testing.assert_allclose(q_model, (heat + power)[:1], rtol=1e-4, atol=1e-4)
    scores = metrics(ctx, base, [0], t_model, q_model)
    assert abs(scores["nmbe_q_percent"]) < 0.5 and scores["r2_q"] > 0.99


def test_wind_infiltration_is_a_quarter_while_the_air_handling_unit_runs_centred_on_the_reference_wind():
    # the DOE reference buildings' convention (and the stand-in's): a running air handling unit pressurises
    # the building, so only a quarter of the wind-driven infiltration is left; the term adds nothing where
    # share x wind speed is the reference, and the air changes never go below zero on a calm hour
    from buildenv.metamodel.surrogate import INPUT_CHANNELS

    ch = {n: i for i, n in enumerate(INPUT_CHANNELS)}
    x = np.zeros((1, 5, len(INPUT_CHANNELS)))
    x[..., ch["infiltration_ach"]] = 0.2
    x[..., ch["WIND_SPEED"]] = [4.0, 4.0, 4.0, em.WIND_REFERENCE_M_S, 0.0]
    x[0, :2, ch["ventilation_on"]] = 1.0
    k = 0.05
    out = em.transform_inputs(x.copy(), {"wind_infiltration": np.array([[k]])})[0, :, ch["infiltration_ach"]]
    ventilated = 0.2 + k * (0.25 * 4.0 - em.WIND_REFERENCE_M_S)
    np.testing.assert_allclose(out[:4], [ventilated, ventilated, 0.2 + k * (4.0 - em.WIND_REFERENCE_M_S), 0.2])
    calm = em.transform_inputs(x.copy(), {"wind_infiltration": np.array([[0.15]])})[0, 4, ch["infiltration_ach"]]
    assert calm == 0.0


def test_unheated_supply_air_saves_less_heat_on_a_cold_evening_than_on_a_mild_one():
    # after the heating period the supply air comes in supply_shortfall_k colder: the air handling unit's heating
    # per K of lift times the shortfall is heat the zones do not get, and the air handling unit does not spend
    from buildenv import catalogue as cat
    from buildenv.metamodel.surrogate import CONTEXT_HOURS, INPUT_CHANNELS

    ch, q_ahu, t_int = (
        {n: i for i, n in enumerate(INPUT_CHANNELS)},
        cat.OUTPUT_NAMES.index("Q_AHU_H"),
        cat.OUTPUT_NAMES.index("T_INT_OFFICE"),
    )
    x = np.zeros((2, CONTEXT_HOURS + 168, len(INPUT_CHANNELS)))
    x[..., ch["ventilation_on"]] = 1.0  # ventilation on, heating period over: every hour is "after heating"
    x[..., ch["supply_air_c"]] = 19.0
    x[0, :, ch["TAMB"]], x[1, :, ch["TAMB"]] = -5.0, 13.0  # lift 24 K and 6 K
    outputs = np.zeros((2, 168, len(cat.OUTPUT_NAMES)), np.float32)
    outputs[..., q_ahu], outputs[..., t_int] = 12.0, 20.0
    out = em.transform_outputs(outputs, x, {"night_cycle_cold_air": np.array([[0.05, 0.0, 6.0]])})
    np.testing.assert_allclose(out[0, :, q_ahu], 12.0 - 6.0 * 12.0 / 24.0)  # still heats from -5 to 13 degC
    np.testing.assert_allclose(out[1, :, q_ahu], 0.0)  # at most all of it
    np.testing.assert_allclose(out[0, :, t_int], 20.0 - 0.05 * 3.0, rtol=1e-6)
    np.testing.assert_allclose(out[1, :, t_int], 20.0 - 0.05 * 12.0, rtol=1e-6)


def _biased_site(tmp_path, bias_k: float, weeks: int = 2):
    """The default site's first weeks with a temperature sensor reading ``bias_k`` high."""
    src = load_site(DEFAULT_SITE)
    write_site(
        tmp_path,
        name="biased",
        weather=src.weather,
        start=src.start,
        floor_area_m2=src.floor_area_m2,
        number_of_floors=src.number_of_floors,
        settings=src.settings[:weeks],
        temperature_c=src.temperature_c[:weeks] + bias_k,
        consumption_kwh=src.consumption_kwh[:weeks],
    )
    return load_site(tmp_path)


def test_diagnosis_names_an_injected_sensor_bias_and_saves_the_extended_model(tmp_path, surrogate):
    # 3 K, the top of a thermostat bias in practice: the base calibration absorbs part of it into the building
    # parameters, and with one held-out week its offset cannot be told from a slow drift (the residual's
    # autocorrelation leaves too few effective values): two fit and two held-out weeks
    site = _biased_site(tmp_path, 3.0, weeks=4)
    settings = DiagnosisSettings(
        candidates=("temperature_sensor_bias", "solar_shading"),
        evaluations=300,
        base_evaluations=800,
        max_effects=1,
    )
    result = diagnose(site, surrogate, settings, plot=tmp_path / "diagnosis.png")
    assert result["selected"] == ["temperature_sensor_bias"]
    first = result["effects"][0]
    assert first["name"] == "temperature_sensor_bias" and first["status"] == "named" and not first["failed"]
    assert first["p_value"] < first["threshold"] == pytest.approx(0.05 / 2)  # alpha over the step's candidates
    assert 1.0 < first["parameters"]["bias_k"] < 3.5
    # scored on both series pooled, standardised
    sse = first["evidence"]["sse_by_series"]
    (tb, ta), (qb, qa) = sse["temperature"], sse["consumption"]
    assert first["score"] == pytest.approx(1 - (ta + qa) / (tb + qb), abs=1e-3)
    days = first["evidence"]["sse_by_day"]["temperature"]
    assert len(days) == 7 * len(result["heldout_weeks"]) and sum(b for b, _ in days) == pytest.approx(tb, rel=1e-3)
    assert first["heldout_after"]["rmse_t_celsius"] < 0.8 * first["heldout_before"]["rmse_t_celsius"]
    # recorded for criteria judged on the fit weeks: the bias lowers the cost the searches minimised
    assert 0 < first["fit_cost"]["candidate"] < first["fit_cost"]["control"]
    assert result["answer"] == "named" and result["verdict"].startswith("unmodelled effect(s) found: temperature")
    assert {"localisation", "effects", "selected", "not_enough_data", "hours_showing", "split_weather"} <= set(result)
    assert set(result["hours_showing"]) == {"heating_peaks", "ventilated_heating", "heating_fans_off"}
    assert (tmp_path / "diagnosis.png").stat().st_size > 0
    site.calibration = {"method": "cmaes", "cost": 9.9, "fit": {"cv_rmse_q_percent": 99.0}, "run_costs": [9.9]}
    saved = save_extended_model(site, result)
    fit = result.pop("_fit")
    json.dumps(result, default=float)
    calibration = json.loads(saved.read_text())
    assert calibration["effects"]["temperature_sensor_bias"]["bias_k"] == first["parameters"]["bias_k"]
    # the figures at the top are the extended model's; the model without the effect keeps its own
    assert calibration["heldout"] == result["heldout_after"]
    assert calibration["at_bounds"] == result["model"]["at_bounds"]
    assert calibration["verdict"]["judged_on"] == "heldout" and {"fit", "run_costs"}.isdisjoint(calibration)
    assert calibration["without_effects"]["fit"] == {"cv_rmse_q_percent": 99.0}
    assert calibration["cost"] == pytest.approx(fit.cost)


def test_a_two_meter_site_is_diagnosed_on_their_sum_and_its_extended_model_judged_meter_by_meter(
    tmp_path, calibrated, surrogate
):
    from buildenv.catalogue import OUTPUT_NAMES

    site, params = calibrated
    weeks = list(range(4))
    problem = cal.build_problem(site, weeks, context_hours=surrogate.context_hours)
    outputs, t, _ = cal.simulate(problem, surrogate, params[None])
    rng = np.random.default_rng(0)
    kwh = site.floor_area_m2 / 1000.0 * (1 + 0.01 * rng.standard_normal(t[0].shape))
    meters = [outputs[0][..., [OUTPUT_NAMES.index(n) for n in names]].sum(-1) for names in HEAT_AND_POWER]
    write_site(
        tmp_path,
        name="two meters, a sensor 3 K high",
        **{**_two_weeks_of(site), "settings": site.settings[:4]},
        temperature_c=t[0] + 3.0 + 0.1 * rng.standard_normal(t[0].shape),
        consumption_kwh=np.maximum(meters[0], 0.0) * kwh,
        consumption_end_uses=("heating",),
        electricity_kwh=meters[1] * kwh,
        electricity_end_uses=("lighting", "plug_loads"),
    )
    split = load_site(tmp_path)
    settings = DiagnosisSettings(candidates=("temperature_sensor_bias",), evaluations=300, base_evaluations=800)
    result = diagnose(split, surrogate, settings)
    assert result["selected"] == ["temperature_sensor_bias"]
    assert {"cv_rmse_q_percent", "cv_rmse_e_percent"} <= set(result["heldout_meters"])
    split.calibration = {"method": "cmaes", "cost": 9.9}
    calibration = json.loads(save_extended_model(split, result).read_text())
    assert calibration["heldout"] == pytest.approx(result["heldout_meters"])
    assert "electricity CV(RMSE)" in calibration["verdict"]["line"]


def test_a_candidate_is_credited_only_with_what_its_own_parameters_add():
    # a refit that found better building parameters than the control, with the effect itself adding nothing
    n = len(cal.parameter_names())
    absent = np.zeros((4, 7))
    current = ModelFit(("holidays",), np.zeros(n), absent)
    flagged = absent.copy()
    flagged[0, 2] = 1.0
    trial = ModelFit(("holidays", "night_plug_loads"), np.arange(n + 1.0), flagged)
    alone = without_new_effect(current, trial)
    assert alone.effects == ("holidays",) and np.array_equal(alone.params, np.arange(float(n)))
    assert not alone.absent.any() and trial.absent.any()
    against_control, against_own = Evidence(0.20, 1e-5, 1, 100, 50.0), Evidence(-0.09, 1.0, 1, 100, 50.0)
    assert stricter_score(against_control, against_own) == (against_own, "own refit without the effect")
    assert (
        stricter_score(dataclasses.replace(against_own, gain=0.3), against_control)[1] == "own refit without the effect"
    )
    assert stricter_score(against_control, dataclasses.replace(against_own, gain=0.3)) == (against_control, "control")


def test_diagnosis_names_the_default_sites_cold_night_air(tmp_path, surrogate):
    # the default site is the VAV-reheat medium office: its night cycle supplies cold air, which our model lacks.
    # Its site.toml declares it; without that declaration a plain
    # calibration misses it and the diagnosis names it; a local refit (DiagnosisSettings.refit_step) keeps the
    # mild fit weeks from moving theta_build
    shutil.copytree(DEFAULT_SITE, tmp_path / "site", ignore=shutil.ignore_patterns("calibration.*"))
    _undeclare_effects(tmp_path / "site")
    # three CMA-ES runs, the lowest fit cost kept, as the blind checks calibrate (--base-restarts 3): from one run
    # (seed 0) a fresh install on 2026-11-27 landed in a basin whose refit gained 0.028 on R2_T (score 0.17),
    # where seeds 1-3 gained 0.054-0.060 (0.38-0.44); with three runs seed 0 gains 0.053 (0.41)
    calibrate_site(load_site(tmp_path / "site"), surrogate, seed=0, restarts=3, prior=False)
    settings = DiagnosisSettings(candidates=("night_cycle_cold_air",), refit_step=0.05)
    result = diagnose(load_site(tmp_path / "site"), surrogate, settings)
    assert result["selected"] == ["night_cycle_cold_air"]
    (entry,) = result["effects"]
    assert 0.05 < entry["parameters"]["cooling_k_per_wh_m2"] < 0.3
    before, after = entry["heldout_before"], entry["heldout_after"]
    assert after["r2_t"] > before["r2_t"] + 0.03 and after["cv_rmse_q_percent"] < before["cv_rmse_q_percent"] + 1.0


def _undeclare_effects(folder: Path) -> None:
    """Take the ``effects`` line out of a site's ``site.toml``."""
    toml = folder / "site.toml"
    toml.write_text(
        "".join(line for line in toml.read_text().splitlines(keepends=True) if not line.startswith("effects ="))
    )


def test_the_default_site_declares_its_effects_and_the_diagnosis_takes_them_as_base_effects():
    site = load_site(DEFAULT_SITE)
    assert site.effects == ("night_cycle_cold_air", "evening_departure", "temperature_sensor_bias")
    assert site.calibration["declared_effects"] == list(site.effects)  # the shipped calibration models them
    assert site.calibration["heldout"]["r2_t"] > 0.95  # issue 4's target, met with them (0.820 without)
    settings = with_declared_effects(site, DiagnosisSettings())
    assert set(settings.base_effects) >= set(site.effects)  # in the base model, not among the candidates


def test_site_model_simulates_the_building_effects_found(calibrated, surrogate, tmp_path):
    site, _ = calibrated
    model = SiteModel.from_site(site, surrogate)  # the declared building effects; the sensor's is not simulated
    assert set(model.effects) == {"night_cycle_cold_air", "evening_departure"}
    model.effects = {}
    settings = np.repeat(model.historical[None], 2, axis=0)
    plain = model.simulate(settings, np.array([45, 46]))
    model.effects = {"heat_recovery": np.array([[0.7]]), "temperature_sensor_bias": np.array([[2.0]])}
    extended = model.simulate(settings, np.array([45, 46]))
    ahu = list(em.cat.OUTPUT_NAMES).index("Q_AHU_H")
    assert extended[..., ahu].sum() < plain[..., ahu].sum()
    t = list(em.cat.OUTPUT_NAMES).index("T_INT_OFFICE")
    np.testing.assert_allclose(extended[..., t], plain[..., t], atol=1e-4)  # a sensor effect is not the building


def _diagnose_synthetic(tmp_path, surrogate, candidate: str, theta: dict[str, float]):
    """A site the metamodel itself produced with building parameters ``theta`` (the rest as
    ``test_calibration._truth``), diagnosed with one candidate; returns the site, the result and its entry."""
    from test_calibration import _synthetic_site, _truth

    truth = _truth()
    for name, value in theta.items():
        truth[cal.parameter_names().index(name)] = value
    site = _synthetic_site(tmp_path, surrogate, truth, noise_seed=0)  # a gain is judged against sensor noise
    settings = DiagnosisSettings(candidates=(candidate,), evaluations=300, base_evaluations=800, max_effects=1)
    result = diagnose(site, surrogate, settings, localisation=False)
    (entry,) = result["effects"]
    return site, result, entry


@pytest.mark.parametrize("light_night_percent, named", [(60.0, True), (0.0, False)])
def test_loads_left_on_at_night_past_the_plug_loads_night_share_are_named_against_dark_nights(
    tmp_path, surrogate, light_night_percent, named
):
    # the metamodel carries a night load through the night shares of its lights and plug loads; with the plug
    # loads' share at the top of its range, what is left on beyond it can only be lighting, so the diagnosis
    # judges night_plug_loads against the model with no lighting at night, and sizes it by the night electricity
    # both shares add up to
    site, result, entry = _diagnose_synthetic(
        tmp_path, surrogate, "night_plug_loads", {"pc_night_percent": 70.0, "light_night_percent": light_night_percent}
    )
    assert result["selected"] == (["night_plug_loads"] if named else [])
    assert set(entry["parameters"]) == {"light_night_percent", "night_electricity_w_m2"}
    true_night = night_electricity_w_m2(
        {
            "light_night_percent": light_night_percent,
            "pc_night_percent": 70.0,
            "plug_load_w_m2": 9.0,
            "lighting_power_w_m2": 10.0,
        }
    )  # test_calibration._truth's loads
    assert entry["parameters"]["night_electricity_w_m2"] == pytest.approx(true_night, rel=0.15)
    if named:
        assert entry["parameters"]["light_night_percent"] > 30.0 and entry["score"] > 0.3


@pytest.mark.parametrize("heating_power_w_m2, named", [(15.0, True), (100.0, False)])
def test_a_heating_plant_short_of_power_is_named_against_an_unlimited_one(
    tmp_path, surrogate, heating_power_w_m2, named
):
    # the metamodel carries a capacity limit through its heating power, so the base calibration absorbs it; the
    # diagnosis judges it against the model with the heating power pinned at the top of the catalogue range
    site, result, entry = _diagnose_synthetic(
        tmp_path, surrogate, "heating_capacity_limit", {"heating_power_w_m2": heating_power_w_m2}
    )
    assert result["selected"] == (["heating_capacity_limit"] if named else [])
    assert set(entry["parameters"]) == {"heating_power_w_m2"}
    if named:
        assert entry["parameters"]["heating_power_w_m2"] < 30.0 and entry["score"] > 0.5
        assert entry["heldout_after"]["rmse_t_celsius"] < 0.5 * entry["heldout_before"]["rmse_t_celsius"]
        saved = json.loads(save_extended_model(site, result).read_text())
        assert "heating_capacity_limit" not in saved["effects"]  # it is in theta, and named in the diagnosis
        assert saved["diagnosis"]["selected"] == ["heating_capacity_limit"]
        assert saved["theta"]["heating_power_w_m2"] == entry["parameters"]["heating_power_w_m2"]
    else:
        assert entry["score"] < 0.15


def test_a_carried_effect_is_also_refitted_from_its_starts_and_the_best_fit_kept(tmp_path, surrogate):
    # a calibration can stop at a heating power near the top of its range on a building short of power, where
    # something else absorbs the limit; refitted from the effect's starts it fits better. Here a calibration stuck
    # at 95 W/m2 on a 20 W/m2 building.
    from test_calibration import _synthetic_site, _truth

    from buildenv.diagnosis.refit import carried_trial, make_context, problem_for

    j = cal.parameter_names().index("heating_power_w_m2")
    truth = _truth()
    truth[j] = 20.0
    site = _synthetic_site(tmp_path, surrogate, truth, noise_seed=0)
    ctx = make_context(site, surrogate, DiagnosisSettings(evaluations=300))
    stuck = truth.copy()
    stuck[j] = 95.0
    absent = np.zeros((site.weeks, 7))
    cost = cal.evaluate(problem_for(ctx, ModelFit((), stuck, absent), ctx.fit_weeks), surrogate, stuck[None])[0]
    control = ModelFit((), stuck, absent, float(cost))
    trial = carried_trial(ctx, control, control, "heating_capacity_limit")
    assert trial.effects == trial.carried == ("heating_capacity_limit",)
    assert trial.cost < control.cost and trial.params[j] < 40.0
    assert get_effect("heating_capacity_limit").carried_starts and not get_effect("night_plug_loads").carried_starts


def test_the_night_electricity_adds_the_lights_and_equipment_left_on():
    theta = {"light_night_percent": 20.0, "lighting_power_w_m2": 10.0, "plug_load_w_m2": 7.5, "pc_night_percent": 40.0}
    assert night_electricity_w_m2(theta) == pytest.approx(10.0 * 0.2 + 7.5 * 0.4)  # W/m2
    moved = theta | {"light_night_percent": 50.0, "pc_night_percent": 0.0}  # the same load, carried by the lights
    assert night_electricity_w_m2(moved) == pytest.approx(night_electricity_w_m2(theta))


def test_the_diagnosis_says_when_its_held_out_weeks_are_colder_than_its_fit_weeks():
    site = load_site(DEFAULT_SITE)  # 6 weeks from 4 November: the last three are the coldest
    tamb = site.weather_hours()[:, :, WEATHER_NAMES.index("TAMB")]
    first = split_weather(site)
    assert first["fit"]["mean_c"] == pytest.approx(tamb[:3].mean(), abs=0.01)
    assert first["heldout"]["min_c"] == pytest.approx(tamb[3:].min(), abs=0.01)
    assert first["heldout_colder_than_fit_percent"] == pytest.approx(100 * (tamb[3:] < tamb[:3].min()).mean(), abs=0.1)
    assert first["heldout_colder_than_fit_percent"] > 20 and "--split alternate" in first["note"]
    alternate = split_weather(site, "alternate")  # weeks 0, 2, 4 reach -7.8 degC
    assert alternate["heldout_colder_than_fit_percent"] < first["heldout_colder_than_fit_percent"]
    assert alternate["note"] is None


@pytest.mark.parametrize("bias_k", [0.0, 1.5])
def test_a_clean_synthetic_site_names_nothing_and_a_sensor_bias_on_it_is_named(tmp_path, surrogate, bias_k):
    # the metamodel's own prediction with the stand-in's sensor noise, its heating plant never running flat out:
    # every candidate of the catalogue tried, none has anything to explain (the null); the same site read by a
    # sensor 1.5 K high names the bias
    from test_calibration import _synthetic_site, _truth

    effects = ("temperature_sensor_bias",) if bias_k else ()
    truth = _truth()
    truth[cal.parameter_names().index("heating_power_w_m2")] = 100.0
    params = np.concatenate([truth, [bias_k] if bias_k else []])
    site = _synthetic_site(tmp_path, surrogate, params, weeks=4, effects=effects, noise_seed=1)
    settings = DiagnosisSettings(evaluations=300, base_evaluations=1500, max_effects=1, split="alternate")
    result = diagnose(site, surrogate, settings, localisation=False)
    assert result["selected"] == ([] if not bias_k else ["temperature_sensor_bias"]), result["verdict"]
    assert result["answer"] == ("named" if bias_k else "none")
    assert all(e["status"] != "named" or e["name"] == "temperature_sensor_bias" for e in result["effects"])
    if bias_k:  # the base calibration took part of it into the building parameters
        assert 0.4 <= result["model"]["effects"]["temperature_sensor_bias"]["bias_k"] <= bias_k + 0.3
        assert result["heldout_after"]["rmse_t_celsius"] < 0.8 * result["heldout_before"]["rmse_t_celsius"]


def test_holidays_cannot_be_a_base_effect_their_days_are_found_from_the_data(surrogate):
    from buildenv.diagnosis.effects import EffectError

    site = load_site(DEFAULT_SITE)
    with pytest.raises(EffectError, match="base effect 'holidays'"):
        diagnose(site, surrogate, DiagnosisSettings(base_effects=("holidays",)), localisation=False)
