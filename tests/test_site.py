"""Site folders: write_site -> load_site round trip, every validation error with its file:line, gaps, EPW hours."""

from __future__ import annotations

import datetime as dt
import json
import re
from pathlib import Path

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, SiteError
from buildenv.sites import Site, load_site, save_calibration, write_site
from buildenv.weather.epw import load_weather

START = dt.date(2024, 1, 1)  # a Monday
AREA = 4982.0  # not on the catalogue's 100 m2 step: must be kept as is
WEEKS = 2


def _arrays(weeks: int = WEEKS, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    lo, hi = cat.bounds("settings")
    settings = lo + (hi - lo) * rng.random((weeks, 7, len(lo)))
    settings = np.round(settings, 1).clip(lo, hi)
    settings[..., cat.SETTING_NAMES.index("hvac_operating")] = np.round(settings[..., -1])  # a day operates or not
    temperature = np.round(21 + 2 * rng.standard_normal((weeks, 168)), 3)
    consumption = np.round(20 + 80 * rng.random((weeks, 168)), 4)
    return {"settings": settings, "temperature_c": temperature, "consumption_kwh": consumption}


def _write(path: Path, **overrides) -> Path:
    kwargs = {
        "name": "Chicago medium office",
        "weather": "usa_il_chicago",
        "start": START,
        "floor_area_m2": AREA,
        "number_of_floors": 3,
        **_arrays(),
        "source": {"seed": 7},
    }
    kwargs.update(overrides)
    return write_site(path, **kwargs)


@pytest.fixture()
def site_dir(tmp_path: Path) -> Path:
    return _write(tmp_path / "site")


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _edit(path: Path, edit) -> None:
    """Apply ``edit(lines) -> lines`` to a text file."""
    path.write_text("\n".join(edit(_lines(path))) + "\n")


def _set_line(path: Path, line: int, text: str) -> None:
    """Replace 1-based ``line``."""

    def edit(lines):
        lines[line - 1] = text
        return lines

    _edit(path, edit)


def _cells(path: Path, line: int) -> list[str]:
    return _lines(path)[line - 1].split(",")


def _stamp(hour: int) -> str:
    return (dt.datetime.combine(START, dt.time()) + dt.timedelta(hours=hour)).strftime("%Y-%m-%d %H:%M")


def _range(name: str) -> str:
    """A variable's catalogue range as its out-of-range error writes it, escaped for a regex (``[5, 150] W/m2``)."""
    v = cat.get(name)
    return re.escape(f"[{v.min:g}, {v.max:g}] {v.unit}")


# --------------------------------------------------------------------------- round trip
def test_round_trip(tmp_path: Path):
    arrays = _arrays()
    arrays["temperature_c"][0, 3] = np.nan
    arrays["consumption_kwh"][1, 100] = np.nan
    source = {"reference": "MediumOffice", "noise_c": 0.2, "seed": 3, "flags": [1, 2], "nested": {"a b": True}}
    truth = {"infiltration_ach": 0.3, "theta": np.array([1.0, 2.0])}
    path = write_site(
        tmp_path / "s",
        name='Office "A"',
        weather="usa_il_chicago",
        start=START,
        floor_area_m2=AREA,
        number_of_floors=3,
        source=source,
        truth=truth,
        **arrays,
    )
    site = load_site(path)
    assert isinstance(site, Site)
    assert site.path == path.resolve()
    assert site.name == 'Office "A"'
    assert site.weather == "usa_il_chicago"
    assert site.start == START and site.weeks == WEEKS
    assert site.floor_area_m2 == AREA and site.number_of_floors == 3
    assert site.settings.shape == (WEEKS, 7, 13)
    np.testing.assert_array_equal(site.settings, arrays["settings"])
    np.testing.assert_array_equal(site.temperature_c, arrays["temperature_c"])  # on the written 3-decimal grid
    np.testing.assert_array_equal(site.consumption_kwh, arrays["consumption_kwh"])
    assert site.source == {
        "reference": "MediumOffice",
        "noise_c": 0.2,
        "seed": 3,
        "flags": [1, 2],
        "nested": {"a b": True},
    }
    assert site.truth == {"infiltration_ach": 0.3, "theta": [1.0, 2.0]}
    assert site.calibration is None
    assert not site.temperature_mask[0, 3] and site.temperature_mask.sum() == WEEKS * 168 - 1
    assert not site.consumption_mask[1, 100] and site.consumption_mask.sum() == WEEKS * 168 - 1
    assert site.week_starts() == [START, START + dt.timedelta(days=7)]
    assert site.theta_known() == {"floor_area_m2": AREA, "number_of_floors": 3.0}
    wh = site.consumption_wh_m2()
    np.testing.assert_allclose(wh, arrays["consumption_kwh"] * 1000 / AREA)
    assert np.isnan(wh[1, 100])


def test_round_trip_rounds_to_written_precision(tmp_path: Path):
    arrays = _arrays()
    arrays["temperature_c"] = arrays["temperature_c"] + 1.23456e-4
    arrays["consumption_kwh"] = arrays["consumption_kwh"] + 1.23456e-5
    site = load_site(_write(tmp_path / "s", **arrays))
    np.testing.assert_allclose(site.temperature_c, arrays["temperature_c"], atol=5e-4 + 1e-9, rtol=0)
    np.testing.assert_allclose(site.consumption_kwh, arrays["consumption_kwh"], atol=5e-5 + 1e-9, rtol=0)


def test_load_site_accepts_the_descriptor_path(site_dir: Path):
    assert load_site(site_dir / "site.toml").weeks == WEEKS


def test_save_calibration_is_read_back(site_dir: Path):
    from buildenv.defaults import DEFAULT_THETA

    occupancy = np.array([[8.0, 18.0]] * 5)
    calibration = {"theta": dict(DEFAULT_THETA), "occupancy": occupancy, "loss": np.float32(0.5), "ok": True}
    target = save_calibration(site_dir, calibration)
    assert target == site_dir / "calibration.json"
    written = {**calibration, "occupancy": occupancy.tolist(), "loss": 0.5}
    assert json.loads(target.read_text()) == written
    assert [p.name for p in site_dir.iterdir() if p.name.startswith(".")] == []  # no temporary file left
    assert load_site(site_dir).calibration == written


def test_save_calibration_needs_a_site_folder(tmp_path: Path):
    with pytest.raises(SiteError, match="not a site folder"):
        save_calibration(tmp_path, {"a": 1})


def test_write_site_removes_stale_calibration(site_dir: Path):
    save_calibration(site_dir, {"a": 1})
    _write(site_dir)
    assert load_site(site_dir).calibration is None


def test_write_site_rejects_bad_shapes_and_start(tmp_path: Path):
    with pytest.raises(SiteError, match="not a Monday"):
        _write(tmp_path / "a", start=dt.date(2024, 1, 2))
    with pytest.raises(SiteError, match=r"settings has shape"):
        _write(tmp_path / "b", settings=np.zeros((WEEKS, 7, 11)))
    with pytest.raises(SiteError, match=r"temperature_c has shape"):
        _write(tmp_path / "c", temperature_c=np.zeros((WEEKS, 24)))
    half_on = _arrays()["settings"]
    half_on[1, 3, cat.SETTING_NAMES.index("hvac_operating")] = 0.5
    with pytest.raises(SiteError, match=r"write_site: hvac_operating=0\.5 in .*: write 1 \(on\) or 0 \(off\)"):
        _write(tmp_path / "d", settings=half_on)
    assert not (tmp_path / "d").exists()  # refused before anything is written


def test_site_error_is_a_buildenv_error():
    assert issubclass(SiteError, BuildenvError)


# --------------------------------------------------------------------------- site.toml
def test_missing_folder_and_descriptor(tmp_path: Path):
    with pytest.raises(SiteError, match="site folder not found"):
        load_site(tmp_path / "nope")
    with pytest.raises(SiteError, match=r"site\.toml is missing"):
        load_site(tmp_path)


def _toml(site_dir: Path, text: str) -> None:
    (site_dir / "site.toml").write_text(text)


GOOD_TOML = """name = "x"
weather = "usa_il_chicago"

[geometry]
floor_area_m2 = 4982
number_of_floors = 3
"""


def test_unknown_top_level_key(site_dir: Path):
    _toml(site_dir, GOOD_TOML.replace('weather = "usa_il_chicago"', 'weather = "usa_il_chicago"\nwether = 1'))
    with pytest.raises(
        SiteError,
        match=r"site\.toml:3: unknown key 'wether'.*allowed: name, weather, "
        r"measurements, settings, effects, geometry, known, meters, bms, source",
    ):
        load_site(site_dir)


def test_unknown_geometry_key(site_dir: Path):
    _toml(site_dir, GOOD_TOML + "height_m = 10\n")
    with pytest.raises(
        SiteError,
        match=r"site\.toml:7: unknown key 'height_m' in \[geometry\].*"
        r"allowed: floor_area_m2, number_of_floors",
    ):
        load_site(site_dir)


def test_known_parameters_round_trip_and_join_the_fixed_theta(tmp_path: Path):
    site = load_site(_write(tmp_path / "s", known={"pc_night_percent": 44.4, "window_to_wall_south_percent": 33}))
    assert site.known == {"pc_night_percent": 44.4, "window_to_wall_south_percent": 33.0}
    assert site.theta_known() == {
        "floor_area_m2": AREA,
        "number_of_floors": 3.0,
        "pc_night_percent": 44.4,
        "window_to_wall_south_percent": 33.0,
    }
    assert load_site(_write(tmp_path / "plain")).known == {}
    # the building parameters this catalogue added can be declared too
    site = load_site(_write(tmp_path / "new", known={"plug_load_w_m2": 8.1, "lighting_power_w_m2": 6.9}))
    assert site.known == {"plug_load_w_m2": 8.1, "lighting_power_w_m2": 6.9}


def test_calibration_of_an_earlier_catalogue_is_read_in_this_ones_names(site_dir: Path):
    from buildenv.defaults import DEFAULT_THETA

    names = cat.EARLIER_CATALOGUES["bf68f6178dc1d1b3"].theta_names  # the catalogue of workstations
    theta = {n: 0.06 if n == "pc_density_per_m2" else DEFAULT_THETA[n] for n in names}
    save_calibration(site_dir, {"theta": theta, "occupancy": [[8.0, 18.0]] * 5, "loss": 0.5})
    theta = load_site(site_dir).calibration["theta"]
    assert theta["plug_load_w_m2"] == pytest.approx(150 * 0.06) and "pc_density_per_m2" not in theta
    assert theta["lighting_power_w_m2"] == 10.0 and theta["heat_recovery_effectiveness"] == 0.0
    assert theta["infiltration_ach"] == 0.3


def test_declared_effects_round_trip(tmp_path: Path):
    site = load_site(_write(tmp_path / "s", effects=("night_cycle_cold_air", "temperature_sensor_bias")))
    assert site.effects == ("night_cycle_cold_air", "temperature_sensor_bias")
    assert load_site(_write(tmp_path / "plain")).effects == ()


@pytest.mark.parametrize(
    "line, error",
    [
        ('effects = ["draughts"]', r"site\.toml:3: unknown effect 'draughts'"),
        ('effects = "heat_recovery"', r"site\.toml:3: 'effects' must be a list of effect names"),
        ('effects = ["heat_recovery", "heat_recovery"]', r"site\.toml:3: effect heat_recovery declared twice"),
        ('effects = ["holidays"]', r"site\.toml:3: effect 'holidays' cannot be declared"),
    ],
)
def test_declared_effect_errors_name_the_line(site_dir: Path, line: str, error: str):
    _toml(site_dir, GOOD_TOML.replace('weather = "usa_il_chicago"\n', 'weather = "usa_il_chicago"\n' + line + "\n"))
    with pytest.raises(SiteError, match=error):
        load_site(site_dir)


@pytest.mark.parametrize(
    "line, error",
    [
        ("floor_area_m2 = 5000", r"site\.toml:9: 'floor_area_m2' belongs in \[geometry\], not \[known\]"),
        (
            "pc_nite_percent = 40",
            r"site\.toml:9: unknown key 'pc_nite_percent' in \[known\] \(did you mean "
            r"'pc_night_percent'\?\)",
        ),
        ('pc_night_percent = "40 %"', r"site\.toml:9: pc_night_percent must be a number \(%\), got '40 %'"),
        (
            "heating_power_w_m2 = 400",
            r"site\.toml:9: heating_power_w_m2=400 is outside its range " + _range("heating_power_w_m2"),
        ),
        (
            "pc_density_per_m2 = 0.05",
            r"site\.toml:9: 'pc_density_per_m2' is now 'plug_load_w_m2' \(W/m2, 150 x the old value\); rename it",
        ),
    ],
)
def test_known_parameter_errors_name_the_line(site_dir: Path, line: str, error: str):
    _toml(site_dir, GOOD_TOML + "\n[known]\n" + line + "\n")
    with pytest.raises(SiteError, match=error):
        load_site(site_dir)


def test_meters_round_trip_and_default_to_heating_lighting_and_plug_loads(tmp_path: Path):
    site = load_site(_write(tmp_path / "s", consumption_end_uses=("heating", "cooling", "lighting", "plug_loads")))
    assert site.consumption_end_uses == ("heating", "cooling", "lighting", "plug_loads")
    assert site.consumption_outputs() == ("Q_AC_OFFICE", "Q_HEAT_OFFICE", "Q_EQP", "Q_LIGHT", "Q_AHU_C", "Q_AHU_H")
    assert "[meters]" in (tmp_path / "s" / "site.toml").read_text()
    plain = _write(tmp_path / "plain")
    assert "[meters]" not in (plain / "site.toml").read_text()  # the default is not written
    assert load_site(plain).consumption_end_uses == ("heating", "lighting", "plug_loads")
    assert load_site(plain).consumption_outputs() == cat.consumption_outputs(cat.DEFAULT_END_USES)
    assert set(cat.consumption_outputs(cat.DEFAULT_END_USES)) == set(cat.HEAT_CONSUMPTION_OUTPUTS)
    _toml(plain, GOOD_TOML + '\n[meters]\nconsumption = ["cooling"]\n')
    assert load_site(plain).consumption_outputs() == ("Q_AC_OFFICE", "Q_AHU_C")


@pytest.mark.parametrize(
    "line, error",
    [
        (
            'consumption = ["heating", "chilled_water"]',
            r"site\.toml:9: \[meters\] consumption: unknown end use 'chilled_water'; allowed: heating, cooling, "
            r"lighting, plug_loads$",
        ),
        ('consumption = ["lightning"]', r"site\.toml:9: .*unknown end use 'lightning' \(did you mean 'lighting'\?\)"),
        ('consumption = ["heating", "fans"]', r"site\.toml:9: \[meters\] consumption: 'fans': the model has no fan"),
        ("consumption = []", r"site\.toml:9: \[meters\] consumption: must be a non-empty list of end uses"),
        ('consumption = "heating"', r"site\.toml:9: \[meters\] consumption: must be a non-empty list"),
        ('consumption = ["heating", "heating"]', r"site\.toml:9: \[meters\] consumption: 'heating' given twice"),
        ('electricity = ["lighting"]', r"site\.toml:9: \[meters\] electricity: lighting also in consumption; a meter"),
        ('gas = ["heating"]', r"site\.toml:9: unknown key 'gas' in \[meters\]"),
    ],
)
def test_meter_errors_name_the_line(site_dir: Path, line: str, error: str):
    _toml(site_dir, GOOD_TOML + "\n[meters]\n" + line + "\n")
    with pytest.raises(SiteError, match=error):
        load_site(site_dir)


def test_heat_and_electricity_metered_apart_round_trip_and_name_their_outputs(tmp_path: Path):
    arrays = _arrays()
    electricity = np.round(5 + 10 * np.random.default_rng(1).random((WEEKS, 168)), 4)
    electricity[0, 3] = np.nan
    folder = _write(
        tmp_path / "s",
        consumption_end_uses=("heating",),
        electricity_kwh=electricity,
        electricity_end_uses=("lighting", "plug_loads"),
        **arrays,
    )
    assert _lines(folder / "measurements.csv")[0].endswith(",heat_consumption_kwh,electricity_kwh")
    site = load_site(folder)
    np.testing.assert_array_equal(site.electricity_kwh, electricity)
    np.testing.assert_array_equal(site.consumption_kwh, arrays["consumption_kwh"])
    assert site.electricity_end_uses == ("lighting", "plug_loads")
    (heat, q, heat_outputs), (column, e, outputs) = site.meters()
    assert (heat, column) == ("heat_consumption_kwh", "electricity_kwh")
    assert heat_outputs == ("Q_HEAT_OFFICE", "Q_AHU_H") and outputs == ("Q_EQP", "Q_LIGHT")
    np.testing.assert_allclose(e, electricity * 1000 / AREA)
    assert [m[0] for m in load_site(_write(tmp_path / "one")).meters()] == ["heat_consumption_kwh"]
    with pytest.raises(SiteError, match="give electricity_kwh and electricity_end_uses together"):
        _write(tmp_path / "half", electricity_kwh=electricity)


def test_a_second_meter_without_its_declaration_or_in_another_unit_is_named(tmp_path: Path):
    folder = _write(
        tmp_path / "s",
        consumption_end_uses=("heating",),
        electricity_kwh=np.full((WEEKS, 168), 9.0),
        electricity_end_uses=("lighting", "plug_loads"),
    )
    text = (folder / "site.toml").read_text()
    (folder / "site.toml").write_text(text.replace('electricity = [\n    "lighting",\n    "plug_loads",\n]\n', ""))
    with pytest.raises(
        SiteError, match=r"measurements\.csv:1: a column electricity_kwh, but site\.toml has no \[meters\] el"
    ):
        load_site(folder)
    (folder / "site.toml").write_text(text)
    _edit(
        folder / "measurements.csv", lambda lines: [lines[0].replace("electricity_kwh", "electricity_wh")] + lines[1:]
    )
    with pytest.raises(SiteError, match=r"measurements\.csv:1: wrong unit: column 'electricity_wh' is in Wh"):
        load_site(folder)
    _edit(
        folder / "measurements.csv", lambda lines: [lines[0].replace("electricity_wh", "electricity_kwh")] + lines[1:]
    )
    _set_line(folder / "measurements.csv", 5, _stamp(3) + ",21.0,20.0,-1")
    with pytest.raises(SiteError, match=r"measurements\.csv:5: electricity_kwh=-1 is negative"):
        load_site(folder)


def test_bms_round_trips_and_defaults_to_all_settings_in_their_catalogue_ranges(tmp_path: Path):
    plain = _write(tmp_path / "plain")
    assert "[bms" not in (plain / "site.toml").read_text()  # the default is not written
    site = load_site(plain)
    assert site.controllable == cat.SETTING_NAMES and site.setting_limits == {}
    lo, hi = site.setting_ranges()
    np.testing.assert_array_equal(lo, cat.bounds("settings")[0])
    np.testing.assert_array_equal(hi, cat.bounds("settings")[1])

    arrays = _arrays()
    vent = cat.SETTING_NAMES.index("ventilation_ach")
    assert arrays["settings"][..., vent].max() > 0.4  # the history may leave the limits
    limited = _write(
        tmp_path / "s",
        **arrays,
        controllable=("ventilation_ach", "heating_comfort_c", "heating_setback_c"),  # not catalogue order
        setting_limits={"ventilation_ach": (0.1, 0.4), "heating_setback_c": (18, 18)},
    )
    site = load_site(limited)
    assert site.controllable == ("heating_setback_c", "heating_comfort_c", "ventilation_ach")  # catalogue order
    assert site.setting_limits == {"ventilation_ach": (0.1, 0.4), "heating_setback_c": (18.0, 18.0)}
    np.testing.assert_allclose(site.settings, arrays["settings"])
    lo, hi = site.setting_ranges()
    assert lo.shape == hi.shape == (len(cat.SETTINGS),)
    assert (lo[vent], hi[vent]) == (0.1, 0.4)
    setback = cat.SETTING_NAMES.index("heating_setback_c")
    assert lo[setback] == hi[setback] == 18.0
    others = [i for i in range(len(cat.SETTINGS)) if i not in (vent, setback)]
    np.testing.assert_array_equal(lo[others], cat.bounds("settings")[0][others])
    np.testing.assert_array_equal(hi[others], cat.bounds("settings")[1][others])

    # limits as an inline table of [bms] read the same
    _toml(limited, GOOD_TOML + '\n[bms]\ncontrollable = ["ventilation_ach"]\nlimits = { ventilation_ach = [0.4, 1] }\n')
    site = load_site(limited)
    assert site.controllable == ("ventilation_ach",) and site.setting_limits == {"ventilation_ach": (0.4, 1.0)}
    _toml(limited, GOOD_TOML + "\n[bms.limits]\nsupply_air_c = [19, 21]\n")  # all controllable, one limited
    site = load_site(limited)
    assert site.controllable == cat.SETTING_NAMES and site.setting_limits == {"supply_air_c": (19.0, 21.0)}


@pytest.mark.parametrize(
    "lines, error",
    [
        (
            'controllable = ["heating_comfort", "ventilation_ach"]',
            r"site\.toml:9: \[bms\] controllable: unknown setting 'heating_comfort' \(did you mean "
            r"'heating_comfort_c'\?\)",
        ),
        (
            'controllable = ["ventilation_ach", "ventilation_ach"]',
            r"site\.toml:9: \[bms\] controllable: 'ventilation_ach' given twice",
        ),
        ("controllable = []", r"site\.toml:9: \[bms\] controllable: empty list"),
        ('controllable = "ventilation_ach"', r"site\.toml:9: \[bms\] controllable: must be a list of setting names"),
        (
            'controllable = ["heating_comfort_c"]\nlimits = { ventilation_ach = [0.1, 0.7] }',
            r"site\.toml:10: \[bms\] limits: 'ventilation_ach' is not in \[bms\] controllable",
        ),
        (
            "limits = { ventilation_ach = [0.1, 2.0] }",
            r"site\.toml:9: \[bms\] limits: ventilation_ach limits \[0\.1, 2\] leave the catalogue range "
            r"\[0\.1, 1\.7\] 1/h",
        ),
        (
            'controllable = ["heating_comfort_c"]\n\n[bms.limits]\nheating_comfort_c = [21, 23]',
            r"site\.toml:12: \[bms\] limits: heating_comfort_c limits \[21, 23\] leave the catalogue range",
        ),
        (
            "limits.heating_comfort_c = [23.5, 22.5]",
            r"site\.toml:9: \[bms\] limits: heating_comfort_c limits \[23\.5, 22\.5\]: min is above max",
        ),
        ("limits = { ventilation_ach = 0.7 }", r"site\.toml:9: \[bms\] limits: ventilation_ach must be a list"),
        (
            'limits = { ventilation_ach = [0.1, "0.7"] }',
            r"site\.toml:9: \[bms\] limits: ventilation_ach must be a list \[min, max\] of two numbers",
        ),
        ("limits = { ventilation_ach = [0.1, 0.4, 0.7] }", r"site\.toml:9: .*must be a list \[min, max\] of two"),
        (
            "limits = { ventilation_ac = [0.1, 0.7] }",
            r"site\.toml:9: \[bms\] limits: unknown setting 'ventilation_ac' \(did you mean 'ventilation_ach'\?\)",
        ),
        ("limits = [0.1, 0.7]", r"site\.toml:9: \[bms\] limits must be a table"),
        ('controlable = ["ventilation_ach"]', r"site\.toml:9: unknown key 'controlable' in \[bms\] \(did you mean"),
    ],
)
def test_bms_errors_name_the_line(site_dir: Path, lines: str, error: str):
    _toml(site_dir, GOOD_TOML + "\n[bms]\n" + lines + "\n")
    with pytest.raises(SiteError, match=error):
        load_site(site_dir)


def test_missing_keys(site_dir: Path):
    _toml(site_dir, GOOD_TOML.replace('weather = "usa_il_chicago"\n', ""))
    with pytest.raises(SiteError, match=r"site\.toml: missing 'weather'"):
        load_site(site_dir)
    _toml(site_dir, GOOD_TOML.replace("number_of_floors = 3\n", ""))
    with pytest.raises(SiteError, match=r"missing 'number_of_floors'"):
        load_site(site_dir)


def test_floor_area_outside_catalogue_range(site_dir: Path):
    small = cat.get("floor_area_m2").min - 100
    _toml(site_dir, GOOD_TOML.replace("4982", f"{small:g}"))
    with pytest.raises(
        SiteError, match=rf"site\.toml:5: floor_area_m2={small:g} is outside its range " + _range("floor_area_m2")
    ):
        load_site(site_dir)


def test_floor_area_is_not_rounded_to_the_step(site_dir: Path):
    _toml(site_dir, GOOD_TOML.replace("4982", "4982.5"))
    assert load_site(site_dir).floor_area_m2 == 4982.5


def test_number_of_floors_must_be_whole_and_in_range(site_dir: Path):
    _toml(site_dir, GOOD_TOML.replace("number_of_floors = 3", "number_of_floors = 2.5"))
    with pytest.raises(SiteError, match=r"site\.toml:6: number_of_floors must be a whole number"):
        load_site(site_dir)
    _toml(site_dir, GOOD_TOML.replace("number_of_floors = 3", "number_of_floors = 40"))
    with pytest.raises(SiteError, match=r"site\.toml:6: number_of_floors=40 is outside its range"):
        load_site(site_dir)


def test_invalid_toml(site_dir: Path):
    _toml(site_dir, GOOD_TOML + "oops = \n")
    with pytest.raises(SiteError, match=r"site\.toml:7: invalid TOML"):
        load_site(site_dir)


def test_unknown_weather(site_dir: Path):
    _toml(site_dir, GOOD_TOML.replace("usa_il_chicago", "mars_base"))
    with pytest.raises(SiteError, match=r"site\.toml:2: weather 'mars_base' is neither.*usa_il_chicago"):
        load_site(site_dir)


def test_weather_path_is_relative_to_the_site_folder(site_dir: Path):
    (site_dir / "local.epw").write_text("not read by load_site")
    _toml(site_dir, GOOD_TOML.replace("usa_il_chicago", "local.epw"))
    assert load_site(site_dir).weather == str((site_dir / "local.epw").resolve())


def test_custom_file_names_and_missing_file(site_dir: Path):
    (site_dir / "measurements.csv").rename(site_dir / "bms.csv")
    _toml(site_dir, GOOD_TOML.replace('name = "x"', 'name = "x"\nmeasurements = "bms.csv"'))
    assert load_site(site_dir).weeks == WEEKS
    _toml(site_dir, GOOD_TOML)
    with pytest.raises(SiteError, match=r"site\.toml: measurements file not found: .*measurements\.csv"):
        load_site(site_dir)


# --------------------------------------------------------------------------- measurements.csv
def _meas(site_dir: Path) -> Path:
    return site_dir / "measurements.csv"


def test_wrong_header(site_dir: Path):
    _set_line(_meas(site_dir), 1, "time,temperature,energy")
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:1: header is 'time,temperature,energy', expected "
        r"the columns 'timestamp,indoor_temperature_c,heat_consumption_kwh'",
    ):
        load_site(site_dir)


