"""The suite: its matrix, its BMS histories, sites made by EnergyPlus and calibrated by the unchanged command."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

from agents.cli import _print_levers
from buildenv import catalogue as cat
from buildenv.calibration.calibrate import calibrate_site
from buildenv.calibration.problem import default_weeks
from buildenv.cli.main import main
from buildenv.energyplus.reference import STAND_IN_VERSION
from buildenv.env.levers import grouping, lever_actions, summarise_levers
from buildenv.env.response import (
    check_suite,
    error_drivers,
    first_heldout_week,
    response_check,
    split_error,
    summarise,
)
from buildenv.errors import BuildenvError
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site
from buildenv.sites.suite import (
    HELD_OUT_CLIMATES,
    SUITE_CLIMATES,
    SuiteCase,
    bms_history,
    make_case,
    read_manifest,
    reference_history,
    suite_cases,
    write_manifest,
)


def test_the_matrix_covers_every_office_climate_and_season_with_a_held_out_part():
    cases = suite_cases()
    assert len(cases) == 6 * len(SUITE_CLIMATES) * 2
    assert {c.part for c in cases if c.climate in HELD_OUT_CLIMATES} == {"held_out"}
    assert {c.part for c in cases if c.climate not in HELD_OUT_CLIMATES} == {"development"}
    assert all(c.start().weekday() == 0 for c in cases)
    assert len({c.seed() for c in cases}) == len(cases)
    with pytest.raises(BuildenvError, match="unknown suite climate usa_xx_nowhere"):
        suite_cases(climates=["usa_xx_nowhere"])


def test_bms_history_changes_setpoints_schedules_and_ventilation_within_the_catalogue():
    settings = bms_history(8, 1.0, np.random.default_rng(3))
    cat.check_values("settings", settings, "test")
    assert settings.shape == (8, 7, len(cat.SETTING_NAMES))
    assert (settings == settings[:, :1]).all()  # one program a week: every day the same

    def changed(*names):
        idx = [cat.SETTING_NAMES.index(n) for n in names]
        return bool((np.diff(settings[:, 0, idx], axis=0) != 0).any())

    assert changed("heating_comfort_c", "cooling_comfort_c")
    assert changed("heating_start_hour", "heating_end_hour", "cooling_start_hour", "cooling_end_hour")
    assert changed("ventilation_ach")
    np.testing.assert_array_equal(settings, bms_history(8, 1.0, np.random.default_rng(3)))


@pytest.mark.parametrize("weeks", [3, 4, 8])
def test_a_bms_history_changes_each_kind_of_setting_within_the_weeks_a_calibration_fits(weeks):
    """Whatever the draw, a default calibration (the first half of the weeks) sees a setpoint, a schedule and an
    outdoor air change: the response it is later asked to predict."""
    fit = len(default_weeks(weeks)[0])
    kinds = {
        "setpoint": ["heating_comfort_c", "cooling_comfort_c"],
        "schedule": ["heating_start_hour", "heating_end_hour", "cooling_start_hour", "cooling_end_hour"],
        "outdoor air": ["ventilation_ach"],
    }
    for seed in range(20):
        settings = bms_history(weeks, 1.0, np.random.default_rng(seed))[:fit, 0]
        for kind, names in kinds.items():
            idx = [cat.SETTING_NAMES.index(n) for n in names]
            assert (np.diff(settings[:, idx], axis=0) != 0).any(), f"seed {seed}: no {kind} change in the fit weeks"


def test_a_reference_offices_history_keeps_its_outdoor_air_within_its_bms_limits():
    j = cat.SETTING_NAMES.index("ventilation_ach")
    # the DOE medium office: from its design (0.7 1/h) down to its ASHRAE 62.1 minimum (0.45), not 0.3 lower
    medium = reference_history("medium_office", 8, np.random.default_rng(3))[:, 0, j]
    assert list(medium) == pytest.approx([0.7] * 2 + [0.45] * 6)  # lowered in the second half of the fit weeks
    # a 2019 office's design is its minimum: no outdoor air change; without limits the full change
    assert set(reference_history("medium_office_2019", 8, np.random.default_rng(3))[:, 0, j]) == {0.45}
    assert bms_history(8, 0.7, np.random.default_rng(3))[-1, 0, j] == pytest.approx(0.4)


def test_a_reference_offices_history_shuts_down_on_the_days_its_own_schedules_do():
    from buildenv.energyplus.reference import operating_days

    j = cat.SETTING_NAMES.index("hvac_operating")
    # the prototypes' HVAC availability: off on Sunday; the 2019 small office off all weekend
    assert operating_days("medium_office") == (1, 1, 1, 1, 1, 1, 0)
    assert operating_days("small_office_2019") == (1, 1, 1, 1, 1, 0, 0)
    history = reference_history("small_office_2019", 4, np.random.default_rng(0))
    assert (history[..., :5, j] == 1).all() and (history[..., 5:, j] == 0).all()
    assert (bms_history(4, 0.7, np.random.default_rng(0))[..., j] == 1).all()  # a generic history operates daily


def test_days_off_not_read_leave_every_day_operating_with_a_warning(tmp_path, caplog):
    from buildenv.energyplus.idf import format_idf, read_idf
    from buildenv.energyplus.reference import operating_days, reference_idf

    idf = tmp_path / "office.idf"
    objects = read_idf(reference_idf("small_office_2019"))
    idf.write_text(format_idf(objects))
    assert operating_days(idf) == (1, 1, 1, 1, 1, 0, 0)
    off = [
        o[:3] + ["Through: 12/31", "For: AllDays", "Until: 24:00", "0"] if o[1].lower() == "hvacoperationschd" else o
        for o in objects
    ]
    idf.write_text(format_idf(off))  # edited in place: read again, not from the cache
    with caplog.at_level("WARNING"):
        assert operating_days(idf) == (1,) * 7
    assert "office.idf: its HVAC availability is off all the week" in caplog.text


def test_a_case_is_made_reused_and_a_refused_one_leaves_nothing_behind(tmp_path):
    case = SuiteCase("medium_office", "usa_ca_san_francisco", "cooling")
    record = make_case(case, tmp_path, weeks=2)
    assert record["status"] == "made" and record["part"] == "development"
    site = load_site(record["site"])
    assert site.weeks == 2 and site.start == case.start()
    cooling_meter = ("heating", "cooling", "lighting", "plug_loads")  # a cooling-season site meters its cooling
    assert site.consumption_end_uses == cooling_meter and record["meters"] == list(cooling_meter)
    assert make_case(case, tmp_path, weeks=2)["status"] == "reused"
    # a site an earlier stand-in made (no version recorded) is made again with this one
    truth = json.loads((tmp_path / case.name / "truth.json").read_text())
    assert truth["stand_in"] == STAND_IN_VERSION
    (tmp_path / case.name / "truth.json").write_text(json.dumps({k: v for k, v in truth.items() if k != "stand_in"}))
    assert make_case(case, tmp_path, weeks=2)["status"] == "made"
    # the heat and chilled water metered apart from the electricity
    split = make_case(case, tmp_path, weeks=2, metering="split")
    assert split["status"] == "made" and split["electricity_meter"] == ["lighting", "plug_loads"]
    site = load_site(split["site"])
    assert (
        (site.consumption_end_uses, site.electricity_end_uses)
        == case.meters("split")
        == (
            ("heating", "cooling"),
            ("lighting", "plug_loads"),
        )
    )
    assert make_case(case, tmp_path, weeks=2, metering="split")["status"] == "reused"
    with pytest.raises(BuildenvError, match="metering 'three' is not one of one, split"):
        case.meters("three")

    # an EnergyPlus model that cannot run the case: the 2019 large office's data-centre coil
    refused = make_case(SuiteCase("large_office_2019", "usa_il_chicago", "heating"), tmp_path, weeks=8)
    assert refused["status"] == "refused" and "EnergyPlus failed" in refused["reason"]
    assert not (tmp_path / "large_office_2019-usa_il_chicago-heating").exists()


def test_a_small_office_site_builds_and_calibrates(tmp_path, caplog):
    record = make_case(SuiteCase("small_office", "usa_fl_miami", "heating"), tmp_path, weeks=3)
    assert record["status"] == "made", record.get("reason")
    site = load_site(record["site"])
    assert 300 <= site.floor_area_m2 < 1000  # the DOE small office, 511 m2
    surrogate = load_metamodel()
    result = calibrate_site(site, surrogate, weeks=[0, 1], max_evaluations=300)
    if surrogate.domain["floor_area_m2"][0] > site.floor_area_m2:  # a metamodel that never saw so small an office
        assert "floor_area_m2" in caplog.text and "extrapolated" in caplog.text
    assert np.isfinite(result["heldout"]["cv_rmse_q_percent"]) and result["heldout"]["r2_t"] > 0.0


def test_suite_make_calibrate_and_verify_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "suite"
    args = ["--buildings", "medium_office", "--climates", "usa_nj_newark", "--seasons", "heating"]
    assert main(["suite", "make", *args, "--out", str(out), "--weeks", "2", "--workers", "1", "--quiet"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made == {"suite": str(out), "cases": 1, "sites": 1, "refused": 0}
    assert [r["part"] for r in read_manifest(out)] == ["held_out"]

    assert main(["suite", "calibrate", "--suite", str(out), "--evaluations", "200", "--quiet", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    (row,) = result["rows"]
    assert row["part"] == "held_out" and np.isfinite(row["cv_rmse_q_percent"]) and row["seconds"] > 0
    assert result["summary"]["held_out"]["sites"] == 1
    assert json.loads((out / "calibration.json").read_text())["rows"] == result["rows"]

    # the response check: random settings on the calibrated metamodel and on the site's EnergyPlus model
    assert main(["suite", "verify", "--suite", str(out), "--random", "3", "--quiet", "--json"]) == 0
    (checked,) = json.loads(capsys.readouterr().out)["rows"]
    assert checked["settings"] == 3 and -1.0 <= checked["savings_spearman"] <= 1.0
    assert checked["savings_error_p90_abs_points"] >= checked["savings_error_mean_abs_points"] * 0.5
    # the same settings on the shoebox at the calibrated parameters split the error
    assert checked["shoebox_vs_building_p90_abs_points"] >= 0 and -1.0 <= checked["shoebox_spearman"] <= 1.0
    assert checked["savings_error_drivers"] == [] and checked["shoebox_vs_building_drivers"] == []  # 3: too few
    env = gym.make("BuildingWeek-v0", site=row["site"], weeks="all")
    historical = env.unwrapped.historical_action  # run as the baseline is: saves nothing on any of the three
    check = response_check(env, first_heldout_week(env), n=1, extra=historical)
    assert check.shoebox_savings[-1] == pytest.approx(0.0, abs=1e-6) and check.shoebox_savings[0] != 0.0
    assert check.predicted_savings[-1] == pytest.approx(0.0, abs=1e-3)
    assert check.realised_savings[-1] == pytest.approx(0.0, abs=1e-3)
    # a chosen setting is scored apart from the random ones
    (chosen,) = check.summary["chosen"]
    assert check.summary["settings"] == 1 and chosen["savings_error_points"] == pytest.approx(0.0, abs=1e-2)
    assert chosen["realised_comfort_k"] == pytest.approx(check.realised_comfort[-1], abs=1e-3)
    # over the suite, an optimiser's choice for each site (here the historical settings) is checked beside them
    (row_chosen,) = check_suite(out, ("held_out",), n=2, progress=False, chosen=lambda e, w: historical[None])
    assert row_chosen["chosen_meets_target"] and row_chosen["settings"] == 2 and "meets_target" in row_chosen
    assert main(["verify", "--site", row["site"], "--random", "3", "--json"]) == 0
    single = json.loads(capsys.readouterr().out)  # the same site, week and seed: the same figures
    assert {k: v for k, v in single.items() if k != "seconds_energyplus"} == {
        k: checked[k] for k in single if k != "seconds_energyplus"
    }
    assert main(["verify", "--site", row["site"], "--random", "2"]) == 0
    text = capsys.readouterr().out  # a table with the shoebox's column, then the split in one line
    assert "shoebox %" in text and "metamodel - shoebox" in text and "shoebox - building" in text
    assert "shoebox - building follows no one setting" in text  # two settings: too few to tell

    # each lever alone: heating the nights of a January week to the comfort level costs energy in both
    assert main(["verify", "--site", row["site"], "--levers", "--json"]) == 0
    levers = json.loads(capsys.readouterr().out)["levers"]
    assert all(r["value"] != r["historical"] for r in levers)  # every lever moved
    assert "supply_air_c" not in {r["setting"] for r in levers}  # not mapped onto the stand-in: not a lever
    nights = next(r for r in levers if (r["setting"], r["end"]) == ("heating_setback_c", "high"))
    assert nights["predicted_savings_percent"] < 0 and nights["realised_savings_percent"] < 0
    assert nights["shoebox_savings_percent"] < 0
    _print_levers(levers, first_heldout_week(env))
    assert "the lever most mispredicted is" in capsys.readouterr().out
    # over the suite: only the parts asked for
    assert main(["suite", "levers", "--suite", str(out), "--part", "development", "--quiet"]) == 2
    assert "no calibrated site in development" in capsys.readouterr().err
    assert main(["suite", "levers", "--suite", str(out), "--by", "building,weather"]) == 2
    assert "weather is not a case field" in capsys.readouterr().err


def test_each_lever_moves_its_own_setting_only_and_the_suite_writes_them_all(tmp_path, monkeypatch, capsys):
    from buildenv.env import levers as lever_module

    env = gym.make("BuildingWeek-v0")  # the default site
    base = env.unwrapped
    levers, actions = lever_actions(env)
    historical = base.site_model.historical
    assert len(levers) == len(actions) == len(set(levers)) and len(levers) > len(base.action_names) // 7
    for (setting, end), settings in zip(levers, base.decode(actions)):
        moved = np.flatnonzero((settings != historical).any(axis=0))
        assert [cat.SETTING_NAMES[j] for j in moved] == [setting], (setting, end)
        j = cat.SETTING_NAMES.index(setting)
        days = [cat.DAYS.index(d) for d in lever_module.LEVER_DAYS.get(setting, cat.DAYS)]  # a day off: weekends
        moved, kept = settings[days, j], np.delete(settings[:, j], days)
        assert (moved < historical[days, j]).all() if end == "low" else (moved > historical[days, j]).all()
        np.testing.assert_array_equal(kept, np.delete(historical[:, j], days))

    # over a suite (here one calibrated site, the lever check itself stood in for): rows, medians and the file
    suite = tmp_path / "suite"
    case, failing = (SuiteCase("medium_office", "usa_il_chicago", s) for s in ("heating", "cooling"))
    for c in (case, failing):
        shutil.copytree(base.site.path, suite / c.name)
        write_manifest(suite, [{**asdict(c), "part": "development", "site": str(suite / c.name), "status": "made"}])
    fake = [
        {
            "setting": s,
            "end": e,
            "savings_error_points": 2.0,
            "realised_savings_percent": 1.0,
            "predicted_savings_percent": 3.0,
        }
        for s, e in levers
    ]

    def check(env, week):  # the second site's building fails: the first site's rows are kept
        if env.unwrapped.site.path.name == failing.name:
            raise BuildenvError("EnergyPlus failed on the building\nits error file")
        return fake

    monkeypatch.setattr(lever_module, "lever_check", check)
    assert main(["suite", "levers", "--suite", str(suite), "--by", "building,season", "--quiet"]) == 1
    captured = capsys.readouterr()  # the failing site named on stderr, the exit status 1
    text = captured.out
    assert "medium_office heating" in text and "heating_setback_c" in text and "levers.json" in text
    assert "1 site(s) could not be checked" in captured.err and "EnergyPlus failed on the building" in captured.err
    written = json.loads((suite / "levers.json").read_text())
    assert len(written["rows"]) == len(levers) and {r["season"] for r in written["rows"]} == {"heating"}
    assert written["errors"] == [
        {
            **asdict(failing),
            "part": "development",
            "site": str(suite / failing.name),
            "error": "EnergyPlus failed on the building",
        }
    ]
    with pytest.raises(SystemExit):  # random settings or levers, not both
        main(["verify", "--site", str(suite / case.name), "--random", "20", "--levers"])

    # the response check over the same suite keeps going past the failing site too
    from buildenv.env import response as response_module

    def respond(env, week, n, seed, extra):
        if env.unwrapped.site.path.name == failing.name:
            raise BuildenvError("EnergyPlus failed on the building\nits error file")
        return SimpleNamespace(summary={"savings_error_p90_abs_points": 4.0, "savings_spearman": 0.95})

    monkeypatch.setattr(response_module, "response_check", respond)
    (row,) = check_suite(suite, ("development",), n=20, progress=False)
    assert row["meets_target"] and row["season"] == "heating"
    written = json.loads((suite / "response.json").read_text())
    assert written["rows"] == [row] and [e["season"] for e in written["errors"]] == ["cooling"]
    assert main(["suite", "verify", "--suite", str(suite), "--part", "development", "--quiet", "--json"]) == 1
    assert [e["season"] for e in json.loads(capsys.readouterr().out)["errors"]] == ["cooling"]


def test_levers_from_a_history_outside_the_action_range_are_measured_from_the_historical_action(tmp_path, monkeypatch):
    """The default site's outdoor air (0.7 1/h) under a BMS limited to 0.45-0.55 1/h: every lever holds it at 0.55,
    so each lever's savings are measured from the historical action (which holds it there too), not from 0.7."""
    from buildenv.env import levers as lever_module
    from buildenv.env import response as response_module

    site = tmp_path / "site"
    shutil.copytree(gym.make("BuildingWeek-v0").unwrapped.site.path, site)
    toml = (site / "site.toml").read_text(encoding="utf-8")
    (site / "site.toml").write_text(toml.replace("ventilation_ach = [0.45, 0.7]", "ventilation_ach = [0.45, 0.55]"))
    env = gym.make("BuildingWeek-v0", site=str(site), weeks="all")
    assert lever_module.shifted_settings(env) == ["ventilation_ach"]
    assert lever_module.shifted_settings(gym.make("BuildingWeek-v0")) == []
    j = cat.SETTING_NAMES.index("ventilation_ach")

    def fake(env, week, n, extra, shoebox):  # savings that count 100 points per 1/h of outdoor air removed
        saved = (0.7 - env.unwrapped.decode(extra)[:, :, j].mean(axis=1)) * 100.0
        chosen = [
            {
                **response_module.chosen_figures(s, s / 2, 0.5, 0.5),
                "shoebox_savings_percent": round(float(s) / 4, 2),
            }
            for s in saved
        ]
        return SimpleNamespace(summary={"chosen": chosen})

    monkeypatch.setattr(response_module, "response_check", fake)
    rows = {(r["setting"], r["end"]): r for r in lever_module.lever_check(env, 0)}
    assert all(r["baseline_shifted"] == ["ventilation_ach"] for r in rows.values())
    assert ("ventilation_ach", "high") not in rows  # 0.55 is where the historical action already holds it
    low = rows["ventilation_ach", "low"]  # 0.55 -> 0.45: 10 points, not the 25 from 0.7
    assert low["predicted_savings_percent"] == pytest.approx(10.0, abs=0.01)
    assert low["realised_savings_percent"] == pytest.approx(5.0, abs=0.01)
    assert low["shoebox_savings_percent"] == pytest.approx(2.5, abs=0.01)
    assert low["savings_error_points"] == pytest.approx(5.0, abs=0.01)
    assert rows["heating_setback_c", "high"]["predicted_savings_percent"] == pytest.approx(0.0, abs=0.01)


