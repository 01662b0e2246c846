"""Reading a site folder with strict validation: :func:`load_site`, ``site.toml`` and ``settings.csv``.

:func:`load_site` parses ``site.toml``, ``measurements.csv`` and ``settings.csv`` (and ``calibration.json`` and
``truth.json`` when present) into a :class:`buildenv.sites.model.Site`, whose module gives the format's names
and conventions; :func:`known_parameter` checks one ``[known]`` value, :func:`check_end_uses` the end uses of
``[meters]``, :func:`check_controllable` and :func:`check_setting_limit` the ``[bms]`` table. Every problem
raises :class:`~buildenv.errors.SiteError` with a one-line ``"<file>:<line>: <what is wrong>"`` message (line 1
is the CSV header). The format for users is ``docs/site-format.md``.

``measurements.csv`` is read by :mod:`.measurements` (its timestamps by :mod:`.timestamps`, its consumption
series by :mod:`.consumption`) as ``[measurements]`` (:mod:`.measurement_options`) says; the rows and cells of
both CSV files by :mod:`.cells`.
"""

from __future__ import annotations

import datetime as dt
import difflib
import json
import logging
import math
import os
import re
import zoneinfo
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from buildenv import catalogue as cat
from buildenv.diagnosis.effects import EffectError, check_declarable
from buildenv.errors import CatalogueError, SiteError
from buildenv.sites.cells import _check_width, _parse_value, _rows, _separator_hint
from buildenv.sites.measurement_options import _MeasurementOptions
from buildenv.sites.measurements import _read_measurements
from buildenv.sites.model import (
    BMS_KEYS,
    CALIBRATION_FILE,
    DEFAULT_MEASUREMENTS,
    DEFAULT_SETTINGS,
    DESCRIPTOR,
    ELECTRICITY_COLUMN,
    GEOMETRY_KEYS,
    KNOWN_KEYS,
    MEASUREMENT_COLUMNS,
    MEASUREMENTS_KEYS,
    METER_KEYS,
    SETTINGS_COLUMNS,
    TOP_LEVEL_KEYS,
    TRUTH_FILE,
    Site,
)
from buildenv.sites.timestamps import named_time_zone

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

log = logging.getLogger(__name__)

_DATE = re.compile(r"(\d{4})-(\d{2})-(\d{2})")


def load_site(path: str | os.PathLike) -> Site:
    """Read and validate a site folder (or its ``site.toml``).

    Checks the descriptor, every row of ``measurements.csv`` and ``settings.csv`` (conventions:
    :mod:`buildenv.sites.model`) and that the weather exists (the EPW itself is read only by
    :meth:`Site.weather_hours`).

    Args:
        path: the site folder, or the path of its ``site.toml``.

    Returns:
        the :class:`Site`.

    Raises:
        SiteError: on the first problem, as ``"<file>:<line>: <what is wrong>"``.
    """
    folder = Path(path).expanduser()
    if folder.is_file() and folder.suffix == ".toml":
        descriptor, folder = folder, folder.parent
    else:
        descriptor = folder / DESCRIPTOR
    if not folder.is_dir():
        raise SiteError(f"site folder not found: {folder}")
    if not descriptor.is_file():
        raise SiteError(f"{folder}: not a site folder: {DESCRIPTOR} is missing (see docs/site-format.md)")
    folder = folder.resolve()
    descriptor = descriptor.resolve()

    desc = _read_descriptor(descriptor)
    measurements_path = _data_file(descriptor, desc, "measurements", DEFAULT_MEASUREMENTS)
    settings_path = _data_file(descriptor, desc, "settings", DEFAULT_SETTINGS)
    start, temperature, consumption, electricity = _read_measurements(
        measurements_path,
        desc["floor_area_m2"],
        desc["measurement_options"],
        desc["consumption_end_uses"],
        desc["weather"],
        desc["electricity_end_uses"],
    )
    settings = _read_settings(settings_path, start, temperature.shape[0])
    series = [(temperature, MEASUREMENT_COLUMNS[1]), (consumption, MEASUREMENT_COLUMNS[2])]
    for values, column in series + ([(electricity, ELECTRICITY_COLUMN)] if electricity is not None else []):
        if not np.isfinite(values).any():
            log.warning("%s: column %s has no measured value", measurements_path, column)
    return Site(
        path=folder,
        name=desc["name"],
        weather=desc["weather"],
        start=start,
        floor_area_m2=desc["floor_area_m2"],
        number_of_floors=desc["number_of_floors"],
        settings=settings,
        temperature_c=temperature,
        consumption_kwh=consumption,
        source=desc["source"],
        known=desc["known"],
        effects=desc["effects"],
        consumption_end_uses=desc["consumption_end_uses"],
        electricity_kwh=electricity,
        electricity_end_uses=desc["electricity_end_uses"],
        controllable=desc["controllable"],
        setting_limits=desc["setting_limits"],
        calibration=_upgraded(_read_json(folder / CALIBRATION_FILE), folder / CALIBRATION_FILE),
        truth=_read_json(folder / TRUTH_FILE),
    )