def test_missing_header(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: lines[1:])
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:1: missing header: the first line must be "
        r"timestamp,indoor_temperature_c,heat_consumption_kwh",
    ):
        load_site(site_dir)


def test_semicolon_separator_is_named(site_dir: Path):
    _set_line(_meas(site_dir), 1, "timestamp;indoor_temperature_c;heat_consumption_kwh")
    with pytest.raises(SiteError, match=r"measurements\.csv:1: .*separated by commas, this file uses ';'"):
        load_site(site_dir)


@pytest.mark.parametrize(
    ("column", "unit"),
    [
        ("indoor_temperature_f", "degF"),
        ("indoor_temperature_k", "K"),
        ("heat_consumption_wh", "Wh"),
        ("heat_consumption_mj", "MJ"),
    ],
)
def test_header_in_wrong_unit(site_dir: Path, column: str, unit: str):
    header = ["timestamp", "indoor_temperature_c", "heat_consumption_kwh"]
    header[1 if column.startswith("indoor") else 2] = column
    _set_line(_meas(site_dir), 1, ",".join(header))
    with pytest.raises(
        SiteError,
        match=rf"measurements\.csv:1: wrong unit: column '{column}' is in {unit}; "
        r"expected (indoor_temperature_c \(degC\)|heat_consumption_kwh \(kWh\))",
    ):
        load_site(site_dir)


