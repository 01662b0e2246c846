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
    CHECKED_DIAGNOSIS,
    EFFECTS,
    EffectError,
    get_effect,
    night_electricity_w_m2,
    parse_effect,
)
from buildenv.diagnosis.gap import (
    DiagnosisSettings,
    ModelFit,
    _verdict,
    diagnose,
    joint_calibration_tests,
    save_extended_model,
    settings_note,
    split_weather,
    stricter_score,
    with_declared_effects,
    without_new_effect,
)
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site, write_site
from buildenv.sites.week_simulator import SiteModel

MODEL_EFFECTS = [e for e in EFFECTS if e != "holidays"]


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


def test_catalogue_lists_the_eight_effects_with_magnitudes_and_parameters():
    assert set(EFFECTS) >= {
        "wind_infiltration",
        "temperature_sensor_bias",
        "temperature_sensor_lag",
        "holidays",
        "night_plug_loads",
        "solar_shading",
        "heating_capacity_limit",
        "heat_recovery",
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
    bias = get_effect("temperature_sensor_bias")
    # within a class-B sensor's tolerance of what a clean site calibrates (-0.233 K, the calibrated model reading
    # the reference office warm) a reading is not named biased, on either side
    assert bias.clean_reading == -0.233
    assert bias.plausible({"bias_k": -0.7}) and not bias.plausible({"bias_k": -0.6})
    assert bias.plausible({"bias_k": 0.2}) and not bias.plausible({"bias_k": 0.1})
    assert not bias.plausible({"bias_k": -0.3})
    verdict = _verdict(
        [],
        [
            {
                "name": bias.name,
                "plausible": False,
                "parameters": {"bias_k": -0.3},
                "score": 0.3,
                "significance": {"p_value": 1e-9, "threshold": 0.025},
            }
        ],
        0.15,
    )
    assert verdict.startswith("no significant unmodelled effect") and "|bias_k + 0.233| >= 0.4 K" in verdict
    assert "sized from the -0.233 K clean sites calibrate" in verdict
    assert "not significant" not in verdict and "held-out gain an effect must bring" not in verdict
    # a significant candidate that removes too little of the held-out error says so
    small = _verdict(
        [],
        [
            {
                "name": "evening_departure",
                "plausible": True,
                "parameters": {},
                "score": 0.134,
                "significance": {"p_value": 6.3e-8, "threshold": 0.025},
            }
        ],
        0.15,
    )
    assert small.endswith("p = 6.3e-08; under the 15 % held-out gain an effect must bring to be named)")
    weak = _verdict(
        [],
        [
            {
                "name": "holidays",
                "plausible": True,
                "parameters": {},
                "score": 0.2,
                "significance": {"p_value": 0.2, "threshold": 0.025},
            }
        ],
        0.15,
    )
    assert weak.endswith("; not significant at p < 0.025)")


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


def test_an_absent_day_is_simulated_without_occupants_and_found_from_both_series(tmp_path, calibrated, surrogate):
    from buildenv.diagnosis.gap import ModelFit, _context, detect_absent_days

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
        weather=site.weather,
        start=site.start,
        floor_area_m2=site.floor_area_m2,
        number_of_floors=site.number_of_floors,
        settings=site.settings[:2],
        temperature_c=t_abs[0] + 0.1 * rng.standard_normal(t_abs[0].shape),
        consumption_kwh=measured_q * site.floor_area_m2 / 1000.0,
    )
    measured = load_site(tmp_path)
    ctx = _context(measured, surrogate, DiagnosisSettings())
    ctx.sigma = (0.3, 2.5)
    found = detect_absent_days(ctx, ModelFit((), params, np.zeros((2, 7)), 0.0, 0), [0, 1])
    assert found[1, 1] > 0.8 and np.count_nonzero(found) == 1


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


@pytest.mark.parametrize("judge", ["pooled", "effect_series"])
def test_diagnosis_names_an_injected_sensor_bias_and_saves_the_extended_model(tmp_path, surrogate, judge):
    # 3 K, the top of a thermostat bias in practice: with one fit week the base calibration absorbs part of a
    # bias into the building parameters (the 80,000-week default absorbed about 1 K and a 2 K bias came out at
    # 0.7 K, below the 0.8 K floor of the time; the 160,000-week default estimates this 3 K bias at 1.3 K)
    site = _biased_site(tmp_path, 3.0)
    settings = DiagnosisSettings(
        candidates=("temperature_sensor_bias", "solar_shading"),
        evaluations=300,
        base_evaluations=800,
        max_effects=1,
        judge=judge,
    )
    result = diagnose(site, surrogate, settings, plot=tmp_path / "diagnosis.png")
    assert result["selected"] == ["temperature_sensor_bias"]
    first = result["effects"][0]
    assert first["name"] == "temperature_sensor_bias" and first["significance"]["significant"]
    assert 1.0 < first["parameters"]["bias_k"] < 3.5
    # "effect_series" judges a sensor bias on the temperature alone, where it shows; "pooled" on both series
    assert first["judged_on"] == (["temperature"] if judge == "effect_series" else ["temperature", "consumption"])
    if judge == "effect_series":
        assert first["score"] == pytest.approx(first["gain_by_series"]["temperature"], abs=1e-3)
    else:
        (tb, ta), (qb, qa) = first["sse_by_series"]["temperature"], first["sse_by_series"]["consumption"]
        assert first["score"] == pytest.approx(1 - (ta + qa) / (tb + qb), abs=1e-3)
    assert first["heldout_after"]["rmse_t_celsius"] < 0.8 * first["heldout_before"]["rmse_t_celsius"]
    # credited with what the bias itself adds: its refit without the bias is the worse baseline here
    assert first["score"] == pytest.approx(min(first["gain_vs_control"], first["gain_vs_own_refit"]), abs=1e-4)
    # recorded for criteria judged on the fit weeks: the bias lowers the cost the searches minimised
    assert 0 < first["fit_cost"]["candidate"] < first["fit_cost"]["control"]
    assert {
        "localisation",
        "effects",
        "selected",
        "verdict",
        "split_weather",
        "base_at_bounds",
        "settings_note",
        "fit_irradiance_w_m2",
    } <= set(result)
    assert result["fit_irradiance_w_m2"] == pytest.approx(
        site.weather_hours()[result["fit_weeks"], :, WEATHER_NAMES.index("IGLOB_H")].mean(), abs=1e-3
    )
    assert (tmp_path / "diagnosis.png").stat().st_size > 0
    saved = save_extended_model(site, result)
    result.pop("_fit")
    json.dumps(result, default=float)
    calibration = json.loads(saved.read_text())
    assert calibration["effects"]["temperature_sensor_bias"]["bias_k"] == first["parameters"]["bias_k"]


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
    against_control, against_own = {"gain": 0.20, "sse_before": 10.0}, {"gain": -0.09, "sse_before": 7.3}
    score = stricter_score(against_control, against_own)
    assert score["gain"] == -0.09 and score["baseline"] == "own refit without the effect"
    assert (score["gain_vs_control"], score["gain_vs_own_refit"]) == (0.2, -0.09)
    assert stricter_score(against_control | {"gain": 0.1}, against_own | {"gain": 0.3})["baseline"] == "control"


