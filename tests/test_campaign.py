"""Simulation campaigns: deterministic, resumable after a kill, runnable on Dask; datasets and splits."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.campaign.dataset import ARRAYS, Dataset, open_dataset
from buildenv.campaign.runs import CampaignConfig, plan_campaign, run_campaign
from buildenv.errors import BuildenvError, DatasetError

SMALL = dict(weeks=4, seed=3, epw=["usa_il_chicago", "usa_fl_miami"], weeks_per_run=2)


def _arrays(directory: Path) -> dict[str, np.ndarray]:
    with open_dataset(directory) as ds:
        return {name: getattr(ds, name)[:] for name in ARRAYS}


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("campaign") / "small"
    run_campaign(CampaignConfig(**SMALL), out, workers=2, progress=False)
    return out


def test_plan_is_deterministic_and_seed_dependent():
    a, b = plan_campaign(CampaignConfig(**SMALL)), plan_campaign(CampaignConfig(**SMALL))
    c = plan_campaign(CampaignConfig(**{**SMALL, "seed": 4}))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.theta, y.theta)
        np.testing.assert_array_equal(x.settings, y.settings)
        assert (x.epw, x.start_week) == (y.epw, y.start_week)
    assert not all(np.array_equal(x.theta, z.theta) for x, z in zip(a, c))
    assert sum(t.n_weeks for t in a) == SMALL["weeks"]
    for task in a:
        cat.check_values("theta_build", task.theta)
        cat.check_values("settings", task.settings)
        assert 0 <= task.start_week and task.start_week + task.n_weeks <= 52


def test_dataset_contents(small_dataset):
    with open_dataset(small_dataset) as ds:
        assert len(ds) == 4
        assert ds.outputs.shape == (4, 168, len(cat.OUTPUT_NAMES))
        assert ds.weather.shape == (4, 168, len(cat.WEATHER_NAMES))
        assert (
            ds.settings.shape == (4, 7, 13)
            and ds.occupancy.shape == (4, 5, 2)
            and ds.theta.shape == (4, len(cat.THETA_BUILD))
        )
        assert json.loads(ds._h5["outputs"].attrs["names"]) == list(cat.OUTPUT_NAMES)
        assert json.loads(ds._h5["theta"].attrs["names"]) == list(cat.THETA_NAMES)
        assert ds.manifest["catalogue_hash"] == cat.catalogue_hash()
        assert ds.manifest["versions"]["energyplus"].startswith("25.")
        assert np.isfinite(ds.outputs[:]).all()
        # consecutive weeks of a run are linked: week 1 of each run follows week 0
        prev = ds.previous_week()
        assert list(prev) == [-1, 0, -1, 2]
        np.testing.assert_array_equal(ds.week_of_year[1::2], ds.week_of_year[0::2] + 1)
        # the stored weather is the EPW's weather of that week of the year
        from buildenv.weather.epw import load_weather

        w = load_weather(ds.weather_names[int(ds.weather_index[0])]).weeks(int(ds.week_of_year[0]), 1)[0]
        np.testing.assert_allclose(ds.weather[0], w, rtol=1e-6)


def test_same_seed_gives_identical_dataset(small_dataset, tmp_path):
    again = tmp_path / "again"
    run_campaign(CampaignConfig(**SMALL), again, workers=1, progress=False)
    first, second = _arrays(small_dataset), _arrays(again)
    for name in ARRAYS:
        np.testing.assert_array_equal(first[name], second[name], err_msg=name)


def test_other_campaign_in_same_directory_is_refused(small_dataset):
    with pytest.raises(DatasetError, match="another campaign"):
        run_campaign(CampaignConfig(**{**SMALL, "seed": 99}), small_dataset, workers=1, progress=False)


def test_a_campaign_of_another_catalogue_is_not_resumed(tmp_path):
    import json

    from buildenv.campaign.runs import _config_record

    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "campaign.json").write_text(
        json.dumps({**_config_record(CampaignConfig(**SMALL)), "catalogue_hash": "88d16120a6d2221f"})
    )
    with pytest.raises(DatasetError, match="catalogue 88d16120a6d2221f .* drawn differently"):
        run_campaign(CampaignConfig(**SMALL), tmp_path / "old", workers=1, progress=False)


def test_unfinished_directory_is_not_a_dataset(tmp_path):
    (tmp_path / "half").mkdir()
    with pytest.raises(DatasetError, match="resume"):
        open_dataset(tmp_path / "half")


def test_resume_after_kill_redoes_nothing(tmp_path):
    out = tmp_path / "killed"
    args = [
        "--weeks",
        "6",
        "--seed",
        "5",
        "--epw",
        "usa_co_golden",
        "--weeks-per-run",
        "1",
        "--workers",
        "1",
        "--quiet",
        "--out",
        str(out),
    ]
    cmd = [sys.executable, "-m", "buildenv.cli.main", "simulate", *args]
    proc = subprocess.Popen(cmd, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and len(list((out / "shards").glob("run_*[0-9].npz"))) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before = len(list((out / "shards").glob("run_*[0-9].npz")))
    assert 2 <= done_before < 6, "the campaign should have been killed part-way"
    assert not (out / "manifest.json").exists()
    with pytest.raises(DatasetError):
        open_dataset(out)

    subprocess.run(cmd, check=True)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is True
    assert manifest["runs_simulated_last_session"] == 6 - done_before

    reference = tmp_path / "reference"
    subprocess.run([sys.executable, "-m", "buildenv.cli.main", "simulate", *args[:-1], str(reference)], check=True)
    resumed, clean = _arrays(out), _arrays(reference)
    for name in ARRAYS:
        np.testing.assert_array_equal(resumed[name], clean[name], err_msg=name)


def test_dask_cluster_gives_the_same_dataset(small_dataset, tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        run_campaign(CampaignConfig(**SMALL), tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    manifest = json.loads((tmp_path / "dask" / "manifest.json").read_text())
    assert manifest["scheduler"].startswith("tcp://")
    local, dask = _arrays(small_dataset), _arrays(tmp_path / "dask")
    for name in ARRAYS:
        np.testing.assert_array_equal(local[name], dask[name], err_msg=name)


def test_splits(small_dataset, tmp_path):
    out = tmp_path / "splits"
    run_campaign(
        CampaignConfig(weeks=12, seed=1, epw=["usa_il_chicago", "usa_fl_miami", "usa_co_golden"], weeks_per_run=2),
        out,
        workers=2,
        progress=False,
    )
    with open_dataset(out) as ds:
        for kind in ("random", "weather_weeks", "buildings", "climate"):
            parts = ds.split(kind, fractions=(0.5, 0.17, 0.33), seed=0)
            together = np.concatenate(list(parts.values()))
            assert sorted(together.tolist()) == list(range(len(ds))), kind
        ww = ds.split("weather_weeks", fractions=(0.5, 0.17, 0.33))
        key = ds.weather_index[:].astype(int) * 100 + ds.week_of_year[:].astype(int)
        assert not set(key[ww["train"]]) & set(key[ww["test"]])
        runs = ds.split("buildings", fractions=(0.5, 0.17, 0.33))
        run_id = ds.run_id[:]
        assert not set(run_id[runs["train"]]) & (set(run_id[runs["test"]]) | set(run_id[runs["val"]]))
        assert len(runs["test"]) > 0
        held = ds.split("climate", test_climates=["usa_fl_miami"])
        miami = ds.weather_names.index("usa_fl_miami")
        assert set(ds.weather_index[:][held["test"]]) == {miami}
        assert miami not in set(ds.weather_index[:][held["train"]])
        with pytest.raises(DatasetError, match="not in"):
            ds.split("climate", test_climates=["usa_xx_nowhere"])


def _weather_weeks(names: list[str], climate: list[int], week: list[int]) -> Dataset:
    """A dataset holding only the arrays a weather-week split reads."""
    h5 = {"weather_index": np.array(climate), "week_of_year": np.array(week), "outputs": np.zeros((len(week), 1))}
    return Dataset(Path("memory"), {}, names, h5)


def test_weather_weeks_are_split_alike_in_every_campaign():
    rng = np.random.default_rng(0)
    one = _weather_weeks(["chicago", "miami"], rng.integers(0, 2, 400).tolist(), rng.integers(0, 52, 400).tolist())
    # another campaign: other weeks present, the climates listed in another order
    other = _weather_weeks(["miami", "chicago"], rng.integers(0, 2, 150).tolist(), rng.integers(0, 30, 150).tolist())

    def parts(ds: Dataset, version: int) -> dict[tuple[str, int], str]:
        split = ds.split("weather_weeks", seed=3, version=version)
        week, climate = ds.week_of_year[:], ds.weather_index[:]
        return {(ds.weather_names[climate[i]], int(week[i])): name for name, idx in split.items() for i in idx}

    a, b = parts(one, 2), parts(other, 2)
    shared = set(a) & set(b)
    assert len(shared) > 40 and all(a[k] == b[k] for k in shared)
    assert {"train", "val", "test"} <= set(a.values())
    # the first assignment permuted the weather weeks a dataset held: campaigns disagreed
    a1, b1 = parts(one, 1), parts(other, 1)
    assert any(a1[k] != b1[k] for k in shared)


def test_floor_area_drawn_evenly_in_its_logarithm():
    area = cat.THETA_NAMES.index("floor_area_m2")

    def areas(scale: str) -> np.ndarray:
        config = CampaignConfig(weeks=2000, seed=5, weeks_per_run=1, floor_area_scale=scale)
        return np.array([task.theta[area] for task in plan_campaign(config)])

    linear, log = areas("linear"), areas("log")
    small = cat.get("floor_area_m2").min * 10  # the range's first decade: 45 % of its logarithm, 5 % of its width
    assert (linear < small).mean() < 0.1 and 0.35 < (log < small).mean() < 0.55
    assert np.all(log == cat.get("floor_area_m2").snap(log))  # on the catalogue's grid
    with pytest.raises(BuildenvError, match="--floor-area-scale"):
        CampaignConfig(weeks=1, floor_area_scale="sqrt").validate()


def test_buildings_drawn_around_calibrated_sites_keep_their_geometry_and_the_catalogue(tmp_path):
    """``--around``: a suite's development sites are the centres (its held-out ones never), each run's building a
    centre moved by steps of ``spread`` times each range, on the grid, the geometry the site's."""
    import shutil

    from buildenv.campaign.dataset import simulate_command
    from buildenv.env.building_week import DEFAULT_SITE
    from buildenv.sites.suite import calibrated_buildings, write_manifest

    suite = tmp_path / "suite"
    for name, part in (("dev", "development"), ("held", "held_out")):
        shutil.copytree(DEFAULT_SITE, suite / name)
        write_manifest(suite, [{"site": str(suite / name), "part": part, "status": "made"}])
    (centre,) = calibrated_buildings([suite])
    assert centre["site"] == str(suite / "dev") and set(centre["theta"]) == set(cat.THETA_NAMES)
    assert calibrated_buildings([suite / "held"])[0]["site"] == str(suite / "held")  # a site folder given itself
    with pytest.raises(BuildenvError, match="neither a calibrated site"):
        calibrated_buildings([tmp_path])

    def thetas(spread: float) -> np.ndarray:
        config = CampaignConfig(weeks=400, seed=1, weeks_per_run=1, around=[centre], spread=spread)
        return np.array([task.theta for task in plan_campaign(config)])

    near, far = thetas(0.05), thetas(0.3)
    middle = np.array([centre["theta"][n] for n in cat.THETA_NAMES])
    width = np.array([v.max - v.min for v in cat.GROUPS["theta_build"]])
    for j, variable in enumerate(cat.GROUPS["theta_build"]):
        assert np.all(near[:, j] == variable.snap(near[:, j])), variable.name  # on the grid, within the range
        if variable.name in cat.GEOMETRY_NAMES:
            assert np.all(far[:, j] == variable.snap(middle[j])), variable.name
    free = [j for j, n in enumerate(cat.THETA_NAMES) if n not in cat.GEOMETRY_NAMES]
    assert np.abs(near - middle)[:, free].mean() < np.abs(far - middle)[:, free].mean()
    assert np.median(np.abs(near - middle)[:, free] / width[free]) < 0.1
    np.testing.assert_array_equal(near, thetas(0.05))  # deterministic
    config = CampaignConfig(weeks=1, around=[centre], spread=0.05)
    assert f"--around {suite / 'dev'} --spread 0.05" in simulate_command(tmp_path / "ds", asdict(config))
    with pytest.raises(BuildenvError, match="--spread"):
        CampaignConfig(weeks=1, around=[centre], spread=0.0).validate()
    with pytest.raises(BuildenvError, match="floor area is each site's own"):
        CampaignConfig(weeks=1, around=[centre], floor_area_scale="log").validate()
    with pytest.raises(BuildenvError, match="lacks lighting_power_w_m2"):
        theta = {k: v for k, v in centre["theta"].items() if k != "lighting_power_w_m2"}
        CampaignConfig(weeks=1, around=[{"site": "x", "theta": theta}]).validate()