def test_empty_file_and_header_only(site_dir: Path):
    _meas(site_dir).write_text("")
    with pytest.raises(SiteError, match=r"measurements\.csv:1: empty file"):
        load_site(site_dir)
    _meas(site_dir).write_text("timestamp,indoor_temperature_c,heat_consumption_kwh\n")
    with pytest.raises(SiteError, match=r"measurements\.csv:2: no data rows"):
        load_site(site_dir)


@pytest.mark.parametrize(
    "text", ["2024/01/01 04:00", "01.01.2024 04:00", "2024-01-01", "yesterday", "2024-13-01 04:00"]
)
def test_unparsable_timestamp(site_dir: Path, text: str):
    _set_line(_meas(site_dir), 6, f"{text},21,50")
    with pytest.raises(SiteError, match=r"measurements\.csv:6: cannot read timestamp"):
        load_site(site_dir)


def test_timestamp_with_utc_offset(site_dir: Path):
    _set_line(_meas(site_dir), 6, "2024-01-01T04:00+01:00,21,50")
    with pytest.raises(SiteError, match=r"measurements\.csv:6: .*UTC offset"):
        load_site(site_dir)


def test_t_separator_is_accepted(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: [lines[0]] + [ln.replace(" ", "T", 1) for ln in lines[1:]])
    assert load_site(site_dir).weeks == WEEKS


