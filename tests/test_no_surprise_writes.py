"""No surprise writes: a command writes into a folder only what it is asked to, and a refused or killed one leaves
nothing behind (`buildenv diagnose` without ``--save``, a refused `buildenv site reference`, a killed campaign)."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import buildenv.campaign.runs as runs
import buildenv.diagnosis.gap as gap
import buildenv.energyplus.reference as reference
import buildenv.energyplus.workdirs as workdirs
import buildenv.metamodel.surrogate as surrogate
from buildenv import catalogue as cat
from buildenv.cli.main import main
from buildenv.env.building_week import DEFAULT_SITE as SHIPPED_SITE
from buildenv.errors import SiteError
from buildenv.sites import load_site, write_site


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# -- buildenv diagnose: saves only with --save ---------------------------------------------------------------


@pytest.fixture
def diagnosed_site(tmp_path, monkeypatch):
    """A copy of the shipped site, and a stand-in diagnosis (no metamodel, no fits) that selects one effect."""
    site = tmp_path / "site"
    shutil.copytree(SHIPPED_SITE, site)
    calls = {}

    def fake_diagnose(site_, surrogate_, settings, progress=True, plot=None, strict_calibration=False):
        calls["plot"], calls["strict"] = plot, strict_calibration
        return {"_fit": object(), "selected": ["temperature_sensor_bias"], "verdict": "unmodelled effect(s) found"}

    def fake_save(site_, result):
        calls["saved"] = True
        return Path(site_.path) / "calibration.json"

    monkeypatch.setattr(surrogate, "load_metamodel", lambda name: None)
    monkeypatch.setattr(gap, "diagnose", fake_diagnose)
    monkeypatch.setattr(gap, "save_extended_model", fake_save)
    return site, calls


def test_diagnose_without_save_leaves_the_site_folder_as_it_was(diagnosed_site, capsys):
    site, calls = diagnosed_site
    before = _snapshot(site)
    assert (site / "calibration.json").is_file()
    assert main(["diagnose", "--site", str(site), "--quiet"]) == 0
    assert _snapshot(site) == before  # calibration.json byte-identical, no diagnosis.png
    assert calls["plot"] is None and "saved" not in calls
    err = capsys.readouterr().err.strip().splitlines()
    assert "--save" in err[-1] and "not saved" in err[-1]


def test_diagnose_with_save_saves_the_extended_model_and_plots_into_the_site(diagnosed_site, capsys):
    site, calls = diagnosed_site
    assert main(["diagnose", "--site", str(site), "--quiet", "--save"]) == 0
    assert calls["saved"] and calls["plot"] == site / "diagnosis.png"
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith("saved: ")


def test_diagnose_no_save_is_still_accepted_and_is_the_default(diagnosed_site):
    site, calls = diagnosed_site
    assert main(["diagnose", "--site", str(site), "--quiet", "--no-save"]) == 0
    assert "saved" not in calls


# -- buildenv site reference / write_site: nothing left behind on a refusal ----------------------------------


@pytest.fixture
def fake_reference_run(monkeypatch):
    """make_reference_site without EnergyPlus: a flat one-week run of the medium office."""

    def run(building, epw, start, settings, **kwargs):
        weeks = len(settings)
        return reference.ReferenceRun(
            temperature_c=np.full((weeks, 168), 21.0),
            consumption_kwh=np.full((weeks, 168), 5.0),
            floor_area_m2=4982.2,
            zones=["core"],
        )

    monkeypatch.setattr(reference, "run_reference", run)
    monkeypatch.setattr(reference, "historical_ventilation_ach", lambda building: 0.5)
    monkeypatch.setattr(reference, "reference_bms", lambda building: (cat.SETTING_NAMES, {}))


def test_refused_site_reference_leaves_no_folder(tmp_path, fake_reference_run, capsys):
    out = tmp_path / "sites" / "refused"
    # 999 storeys: written, then refused by load_site (out of the catalogue's range)
    assert main(["site", "reference", "--floors", "999", "--weeks", "1", "--out", str(out)]) == 2
    assert "number_of_floors" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # neither the folder, its parent, nor a temporary folder


def test_refused_site_reference_keeps_an_existing_site_as_it_was(tmp_path, fake_reference_run):
    site = tmp_path / "site"
    shutil.copytree(SHIPPED_SITE, site)
    before = _snapshot(site)
    assert main(["site", "reference", "--floors", "999", "--weeks", "1", "--out", str(site)]) == 2
    assert _snapshot(site) == before
    assert [p.name for p in tmp_path.iterdir()] == ["site"]


def test_site_reference_into_an_existing_folder_replaces_the_site(tmp_path, fake_reference_run):
    site = tmp_path / "site"
    shutil.copytree(SHIPPED_SITE, site)
    (site / "notes.txt").write_text("mine")
    assert main(["site", "reference", "--weeks", "1", "--out", str(site)]) == 0
    assert load_site(site).weeks == 1
    assert not (site / "calibration.json").exists()  # it described the earlier data
    assert (site / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


def test_site_reference_records_the_schedules_it_was_told_and_its_building_runs_again_with_them(
    tmp_path, fake_reference_run, monkeypatch
):
    from buildenv.env.energyplus_backend import run_weeks

    named = {role: [f"my {role}"] for role in reference.SCHEDULE_ROLES}
    named["hvac_availability"] = ["my fans", "my pumps"]
    maps = [f"{role}={','.join(names)}" for role, names in named.items()]
    site_dir = tmp_path / "site"
    argv = ["site", "reference", "--weeks", "1", "--out", str(site_dir)]
    assert main([*argv, *(a for m in maps for a in ("--map", m))]) == 0
    site = load_site(site_dir)
    assert site.truth["schedule_map"] == named
    # detected, not named: nothing recorded, detected again on each run
    assert main(["site", "reference", "--weeks", "1", "--out", str(tmp_path / "detected")]) == 0
    assert reference.recorded_schedule_map(load_site(tmp_path / "detected")) is None
    used = []
    monkeypatch.setattr(
        reference,
        "run_reference",
        lambda *args, schedule_map=None, **kwargs: (
            used.append(schedule_map)
            or SimpleNamespace(temperature_c=np.zeros((2, 168)), hvac_kwh=np.zeros((2, 168)), floor_area_m2=1.0)
        ),
    )
    run_weeks(site, [site.start], site.settings[:1], workers=1)
    assert used == [reference.ScheduleMap(**named)]
    # a damaged record is refused in one line naming the file
    bad = SimpleNamespace(truth={"schedule_map": {"heating_setpoint": "x"}}, path=site_dir)
    with pytest.raises(reference.ReferenceBuildingError, match="truth.json: schedule_map must name"):
        reference.recorded_schedule_map(bad)


def test_write_site_refused_after_writing_leaves_nothing(tmp_path):
    arrays = {
        "settings": np.tile(load_site(SHIPPED_SITE).settings[:1], (1, 1, 1)),
        "temperature_c": np.full((1, 168), 21.0),
        "consumption_kwh": np.full((1, 168), 5.0),
    }
    common = {"name": "x", "weather": "usa_il_chicago", "start": load_site(SHIPPED_SITE).start, "floor_area_m2": 5000}
    with pytest.raises(SiteError, match="number_of_floors"):
        write_site(tmp_path / "new", **common, number_of_floors=999, **arrays)
    assert list(tmp_path.iterdir()) == []
    assert load_site(write_site(tmp_path / "new", **common, number_of_floors=3, **arrays)).number_of_floors == 3
    assert [p.name for p in tmp_path.iterdir()] == ["new"]


# -- buildenv simulate: a killed campaign's temporary folders go at the next start ---------------------------


def _dead_pid() -> int:
    """A process id no process has (beyond the kernel's largest)."""
    return int(Path("/proc/sys/kernel/pid_max").read_text()) + 1


@pytest.mark.skipif(not Path("/proc/sys/kernel/pid_max").is_file(), reason="needs Linux's pid_max")
def test_next_campaign_removes_the_temporary_folders_a_killed_one_left(tmp_path, monkeypatch):
    system_tmp = tmp_path / "tmp"
    system_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    stale = Path(tempfile.mkdtemp(prefix=f"buildenv-campaign-{_dead_pid()}-"))
    (stale / "buildenv-run3-abcdefgh").mkdir()  # what a killed run left
    (stale / "buildenv-run3-abcdefgh" / "eplusout.err").write_text("...")
    alive = Path(tempfile.mkdtemp(prefix=f"buildenv-campaign-{os.getppid()}-"))  # a campaign running now
    other = system_tmp / "buildenv-run7-abcdefgh"  # not a campaign folder of this pattern: not ours to judge
    other.mkdir()
    seen = []

    def fake_run(task, tmp_root=None):
        assert not stale.exists()
        root = Path(tmp_root)
        assert root.parent == system_tmp and root.name.startswith(workdirs.prefix("campaign"))
        seen.append(root)
        with tempfile.TemporaryDirectory(prefix=f"buildenv-run{task.run_id}-", dir=tmp_root) as work:
            (Path(work) / "eplusout.csv").write_text("")
            if task.run_id == 1:
                raise KeyboardInterrupt  # the campaign is stopped during its second run
        return task.run_id, np.zeros((task.n_weeks, 168, 8), np.float32), ""

    monkeypatch.setattr(runs, "run_task", fake_run)
    config = runs.CampaignConfig(weeks=2, weeks_per_run=1, epw=["usa_il_chicago"])
    out = tmp_path / "campaign"
    with pytest.raises(KeyboardInterrupt):
        runs.run_campaign(config, out, workers=1, progress=False)
    assert not stale.exists() and alive.is_dir() and other.is_dir()
    assert seen and not seen[0].exists()  # a stopped campaign removes its own folder
    assert runs._shard_path(out, 0).is_file() and not runs._shard_path(out, 1).exists()
    assert sorted(p.name for p in system_tmp.iterdir()) == sorted([alive.name, other.name])


def test_a_run_without_a_campaign_folder_works_in_one_the_next_campaign_can_sweep(tmp_path, monkeypatch):
    from buildenv.energyplus import simulate

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    seen = []

    def fake_simulate(*args, workdir, **kwargs):
        seen.append(workdir)
        raise KeyboardInterrupt  # a Dask worker killed during its run

    monkeypatch.setattr(simulate, "simulate_weeks", fake_simulate)
    task = runs.plan_campaign(runs.CampaignConfig(weeks=1, weeks_per_run=1, epw=["usa_il_chicago"]))[0]
    with pytest.raises(KeyboardInterrupt):
        runs.run_task(task)  # as _execute_dask calls it: no tmp_root
    assert workdirs._FOLDER.fullmatch(seen[0].name) and seen[0].parent == tmp_path
    assert seen[0].name.startswith(workdirs.prefix("campaign"))


def test_remove_stale_run_folders_keeps_running_and_foreign_ones(tmp_path):
    dead = [tmp_path / f"buildenv-{kind}-{_dead_pid()}-abc_1234" for kind in workdirs.KINDS]
    mine = tmp_path / f"{workdirs.prefix('calib')}abcd1234"
    running = tmp_path / f"buildenv-ref-{os.getppid()}-abcd1234"
    unlike = tmp_path / f"buildenv-campaign-{_dead_pid()}-abc"  # not a mkdtemp name
    other = tmp_path / f"buildenv-run-{_dead_pid()}-abcd1234"  # not a kind of ours
    for folder in (*dead, mine, running, unlike, other):
        folder.mkdir()
    assert sorted(workdirs.remove_stale_run_folders(tmp_path)) == sorted(dead)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (mine, running, unlike, other))


@pytest.mark.skipif(not Path("/proc/sys/kernel/pid_max").is_file(), reason="needs Linux's pid_max")
def test_a_killed_shoebox_run_s_folder_goes_with_the_next_process_s_first_run(tmp_path, monkeypatch):
    from buildenv.defaults import default_theta, default_week
    from buildenv.energyplus import simulate

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(workdirs, "_swept", False)  # a new process
    stale = Path(tempfile.mkdtemp(prefix=f"buildenv-calib-{_dead_pid()}-"))
    (stale / "eplusout.err").write_text("...")
    made = []

    def fake_run(model, epw, workdir, **kwargs):
        made.append(Path(workdir))
        assert not stale.exists()
        raise KeyboardInterrupt  # killed during its run

    monkeypatch.setattr(simulate, "run_energyplus", fake_run)
    with pytest.raises(KeyboardInterrupt):
        simulate.simulate_weeks(default_theta(), *default_week(), "usa_il_chicago", 1)
    assert made[0].name.startswith(workdirs.prefix("eplus")) and not made[0].exists()