def _toml_line(text: str, key: str, table: str | None = None) -> int | None:
    """1-based line where ``key = ...`` is set (inside ``[table]`` when given), or None."""
    current: str | None = None
    assign = re.compile(rf"\s*(?:{re.escape(key)}|\"{re.escape(key)}\"|'{re.escape(key)}')\s*=")
    header = re.compile(r"\s*\[\s*([^\]]+?)\s*\]")
    for number, line in enumerate(text.splitlines(), start=1):
        m = header.match(line)
        if m:
            current = m.group(1).strip("\"'")
            if table is None and current == key:
                return number
            continue
        if current == table and assign.match(line):
            return number
    return None


def _where(descriptor: Path, text: str, key: str, table: str | None = None) -> str:
    line = _toml_line(text, key, table)
    return f"{descriptor}:{line}" if line else str(descriptor)


def _allowed(keys: tuple[str, ...]) -> str:
    return ", ".join(keys)


def _reject_unknown_keys(
    descriptor: Path, text: str, table: Mapping[str, Any], allowed: tuple[str, ...], name: str | None = None
) -> None:
    """SiteError naming the first key of ``table`` (the top level, or ``[name]``) not in ``allowed``."""
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            where = f" in [{name}]" if name else ""
            raise SiteError(
                f"{_where(descriptor, text, key, name)}: unknown key {key!r}{where}{hint}; allowed: {_allowed(allowed)}"
            )


def _as_float(value: int | float) -> float:
    """``float(value)``, or an infinity for an integer too large for a float (TOML integers have no bound)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def _is_number(value) -> bool:
    """Whether a TOML or JSON value is a finite number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(_as_float(value))