def test_timestamp_not_on_the_hour(site_dir: Path):
    _set_line(_meas(site_dir), 6, "2024-01-01 04:30,21,50")
    with pytest.raises(SiteError, match=r"measurements\.csv:6: timestamp '2024-01-01 04:30' is not on the hour"):
        load_site(site_dir)


def test_duplicate_timestamp(site_dir: Path):
    _set_line(_meas(site_dir), 7, f"{_stamp(4)},21,50")  # line 7 would be hour 5; line 6 is hour 4
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:7: duplicate timestamp 2024-01-01 04:00 "
        r"\(also on line 6\): remove one$",  # a Monday in January: no clock went back, no time zone to declare
    ):
        load_site(site_dir)


def test_non_monotonic_timestamp(site_dir: Path):
    def swap(lines):
        lines[5], lines[6] = lines[6], lines[5]  # lines 6 and 7
        return lines

    _edit(_meas(site_dir), swap)
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:7: timestamp 2024-01-01 04:00 is earlier than the "
        r"previous row's 2024-01-01 05:00 \(line 6\)",
    ):
        load_site(site_dir)


@pytest.mark.parametrize(
    ("cells", "column"),
    [("abc,50", "indoor_temperature_c"), ("21,12;5", "heat_consumption_kwh"), ("21,inf", "heat_consumption_kwh")],
)
def test_non_numeric_value(site_dir: Path, cells: str, column: str):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},{cells}")
    with pytest.raises(SiteError, match=rf"measurements\.csv:10: {column}: .* not a (finite )?number"):
        load_site(site_dir)


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("21,50,7", "too many columns: 4 instead of 3"),
        ("21", "too few columns: 2 instead of 3"),
    ],
)
def test_wrong_number_of_columns(site_dir: Path, row: str, message: str):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},{row}")
    with pytest.raises(SiteError, match=rf"measurements\.csv:10: {message}"):
        load_site(site_dir)


