"""Injection of the unmodelled effects into the reference-building stand-in (buildenv.energyplus.injections).

Short runs: medium_office, Chicago, one measured week from 2019-11-04 after one warm-up week (about 3 s each);
the baseline is run once per module.
"""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.cli.main import main
from buildenv.diagnosis.effects import EFFECTS, NO_EFFECT_MAGNITUDE, EffectError
from buildenv.energyplus.idf import of_type, read_idf
from buildenv.energyplus.injections import (
    InjectedEffect,
    assign_holidays,
    choose_holidays,
    complement_schedule,
    first_order_lag,
    inject_energyplus,
    plan_effects,
    weekday_profile,
)
from buildenv.energyplus.reference import (
    REFERENCE_BUILDINGS,
    historical_settings,
    make_reference_site,
    reference_idf,
    run_reference,
)
from buildenv.errors import ReferenceBuildingError
from buildenv.weather.epw import epw_day_of_year, load_weather

START = dt.date(2019, 11, 4)
WEEKS = 1
HOUR = np.arange(cat.HOURS_PER_WEEK) % 24
DAY = np.arange(cat.HOURS_PER_WEEK) // 24


def _run(effects=None, seed: int = 0):
    return run_reference(
        "medium_office", "usa_il_chicago", START, historical_settings(WEEKS), effects=effects, effect_seed=seed
    )


@pytest.fixture(scope="module")
def base():
    return _run()


@pytest.fixture(scope="module")
def weather_week():
    w = load_weather("usa_il_chicago")
    h0 = epw_day_of_year(START) * 24
    return {n: w.channel(n)[h0 : h0 + cat.HOURS_PER_WEEK] for n in ("WIND_SPEED", "IGLOB_H", "TAMB")}


# --- planning and pure edits (no EnergyPlus) ------------------------------------------------------------------


def test_plan_effects_defaults_and_errors():
    planned = plan_effects([("temperature_sensor_bias", None), ("holidays", 2)], START, 4, seed=5)
    assert planned[0].magnitude == EFFECTS["temperature_sensor_bias"].default_magnitude
    assert planned[1].truth()["unit"] == EFFECTS["holidays"].magnitude_unit
    assert len(planned[1].details["dates"]) == 2
    with pytest.raises(EffectError, match="unknown effect"):
        plan_effects([("wind", 1.0)], START, 1)
    with pytest.raises(EffectError, match="outside"):
        plan_effects([("solar_shading", 120.0)], START, 1)
    with pytest.raises(EffectError, match="more than once"):
        plan_effects([("holidays", 1), ("holidays", 2)], START, 2)
    with pytest.raises(EffectError, match="whole number"):
        plan_effects([("holidays", 1.5)], START, 2)
    with pytest.raises(EffectError, match="at most 5"):
        plan_effects([("holidays", 6)], START, 1)


