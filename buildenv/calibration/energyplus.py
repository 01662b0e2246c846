"""Calibrating the EnergyPlus shoebox itself to a site: the paper's Table 2 baseline (the BEM, no metamodel).

The same problem as :mod:`buildenv.calibration.problem` (free parameters, bounds, cost and metrics all come
from there), but each candidate is simulated by EnergyPlus, the simulator the metamodel imitates; CMA-ES runs
until a wall-clock budget is used. A search can start from given parameters (a saved metamodel calibration)
and use ranges other than the catalogue's, past it too, for studies of the shoebox itself.

**One candidate, one EnergyPlus run** over the requested site weeks with the site's settings and weather,
from the week before the first requested one (a warm-up week, discarded, when the site has it: the metamodel
too reads context hours before each week) to the last, contiguously, so later weeks start from the state the
earlier ones left. Runs are placed on the site's calendar day by day
(:func:`buildenv.weather.epw.epw_day_of_year`), so EnergyPlus reads the weather hours the metamodel sees
(:meth:`buildenv.sites.Site.weather_hours`); a run past Dec 31 goes on at the start of the EPW
year as the metamodel's weeks do; weeks that would need Feb 29 are refused.

**Parallelism.** The candidates of a generation run in worker processes (:class:`ShoeboxPool`, one
EnergyPlus run each, spawned and warmed before the clock starts). A short run is dominated by EnergyPlus's
start-up and warm-up days, so a generation takes seconds where the metamodel scores thousands of candidates.

**Budget.** ``wall_seconds`` counts the CMA-ES loop only (ask, simulate, tell), as
:func:`buildenv.calibration.calibrate.calibrate_site`'s ``seconds`` counts its loop. A generation is not
started when the previous one's duration no longer fits in what is left (the first always runs). Scoring the
best candidate afterwards (fit and held-out weeks, two more EnergyPlus runs) is timed separately.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import os
import time
from collections.abc import Mapping
from contextlib import nullcontext
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.calibration.problem import (
    SIGMA0,
    CalibrationError,
    _scale,
    _split,
    build_problem,
    cmaes_strategy,
    costs,
    default_weeks,
    electricity_series,
    model_series,
    score_outputs,
)
from buildenv.campaign.runs import TASKS_PER_WORKER
from buildenv.energyplus import workdirs
from buildenv.energyplus.shoebox import ACCEPTED_SEVERE, DEFAULT_ZONING
from buildenv.metrics import GUIDELINE14_P

METHOD = "cmaes-energyplus"
HOURS_PER_YEAR = 8760
_EPW_YEAR = 2001  # the shoebox's calendar: a non-leap year that starts on a Monday, like the EPW rows
#: Longest run, weeks: one EnergyPlus run holds each calendar day once (its CSV has no year).
_MAX_RUN_WEEKS = 52


@dataclass(frozen=True)
class SiteRun:
    """One EnergyPlus run that covers some of a site's weeks (see the module docstring).

    Attributes:
        weather: the site's weather (EPW short name or path).
        first_day: EPW day index (0..364) of the run's first day, a Monday.
        settings: I_k of each simulated week, ``(run weeks, 7, 13)``.
        keep: indices of the requested weeks among the run's weeks, in request order.
        zoning: the shoebox's zoning (:data:`buildenv.energyplus.shoebox.ZONINGS`).
    """

    weather: str
    first_day: int
    settings: np.ndarray
    keep: tuple[int, ...]
    zoning: str = DEFAULT_ZONING

    @property
    def weeks(self) -> int:
        """Number of simulated weeks (requested weeks, any weeks between them and the warm-up week)."""
        return int(len(self.settings))


def plan_site_run(site, weeks: list[int], zoning: str = DEFAULT_ZONING) -> SiteRun:
    """The EnergyPlus run that simulates ``weeks`` (0-based site weeks) with the week before as warm-up, with
    the shoebox of ``zoning``.

    Raises:
        CalibrationError: no weeks, a week the site lacks, a run longer than 52 weeks or one that would need Feb 29.
    """
    if not weeks:
        raise CalibrationError("no weeks to simulate")
    bad = [w for w in weeks if not 0 <= w < site.weeks]
    if bad:
        raise CalibrationError(f"week(s) {bad} not in {site.path} (it has weeks 0..{site.weeks - 1})")
    first = max(min(weeks) - 1, 0)
    last = max(weeks)
    if last - first + 1 > _MAX_RUN_WEEKS:
        raise CalibrationError(
            f"site weeks {first}..{last} of {site.path} span more than a year ({_MAX_RUN_WEEKS} weeks at most, "
            "warm-up week included): choose fewer --weeks"
        )
    hours = site.epw_hours()[first : last + 1].reshape(-1)
    if not np.array_equal(hours, (hours[0] + np.arange(len(hours))) % HOURS_PER_YEAR):
        raise CalibrationError(
            f"site weeks {first}..{last} of {site.path} hold Feb 29, which the 365-day EPW year lacks (the "
            "metamodel reads Feb 28 twice, EnergyPlus cannot): choose other --weeks"
        )
    return SiteRun(
        str(site.weather),
        int(hours[0]) // cat.HOURS_PER_DAY,
        np.asarray(site.settings[first : last + 1]),
        tuple(w - first for w in weeks),
        zoning,
    )


def schedule_rows(theta: dict[str, float], run: SiteRun, occupancy: np.ndarray) -> np.ndarray:
    """Schedule:File rows ``(8760, columns)`` with the run's weeks placed at its first day.

    :func:`buildenv.energyplus.shoebox.schedule_table` places weeks at week-of-year boundaries; here they
    are shifted to the site's day of year (hours outside the run repeat its first week, never used).
    """
    from buildenv.energyplus.shoebox import schedule_table

    occ = np.broadcast_to(np.asarray(occupancy, float), (run.weeks, len(cat.WEEKDAYS), 2))
    table = schedule_table(theta, run.settings, occ, 0)
    return np.roll(table, run.first_day * cat.HOURS_PER_DAY, axis=0)


def simulate_site_run(
    run: SiteRun, theta: np.ndarray, occupancy: np.ndarray, workdir: Path | None = None, within_catalogue: bool = True
) -> np.ndarray:
    """Simulate one candidate with EnergyPlus over a site run.

    Args:
        run: what to simulate (:func:`plan_site_run`).
        theta: theta_build ``(21,)``, catalogue order, physical units (geometry included).
        occupancy: weekday occupancy ``(5, 2)`` (start hour, end hour), used in every week.
        workdir: where EnergyPlus runs (a temporary directory, removed afterwards, if ``None``).
        within_catalogue: refuse a theta_build outside the catalogue's ranges (``False`` runs it, for
            sensitivity studies past them).
    Returns:
        outputs of the requested weeks, ``(len(run.keep), 168, 8)``, catalogue output order (Wh/m2 in the
        hour; degC for T_INT_OFFICE).
    Raises:
        SimulationError: EnergyPlus failed.
    """
    import pandas as pd

    from buildenv.energyplus.runner import WARMUP_TEMPERATURE_LIMIT_K, run_energyplus, run_period_rows
    from buildenv.energyplus.shoebox import (
        SCHEDULE_COLUMNS,
        build_epjson,
        theta_dict,
    )
    from buildenv.energyplus.simulate import read_outputs
    from buildenv.weather.epw import load_weather

    t = theta_dict(np.asarray(theta, float), check=within_catalogue)
    cat.check_values("occupancy", np.asarray(occupancy, float), "occupancy")
    weather = load_weather(run.weather)
    with nullcontext(workdir) if workdir is not None else workdirs.temporary_folder("calib") as tmp:
        work = Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        csv = work / "schedules.csv"
        np.savetxt(
            csv,
            schedule_rows(t, run, occupancy),
            delimiter=",",
            fmt="%.4f",
            header=",".join(SCHEDULE_COLUMNS),
            comments="",
        )
        model = build_epjson(t, weather, csv, 0, run.weeks, run.zoning, check=within_catalogue)
        first = dt.date(_EPW_YEAR, 1, 1) + dt.timedelta(days=run.first_day)
        last = first + dt.timedelta(days=7 * run.weeks - 1)
        model["RunPeriod"]["weeks"].update(
            begin_month=first.month, begin_day_of_month=first.day, end_month=last.month, end_day_of_month=last.day
        )
        if last.year > first.year:  # past Dec 31: the same EPW year again, the schedules' rows wrapped alike
            model["RunPeriod"]["weeks"].update(begin_year=first.year, end_year=last.year)
        # a run that discards a warm-up week may start from any warm-up that settled (runner.warmup_settled)
        limit = math.inf if min(run.keep) > 0 else WARMUP_TEMPERATURE_LIMIT_K
        run_energyplus(
            model, weather.path, work, label="shoebox", accepted_severe=ACCEPTED_SEVERE, warmup_limit_k=limit
        )
        if last.year > first.year:  # EnergyPlus lists the new year's hours first
            csv_path = work / "eplusout.csv"
            run_period_rows(pd.read_csv(csv_path), first, run.weeks * cat.HOURS_PER_WEEK, csv_path).to_csv(
                csv_path, index=False
            )
        outputs = read_outputs(work / "eplusout.csv", t, run.weeks, run.zoning)
    return outputs[list(run.keep)]


def _simulate_task(task: tuple[SiteRun, np.ndarray, np.ndarray, bool]) -> np.ndarray:
    run, theta, occupancy, within_catalogue = task
    return simulate_site_run(run, theta, occupancy, within_catalogue=within_catalogue)


def _warm(_: int = 0) -> int:
    """Import what a simulation needs (in a worker); the short sleep lets each worker take one call."""
    import buildenv.energyplus.runner  # noqa: F401  (imports pyenergyplus, pandas)
    import buildenv.energyplus.shoebox  # noqa: F401
    import buildenv.weather.epw  # noqa: F401

    time.sleep(0.2)
    return os.getpid()


class ShoeboxPool:
    """Worker processes that simulate candidates in parallel (a context manager).

    A ``multiprocessing`` pool recycles its workers after :data:`buildenv.campaign.runs.TASKS_PER_WORKER` runs
    (``concurrent.futures.ProcessPoolExecutor`` with ``max_tasks_per_child`` can deadlock on Python 3.11-3.13
    when a worker retires with tasks queued, CPython gh-115634).

    Args:
        workers: number of processes (default: all cores); 1 runs in the calling process.
        tasks_per_worker: EnergyPlus runs after which a worker process is replaced.
        within_catalogue: refuse candidates outside the catalogue's ranges (:func:`simulate_site_run`).
    """

    def __init__(
        self, workers: int | None = None, tasks_per_worker: int = TASKS_PER_WORKER, within_catalogue: bool = True
    ):
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.tasks_per_worker = tasks_per_worker
        self.within_catalogue = within_catalogue
        self._pool = None

    def __enter__(self) -> ShoeboxPool:
        if self.workers > 1:
            self._pool = get_context("spawn").Pool(
                self.workers, initializer=_warm, maxtasksperchild=self.tasks_per_worker
            )
            self._pool.map(_warm, range(self.workers), chunksize=1)  # spawned and imported before any clock starts
        else:
            _warm()
        return self

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None

    def simulate(self, run: SiteRun, theta: np.ndarray, occupancy: np.ndarray) -> np.ndarray:
        """Outputs ``(pop, len(run.keep), 168, 8)`` of candidates ``theta (pop, 21)``, ``occupancy (pop, 5, 2)``."""
        return np.stack(self.simulate_runs([run] * len(theta), theta, occupancy))

    def simulate_runs(self, runs: list[SiteRun], theta: np.ndarray, occupancy: np.ndarray) -> list[np.ndarray]:
        """Outputs ``[(len(run.keep), 168, 8)]`` of each run with its own ``theta[i]`` and ``occupancy[i]``."""
        tasks = [(run, th, oc, self.within_catalogue) for run, th, oc in zip(runs, theta, occupancy)]
        if self._pool is None:
            return [_simulate_task(t) for t in tasks]
        return self._pool.map(_simulate_task, tasks, chunksize=1)


def evaluate_energyplus(problem, run: SiteRun, pool: ShoeboxPool, params: np.ndarray) -> np.ndarray:
    """Costs ``(pop,)`` (:func:`buildenv.calibration.problem.costs`) of physical parameters ``(pop, dim)``, by
    EnergyPlus."""
    theta, occ = _split(problem, np.atleast_2d(params))
    outputs = pool.simulate(run, theta, occ)
    return costs(problem, *model_series(problem, outputs), electricity_series(problem, outputs))


def calibrate_energyplus_cmaes(
    site,
    weeks: list[int] | None = None,
    seed: int = 0,
    wall_seconds: float = 60.0,
    workers: int | None = None,
    progress: bool = False,
    zoning: str = DEFAULT_ZONING,
    start: np.ndarray | None = None,
    sigma0: float = SIGMA0,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> dict:
    """Calibrate the EnergyPlus shoebox to a site with CMA-ES under a wall-clock budget, and score it.

    By default the same free parameters, bounds, start point, step size and cost as
    :func:`buildenv.calibration.calibrate.calibrate_site` with ``method="cmaes"``; fit and held-out weeks are scored
    with the same metrics on EnergyPlus outputs.

    Args:
        site: a :class:`buildenv.sites.Site`.
        weeks: calibration weeks (0-based); the site's other weeks are held out.
            Default :func:`buildenv.calibration.problem.default_weeks`.
        seed: seed of the optimiser.
        wall_seconds: wall-clock budget of the CMA-ES loop, s (see the module docstring).
        workers: worker processes (default: all cores).
        progress: progress bar (generations).
        zoning: the shoebox's zoning (:data:`buildenv.energyplus.shoebox.ZONINGS`).
        start: physical parameters ``(dim,)`` (:func:`buildenv.calibration.problem.parameter_names` order) the search
            starts from, e.g. a saved calibration's (:func:`parameters_of`); default the centre of the bounds.
        sigma0: initial step size, in units of each parameter's range.
        ranges: ``{building parameter: (low, high)}`` replacing the catalogue's range of those parameters,
            for studies of what the shoebox reaches past the catalogue (candidates outside it are simulated:
            ``ShoeboxPool(within_catalogue=False)``); the metamodel cannot follow such a calibration.
    Returns:
        ``{"method": "cmaes-energyplus", "seconds" (loop, s), "wall_seconds" (budget, s), "evaluations",
        "generations", "cost", "history": [[s, evaluations, best cost] per generation], "scoring_seconds",
        "workers", "zoning", "fit_weeks", "heldout_weeks", "start" ("centre" or "given"), "sigma0", "ranges",
        "guideline14_p", "theta", "known", "occupancy", "catalogue_hash", "fit": metrics,
        "heldout": metrics}`` (metrics as :func:`buildenv.metrics.site_metrics`).
    Raises:
        CalibrationError: a non-positive budget, weeks EnergyPlus cannot run (see :func:`plan_site_run`), a
            start of the wrong length, or a range that is not a free building parameter's or is empty.
    """
    from tqdm import tqdm

    if not wall_seconds > 0:
        raise CalibrationError(f"wall_seconds must be positive (got {wall_seconds})")
    fit_weeks, heldout = (
        default_weeks(site.weeks)
        if weeks is None
        else (sorted(weeks), [w for w in range(site.weeks) if w not in weeks])
    )
    problem = with_ranges(build_problem(site, fit_weeks), ranges or {})
    if start is not None and np.shape(start) != (problem.dim,):
        raise CalibrationError(f"start has shape {np.shape(start)}; the problem has {problem.dim} parameters")
    run = plan_site_run(site, fit_weeks, zoning)
    if heldout:
        plan_site_run(site, heldout, zoning)  # refuse weeks EnergyPlus cannot score before spending the budget
    history: list[list[float]] = []
    x0 = None if start is None else problem.to_unit(np.clip(start, problem.lo, problem.hi))
    with ShoeboxPool(workers, within_catalogue=not ranges) as pool:
        es = cmaes_strategy(int(problem.free.sum()), seed, sigma0=sigma0, x0=x0)
        bar = tqdm(desc="CMA-ES (EnergyPlus)", unit="generation", disable=not progress, leave=False)
        started = time.perf_counter()
        last = 0.0
        while not es.stop():
            elapsed = time.perf_counter() - started
            if history and elapsed + last > wall_seconds:
                break
            z = np.asarray(es.ask())
            f = evaluate_energyplus(problem, run, pool, problem.from_unit(z))
            es.tell(list(z), f.tolist())
            last = time.perf_counter() - started - elapsed
            history.append(
                [round(time.perf_counter() - started, 2), int(es.result.evaluations), float(es.result.fbest)]
            )
            bar.update(1)
            bar.set_postfix(cost=f"{es.result.fbest:.4f}")
        seconds = time.perf_counter() - started
        bar.close()
        best = problem.from_unit(np.asarray(es.result.xbest))[0]
        scoring = time.perf_counter()
        scores = score_energyplus(site, best, fit_weeks, heldout, pool, zoning)
        scoring_seconds = time.perf_counter() - scoring
    theta, occ = _split(problem, best[None])
    result = {
        "method": METHOD,
        "seconds": round(seconds, 2),
        "wall_seconds": wall_seconds,
        "evaluations": int(es.result.evaluations),
        "generations": len(history),
        "cost": float(es.result.fbest),
        "history": history,
        "scoring_seconds": round(scoring_seconds, 2),
        "workers": pool.workers,
        "zoning": zoning,
        "fit_weeks": fit_weeks,
        "heldout_weeks": heldout,
        "start": "centre" if start is None else "given",
        "sigma0": sigma0,
        "ranges": {name: list(map(float, r)) for name, r in (ranges or {}).items()},
        "guideline14_p": GUIDELINE14_P,
        "theta": dict(zip(cat.THETA_NAMES, np.round(theta[0], 5).tolist())),
        "known": sorted(site.known),
        "occupancy": np.round(occ[0], 3).tolist(),
        "catalogue_hash": cat.catalogue_hash(),
    }
    for key, metrics in scores.items():
        result[key] = {**metrics, "seconds": result["seconds"], "evaluations": result["evaluations"]}
    return result


def with_ranges(problem, ranges: Mapping[str, tuple[float, float]]):
    """``problem`` (:class:`buildenv.calibration.problem.Problem`) with the bounds of some free building parameters
    replaced, ``{name: (low, high)}``; raises :class:`CalibrationError` for a name that is not a free building
    parameter of the problem or an empty range."""
    lo, hi = problem.lo.copy(), problem.hi.copy()
    for name, (low, high) in ranges.items():
        j = problem.names.index(name) if name in cat.THETA_NAMES and name in problem.names else None
        if j is None or not problem.free[j]:
            raise CalibrationError(f"range given for {name!r}, which is not a free building parameter of this site")
        if not low < high:
            raise CalibrationError(f"range of {name}: low {low} is not below high {high}")
        lo[j], hi[j] = float(low), float(high)
    return dataclasses.replace(problem, lo=lo, hi=hi)


def score_energyplus(
    site,
    params: np.ndarray,
    fit_weeks: list[int],
    heldout: list[int],
    pool: ShoeboxPool | None = None,
    zoning: str = DEFAULT_ZONING,
) -> dict[str, dict[str, float]]:
    """Metrics of physical parameters ``params (dim,)`` simulated by EnergyPlus on fit and held-out weeks.

    Standardised MSEs use the fit weeks' measured mean and standard deviation, as
    :func:`buildenv.calibration.calibrate.calibrate_site` does. Returns ``{"fit": metrics, "heldout": metrics}``
    (``heldout`` only if there are held-out weeks); each set of weeks is one EnergyPlus run with the week
    before it as warm-up (:func:`plan_site_run`).
    """
    problem = build_problem(site, fit_weeks)
    scale = _scale(problem)
    theta, occ = _split(problem, np.asarray(params, float)[None])
    out: dict[str, dict[str, float]] = {}
    with ShoeboxPool(1) if pool is None else nullcontext(pool) as runner:
        for key, weeks in (("fit", fit_weeks), ("heldout", heldout)):
            if weeks:
                outputs = runner.simulate(plan_site_run(site, weeks, zoning), theta, occ)[0]
                out[key] = score_outputs(build_problem(site, weeks), outputs, np.asarray(params, float), scale)
    return out


def parameters_of(result: dict) -> np.ndarray:
    """Physical parameter vector ``(dim,)`` (:func:`buildenv.calibration.problem.parameter_names` order) of a
    calibration result (``calibration.json`` or a :func:`calibrate_energyplus_cmaes` result)."""
    from buildenv.calibration.problem import free_theta

    theta = [float(result["theta"][name]) for name in free_theta()]
    occupancy = np.asarray(result["occupancy"], float).reshape(-1)
    return np.concatenate([theta, occupancy])