def test_diagnosis_names_the_default_sites_cold_night_air(tmp_path, surrogate):
    # the default site is the VAV-reheat medium office: its night cycle supplies cold air, which our model lacks
    # (bench/results/default_site_error_budget.md). Its site.toml declares it; without that declaration a plain
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


def test_the_settings_note_names_what_differs_from_the_blind_checks():
    assert settings_note(DiagnosisSettings(**CHECKED_DIAGNOSIS)) == ""
    note = settings_note(DiagnosisSettings())  # the API's faster defaults: the first half fitted, one base run
    assert "split first_half (checks: alternate)" in note and "base_restarts 1 (checks: 3)" in note


def test_diagnosis_rejects_an_unknown_judging_rule(calibrated, surrogate):
    site, _ = calibrated
    with pytest.raises(ValueError, match="unknown judge 'both'"):
        diagnose(site, surrogate, DiagnosisSettings(judge="both"))


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


@pytest.mark.parametrize("ach_per_m_s", [0.08, 0.0])
def test_a_joint_calibration_with_wind_infiltration_gains_only_where_the_wind_drives_the_infiltration(
    tmp_path, surrogate, ach_per_m_s
):
    # the building parameters and the wind term calibrated together from scratch, the model without it likewise
    from test_calibration import _synthetic_site, _truth

    site = _synthetic_site(
        tmp_path, surrogate, np.concatenate([_truth(), [ach_per_m_s]]), effects=("wind_infiltration",), noise_seed=0
    )
    # with the sensors' noise, as a site has: without it the residual of a converged fit is the optimiser's
    # own spread, and the ratio of two such residuals is no gain (it ranged from -15 to +0.2 here)
    # converged enough (1,500 evaluations each) that the two fits' own spread does not pass for a gain
    (test,) = joint_calibration_tests(site, surrogate, ("wind_infiltration",), DiagnosisSettings(base_evaluations=1500))
    estimate = test["estimate"]["ach_per_m_s"]
    if ach_per_m_s:
        assert test["gain"] > 0.3 and test["p_value"] < 1e-3 and 0.04 < estimate < 0.15
    else:
        assert test["gain"] < 0.15 and estimate < 0.02
    with pytest.raises(ValueError, match="base effect"):
        joint_calibration_tests(
            site, surrogate, ("wind_infiltration",), DiagnosisSettings(base_effects=("wind_infiltration",))
        )
    with pytest.raises(ValueError, match="holidays"):
        joint_calibration_tests(site, surrogate, ("holidays",))


def test_an_absorbed_candidate_is_tested_again_by_joint_calibration():
    # the blind checks' records (bench/results/gap_joint_fallback.md): seed 3 case 13, a 35 % wind infiltration,
    # refitted at 0.0214 1/h per m/s (beyond every clean site's 0.0157) with a held-out gain of -1.6 %; calibrated
    # from scratch with and without the wind term it gained 25 % (p = 1e-11)
    from buildenv.diagnosis.gap import absorbed_candidate, joint_test_qualifies

    assert absorbed_candidate("wind_infiltration", {"ach_per_m_s": 0.0214})
    assert not absorbed_candidate("wind_infiltration", {"ach_per_m_s": 0.011})  # within the clean sites' estimates
    assert not absorbed_candidate("wind_infiltration", {"ach_per_m_s": 0.0214}, {"wind_infiltration": 0.03})
    assert not absorbed_candidate("wind_infiltration", {"ach_per_m_s": 0.0214}, False)
    assert not absorbed_candidate("holidays", {"absent_days": 3})
    # judged through the building parameter that carries it: the base calibration is that effect's model already
    assert not absorbed_candidate("heating_capacity_limit", {"heating_power_w_m2": 20.0})
    # beyond the ceiling but under the smallest bias named (0.4 K): implausible, so not tested again
    assert not absorbed_candidate("temperature_sensor_bias", {"bias_k": -0.35}, {"temperature_sensor_bias": 0.3})
    wind = {"ach_per_m_s": 0.0384}
    assert joint_test_qualifies("wind_infiltration", {"gain": 0.253, "p_value": 1.4e-11, "estimate": wind}, 0.00625)
    assert not joint_test_qualifies("wind_infiltration", {"gain": 0.029, "p_value": 0.01, "estimate": wind}, 0.00625)
    assert not joint_test_qualifies("wind_infiltration", {"gain": -0.035, "p_value": 1.0, "estimate": wind}, 0.00625)
    assert not joint_test_qualifies(
        "wind_infiltration", {"gain": 0.2, "p_value": 1e-9, "estimate": {"ach_per_m_s": 0.001}}, 0.00625
    )
    # seed 47's case 7 twin, a clean site: a sensor lag refit at 0.766 h (beyond every clean site's 0.668 h) with a
    # held-out gain of -12 %, whose joint test gained 4.6 % (p = 0.0006) with its estimate back at 0.414 h
    lag = {"gain": 0.046, "p_value": 5.8e-4, "estimate": {"tau_h": 0.414}}
    assert absorbed_candidate("temperature_sensor_lag", {"tau_h": 0.766})
    assert not joint_test_qualifies("temperature_sensor_lag", lag, 0.00625)
    assert joint_test_qualifies("temperature_sensor_lag", lag, 0.00625, False)  # no ceilings: the gain alone
    assert joint_test_qualifies("temperature_sensor_lag", lag, 0.00625, {"temperature_sensor_lag": 0.3})
    # seed 8 case 6: a 29 % wind infiltration whose joint test lost 3.5 %; the verdict says so after the best one
    best = {
        "name": "solar_shading",
        "plausible": True,
        "parameters": {"blocked_fraction": 0.3},
        "score": 0.02,
        "series_made_worse": [],
        "beyond_clean_sites": False,
        "significance": {"p_value": 0.2, "threshold": 0.006},
    }
    tested = {
        "name": "wind_infiltration",
        "joint_test": {"candidate": "wind_infiltration", "gain": -0.035, "p_value": 1.0, "estimate": wind},
    }
    assert _verdict([], [best, tested], 0.10).endswith(
        "; wind_infiltration calibrated from scratch with and without it gains -3.5 %, p = 1, ach_per_m_s 0.0384 1/h "
        "per m/s (not named: a joint test must gain significantly with a plausible estimate beyond every clean "
        "site's))"
    )
    named = tested | {"joint_test": {"qualifies": True}}
    assert (
        _verdict(["wind_infiltration"], [named], 0.10, [{"candidates": [named]}])
        == "unmodelled effect(s) found: wind_infiltration (wind-driven infiltration; named by joint calibration)"
    )


