"""Simulate consecutive weeks of the shoebox: theta_build + weekly I_k, O_k + weather -> hourly outputs."""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.energyplus import workdirs
from buildenv.energyplus.runner import read_hourly_csv, run_energyplus
from buildenv.energyplus.shoebox import (
    ACCEPTED_SEVERE,
    DEFAULT_ZONING,
    Geometry,
    build_epjson,
    output_keys,
    theta_dict,
    write_schedule_file,
    zone_names,
    zone_shares,
)
from buildenv.errors import SimulationError
from buildenv.weather.epw import load_weather

J_PER_WH = 3600.0


@dataclass(frozen=True)
class WeeksResult:
    """Hourly outputs of consecutive simulated weeks.

    Attributes:
        outputs: ``(weeks, 168, 8)`` in catalogue output order (Wh/m2 per hour; degC for T_INT_OFFICE).
        weather: ``(weeks, 168, 9)`` W_k of the same hours, catalogue weather order.
        start_week: week of year of the first week.
    """

    outputs: np.ndarray
    weather: np.ndarray
    start_week: int


def simulate_weeks(
    theta: np.ndarray | dict[str, float],
    settings: np.ndarray,
    occupancy: np.ndarray,
    epw: str | Path,
    start_week: int,
    workdir: Path | None = None,
    keep_files: bool = False,
    zoning: str = DEFAULT_ZONING,
) -> WeeksResult:
    """Run EnergyPlus for ``len(settings)`` consecutive weeks of one building.

    Args:
        theta: theta_build (catalogue order or ``{name: value}``).
        settings: I_k per week, ``(weeks, 7, 13)``; validated against the catalogue.
        occupancy: O_k per week, ``(weeks, 5, 2)``; validated against the catalogue.
        epw: weather short name or EPW path.
        start_week: week of year of the first week (0 = the week starting Monday January 1st).
        workdir: where EnergyPlus runs (a temporary directory, removed afterwards, if ``None``).
        keep_files: keep the model, schedules and EnergyPlus outputs in ``workdir``.
        zoning: ``single`` or ``core_perimeter`` (:mod:`buildenv.energyplus.shoebox`).
    Returns:
        :class:`WeeksResult`.
    """
    settings = np.asarray(settings, dtype=float)
    occupancy = np.asarray(occupancy, dtype=float)
    if settings.ndim == 2:
        settings = settings[None]
    if occupancy.ndim == 2:
        occupancy = occupancy[None]
    cat.check_values("settings", settings, "settings")
    cat.check_values("occupancy", occupancy, "occupancy")
    n_weeks = settings.shape[0]
    t = theta_dict(theta)
    weather = load_weather(epw)
    tmp = None
    if workdir is None:
        tmp = workdirs.make_folder("eplus")
        workdir = Path(tmp)
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        csv = write_schedule_file(workdir / "schedules.csv", t, settings, occupancy, start_week)
        model = build_epjson(t, weather, csv, start_week, n_weeks, zoning)
        if keep_files:
            (workdir / "shoebox.epJSON").write_text(json.dumps(model, indent=1))
        run_energyplus(model, weather.path, workdir, label="shoebox", accepted_severe=ACCEPTED_SEVERE)
        outputs = read_outputs(workdir / "eplusout.csv", t, n_weeks, zoning)
    finally:
        if tmp is not None and not keep_files:
            shutil.rmtree(tmp, ignore_errors=True)
    return WeeksResult(outputs, weather.weeks(start_week, n_weeks), start_week)


def read_outputs(csv_path: Path, theta: dict[str, float], n_weeks: int, zoning: str = DEFAULT_ZONING) -> np.ndarray:
    """The catalogue outputs of a finished shoebox run, ``(n_weeks, 168, 8)``.

    Energies are summed over the zones and divided by the floor area (Wh/m2 in the hour); the temperature
    is the floor-area weighted mean of the zones' air temperatures (degC), as a building's sensors read it.
    Raises :class:`SimulationError` if the run did not report ``n_weeks`` weeks of hours.
    """
    shares = zone_shares(Geometry.from_theta(theta), zoning)
    zones = zone_names(zoning)
    keys = {name: output_keys(name, zoning) for name in cat.OUTPUT_NAMES}
    pairs = {f"{name}|{zone}|{i}": pair for name in keys for zone in zones for i, pair in enumerate(keys[name][zone])}
    raw = read_hourly_csv(Path(csv_path), pairs)
    hours = n_weeks * cat.HOURS_PER_WEEK
    columns = []
    for name in cat.OUTPUT_NAMES:
        series = [sum(raw[f"{name}|{zone}|{i}"] for i in range(len(keys[name][zone]))) for zone in zones]
        if any(len(x) != hours for x in series):
            raise SimulationError(f"{csv_path}: EnergyPlus returned {len(series[0])} hours for {n_weeks} weeks")
        if name in cat.TEMPERATURE_OUTPUTS:
            columns.append(sum(shares[zone] * x for zone, x in zip(zones, series)))
        else:
            columns.append(sum(series) / J_PER_WH / theta["floor_area_m2"])
    return np.stack(columns, axis=-1).reshape(n_weeks, cat.HOURS_PER_WEEK, len(cat.OUTPUT_NAMES))
