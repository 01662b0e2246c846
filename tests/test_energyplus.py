"""The EnergyPlus shoebox is physically sane (real runs of one or two weeks)."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.campaign.runs import CampaignConfig, plan_campaign
from buildenv.defaults import DEFAULT_THETA, default_week
from buildenv.diagnosis.effects import night_electricity_w_m2
from buildenv.energyplus.runner import run_energyplus, warmup_settled
from buildenv.energyplus.shoebox import DEFAULT_ZONING, ZONINGS, build_epjson, night_cycling, write_schedule_file
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.errors import CatalogueError, SimulationError
from buildenv.schedules import hourly_schedules
from buildenv.weather.epw import load_weather

JANUARY, JULY, LATE_OCTOBER = 2, 28, 43
OUT = {name: i for i, name in enumerate(cat.OUTPUT_NAMES)}


def _week(epw: str, week: int, theta: dict | None = None, zoning: str = DEFAULT_ZONING, **setting_overrides):
    settings, occupancy = default_week()
    for name, value in setting_overrides.items():
        settings[..., cat.SETTING_NAMES.index(name)] = value
    result = simulate_weeks({**DEFAULT_THETA, **(theta or {})}, settings, occupancy, epw, week, zoning=zoning)
    return result.outputs[0], hourly_schedules(settings, occupancy)


@pytest.fixture(scope="module")
def chicago_january():
    return _week("usa_il_chicago", JANUARY, {"heating_power_w_m2": 100})


@pytest.fixture(scope="module")
def chicago_july():
    return _week("usa_il_chicago", JULY, {"cooling_power_w_m2": 100})


def test_january_heats_and_does_not_cool(chicago_january):
    out, _ = chicago_january
    heating = out[:, OUT["Q_HEAT_OFFICE"]].sum() + out[:, OUT["Q_AHU_H"]].sum()
    cooling = out[:, OUT["Q_AC_OFFICE"]].sum() + out[:, OUT["Q_AHU_C"]].sum()
    assert heating > 500.0  # Wh/m2 in a Chicago January week
    assert cooling < 0.02 * heating


def test_july_cools_and_does_not_heat(chicago_july):
    out, _ = chicago_july
    cooling = out[:, OUT["Q_AC_OFFICE"]].sum() + out[:, OUT["Q_AHU_C"]].sum()
    assert cooling > 300.0
    assert out[:, OUT["Q_AC_OFFICE"]].sum() > 0 and out[:, OUT["Q_AHU_C"]].sum() > 0
    assert out[:, OUT["Q_HEAT_OFFICE"]].sum() < 0.05 * cooling


def test_indoor_temperature_tracks_comfort_setpoint_when_occupied(chicago_january, chicago_july):
    for out, sched in (chicago_january, chicago_july):
        t_int = out[:, OUT["T_INT_OFFICE"]]
        occ = sched["occupancy_fraction"][0] > 0
        occupied = occ & np.roll(occ, 1)  # the first occupied hour of a day is the start-up
        heat_sp, cool_sp = sched["heating_setpoint_c"][0], sched["cooling_setpoint_c"][0]
        # within the dead band, give or take half a kelvin, in every occupied hour after the start-up hour
        assert np.all(t_int[occupied] > heat_sp[occupied] - 0.5)
        assert np.all(t_int[occupied] < cool_sp[occupied] + 0.5)


def test_january_occupied_temperature_sits_at_heating_comfort(chicago_january):
    """A single zone sits at the heating setpoint; with a core, whose gains need cooling even in January,
    the mean lies between the heating and the cooling setpoints."""
    single = _week("usa_il_chicago", JANUARY, {"heating_power_w_m2": 100}, zoning="single")
    for (out, sched), low, high in ((single, 0.3, 0.3), (chicago_january, 0.3, -0.5)):
        occupied = sched["occupancy_fraction"][0] > 0
        t_int = np.median(out[occupied, OUT["T_INT_OFFICE"]])
        heat, cool = sched["heating_setpoint_c"][0][occupied][0], sched["cooling_setpoint_c"][0][occupied][0]
        assert heat - low < t_int < (heat + high if high > 0 else cool + high), (t_int, heat, cool)


def test_internal_gains_follow_schedules_exactly(chicago_january):
    out, sched = chicago_january
    occ = sched["occupancy_fraction"][0]
    light = DEFAULT_THETA["light_night_percent"] / 100 + (1 - DEFAULT_THETA["light_night_percent"] / 100) * occ
    eqp = DEFAULT_THETA["pc_night_percent"] / 100 + (1 - DEFAULT_THETA["pc_night_percent"] / 100) * occ
    np.testing.assert_allclose(
        out[:, OUT["Q_LIGHT"]], DEFAULT_THETA["lighting_power_w_m2"] * light, rtol=1e-3, atol=1e-3
    )
    np.testing.assert_allclose(out[:, OUT["Q_EQP"]], DEFAULT_THETA["plug_load_w_m2"] * eqp, rtol=1e-3, atol=1e-3)
    assert np.all(out[occ == 0, OUT["Q_PEOPLE"]] == 0)
    assert np.all(out[occ > 0, OUT["Q_PEOPLE"]] > 0)
    # what the gap diagnosis judges loads left on at night by: the electricity of the unoccupied hours
    night = out[occ == 0][:, [OUT["Q_LIGHT"], OUT["Q_EQP"]]].sum(axis=1)
    np.testing.assert_allclose(night, night_electricity_w_m2(DEFAULT_THETA), rtol=1e-3)


def _heating(out: np.ndarray) -> float:
    return float(out[:, OUT["Q_HEAT_OFFICE"]].sum() + out[:, OUT["Q_AHU_H"]].sum())


def test_lighting_power_sets_the_lights_and_their_heat(chicago_january):
    base, _ = chicago_january
    dim, _ = _week("usa_il_chicago", JANUARY, {"heating_power_w_m2": 100, "lighting_power_w_m2": 4})
    ratio = 4 / DEFAULT_THETA["lighting_power_w_m2"]
    np.testing.assert_allclose(dim[:, OUT["Q_LIGHT"]], ratio * base[:, OUT["Q_LIGHT"]], rtol=1e-3, atol=1e-3)
    assert _heating(dim) > _heating(base) + 0.2 * (base[:, OUT["Q_LIGHT"]].sum() - dim[:, OUT["Q_LIGHT"]].sum())


def test_plug_loads_set_the_equipment_and_their_heat(chicago_january):
    base, _ = chicago_january
    busy, _ = _week("usa_il_chicago", JANUARY, {"heating_power_w_m2": 100, "plug_load_w_m2": 20})
    ratio = 20 / DEFAULT_THETA["plug_load_w_m2"]
    np.testing.assert_allclose(busy[:, OUT["Q_EQP"]], ratio * base[:, OUT["Q_EQP"]], rtol=1e-3, atol=1e-3)
    assert _heating(busy) < _heating(base) - 0.2 * (busy[:, OUT["Q_EQP"]].sum() - base[:, OUT["Q_EQP"]].sum())


def test_heat_recovery_is_an_exchanger_in_the_air_handling_unit_only_when_effective(tmp_path):
    settings, occupancy = default_week()
    weather = load_weather("usa_il_chicago")
    csv = write_schedule_file(tmp_path / "schedules.csv", DEFAULT_THETA, settings, occupancy, 0)
    for zoning in ZONINGS:
        plain = build_epjson({**DEFAULT_THETA, "heat_recovery_effectiveness": 0.0}, weather, csv, 0, 1, zoning)
        assert "HeatExchanger:AirToAir:SensibleAndLatent" not in plain  # no recovery: the model as it was
        model = build_epjson({**DEFAULT_THETA, "heat_recovery_effectiveness": 0.7}, weather, csv, 0, 1, zoning)
        exchangers = model["HeatExchanger:AirToAir:SensibleAndLatent"]
        assert len(exchangers) == len(model["ZoneHVAC:OutdoorAirUnit"])
        for components in model["ZoneHVAC:OutdoorAirUnit:EquipmentList"].values():
            assert components["component_1_object_type"] == "HeatExchanger:AirToAir:SensibleAndLatent"
        for hx in exchangers.values():
            assert hx["sensible_effectiveness_at_100_heating_air_flow"] == 0.7
            assert hx["sensible_effectiveness_at_100_cooling_air_flow"] == 0.7
            assert hx["latent_effectiveness_at_100_heating_air_flow"] == 0.0
            assert hx["availability_schedule_name"] == "ventilation_on"


@pytest.mark.parametrize("zoning", ZONINGS)
def test_heat_recovery_cuts_the_air_handling_units_heating_and_cooling(zoning):
    recovered = {"heat_recovery_effectiveness": 0.7}
    # January: 70 % of the zone-to-outdoor difference recovered leaves well under half of the outdoor air's lift to
    # the supply temperature to the coil; July: the exchanger pre-cools the outdoor air
    for week, output, most in ((JANUARY, "Q_AHU_H", 0.5), (JULY, "Q_AHU_C", 0.95)):
        without = _week("usa_il_chicago", week, zoning=zoning)[0]
        with_hx = _week("usa_il_chicago", week, recovered, zoning=zoning)[0]
        assert 0 < with_hx[:, OUT[output]].sum() < most * without[:, OUT[output]].sum()
        assert np.isfinite(with_hx).all() and 15.0 < with_hx[:, OUT["T_INT_OFFICE"]].mean() < 30.0


@pytest.mark.parametrize("zoning", ZONINGS)
def test_a_small_one_storey_office_simulates(zoning):
    small = {"floor_area_m2": cat.get("floor_area_m2").min, "number_of_floors": 1}
    out, sched = _week("usa_il_chicago", JANUARY, small, zoning=zoning)
    assert np.isfinite(out).all() and _heating(out) > 500.0  # Wh/m2: more envelope per m2 than the default
    occupied = sched["occupancy_fraction"][0] > 0
    assert np.all(out[occupied, OUT["Q_LIGHT"]] > 0.5 * DEFAULT_THETA["lighting_power_w_m2"])


def test_ahu_energy_rises_with_ventilation_volume_and_supply_temperature():
    low = _week("usa_il_chicago", JANUARY, ventilation_ach=0.7)[0][:, OUT["Q_AHU_H"]].sum()
    high = _week("usa_il_chicago", JANUARY, ventilation_ach=1.6)[0][:, OUT["Q_AHU_H"]].sum()
    warm = _week("usa_il_chicago", JANUARY, ventilation_ach=0.7, supply_air_c=25)[0][:, OUT["Q_AHU_H"]].sum()
    assert high / low == pytest.approx(1.6 / 0.7, rel=0.1)  # heating outdoor air scales with its flow
    assert warm > 1.1 * low


def test_ahu_runs_only_in_ventilation_hours(chicago_january):
    out, sched = chicago_january
    off = sched["ventilation_on"][0] == 0
    assert np.all(out[off, OUT["Q_AHU_H"]] == 0) and np.all(out[off, OUT["Q_AHU_C"]] == 0)


def test_a_weekend_set_back_entirely_saves_heating_and_holds_the_setback(chicago_january):
    operating, _ = chicago_january
    settings, occupancy = default_week()
    settings[0, 5:, cat.SETTING_NAMES.index("hvac_operating")] = 0  # Saturday and Sunday off
    off = simulate_weeks({**DEFAULT_THETA, "heating_power_w_m2": 100}, settings, occupancy, "usa_il_chicago", JANUARY)
    out = off.outputs[0]
    weekend = slice(5 * 24, 7 * 24)
    assert out[weekend, OUT["Q_AHU_H"]].sum() == 0 and out[weekend, OUT["Q_AHU_C"]].sum() == 0
    heating = (out[:, OUT["Q_HEAT_OFFICE"]] + out[:, OUT["Q_AHU_H"]]).sum()
    assert heating < 0.95 * (operating[:, OUT["Q_HEAT_OFFICE"]] + operating[:, OUT["Q_AHU_H"]]).sum()
    # the zone cools towards the heating setback, which holds it
    setback = cat.get("heating_setback_c").snap(settings[0, 5, cat.SETTING_NAMES.index("heating_setback_c")])
    assert out[weekend, OUT["T_INT_OFFICE"]].min() >= setback - 0.5
    midday = [24 * d + h for d in (5, 6) for h in range(10, 17)]  # the heating comfort period, were it operating
    assert operating[midday, OUT["T_INT_OFFICE"]].min() > 21.9 and out[midday, OUT["T_INT_OFFICE"]].max() < 21.5


def test_same_inputs_give_identical_outputs():
    a = _week("usa_ca_san_francisco", 10)[0]
    b = _week("usa_ca_san_francisco", 10)[0]
    np.testing.assert_array_equal(a, b)


def test_consecutive_weeks_in_one_run_carry_thermal_state():
    settings, occupancy = default_week(2)
    two = simulate_weeks(DEFAULT_THETA, settings, occupancy, "usa_il_chicago", JANUARY).outputs
    assert two.shape == (2, 168, 8)
    # Monday 00:00 of week 2 continues from Sunday 23:00 of week 1 (no jump to a warm-up state)
    t = two[..., OUT["T_INT_OFFICE"]].reshape(-1)
    assert abs(t[168] - t[167]) < 1.0


def test_energyplus_severe_error_is_reported_with_err_lines(tmp_path):
    settings, occupancy = default_week()
    weather = load_weather("usa_il_chicago")
    csv = write_schedule_file(tmp_path / "schedules.csv", DEFAULT_THETA, settings, occupancy, 0)
    model = build_epjson(DEFAULT_THETA, weather, csv, 0, 1)
    del model["Material"]["Plasterboard"]  # three wall constructions now name a missing layer
    with pytest.raises(SimulationError) as info:
        run_energyplus(model, weather.path, tmp_path / "run", label="broken")
    message = str(info.value)
    assert "\n" not in message  # one line
    assert "broken.epJSON" in message
    assert "Severe" in message or "Fatal" in message
    assert "PLASTERBOARD" in message.upper()


def test_a_building_outside_the_catalogue_is_refused_unless_asked_for(tmp_path):
    # bench/calibration_bounds.py runs the shoebox past the catalogue's ranges; by default they are enforced
    settings, occupancy = default_week()
    weather = load_weather("usa_il_chicago")
    csv = write_schedule_file(tmp_path / "schedules.csv", DEFAULT_THETA, settings, occupancy, 0)
    low = cat.get("capacitance_kj_per_k_m3").min
    thin = {**DEFAULT_THETA, "capacitance_kj_per_k_m3": low / 2}
    with pytest.raises(CatalogueError, match=f"capacitance_kj_per_k_m3={low / 2:g} .* outside its range"):
        build_epjson(thin, weather, csv, 0, 1)
    mass = {
        c: build_epjson({**DEFAULT_THETA, "capacitance_kj_per_k_m3": c}, weather, csv, 0, 1, check=c >= low)[
            "Material"
        ]["Internal mass concrete"]["thickness"]
        for c in (low / 2, low)
    }
    assert mass[low / 2] == pytest.approx(mass[low] / 2)


WARMUP_SEVERE = [
    '** Severe  ** CheckWarmupConvergence: Loads Initialization, Zone="PERIMETER" did not converge after 50 warmup '
    "days.",
    '**   ~~~   ** ...Environment(RunPeriod)="WEEKS"',
    "**   ~~~   ** ..Max Temp Comparison = 0.20 vs Temperature Convergence Tolerance=0.40 - Pass Convergence",
    "**   ~~~   ** ..Max Cool Load Comparison = 0.1229 vs Loads Convergence Tolerance=0.10 - Fail Convergence",
]


def test_warmup_settled_accepts_converged_temperatures_and_nothing_else():
    assert warmup_settled(WARMUP_SEVERE)
    hot = [line.replace("0.20 vs", "0.55 vs").replace("0.40 - Pass", "0.40 - Fail") for line in WARMUP_SEVERE]
    assert not warmup_settled(hot)  # a zone whose temperature did not settle: the state is not sound
    # a temperature alternating by less than EnergyPlus's largest tolerance (0.5 K) between warm-up days
    near = [line.replace("0.20 vs", "0.46 vs").replace("0.40 - Pass", "0.40 - Fail") for line in WARMUP_SEVERE]
    assert warmup_settled(near)
    assert not warmup_settled(near + hot[2:3])
    assert not warmup_settled(WARMUP_SEVERE + ["** Severe  ** GetSurfaceData: a surface names a missing layer"])
    assert not warmup_settled([])
    assert not warmup_settled([line.replace("Severe ", "Fatal ") for line in WARMUP_SEVERE])


def test_campaign_run_whose_perimeter_loads_never_settle_in_warmup_still_simulates():
    """Run 2 of the seed-0 1,040-week Chicago/Miami campaign: a perimeter's cooling load in Miami in January
    changes 12 % a day for the 50 warm-up days (EnergyPlus: Severe) while its temperatures converged."""
    task = plan_campaign(
        CampaignConfig(weeks=1040, seed=0, epw=["usa_il_chicago", "usa_fl_miami"], zoning="core_perimeter")
    )[2]
    out = simulate_weeks(
        task.theta, task.settings[:1], task.occupancy[:1], task.epw, task.start_week, zoning=task.zoning
    ).outputs
    assert np.isfinite(out).all() and 15.0 < out[..., OUT["T_INT_OFFICE"]].mean() < 35.0


def test_campaign_run_whose_thermostat_alternates_in_warmup_still_simulates():
    """Run 3408 of the seed-0 80,000-week campaign (13 weeks per run): Tampa in January, heating and cooling
    setpoints 0.5 K apart; the perimeter's minimum temperature changes 0.46 K a day for the 50 warm-up days."""
    task = plan_campaign(CampaignConfig(weeks=80000, seed=0, weeks_per_run=13, zoning="core_perimeter"))[3408]
    out = simulate_weeks(
        task.theta, task.settings[:1], task.occupancy[:1], task.epw, task.start_week, zoning=task.zoning
    ).outputs
    assert np.isfinite(out).all() and 18.0 < out[..., OUT["T_INT_OFFICE"]].mean() < 30.0


