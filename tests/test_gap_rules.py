"""The gap diagnosis' held-out evidence, data needs and naming rules, on constructed cases."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.diagnosis import data_needs, rules
from buildenv.diagnosis.evidence import Evidence, heldout_test, variance_inflation
from buildenv.diagnosis.report import verdict
from buildenv.metamodel import surrogate as sg

SERIES = ("temperature", "consumption")


def _ar1(rng: np.random.Generator, shape: tuple[int, ...], rho: float) -> np.ndarray:
    """A first-order autoregressive series of unit variance laid out as ``shape``."""
    e = rng.standard_normal(int(np.prod(shape)))
    x = np.empty_like(e)
    x[0] = e[0]
    for i in range(1, len(e)):
        x[i] = rho * x[i - 1] + np.sqrt(1.0 - rho**2) * e[i]
    return x.reshape(shape)


def _evidence(gain: float, p: float, **by_series: float) -> Evidence:
    return Evidence(gain, p, 1, 1344, 200.0, gain_by_series={"temperature": gain, "consumption": gain, **by_series})


@pytest.mark.parametrize("rho", [0.0, 0.8, 0.9])
def test_a_steady_footprint_against_a_first_order_lag_counts_its_autocorrelation_time(rho):
    # Bartlett: a constant footprint (a sensor bias) against what is left with it, a first-order lag
    residuals = _ar1(np.random.default_rng(1), (8, 168), rho)
    residuals -= residuals.mean()
    inflation = variance_inflation(residuals, np.ones((8, 168)))
    assert inflation == pytest.approx((1 + rho) / (1 - rho), rel=0.25, abs=0.3)
    # a footprint of independent hours is not inflated whatever the residuals do
    assert variance_inflation(residuals, np.random.default_rng(2).standard_normal((8, 168))) < 1.5


def test_a_miss_repeated_every_day_against_a_daily_footprint_counts_once():
    rng = np.random.default_rng(2)
    days = 4 * 7
    daily = np.tile(rng.standard_normal(24), days).reshape(4, 168)  # the same evening missed every day
    assert variance_inflation(daily, np.tile(rng.standard_normal(24), days).reshape(4, 168)) > 0.5 * days
    assert variance_inflation(np.full((4, 168), np.nan), daily) == 1.0


@pytest.mark.parametrize("rho, smooth, series", [(0.0, 0.0, SERIES), (0.8, 0.98, SERIES), (0.95, 0.98, SERIES[:1])])
def test_a_candidate_that_is_not_there_is_significant_at_most_at_the_stated_rate(rho, smooth, series):
    # the worst case: residuals of an exact model (autocorrelated noise) and a candidate footprint unrelated to
    # them, fitted on the held-out weeks themselves, in both series or in the temperature alone (a sensor effect);
    # counting every hour as independent names it far more often
    rng = np.random.default_rng(0)
    draws, alpha, hits = 300, 0.05, 0
    for _ in range(draws):
        before = {s: _ar1(rng, (4, 168), rho) for s in SERIES}
        footprint = {s: _ar1(rng, (4, 168), smooth) if s in series else np.zeros((4, 168)) for s in SERIES}
        x = np.concatenate([footprint[s].ravel() for s in SERIES])
        y = np.concatenate([before[s].ravel() for s in SERIES])
        beta = (x @ y) / (x @ x)
        hits += heldout_test(before, {s: before[s] - beta * footprint[s] for s in SERIES}, 1).p_value < alpha
    assert hits / draws <= alpha + 2 * np.sqrt(alpha * (1 - alpha) / draws)


def test_an_effect_that_is_there_is_significant_and_its_gain_is_the_share_removed():
    rng = np.random.default_rng(3)
    noise = {s: 0.3 * _ar1(rng, (4, 168), 0.5) for s in SERIES}
    effect = np.sin(np.arange(4 * 168) * 2 * np.pi / 24).reshape(4, 168)  # a daily footprint, both series
    before = {s: noise[s] + effect for s in SERIES}
    e = heldout_test(before, noise, 1)
    sse_b = sum(float((before[s] ** 2).sum()) for s in SERIES)
    sse_a = sum(float((noise[s] ** 2).sum()) for s in SERIES)
    assert e.gain == pytest.approx(1 - sse_a / sse_b) and e.gain > 0.8 and e.p_value < 1e-6
    assert e.n == 2 * 672 and e.k == 1 and len(e.sse_by_day["consumption"]) == 28
    worse = heldout_test(noise, before, 1)
    assert worse.gain < 0 and worse.p_value == 1.0


def test_each_rule_judges_its_own_question():
    lacking = rules.Candidate("heat_recovery", None, lacking="0 fit-week hours")
    assert "not enough data to tell: 0 fit-week hours" in rules.EnoughData().check(lacking)
    assert rules.EnoughData().check(rules.Candidate("wind_infiltration", _evidence(0.2, 1e-9))) is None

    significant = rules.Significant()
    assert significant.check(rules.Candidate("holidays", _evidence(0.2, 1e-9), threshold=0.005)) is None
    assert "not significant (p = 0.01" in significant.check(
        rules.Candidate("holidays", _evidence(0.2, 0.01), threshold=0.005)
    )
    assert "does not improve" in significant.check(rules.Candidate("holidays", _evidence(-0.01, 1.0)))

    shows = rules.ShowsWhereItShould()
    # a sensor bias shows in the temperature: a worse consumption is none of its business
    bias = rules.Candidate("temperature_sensor_bias", _evidence(0.2, 1e-9, consumption=-0.1), {"bias_k": 1.0})
    assert shows.check(bias) is None
    wind_on_temperature = _evidence(0.1, 1e-9, consumption=-0.02, temperature=0.3)
    assert "consumption" in shows.check(rules.Candidate("wind_infiltration", wind_on_temperature))
    # a carried heating power that trades the temperature for the consumption absorbs another miss
    trade = rules.Candidate(
        "heating_capacity_limit", _evidence(0.35, 1e-9, temperature=-0.7), {"heating_power_w_m2": 30.0}
    )
    assert "temperature" in shows.check(trade)
    trade.evidence.gain_by_series["temperature"] = 0.4
    assert shows.check(trade) is None
    # the lights' night share carrying a night load heats the zones too: a worse temperature is its business
    night = rules.Candidate("night_plug_loads", _evidence(0.2, 1e-9, temperature=-0.1), {"light_night_percent": 40.0})
    assert "temperature" in shows.check(night)

    plausible = rules.PlausibleSize()
    assert plausible.check(rules.Candidate("temperature_sensor_bias", None, {"bias_k": -1.0})) is None
    small = plausible.check(rules.Candidate("temperature_sensor_bias", None, {"bias_k": 0.3}))
    assert "bias_k 0.3 K" in small and "|bias_k| >= 0.4 K" in small


def test_the_best_qualifying_gain_is_selected_and_a_candidate_without_data_is_judged_by_nothing_else():
    candidates = [
        rules.Candidate("solar_shading", _evidence(0.5, 1e-9), {"blocked_fraction": 0.05}, 0.01),  # implausible
        rules.Candidate("wind_infiltration", _evidence(0.1, 1e-6), {"ach_per_m_s": 0.05}, 0.01),
        rules.Candidate("temperature_sensor_lag", _evidence(0.2, 1e-8), {"tau_h": 1.0}, 0.01),
        rules.Candidate("heat_recovery", None, lacking="no heating"),
    ]
    rules.judge(candidates)
    assert [c.name for c in candidates][:3] == ["solar_shading", "temperature_sensor_lag", "wind_infiltration"]
    assert list(candidates[0].failed) == ["plausible_size"]
    assert candidates[-1].status == rules.NOT_ENOUGH_DATA and list(candidates[-1].failed) == ["enough_data"]
    assert rules.select(candidates).name == "temperature_sensor_lag"
    assert rules.select([candidates[0], candidates[-1]]) is None


def test_an_effect_needing_heated_hours_lacks_data_in_a_summer_week():
    outputs = np.zeros((2, 168, len(cat.OUTPUT_NAMES)))
    inputs = np.zeros((2, 168, len(sg.INPUT_CHANNELS)))
    inputs[..., sg.INPUT_CHANNELS.index("heating_power_w_m2")] = 100.0
    inputs[:, 8:18, sg.INPUT_CHANNELS.index("ventilation_on")] = 1.0
    ahu, zone = cat.OUTPUT_NAMES.index("Q_AHU_H"), cat.OUTPUT_NAMES.index("Q_HEAT_OFFICE")
    assert not data_needs.hours_showing("ventilated_heating", outputs, inputs).any()
    outputs[:, 8:12, ahu] = 30.0  # four cold mornings' worth of heated outdoor air a week
    outputs[:, 0:6, zone] = 5.0  # heated nights, the fans off
    outputs[:, 6:8, zone] = 30.0  # the zones' morning boost
    assert data_needs.hours_showing("ventilated_heating", outputs, inputs).sum() == 8
    assert data_needs.hours_showing("heating_fans_off", outputs, inputs).sum() == 16
    assert data_needs.hours_showing("heating_peaks", outputs, inputs, 0.25).sum() == 4  # 30 of 100 W/m2, zones
    assert data_needs.lacking("ventilated_heating", 12, 12) is None and data_needs.lacking(None, 0, 0) is None
    assert "3 held-out hours in which the air handling unit" in data_needs.lacking("ventilated_heating", 40, 3)
    with pytest.raises(KeyError, match="unknown data need"):
        data_needs.hours_showing("sunny", outputs, inputs)


def test_the_verdict_names_the_effects_or_says_why_not_and_what_it_cannot_tell():
    lag = {
        "name": "temperature_sensor_lag",
        "title": "temperature sensor lag",
        "status": rules.NAMED,
        "score": 0.21,
        "p_value": 3e-9,
        "parameters": {"tau_h": 1.2},
        "failed": {},
    }
    wind = {**lag, "name": "wind_infiltration", "status": rules.NOT_NAMED, "score": 0.04, "failed": {"x": "too weak"}}
    lacking = {"heat_recovery": "0 fit-week hours"}
    named = {"steps": [{"candidates": [lag, wind]}], "effects": [lag, wind], "not_enough_data": lacking}
    text = verdict(named)
    assert text.startswith("unmodelled effect(s) found: temperature_sensor_lag (temperature sensor lag; tau_h 1.2 h;")
    assert "held-out gain 21.0 %, p = 3e-09" in text and text.endswith("heat_recovery (0 fit-week hours)")
    nothing = {"steps": [{"candidates": [wind]}], "effects": [wind], "not_enough_data": {}}
    assert verdict(nothing) == (
        "no unmodelled effect found among the 1 effects these weeks can show (best candidate: wind_infiltration, "
        "held-out gain 4.0 %: too weak)"
    )