@pytest.mark.parametrize(
    ("value", "hint"),
    [
        ("72.5", "looks like degF"),
        ("294.1", "looks like K"),
        ("-35", "fix the unit"),
        ("55", "looks like degF"),
    ],
)
def test_impossible_temperature(site_dir: Path, value: str, hint: str):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},{value},50")
    with pytest.raises(
        SiteError,
        match=rf"measurements\.csv:10: indoor_temperature_c={value} is outside "
        rf"\[-20, 50\] degC.*{hint}",
    ):
        load_site(site_dir)


def test_temperature_at_the_limits_is_accepted(site_dir: Path):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},-20,50")
    _set_line(_meas(site_dir), 11, f"{_stamp(9)},50,50")
    assert load_site(site_dir).temperature_c[0, 9] == 50


def test_negative_consumption(site_dir: Path):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},21,-0.5")
    with pytest.raises(SiteError, match=r"measurements\.csv:10: heat_consumption_kwh=-0.5 is negative"):
        load_site(site_dir)


def test_consumption_above_one_kwh_per_m2(site_dir: Path):
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},21,60000")  # 60 kWh written in Wh
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:10: heat_consumption_kwh=60000 is above 1 kWh/m2 in "
        r"one hour \(4982 kWh for 4982 m2\); looks like Wh",
    ):
        load_site(site_dir)
    _set_line(_meas(site_dir), 10, f"{_stamp(8)},21,9e9")
    with pytest.raises(SiteError, match=r"measurements\.csv:10: .*is above 1 kWh/m2") as info:
        load_site(site_dir)
    assert "looks like Wh" not in str(info.value)