@pytest.mark.parametrize("ach_per_m_s", [0.08, 0.0])
def test_a_step_that_names_nothing_selects_an_absorbed_candidate_its_joint_test_names(
    tmp_path, surrogate, monkeypatch, ach_per_m_s
):
    # every refit held to not qualify, as when the base calibration has absorbed the effect: the wind term's
    # refit estimate is beyond the clean sites' only where the wind drives the infiltration, and only there is
    # it tested from scratch, and named
    from test_calibration import _synthetic_site, _truth

    import buildenv.diagnosis.gap

    monkeypatch.setattr(buildenv.diagnosis.gap, "candidate_qualifies", lambda *args, **kwargs: False)
    site = _synthetic_site(
        tmp_path, surrogate, np.concatenate([_truth(), [ach_per_m_s]]), effects=("wind_infiltration",), noise_seed=0
    )
    settings = DiagnosisSettings(
        candidates=("wind_infiltration",), evaluations=300, base_evaluations=1500, max_effects=1
    )
    result = diagnose(site, surrogate, settings, localisation=False)
    (entry,) = result["effects"]
    assert not entry["qualifies"]
    if ach_per_m_s:
        assert entry["beyond_clean_sites"] and entry["joint_test"]["qualifies"]
        assert result["selected"] == ["wind_infiltration"] and "named by joint calibration" in result["verdict"]
        assert result["model"]["effects"]["wind_infiltration"] == entry["joint_test"]["estimate"]
        assert 0.06 < entry["joint_test"]["estimate"]["ach_per_m_s"] < 0.10  # 0.08 injected
        # the gap as the blind checks measure its shrinkage: the squared error of the effect's main series
        assert result["heldout_after"]["mse_q"] < 0.5 * result["heldout_before"]["mse_q"]
        # without the joint test, the estimate alone names it (beyond every clean site's), and the model stays
        alone = diagnose(site, surrogate, dataclasses.replace(settings, joint_fallback=False), localisation=False)
        assert not alone["selected"] and alone["named_by_estimate"] == ["wind_infiltration"]
        assert alone["verdict"].startswith("unmodelled effect named by its estimate alone: wind_infiltration")
        assert alone["model"]["effects"] == {} and "heldout_after" not in alone
    else:
        assert "joint_test" not in entry and result["selected"] == [] and result["named_by_estimate"] == []


def test_a_night_load_carried_on_the_equipments_share_is_named_by_its_night_electricity_alone():
    # the blind checks' records (bench/results/gap_night_alone.md): seed 25 case 12, a 1.12 W/m2 night load, carried
    # 4.47 W/m2 of night electricity on a 0.3 % lights' night share (under the 10 % floor of the held-out test) with
    # the sensor bias refit at -0.29 K, and named nothing; seed 59 case 1, a +0.25 K bias, carried 4.33 W/m2 on 0 %.
    # No clean site of seeds 0-100 carried more than 3.60 W/m2 (the ceiling: 3.61)
    from buildenv.diagnosis.gap import named_by_estimate, plausible_alone

    def estimates(night, share, bias):
        return {
            "night_plug_loads": {"light_night_percent": share, "night_electricity_w_m2": night},
            "temperature_sensor_bias": {"bias_k": bias},
        }

    gains = {"night_plug_loads": -0.061, "temperature_sensor_bias": -0.2}
    assert not get_effect("night_plug_loads").plausible(estimates(4.47, 0.3, -0.29)["night_plug_loads"])
    assert plausible_alone(
        "night_plug_loads", estimates(4.47, 0.3, -0.29)["night_plug_loads"], estimates(4.47, 0.3, -0.29)
    )
    assert named_by_estimate(estimates(4.47, 0.3, -0.29), gains) == ["night_plug_loads"]
    # a sensor reading warm is carried as heat at night too: seed 59 case 1 names its bias, never night loads
    assert named_by_estimate(estimates(4.33, 0.0, 0.25), gains) == ["temperature_sensor_bias"]
    assert named_by_estimate(estimates(4.33, 0.0, 0.02), gains) == []
    assert named_by_estimate(estimates(3.60, 0.0, -0.29), gains) == []  # among the clean sites'
    assert named_by_estimate(estimates(4.47, 0.3, -0.29), gains, {"night_plug_loads": 5.0}) == []  # a replay's
    no_bias = estimates(4.47, 0.3, -0.29)
    del no_bias["temperature_sensor_bias"]
    assert named_by_estimate(no_bias, gains) == []  # the bias declared or not tested: the floor stands
    assert named_by_estimate(estimates(4.47, 26.0, 0.25), gains) == ["night_plug_loads"]  # over the floor, as before
    # other effects keep their plausibility: a heat exchanger under its 0.3 floor is not named however far beyond
    exchanger = {"heat_recovery": {"effectiveness": 0.29}, "temperature_sensor_bias": {"bias_k": -0.3}}
    assert not plausible_alone("heat_recovery", exchanger["heat_recovery"], exchanger)


