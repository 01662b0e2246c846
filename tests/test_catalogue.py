"""The variable catalogue: sizes, grids, conversions, lookup, validation, hashing."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, CatalogueError

PAPER_WEATHER = ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H", "RHUM", "TAMB")
PAPER_OUTPUTS = ("Q_AC_OFFICE", "Q_HEAT_OFFICE", "Q_PEOPLE", "Q_EQP", "Q_LIGHT", "Q_AHU_C", "Q_AHU_H", "T_INT_OFFICE")
STEPPED = [v for v in cat.ALL_VARIABLES if v.step is not None]


# --------------------------------------------------------------------------- group sizes
def test_group_sizes_match_the_paper():
    # theta_build: the paper's 17 (nb_PCs as plug-load power) + floor area, floors, lighting power, heat recovery,
    # minimum supply air, economiser share, infiltration left while the fans pressurise the building, the night
    # cycle's heating share
    assert len(cat.THETA_BUILD) == 25
    assert {"lighting_power_w_m2", "heat_recovery_effectiveness", "plug_load_w_m2"} <= set(cat.THETA_NAMES)
    assert "pc_density_per_m2" not in cat.THETA_NAMES
    assert len(cat.SETTINGS) == 13 and cat.SETTING_NAMES[-1] == "hvac_operating"  # + a day set back entirely
    assert len(cat.OCCUPANCY) == 2
    assert len(cat.WEATHER) == 9
    assert len(cat.OUTPUTS) == 8
    assert len(cat.ALL_VARIABLES) == 25 + 13 + 2 + 9 + 8
    assert set(cat.GROUPS) == {"theta_build", "settings", "occupancy", "weather", "outputs"}


def test_names_are_unique_and_groups_consistent():
    names = [v.name for v in cat.ALL_VARIABLES]
    assert len(names) == len(set(names))
    for group, variables in cat.GROUPS.items():
        assert all(v.group == group for v in variables), group
    assert cat.THETA_NAMES == tuple(v.name for v in cat.THETA_BUILD)
    assert cat.WEATHER_NAMES == tuple(v.name for v in cat.WEATHER)


def test_geometry_variables():
    area = cat.get("floor_area_m2")
    floors = cat.get("number_of_floors")
    assert area.group == floors.group == "theta_build"
    assert (area.min, area.max, area.step) == (300.0, 50000.0, 100.0)
    assert (floors.min, floors.max) == (1.0, 15.0)
    assert floors.step == 1.0
    np.testing.assert_array_equal(floors.grid(), np.arange(1, 16))


def test_paper_weather_and_output_names():
    assert set(PAPER_WEATHER) <= set(cat.WEATHER_NAMES)
    assert cat.WEATHER_NAMES[:7] == PAPER_WEATHER
    assert set(cat.OUTPUT_NAMES) == set(PAPER_OUTPUTS)
    for name in PAPER_WEATHER + PAPER_OUTPUTS:
        assert cat.get(name).paper_name == name


def test_granularities():
    assert all(v.granularity is cat.Granularity.STATIC for v in cat.THETA_BUILD)
    assert all(v.granularity is cat.Granularity.PER_DAY for v in cat.SETTINGS)
    assert all(v.granularity is cat.Granularity.PER_WEEKDAY for v in cat.OCCUPANCY)
    assert all(v.granularity is cat.Granularity.PER_HOUR for v in cat.WEATHER + cat.OUTPUTS)
    # inputs that are sampled have a grid, measured series are continuous
    assert all(v.step is not None for v in cat.THETA_BUILD + cat.SETTINGS + cat.OCCUPANCY)
    assert all(v.step is None for v in cat.WEATHER + cat.OUTPUTS)


def test_min_below_max_everywhere():
    for v in cat.ALL_VARIABLES:
        assert v.min < v.max, v.name


# --------------------------------------------------------------------------- grids
@pytest.mark.parametrize("var", STEPPED, ids=lambda v: v.name)
def test_grid_starts_at_min_stays_within_max_and_has_the_step(var):
    grid = var.grid()
    assert grid.ndim == 1 and len(grid) >= 2
    assert grid[0] == pytest.approx(var.min)
    assert grid[-1] <= var.max + 1e-9
    # the grid goes as far as it can: one more step would overshoot max
    assert grid[-1] + var.step > var.max + 1e-9
    np.testing.assert_allclose(np.diff(grid), var.step, rtol=0, atol=1e-9)


def test_vol_ventilation_grid_holds_the_papers_and_a_bms_range():
    grid = cat.get("ventilation_ach").grid()
    assert grid[0] == pytest.approx(0.1) and grid[-1] == pytest.approx(1.7) and len(grid) == 33
    # the paper's 0.7, 1.0, 1.3 and 1.6 are on it
    assert np.isclose(grid[:, None], [0.7, 1.0, 1.3, 1.6]).any(axis=0).all()
    # a DOE medium office's BMS range, from the ASHRAE 62.1 minimum (0.45) to its design (0.7), has six settings
    assert np.count_nonzero((grid > 0.45 - 1e-9) & (grid < 0.7 + 1e-9)) == 6


def test_grid_of_continuous_variable_raises():
    with pytest.raises(CatalogueError, match="TAMB"):
        cat.get("TAMB").grid()


# --------------------------------------------------------------------------- per-m2 conversions
def test_paper_occupants_and_pcs_per_m2_within_range():
    paper_area = 28_733.0
    lo, hi = round(1000 / paper_area, 3), round(2000 / paper_area, 3)  # 1,000-2,000 occupants (and PCs)
    dens = cat.get("occupant_density_per_m2")
    assert dens.min < lo and hi < dens.max
    # the earlier catalogue drew the paper's range itself, for occupants and (x 150 W) for workstations
    earlier = cat.EARLIER_CATALOGUES["bf68f6178dc1d1b3"]
    assert earlier.ranges["occupant_density_per_m2"][:2] == pytest.approx((lo, hi))
    assert earlier.ranges["plug_load_w_m2"][:2] == pytest.approx((150 * lo, 150 * hi))
    plug = cat.get("plug_load_w_m2")
    assert plug.min < 150 * lo and 150 * hi < plug.max


def test_paper_fan_coil_power_per_m2_within_range():
    # the paper's 1,000 kW on 28,733 m2 is about 35 W/m2, inside the catalogue's range
    w_m2 = 1000e3 / 28_733
    assert w_m2 == pytest.approx(34.8, abs=0.05)
    for name in ("heating_power_w_m2", "cooling_power_w_m2"):
        v = cat.get(name)
        assert v.min <= w_m2 <= v.max


# --------------------------------------------------------------------------- snap / check
@pytest.mark.parametrize("var", STEPPED, ids=lambda v: v.name)
def test_snap_round_trips_grid_values(var):
    grid = var.grid()
    np.testing.assert_array_equal(var.snap(grid), grid)


def test_snap_rounds_to_nearest_and_clips():
    vent = cat.get("ventilation_ach")
    assert float(vent.snap(1.11)) == pytest.approx(1.1)
    assert float(vent.snap(0.44)) == pytest.approx(0.45)
    assert float(vent.snap(-5.0)) == pytest.approx(0.1)
    assert float(vent.snap(99.0)) == pytest.approx(1.7)
    off_grid = dataclasses.replace(vent, max=1.72)  # a max off the grid clips to the last grid point below it
    assert float(off_grid.snap(99.0)) == pytest.approx(1.7)
    area = cat.get("floor_area_m2")
    np.testing.assert_array_equal(area.snap([10.0, 2449.0, 2451.0, 1e9]), [300.0, 2400.0, 2500.0, 50000.0])
    # a continuous variable is only clipped
    tamb = cat.get("TAMB")
    np.testing.assert_array_equal(tamb.snap([-100.0, 12.34, 100.0]), [-60.0, 12.34, 60.0])


def test_check_accepts_in_range_values():
    v = cat.get("heating_comfort_c")
    v.check(22.0)
    v.check(24.0)
    v.check(np.array([[22.0, 23.3], [24.0, 22.5]]))


@pytest.mark.parametrize("bad", [21.0, 30.0, -1.0])
def test_check_rejects_out_of_range_naming_variable_and_value(bad):
    v = cat.get("heating_comfort_c")
    with pytest.raises(CatalogueError) as info:
        v.check(np.array([23.0, bad, 22.0]), where="test.csv:3")
    msg = str(info.value)
    assert "heating_comfort_c" in msg
    assert f"{bad:g}" in msg
    assert "[22, 24]" in msg
    assert "test.csv:3" in msg
    assert isinstance(info.value, BuildenvError)


def test_check_rejects_nan_and_inf():
    v = cat.get("floor_area_m2")
    with pytest.raises(CatalogueError, match=r"floor_area_m2=nan"):
        v.check(float("nan"))
    with pytest.raises(CatalogueError, match=r"floor_area_m2=inf"):
        v.check(np.array([5000.0, np.inf]))


def test_check_values_checks_each_column_and_shape():
    lo, hi = cat.bounds("occupancy")
    cat.check_values("occupancy", np.stack([lo, hi]))
    with pytest.raises(CatalogueError, match="occupancy_end_hour=21"):
        cat.check_values("occupancy", np.array([[8.0, 18.0], [8.0, 21.0]]))
    with pytest.raises(CatalogueError, match="expected 2"):
        cat.check_values("occupancy", np.zeros((4, 3)))


def test_bounds_follow_catalogue_order():
    lo, hi = cat.bounds("settings")
    assert lo.shape == hi.shape == (13,)
    assert lo[cat.SETTING_NAMES.index("heating_comfort_c")] == 22.0
    assert hi[cat.SETTING_NAMES.index("ventilation_ach")] == 1.7


# --------------------------------------------------------------------------- get
@pytest.mark.parametrize(
    "alias, canonical",
    [
        ("t_heat_conf_day", "heating_comfort_c"),
        ("airchange_infiltration_vol_per_h", "infiltration_ach"),
        ("capacitance_kJ_perdegreK_perm3", "capacitance_kj_per_k_m3"),
        ("nb_occupants", "occupant_density_per_m2"),
        ("vol_ventilation_day", "ventilation_ach"),
        ("T_HEAT_CONF_DAY", "heating_comfort_c"),  # aliases are case-insensitive
    ],
)
def test_get_accepts_paper_aliases(alias, canonical):
    assert cat.get(alias).name == canonical
    assert cat.get(alias) is cat.get(canonical)


def test_get_canonical_names():
    for v in cat.ALL_VARIABLES:
        assert cat.get(v.name) is v


@pytest.mark.parametrize(
    "typo, suggestion",
    [
        ("heating_comfrt_c", "heating_comfort_c"),
        ("floor_aera_m2", "floor_area_m2"),
        ("t_heat_conf_dya", "t_heat_conf_day"),
    ],
)
def test_get_suggests_close_name(typo, suggestion):
    with pytest.raises(CatalogueError) as info:
        cat.get(typo)
    msg = str(info.value)
    assert repr(typo) in msg
    assert f"did you mean {suggestion!r}" in msg


def test_get_unknown_name_without_close_match():
    with pytest.raises(CatalogueError) as info:
        cat.get("zzzzzzzzzzzz")
    assert "zzzzzzzzzzzz" in str(info.value)
    assert "did you mean" not in str(info.value)
    # a CatalogueError is also a KeyError, but prints its message unquoted
    assert isinstance(info.value, KeyError)
    assert not str(info.value).startswith('"')


# --------------------------------------------------------------------------- from_mapping
def _theta_mapping(**overrides):
    values = {v.name: float(v.grid()[len(v.grid()) // 2]) for v in cat.THETA_BUILD}
    values.update(overrides)
    return values


def test_from_mapping_builds_vector_in_catalogue_order():
    mapping = _theta_mapping()
    vector = cat.from_mapping("theta_build", dict(reversed(list(mapping.items()))))
    assert vector.shape == (len(cat.THETA_BUILD),)
    np.testing.assert_array_equal(vector, [mapping[n] for n in cat.THETA_NAMES])


def test_from_mapping_accepts_aliases_and_defaults():
    mapping = _theta_mapping()
    defaults = dict(mapping)
    vector = cat.from_mapping("theta_build", {"airchange_infiltration_vol_per_h": 0.5}, defaults=defaults)
    assert vector[cat.THETA_NAMES.index("infiltration_ach")] == 0.5
    assert vector[cat.THETA_NAMES.index("floor_area_m2")] == defaults["floor_area_m2"]


def test_from_mapping_rejects_unknown_name():
    with pytest.raises(CatalogueError, match="floor_aera_m2.*did you mean 'floor_area_m2'"):
        cat.from_mapping("theta_build", {"floor_aera_m2": 5000}, defaults=_theta_mapping())


def test_from_mapping_rejects_wrong_group():
    with pytest.raises(CatalogueError) as info:
        cat.from_mapping("theta_build", {"heating_comfort_c": 22}, defaults=_theta_mapping(), where="b.json")
    msg = str(info.value)
    assert "heating_comfort_c" in msg and "settings" in msg and "theta_build" in msg and "b.json" in msg


def test_from_mapping_rejects_missing_names():
    mapping = _theta_mapping()
    del mapping["roof_insulation_m"]
    del mapping["number_of_floors"]
    with pytest.raises(CatalogueError) as info:
        cat.from_mapping("theta_build", mapping)
    msg = str(info.value)
    assert "missing" in msg and "roof_insulation_m" in msg and "number_of_floors" in msg


def test_from_mapping_rejects_out_of_range():
    with pytest.raises(CatalogueError, match=r"number_of_floors=20.*\[1, 15\]"):
        cat.from_mapping("theta_build", _theta_mapping(number_of_floors=20))


# --------------------------------------------------------------------------- weekly names
def test_weekly_names_sizes_and_order():
    settings = cat.weekly_names("settings")
    occupancy = cat.weekly_names("occupancy")
    assert len(settings) == 91 and len(set(settings)) == 91
    assert len(occupancy) == 10 and len(set(occupancy)) == 10
    # day-major: all of Monday's settings first, in catalogue order, then Tuesday's ...
    assert settings[:13] == tuple(f"{n}_monday" for n in cat.SETTING_NAMES)
    assert settings[13] == "cooling_start_hour_tuesday"
    assert settings[0] == "cooling_start_hour_monday"
    assert settings[-1] == "hvac_operating_sunday"
    assert occupancy == (
        "occupancy_start_hour_monday",
        "occupancy_end_hour_monday",
        "occupancy_start_hour_tuesday",
        "occupancy_end_hour_tuesday",
        "occupancy_start_hour_wednesday",
        "occupancy_end_hour_wednesday",
        "occupancy_start_hour_thursday",
        "occupancy_end_hour_thursday",
        "occupancy_start_hour_friday",
        "occupancy_end_hour_friday",
    )
    # the flat order matches a C-order reshape of (7, 13) arrays
    idx = np.arange(91).reshape(7, 13)
    assert settings[idx[3, 7]] == f"{cat.SETTING_NAMES[7]}_{cat.DAYS[3]}"


# --------------------------------------------------------------------------- earlier catalogues
def test_earlier_catalogue_describes_the_one_it_replaced():
    assert cat.catalogue_hash() not in cat.EARLIER_CATALOGUES
    earlier = cat.EARLIER_CATALOGUES["bf68f6178dc1d1b3"]
    assert len(earlier.theta_names) == 19 and "pc_density_per_m2" in earlier.theta_names
    # its names, renamed, plus what it lacked, are exactly this catalogue's theta_build
    renamed = {earlier.renamed.get(n, (n, 1.0))[0] for n in earlier.theta_names}
    assert renamed | set(earlier.implied) == set(cat.THETA_NAMES) and not renamed & set(earlier.implied)
    assert earlier.implied == {
        "lighting_power_w_m2": 10.0,
        "heat_recovery_effectiveness": 0.0,
        "minimum_supply_air_ach": 0.0,
        "economiser_share": 0.0,
        "infiltration_fans_on_share": 1.0,
        "night_cycle_heating_share": 0.0,
    }
    for name, value in earlier.implied.items():
        cat.get(name).check(value)
    # the catalogue widened: each earlier range lies inside this one's
    for name, (lo, hi, _) in earlier.ranges.items():
        var = cat.get(name)
        assert var.min <= lo <= hi <= var.max, name
    assert earlier.ranges["ventilation_ach"] == (0.7, 1.7, 0.3)
    # no catalogue up to d40fb58bb6ff03a6 set a day back entirely: a metamodel of one knows operating days only
    names = list(cat.EARLIER_CATALOGUES)
    k = names.index("d40fb58bb6ff03a6") + 1
    assert all(cat.EARLIER_CATALOGUES[n].ranges["hvac_operating"] == (1.0, 1.0, 1.0) for n in names[:k])
    assert not any("hvac_operating" in cat.EARLIER_CATALOGUES[n].ranges for n in names[k:])


def test_a_switch_is_on_or_off_and_nothing_between():
    switches = [v.name for v in cat.ALL_VARIABLES if v.is_switch]
    assert switches == ["hvac_operating"]  # a day operates or is set back; no other variable is on/off
    day = cat.get("hvac_operating")
    day.check_switch(np.array([0.0, 1.0, 1.0]))
    with pytest.raises(CatalogueError, match=r"hvac_operating=0\.5: write 1 \(on\) or 0 \(off\)"):
        day.check_switch(np.array([1.0, 0.5]))
    cat.get("heating_comfort_c").check_switch(21.3)  # not a switch: values between its ends pass


def test_upgrade_theta_converts_pc_density_and_fills_what_was_missing():
    old = {"pc_density_per_m2": 0.055, "infiltration_ach": 0.3, "floor_area_m2": 5000.0}
    new = cat.upgrade_theta(old)
    assert "pc_density_per_m2" not in new
    assert new["plug_load_w_m2"] == pytest.approx(150 * 0.055)
    assert new["lighting_power_w_m2"] == 10.0 and new["heat_recovery_effectiveness"] == 0.0
    assert new["infiltration_ach"] == 0.3 and new["floor_area_m2"] == 5000.0  # others pass unchanged
    assert old == {"pc_density_per_m2": 0.055, "infiltration_ach": 0.3, "floor_area_m2": 5000.0}  # not mutated
    # written under this catalogue: nothing is converted or filled in
    current = {"plug_load_w_m2": 12.0, "infiltration_ach": 0.3}
    assert cat.upgrade_theta(current) == current
    # a full theta of the catalogue before the minimum supply flow: its 100 % outdoor air units
    before = {n: cat.get(n).min for n in cat.EARLIER_CATALOGUES["6f2f25c1acea3f20"].theta_names}
    assert "minimum_supply_air_ach" not in before
    unpressurised = {"infiltration_fans_on_share": 1.0, "night_cycle_heating_share": 0.0}
    assert cat.upgrade_theta(before) == {
        **before,
        "minimum_supply_air_ach": 0.0,
        "economiser_share": 0.0,
        **unpressurised,
    }
    # a full theta of the catalogue before the economiser: mechanical cooling only
    before = {n: cat.get(n).min for n in cat.EARLIER_CATALOGUES["bda1c8ff3b9294aa"].theta_names}
    assert "economiser_share" not in before and "minimum_supply_air_ach" in before
    assert cat.upgrade_theta(before) == {**before, "economiser_share": 0.0, **unpressurised}
    # a full theta of the catalogue before the fans pressurised: the same infiltration day and night
    before = {n: cat.get(n).min for n in cat.EARLIER_CATALOGUES["bf2a5f1cabb2a9f8"].theta_names}
    assert "infiltration_fans_on_share" not in before and "economiser_share" in before
    assert cat.upgrade_theta(before) == {**before, **unpressurised}
    # an earlier full theta becomes a vector of this catalogue
    earlier = cat.EARLIER_CATALOGUES["bf68f6178dc1d1b3"]
    mid = {n: float(np.mean(earlier.ranges.get(n, (cat.get(n).min, cat.get(n).max))[:2])) for n in cat.THETA_NAMES}
    mid["pc_density_per_m2"] = mid.pop("plug_load_w_m2") / 150
    upgraded = cat.upgrade_theta({n: mid[n] for n in earlier.theta_names})
    vector = cat.from_mapping("theta_build", upgraded)
    assert vector[cat.THETA_NAMES.index("plug_load_w_m2")] == pytest.approx(150 * mid["pc_density_per_m2"])


def test_shipped_checkpoints_read_through_their_earlier_catalogues():
    from buildenv.metamodel.surrogate import load_metamodel

    default = load_metamodel()  # every range its own, days set back entirely included; its zoning has no night cycle
    assert default.implied == {"night_cycle_heating_share": 0.0} and default.earlier.ranges == {}
    assert default.domain["hvac_operating"] == (0.0, 1.0) and default.domain["ventilation_ach"] == (0.1, 1.7)
    surrogate = load_metamodel("diagnosis")
    assert surrogate.checkpoint.metadata["catalogue_hash"] in cat.EARLIER_CATALOGUES
    assert surrogate.earlier is cat.EARLIER_CATALOGUES[surrogate.checkpoint.metadata["catalogue_hash"]]
    assert surrogate.domain["ventilation_ach"] == (0.7, 1.7) and surrogate.domain["hvac_operating"] == (1.0, 1.0)
    assert surrogate.domain["floor_area_m2"] == (1000.0, 50000.0)
    assert set(surrogate.domain) == set(cat.THETA_NAMES) | set(cat.SETTING_NAMES)
    assert surrogate.implied == cat.EARLIER_CATALOGUES["bf68f6178dc1d1b3"].implied


# --------------------------------------------------------------------------- hash / describe
def test_catalogue_hash_is_stable():
    h = cat.catalogue_hash()
    assert h == cat.catalogue_hash()
    assert len(h) == 16
    int(h, 16)


def test_catalogue_hash_changes_when_a_variable_changes(monkeypatch):
    before = cat.catalogue_hash()
    changed = dataclasses.replace(cat.THETA_BUILD[0], max=60000.0)
    new_theta = (changed,) + cat.THETA_BUILD[1:]
    monkeypatch.setattr(cat, "THETA_BUILD", new_theta)
    monkeypatch.setitem(cat.GROUPS, "theta_build", new_theta)
    monkeypatch.setattr(cat, "ALL_VARIABLES", tuple(v for g in cat.GROUPS.values() for v in g))
    after = cat.catalogue_hash()
    assert after != before
    monkeypatch.undo()
    assert cat.catalogue_hash() == before
    assert cat.GROUPS["theta_build"][0].max == 50000.0


def test_catalogue_hash_changes_with_a_description(monkeypatch):
    before = cat.catalogue_hash()
    variables = list(cat.ALL_VARIABLES)
    variables[-1] = dataclasses.replace(variables[-1], description="changed")
    monkeypatch.setattr(cat, "ALL_VARIABLES", tuple(variables))
    assert cat.catalogue_hash() != before


def test_describe_is_json_serialisable():
    rows = cat.describe()
    assert len(rows) == len(cat.ALL_VARIABLES)
    text = json.dumps(rows)
    back = json.loads(text)
    assert back == rows
    first = back[0]
    assert set(first) == {"name", "group", "unit", "min", "max", "step", "granularity", "description", "paper_name"}
    assert first["name"] == "floor_area_m2" and first["granularity"] == "static"
    tamb = next(r for r in back if r["name"] == "TAMB")
    assert tamb["step"] is None and tamb["granularity"] == "per_hour"
    assert all(isinstance(r["min"], float) and math.isfinite(r["min"]) for r in back)


def test_describe_selected_groups():
    rows = cat.describe(["occupancy", "settings"])
    assert [r["name"] for r in rows] == list(cat.OCCUPANCY_NAMES + cat.SETTING_NAMES)
    json.dumps(rows)


def test_datasets_of_a_catalogue_that_lacked_a_variable_read_it_at_the_value_its_shoebox_had():
    import numpy as np

    from buildenv.campaign.dataset import PaddedTheta, readable_catalogue

    assert readable_catalogue(cat.catalogue_hash())
    assert readable_catalogue("bf2a5f1cabb2a9f8")  # before the infiltration with fans on and night heating
    assert not readable_catalogue("bf68f6178dc1d1b3")  # PCs, not plug-load power: a renamed variable
    assert not readable_catalogue("0123456789abcdef") and not readable_catalogue(None)
    earlier = cat.EARLIER_CATALOGUES["bf2a5f1cabb2a9f8"]
    stored = np.arange(3 * len(earlier.theta_names), dtype=np.float32).reshape(3, -1)
    padded = PaddedTheta(stored, earlier)
    assert padded.shape == (3, len(cat.THETA_NAMES))
    rows = padded[np.array([0, 2])]
    for j, name in enumerate(cat.THETA_NAMES):
        want = earlier.implied[name] if name in earlier.implied else stored[[0, 2], earlier.theta_names.index(name)]
        np.testing.assert_array_equal(rows[:, j], want)
    np.testing.assert_array_equal(padded[1], padded[:][1])
