"""Reference buildings beyond the default site's: one short (1 week) EnergyPlus run each, read as sensors."""

from __future__ import annotations

import datetime as dt
import re

import numpy as np
import pandas as pd
import pytest

from buildenv import catalogue as cat
from buildenv.energyplus.idf import of_type, read_idf
from buildenv.energyplus.reference import (
    design_occupants_per_m2,
    detect_schedule_map,
    historical_settings,
    reference_idf,
    run_reference,
    serves_24h_space,
)
from buildenv.energyplus.runner import run_period_rows
from buildenv.energyplus.ventilation_code import code_minimum_ventilation_ach
from buildenv.errors import ReferenceBuildingError

START = dt.date(2019, 11, 4)  # a Monday; Chicago in November: mild enough for the ASHRAE large office


def _check_run(run) -> None:
    assert run.temperature_c.shape == run.consumption_kwh.shape == (1, cat.HOURS_PER_WEEK)
    assert run.warmup_temperature_c.shape == (cat.HOURS_PER_WEEK,)
    hours = np.arange(cat.HOURS_PER_WEEK)
    occupied = (hours // 24 < 5) & (hours % 24 >= 9) & (hours % 24 < 17)  # weekdays 9-17 h
    t = run.temperature_c[0][occupied]
    assert np.all((t > 15.0) & (t < 30.0)), (t.min(), t.max())
    assert np.all(run.consumption_kwh > 0.0)
    assert run.floor_area_m2 > 10_000


def test_run_period_rows_drop_design_days_by_stamp():
    first = dt.date(2019, 1, 14)
    stamps = [f" 01/{d:02d}  {h:02d}:00:00" for d in (14, 15) for h in range(1, 25)]
    frame = pd.DataFrame(
        {"Date/Time": [" 01/01  01:00:00", *stamps[:30], " 07/21  01:00:00", *stamps[30:]], "x": np.arange(50)}
    )
    rows = run_period_rows(frame, first, 48, "eplusout.csv")
    assert list(rows["Date/Time"]) == stamps
    with pytest.raises(Exception, match="expected 24 consecutive hours"):
        run_period_rows(frame, dt.date(2019, 1, 16), 24, "eplusout.csv")


def test_data_centre_keeps_its_schedules():
    objects = read_idf(reference_idf("large_office_2019"))
    mapping = detect_schedule_map(objects)
    assert "HTGSETP_DC_SCH" not in mapping.heating_setpoint
    assert "CLGSETP_DC_SCH" not in mapping.cooling_setpoint
    data_centre = [o for o in of_type(objects, "Controller:OutdoorAir") if serves_24h_space(o)]
    assert len(data_centre) == 4  # the AirLoop DataCenter ... OA controllers
    offices = [o for o in of_type(objects, "Controller:OutdoorAir") if not serves_24h_space(o)]
    assert len(offices) == 4


@pytest.mark.parametrize("building", ["large_office", "large_office_2019"])
def test_reference_building_one_week(building):
    run = run_reference(building, "usa_il_chicago", START, historical_settings(1))
    _check_run(run)


def test_a_stand_in_is_sized_with_the_design_days_of_its_own_climate():
    from buildenv.energyplus.design_days import climate_design_days, design_conditions
    from buildenv.weather.epw import resolve_epw

    miami, chicago = design_conditions(resolve_epw("usa_fl_miami")), design_conditions(resolve_epw("usa_il_chicago"))
    phoenix = design_conditions(resolve_epw("usa_az_phoenix"))
    assert miami["heating"]["dry_bulb_c"] > chicago["heating"]["dry_bulb_c"] + 20  # a mild winter
    assert phoenix["cooling"]["dry_bulb_c"] > miami["cooling"]["dry_bulb_c"]  # a hotter summer...
    assert phoenix["cooling"]["dew_point_c"] < miami["cooling"]["dew_point_c"] - 5  # ...and a drier one
    assert (
        -23 < chicago["heating"]["dry_bulb_c"] < -18 and 30 < chicago["cooling"]["dry_bulb_c"] < 34
    )  # ASHRAE: -20.6, 31.2

    objects = read_idf(reference_idf("medium_office"))  # a Chicago model
    assert climate_design_days(objects, resolve_epw("usa_il_chicago")) is objects  # its own climate: unchanged
    moved = climate_design_days(objects, resolve_epw("usa_fl_miami"))
    assert "Miami" in of_type(moved, "Site:Location")[0][1]
    days = of_type(moved, "SizingPeriod:DesignDay")
    assert [(d[4], float(d[5])) for d in days] == [
        ("WinterDesignDay", miami["heating"]["dry_bulb_c"]),
        ("SummerDesignDay", miami["cooling"]["dry_bulb_c"]),
    ]


def test_run_period_rows_put_a_run_across_a_new_year_in_order():
    # EnergyPlus's CSV keys rows by MM/DD stamp: the January days of a December-January run come first
    december = [f" 12/31  {h:02d}:00:00" for h in range(1, 25)]
    january = [f" 01/01  {h:02d}:00:00" for h in range(1, 25)]
    frame = pd.DataFrame({"Date/Time": january + december, "x": np.arange(48)})
    rows = run_period_rows(frame, dt.date(2019, 12, 31), 48, "eplusout.csv")
    assert list(rows["Date/Time"]) == december + january and list(rows["x"]) == [*range(24, 48), *range(24)]


def test_a_site_measured_across_a_new_year_is_made_calibrated_and_run_again(tmp_path):
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.cli.main import main
    from buildenv.env.energyplus_backend import run_weeks
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site
    from buildenv.sites.week_simulator import SiteModel, model_weeks, year_weeks

    assert model_weeks(dt.date(2019, 11, 4), 6) == year_weeks(2019)  # inside the year: its weeks
    weeks = model_weeks(dt.date(2019, 12, 16), 4)  # 16 December 2019 to 12 January 2020
    assert weeks[-2:] == [dt.date(2019, 12, 30), dt.date(2020, 1, 6)] and len(weeks) == len(year_weeks(2019)) + 2
    site_dir = tmp_path / "site"
    args = ["site", "reference", "--building", "small_office", "--start", "2019-12-16", "--weeks", "4"]
    assert main([*args, "--out", str(site_dir)]) == 0
    site = load_site(site_dir)
    calibrate_site(site, load_metamodel(), max_evaluations=300)
    model = SiteModel.from_site(load_site(site_dir), load_metamodel())
    last = model.week_of(dt.date(2020, 1, 6))
    assert model.simulate(model.historical[None], np.array([last])).shape == (1, cat.HOURS_PER_WEEK, 8)
    # the week across the new year, run again from the week before: the measured temperatures, up to the noise
    temperature, _ = run_weeks(site, [dt.date(2019, 12, 30)], site.settings[2][None], workers=1)
    assert np.nanmean(np.abs(temperature[0] - site.temperature_c[2])) < 0.15


def test_central_supply_air_is_read_where_a_loop_holds_its_own_temperature():
    from buildenv.energyplus.reference import central_supply_nodes, recorded_supply_air

    nodes = {b: central_supply_nodes(read_idf(reference_idf(b))) for b in ("medium_office", "small_office")}
    assert nodes["medium_office"] == [f"VAV_{k} Supply Equipment Outlet Node" for k in (1, 2, 3)]  # scheduled 12.8
    assert nodes["small_office"] == []  # single-zone units: their supply follows the zone's load
    large = central_supply_nodes(read_idf(reference_idf("large_office_2019")))  # outdoor-air reset VAV loops only
    assert len(large) == 3 and all("WITH REHEAT" in n for n in large)
    settings = historical_settings(1)
    j = cat.SETTING_NAMES.index("supply_air_c")
    hours = np.arange(cat.HOURS_PER_WEEK) % 24
    supply = np.where((hours >= 7) & (hours < 19), 12.8, 30.0)[None]  # the loop off outside its hours
    recorded = recorded_supply_air(settings, supply)
    assert set(recorded[..., j].ravel()) == {13.0}  # the ventilation hours' mean, on the 0.5 K grid
    assert set(recorded_supply_air(settings, supply + 30.0)[..., j].ravel()) == {cat.get("supply_air_c").max}
    others = [k for k in range(len(cat.SETTING_NAMES)) if k != j]
    np.testing.assert_array_equal(recorded[..., others], settings[..., others])


def test_design_occupants_come_from_the_models_people_per_floor_area():
    # the DOE 2004 offices: 18.58 m2 per person (200 ft2), the large office's basement half as dense
    for building in ("medium_office", "large_office"):
        density = design_occupants_per_m2(read_idf(reference_idf(building)))
        assert density == pytest.approx(1 / 18.58)
        # ASHRAE 62.1 at that density, in the model's air changes: the lower ventilation limit of its stand-in
        assert code_minimum_ventilation_ach(density) == pytest.approx((2.5 / 18.58 + 0.3) * 3.6 / 3.5)
    assert design_occupants_per_m2([("People", "p", "zone", "sched", "People", "12")]) is None  # a head count


def test_a_users_epjson_model_is_read_as_the_idf_it_converts_to(tmp_path):
    from pyenergyplus.api import EnergyPlusAPI

    idf = tmp_path / "office.idf"
    idf.write_text(reference_idf("small_office").read_text())
    api = EnergyPlusAPI()
    state = api.state_manager.new_state()
    api.runtime.set_console_output_status(state, False)
    assert api.runtime.run_energyplus(state, ["--convert-only", "-d", str(tmp_path), str(idf)]) == 0
    api.state_manager.delete_state(state)
    converted = reference_idf(tmp_path / "office.epJSON")
    assert converted.suffix == ".idf"
    assert detect_schedule_map(read_idf(converted)) == detect_schedule_map(read_idf(idf))
    assert len(read_idf(converted)) == len(read_idf(idf))


def test_an_idf_of_another_energyplus_version_is_refused_in_one_line(tmp_path):
    old = tmp_path / "old.idf"
    old.write_text(re.sub(r"Version,\s*[0-9.]+;", "Version,9.6;", reference_idf("small_office").read_text(), count=1))
    with pytest.raises(
        ReferenceBuildingError, match=r"old\.idf: written for EnergyPlus 9\.6.*IDFVersionUpdater"
    ) as err:
        reference_idf(old)
    assert "\n" not in str(err.value)


def test_infiltration_the_model_cuts_while_its_fans_run_follows_the_sites_ventilation_hours(tmp_path):
    from buildenv.energyplus.reference import prepare_model, pressurised_infiltration

    assert pressurised_infiltration(read_idf(reference_idf("medium_office_2019"))) == {"INFIL_SCH_PNNL": (0.25, 1.0)}
    settings = historical_settings(1)
    start, end = cat.SETTING_NAMES.index("ventilation_start_hour"), cat.SETTING_NAMES.index("ventilation_end_hour")
    settings[0, 0, start], settings[0, 0, end] = 5, 21  # Monday: ventilated 05-21 h, not the model's 06-22 h
    first = dt.date(2019, 1, 14)
    idf, _ = prepare_model(reference_idf("medium_office_2019"), settings, first, tmp_path)
    objects = read_idf(idf)
    schedules = {o[3] for o in of_type(objects, "ZoneInfiltration:DesignFlowRate")}
    assert schedules == {"buildenv_infiltration_1", "INFIL_Door_Opening_SCH"}  # door openings keep their clock
    (column,) = [int(o[4]) for o in of_type(objects, "Schedule:File") if o[1] == "buildenv_infiltration_1"]
    table = np.loadtxt(tmp_path / "buildenv_schedules.csv", delimiter=",", skiprows=1)
    monday = table[13 * 24 : 14 * 24, column - 1]  # 14 January, the column EnergyPlus reads
    assert set(monday[5:21]) == {0.25} and set(monday[:5]) == set(monday[21:]) == {1.0}
    # a site made by the first stand-in keeps the model's own clock when its building runs again
    idf, _ = prepare_model(reference_idf("medium_office_2019"), settings, first, tmp_path / "v1", stand_in=1)
    assert "INFIL_SCH_PNNL" in {o[3] for o in of_type(read_idf(idf), "ZoneInfiltration:DesignFlowRate")}
    with pytest.raises(ReferenceBuildingError, match="stand-in version 9"):
        prepare_model(reference_idf("medium_office_2019"), settings, first, tmp_path / "v9", stand_in=9)


def test_a_sites_building_runs_again_as_the_stand_in_version_it_was_made_with(tmp_path, monkeypatch):
    import json
    import shutil
    from types import SimpleNamespace

    from buildenv.energyplus import reference
    from buildenv.env.energyplus_backend import run_weeks
    from buildenv.sites import load_site

    used = []

    def run(building, epw, start, settings, warmup_weeks=1, stand_in=reference.STAND_IN_VERSION, **kw):
        used.append(stand_in)
        week = np.full((len(settings), cat.HOURS_PER_WEEK), 21.0)
        return SimpleNamespace(temperature_c=week, hvac_kwh=week, floor_area_m2=1000.0)

    monkeypatch.setattr(reference, "run_reference", run)
    shutil.copytree("buildenv/data/sites/default", tmp_path / "site")
    truth_path = tmp_path / "site" / "truth.json"
    truth = json.loads(truth_path.read_text())
    for version in (None, 2, 7):
        truth_path.write_text(json.dumps(truth if version is None else {**truth, "stand_in": version}))
        site = load_site(tmp_path / "site")
        if version == 7:
            with pytest.raises(ReferenceBuildingError, match="stand_in 7 is not a stand-in version"):
                run_weeks(site, [site.start], site.settings[:1], workers=1)
        else:
            run_weeks(site, [site.start], site.settings[:1], workers=1)
    assert used == [1, 2]  # the shipped default site predates versions: its infiltration on the model's clock


def test_a_data_centres_it_load_runs_steady_at_its_level_of_the_runs_first_day(tmp_path):
    from buildenv.energyplus.compact_schedules import daily_means
    from buildenv.energyplus.reference import prepare_model

    settings = historical_settings(1)
    source = reference_idf("large_office_2019")
    sawtooth = [o for o in of_type(read_idf(source), "Schedule:Compact") if o[1] == "DataCenter_EQUIP_SCH"][0]
    assert sorted(set(daily_means(sawtooth, 2019))) == [0.25, 0.5, 0.75, 1.0]  # the prototype's months
    for first, level in ((dt.date(2019, 1, 7), 0.25), (dt.date(2019, 2, 4), 0.5)):
        idf, _ = prepare_model(source, settings, first, tmp_path / str(first))
        objects = read_idf(idf)
        equipment = {o[1]: o[3] for o in of_type(objects, "ElectricEquipment")}
        steady = {s for name, s in equipment.items() if serves_24h_space(["ElectricEquipment", name])}
        assert steady == {"buildenv_steady_DataCenter_EQUIP_SCH"}
        (schedule,) = [o for o in of_type(objects, "Schedule:Compact") if o[1] in steady]
        assert set(daily_means(schedule, first.year)) == {level}
        assert "For: summerdesignday" in schedule  # sized as the model was
        offices = {s for name, s in equipment.items() if not serves_24h_space(["ElectricEquipment", name])}
        assert "buildenv_steady_DataCenter_EQUIP_SCH" not in offices
    # a site's building runs again, any week, with the level of the day its own run began
    idf, _ = prepare_model(source, settings, dt.date(2019, 3, 4), tmp_path / "again", steady_day=dt.date(2019, 1, 7))
    (schedule,) = [o for o in of_type(read_idf(idf), "Schedule:Compact") if o[1].startswith("buildenv_steady")]
    assert set(daily_means(schedule, 2019)) == {0.25}
    idf, _ = prepare_model(source, settings, dt.date(2019, 1, 7), tmp_path / "v2", stand_in=2)
    assert "DataCenter_EQUIP_SCH" in {o[3] for o in of_type(read_idf(idf), "ElectricEquipment")}