def test_an_estimate_beyond_every_clean_sites_names_its_effect_alone(monkeypatch):
    # the blind checks' records (bench/results/gap_estimate_alone.md): seed 25 case 13, a 33 % wind infiltration,
    # refitted at 0.0333 1/h per m/s with a held-out gain of -3.4 %, its joint test -1.1 %; the furthest any of
    # the 464 clean sites calibrated was 0.0175
    from buildenv.diagnosis.gap import held_back_from_estimate, named_by_estimate

    wind = {
        "wind_infiltration": {"ach_per_m_s": 0.0333},
        "solar_shading": {"blocked_fraction": 0.3},
        "holidays": {"absent_days": 2},
    }
    gains = {"wind_infiltration": -0.034, "solar_shading": 0.01, "holidays": 0.0, "heating_capacity_limit": 0.046}
    assert named_by_estimate(wind, gains) == ["wind_infiltration"]
    assert named_by_estimate({"wind_infiltration": {"ach_per_m_s": 0.0170}}, gains) == []
    assert named_by_estimate(wind, gains, False) == []
    assert named_by_estimate(wind, gains, {"wind_infiltration": 0.04}) == []  # a replay's ceilings, used instead
    assert named_by_estimate({"holidays": {"absent_days": 2}}, gains) == []  # detected, not calibrated
    # seed 29 case 12, a 1.17 W/m2 night load: a sensor bias refitted at -0.575 K read the temperature 58 % worse
    # held out (the held-out weeks 37 % worse): the sensor rule holds it back (sized from the clean sites'
    # -0.233 K, that bias is no longer plausible either; a +0.3 K one is). No guard on the pooled held-out gain:
    # without the series' gains a plausible one is named however much worse the held-out weeks read
    bias = {"temperature_sensor_bias": {"bias_k": 0.3}}
    series = {"temperature_sensor_bias": {"temperature": -0.575, "consumption": -0.166}}
    assert named_by_estimate(bias, {"temperature_sensor_bias": -0.368}, True, series) == []
    assert named_by_estimate(bias, {"temperature_sensor_bias": -0.368}) == ["temperature_sensor_bias"]
    assert named_by_estimate({"temperature_sensor_bias": {"bias_k": -0.575}}, {"temperature_sensor_bias": -0.09}) == []
    # a sensor effect whose own series reads worse held out names nothing by its estimate (seed 79's case 4 twin:
    # a 0.749 h lag past the 0.713 h ceiling, -6.5 % pooled, the temperature 29 % worse); a bias reading it better
    # does (seed 27's case 10: +0.35 K, the temperature 37 % better, the consumption 48 % worse); other effects'
    # series are not judged so (seed 42's case 15, a wind whose temperature read 20 % worse, was named right)
    lag = {"temperature_sensor_lag": {"tau_h": 0.749}}
    assert named_by_estimate(lag, {"temperature_sensor_lag": -0.065}) == ["temperature_sensor_lag"]
    assert (
        named_by_estimate(
            lag,
            {"temperature_sensor_lag": -0.065},
            True,
            {"temperature_sensor_lag": {"temperature": -0.29, "consumption": 0.109}},
        )
        == []
    )
    assert named_by_estimate(
        {"temperature_sensor_bias": {"bias_k": 0.35}},
        {"temperature_sensor_bias": -0.05},
        True,
        {"temperature_sensor_bias": {"temperature": 0.368, "consumption": -0.476}},
    ) == ["temperature_sensor_bias"]
    assert named_by_estimate(
        {"wind_infiltration": {"ach_per_m_s": 0.0243}},
        {"wind_infiltration": -0.076},
        True,
        {"wind_infiltration": {"temperature": -0.20, "consumption": 0.045}},
    ) == ["wind_infiltration"]
    # seed 86's case 2, a 20.3 % wind refit at 0.0264, 18.6 % worse held out (the temperature 27.6 %): named,
    # where the -10 % guard held it back
    assert named_by_estimate(
        {"wind_infiltration": {"ach_per_m_s": 0.0264}},
        {"wind_infiltration": -0.186},
        True,
        {"wind_infiltration": {"temperature": -0.276, "consumption": -0.082}},
    ) == ["wind_infiltration"]
    # a carried effect by its building parameter (a heating power under every clean site's 38.1 W/m2), and the
    # one furthest beyond its ceiling first
    power = {"heating_capacity_limit": {"heating_power_w_m2": 31.8}}
    assert named_by_estimate(power, gains) == ["heating_capacity_limit"]
    assert named_by_estimate(power | {"wind_infiltration": {"ach_per_m_s": 0.0333}}, gains) == ["wind_infiltration"]
    assert named_by_estimate({"heating_capacity_limit": {"heating_power_w_m2": 40.0}}, gains) == []
    # every estimate ceiling lies at or beyond the gain route's ceiling: no clean site of either set went further
    # (a size measured from the effect's clean reading, the sensor bias's -0.233 K)
    for effect in EFFECTS.values():
        if effect.estimate_ceiling is not None:
            at_ceiling = {effect.ceiling_on: effect.clean_reading + effect.clean_ceiling}
            assert effect.beyond_estimate_ceiling(at_ceiling) is False, effect.name
    entry = {"name": "wind_infiltration", "parameters": wind["wind_infiltration"], "score": -0.034}
    assert _verdict([], [entry], 0.10, [], ["wind_infiltration"]).startswith(
        "unmodelled effect named by its estimate alone: wind_infiltration (wind-driven infiltration; ach_per_m_s "
        "0.0333 1/h per m/s, beyond ach_per_m_s > 0.0175 1/h per m/s (the largest estimate calibrated on 464 clean "
        "sites"
    )
    # held back: the verdict says why each candidate beyond every clean site's names nothing (seed 79's case 4
    # twin, a 0.749 h lag reading the temperature 29 % worse; seed 77's case 1, a wind refit at 0.0498, -17.5 %,
    # held back only under a guard on the held-out gain, as a replay sets one)
    significance = {"p_value": 1.0, "threshold": 0.0063}
    best = {
        "name": "solar_shading",
        "plausible": True,
        "parameters": {"blocked_fraction": 0.44},
        "score": 0.157,
        "significance": {"p_value": 2e-10, "threshold": 0.0063},
        "beyond_clean_sites": False,
    }
    lag = {
        "name": "temperature_sensor_lag",
        "plausible": True,
        "parameters": {"tau_h": 0.749},
        "score": -0.065,
        "beyond_estimate_ceiling": True,
        "gain_by_series": {"temperature": -0.29, "consumption": 0.109},
        "significance": significance,
    }
    held = {
        "name": "wind_infiltration",
        "plausible": True,
        "parameters": {"ach_per_m_s": 0.0498},
        "score": -0.175,
        "beyond_estimate_ceiling": True,
        "gain_by_series": {"temperature": -0.243, "consumption": 0.01},
        "significance": significance,
    }
    inside = held | {"parameters": {"ach_per_m_s": 0.012}, "beyond_estimate_ceiling": False}
    verdict = _verdict([], [best, lag, inside], 0.10)
    assert verdict.startswith("no significant unmodelled effect (best candidate: solar_shading")
    assert (
        "; temperature_sensor_lag's estimate (tau_h 0.749 h) is beyond every clean site's, but not named by it: "
        "with it the temperature reads 29 % worse held out" in verdict
    )
    assert held_back_from_estimate("wind_infiltration", held["score"], held["gain_by_series"]) == []
    monkeypatch.setattr("buildenv.diagnosis.gap.ESTIMATE_ALONE_LOWEST_GAIN", -0.10)
    verdict = _verdict([], [best, lag, held, inside], 0.10)
    assert (
        "; wind_infiltration's estimate (ach_per_m_s 0.0498 1/h per m/s) is beyond every clean site's, but not "
        "named by it: its held-out gain (-17.5 %) is below the -10 % the estimate alone allows)" in verdict
    )
    assert "0.012" not in verdict and "temperature reads 24 %" not in verdict  # a wind's series are not judged so