@pytest.mark.parametrize("zoning", ZONINGS)
def test_a_minimum_supply_flow_mixes_return_air_that_the_zones_reheat(zoning):
    # outdoor air 1.0 ach at 13 degC supply; a VAV minimum of 2.5 ach makes up the rest with return air
    vav = {"minimum_supply_air_ach": 2.5}
    for week in (JANUARY, JULY):
        doas = _week("usa_il_chicago", week, zoning=zoning, supply_air_c=13)[0]
        mixed = _week("usa_il_chicago", week, vav, zoning=zoning, supply_air_c=13)[0]
        assert np.isfinite(mixed).all() and 15.0 < mixed[:, OUT["T_INT_OFFICE"]].mean() < 30.0
        # the zones reheat the larger flow of 13 degC air
        assert mixed[:, OUT["Q_HEAT_OFFICE"]].sum() > doas[:, OUT["Q_HEAT_OFFICE"]].sum() + 50.0
        if week == JANUARY:  # mixing with return air lifts the outdoor air: the coil heats less
            assert mixed[:, OUT["Q_AHU_H"]].sum() < 0.6 * doas[:, OUT["Q_AHU_H"]].sum()
        else:  # the coil cools the whole minimum flow to 13 degC
            assert mixed[:, OUT["Q_AHU_C"]].sum() > 1.2 * doas[:, OUT["Q_AHU_C"]].sum()
    # a minimum below the outdoor air changes nothing, but for the night cycling of a VAV system (test_zoning)
    below = _week("usa_il_chicago", JANUARY, {"minimum_supply_air_ach": 0.5}, zoning=zoning)[0]
    if not night_cycling(zoning, {**DEFAULT_THETA, "minimum_supply_air_ach": 0.5}):
        np.testing.assert_allclose(below, _week("usa_il_chicago", JANUARY, zoning=zoning)[0], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("zoning", ZONINGS)
def test_an_economiser_cools_with_outdoor_air_while_it_is_cooler(zoning):
    # a cooling comfort setpoint of 22.5 degC in a Chicago late October: the zones need cooling, outdoor air is cool
    cold = {"cooling_power_w_m2": 100}
    settings = {"cooling_comfort_c": 22.5, "heating_comfort_c": 22.0}
    mechanical = _week("usa_il_chicago", LATE_OCTOBER, cold, zoning=zoning, **settings)[0]
    half = _week("usa_il_chicago", LATE_OCTOBER, {**cold, "economiser_share": 0.5}, zoning=zoning, **settings)[0]
    economiser = _week("usa_il_chicago", LATE_OCTOBER, {**cold, "economiser_share": 1.0}, zoning=zoning, **settings)[0]
    cooling = [out[:, OUT["Q_AC_OFFICE"]].sum() for out in (mechanical, half, economiser)]
    assert cooling[0] > 5.0  # Wh/m2 in the week
    assert cooling[2] < 0.05 * cooling[0] and 0.3 * cooling[0] < cooling[1] < 0.7 * cooling[0]
    # the same zone temperatures: outdoor air only replaces the mechanical cooling
    for out in (half, economiser):
        np.testing.assert_allclose(out[:, OUT["T_INT_OFFICE"]], mechanical[:, OUT["T_INT_OFFICE"]], atol=0.3)
    # in July outdoor air is warmer than the zones in the afternoon: the economiser cannot replace most cooling
    july = [_week("usa_il_chicago", JULY, {**cold, "economiser_share": s})[0] for s in (0.0, 1.0)]
    assert july[1][:, OUT["Q_AC_OFFICE"]].sum() > 0.5 * july[0][:, OUT["Q_AC_OFFICE"]].sum()


def test_infiltration_falls_while_the_fans_pressurise_the_building():
    # a Chicago January at 0.6 air changes: a quarter of them while the air handling unit runs, all while it is off
    leaky = {"heating_power_w_m2": 100, "infiltration_ach": 0.6}
    same, _ = _week("usa_il_chicago", JANUARY, leaky)
    pressurised, series = _week("usa_il_chicago", JANUARY, {**leaky, "infiltration_fans_on_share": 0.25})
    on = series["ventilation_on"][0] > 0
    heat = [out[:, OUT["Q_HEAT_OFFICE"]] for out in (same, pressurised)]
    # less zone heating while the fans run, about the same while they are off (the night's store differs a little)
    assert heat[1][on].sum() < 0.9 * heat[0][on].sum()
    assert heat[1][~on].sum() == pytest.approx(heat[0][~on].sum(), rel=0.1)
    assert heat[1][~on].sum() > 0.0
