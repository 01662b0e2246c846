"""Writing a site folder that :func:`buildenv.sites.reader.load_site` reads back, and a site's calibration.

:func:`write_site` writes ``site.toml`` (with ``tomli_w``), ``measurements.csv``, ``settings.csv`` and
``truth.json``; :func:`save_calibration` writes ``calibration.json`` atomically.
"""

from __future__ import annotations

import calendar
import datetime as dt
import json
import math
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from buildenv import catalogue as cat
from buildenv.errors import CatalogueError, SiteError
from buildenv.jsonio import dumps
from buildenv.sites.model import (
    CALIBRATION_FILE,
    DEFAULT_MEASUREMENTS,
    DEFAULT_SETTINGS,
    DESCRIPTOR,
    ELECTRICITY_COLUMN,
    MEASUREMENT_COLUMNS,
    SETTINGS_COLUMNS,
    TRUTH_FILE,
)
from buildenv.sites.reader import load_site
from buildenv.sites.timestamps import _fmt


def _toml_plain(value: Any, where: str) -> Any:
    """``value`` as the plain Python types ``tomli_w`` writes (numpy scalars and arrays, paths, tuples)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, (str, Path)):
        return str(value)
    if isinstance(value, (dt.date, dt.datetime)):
        return value
    if isinstance(value, Mapping):
        return {str(k): _toml_plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_toml_plain(v, where) for v in list(value)]
    raise SiteError(f"{where}: cannot write a {type(value).__name__} to TOML ({value!r})")


def _toml_number(value: float) -> int | float:
    """A whole number as an int (``5000`` rather than ``5000.0``), any other as a float."""
    value = float(value)
    return int(value) if value.is_integer() and abs(value) < 2**53 else value


def _cell(value: float, decimals: int) -> str:
    return "" if not math.isfinite(value) else f"{value:.{decimals}f}"


def _setting_cell(value: float) -> str:
    return np.format_float_positional(round(float(value), 6), trim="-")


def _atomic_write(path: Path, text: str) -> None:
    with tempfile.NamedTemporaryFile(
        "w", encoding="utf-8", dir=path.parent, prefix=f".{path.name}.", suffix=".tmp", delete=False, newline=""
    ) as handle:
        handle.write(text)
        tmp = Path(handle.name)
    try:
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would make the file private to its writer
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (Path, dt.date)):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_site(
    path: str | os.PathLike,
    *,
    name: str,
    weather: str | os.PathLike,
    start: dt.date,
    floor_area_m2: float,
    number_of_floors: int,
    settings: np.ndarray,
    temperature_c: np.ndarray,
    consumption_kwh: np.ndarray,
    source: Mapping[str, Any] | None = None,
    truth: Mapping[str, Any] | None = None,
    known: Mapping[str, float] | None = None,
    effects: tuple[str, ...] = (),
    consumption_end_uses: tuple[str, ...] = cat.DEFAULT_END_USES,
    controllable: tuple[str, ...] = cat.SETTING_NAMES,
    setting_limits: Mapping[str, tuple[float, float]] | None = None,
    electricity_kwh: np.ndarray | None = None,
    electricity_end_uses: tuple[str, ...] = (),
) -> Path:
    """Write a site folder that :func:`buildenv.sites.load_site` reads back, then validate it by loading it.

    Writes ``site.toml``, ``measurements.csv`` (NaN -> empty cell; temperature with 3 decimals, kWh with 4;
    every hour of every week gets a row), ``settings.csv`` (6 decimals at most) and ``truth.json`` when
    ``truth`` is given. A ``calibration.json`` or ``truth.json`` left from an earlier site in the folder is
    removed (it described other data). The files are written into a temporary folder beside ``path`` and moved
    into place; on any error nothing is left behind (a folder this call made is removed, an existing one keeps
    its earlier files).

    Args:
        path: the site folder (created if needed).
        name: free text.
        weather: an EPW short name or path (a relative path is read relative to the site folder).
        start: Monday of the first week (a ``datetime`` is reduced to its date).
        floor_area_m2: floor area, m2, within the catalogue range.
        number_of_floors: storeys, within the catalogue range.
        settings: ``(weeks, 7, 13)`` BMS settings, catalogue order, in catalogue units.
        temperature_c: ``(weeks, 168)`` hourly indoor temperature, degC, NaN where missing.
        consumption_kwh: ``(weeks, 168)`` hourly consumption of ``consumption_end_uses``, kWh, NaN where missing.
        source: free ``[source]`` table (strings, numbers, booleans, lists, nested tables).
        known: ``[known]`` table, ``{theta_build name: value}`` in catalogue units (:attr:`buildenv.sites.Site.known`).
        effects: effects the building is known to have (:attr:`buildenv.sites.Site.effects`).
        consumption_end_uses: end uses the consumption sums (:attr:`buildenv.sites.Site.consumption_end_uses`);
            written as ``[meters]`` unless they are the default.
        controllable: settings the BMS can change (:attr:`buildenv.sites.Site.controllable`); written as ``[bms]
            controllable`` unless all 13.
        setting_limits: ``{controllable setting: (min, max)}``, catalogue units
            (:attr:`buildenv.sites.Site.setting_limits`); written as ``[bms.limits]`` when given.
        electricity_kwh: ``(weeks, 168)`` hourly consumption of a second meter, kWh, NaN where missing
            (:attr:`buildenv.sites.Site.electricity_kwh`); None: one meter.
        electricity_end_uses: end uses the second meter sums (with ``electricity_kwh``), written as ``[meters]``.
        truth: true parameters of a synthetic site, written as ``truth.json``.

    Returns:
        the site folder.

    Raises:
        SiteError: wrong shapes, a start that is not a Monday, or values :func:`buildenv.sites.load_site` rejects.
    """
    folder = Path(path).expanduser()
    if isinstance(start, dt.datetime):
        start = start.date()
    if start.weekday() != 0:
        raise SiteError(f"write_site: start {start} is a {calendar.day_name[start.weekday()]}, not a Monday")
    temperature = np.asarray(temperature_c, dtype=float)
    consumption = np.asarray(consumption_kwh, dtype=float)
    setting_values = np.asarray(settings, dtype=float)
    if temperature.ndim != 2 or temperature.shape[1] != cat.HOURS_PER_WEEK or temperature.shape[0] < 1:
        raise SiteError(f"write_site: temperature_c has shape {temperature.shape}, expected (weeks, 168)")
    weeks = temperature.shape[0]
    if consumption.shape != temperature.shape:
        raise SiteError(f"write_site: consumption_kwh has shape {consumption.shape}, expected {temperature.shape}")
    electricity = None if electricity_kwh is None else np.asarray(electricity_kwh, dtype=float)
    if electricity is not None and electricity.shape != temperature.shape:
        raise SiteError(f"write_site: electricity_kwh has shape {electricity.shape}, expected {temperature.shape}")
    if (electricity is None) != (not electricity_end_uses):
        raise SiteError("write_site: give electricity_kwh and electricity_end_uses together, or neither")
    if setting_values.shape[-1:] == (len(cat.SETTINGS) - 1,):  # written before hvac_operating: every day operates
        setting_values = cat.upgrade_settings(setting_values)
    if setting_values.shape != (weeks, 7, len(cat.SETTINGS)):
        raise SiteError(
            f"write_site: settings has shape {setting_values.shape}, expected ({weeks}, 7, {len(cat.SETTINGS)})"
        )
    for j, var in enumerate(cat.SETTINGS):  # a switch is on or off: the first day that is neither is named
        between = np.argwhere(var.between_ends(setting_values[..., j]))
        if len(between):
            w, d = between[0]
            try:
                var.check_switch(setting_values[w, d, j], f"the settings of week {w}, {cat.DAYS[d]}")
            except CatalogueError as exc:
                raise SiteError(f"write_site: {exc}") from exc

    if folder.exists() and not folder.is_dir():
        raise SiteError(f"write_site: {folder} exists and is not a folder")
    descriptor: dict[str, Any] = {"name": str(name), "weather": str(weather)}
    if effects:
        descriptor["effects"] = [str(e) for e in effects]
    descriptor["geometry"] = {"floor_area_m2": _toml_number(floor_area_m2), "number_of_floors": int(number_of_floors)}
    if known:
        descriptor["known"] = {k: float(v) for k, v in known.items()}
    meters: dict[str, list[str]] = {}
    if list(consumption_end_uses) != list(cat.DEFAULT_END_USES):
        meters["consumption"] = [str(u) for u in consumption_end_uses]
    if electricity_end_uses:
        meters["electricity"] = [str(u) for u in electricity_end_uses]
    if meters:
        descriptor["meters"] = meters
    bms: dict[str, Any] = {}
    if set(controllable) != set(cat.SETTING_NAMES) or len(controllable) != len(cat.SETTING_NAMES):
        bms["controllable"] = [str(n) for n in controllable]
    if setting_limits:
        bms["limits"] = {str(k): [_toml_number(v) for v in lim] for k, lim in setting_limits.items()}
    if bms:
        descriptor["bms"] = bms
    if source:
        descriptor["source"] = _toml_plain(dict(source), "source")
    files = {DESCRIPTOR: tomli_w.dumps(descriptor)}

    columns = MEASUREMENT_COLUMNS + ((ELECTRICITY_COLUMN,) if electricity is not None else ())
    out = [",".join(columns)]
    t_flat, q_flat = temperature.ravel(), consumption.ravel()
    e_flat = None if electricity is None else electricity.ravel()
    first = dt.datetime.combine(start, dt.time())
    for h in range(weeks * cat.HOURS_PER_WEEK):
        stamp = first + dt.timedelta(hours=h)
        second = "" if e_flat is None else f",{_cell(e_flat[h], 4)}"
        out.append(f"{_fmt(stamp)},{_cell(t_flat[h], 3)},{_cell(q_flat[h], 4)}{second}")
    files[DEFAULT_MEASUREMENTS] = "\n".join(out) + "\n"

    out = [",".join(SETTINGS_COLUMNS)]
    for d, row in enumerate(setting_values.reshape(weeks * 7, -1)):
        out.append(",".join([(start + dt.timedelta(days=d)).isoformat(), *(_setting_cell(v) for v in row)]))
    files[DEFAULT_SETTINGS] = "\n".join(out) + "\n"

    if truth is not None:
        files[TRUTH_FILE] = dumps(dict(truth), where=str(folder / TRUTH_FILE), indent=2, default=_json_default) + "\n"
    _place_site(folder, files)
    return folder


#: the files a site folder written by :func:`write_site` may hold; those it does not write again are removed
_SITE_FILES = (DESCRIPTOR, DEFAULT_MEASUREMENTS, DEFAULT_SETTINGS, TRUTH_FILE, CALIBRATION_FILE)


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and those of its parents that do not exist yet, innermost first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def _place_site(folder: Path, files: Mapping[str, str]) -> None:
    """Write ``files`` (``{name: text}``) as the site folder ``folder`` and check that it loads, leaving nothing
    behind on any error: the files are written into a hidden temporary folder beside ``folder``; a new folder is
    that one renamed into place, an existing one gets them by ``os.replace`` (its earlier site files moved aside,
    and back on an error). A folder, or parent folder, this call made is removed again on an error.

    Raises:
        SiteError: what is written does not load (:func:`buildenv.sites.load_site`), or a file cannot be written.
    """
    made = _missing_folders(folder)
    tag = f"{os.getpid()}.{os.urandom(4).hex()}"
    stage = folder.parent / f".{folder.name}.{tag}.writing"
    aside = folder.parent / f".{folder.name}.{tag}.previous"
    placed: list[str] = []
    moved: list[str] = []
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        stage.mkdir()
        for name, text in files.items():
            (stage / name).write_text(text, encoding="utf-8")
        if made:  # a new folder: the complete one appears at once
            os.rename(stage, folder)
            placed = list(files)
        else:
            aside.mkdir()
            for name in _SITE_FILES:
                if (folder / name).is_file():
                    os.replace(folder / name, aside / name)
                    moved.append(name)
            for name in files:
                os.replace(stage / name, folder / name)
                placed.append(name)
        load_site(folder)  # what is written must load: raises SiteError with file:line otherwise
    except BaseException as error:
        if made:
            if placed:  # renamed into place: ours
                shutil.rmtree(folder, ignore_errors=True)
            for parent in made[1:]:  # innermost first; only the empty ones this call made
                try:
                    parent.rmdir()
                except OSError:
                    break
        else:
            for name in placed:
                (folder / name).unlink(missing_ok=True)
            for name in moved:
                os.replace(aside / name, folder / name)
        shutil.rmtree(stage, ignore_errors=True)
        shutil.rmtree(aside, ignore_errors=True)
        if isinstance(error, OSError):
            raise SiteError(f"write_site: cannot write the site folder {folder}: {error}") from error
        raise
    shutil.rmtree(stage, ignore_errors=True)
    shutil.rmtree(aside, ignore_errors=True)


def save_calibration(site_path: str | os.PathLike, result: Mapping[str, Any]) -> Path:
    """Write ``result`` as the site's ``calibration.json``, atomically (temporary file + ``os.replace``).

    Args:
        site_path: the site folder.
        result: a JSON-serialisable mapping (numpy arrays and scalars are converted to lists and numbers).

    Returns:
        the path of ``calibration.json``.

    Raises:
        SiteError: the folder is not a site folder or ``result`` cannot be written as JSON.
    """
    folder = Path(site_path).expanduser()
    if not (folder / DESCRIPTOR).is_file():
        raise SiteError(f"{folder}: not a site folder ({DESCRIPTOR} is missing)")
    try:
        text = json.dumps(dict(result), indent=2, default=_json_default) + "\n"
    except (TypeError, ValueError) as exc:
        raise SiteError(f"{folder / CALIBRATION_FILE}: cannot write the calibration as JSON: {exc}") from exc
    target = folder / CALIBRATION_FILE
    _atomic_write(target, text)
    return target