def test_the_estimate_ceilings_are_those_measured_rounded_outwards():
    results = Path(__file__).resolve().parent / "fixtures" / "measured_ceilings"  # copied from the benchmarks
    measured = json.loads((results / "gap_estimate_alone.json").read_text())["measured"]
    # the sensor bias sized from the clean sites' median: its ceiling measured again from it, on the same sites
    reading = json.loads((results / "gap_bias_reading.json").read_text())
    measured["temperature_sensor_bias"] = {"furthest": reading["ceiling"]}
    assert reading["clean_sites"] == 464
    assert round(reading["reading"], 3) == EFFECTS["temperature_sensor_bias"].clean_reading
    typed = {e.name: e.estimate_ceiling for e in EFFECTS.values() if e.estimate_ceiling is not None}
    assert set(typed) == set(measured)
    for name, value in measured.items():
        effect = get_effect(name)
        orient = effect.strength if effect.building_parameter and effect.judged_on is None else float
        value = value["furthest"]
        assert orient(value) <= orient(typed[name]) <= orient(value) + 0.01 * abs(value), (name, value, typed[name])


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
    # two capacity limits of the blind checks (seed 12 case 11, seed 17 case 4) calibrated their heating power at
    # 89-95 W/m2 and a sensor lag was named; refitted from 25 W/m2 they fitted better at 36 W/m2
    # (bench/results/gap_carried_starts.md). Here a calibration stuck at 95 W/m2 on a 20 W/m2 building.
    from test_calibration import _synthetic_site, _truth

    from buildenv.diagnosis.gap import _context, _problem, carried_trial

    j = cal.parameter_names().index("heating_power_w_m2")
    truth = _truth()
    truth[j] = 20.0
    site = _synthetic_site(tmp_path, surrogate, truth, noise_seed=0)
    ctx = _context(site, surrogate, DiagnosisSettings(evaluations=300))
    stuck = truth.copy()
    stuck[j] = 95.0
    absent = np.zeros((site.weeks, 7))
    cost = cal.evaluate(_problem(ctx, ModelFit((), stuck, absent), ctx.fit_weeks), surrogate, stuck[None])[0]
    control = ModelFit((), stuck, absent, float(cost))
    trial = carried_trial(ctx, control, control, "heating_capacity_limit")
    assert trial.effects == trial.carried == ("heating_capacity_limit",)
    assert trial.cost < control.cost and trial.params[j] < 40.0
    assert get_effect("heating_capacity_limit").carried_starts and not get_effect("night_plug_loads").carried_starts


def test_a_carried_effect_that_trades_one_series_for_the_other_is_not_named():
    # a sensor reading low absorbed by a low heating power: consumption better, temperature worse
    from buildenv.diagnosis.gap import series_made_worse

    assert series_made_worse("heating_capacity_limit", {"temperature": -0.74, "consumption": 0.78}) == ["temperature"]
    assert series_made_worse("heating_capacity_limit", {"temperature": 0.40, "consumption": 0.44}) == []
    verdict = _verdict(
        [],
        [
            {
                "name": "heating_capacity_limit",
                "plausible": True,
                "parameters": {},
                "score": 0.35,
                "series_made_worse": ["temperature"],
                "significance": {"p_value": 7e-7, "threshold": 0.006},
            }
        ],
        0.15,
    )
    assert verdict.endswith(
        "it makes the temperature worse: a building parameter trading one series against the "
        "other absorbs another miss)"
    )


def test_an_effect_with_a_clean_site_ceiling_is_named_by_its_estimate():
    # seed 0 case 8 of the blind check: 40 % wind-driven infiltration injected, calibrated at 0.029 1/h per m/s
    # (beyond every clean site's 0.0157) with a held-out gain of 4 %, under the 10 % bar
    from buildenv.diagnosis.gap import candidate_qualifies

    wind = get_effect("wind_infiltration")
    assert wind.beyond_clean_sites({"ach_per_m_s": 0.029}) and not wind.beyond_clean_sites({"ach_per_m_s": 0.011})
    assert candidate_qualifies("wind_infiltration", 0.0425, 3e-4, 0.006, 0.10, {"ach_per_m_s": 0.029})
    assert not candidate_qualifies(
        "wind_infiltration", 0.0425, 3e-4, 0.006, 0.10, {"ach_per_m_s": 0.029}, clean_ceilings=False
    )
    assert not candidate_qualifies("wind_infiltration", 0.0425, 0.01, 0.006, 0.10, {"ach_per_m_s": 0.029})
    # at or below the ceiling no gain names it: the clean sites' structural misses give such estimates
    assert not candidate_qualifies("wind_infiltration", 0.3, 1e-9, 0.006, 0.10, {"ach_per_m_s": 0.011})
    assert candidate_qualifies(
        "wind_infiltration", 0.3, 1e-9, 0.006, 0.10, {"ach_per_m_s": 0.011}, clean_ceilings=False
    )
    # ceilings measured elsewhere may replace the catalogue's; an effect left out of them has none
    assert not candidate_qualifies(
        "wind_infiltration",
        0.0425,
        3e-4,
        0.006,
        0.10,
        {"ach_per_m_s": 0.029},
        clean_ceilings={"wind_infiltration": 0.03},
    )
    assert candidate_qualifies("wind_infiltration", 0.12, 3e-4, 0.006, 0.10, {"ach_per_m_s": 0.029}, clean_ceilings={})
    # with its building parameter declared known a carried effect's model-side addition is calibrated: it has no
    # ceiling and keeps the gain bar
    assert get_effect("heating_capacity_limit").beyond_clean_sites({"capacity_w_m2": 30.0}) is None
    assert not candidate_qualifies("heating_capacity_limit", 0.05, 1e-6, 0.006, 0.10, {"capacity_w_m2": 30.0})
    assert candidate_qualifies("heating_capacity_limit", 0.12, 1e-6, 0.006, 0.10, {"capacity_w_m2": 30.0})
    verdict = _verdict(
        [],
        [
            {
                "name": "solar_shading",
                "plausible": True,
                "parameters": {"blocked_fraction": 0.42},
                "score": 0.199,
                "series_made_worse": [],
                "beyond_clean_sites": False,
                "significance": {"p_value": 1e-9, "threshold": 0.006},
            }
        ],
        0.10,
    )
    assert (
        "its estimate (blocked_fraction 0.42) is not beyond every clean site's: blocked_fraction > 0.574 (the "
        "largest" in verdict
    )
    assert "held-out gain an effect must bring" not in verdict