def test_choose_holidays_spreads_over_both_halves():
    for seed in range(20):
        days = choose_holidays(2, START, 4, seed)
        weeks = sorted((d - START).days // 7 for d in days)
        assert all(d.weekday() < 5 for d in days) and len(set(days)) == 2
        assert weeks[0] < 2 <= weeks[1]  # one in the first ceil(4/2) weeks, one in the others
    assert choose_holidays(3, START, 3, 7) == choose_holidays(3, START, 3, 7)  # seeded


def test_assign_holidays_moves_the_holiday_clause():
    infil = [
        "Schedule:Compact",
        "INFIL",
        "Fraction",
        "Through: 12/31",
        "For: Weekdays SummerDesignDay",
        "Until: 06:00",
        "1.0",
        "Until: 24:00",
        "0.25",
        "For: Sunday Holidays AllOtherDays",
        "Until: 24:00",
        "1.0",
    ]
    out = assign_holidays(infil, "monday")
    assert out[4] == "For: Weekdays SummerDesignDay Holiday" and out[9] == "For: Sunday AllOtherDays"
    only = [
        "Schedule:Compact",
        "S",
        "Fraction",
        "Through: 12/31",
        "For: Weekdays",
        "Until: 24:00",
        "1",
        "For: Holiday",
        "Until: 24:00",
        "0",
        "For: AllOtherDays",
        "Until: 24:00",
        "0.5",
    ]
    assert assign_holidays(only, "sunday") == [
        "Schedule:Compact",
        "S",
        "Fraction",
        "Through: 12/31",
        "For: Weekdays",
        "Until: 24:00",
        "1",
        "For: AllOtherDays Holiday",
        "Until: 24:00",
        "0.5",
    ]
    always = ["Schedule:Compact", "A", "", "Through: 12/31", "For: AllDays", "Until: 24:00", "1"]
    assert assign_holidays(always, "monday") == always


def test_complement_schedule():
    occ = [
        "Schedule:Compact",
        "OCC",
        "Fraction",
        "Through: 12/31",
        "For: AllDays",
        "Until: 08:00",
        "0.0",
        "Until: 18:00",
        "0.95",
        "Until: 24:00",
        "0.05",
    ]
    out = complement_schedule(occ, "NIGHT")
    assert out[1] == "NIGHT" and [out[6], out[8], out[10]] == ["1", "0.05", "0.95"]


def test_energyplus_edits_on_the_idf():
    objects = read_idf(reference_idf("medium_office"))
    planned = plan_effects(
        [
            ("wind_infiltration", 20),
            ("solar_shading", 50),
            ("night_plug_loads", 2),
            ("heat_recovery", 60),
            ("holidays", 1),
        ],
        START,
        1,
        seed=1,
    )
    out = inject_energyplus(objects, planned, "medium_office")
    assert read_idf(reference_idf("medium_office")) == objects  # input untouched
    assert {o[11] for o in of_type(out, "ZoneInfiltration:DesignFlowRate")} == {"0.2"}
    assert of_type(out, "WindowMaterial:SimpleGlazingSystem")[0][3] == "0.195"
    people = of_type(out, "People")
    night = [o for o in of_type(out, "ElectricEquipment") if o[-1] == "NightPlugLoads"]
    assert len(night) == len(people) and all(o[6] == "2" for o in night)
    hx = of_type(out, "HeatExchanger:AirToAir:SensibleAndLatent")
    assert len(hx) == len(of_type(out, "AirLoopHVAC:OutdoorAirSystem")) and hx[0][4] == "0.6"
    mixers = {o[3] for o in of_type(out, "OutdoorAir:Mixer")}
    assert {o[9] for o in hx} == mixers  # the mixers draw the exchangers' outlets
    special = of_type(out, "RunPeriodControl:SpecialDays")
    assert [o[2:] for o in special] == [
        [f"{d.month}/{d.day}", "1", "Holiday"] for d in map(dt.date.fromisoformat, planned[-1].details["dates"])
    ]
    night = inject_energyplus(objects, plan_effects([("night_cycle_cold_air", 20)], START, 1), "medium_office")
    boxes = of_type(night, "AirTerminal:SingleDuct:VAV:Reheat")
    assert {(o[6], o[9]) for o in boxes} == {("Scheduled", "buildenv night minimum flow 1")}
    (program,) = of_type(night, "EnergyManagementSystem:Program")
    assert program[2:] == [
        "IF buildenv_hvac_on > 0.5",
        "SET buildenv_minimum_flow_0 = 0.3",
        "ELSE",
        "SET buildenv_minimum_flow_0 = 0.5",
        "ENDIF",
    ]
    evening = inject_energyplus(objects, plan_effects([("evening_departure", 2)], START, 1), "medium_office")
    schedules = {o[1]: o for o in of_type(evening, "Schedule:Compact")}
    before = {o[1]: o for o in of_type(objects, "Schedule:Compact")}
    # the DOE occupancy: 0.7 to 18:00, 0.4 to 20:00, 0.1 to 22:00, 0.05 to 24:00 -> 0.4 two hours longer
    np.testing.assert_allclose(
        weekday_profile(schedules["BLDG_OCC_SCH"])[2][16:], [0.95, 0.7, 0.4, 0.4, 0.4, 0.4, 0.1, 0.1]
    )
    np.testing.assert_allclose(weekday_profile(schedules["BLDG_LIGHT_SCH"])[2][17:], [0.7] + [0.5] * 4 + [0.3] * 2)
    for name in ("BLDG_OCC_SCH", "BLDG_LIGHT_SCH", "BLDG_EQUIP_SCH"):  # the day until 18:00 and other days kept
        np.testing.assert_array_equal(weekday_profile(schedules[name])[2][:18], weekday_profile(before[name])[2][:18])
        assert (
            schedules[name][weekday_profile(schedules[name])[1] :] == before[name][weekday_profile(before[name])[1] :]
        )
    small = read_idf(reference_idf("small_office"))  # packaged single-zone units: no VAV boxes
    with pytest.raises(ReferenceBuildingError, match="night_cycle_cold_air"):
        inject_energyplus(small, plan_effects([("night_cycle_cold_air", 20)], START, 1), "small_office")
    with pytest.raises(ReferenceBuildingError, match="sizing run"):
        inject_energyplus(objects, plan_effects([("heating_capacity_limit", 50)], START, 1), "medium_office")
    with pytest.raises(ReferenceBuildingError, match="no heat exchanger"):
        inject_energyplus(out, plan_effects([("heat_recovery", 60)], START, 1), "medium_office")


def test_first_order_lag():
    x = np.r_[np.zeros(5), np.ones(20)]
    y = first_order_lag(x, 2.0)
    assert y[5] == pytest.approx(1 - np.exp(-0.5)) and y[-1] < 1 and np.all(np.diff(y) >= 0)
    np.testing.assert_array_equal(first_order_lag(x, 0.0), x)


# --- runs -----------------------------------------------------------------------------------------------------


def test_no_effect_magnitudes_are_bit_identical(base):
    run = _run([(name, NO_EFFECT_MAGNITUDE[name]) for name in EFFECTS])
    np.testing.assert_array_equal(run.temperature_c, base.temperature_c)
    np.testing.assert_array_equal(run.consumption_kwh, base.consumption_kwh)
    np.testing.assert_array_equal(run.hvac_kwh, base.hvac_kwh)
    assert [e["name"] for e in run.effects] == list(EFFECTS) and base.effects == []


def test_sensor_bias_and_lag(base):
    run = _run([("temperature_sensor_bias", -1.5), ("temperature_sensor_lag", 2.0)])
    np.testing.assert_array_equal(run.consumption_kwh, base.consumption_kwh)
    full = first_order_lag(np.r_[base.warmup_temperature_c, base.temperature_c.ravel()], 2.0)
    np.testing.assert_allclose(run.temperature_c.ravel(), full[-cat.HOURS_PER_WEEK :] - 1.5, atol=1e-12)
    rise = np.diff(run.temperature_c[0]).reshape(-1)[: 24 * 5 - 1]  # weekdays: start-ups and setbacks
    true_rise = np.diff(base.temperature_c[0]).reshape(-1)[: 24 * 5 - 1]
    assert rise.max() < 0.7 * true_rise.max() and np.abs(rise).sum() < np.abs(true_rise).sum()


def test_holidays_cut_the_absent_day(base):
    run = _run([("holidays", 1)], seed=3)
    (date,) = run.effects[0]["details"]["dates"]
    day = (dt.date.fromisoformat(date) - START).days
    assert 0 <= day < 5
    absent, usual = run.consumption_kwh[0].reshape(7, 24)[day].sum(), base.consumption_kwh[0].reshape(7, 24)[day].sum()
    assert absent < 0.7 * usual
    np.testing.assert_array_equal(run.consumption_kwh[0, : 24 * day], base.consumption_kwh[0, : 24 * day])  # before it
    t_run, t_base = run.temperature_c[0].reshape(7, 24), base.temperature_c[0].reshape(7, 24)
    assert t_run[day, 9:17].mean() < t_base[day, 9:17].mean()  # no people, lights or plug loads: colder


def test_night_plug_loads_raise_the_night_base(base):
    run = _run([("night_plug_loads", 3.0)])
    night = (DAY >= 5) | (HOUR < 6)
    added = (run.consumption_kwh[0] - base.consumption_kwh[0])[night].mean()
    full = 3.0 * base.floor_area_m2 / 1000.0  # kWh per hour if no heating were saved
    assert 0.4 * full < added < 1.1 * full  # part of it replaces electric reheat at night


def test_solar_shading_cools_sunny_hours(base, weather_week):
    run = _run([("solar_shading", 90.0)])
    ghi = weather_week["IGLOB_H"]
    sunny = (ghi > np.median(ghi[ghi > 0])) & (DAY < 5)
    assert (run.temperature_c[0] - base.temperature_c[0])[sunny].mean() < -0.02


def test_heating_capacity_limit_cuts_the_peak(base):
    run = _run([("heating_capacity_limit", 25.0)])
    details = run.effects[0]["details"]
    assert details["available_capacity_kw"] == pytest.approx(0.25 * details["design_capacity_kw"], rel=1e-3)
    assert run.consumption_kwh.max() < 0.95 * base.consumption_kwh.max()
    assert run.temperature_c.mean() < base.temperature_c.mean() - 0.02


def test_heat_recovery_saves_heating(base):
    run = _run([("heat_recovery", 70.0)])
    assert run.consumption_kwh.sum() < 0.98 * base.consumption_kwh.sum()
    assert np.all(run.consumption_kwh <= base.consumption_kwh + 0.5)


def test_night_cycle_cold_air_cools_the_nights(base):
    run = _run([("night_cycle_cold_air", 30.0)])
    night = (HOUR >= 23) | (HOUR < 6)
    change = run.temperature_c[0] - base.temperature_c[0]
    assert change[night].mean() < -0.1  # more cold air while the fans cycle (the mass carries some into the day)
    assert run.consumption_kwh[0][night].sum() > 1.02 * base.consumption_kwh[0][night].sum()  # reheat


def test_evening_departure_warms_the_evenings_and_uses_more(base):
    run = _run([("evening_departure", 3.0)])
    evening = (DAY < 5) & (HOUR >= 20) & (HOUR < 24)
    day = (DAY < 5) & (HOUR >= 9) & (HOUR < 17)
    change = run.temperature_c[0] - base.temperature_c[0]
    assert change[evening].mean() > 0.1 and abs(change[day].mean()) < 0.1  # people, lights and computers stay on
    extra = run.consumption_kwh[0] - base.consumption_kwh[0]
    assert extra[evening].mean() > 0.5 and abs(extra[day].mean()) < 0.1 * base.consumption_kwh[0][day].mean()


@pytest.mark.parametrize("building", sorted(REFERENCE_BUILDINGS))
def test_evening_departure_edits_every_shipped_office(building):
    objects = read_idf(reference_idf(building))
    out = inject_energyplus(objects, plan_effects([("evening_departure", 2)], START, 1), building)
    occupancy = of_type(out, "People")[0][3]
    after = {o[1]: o for o in of_type(out, "Schedule:Compact")}[occupancy]
    before = {o[1]: o for o in of_type(objects, "Schedule:Compact")}[occupancy]
    assert weekday_profile(after)[2].sum() > weekday_profile(before)[2].sum()  # more evening occupancy


def test_weekday_profile_refuses_what_it_cannot_shift():
    ok = [
        "Schedule:Compact",
        "S",
        "Fraction",
        "Through: 12/31",
        "For: Weekdays",
        "Until: 08:00",
        "0",
        "Until: 24:00",
        "1",
        "For: AllOtherDays",
        "Until: 24:00",
        "0",
    ]
    assert weekday_profile(ok)[:2] == (5, 9) and weekday_profile(ok)[2].sum() == 16
    with pytest.raises(ReferenceBuildingError, match="not on a whole hour"):
        weekday_profile(ok[:5] + ["Until: 08:30", "0", "Until: 24:00", "1"])
    with pytest.raises(ReferenceBuildingError, match="no For: Weekdays"):
        weekday_profile(ok[:4] + ["For: Saturday", "Until: 24:00", "0"])
    with pytest.raises(ReferenceBuildingError, match="does not run to 24:00"):
        weekday_profile(ok[:7])


def test_wind_infiltration_costs_heat_in_windy_hours(base, weather_week):
    run = _run([("wind_infiltration", 40.0)])
    extra = run.consumption_kwh[0] - base.consumption_kwh[0]
    windy = weather_week["WIND_SPEED"] > np.median(weather_week["WIND_SPEED"])
    assert extra.sum() > 0.02 * base.consumption_kwh.sum()
    assert extra[windy].mean() > 2 * extra[~windy].mean()


# --- site and CLI ---------------------------------------------------------------------------------------------


def test_site_truth_lists_the_effects(tmp_path):
    path = make_reference_site(tmp_path / "site", weeks=WEEKS, effects=[("temperature_sensor_bias", 2.0)])
    truth = json.loads((path / "truth.json").read_text())
    assert truth["effects"] == [
        {
            "name": "temperature_sensor_bias",
            "magnitude": 2.0,
            "unit": EFFECTS["temperature_sensor_bias"].magnitude_unit,
            "details": {},
        }
    ]
    assert "effect" not in (path / "site.toml").read_text()  # blind: the effects are only in truth.json


def test_cli_rejects_unknown_effects_in_one_line(tmp_path, capsys):
    assert main(["site", "reference", "--out", str(tmp_path / "s"), "--effect", "wind_infiltraton"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "unknown effect 'wind_infiltraton'" in err and "wind_infiltration" in err
    assert main(["site", "reference", "--out", str(tmp_path / "s"), "--effect", "holidays=x"]) == 2
    assert "not a number" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_cli_lists_the_catalogue(capsys):
    assert main(["effects", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == list(EFFECTS)
    assert all(
        {"magnitude_unit", "magnitude_range", "default_magnitude", "series", "parameters"} <= set(r) for r in rows
    )
    named_from = {r["name"]: r["named_from"] for r in rows}
    # one catalogue step below the top of its range, in the catalogue the diagnosis was measured under
    assert named_from["heating_capacity_limit"].startswith("heating_power_w_m2 <= 90 W/m2 (")
    assert named_from["heat_recovery"].startswith("effectiveness >= 0.3 (")
    assert named_from["temperature_sensor_bias"].startswith("|bias_k| >= 0.4 K (")
    needs = {r["name"]: r["needs"] for r in rows if r["needs"]}
    assert set(needs) == {"heating_capacity_limit", "heat_recovery", "night_cycle_cold_air"}
    assert needs["heat_recovery"] == "hours in which the air handling unit heats outdoor air"
    starts = {r["name"]: r["also_recalibrated_from"] for r in rows}
    assert (
        starts["heating_capacity_limit"] == "heating_power_w_m2 = 25, 40 W/m2" and starts["wind_infiltration"] is None
    )
    assert main(["effects"]) == 0
    out = capsys.readouterr().out
    assert "heat_recovery" in out and "named from: effectiveness >= 0.3 (" in out
    assert "also recalibrated from: heating_power_w_m2 = 25, 40 W/m2" in out
    assert "needs: heated hours with the ventilation off in the fit and held-out weeks" in out
    assert "ceiling" not in out


def test_injected_effect_is_inactive_at_no_effect():
    assert not InjectedEffect("heating_capacity_limit", 100.0).active
    assert InjectedEffect("heating_capacity_limit", 99.0).active