def test_first_timestamp_must_be_monday_midnight(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: [lines[0]] + lines[2:])  # starts Monday 01:00
    with pytest.raises(
        SiteError,
        match=r"measurements\.csv:2: the first timestamp 2024-01-01 01:00 is a "
        r"Monday at 01:00: data must start on a Monday at 00:00",
    ):
        load_site(site_dir)
    _edit(_meas(site_dir), lambda lines: [lines[0]] + lines[24:])  # starts Tuesday 00:00
    with pytest.raises(SiteError, match=r"measurements\.csv:2: the first timestamp 2024-01-02 00:00 is a Tuesday"):
        load_site(site_dir)


def test_data_must_cover_whole_weeks(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: lines[:-1])  # stops Sunday 22:00
    n = len(_lines(_meas(site_dir)))
    with pytest.raises(
        SiteError,
        match=rf"measurements\.csv:{n}: the data end at Sunday 2024-01-14 22:00: they "
        r"must cover whole weeks.*add rows up to 2024-01-14 23:00",
    ):
        load_site(site_dir)
    _edit(_meas(site_dir), lambda lines: lines[: 1 + 168 + 30])  # stops in week 2
    with pytest.raises(SiteError, match=r"measurements\.csv:199: the data end at Tuesday 2024-01-09 05:00"):
        load_site(site_dir)


def test_first_week_only_is_one_week_and_needs_fewer_settings(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: lines[: 1 + 168])
    _edit(site_dir / "settings.csv", lambda lines: lines[: 1 + 7])
    assert load_site(site_dir).weeks == 1


def test_not_utf8(site_dir: Path):
    _meas(site_dir).write_bytes("timestamp,indoor_temperature_c,heat_consumption_kwh\n\xe9".encode("latin-1"))
    with pytest.raises(SiteError, match=r"measurements\.csv: not UTF-8"):
        load_site(site_dir)


# --------------------------------------------------------------------------- gaps
def test_gaps_become_nan_and_masked_and_nothing_else_changes(tmp_path: Path):
    full = load_site(_write(tmp_path / "full"))
    gappy_dir = _write(tmp_path / "gappy")
    missing_rows = set(range(30, 40)) | {167, 168} | set(range(200, 230))  # hours (row = hour + 2)
    empty_t = {5, 250}
    nan_q = {6, 251, 300}

    def edit(lines):
        out = [lines[0]]
        for hour, line in enumerate(lines[1:]):
            if hour in missing_rows:
                continue
            stamp, t, q = line.split(",")
            if hour in empty_t:
                t = ""
            if hour in nan_q:
                q = "NaN" if hour != 300 else "nan"
            out.append(",".join([stamp, t, q]))
        return out

    _edit(gappy_dir / "measurements.csv", edit)
    gappy = load_site(gappy_dir)

    t_gap = np.zeros(WEEKS * 168, bool)
    q_gap = np.zeros(WEEKS * 168, bool)
    t_gap[list(missing_rows | empty_t)] = True
    q_gap[list(missing_rows | nan_q)] = True
    t_gap, q_gap = t_gap.reshape(WEEKS, 168), q_gap.reshape(WEEKS, 168)

    assert gappy.weeks == full.weeks and gappy.start == full.start
    np.testing.assert_array_equal(gappy.temperature_mask, ~t_gap)
    np.testing.assert_array_equal(gappy.consumption_mask, ~q_gap)
    assert np.isnan(gappy.temperature_c[t_gap]).all() and np.isnan(gappy.consumption_kwh[q_gap]).all()
    np.testing.assert_array_equal(gappy.temperature_c[~t_gap], full.temperature_c[~t_gap])
    np.testing.assert_array_equal(gappy.consumption_kwh[~q_gap], full.consumption_kwh[~q_gap])
    np.testing.assert_array_equal(gappy.settings, full.settings)