def test_a_carried_effect_is_named_by_its_building_parameter_against_the_clean_sites():
    # seed 9 of the blind check: a plant at 49 % of design calibrated its heating power at 31.4 W/m2 (gain 4 %,
    # under the 10 % bar); the clean twin of another case calibrated 88.5 W/m2 and gained 11 %, which the bar named
    from buildenv.diagnosis.gap import candidate_qualifies

    capacity, night = get_effect("heating_capacity_limit"), get_effect("night_plug_loads")
    assert capacity.beyond_clean_sites({"heating_power_w_m2": 31.4})
    assert not capacity.beyond_clean_sites({"heating_power_w_m2": 88.5})
    assert not capacity.beyond_clean_sites({"heating_power_w_m2": 47.5})  # a clean twin of seed 10 gave 46.75
    assert not capacity.beyond_clean_sites({"heating_power_w_m2": 42.6})  # seed 17's clean case 0 gave 42.52
    both_better = {"temperature": 0.07, "consumption": 0.01}
    assert candidate_qualifies(
        "heating_capacity_limit", 0.042, 0.0048, 0.00625, 0.10, {"heating_power_w_m2": 31.4}, both_better
    )
    assert not candidate_qualifies(
        "heating_capacity_limit", 0.11, 1e-7, 0.006, 0.10, {"heating_power_w_m2": 88.5}, both_better
    )
    assert candidate_qualifies(
        "heating_capacity_limit",
        0.11,
        1e-7,
        0.006,
        0.10,
        {"heating_power_w_m2": 88.5},
        both_better,
        clean_ceilings=False,
    )
    # the series rule still holds beyond the ceiling
    assert not candidate_qualifies(
        "heating_capacity_limit",
        0.042,
        1e-4,
        0.006,
        0.10,
        {"heating_power_w_m2": 31.4},
        {"temperature": -0.01, "consumption": 0.2},
    )
    # loads left on at night: judged on the night electricity both night shares add up to, not on the lights'
    # share (seed 10 case 7, 2.2 W/m2 injected: the lights' share 10.7 %, under the clean sites' 22.2 %, the night
    # electricity 4.68 W/m2; the clean twin of seed 8 case 5: 22.2 % and 3.19 W/m2)
    assert night.beyond_clean_sites({"light_night_percent": 10.7, "night_electricity_w_m2": 4.68})
    assert not night.beyond_clean_sites({"light_night_percent": 22.2, "night_electricity_w_m2": 3.19})
    assert night.beyond_clean_sites({"light_night_percent": 25.1}) is None  # a record made before: not judged
    assert "heating_power_w_m2 < 42.5 W/m2 (the lowest" in capacity.clean_ceiling_text()
    assert (
        "night_electricity_w_m2 > " in night.clean_ceiling_text() and "W/m2 (the largest" in night.clean_ceiling_text()
    )


@pytest.mark.parametrize("page", ["gap_clean_ceiling_all", "gap_declared_ceiling"])
def test_the_catalogue_ceilings_are_those_measured_rounded_outwards(page):
    # the catalogue types each ceiling once; the benchmark pages that measured them are their source (the
    # largest size on a clean site, rounded outwards to 3 significant digits, a heating power downwards)
    from buildenv.diagnosis.effects import declared_ceilings

    results = Path(__file__).resolve().parent / "fixtures" / "measured_ceilings"  # copied from the benchmarks
    measured = {n: v for n, (v, _) in json.loads((results / f"{page}.json").read_text())["measured"].items()}
    # the wind term centred on a reference wind speed: its ceiling measured again, with it only (and the heating
    # power on the same sites, the carried starts' search)
    centred = json.loads(
        (results / f"gap_wind_centred{'_declared' if page == 'gap_declared_ceiling' else ''}.json").read_text()
    )["measured"]
    measured["wind_infiltration"] = centred["wind_infiltration"][0]
    measured["heating_capacity_limit"] = min(measured["heating_capacity_limit"], centred["heating_capacity_limit"][0])
    # the sensor bias sized from the clean sites' median: its ceilings measured again from it
    reading = json.loads((results / "gap_bias_reading.json").read_text())
    measured["temperature_sensor_bias"] = reading["declared_ceiling" if page == "gap_declared_ceiling" else "ceiling"]
    if page == "gap_declared_ceiling":
        typed = declared_ceilings()
    else:  # night plug loads are judged on the night electricity of recalibrated clean sites, measured apart
        typed = {e.name: e.clean_ceiling for e in EFFECTS.values() if e.clean_ceiling is not None}
        nights = json.loads((results / "gap_night_electricity.json").read_text())["clean_nights"]
        measured["night_plug_loads"] = max(value for value, _ in nights)
        # the heating power, also on the clean sites diagnosed again with its extra starts (either search)
        for path in results.glob("gap_carried_starts*.json"):
            ((power, _),) = json.loads(path.read_text())["measured"].values()
            measured["heating_capacity_limit"] = min(measured["heating_capacity_limit"], power)
    assert set(typed) == set(measured)
    for name, value in measured.items():
        effect = get_effect(name)
        orient = effect.strength if effect.building_parameter and effect.judged_on is None else float
        assert orient(value) <= orient(typed[name]) <= orient(value) + 0.01 * abs(value), (name, value, typed[name])


