"""Simulation campaigns: sample buildings, weeks and weather, run EnergyPlus in parallel, write a dataset.

A campaign of N weeks is cut into *runs*: one building (theta_build), one weather file and up to
``weeks_per_run`` consecutive weeks, each with its own sampled settings (I_k) and occupancy (O_k). One
EnergyPlus run simulates the consecutive weeks in one go (whole years by default) and is cut into weeks,
so only the first week of a run starts from EnergyPlus's warm-up state; every later week starts from the
real end state of the week before it (and the dataset records which week precedes which).

The whole plan (every sampled value) is drawn up front from the seed, so a campaign is deterministic and a
rerun of the same command resumes it: each finished run is saved as its own shard file (written to a
temporary name, then renamed), and finished shards are never redone. When all runs are done the shards
are consolidated into ``dataset.h5``; ``manifest.json`` is written last, so a directory without it is
never mistaken for a complete dataset.

Runs execute in worker processes (EnergyPlus states are not thread-safe; workers are recycled because each
run leaves a few MB behind) or, with ``scheduler``, on a Dask cluster. Local runs work in one temporary folder
per campaign, named after its process (``buildenv-campaign-<pid>-*`` in the system's temporary folder) and
removed when the campaign ends or fails; one left by a killed campaign is removed when the next starts
(:mod:`buildenv.energyplus.workdirs`).
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.campaign.dataset import DATA_FILE, data_file_record, simulate_command
from buildenv.campaign.sampling import FLOOR_AREA_SCALES, METHODS, sample_group, sample_weeks, theta_around
from buildenv.energyplus import workdirs
from buildenv.energyplus.shoebox import DEFAULT_ZONING, ZONINGS
from buildenv.errors import BuildenvError, DatasetError, SimulationError
from buildenv.weather.epw import resolve_epw, shipped_weather

log = logging.getLogger(__name__)

#: share of a campaign's runs that may fail (and be left out) before the campaign stops: one building in
#: thousands whose warm-up never settles must not stop a campaign that a rerun could never finish
MAX_FAILED_SHARE = 0.01
TASKS_PER_WORKER = 50  # recycle worker processes after this many EnergyPlus runs (each leaves ~3 MB behind)
DEFAULT_CLIMATES: tuple[str, ...] = tuple(shipped_weather())


@dataclass
class CampaignConfig:
    """What to simulate. CLI flags of ``buildenv simulate`` map one to one onto these fields.

    Attributes:
        weeks: number of weeks in the dataset.
        seed: seed of every random draw of the campaign.
        epw: weather short names or EPW paths; runs are spread evenly over them.
        weeks_per_run: consecutive weeks simulated per EnergyPlus run (1-52).
        sampling: ``uniform`` (paper) or ``lhs``.
        zoning: the shoebox's zoning, ``core_perimeter``, ``five_zone`` or ``single`` (the paper's single zone;
            see :mod:`buildenv.energyplus.shoebox`).
        floor_area_scale: ``linear`` (each floor area of the catalogue's grid equally likely) or ``log`` (uniform
            in its logarithm: small offices as well represented as large ones).
        around: calibrated buildings to draw the campaign's buildings around instead of over the whole catalogue
            (:func:`buildenv.campaign.sampling.theta_around`), each ``{"site": folder, "theta": {name: value}}``
            (``buildenv simulate --around``); the settings, occupancy and weather are drawn as in any campaign.
        spread: with ``around``, each parameter's random step as a share of its catalogue range.
        settings_draws: runs that share a building, a weather file, start week and occupancy, each under its own
            settings (``buildenv simulate --settings-draws``): runs ``K g`` to ``K g + K - 1`` form group ``g``, so
            the dataset holds the same weeks under ``K`` settings, from which a metamodel's response to settings is
            scored (:func:`buildenv.metrics.response_scores`); 1 draws every run anew.
    """

    weeks: int
    seed: int = 0
    epw: list[str] = field(default_factory=lambda: list(DEFAULT_CLIMATES))
    weeks_per_run: int = cat.WEEKS_PER_YEAR
    sampling: str = "uniform"
    zoning: str = DEFAULT_ZONING
    floor_area_scale: str = "linear"
    around: list[dict] = field(default_factory=list)
    spread: float = 0.1
    settings_draws: int = 1

    def validate(self) -> None:
        """Raise :class:`BuildenvError` on a value no campaign can use."""
        if self.weeks < 1:
            raise BuildenvError(f"--weeks must be at least 1 (got {self.weeks})")
        if not 1 <= self.weeks_per_run <= cat.WEEKS_PER_YEAR:
            raise BuildenvError(f"--weeks-per-run must be within 1..{cat.WEEKS_PER_YEAR} (got {self.weeks_per_run})")
        if self.sampling not in METHODS:
            raise BuildenvError(f"--sampling must be one of {', '.join(METHODS)} (got {self.sampling!r})")
        if self.zoning not in ZONINGS:
            raise BuildenvError(f"--zoning must be one of {', '.join(ZONINGS)} (got {self.zoning!r})")
        if self.floor_area_scale not in FLOOR_AREA_SCALES:
            raise BuildenvError(
                f"--floor-area-scale must be one of {', '.join(FLOOR_AREA_SCALES)} (got {self.floor_area_scale!r})"
            )
        if self.settings_draws < 1:
            raise BuildenvError(f"--settings-draws must be at least 1 (got {self.settings_draws})")
        if not 0.0 < self.spread <= 1.0:
            raise BuildenvError(f"--spread must be a share of each range within (0, 1] (got {self.spread})")
        if self.around and self.floor_area_scale != "linear":
            raise BuildenvError("--floor-area-scale: with --around the floor area is each site's own; leave it out")
        for centre in self.around:
            missing = [n for n in cat.THETA_NAMES if not np.isfinite(centre.get("theta", {}).get(n, np.nan))]
            if missing:
                raise BuildenvError(f"--around {centre.get('site')}: its calibration lacks {', '.join(missing)}")
        if not self.epw:
            raise BuildenvError("--epw: give at least one weather file")
        for epw in self.epw:
            resolve_epw(epw)


@dataclass(frozen=True)
class RunTask:
    """One EnergyPlus run of a campaign: a building, a weather file and consecutive weeks."""

    run_id: int
    theta: np.ndarray  # (21,)
    settings: np.ndarray  # (weeks, 7, 13)
    occupancy: np.ndarray  # (weeks, 5, 2)
    epw: str
    weather_index: int
    start_week: int
    zoning: str = DEFAULT_ZONING

    @property
    def n_weeks(self) -> int:
        return int(self.settings.shape[0])


def plan_campaign(config: CampaignConfig) -> list[RunTask]:
    """Draw every run of a campaign from its seed (deterministic; the same config gives the same plan). With
    ``settings_draws`` K > 1, each group of K consecutive runs shares its building, weather, start week and
    occupancy, and draws its own settings."""
    config.validate()
    rng = np.random.default_rng(config.seed)
    n_runs = math.ceil(config.weeks / config.weeks_per_run)
    lengths = [min(config.weeks_per_run, config.weeks - r * config.weeks_per_run) for r in range(n_runs)]
    draws = config.settings_draws
    n_buildings = math.ceil(n_runs / draws)
    log_scaled = ("floor_area_m2",) if config.floor_area_scale == "log" else ()
    if config.around:
        centres = np.array([[c["theta"][n] for n in cat.THETA_NAMES] for c in config.around])
        thetas = theta_around(centres, n_buildings, rng, config.spread, cat.GEOMETRY_NAMES)
    else:
        thetas = sample_group("theta_build", n_buildings, rng, config.sampling, log_scaled)
    settings, occupancy = sample_weeks(config.weeks, rng, config.sampling)
    order = np.resize(rng.permutation(len(config.epw)), n_buildings)
    climates = rng.permutation(order)
    starts = [int(rng.integers(0, cat.WEEKS_PER_YEAR - lengths[g * draws] + 1)) for g in range(n_buildings)]
    tasks, offset = [], 0
    for r, n in enumerate(lengths):
        g = r // draws
        first = g * draws * config.weeks_per_run  # the group's first run's weeks: its occupancy
        tasks.append(
            RunTask(
                r,
                thetas[g],
                settings[offset : offset + n],
                occupancy[first : first + n],
                config.epw[climates[g]],
                int(climates[g]),
                starts[g],
                config.zoning,
            )
        )
        offset += n
    return tasks


def run_task(task: RunTask, tmp_root: str | None = None) -> tuple[int, np.ndarray | None, str]:
    """Simulate one run (in a worker process); returns ``(run_id, outputs (weeks, 168, 8), "")``, or
    ``(run_id, None, message)`` when EnergyPlus refused the building (a :class:`SimulationError`). EnergyPlus
    runs in a temporary folder inside ``tmp_root``, removed after; without one (a Dask worker), a folder of the
    system's named as a campaign's of this process, which the next campaign removes if the worker is killed
    (:mod:`buildenv.energyplus.workdirs`)."""
    from buildenv.energyplus.simulate import simulate_weeks

    folder = (
        tempfile.TemporaryDirectory(prefix=f"buildenv-run{task.run_id}-", dir=tmp_root)
        if tmp_root
        else workdirs.temporary_folder("campaign")
    )
    try:
        with folder as tmp:
            result = simulate_weeks(
                task.theta,
                task.settings,
                task.occupancy,
                task.epw,
                task.start_week,
                workdir=Path(tmp),
                zoning=task.zoning,
            )
    except SimulationError as exc:
        return task.run_id, None, str(exc)
    return task.run_id, result.outputs.astype(np.float32), ""


def _shard_path(out: Path, run_id: int) -> Path:
    return out / "shards" / f"run_{run_id:06d}.npz"


def _record_failure(out: Path, task: RunTask, message: str) -> dict:
    """Write what EnergyPlus said about a failed run beside the shards (a rerun tries the run again)."""
    record = {
        "run_id": task.run_id,
        "epw": str(task.epw),
        "start_week": task.start_week,
        "weeks": task.n_weeks,
        "error": message,
    }
    (out / "shards" / f"run_{task.run_id:06d}.failed.json").write_text(json.dumps(record, indent=2, allow_nan=False))
    return record


def _write_shard(out: Path, task: RunTask, outputs: np.ndarray) -> None:
    path = _shard_path(out, task.run_id)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, outputs=outputs)
    os.replace(tmp, path)


def _config_record(config: CampaignConfig) -> dict:
    return {"config": asdict(config), "catalogue_hash": cat.catalogue_hash()}


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    from buildenv.energyplus.runner import energyplus_version

    out = {"energyplus": energyplus_version()}
    for pkg in ("buildenv", "pyenergyplus-lbnl", "numpy", "h5py", "pvlib", "pandas"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def _prepare_directory(out: Path, config: CampaignConfig) -> None:
    record = _config_record(config)
    campaign_file = out / "campaign.json"
    if campaign_file.exists():
        previous = json.loads(campaign_file.read_text())
        previous["config"].setdefault("zoning", "single")  # campaigns made before zoning was a choice
        previous["config"].setdefault("floor_area_scale", "linear")
        previous["config"].setdefault("around", [])  # campaigns made before buildings could be drawn around sites
        previous["config"].setdefault("spread", 0.1)
        previous["config"].setdefault("settings_draws", 1)  # campaigns made before runs could share a building
        if previous.get("catalogue_hash") != record["catalogue_hash"]:
            raise DatasetError(
                f"{out} holds a campaign of catalogue {previous.get('catalogue_hash')} ({campaign_file}), this "
                f"buildenv has {record['catalogue_hash']}: its remaining weeks would be drawn differently; use another "
                "--out, or delete it and simulate it again"
            )
        if previous != record:
            raise DatasetError(
                f"{out} holds another campaign ({campaign_file}: {previous['config']}); use another --out or delete it"
            )
    else:
        out.mkdir(parents=True, exist_ok=True)
        tmp = campaign_file.with_suffix(".tmp")
        tmp.write_text(json.dumps(record, indent=2, allow_nan=False))
        os.replace(tmp, campaign_file)
    (out / "shards").mkdir(exist_ok=True)


def _execute_local(
    tasks: list[RunTask], workers: int, tmp_root: str | None = None
) -> Iterator[tuple[int, np.ndarray | None, str]]:
    if workers <= 1:
        for task in tasks:
            yield run_task(task, tmp_root)
        return
    ctx = get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, max_tasks_per_child=TASKS_PER_WORKER) as pool:
        pending = {pool.submit(run_task, t, tmp_root) for t in tasks[: 2 * workers]}
        queue = iter(tasks[2 * workers :])
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield fut.result()
                    nxt = next(queue, None)
                    if nxt is not None:
                        pending.add(pool.submit(run_task, nxt, tmp_root))
        finally:
            for fut in pending:
                fut.cancel()


def _execute_dask(tasks: list[RunTask], scheduler: str) -> Iterator[tuple[int, np.ndarray | None, str]]:
    from distributed import Client, as_completed

    with Client(scheduler) as client:
        futures = client.map(run_task, tasks, pure=False)
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            client.cancel(futures)


def run_campaign(
    config: CampaignConfig,
    out: Path,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    max_failed_share: float = MAX_FAILED_SHARE,
) -> Path:
    """Run (or resume) a campaign into ``out`` and return the path of the finished ``dataset.h5``.

    Args:
        config: what to simulate.
        out: dataset directory (created; an existing one is resumed if it holds the same campaign).
        workers: local worker processes (default: all cores); ignored with ``scheduler``.
        scheduler: address of a Dask scheduler (``tcp://host:port``) to run on instead of local processes.
        progress: show a progress bar (weeks done / total).
        max_failed_share: share of the planned runs EnergyPlus may refuse (a building whose warm-up never
            settles, say): those are left out of the dataset and listed in the manifest's ``failed_runs``.

    Local runs work in a temporary folder of this campaign's, removed when it ends or fails; folders left by
    killed processes are removed first (:func:`buildenv.energyplus.workdirs.remove_stale_run_folders`).

    Raises:
        DatasetError: ``out`` holds a different campaign.
        SimulationError: more runs failed than ``max_failed_share`` allows (the message quotes the first);
            finished runs stay saved and a rerun resumes, trying the failed runs again.
    """
    from tqdm import tqdm

    out = Path(out)
    tasks = plan_campaign(config)
    _prepare_directory(out, config)
    for stale in workdirs.remove_stale_run_folders():
        log.info("removed %s, left by a killed run", stale)
    if (out / "manifest.json").exists():
        log.info("%s is already complete", out)
        return out / "dataset.h5"
    todo = [t for t in tasks if not _shard_path(out, t.run_id).exists()]
    done_weeks = config.weeks - sum(t.n_weeks for t in todo)
    by_id = {t.run_id: t for t in tasks}
    started = time.perf_counter()
    workers = workers or os.cpu_count() or 1
    tmp_root = None if scheduler else str(workdirs.make_folder("campaign"))
    results = _execute_dask(todo, scheduler) if scheduler else _execute_local(todo, workers, tmp_root)
    failed: dict[int, dict] = {}
    try:
        with tqdm(total=config.weeks, initial=done_weeks, unit="week", desc="simulate", disable=not progress) as bar:
            for run_id, outputs, error in results:
                if outputs is None:
                    failed[run_id] = _record_failure(out, by_id[run_id], error)
                    log.warning("run %d left out of the campaign: %s", run_id, error)
                    if len(failed) > max_failed_share * len(tasks):
                        raise SimulationError(
                            f"{out}: {len(failed)} of {len(tasks)} EnergyPlus runs failed (more than "
                            f"{max_failed_share:.0%}); first: {next(iter(failed.values()))['error']}"
                        )
                else:
                    _write_shard(out, by_id[run_id], outputs)
                bar.update(by_id[run_id].n_weeks)
    finally:
        results.close()  # the workers stopped (their runs finished) before their folder goes
        if tmp_root is not None:
            shutil.rmtree(tmp_root, ignore_errors=True)
    elapsed = time.perf_counter() - started
    kept = [t for t in tasks if t.run_id not in failed]
    path = _consolidate(out, config, kept)
    manifest = {
        **_config_record(config),
        "complete": True,
        "weeks": sum(t.n_weeks for t in kept),
        "weeks_planned": config.weeks,
        "runs": len(kept),
        "failed_runs": [failed[r] for r in sorted(failed)],
        "weather": [str(resolve_epw(e)) for e in config.epw],
        "versions": _versions(),
        "seconds_last_session": round(elapsed, 1),
        "runs_simulated_last_session": len(todo),
        "weeks_simulated_last_session": config.weeks - done_weeks,
        "workers": None if scheduler else workers,
        "scheduler": scheduler,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "command": simulate_command(out.resolve(), asdict(config)),
        "files": {DATA_FILE: data_file_record(path)},  # checked by buildenv.campaign.dataset.open_dataset
    }
    tmp = out / "manifest.json.tmp"
    tmp.write_text(json.dumps(manifest, indent=2, allow_nan=False))
    os.replace(tmp, out / "manifest.json")
    shutil.rmtree(out / "shards", ignore_errors=True)
    return path


def _consolidate(out: Path, config: CampaignConfig, tasks: list[RunTask]) -> Path:
    """Gather the shards into one chunked HDF5 file (written under a temporary name, then renamed)."""
    import h5py

    from buildenv.weather.epw import load_weather

    n = sum(t.n_weeks for t in tasks)
    tmp, final = out / "dataset.h5.tmp", out / "dataset.h5"
    chunk = min(64, n)
    with h5py.File(tmp, "w") as h5:

        def make(name, shape, dtype=np.float32):
            return h5.create_dataset(
                name, shape=shape, dtype=dtype, chunks=(chunk,) + tuple(shape[1:]) if len(shape) > 1 else (chunk,)
            )

        d = {
            "theta": make("theta", (n, len(cat.THETA_NAMES))),
            "settings": make("settings", (n, 7, len(cat.SETTING_NAMES))),
            "occupancy": make("occupancy", (n, 5, len(cat.OCCUPANCY_NAMES))),
            "weather": make("weather", (n, cat.HOURS_PER_WEEK, len(cat.WEATHER_NAMES))),
            "outputs": make("outputs", (n, cat.HOURS_PER_WEEK, len(cat.OUTPUT_NAMES))),
            "run_id": make("run_id", (n,), np.int32),
            "week_in_run": make("week_in_run", (n,), np.int16),
            "week_of_year": make("week_of_year", (n,), np.int16),
            "weather_index": make("weather_index", (n,), np.int16),
        }
        offset = 0
        for task in tasks:
            k = task.n_weeks
            sl = slice(offset, offset + k)
            with np.load(_shard_path(out, task.run_id)) as shard:
                d["outputs"][sl] = shard["outputs"]
            d["theta"][sl] = np.broadcast_to(task.theta, (k, len(task.theta)))
            d["settings"][sl] = task.settings
            d["occupancy"][sl] = task.occupancy
            d["weather"][sl] = load_weather(task.epw).weeks(task.start_week, k)
            d["run_id"][sl] = task.run_id
            d["week_in_run"][sl] = np.arange(k)
            d["week_of_year"][sl] = task.start_week + np.arange(k)
            d["weather_index"][sl] = task.weather_index
            offset += k
        h5.attrs["catalogue_hash"] = cat.catalogue_hash()
        h5.attrs["weather_names"] = json.dumps(list(config.epw), allow_nan=False)
        for group, names in (
            ("theta", cat.THETA_NAMES),
            ("settings", cat.SETTING_NAMES),
            ("occupancy", cat.OCCUPANCY_NAMES),
            ("weather", cat.WEATHER_NAMES),
            ("outputs", cat.OUTPUT_NAMES),
        ):
            h5[group].attrs["names"] = json.dumps(list(names), allow_nan=False)
        units = {v.name: v.unit for v in cat.ALL_VARIABLES}
        h5.attrs["units"] = json.dumps(units, allow_nan=False)
    os.replace(tmp, final)
    return final