def test_the_lever_summary_takes_medians_per_group_setting_and_end():
    def row(building, error, shoebox):
        return {
            "building": building,
            "season": "heating",
            "setting": "heating_setback_c",
            "end": "high",
            "savings_error_points": error,
            "predicted_savings_percent": -20.0 + error,
            "realised_savings_percent": -20.0,
            "shoebox_savings_percent": -20.0 + shoebox,
        }

    rows = [row("medium_office", 10.0, 8.0), row("medium_office", 20.0, 16.0), row("small_office", -30.0, -25.0)]
    (pooled,) = summarise_levers(rows)
    assert pooled["season"] == "heating" and pooled["sites"] == 3 and pooled["error_median_points"] == 10.0
    assert pooled["error_median_abs_points"] == 20.0 and pooled["shoebox_vs_building_median_points"] == 8.0
    medium, small = summarise_levers(rows, grouping("building, season"))
    assert (medium["building"], medium["sites"], medium["error_median_points"]) == ("medium_office", 2, 15.0)
    assert medium["metamodel_vs_shoebox_median_points"] == 3.0 and small["error_median_points"] == -30.0
    with pytest.raises(BuildenvError, match="floor is not a case field"):
        grouping("building,floor")


def test_the_response_summary_scores_agreement_and_disagreement():
    same = summarise([10.0, -5.0, 3.0], [10.0, -5.0, 3.0], [0.2, 0.5, 0.1], [0.2, 0.5, 0.1])
    assert same["savings_error_p90_abs_points"] == 0.0 and same["savings_spearman"] == 1.0
    off = summarise([30.0, -15.0, 9.0], [10.0, -5.0, 3.0], [0.2, 0.5, 0.1], [0.1, 0.6, 0.3])
    assert off["savings_bias_points"] > 0 and off["savings_spearman"] == 1.0 and off["comfort_spearman"] < 1.0