def test_last_week_may_have_gaps_up_to_sunday_2300(site_dir: Path):
    _edit(_meas(site_dir), lambda lines: lines[: 1 + 170] + lines[-1:])  # week 2: Mon 00-01 then Sun 23:00 only
    site = load_site(site_dir)
    assert site.weeks == 2
    assert site.temperature_mask[1].sum() == 3 and site.temperature_mask[1, [0, 1, 167]].all()


def test_gap_of_a_whole_week_is_allowed(tmp_path: Path):
    site_dir = _write(tmp_path / "s", **_arrays(weeks=3))
    _edit(_meas(site_dir), lambda lines: lines[: 1 + 168] + lines[1 + 336 :])
    site = load_site(site_dir)
    assert site.weeks == 3 and not site.temperature_mask[1].any() and site.temperature_mask[[0, 2]].all()


# --------------------------------------------------------------------------- settings.csv
def _settings(site_dir: Path) -> Path:
    return site_dir / "settings.csv"


def _set_cell(path: Path, line: int, column: str, value: str) -> None:
    cells = _cells(path, line)
    cells[("date", *cat.SETTING_NAMES).index(column)] = value
    _set_line(path, line, ",".join(cells))


def test_settings_header(site_dir: Path):
    header = _cells(_settings(site_dir), 1)
    header[8] = "heating_comfrt_c"
    _set_line(_settings(site_dir), 1, ",".join(header))
    with pytest.raises(
        SiteError,
        match=r"settings\.csv:1: wrong header \(missing heating_comfort_c; unknown "
        r"'heating_comfrt_c' \(did you mean 'heating_comfort_c'\?\)\); expected "
        r"date,cooling_start_hour,",
    ):
        load_site(site_dir)
    header[8], header[9] = "ventilation_start_hour", "heating_comfort_c"
    _set_line(_settings(site_dir), 1, ",".join(header))
    with pytest.raises(SiteError, match=r"settings\.csv:1: wrong header \(columns in the wrong order\)"):
        load_site(site_dir)


def test_settings_value_out_of_range_names_the_variable(site_dir: Path):
    _set_cell(_settings(site_dir), 4, "heating_comfort_c", "30")
    with pytest.raises(
        SiteError,
        match=r"settings\.csv:4: heating_comfort_c=30 is outside its range " + _range("heating_comfort_c"),
    ):
        load_site(site_dir)


def test_settings_off_grid_value_is_kept(site_dir: Path):
    _set_cell(_settings(site_dir), 4, "heating_comfort_c", "22.37")
    assert load_site(site_dir).settings[0, 2, cat.SETTING_NAMES.index("heating_comfort_c")] == 22.37


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("", "heating_setback_c is missing"),
        ("NaN", "heating_setback_c is missing"),
        ("warm", "heating_setback_c: 'warm' is not a number"),
    ],
)
def test_settings_missing_or_non_numeric(site_dir: Path, value: str, message: str):
    _set_cell(_settings(site_dir), 3, "heating_setback_c", value)
    with pytest.raises(SiteError, match=rf"settings\.csv:3: {message}"):
        load_site(site_dir)


def test_settings_must_start_on_the_first_monday(site_dir: Path):
    _set_cell(_settings(site_dir), 2, "date", "2023-12-31")
    with pytest.raises(
        SiteError,
        match=r"settings\.csv:2: date 2023-12-31 should be 2024-01-01 \(the first "
        r"measured Monday\)",
    ):
        load_site(site_dir)


def test_settings_dates_must_be_consecutive(site_dir: Path):
    original = _settings(site_dir).read_text()
    _edit(_settings(site_dir), lambda lines: lines[:3] + lines[4:])  # drop 2024-01-03 (line 4)
    with pytest.raises(SiteError, match=r"settings\.csv:4: date 2024-01-04 should be 2024-01-03 \(the day after"):
        load_site(site_dir)
    _settings(site_dir).write_text(original)
    _set_cell(_settings(site_dir), 5, "date", "04/01/2024")
    with pytest.raises(SiteError, match=r"settings\.csv:5: cannot read date '04/01/2024'"):
        load_site(site_dir)


def test_settings_must_cover_exactly_the_measured_days(site_dir: Path):
    lines = _lines(_settings(site_dir))
    _settings(site_dir).write_text("\n".join(lines[:-2]) + "\n")
    with pytest.raises(
        SiteError,
        match=r"settings\.csv:13: the settings end on 2024-01-12, but the measurements "
        r"run to Sunday 2024-01-14: expected 14 rows",
    ):
        load_site(site_dir)
    extra = lines[-1].replace("2024-01-14", "2024-01-15")
    _settings(site_dir).write_text("\n".join([*lines, extra]) + "\n")
    with pytest.raises(SiteError, match=r"settings\.csv:16: one row too many"):
        load_site(site_dir)


def test_settings_row_width(site_dir: Path):
    _set_line(_settings(site_dir), 3, ",".join(_cells(_settings(site_dir), 3)[:-1]))
    with pytest.raises(SiteError, match=r"settings\.csv:3: too few columns: 13 instead of 14"):
        load_site(site_dir)


