"""Hourly encoding of daily settings and weekday occupancy."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.campaign.sampling import sample_weeks
from buildenv.schedules import DEADBAND_K, HOURLY_CHANNELS, hourly_encoding, hourly_schedules, usage_fraction

S = {name: i for i, name in enumerate(cat.SETTING_NAMES)}

BASE_DAY = {
    "cooling_start_hour": 8,
    "cooling_end_hour": 19,
    "cooling_setback_c": 28,
    "cooling_comfort_c": 24,
    "heating_start_hour": 7,
    "heating_end_hour": 18,
    "heating_setback_c": 18,
    "heating_comfort_c": 22,
    "ventilation_start_hour": 7,
    "ventilation_end_hour": 19,
    "supply_air_c": 19,
    "ventilation_ach": 1.0,
    "hvac_operating": 1,
}


def _week(day_overrides: dict[int, dict[str, float]] | None = None, occ=((8, 18),) * 5):
    """One week (1, 7, 13) of settings from BASE_DAY with per-day overrides, and (1, 5, 2) occupancy."""
    settings = np.tile([BASE_DAY[n] for n in cat.SETTING_NAMES], (1, 7, 1)).astype(float)
    for day, over in (day_overrides or {}).items():
        for name, value in over.items():
            settings[0, day, S[name]] = value
    occupancy = np.array(occ, dtype=float)[None]
    cat.check_values("settings", settings)
    cat.check_values("occupancy", occupancy)
    return settings, occupancy


def _day(series: np.ndarray, day: int) -> np.ndarray:
    return series[0, day * 24 : (day + 1) * 24]


# --------------------------------------------------------------------------- hand-made week
def test_comfort_periods_follow_start_and_end_of_each_day():
    overrides = {
        0: {"heating_start_hour": 6, "heating_end_hour": 17},
        2: {"heating_start_hour": 8, "heating_end_hour": 19, "heating_comfort_c": 23.5, "heating_setback_c": 17},
        6: {"cooling_start_hour": 9, "cooling_end_hour": 20, "cooling_setback_c": 30},
    }
    settings, occupancy = _week(overrides)
    sched = hourly_schedules(settings, occupancy)
    hours = np.arange(24)
    for day in range(7):
        s = settings[0, day]
        heat_on = (hours >= s[S["heating_start_hour"]]) & (hours < s[S["heating_end_hour"]])
        cool_on = (hours >= s[S["cooling_start_hour"]]) & (hours < s[S["cooling_end_hour"]])
        np.testing.assert_array_equal(_day(sched["heating_comfort_on"], day), heat_on.astype(float))
        np.testing.assert_array_equal(_day(sched["cooling_comfort_on"], day), cool_on.astype(float))
        np.testing.assert_array_equal(
            _day(sched["heating_setpoint_c"], day),
            np.where(heat_on, s[S["heating_comfort_c"]], s[S["heating_setback_c"]]),
        )
        np.testing.assert_array_equal(
            _day(sched["cooling_setpoint_c"], day),
            np.where(cool_on, s[S["cooling_comfort_c"]], s[S["cooling_setback_c"]]),
        )
    # spot checks with literal numbers (Monday heating 06-17, Wednesday 08-19 at 23.5/17)
    mon_heat = _day(sched["heating_setpoint_c"], 0)
    assert mon_heat[5] == 18 and mon_heat[6] == 22 and mon_heat[16] == 22 and mon_heat[17] == 18
    wed_heat = _day(sched["heating_setpoint_c"], 2)
    assert wed_heat[7] == 17 and wed_heat[8] == 23.5 and wed_heat[18] == 23.5 and wed_heat[19] == 17
    sun_cool = _day(sched["cooling_setpoint_c"], 6)
    assert sun_cool[8] == 30 and sun_cool[9] == 24 and sun_cool[19] == 24 and sun_cool[20] == 30
    # the week starts Monday 00:00: hour 24 is Tuesday 00:00
    assert sched["heating_setpoint_c"][0, 24 + 7] == 22 and sched["heating_setpoint_c"][0, 24 + 6] == 18


def test_occupancy_weekdays_only_and_within_hours():
    occ = ((7, 17), (8, 18), (9, 19), (7, 20), (9, 17))
    settings, occupancy = _week(occ=occ)
    frac = hourly_schedules(settings, occupancy)["occupancy_fraction"]
    assert frac.shape == (1, 168)
    hours = np.arange(24)
    for day, (start, end) in enumerate(occ):
        np.testing.assert_array_equal(_day(frac, day), ((hours >= start) & (hours < end)).astype(float))
    assert frac[0, 5 * 24 :].sum() == 0  # Saturday and Sunday empty
    assert frac.sum() == 10 + 10 + 10 + 13 + 8


def test_deadband_interlock_raises_cooling_setpoint():
    # cooling comfort 20 with heating comfort 23: cooling in force is 23 + 0.5 while heating comfort is on
    settings, occupancy = _week({d: {"cooling_comfort_c": 20, "heating_comfort_c": 23} for d in range(7)})
    sched = hourly_schedules(settings, occupancy)
    heat_on = sched["heating_comfort_on"].astype(bool)
    cool_on = sched["cooling_comfort_on"].astype(bool)
    cool = sched["cooling_setpoint_c"]
    assert DEADBAND_K == 0.5
    assert np.all(cool[heat_on & cool_on] == 23.5)
    assert (heat_on & cool_on).sum() == 7 * 10  # 08-18 each day
    # hour 7: heating comfort on, cooling at its 28 degC setback, already above 23.5
    assert np.all(cool[heat_on & ~cool_on] == 28.0)
    # cooling comfort on (08-19) but heating back at setback 18 (hour 18): cooling comfort 20 stays
    both = cool_on & ~heat_on
    assert both.sum() == 7  # hour 18 of each day
    assert np.all(cool[both] == 20.0)
    # outside both periods: setbacks 18 / 28, no interlock needed
    neither = ~cool_on & ~heat_on
    assert np.all(cool[neither] == 28.0)
    assert np.all(sched["heating_setpoint_c"] < cool)


def test_deadband_interlock_inactive_when_setpoints_are_apart():
    settings, occupancy = _week()
    sched = hourly_schedules(settings, occupancy)
    day = _day(sched["cooling_setpoint_c"], 1)
    expected = np.where((np.arange(24) >= 8) & (np.arange(24) < 19), 24.0, 28.0)
    np.testing.assert_array_equal(day, expected)


def test_ventilation_ach_zero_when_off_and_supply_all_day():
    overrides = {
        4: {"ventilation_start_hour": 9, "ventilation_end_hour": 18, "ventilation_ach": 1.6, "supply_air_c": 24.5}
    }
    settings, occupancy = _week(overrides)
    sched = hourly_schedules(settings, occupancy)
    on = sched["ventilation_on"].astype(bool)
    ach = sched["ventilation_ach"]
    assert np.all(ach[~on] == 0.0)
    assert np.all(ach[on] > 0)
    fri_ach = _day(ach, 4)
    hours = np.arange(24)
    np.testing.assert_allclose(fri_ach, np.where((hours >= 9) & (hours < 18), 1.6, 0.0))
    np.testing.assert_allclose(_day(ach, 0), np.where((hours >= 7) & (hours < 19), 1.0, 0.0))
    # supply air temperature is the day's value around the clock
    np.testing.assert_array_equal(_day(sched["supply_air_c"], 4), np.full(24, 24.5))
    np.testing.assert_array_equal(_day(sched["supply_air_c"], 3), np.full(24, 19.0))


def test_a_day_set_back_entirely_holds_the_setbacks_with_the_air_handling_unit_off():
    settings, occupancy = _week({5: {"hvac_operating": 0}, 6: {"hvac_operating": 0}})
    sched = {k: v.reshape(7, 24) for k, v in hourly_schedules(settings, occupancy).items()}
    for name in ("heating_comfort_on", "cooling_comfort_on", "ventilation_on", "ventilation_ach"):
        assert sched[name][5:].sum() == 0, name
        assert sched[name][:5].sum() > 0, name
    assert np.all(sched["heating_setpoint_c"][5:] == BASE_DAY["heating_setback_c"])
    assert np.all(sched["cooling_setpoint_c"][5:] == BASE_DAY["cooling_setback_c"])


def test_settings_from_before_hvac_operating_read_every_day_as_operating():
    settings, occupancy = _week()
    old = hourly_encoding(settings[..., :-1], occupancy)
    np.testing.assert_array_equal(old, hourly_encoding(settings, occupancy))
    with pytest.raises(cat.CatalogueError, match="values a day"):
        hourly_encoding(settings[..., :-2], occupancy)


def test_campaign_weeks_set_weekend_days_back_more_often_than_weekdays():
    settings, _ = sample_weeks(4000, np.random.default_rng(0))
    off = 1.0 - settings[..., S["hvac_operating"]].mean(0)
    assert set(np.unique(settings[..., S["hvac_operating"]])) == {0.0, 1.0}
    assert np.all(np.abs(off[:5] - 0.15) < 0.03) and np.all(np.abs(off[5:] - 0.5) < 0.04)


def test_two_dimensional_inputs_are_one_week():
    settings, occupancy = _week()
    a = hourly_schedules(settings[0], occupancy[0])
    b = hourly_schedules(settings, occupancy)
    assert set(a) == set(HOURLY_CHANNELS)
    for k in HOURLY_CHANNELS:
        assert a[k].shape == (1, 168)
        np.testing.assert_array_equal(a[k], b[k])


# --------------------------------------------------------------------------- encoding
def test_hourly_encoding_shape_and_channel_order():
    rng = np.random.default_rng(3)
    settings, occupancy = sample_weeks(4, rng)
    enc = hourly_encoding(settings, occupancy)
    assert enc.shape == (4, 168, 8)
    assert len(HOURLY_CHANNELS) == 8
    assert HOURLY_CHANNELS == (
        "heating_setpoint_c",
        "cooling_setpoint_c",
        "heating_comfort_on",
        "cooling_comfort_on",
        "ventilation_on",
        "ventilation_ach",
        "supply_air_c",
        "occupancy_fraction",
    )
    sched = hourly_schedules(settings, occupancy)
    for i, name in enumerate(HOURLY_CHANNELS):
        np.testing.assert_array_equal(enc[..., i], sched[name])
    # each week is encoded from its own settings
    np.testing.assert_array_equal(hourly_encoding(settings[2], occupancy[2])[0], enc[2])


# --------------------------------------------------------------------------- usage fraction
def test_usage_fraction():
    occ = np.array([0.0, 1.0, 0.0, 1.0])
    np.testing.assert_allclose(usage_fraction(occ, 30), [0.3, 1.0, 0.3, 1.0])
    np.testing.assert_allclose(usage_fraction(occ, 0), occ)
    np.testing.assert_allclose(usage_fraction(occ, 100), np.ones(4))
    np.testing.assert_allclose(usage_fraction(np.array([0.5]), 20), [0.6])


# --------------------------------------------------------------------------- properties on random weeks
@pytest.fixture(scope="module")
def random_weeks():
    rng = np.random.default_rng(20240611)
    settings, occupancy = sample_weeks(200, rng)
    return settings, occupancy, hourly_schedules(settings, occupancy)


def test_property_heating_below_cooling(random_weeks):
    _, _, sched = random_weeks
    gap = sched["cooling_setpoint_c"] - sched["heating_setpoint_c"]
    assert gap.min() >= DEADBAND_K - 1e-12


def test_property_occupancy_only_on_weekdays(random_weeks):
    _, occupancy, sched = random_weeks
    occ = sched["occupancy_fraction"].reshape(-1, 7, 24)
    assert np.all(occ[:, 5:] == 0)
    assert set(np.unique(occ)) <= {0.0, 1.0}
    hours_per_day = occ[:, :5].sum(axis=-1)
    np.testing.assert_array_equal(hours_per_day, occupancy[..., 1] - occupancy[..., 0])
    assert hours_per_day.min() >= 17 - 9 and hours_per_day.max() <= 20 - 7


def test_property_setpoints_come_from_the_days_settings(random_weeks):
    settings, _, sched = random_weeks
    heat = sched["heating_setpoint_c"].reshape(-1, 7, 24)
    on = sched["heating_comfort_on"].reshape(-1, 7, 24).astype(bool)
    comfort = np.broadcast_to(settings[..., S["heating_comfort_c"], None], heat.shape)
    setback = np.broadcast_to(settings[..., S["heating_setback_c"], None], heat.shape)
    np.testing.assert_array_equal(heat[on], comfort[on])
    np.testing.assert_array_equal(heat[~on], setback[~on])
    # comfort periods are contiguous blocks of end - start hours
    length = settings[..., S["heating_end_hour"]] - settings[..., S["heating_start_hour"]]
    np.testing.assert_array_equal(on.sum(-1), length * settings[..., S["hvac_operating"]])


def test_property_cooling_in_force_is_the_setting_or_the_interlock(random_weeks):
    settings, _, sched = random_weeks
    cool = sched["cooling_setpoint_c"].reshape(-1, 7, 24)
    heat = sched["heating_setpoint_c"].reshape(-1, 7, 24)
    on = sched["cooling_comfort_on"].reshape(-1, 7, 24).astype(bool)
    nominal = np.where(on, settings[..., S["cooling_comfort_c"], None], settings[..., S["cooling_setback_c"], None])
    np.testing.assert_array_equal(cool, np.maximum(nominal, heat + DEADBAND_K))
    assert np.any(cool > nominal)  # the interlock does fire on random weeks


def test_property_ventilation(random_weeks):
    settings, _, sched = random_weeks
    on = sched["ventilation_on"].astype(bool)
    ach = sched["ventilation_ach"]
    assert np.all(ach[~on] == 0)
    vent = cat.get("ventilation_ach")
    assert np.all((ach[on] >= vent.min) & (ach[on] <= vent.max))
    supply = sched["supply_air_c"].reshape(-1, 7, 24)
    np.testing.assert_array_equal(supply, np.broadcast_to(settings[..., S["supply_air_c"], None], supply.shape))


def test_property_binary_channels(random_weeks):
    _, _, sched = random_weeks
    for name in ("heating_comfort_on", "cooling_comfort_on", "ventilation_on", "occupancy_fraction"):
        assert set(np.unique(sched[name])) <= {0.0, 1.0}, name
    # night hours (00-05, 21-23) are never in a comfort, ventilation or occupancy period
    night = np.r_[0:6, 21:24]
    for name in ("heating_comfort_on", "cooling_comfort_on", "ventilation_on", "occupancy_fraction"):
        assert sched[name].reshape(-1, 7, 24)[..., night].sum() == 0, name