def test_the_split_at_the_shoebox_tells_the_metamodel_from_the_model_structure():
    split = split_error([12.0, -4.0, 5.0], [10.0, -5.0, 3.0], [10.0, -5.0, 3.0])  # a shoebox right, its imitation off
    assert split["shoebox_vs_building_p90_abs_points"] == 0.0 and split["shoebox_spearman"] == 1.0
    assert split["metamodel_vs_shoebox_bias_points"] == pytest.approx(5 / 3, abs=0.01)
    split = split_error(
        [10.0, -5.0, 3.0], [10.0, -5.0, 3.0], [-5.0, 10.0, 9.0]
    )  # a faithful imitation of a wrong model
    assert split["metamodel_vs_shoebox_p90_abs_points"] == 0.0 and split["shoebox_spearman"] < 0.0


def test_the_settings_an_error_follows_are_named_when_significant():
    """A savings error that grows with the heating setback names it (a positive correlation); errors that follow
    nothing name a setting at most at the significance level; settings held constant are not tested."""
    rng = np.random.default_rng(0)
    settings = np.stack([rng.uniform(v.min, v.max, (20, 7)) for v in cat.GROUPS["settings"]], axis=-1)
    settings[..., cat.SETTING_NAMES.index("hvac_operating")] = 1.0
    setback = settings[..., cat.SETTING_NAMES.index("heating_setback_c")].mean(axis=1)
    (driver,) = error_drivers(settings, 10.0 * setback + rng.normal(0.0, 1.0, 20))
    assert driver["setting"] == "heating_setback_c" and driver["spearman"] > 0.8 and driver["p_value"] < 0.05 / 12
    named = [bool(error_drivers(settings, rng.normal(0.0, 1.0, 20))) for _ in range(200)]
    assert np.mean(named) <= 0.08  # on errors that follow nothing, a setting named at most at the stated 5 %
    assert error_drivers(settings[:4], setback[:4]) == []  # too few settings to tell


def test_a_copied_suite_folder_names_its_own_sites(tmp_path):
    """A manifest names each site's folder; a copied suite reads its own copies, one record per folder."""
    original, copy = tmp_path / "suite", tmp_path / "copy"
    original.mkdir()
    records = [{"site": str(original / "a-case"), "part": "held_out"}, {"site": str(original / "b-case"), "part": "x"}]
    write_manifest(original, records)
    shutil.copytree(original, copy)
    write_manifest(copy, [{"site": str(copy / "a-case"), "part": "development"}])  # a record of the copy's own
    assert read_manifest(copy) == [
        {"site": str(copy / "a-case"), "part": "development"},
        {"site": str(copy / "b-case"), "part": "x"},
    ]
    assert [r["site"] for r in read_manifest(original)] == [str(original / "a-case"), str(original / "b-case")]