def test_a_site_declaring_parameters_known_is_judged_by_the_ceilings_of_such_sites():
    # with the medium office's internal loads declared known, clean sites calibrated a sensor bias of -0.29 to
    # -0.66 K and a heat exchanger of 0.2-0.3 (bench/results/gap_declared_ceiling.md), beyond the ceilings measured
    # on sites declaring nothing (0.281 K from the -0.233 K reading, 0.129): seed 100's clean case 1 had been named
    # a heat exchanger at 0.307
    from types import SimpleNamespace

    from buildenv.diagnosis.effects import declared_ceilings
    from buildenv.diagnosis.gap import candidate_qualifies, site_ceilings

    declaring, plain = SimpleNamespace(known={"light_night_percent": 5.6}), SimpleNamespace(known={})
    assert site_ceilings(plain) is True and site_ceilings(declaring, False) is False
    assert site_ceilings(plain, {"wind_infiltration": 0.03}) == {"wind_infiltration": 0.03}
    ceilings = site_ceilings(declaring)
    assert ceilings == declared_ceilings() and {"temperature_sensor_bias", "heat_recovery"} <= set(ceilings)
    exchanger, clean_bias = {"effectiveness": 0.307}, {"bias_k": -0.66}  # seed 102's twin of case 0: -0.664 K
    assert candidate_qualifies("heat_recovery", 0.26, 8e-13, 0.006, 0.10, exchanger)
    assert not candidate_qualifies("heat_recovery", 0.26, 8e-13, 0.006, 0.10, exchanger, clean_ceilings=ceilings)
    assert candidate_qualifies("temperature_sensor_bias", 0.28, 5e-20, 0.006, 0.10, clean_bias)
    assert not candidate_qualifies(
        "temperature_sensor_bias", 0.28, 5e-20, 0.006, 0.10, clean_bias, clean_ceilings=ceilings
    )
    # seed 103 case 4: a 1.6 K bias estimated at 0.797 K, under the 0.8 K floor of the time
    assert candidate_qualifies(
        "temperature_sensor_bias", 0.31, 1e-12, 0.006, 0.10, {"bias_k": 0.797}, clean_ceilings=ceilings
    )
    # the verdict quotes the ceiling the site was judged by
    entry = {
        "name": "temperature_sensor_bias",
        "plausible": True,
        "parameters": clean_bias,
        "score": 0.28,
        "series_made_worse": [],
        "beyond_clean_sites": False,
        "ceilings_of_declaring_sites": True,
        "significance": {"p_value": 5e-20, "threshold": 0.006},
    }
    bias_ceiling = ceilings["temperature_sensor_bias"]
    assert f"|bias_k + 0.233| > {bias_ceiling:g} K (the largest estimate calibrated on" in _verdict([], [entry], 0.10)
    assert "declaring the medium office's internal loads known" in _verdict([], [entry], 0.10)
    assert "|bias_k + 0.233| > 0.281 K" in _verdict([], [entry | {"ceilings_of_declaring_sites": False}], 0.10)


def test_the_night_electricity_adds_the_lights_and_equipment_left_on():
    theta = {"light_night_percent": 20.0, "lighting_power_w_m2": 10.0, "plug_load_w_m2": 7.5, "pc_night_percent": 40.0}
    assert night_electricity_w_m2(theta) == pytest.approx(10.0 * 0.2 + 7.5 * 0.4)  # W/m2
    moved = theta | {"light_night_percent": 50.0, "pc_night_percent": 0.0}  # the same load, carried by the lights
    assert night_electricity_w_m2(moved) == pytest.approx(night_electricity_w_m2(theta))


def test_a_carried_effect_calibrated_at_the_top_of_its_range_is_not_named():
    # seed 0 case 5 of the blind check (a heat exchanger): heating power calibrated at 99.9 W/m2, so the model is
    # the same building as the unlimited one it is judged against, yet the two refits differed by 28 % held-out
    from buildenv.diagnosis.gap import candidate_qualifies

    assert not candidate_qualifies("heating_capacity_limit", 0.28, 2.6e-6, 0.006, 0.15, {"heating_power_w_m2": 99.85})
    assert candidate_qualifies("heating_capacity_limit", 0.28, 2.6e-6, 0.006, 0.15, {"heating_power_w_m2": 36.0})
    # with the heating power declared known, the model-side cap is judged as any other effect
    assert candidate_qualifies(
        "heating_capacity_limit", 0.28, 2.6e-6, 0.006, 0.15, {"capacity_w_m2": 99.0, "sag_k_per_wh_m2": 0.0}
    )
    verdict = _verdict(
        [],
        [
            {
                "name": "heating_capacity_limit",
                "plausible": False,
                "score": 0.28,
                "parameters": {"heating_power_w_m2": 99.85},
                "series_made_worse": [],
                "significance": {"p_value": 2.6e-6, "threshold": 0.006},
            }
        ],
        0.15,
    )
    assert (
        "its estimate (heating_power_w_m2 99.8 W/m2) is outside what the diagnosis names: heating_power_w_m2 <= "
        "90 W/m2 (one catalogue step below" in verdict
    )


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