class _RefusingSimulator:
    """Stands in for EnergyPlus: refuses the runs whose start week is in ``refuse``, returns constant weeks."""

    def __init__(self, refuse: set[int]):
        self.refuse = refuse

    def __call__(self, theta, settings, occupancy, epw, start_week, workdir=None, zoning=None):
        from types import SimpleNamespace

        from buildenv.errors import SimulationError

        if start_week in self.refuse:
            raise SimulationError(f"EnergyPlus failed on shoebox.epJSON: ** Severe ** warm-up (week {start_week})")
        return SimpleNamespace(outputs=np.full((len(settings), 168, len(cat.OUTPUT_NAMES)), float(start_week)))


def test_a_failed_run_is_left_out_and_listed(tmp_path, monkeypatch):
    config = CampaignConfig(weeks=8, seed=3, epw=["usa_il_chicago"], weeks_per_run=2)
    tasks = plan_campaign(config)
    refused = tasks[1]
    monkeypatch.setattr("buildenv.energyplus.simulate.simulate_weeks", _RefusingSimulator({refused.start_week}))
    run_campaign(config, tmp_path / "c", workers=1, progress=False, max_failed_share=0.3)
    with open_dataset(tmp_path / "c") as ds:
        assert len(ds) == 6 and ds.manifest["weeks"] == 6 and ds.manifest["weeks_planned"] == 8
        assert refused.run_id not in set(ds.run_id[:].tolist())
        assert [r["run_id"] for r in ds.manifest["failed_runs"]] == [refused.run_id]
        assert "warm-up" in ds.manifest["failed_runs"][0]["error"]
        kept = [t for t in tasks if t.run_id != refused.run_id]
        np.testing.assert_array_equal(ds.outputs[:, 0, 0], np.repeat([t.start_week for t in kept], 2))
        np.testing.assert_array_equal(ds.previous_week()[::2], -1)  # every kept run still starts from a warm-up


