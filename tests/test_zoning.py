"""The shoebox's zoning (one zone, core + perimeter ring, core + four perimeter zones) and the stand-in's ventilation
in physical units."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from buildenv import catalogue as cat
from buildenv.campaign.runs import CampaignConfig, run_campaign
from buildenv.defaults import DEFAULT_THETA, default_week
from buildenv.energyplus.reference import (
    UNMAPPED_SETTINGS,
    _schedule_columns,
    design_outdoor_air_ach,
    historical_settings,
    historical_ventilation_ach,
    reference_bms,
    reference_idf,
)
from buildenv.energyplus.shoebox import (
    CORE,
    PERIMETER,
    PERIMETER_DEPTH_M,
    Geometry,
    build_epjson,
    night_cycling,
    perimeter_zone,
    zone_names,
    zone_shares,
)
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.errors import BuildenvError
from buildenv.schedules import hourly_schedules
from buildenv.weather.epw import load_weather, resolve_epw

OUT = {name: i for i, name in enumerate(cat.OUTPUT_NAMES)}
JANUARY, JULY = 2, 28


def test_zone_shares_follow_the_footprint():
    office = Geometry.from_theta({"floor_area_m2": 4982.2, "number_of_floors": 3})
    shares = zone_shares(office, "core_perimeter")
    assert sum(shares.values()) == pytest.approx(1.0)
    core_side = office.side_m - 2 * PERIMETER_DEPTH_M
    assert shares[CORE] == pytest.approx(core_side**2 / office.side_m**2)
    tower = Geometry.from_theta({"floor_area_m2": 1000.0, "number_of_floors": 15})  # 8.2 m side
    assert tower.perimeter_depth_m == pytest.approx(tower.side_m / 4)
    assert zone_shares(tower, "core_perimeter")[CORE] == pytest.approx(0.25)
    assert zone_shares(office, "single") == {"Office": 1.0}
    with pytest.raises(ValueError, match="zoning 'two'"):
        zone_shares(office, "two")


def _centroid(surface: dict) -> np.ndarray:
    return np.mean([[v[f"vertex_{a}_coordinate"] for a in "xyz"] for v in surface["vertices"]], axis=0)


def _inside(point: np.ndarray, floor: dict) -> bool:
    """Whether a point (x, y) lies inside a floor's outline (ray casting)."""
    xy = [(v["vertex_x_coordinate"], v["vertex_y_coordinate"]) for v in floor["vertices"]]
    inside = False
    for (x0, y0), (x1, y1) in zip(xy, xy[1:] + xy[:1]):
        if (y0 > point[1]) != (y1 > point[1]) and point[0] < x0 + (point[1] - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def _normal(surface: dict) -> np.ndarray:
    """Outward normal of a surface whose vertices run counter-clockwise seen from outside (Newell's method)."""
    p = np.array([[v[f"vertex_{a}_coordinate"] for a in "xyz"] for v in surface["vertices"]])
    n = np.sum(np.cross(p, np.roll(p, -1, axis=0)), axis=0)
    return n / np.linalg.norm(n)


@pytest.mark.parametrize("zoning", ["core_perimeter", "five_zone"])
def test_zoned_model_is_closed_and_paired(tmp_path, zoning):
    weather = load_weather("usa_il_chicago")
    model = build_epjson(DEFAULT_THETA, weather, tmp_path / "s.csv", 0, 1, zoning=zoning)
    assert set(model["Zone"]) == set(zone_names(zoning))
    area = sum(z["floor_area"] for z in model["Zone"].values())
    assert area == pytest.approx(DEFAULT_THETA["floor_area_m2"], rel=1e-6)
    surfaces = model["BuildingSurface:Detailed"]
    floors = [(s["zone_name"], s) for s in surfaces.values() if s["surface_type"] == "Floor"]

    def zone_at(point: np.ndarray) -> set[str]:  # the zones whose ground floor holds a point (x, y)
        return {zone for zone, floor in floors if _inside(point, floor)}

    for name, s in surfaces.items():
        if s["outside_boundary_condition"] == "Surface":  # each partition faces its twin, vertices reversed
            twin = surfaces[s["outside_boundary_condition_object"]]
            assert twin["outside_boundary_condition_object"] == name and twin["zone_name"] != s["zone_name"]
            assert twin["vertices"] == s["vertices"][::-1]
            # its normal points out of its zone, into the zone beyond
            step = 0.1 * _normal(s)[:2]
            assert zone_at(_centroid(s)[:2] - step) == {s["zone_name"]}, name
            assert zone_at(_centroid(s)[:2] + step) == {twin["zone_name"]}, name
    walls = [
        s for s in surfaces.values() if s["outside_boundary_condition"] == "Outdoors" and s["surface_type"] == "Wall"
    ]
    for wall in walls:  # each facade in its perimeter zone, facing away from the building
        facade = wall["construction_name"].split()[-1]
        assert wall["zone_name"] == perimeter_zone(zoning, facade)
        centre = Geometry.from_theta(DEFAULT_THETA).side_m / 2
        assert np.dot(_normal(wall)[:2], _centroid(wall)[:2] - centre) > 0
    for kind in ("Roof", "Floor"):  # roof and ground cover the footprint once
        pieces = [s for s in surfaces.values() if s["surface_type"] == kind]
        total = 0.0
        for s in pieces:
            xy = np.array([[v["vertex_x_coordinate"], v["vertex_y_coordinate"]] for v in s["vertices"]])
            total += 0.5 * abs(np.dot(xy[:, 0], np.roll(xy[:, 1], 1)) - np.dot(xy[:, 1], np.roll(xy[:, 0], 1)))
        side = Geometry.from_theta(DEFAULT_THETA).side_m
        assert total == pytest.approx(side**2, rel=1e-3)
    infiltration = model["ZoneInfiltration:DesignFlowRate"].values()  # the whole building's, through its facades
    volume = Geometry.from_theta(DEFAULT_THETA).volume_m3
    assert sum(i["design_flow_rate"] for i in infiltration) == pytest.approx(
        DEFAULT_THETA["infiltration_ach"] * volume / 3600.0, rel=1e-4
    )
    assert len(build_epjson(DEFAULT_THETA, weather, tmp_path / "s.csv", 0, 1, zoning="single")["Zone"]) == 1


def test_five_zone_perimeters_share_the_ring():
    office = Geometry.from_theta({"floor_area_m2": 4982.2, "number_of_floors": 3})
    five, two = zone_shares(office, "five_zone"), zone_shares(office, "core_perimeter")
    assert sum(five.values()) == pytest.approx(1.0) and five[CORE] == pytest.approx(two[CORE])
    for facade in ("north", "east", "south", "west"):
        assert five[perimeter_zone("five_zone", facade)] == pytest.approx(two[PERIMETER] / 4)


@pytest.fixture(scope="module")
def january(tmp_path_factory):
    settings, occupancy = default_week()
    work = tmp_path_factory.mktemp("zoning")
    runs = {
        z: simulate_weeks(
            DEFAULT_THETA, settings, occupancy, "usa_il_chicago", JANUARY, workdir=work / z, keep_files=True, zoning=z
        ).outputs[0]
        for z in ("single", "core_perimeter")
    }
    return runs, work


def test_outputs_are_the_zones_mean_temperature_and_summed_energy(january):
    runs, work = january
    frame = pd.read_csv(work / "core_perimeter" / "eplusout.csv")
    column = {c.split(" [")[0].upper(): c for c in frame.columns}
    shares = zone_shares(Geometry.from_theta(DEFAULT_THETA), "core_perimeter")
    t = sum(shares[z] * frame[column[f"{z.upper()}:ZONE MEAN AIR TEMPERATURE"]] for z in (PERIMETER, CORE))
    np.testing.assert_allclose(runs["core_perimeter"][:, OUT["T_INT_OFFICE"]], t, atol=1e-6)
    heat = sum(
        frame[column[f"{z.upper()} FAN COILS:ZONE IDEAL LOADS SUPPLY AIR TOTAL HEATING ENERGY"]]
        for z in (PERIMETER, CORE)
    )
    np.testing.assert_allclose(
        runs["core_perimeter"][:, OUT["Q_HEAT_OFFICE"]], heat / 3600.0 / DEFAULT_THETA["floor_area_m2"], rtol=1e-6
    )


def test_perimeter_heats_at_night_while_the_mean_stays_above_setback(january):
    runs, _ = january
    settings, occupancy = default_week()
    setback = settings[0, 0, cat.SETTING_NAMES.index("heating_setback_c")]
    hours = np.arange(cat.HOURS_PER_WEEK)
    night = (hours // 24 < 5) & (hours % 24 < 6)  # weekday nights 0-6 h
    split = runs["core_perimeter"]
    assert split[night, OUT["Q_HEAT_OFFICE"]].mean() > 1.0  # Wh/m2 per night hour
    assert split[night, OUT["T_INT_OFFICE"]].mean() > setback + 0.3  # the warm core lifts the mean
    # the same internal gains and envelope: the energy balance of the week stays close
    week = lambda out: out[:, [OUT["Q_HEAT_OFFICE"], OUT["Q_AHU_H"]]].sum()  # noqa: E731
    assert week(split) == pytest.approx(week(runs["single"]), rel=0.25)


def test_reference_design_ventilation_is_recorded_in_model_units():
    medium = design_outdoor_air_ach(reference_idf("medium_office"), resolve_epw("usa_il_chicago"))
    assert 0.6 < medium < 0.8  # 3 air handlers x 1.117 m3/s over 4,982 m2 x 3.5 m
    assert historical_ventilation_ach("medium_office") == pytest.approx(0.7)
    controllable, limits = reference_bms("medium_office")
    assert controllable == tuple(n for n in cat.SETTING_NAMES if n not in UNMAPPED_SETTINGS)
    # from ASHRAE 62.1 for its 18.58 m2 a person, (2.5 / 18.58 + 0.3) L/s m2 over 3.5 m, up to its design
    assert "supply_air_c" in UNMAPPED_SETTINGS and limits == {"ventilation_ach": (0.45, 0.7)}
    settings = historical_settings(1, 1.3)
    assert np.all(settings[..., cat.SETTING_NAMES.index("ventilation_ach")] == 1.3)
    low = historical_settings(1, 0.7)
    oa_design = _schedule_columns(low, 0.7)["outdoor_air"]
    oa_half = _schedule_columns(low, 1.4)["outdoor_air"]
    assert oa_design.max() == pytest.approx(1.0) and oa_half.max() == pytest.approx(0.5)
    assert _schedule_columns(settings, 0.7)["outdoor_air"].max() == pytest.approx(1.0)  # above design: capped


def test_campaign_zoning_is_validated_and_old_campaigns_resume_as_single(tmp_path):
    with pytest.raises(BuildenvError, match="--zoning"):
        CampaignConfig(weeks=1, zoning="three").validate()
    config = CampaignConfig(weeks=1, seed=1, epw=["usa_co_golden"], weeks_per_run=1, zoning="single")
    out = tmp_path / "old"
    out.mkdir()
    record = {
        "config": {k: v for k, v in config.__dict__.items() if k != "zoning"},
        "catalogue_hash": cat.catalogue_hash(),
    }
    (out / "campaign.json").write_text(json.dumps(record))  # written before zoning existed
    run_campaign(config, out, workers=1, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["zoning"] == "single"


def test_five_zone_vav_night_cycles_the_whole_building_on_its_warmest_zone():
    settings, occupancy = default_week()
    off = hourly_schedules(settings, occupancy)["ventilation_on"][0] == 0
    vav = {**DEFAULT_THETA, "minimum_supply_air_ach": 1.5, "cooling_power_w_m2": 100}

    def run(theta, zoning, week=JULY):
        return simulate_weeks(theta, settings, occupancy, "usa_il_chicago", week, zoning=zoning).outputs[0]

    cycled, ring = run(vav, "five_zone"), run(vav, "core_perimeter")
    outdoor_air_only = run({**vav, "minimum_supply_air_ach": 0.0}, "five_zone")
    # out of hours the air handling units cool return air whenever the warmest perimeter reaches the setback
    assert cycled[off, OUT["Q_AHU_C"]].sum() > 10 * cycled[off, OUT["Q_AC_OFFICE"]].sum() > 0
    assert cycled[off, OUT["T_INT_OFFICE"]].mean() < ring[off, OUT["T_INT_OFFICE"]].mean() - 0.2
    # a 100 % outdoor air unit does not night-cycle: its fan coils hold each zone at the setback
    assert outdoor_air_only[off, OUT["Q_AHU_C"]].sum() == 0 and outdoor_air_only[off, OUT["Q_AC_OFFICE"]].sum() > 0
    assert not night_cycling("core_perimeter", vav) and night_cycling("five_zone", vav)
    # in winter the fan coils hold the heating setback zone by zone; the air handling units stay off
    winter = run(vav, "five_zone", JANUARY)
    assert winter[off, OUT["Q_AHU_H"]].sum() == 0 and winter[off, OUT["Q_HEAT_OFFICE"]].sum() > 0


def test_a_vav_system_night_cycles_cold_supply_air_that_the_zones_reheat_at_its_heating_share():
    settings, occupancy = default_week()
    settings[..., cat.SETTING_NAMES.index("supply_air_c")] = 13.0  # the DOE offices' 12.8 degC
    off = hourly_schedules(settings, occupancy)["ventilation_on"][0] == 0
    vav = {**DEFAULT_THETA, "minimum_supply_air_ach": 1.5, "heating_power_w_m2": 100}

    def night_heating(share, zoning="five_zone"):
        theta = {**vav, "night_cycle_heating_share": share}
        out = simulate_weeks(theta, settings, occupancy, "usa_il_chicago", JANUARY, zoning=zoning).outputs[0]
        return out[off, OUT["Q_HEAT_OFFICE"]].sum() + out[off, OUT["Q_AHU_H"]].sum()

    # the larger the share of the minimum flow cycled at the supply temperature, the more the zones reheat at night
    none, half, full = (night_heating(s) for s in (0.0, 0.5, 1.0))
    assert none > 0 and full > 1.15 * half > 1.3 * none
    # a shoebox that does not night-cycle ignores it
    assert night_heating(1.0, "core_perimeter") == pytest.approx(night_heating(0.0, "core_perimeter"), rel=1e-9)