def test_a_night_electricity_far_beyond_every_clean_sites_names_night_loads_first_unless_the_bias_refits_warm():
    # the blind checks' records (bench/results/gap_night_first.md): seed 88 case 5, a 4.87 W/m2 night load whose
    # first step carried 7.82 W/m2 of night electricity (the lights' night share at 26 %) and refit the sensor bias
    # at -0.98 K; the held-out gains named that bias. Seed 57 case 9, a +2.94 K bias, carried 9.35 W/m2 and refit it
    # at +2.8 K. The other sites of seeds 0-92 carried at most 3.90 W/m2 (the ceiling: 3.61; 1.25 times: 4.51)
    from buildenv.diagnosis.effects import NIGHT_LOAD_FIRST_BEYOND
    from buildenv.diagnosis.gap import _night_load_first, night_load_named_first

    assert NIGHT_LOAD_FIRST_BEYOND == 1.25

    def estimates(night, bias):
        return {
            "night_plug_loads": {"light_night_percent": 26.3, "night_electricity_w_m2": night},
            "temperature_sensor_bias": {"bias_k": bias},
            "solar_shading": {"blocked_fraction": 0.5},
        }

    assert night_load_named_first(estimates(7.82, -0.98))
    assert not night_load_named_first(estimates(9.35, 2.8))  # a sensor reading warm makes the model heat at night
    assert not night_load_named_first(estimates(3.90, -0.33))  # seed 77 case 13, a capacity limit
    assert night_load_named_first(estimates(4.55, -0.41))  # seed 81 case 4, a 2.32 W/m2 load named nothing
    assert not night_load_named_first(estimates(4.50, -0.41))
    assert not night_load_named_first(estimates(7.82, -0.98), False)
    assert not night_load_named_first(estimates(7.82, -0.98), {"night_plug_loads": 8.0})  # a replay's ceilings
    no_bias = estimates(7.82, -0.98)
    del no_bias["temperature_sensor_bias"]
    assert not night_load_named_first(no_bias)  # the bias declared or not tested: a warm sensor is not ruled out

    # in a first step: the night candidate's trial replaces what the held-out gains selected, its entry marked
    trials = [(name, object(), {}) for name in ("solar_shading", "temperature_sensor_bias", "night_plug_loads")]
    entries = [
        {"name": name, "parameters": estimates(7.82, -0.98)[name], "qualifies": name == "solar_shading"}
        for name, _, _ in trials
    ]
    chosen = _night_load_first(trials, entries)
    assert chosen == ("night_plug_loads", trials[2][1]) and entries[2]["named_by_night_electricity"]
    assert _verdict(["night_plug_loads"], entries, 0.10) == (
        "unmodelled effect(s) found: night_plug_loads (plug loads left on at night; named first by the night "
        "electricity the model carries, 7.82 W/m2, beyond 1.25 times every clean site's 3.61 W/m2, with the sensor "
        "bias refit cold)"
    )
    entries[0]["qualifies"], entries[2]["qualifies"] = False, True  # already first by its gain: left as it is
    del entries[2]["named_by_night_electricity"]
    assert _night_load_first(trials, entries) is None and "named_by_night_electricity" not in entries[2]
    entries[2]["qualifies"], entries[1]["parameters"] = False, {"bias_k": 2.8}  # nothing selected, the bias warm
    assert _night_load_first(trials, entries) is None
    entries[1]["parameters"] = {"bias_k": -0.2}  # nothing selected, the bias cold: named all the same
    assert _night_load_first(trials, entries) == ("night_plug_loads", trials[2][1])


def test_blinds_are_judged_by_a_ceiling_that_grows_with_the_sunshine_of_the_fit_weeks():
    # bench/results/gap_sunshine_ceiling.md: clean sites fitted on the November weeks of the blind checks (66.9 W/m2)
    # calibrated blinds up to 0.332, those fitted on sunny October weeks (94.4 W/m2) up to 0.581
    from buildenv.diagnosis.effects import ceilings_in_sunshine
    from buildenv.diagnosis.gap import beyond_clean_sites, fit_irradiance_w_m2, named_by_estimate, site_ceilings

    blinds = get_effect("solar_shading")
    assert blinds.sunshine_ceiling == (0.00616, 66.9)
    assert blinds.in_sunshine(None) is blinds
    assert get_effect("heat_recovery").in_sunshine(50.0).clean_ceiling == 0.129
    november, october, winter = blinds.in_sunshine(66.878), blinds.in_sunshine(94.4), blinds.in_sunshine(40.0)
    assert november.clean_ceiling == november.estimate_ceiling == pytest.approx(0.412, abs=1e-3)
    assert 0.581 < october.clean_ceiling < 0.582  # the October clean site at 0.581 stays under it
    assert winter.clean_ceiling == november.clean_ceiling  # not extrapolated below the darkest weeks measured
    assert "times this site's 40.0 W/m2 (taken as 66.9)" in winter.clean_ceiling_text()
    assert "times this site's 66.9 W/m2" in november.estimate_ceiling_text()
    assert november.declared_ceiling == blinds.declared_ceiling == 0.795

    clean = ceilings_in_sunshine(66.9)
    assert set(clean) == {n for n, e in EFFECTS.items() if e.clean_ceiling is not None}
    assert clean["solar_shading"] == pytest.approx(0.412, abs=1e-3) and clean["heat_recovery"] == 0.129
    assert ceilings_in_sunshine(None, "estimate")["solar_shading"] == blinds.estimate_ceiling == 0.581
    with pytest.raises(ValueError, match="clean or estimate"):
        ceilings_in_sunshine(66.9, "declared")
    # a 0.45 blinds estimate: beyond every clean site's in November, among them in October
    assert beyond_clean_sites("solar_shading", {"blocked_fraction": 0.45}, ceilings_in_sunshine(66.9)) is True
    assert beyond_clean_sites("solar_shading", {"blocked_fraction": 0.45}, ceilings_in_sunshine(94.4)) is False
    assert beyond_clean_sites("solar_shading", {"blocked_fraction": 0.45}) is False  # the constant 0.574
    estimates = {"solar_shading": {"blocked_fraction": 0.45}, "heat_recovery": {"effectiveness": 0.05}}
    gains = {"solar_shading": -0.01, "heat_recovery": 0.0}
    assert named_by_estimate(estimates, gains, ceilings_in_sunshine(66.9, "estimate")) == ["solar_shading"]
    assert named_by_estimate(estimates, gains, ceilings_in_sunshine(94.4, "estimate")) == []

    site = load_site(DEFAULT_SITE)
    assert site_ceilings(site, True, 70.0) == ceilings_in_sunshine(70.0)
    assert site_ceilings(site, True) is True and site_ceilings(site, False, 70.0) is False
    declaring = dataclasses.replace(site, known={"occupants_per_100m2": 5.0})
    assert site_ceilings(declaring, True, 70.0)["solar_shading"] == 0.795  # declared sites' ceilings, unscaled

    weather = np.zeros((4, 168, len(WEATHER_NAMES)))
    weather[:, :, WEATHER_NAMES.index("IGLOB_H")] = np.array([100.0, 500.0, 60.0, 500.0])[:, None]
    assert fit_irradiance_w_m2(weather, [0, 2]) == pytest.approx(80.0)


def test_the_diagnosis_warns_when_its_metamodel_is_not_the_one_its_ceilings_were_measured_with(surrogate, caplog):
    from buildenv.diagnosis.gap import _warn_not_measured_with

    with caplog.at_level("WARNING"):
        _warn_not_measured_with(surrogate)
        assert not caplog.text
        _warn_not_measured_with(load_metamodel())
    assert "not with default" in caplog.text and "--checkpoint diagnosis" in caplog.text