def _read_descriptor(descriptor: Path) -> dict[str, Any]:
    """Parse and validate ``site.toml`` into plain values (weather resolved)."""
    try:
        text = descriptor.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise SiteError(f"{descriptor}: cannot read: {exc}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"at line (\d+)", str(exc))
        line = m.group(1) if m else max(len(text.splitlines()), 1)  # "at end of document": the last line
        raise SiteError(f"{descriptor}:{line}: invalid TOML: {exc}") from exc

    _reject_unknown_keys(descriptor, text, data, TOP_LEVEL_KEYS)
    for key in ("name", "weather", "geometry"):
        if key not in data:
            what = {
                "name": "free text",
                "weather": "an EPW short name such as 'usa_il_chicago' or a path",
                "geometry": f"a table with {_allowed(GEOMETRY_KEYS)}",
            }[key]
            raise SiteError(f"{descriptor}: missing {key!r} ({what})")
    for key in ("name", "weather", "measurements", "settings"):
        if key == "measurements" and isinstance(data.get(key), dict):
            continue  # a [measurements] table: _read_measurement_options
        if key in data and (not isinstance(data[key], str) or not data[key].strip()):
            raise SiteError(f"{_where(descriptor, text, key)}: {key!r} must be a non-empty string, got {data[key]!r}")
    for key in ("geometry", "known", "meters", "bms", "source"):
        if key in data and not isinstance(data[key], dict):
            raise SiteError(f"{_where(descriptor, text, key)}: {key!r} must be a table ([{key}]), got {data[key]!r}")

    geometry = data["geometry"]
    _reject_unknown_keys(descriptor, text, geometry, GEOMETRY_KEYS, "geometry")
    for key in GEOMETRY_KEYS:
        if key not in geometry:
            raise SiteError(f"{descriptor}: [geometry] is missing {key!r} ({cat.get(key).description})")
    area = geometry["floor_area_m2"]
    where = _where(descriptor, text, "floor_area_m2", "geometry")
    if not _is_number(area):
        raise SiteError(f"{where}: floor_area_m2 must be a number (m2), got {area!r}")
    floors = geometry["number_of_floors"]
    where_floors = _where(descriptor, text, "number_of_floors", "geometry")
    if isinstance(floors, float) and floors.is_integer():
        floors = int(floors)
    if isinstance(floors, bool) or not isinstance(floors, int):
        raise SiteError(f"{where_floors}: number_of_floors must be a whole number, got {floors!r}")
    for key, value, loc in (("floor_area_m2", float(area), where), ("number_of_floors", floors, where_floors)):
        try:
            cat.get(key).check(_as_float(value))  # the catalogue range, not its sampling step
        except CatalogueError as exc:
            raise SiteError(f"{loc}: {exc}") from exc

    controllable, setting_limits = _read_bms(descriptor, text, data.get("bms", {}))
    consumption_end_uses, electricity_end_uses = _read_meters(descriptor, text, data.get("meters", {}))
    options = _read_measurement_options(descriptor, text, data.get("measurements", DEFAULT_MEASUREMENTS))
    return {
        "measurement_options": options,
        "controllable": controllable,
        "setting_limits": setting_limits,
        "known": _read_known(descriptor, text, data.get("known", {})),
        "effects": _read_effects(descriptor, text, data.get("effects", [])),
        "consumption_end_uses": consumption_end_uses,
        "electricity_end_uses": electricity_end_uses,
        "name": data["name"].strip(),
        "weather": _resolve_weather(descriptor, text, data["weather"]),
        "floor_area_m2": float(area),
        "number_of_floors": int(floors),
        "measurements": options.file,
        "settings": data.get("settings", DEFAULT_SETTINGS),
        "source": dict(data.get("source", {})),
        "text": text,
    }


def _read_measurement_options(descriptor: Path, text: str, value: Any) -> _MeasurementOptions:
    """``measurements``: the file name, or a ``[measurements]`` table (:data:`MEASUREMENTS_KEYS`)."""
    if isinstance(value, str):
        return _MeasurementOptions(file=value)
    _reject_unknown_keys(descriptor, text, value, MEASUREMENTS_KEYS, "measurements")
    file = value.get("file", DEFAULT_MEASUREMENTS)
    if not isinstance(file, str) or not file.strip():
        where = _where(descriptor, text, "file", "measurements")
        raise SiteError(f"{where}: [measurements] file must be a non-empty string, got {file!r}")
    zone = None
    if "time_zone" in value:
        zone = _zone(value["time_zone"], _where(descriptor, text, "time_zone", "measurements"))
    stamped = value.get("stamped", "start")
    if stamped not in ("start", "end"):
        raise SiteError(
            f'{_where(descriptor, text, "stamped", "measurements")}: [measurements] stamped must be "start" '
            f'(a row stamps the start of its hour, the default) or "end" (01:00 for 00:00-01:00), got {stamped!r}'
        )
    cumulative = value.get("cumulative", False)
    if not isinstance(cumulative, bool):
        raise SiteError(
            f"{_where(descriptor, text, 'cumulative', 'measurements')}: [measurements] cumulative must be true "
            f"(heat_consumption_kwh holds meter register readings) or false, got {cumulative!r}"
        )
    return _MeasurementOptions(
        file=file,
        time_zone=zone,
        stamped_end=stamped == "end",
        cumulative=cumulative,
        where=_where(descriptor, text, "measurements"),
    )


def _zone(name: Any, where: str) -> zoneinfo.ZoneInfo:
    """The IANA time zone ``name``, or a SiteError at ``where``."""
    what = "the IANA name of the zone whose clock the BMS keeps, such as 'America/Chicago' or 'Europe/Paris'"
    if not isinstance(name, str) or not name.strip():
        raise SiteError(f"{where}: [measurements] time_zone must be {what}, got {name!r}")
    zone, hint = named_time_zone(name)
    if zone is None:
        raise SiteError(
            f"{where}: unknown time zone {name!r}{hint}: give {what} (a clock without daylight saving keeps "
            "standard time: leave time_zone out)"
        )
    return zone


def known_parameter(name: str, value: Any) -> float:
    """A value a site may declare known (``[known]``): ``name`` a theta_build variable other than the geometry,
    ``value`` a number in its catalogue range and unit. Raises :class:`SiteError` (no location) otherwise."""
    if name in GEOMETRY_KEYS:
        raise SiteError(f"{name!r} belongs in [geometry], not [known]")
    renamed = {old: new for e in cat.EARLIER_CATALOGUES.values() for old, new in e.renamed.items()}
    if name in renamed:
        new, factor = renamed[name]
        raise SiteError(f"{name!r} is now {new!r} ({cat.get(new).unit}, {factor:g} x the old value); rename it")
    if name not in KNOWN_KEYS:
        close = difflib.get_close_matches(name, KNOWN_KEYS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise SiteError(f"unknown key {name!r} in [known]{hint}; allowed: {_allowed(KNOWN_KEYS)}")
    variable = cat.get(name)
    if not _is_number(value):
        raise SiteError(f"{name} must be a number ({variable.unit}), got {value!r}")
    try:
        variable.check(float(value))
    except CatalogueError as exc:
        raise SiteError(str(exc)) from exc
    return float(value)


def _read_known(descriptor: Path, text: str, table: Mapping[str, Any]) -> dict[str, float]:
    """Validate ``[known]`` (:func:`known_parameter`), errors located at the key's line."""
    known: dict[str, float] = {}
    for key, value in table.items():
        try:
            known[key] = known_parameter(key, value)
        except SiteError as exc:
            raise SiteError(f"{_where(descriptor, text, key, 'known')}: {exc}") from exc
    return known


def _read_effects(descriptor: Path, text: str, value: Any) -> tuple[str, ...]:
    """Validate ``effects`` (:func:`buildenv.diagnosis.effects.check_declarable`), errors located at the key's
    line."""
    where = _where(descriptor, text, "effects")
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise SiteError(
            f"{where}: 'effects' must be a list of effect names (`buildenv effects` lists them), got {value!r}"
        )
    try:
        return check_declarable(value)
    except EffectError as exc:
        raise SiteError(f"{where}: {exc}") from None


def check_end_uses(value: Any) -> tuple[str, ...]:
    """The end uses a consumption series sums: ``value`` a non-empty list of distinct keys of
    :data:`buildenv.catalogue.END_USE_OUTPUTS`. Raises :class:`SiteError` (no location) otherwise."""
    allowed = _allowed(tuple(cat.END_USE_OUTPUTS))
    if not isinstance(value, (list, tuple)) or not value or not all(isinstance(v, str) for v in value):
        raise SiteError(f"must be a non-empty list of end uses ({allowed}), got {value!r}")
    for i, use in enumerate(value):
        if use in value[:i]:
            raise SiteError(f"{use!r} given twice")
        if use == "fans":
            raise SiteError(
                f"'fans': the model has no fan output; leave the fans out of the series (allowed: {allowed})"
            )
        if use not in cat.END_USE_OUTPUTS:
            close = difflib.get_close_matches(use, list(cat.END_USE_OUTPUTS), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise SiteError(f"unknown end use {use!r}{hint}; allowed: {allowed}")
    return tuple(value)


def _read_meters(descriptor: Path, text: str, table: Mapping[str, Any]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Validate ``[meters]`` (:func:`check_end_uses`), errors located at the key's line: ``(consumption end uses,
    electricity end uses)``; without ``consumption`` the default :data:`buildenv.catalogue.DEFAULT_END_USES`,
    without ``electricity`` none (one meter). No end use may be metered twice."""
    _reject_unknown_keys(descriptor, text, table, METER_KEYS, "meters")
    uses = {}
    for key, default in (("consumption", cat.DEFAULT_END_USES), ("electricity", ())):
        if key not in table:
            uses[key] = default
            continue
        try:
            uses[key] = check_end_uses(table[key])
        except SiteError as exc:
            raise SiteError(f"{_where(descriptor, text, key, 'meters')}: [meters] {key}: {exc}") from None
    twice = [use for use in uses["electricity"] if use in uses["consumption"]]
    if twice:
        raise SiteError(
            f"{_where(descriptor, text, 'electricity', 'meters')}: [meters] electricity: {', '.join(twice)} also in "
            "consumption; a meter's end uses are its own: list each end use under the meter that reads it"
        )
    return uses["consumption"], uses["electricity"]


def _unknown_setting(name: str) -> str:
    close = difflib.get_close_matches(name, cat.SETTING_NAMES, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown setting {name!r}{hint}; settings: {_allowed(cat.SETTING_NAMES)}"


def check_controllable(value: Any) -> tuple[str, ...]:
    """The settings a BMS can change: ``value`` a non-empty list of distinct names of
    :data:`buildenv.catalogue.SETTING_NAMES`; returned in catalogue order. Raises :class:`SiteError` (no
    location) otherwise."""
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise SiteError(f"must be a list of setting names ({_allowed(cat.SETTING_NAMES)}), got {value!r}")
    if not value:
        raise SiteError("empty list: name the settings the BMS can change (leave the key out for all 13)")
    for i, name in enumerate(value):
        if name in value[:i]:
            raise SiteError(f"{name!r} given twice")
        if name not in cat.SETTING_NAMES:
            raise SiteError(_unknown_setting(name))
    return tuple(n for n in cat.SETTING_NAMES if n in value)


def check_setting_limit(
    name: str, value: Any, controllable: tuple[str, ...] = cat.SETTING_NAMES
) -> tuple[float, float]:
    """The range operators may use for setting ``name``: ``value`` a ``[min, max]`` list of numbers in the
    catalogue's unit, ``min <= max`` (equal: the setting is held), inside the catalogue's range; ``name`` one of
    ``controllable``. Returns ``(min, max)``. Raises :class:`SiteError` (no location) otherwise."""
    if name not in cat.SETTING_NAMES:
        raise SiteError(_unknown_setting(name))
    if name not in controllable:
        raise SiteError(f"{name!r} is not in [bms] controllable: add it there or remove its limit")
    variable = cat.get(name)
    numbers = isinstance(value, (list, tuple)) and len(value) == 2 and all(map(_is_number, value))
    if not numbers:
        raise SiteError(f"{name} must be a list [min, max] of two numbers ({variable.unit}), got {value!r}")
    low, high = float(value[0]), float(value[1])
    if low > high:
        raise SiteError(f"{name} limits [{low:g}, {high:g}]: min is above max")
    if low < variable.min - 1e-9 or high > variable.max + 1e-9:
        raise SiteError(
            f"{name} limits [{low:g}, {high:g}] leave the catalogue range [{variable.min:g}, {variable.max:g}] "
            f"{variable.unit}"
        )
    return low, high


def _read_bms(
    descriptor: Path, text: str, table: Mapping[str, Any]
) -> tuple[tuple[str, ...], dict[str, tuple[float, float]]]:
    """Validate ``[bms]`` (:func:`check_controllable`, :func:`check_setting_limit`), errors located at the key's
    line; without ``controllable`` all settings, without ``limits`` none."""
    _reject_unknown_keys(descriptor, text, table, BMS_KEYS, "bms")
    controllable = cat.SETTING_NAMES
    if "controllable" in table:
        try:
            controllable = check_controllable(table["controllable"])
        except SiteError as exc:
            where = _where(descriptor, text, "controllable", "bms")
            raise SiteError(f"{where}: [bms] controllable: {exc}") from None
    limits = table.get("limits", {})
    if not isinstance(limits, dict):
        where = _where(descriptor, text, "limits", "bms")
        raise SiteError(f"{where}: [bms] limits must be a table {{setting = [min, max], ...}}, got {limits!r}")
    setting_limits: dict[str, tuple[float, float]] = {}
    for name, value in limits.items():
        try:
            setting_limits[name] = check_setting_limit(name, value, controllable)
        except SiteError as exc:
            line = (  # [bms.limits] name = ..., or limits = {...} / limits.name = ... in [bms]
                _toml_line(text, name, "bms.limits")
                or _toml_line(text, f"limits.{name}", "bms")
                or _toml_line(text, "limits", "bms")
            )
            where = f"{descriptor}:{line}" if line else str(descriptor)
            raise SiteError(f"{where}: [bms] limits: {exc}") from None
    return controllable, setting_limits


def _resolve_weather(descriptor: Path, text: str, weather: str) -> str:
    """A shipped short name stays as is; a path (relative to the site folder) becomes absolute."""
    from buildenv.weather.epw import shipped_weather

    try:
        shipped = shipped_weather()
    except Exception:  # pragma: no cover - pyenergyplus is a dependency, but do not fail on its absence
        shipped = {}
    if weather in shipped:
        return weather
    path = Path(weather).expanduser()
    if not path.is_absolute():
        path = descriptor.parent / path
    if path.is_file():
        return str(path.resolve())
    where = _where(descriptor, text, "weather")
    names = ", ".join(shipped) if shipped else "(none installed)"
    raise SiteError(
        f"{where}: weather {weather!r} is neither a shipped EPW short name nor a file "
        f"(looked for {path}); short names: {names}"
    )


def _data_file(descriptor: Path, desc: dict[str, Any], key: str, default: str) -> Path:
    path = Path(desc[key]).expanduser()
    if not path.is_absolute():
        path = descriptor.parent / path
    if not path.is_file():
        raise SiteError(f"{_where(descriptor, desc['text'], key)}: {key} file not found: {path}")
    return path


def _read_settings(path: Path, start: dt.date, weeks: int) -> np.ndarray:
    """Parse ``settings.csv`` into ``(weeks, 7, 13)``: one row per day from ``start``, catalogue ranges checked; a
    file without the last column, ``hvac_operating``, has every day operating."""
    rows = _rows(path)
    first = next(rows, None)
    expected = ",".join(SETTINGS_COLUMNS)
    if first is None:
        raise SiteError(f"{path}:1: empty file: expected the header {expected}")
    header = first[1]
    optional = SETTINGS_COLUMNS[-1]  # hvac_operating: every day operating when left out
    columns = SETTINGS_COLUMNS if tuple(header) == SETTINGS_COLUMNS else SETTINGS_COLUMNS[:-1]
    if tuple(header) != columns:
        missing = [c for c in SETTINGS_COLUMNS if c not in header and c != optional]
        unknown = [c for c in header if c not in SETTINGS_COLUMNS]
        parts = []
        if missing:
            parts.append("missing " + ", ".join(missing))
        for column in unknown:
            close = difflib.get_close_matches(column, SETTINGS_COLUMNS, n=1)
            parts.append(f"unknown {column!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
        if not parts:
            parts.append("columns in the wrong order" if len(set(header)) == len(header) else "repeated columns")
        raise SiteError(
            f"{path}:1: wrong header ({'; '.join(parts)}{_separator_hint(header)}); expected "
            f"{expected} (the catalogue's settings in order; see `buildenv catalogue --group settings`)"
        )

    days = weeks * 7
    last_day = start + dt.timedelta(days=days - 1)
    values = np.ones((days, len(cat.SETTINGS)))
    count = 0
    last_line = 1
    for line, cells in rows:
        if count == days:
            raise SiteError(
                f"{path}:{line}: one row too many: the measurements end on Sunday {last_day} "
                f"({weeks} week(s) from {start}); settings need one row per day of those weeks"
            )
        _check_width(path, line, cells, columns)
        m = _DATE.fullmatch(cells[0])
        try:
            day = dt.date(*(int(g) for g in m.groups())) if m else None
        except ValueError:
            day = None
        if day is None:
            raise SiteError(f"{path}:{line}: cannot read date {cells[0]!r}: expected 'YYYY-MM-DD'")
        wanted = start + dt.timedelta(days=count)
        if day != wanted:
            what = "the first measured Monday" if count == 0 else "the day after the previous row"
            raise SiteError(
                f"{path}:{line}: date {day} should be {wanted} ({what}): one row per day, "
                f"consecutive, from {start} to {last_day}"
            )
        for i, var in enumerate(cat.SETTINGS[: len(columns) - 1]):
            value = _parse_value(path, line, var.name, cells[i + 1], missing_ok=False)
            try:
                var.check(value)  # range only: a BMS may use values between grid steps, but a switch is on or off
                var.check_switch(value)
            except CatalogueError as exc:
                raise SiteError(f"{path}:{line}: {exc}") from exc
            values[count, i] = value
        count += 1
        last_line = line
    if count < days:
        seen = f"end on {start + dt.timedelta(days=count - 1)}" if count else "have no data rows"
        raise SiteError(
            f"{path}:{last_line}: the settings {seen}, but the measurements run to Sunday {last_day}: "
            f"expected {days} rows (one per day), found {count}"
        )
    return values.reshape(weeks, 7, len(cat.SETTINGS))


def _upgraded(calibration: dict | None, path: Path) -> dict | None:
    """A calibration read from ``path`` with its theta in this catalogue's names
    (:func:`buildenv.catalogue.upgrade_theta`), checked as :func:`_check_calibration` does."""
    if calibration is None:
        return None
    theta = calibration.get("theta")
    if isinstance(theta, dict):
        wrong = next((k for k, v in theta.items() if not _is_number(v)), None)
        if wrong is not None:
            raise SiteError(f"{path}: theta {wrong!r} is {theta[wrong]!r}, not a finite number{_AGAIN}")
        calibration["theta"] = cat.upgrade_theta(theta)
    _check_calibration(calibration, path)
    return calibration


_OCC = cat.GROUPS["occupancy"]  # arrival, departure
_AGAIN = "; calibrate the site again (buildenv calibrate --site FOLDER) or restore the file"


def _check_calibration(calibration: dict, path: Path) -> None:
    """Raise :class:`SiteError` naming ``path`` and the key unless the calibration holds what its users read: every
    theta_build variable (finite: :func:`_upgraded`; in its catalogue range), the weekday occupancy as 5 pairs of
    hours in the catalogue's ranges, and its metrics (``fit``, ``heldout``), declared effects (``effects``) and
    verdict as objects where present."""
    theta = calibration.get("theta")
    if not isinstance(theta, dict):
        raise SiteError(f"{path}: 'theta' is missing or not an object of building parameters{_AGAIN}")
    missing = next((n for n in cat.THETA_NAMES if n not in theta), None)
    if missing is not None:
        raise SiteError(f"{path}: theta has no {missing!r}{_AGAIN}")
    occupancy = calibration.get("occupancy")
    pairs = isinstance(occupancy, list) and len(occupancy) == len(cat.WEEKDAYS)
    if not pairs or not all(isinstance(d, list) and len(d) == 2 and all(map(_is_number, d)) for d in occupancy):
        raise SiteError(
            f"{path}: 'occupancy' must be {len(cat.WEEKDAYS)} pairs of hours [arrival, departure], "
            f"Monday to Friday; got {occupancy!r}{_AGAIN}"
        )
    values = [("theta", cat.get(n), theta[n]) for n in cat.THETA_NAMES]
    values += [(f"occupancy of {day}", v, h) for day, d in zip(cat.WEEKDAYS, occupancy) for v, h in zip(_OCC, d)]
    for where, variable, value in values:  # a calibration is searched within the catalogue's ranges
        try:
            variable.check(value)
        except cat.CatalogueError as error:
            raise SiteError(f"{path}: {where}: {error}{_AGAIN}") from None
    for key in ("fit", "heldout", "effects", "verdict"):
        if key in calibration and calibration[key] is not None and not isinstance(calibration[key], dict):
            raise SiteError(f"{path}: {key!r} is {type(calibration[key]).__name__}, not an object{_AGAIN}")


def _read_json(path: Path) -> dict | None:
    """A JSON object file as a dict, or None when the file does not exist."""
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise SiteError(f"{path}:{exc.lineno}: invalid JSON: {exc.msg}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise SiteError(f"{path}: cannot read: {exc}") from exc
    if not isinstance(data, dict):
        raise SiteError(f"{path}:1: expected a JSON object, got {type(data).__name__}")
    return data
