"""BuildingWeek-v0's ``backend="energyplus"``: the same weeks run on the site's real-building EnergyPlus model.

A site made by ``buildenv site reference`` records the reference building it stands in for (``truth.json``);
its weeks can then be run under any settings, so optimised settings are checked on the building itself,
not on the metamodel that chose them. Each week runs with the previous week's settings as one warm-up week
(the historical settings unless given), as the metamodel's context, across a new year where the week before
lies in the previous one. Weeks run in parallel processes, with the stand-in's mapping the site was made with
(:func:`buildenv.energyplus.reference.stand_in_version`) and the schedules it named, if any
(:func:`buildenv.energyplus.reference.recorded_schedule_map`).

The HVAC energy is the reference's heating + cooling coil energy (:mod:`buildenv.energyplus.reference`), the
temperature its occupied-zone mean, both without sensor noise.
"""

from __future__ import annotations

import datetime as dt
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildingEnvError


def reference_building(site) -> str:
    """The reference building (name or IDF path) a site stands in for; raises if it has none."""
    building = (site.truth or {}).get("building")
    if not building:
        raise BuildingEnvError(
            f"site {site.path} has no EnergyPlus model (truth.json names none): "
            "backend='energyplus' needs a site made by `buildenv site reference`"
        )
    return str(building)


def _run_one(
    building: str,
    epw: str,
    monday: dt.date,
    settings: np.ndarray,
    previous: np.ndarray,
    stand_in: int,
    schedule_map,
    steady_day: dt.date,
) -> tuple[np.ndarray, np.ndarray, float]:
    from buildenv.energyplus.reference import run_reference

    week = np.stack([previous, settings])
    run = run_reference(
        building,
        epw,
        monday - dt.timedelta(days=7),
        week,
        warmup_weeks=1,
        schedule_map=schedule_map,
        stand_in=stand_in,
        steady_day=steady_day,
    )
    return run.temperature_c[1], run.hvac_kwh[1], run.floor_area_m2


def run_weeks(
    site,
    week_starts: list[dt.date],
    settings: np.ndarray,
    previous: np.ndarray | None = None,
    historical: np.ndarray | None = None,
    workers: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Run weeks on the site's reference model.

    Args:
        site: a :class:`buildenv.sites.Site` made by ``buildenv site reference``.
        week_starts: the Monday of each week ``(N)``.
        settings: settings of each week ``(N, 7, 13)``.
        previous: settings of each preceding week ``(N, 7, 13)``; default ``historical``.
        historical: the site's historical settings ``(7, 13)`` (default: its first measured week's).
        workers: parallel EnergyPlus processes (default: the CPU count).
    Returns:
        occupied-zone mean temperature ``(N, 168)`` degC and HVAC energy ``(N, 168)`` Wh/m2 per hour.
    """
    building = reference_building(site)
    settings = np.asarray(settings, dtype=float)
    hist = np.asarray(site.settings[0] if historical is None else historical, dtype=float)
    prev = np.broadcast_to(hist, settings.shape) if previous is None else np.asarray(previous, dtype=float)
    from buildenv.energyplus.reference import recorded_schedule_map, site_steady_day, stand_in_version

    version, mapping, steady = stand_in_version(site), recorded_schedule_map(site), site_steady_day(site)
    jobs = [
        (building, site.weather, monday, settings[i], prev[i], version, mapping, steady)
        for i, monday in enumerate(week_starts)
    ]
    workers = max(1, min(len(jobs), workers or os.cpu_count() or 1))
    if workers == 1:
        results = [_run_one(*job) for job in jobs]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            results = list(pool.map(_run_one, *zip(*jobs)))
    temperature = np.stack([r[0] for r in results])
    hvac = np.stack([r[1] for r in results]) * 1000.0 / float(site.floor_area_m2)
    return temperature, hvac


def as_outputs(temperature: np.ndarray, hvac_wh_m2: np.ndarray) -> np.ndarray:
    """Pack reference readings as catalogue outputs ``(N, 168, 8)`` (HVAC energy on Q_HEAT_OFFICE, others 0)
    so the environment scores them exactly as metamodel outputs."""
    out = np.zeros((*np.shape(temperature), len(cat.OUTPUT_NAMES)))
    out[..., cat.OUTPUT_NAMES.index("T_INT_OFFICE")] = temperature
    out[..., cat.OUTPUT_NAMES.index("Q_HEAT_OFFICE")] = hvac_wh_m2
    return out
