"""The command line: catalogue and weather listings, argument errors (no EnergyPlus run)."""

from __future__ import annotations

import json
import shutil

import pytest

from buildenv import catalogue as cat
from buildenv.cli.main import build_parser, main


def test_catalogue_json(capsys):
    assert main(["catalogue", "--json"]) == 0
    out = capsys.readouterr().out
    data = json.loads(out)
    assert data["catalogue_hash"] == cat.catalogue_hash()
    assert len(data["variables"]) == len(cat.ALL_VARIABLES) == 57
    assert [v["name"] for v in data["variables"]] == [v.name for v in cat.ALL_VARIABLES]
    area = data["variables"][0]
    assert area["name"] == "floor_area_m2" and area["min"] == 300 and area["max"] == 50000 and area["step"] == 100


def test_catalogue_json_one_group(capsys):
    assert main(["catalogue", "--group", "occupancy", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [v["name"] for v in data["variables"]] == ["occupancy_start_hour", "occupancy_end_hour"]


def test_catalogue_table(capsys):
    assert main(["catalogue"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0] == f"catalogue {cat.catalogue_hash()}"
    assert len(lines) == 2 + len(cat.ALL_VARIABLES)
    row = next(line for line in lines if " ventilation_ach " in line)
    assert row.split() == ["settings", "ventilation_ach", "1/h", "0.1", "1.7", "0.05", "per_day", "vol_ventilation_day"]


def test_catalogue_unknown_group_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main(["catalogue", "--group", "nonsense"])
    assert info.value.code == 2
    assert "nonsense" in capsys.readouterr().err


def test_weather_lists_shipped_files(capsys):
    assert main(["weather"]) == 0
    out = capsys.readouterr().out
    names = [line.split()[0] for line in out.splitlines()]
    assert "usa_il_chicago" in names
    chicago_line = next(line for line in out.splitlines() if line.startswith("usa_il_chicago "))
    assert chicago_line.rstrip().lower().endswith(".epw")


def test_weather_summary(capsys):
    assert main(["weather", "usa_il_chicago"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["name"] == "usa_il_chicago"
    assert info["latitude_deg"] == pytest.approx(41.98, abs=0.2)
    assert 5 < info["tamb_mean_c"] < 15
    assert info["tamb_min_c"] < -15 and info["tamb_max_c"] > 30
    assert 1000 < info["ghi_annual_kwh_m2"] < 1800


def test_weather_unknown_name(capsys):
    assert main(["weather", "atlantis"]) == 2
    err = capsys.readouterr().err
    assert "buildenv weather: error" in err and "'atlantis'" in err


def test_week_misspelled_variable_suggests(capsys, tmp_path):
    assert main(["week", "--set", "heating_comfrt_c=21", "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "did you mean" in err
    assert "heating_comfort_c" in err
    assert not (tmp_path / "w").exists()


def test_week_out_of_range_setting(capsys, tmp_path):
    assert main(["week", "--set", "heating_comfort_c=30", "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "heating_comfort_c=30" in err
    assert "[22, 24]" in err
    assert not (tmp_path / "w").exists()


def test_week_out_of_range_building_parameter(capsys, tmp_path):
    assert main(["week", "--set", "number_of_floors=40", "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "number_of_floors=40" in err and "[1, 15]" in err


def test_week_nan_setting(capsys, tmp_path):
    assert main(["week", "--set", "occupancy_end_hour=nan", "--out", str(tmp_path / "w")]) == 2
    assert "occupancy_end_hour=nan" in capsys.readouterr().err


@pytest.mark.parametrize(
    "item, message",
    [
        ("heating_comfort_c", "expected NAME=VALUE"),
        ("heating_comfort_c=warm", "is not a number"),
    ],
)
def test_week_malformed_assignment(capsys, tmp_path, item, message):
    assert main(["week", "--set", item, "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert message in err and item in err


def test_week_cannot_set_weather_or_outputs(capsys, tmp_path):
    assert main(["week", "--set", "TAMB=10", "--out", str(tmp_path / "w")]) == 2
    assert "TAMB" in capsys.readouterr().err


def test_week_out_of_year(capsys, tmp_path):
    assert main(["week", "--week", "60", "--out", str(tmp_path / "w")]) == 2
    assert "--week 60" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()


def test_simulate_unknown_epw(capsys, tmp_path):
    out = tmp_path / "ds"
    assert main(["simulate", "--weeks", "2", "--epw", "nowhere", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "'nowhere'" in err
    assert "buildenv simulate: error" in err
    assert not out.exists()  # the campaign is validated before the directory is created


def test_simulate_bad_weeks(capsys, tmp_path):
    out = tmp_path / "ds"
    assert main(["simulate", "--weeks", "0", "--epw", "usa_il_chicago", "--out", str(out)]) == 2
    assert "--weeks" in capsys.readouterr().err
    assert main(["simulate", "--weeks", "3", "--weeks-per-run", "60", "--out", str(out)]) == 2
    assert "--weeks-per-run" in capsys.readouterr().err
    assert not out.exists()


def test_parser_defaults_and_required():
    parser = build_parser()
    args = parser.parse_args(["week"])
    assert args.epw == "usa_il_chicago" and args.week == 2 and args.set == [] and not args.json
    args = parser.parse_args(["week", "--set", "a=1", "--set", "b=2"])
    assert args.set == ["a=1", "b=2"]
    args = parser.parse_args(["simulate", "--weeks", "4", "--out", "x", "--epw", "a", "b"])
    assert args.weeks == 4 and args.epw == ["a", "b"] and args.sampling == "uniform" and args.weeks_per_run == 52
    with pytest.raises(SystemExit):
        parser.parse_args(["simulate", "--out", "x"])  # --weeks is required
    with pytest.raises(SystemExit):
        parser.parse_args([])  # a subcommand is required
    with pytest.raises(SystemExit):
        parser.parse_args(["simulate", "--weeks", "2", "--out", "x", "--sampling", "sobol"])


@pytest.mark.parametrize(
    "item, error",
    [
        ("pc_night_percent", "expected NAME=VALUE"),
        ("pc_night=40", "unknown key 'pc_night' in [known] (did you mean 'pc_night_percent'?)"),
        ("pc_night_percent=lots", "pc_night_percent must be a number (%), got 'lots'"),
        ("number_of_floors=3", "'number_of_floors' belongs in [geometry], not [known]"),
    ],
)
def test_site_reference_rejects_a_bad_known_parameter_in_one_line(item, error, tmp_path, capsys):
    assert main(["site", "reference", "--known", item, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--known {item!r}: {error}" in err[0]
    assert not (tmp_path / "s").exists()  # refused before EnergyPlus ran


def test_known_parameters_parse_from_the_command_line():
    from buildenv.cli.sites import parse_known

    assert parse_known(["pc_night_percent=44.4", "occupant_density_per_m2=0.0538"]) == {
        "pc_night_percent": 44.4,
        "occupant_density_per_m2": 0.0538,
    }


def test_calibrate_models_the_sites_declared_effects_and_the_extra_ones_unless_told_not_to():
    from buildenv.cli.sites import declared_for_calibration
    from buildenv.env.building_week import DEFAULT_SITE
    from buildenv.sites import load_site

    site = load_site(DEFAULT_SITE)
    own = ("night_cycle_cold_air", "evening_departure", "temperature_sensor_bias")
    assert declared_for_calibration(site, []) == own
    assert declared_for_calibration(site, ["heat_recovery", "evening_departure"]) == (*own, "heat_recovery")
    assert declared_for_calibration(site, ["heat_recovery"], no_site_effects=True) == ("heat_recovery",)
    assert declared_for_calibration(site, [], no_site_effects=True) == ()


def test_site_show_lists_what_the_site_declares_known(tmp_path, capsys):
    from buildenv.env.building_week import DEFAULT_SITE

    shutil.copytree(DEFAULT_SITE, tmp_path / "s")
    with open(tmp_path / "s" / "site.toml", "a") as f:
        f.write("\n[known]\npc_night_percent = 44.4\n")
    assert main(["site", "show", str(tmp_path / "s")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["known"] == {"pc_night_percent": 44.4} and info["weeks"] == 6
    assert info["effects"] == ["night_cycle_cold_air", "evening_departure", "temperature_sensor_bias"]


@pytest.mark.parametrize(
    "item, error",
    [
        ("heating,fans", "'fans': the model has no fan output"),
        ("heating,heating", "'heating' given twice"),
        ("heating,steam", "unknown end use 'steam'; allowed: heating, cooling, lighting, plug_loads"),
        (",", "must be a non-empty list of end uses"),
    ],
)
def test_site_reference_rejects_a_bad_meter_in_one_line(item, error, tmp_path, capsys):
    assert main(["site", "reference", "--meter", item, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--meter {item!r}: {error}" in err[0]
    assert not (tmp_path / "s").exists()  # refused before EnergyPlus ran


def test_meter_parses_from_the_command_line_and_site_show_lists_it(tmp_path, capsys):
    from buildenv.cli.sites import parse_meter
    from buildenv.env.building_week import DEFAULT_SITE

    assert parse_meter(None) == ("heating", "lighting", "plug_loads")
    assert parse_meter("heating, cooling,lighting,plug_loads") == ("heating", "cooling", "lighting", "plug_loads")
    shutil.copytree(DEFAULT_SITE, tmp_path / "s")
    assert main(["site", "show", str(tmp_path / "s")]) == 0
    assert json.loads(capsys.readouterr().out)["meters"] == ["heating", "lighting", "plug_loads"]