def test_too_many_failed_runs_stop_the_campaign_and_a_rerun_retries_them(tmp_path, monkeypatch):
    from buildenv.errors import SimulationError

    config = CampaignConfig(weeks=8, seed=3, epw=["usa_il_chicago"], weeks_per_run=2)
    tasks = plan_campaign(config)
    monkeypatch.setattr("buildenv.energyplus.simulate.simulate_weeks", _RefusingSimulator({tasks[0].start_week}))
    with pytest.raises(SimulationError, match=r"1 of 4 EnergyPlus runs failed .*warm-up"):
        run_campaign(config, tmp_path / "c", workers=1, progress=False)
    assert not (tmp_path / "c" / "manifest.json").exists()
    monkeypatch.setattr("buildenv.energyplus.simulate.simulate_weeks", _RefusingSimulator(set()))
    run_campaign(config, tmp_path / "c", workers=1, progress=False)
    with open_dataset(tmp_path / "c") as ds:
        assert len(ds) == 8 and ds.manifest["failed_runs"] == []


def test_simulate_command_reports_the_runs_it_left_out(tmp_path, monkeypatch, capsys):
    from buildenv.cli.main import main

    config = CampaignConfig(weeks=8, seed=3, epw=["usa_il_chicago"], weeks_per_run=2)
    refused = plan_campaign(config)[2]
    monkeypatch.setattr("buildenv.energyplus.simulate.simulate_weeks", _RefusingSimulator({refused.start_week}))
    assert (
        main(
            [
                "simulate",
                "--weeks",
                "8",
                "--seed",
                "3",
                "--epw",
                "usa_il_chicago",
                "--weeks-per-run",
                "2",
                "--workers",
                "1",
                "--max-failed-share",
                "0.3",
                "--quiet",
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 0
    )
    out, err = capsys.readouterr()
    assert json.loads(out)["failed_runs"] == 1 and json.loads(out)["weeks"] == 6
    assert f"run {refused.run_id} (2 weeks) left out" in err


def test_settings_draws_share_a_building_weather_and_occupancy_and_draw_their_own_settings():
    config = CampaignConfig(weeks=10, seed=2, epw=["usa_il_chicago", "usa_fl_miami"], weeks_per_run=3, settings_draws=2)
    tasks = plan_campaign(config)
    assert [t.n_weeks for t in tasks] == [3, 3, 3, 1]
    for a, b in (tasks[0:2], tasks[2:4]):
        np.testing.assert_array_equal(a.theta, b.theta)
        assert (a.epw, a.start_week) == (b.epw, b.start_week)
        np.testing.assert_array_equal(a.occupancy[: b.n_weeks], b.occupancy)
        assert not np.array_equal(a.settings[: b.n_weeks], b.settings)
    assert not np.array_equal(tasks[0].theta, tasks[2].theta)
    with pytest.raises(BuildenvError, match="--settings-draws"):
        plan_campaign(CampaignConfig(weeks=4, settings_draws=0))


def test_response_scores_compare_savings_within_each_group():
    from buildenv.metrics import response_scores

    truth = np.array([10.0, 8.0, 12.0, 5.0, 4.0, 6.0])
    groups = np.array([0, 0, 0, 1, 1, 1])
    exact = response_scores(truth, 1.3 * truth, groups, floor=0.5)  # a constant factor saves the same shares
    assert exact["response_pairs"] == 4 and exact["response_savings_error_p90_abs_points"] == pytest.approx(0.0)
    assert exact["response_savings_spearman"] == pytest.approx(1.0)
    offset = response_scores(truth, truth + 1.0, groups, floor=0.5)  # 20 % saved on 10 -> 2/11 = 18.2 % predicted
    assert offset["response_savings_error_mean_abs_points"] > 1.0
    assert response_scores(truth, truth, np.arange(6), floor=0.5) == {"response_pairs": 0}


def test_evaluate_scores_the_response_on_a_campaign_of_settings_draws(tmp_path, capsys):
    from buildenv.cli.main import main

    out = tmp_path / "pairs"
    words = ["simulate", "--weeks", "4", "--weeks-per-run", "2", "--settings-draws", "2", "--seed", "1"]
    assert main([*words, "--epw", "usa_il_chicago", "--zoning", "core_perimeter", "--out", str(out), "--quiet"]) == 0
    assert "--settings-draws 2" in json.loads((out / "manifest.json").read_text())["command"]
    capsys.readouterr()
    assert main(["evaluate", "--data", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["response_pairs"] == 2
    assert 0.0 <= result["response_savings_error_p90_abs_points"] < 100.0