def test_settings_without_hvac_operating_operate_every_day(site_dir: Path):
    path = _settings(site_dir)
    _edit(path, lambda lines: [line.rsplit(",", 1)[0] for line in lines])
    site = load_site(site_dir)
    assert site.settings.shape == (WEEKS, 7, 13) and np.all(site.settings[..., -1] == 1)


def test_hvac_operating_is_one_or_zero(site_dir: Path):
    path = _settings(site_dir)
    _set_line(path, 4, ",".join([*_cells(path, 4)[:-1], "0.5"]))
    with pytest.raises(SiteError, match=r"settings\.csv:4: hvac_operating=0\.5: write 1 .* or 0"):
        load_site(site_dir)


# --------------------------------------------------------------------------- json files
@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda c: c.pop("theta"), r"'theta' is missing or not an object"),
        (lambda c: c["theta"].pop("roof_insulation_m"), r"theta has no 'roof_insulation_m'"),
        (lambda c: c["theta"].update(roof_insulation_m="0.1"), r"theta 'roof_insulation_m' is '0\.1', not a finite"),
        (lambda c: c["theta"].update(roof_insulation_m=None), r"theta 'roof_insulation_m' is None, not a finite"),
        (lambda c: c.update(occupancy=[[8, 18]] * 7), r"'occupancy' must be 5 pairs of hours"),
        (lambda c: c.update(occupancy=[[8, 18]] * 4 + [[8]]), r"'occupancy' must be 5 pairs of hours"),
        (lambda c: c.update(heldout=[1, 2]), r"'heldout' is list, not an object"),
        (lambda c: c["theta"].update(plug_load_w_m2=500.0), r"theta: plug_load_w_m2=500 is outside its range"),
        (lambda c: c["occupancy"].__setitem__(4, [8.0, 2.0]), r"occupancy of friday: occupancy_end_hour=2 is outside"),
    ],
)
def test_a_damaged_calibration_is_named_in_one_line(site_dir: Path, edit, message):
    from buildenv.defaults import DEFAULT_THETA

    calibration = {"theta": dict(DEFAULT_THETA), "occupancy": [[8.0, 18.0]] * 5, "fit": {}, "heldout": {}}
    edit(calibration)
    (site_dir / "calibration.json").write_text(json.dumps(calibration))
    with pytest.raises(SiteError, match=r"calibration\.json: " + message) as caught:
        load_site(site_dir)
    assert "\n" not in str(caught.value) and "buildenv calibrate --site" in str(caught.value)


def test_a_whole_calibration_loads(site_dir: Path):
    from buildenv.defaults import DEFAULT_THETA

    calibration = {"theta": dict(DEFAULT_THETA), "occupancy": [[8.0, 18.0]] * 5}
    (site_dir / "calibration.json").write_text(json.dumps(calibration))
    assert load_site(site_dir).calibration["theta"] == pytest.approx(DEFAULT_THETA)


def test_invalid_truth_json(site_dir: Path):
    (site_dir / "truth.json").write_text('{\n  "a": 1,\n}\n')
    with pytest.raises(SiteError, match=r"truth\.json:3: invalid JSON"):
        load_site(site_dir)
    (site_dir / "truth.json").write_text("[1, 2]")
    with pytest.raises(SiteError, match=r"truth\.json:1: expected a JSON object"):
        load_site(site_dir)


# --------------------------------------------------------------------------- EPW hours
def _bare_site(start: dt.date, weeks: int = 1, weather: str = "usa_il_chicago") -> Site:
    nan = np.full((weeks, 168), np.nan)
    return Site(
        path=Path("."),
        name="x",
        weather=weather,
        start=start,
        floor_area_m2=AREA,
        number_of_floors=3,
        settings=np.zeros((weeks, 7, 12)),
        temperature_c=nan,
        consumption_kwh=nan.copy(),
    )


def test_start_hour_of_year():
    assert _bare_site(dt.date(2024, 1, 1)).start_hour_of_year(0) == 0
    # non-leap year: Monday 2023-03-06 is day 64
    assert _bare_site(dt.date(2023, 3, 6)).start_hour_of_year(0) == 64 * 24
    # leap year, after Feb 28: Monday 2024-03-04 is day 63 of 2024 but day 62 (Mar 4) of the 365-day EPW year
    leap = _bare_site(dt.date(2024, 2, 26), weeks=2)
    assert leap.start_hour_of_year(0) == 56 * 24  # Feb 26, before the leap day: unshifted
    assert leap.start_hour_of_year(1) == 62 * 24 == (dt.date(2023, 3, 4) - dt.date(2023, 1, 1)).days * 24
    # last Monday of a leap year: Dec 30, 2024 -> the EPW's Dec 30
    assert _bare_site(dt.date(2024, 12, 30)).start_hour_of_year(0) == 363 * 24
    with pytest.raises(SiteError, match="out of range"):
        leap.start_hour_of_year(2)


def test_epw_hours_leap_day_and_year_wrap():
    leap = _bare_site(dt.date(2024, 2, 26)).epw_hours()[0]
    feb28 = 58 * 24
    np.testing.assert_array_equal(leap[48:72], np.arange(feb28, feb28 + 24))  # Wed Feb 28
    np.testing.assert_array_equal(leap[72:96], np.arange(feb28, feb28 + 24))  # Thu Feb 29 -> Feb 28
    np.testing.assert_array_equal(leap[96:120], np.arange(59 * 24, 60 * 24))  # Fri Mar 1
    wrap = _bare_site(dt.date(2024, 12, 30)).epw_hours()[0]
    np.testing.assert_array_equal(wrap, np.concatenate([np.arange(363 * 24, 8760), np.arange(0, 120)]))


def test_weather_hours_shape_and_values():
    site = _bare_site(dt.date(2024, 12, 23), weeks=2)  # the second week runs into January
    hourly = np.asarray(load_weather("usa_il_chicago").hourly)
    weather = site.weather_hours()
    assert weather.shape == (2, 168, len(cat.WEATHER_NAMES))
    start = site.start_hour_of_year(0)
    np.testing.assert_array_equal(weather[0], hourly[start : start + 168])
    np.testing.assert_array_equal(weather[1, :48], hourly[8760 - 48 :])
    np.testing.assert_array_equal(weather[1, 48:], hourly[:120])
