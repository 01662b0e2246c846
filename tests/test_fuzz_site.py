"""Fuzz tests: seeded random corruptions of a valid site folder, and invalid command-line arguments.

**The site reader.** A copy of the shipped default site (``buildenv/data/sites/default``) gets one corruption at a
time in ``measurements.csv``, ``settings.csv`` or ``site.toml`` (characters flipped, deleted or inserted; rows
deleted, duplicated or swapped; columns swapped; a number's magnitude changed; NaN, empty or text cells; blank
lines; the file truncated, re-encoded or given another header or separator; TOML lines removed or duplicated,
values retyped, unknown keys or tables added), is loaded with :func:`load_site`, and is restored. The outcome is
judged against :func:`_expected`, an independent reading of the corrupted files by the rules of
``docs/site-format.md``, which says either what the files mean or which rule they break:

- they break a rule: ``load_site`` must raise a :class:`~buildenv.errors.BuildenvError` (``SiteError``) whose
  message is one line starting with the path of a site file, ``<file>[:<line>]: <what>``;
- they follow the rules: ``load_site`` must return exactly what they mean. "The same result" is the original
  site wherever the corruption left the files' meaning alone, and otherwise what the files now say: a cell
  changed to another valid number is that number; an empty or ``NaN`` measurement cell, or a measurement row
  missing inside the weeks, is a gap, NaN in that hour and column only (the format: "a missing row (a jump of
  more than one hour), an empty cell or NaN is a missing value ... never interpolated"; a settings cell has no
  gap); blank lines, spaces around a cell, a UTF-8 BOM or CRLF line ends change nothing; a TOML key removed
  takes its default (no effects, every setting controllable, no limits, ...) and a ``[source]`` entry is kept
  as given.

Any other outcome fails: another exception (a traceback), a message on several lines or not naming a site file,
an error on files that follow the rules, or a site that differs from what the files say. The failure lists each
case as ``seed=S case=N <file>: <corruption>``; ``_case(S, N, _originals(<a copy of the default site>))``
rebuilds it. The rule that a consumption column which never falls is a meter register is not checked by
:func:`_expected`: no single corruption of this site (whose consumption falls hundreds of times) reaches it.

**The command line.** Each command that can be refused before any EnergyPlus run, training or calibration starts
gets a base argument list that fails fast (a missing site, dataset, checkpoint or weather file, an unknown
building or variable), mutated at random with the parser's own options: unknown flags, values of the wrong type,
invalid choices, negative numbers, garbage text, a required option left out, a value missing. Each must exit
non-zero with one line ``buildenv <command>: error: ...`` (or argparse's usage and one error line), never a
traceback; EnergyPlus is stubbed to fail the test should an argument list ever get that far.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import datetime as dt
import importlib
import io
import math
import re
import shutil
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import buildenv
from buildenv import catalogue as cat
from buildenv.cli.main import build_parser, main
from buildenv.diagnosis.effects import EFFECTS
from buildenv.errors import BuildenvError
from buildenv.sites import load_site
from buildenv.sites.model import (
    BMS_KEYS,
    GEOMETRY_KEYS,
    KNOWN_KEYS,
    MAX_KWH_PER_M2_PER_HOUR,
    MEASUREMENT_COLUMNS,
    METER_KEYS,
    MIN_PEAK_SHARE_OF_LEAST_POWER,
    SETTINGS_COLUMNS,
    TEMPERATURE_RANGE_C,
    TOP_LEVEL_KEYS,
)
from buildenv.weather.epw import shipped_weather

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

DEFAULT_SITE = Path(buildenv.__file__).parent / "data" / "sites" / "default"
TOML, MEAS, SETS = "site.toml", "measurements.csv", "settings.csv"
SEEDS = range(4)
CASES = 125  # per seed: 500 corruptions of the site
CLI_CASES = 40  # per seed

# ------------------------------------------------------------------------------------------------------------
# The expected reading: what the files mean by docs/site-format.md, written apart from the reader.


class Invalid(Exception):
    """The files break a rule of the format (the message says which, for a failure report)."""


_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")  # '.' as the decimal mark, nothing else
_STAMP = re.compile(r"(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2})(?::(\d{2}))?")
_DAY = re.compile(r"(\d{4})-(\d{2})-(\d{2})")
_HOUR = dt.timedelta(hours=1)


def _csv_rows(raw: bytes, name: str) -> list[list[str]]:
    """The rows of a CSV file (UTF-8, a BOM allowed), cells stripped, blank lines left out."""
    try:
        text = raw.decode("utf-8-sig")
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise Invalid(f"{name}: {exc}") from None
    return [[c.strip() for c in r] for r in rows if r and not (len(r) == 1 and not r[0].strip())]


def _value(cell: str, gap: bool) -> float:
    """A cell as a number; empty or NaN is a gap (NaN) where ``gap``."""
    if cell == "" or cell.lower() == "nan":
        if gap:
            return math.nan
        raise Invalid("a settings cell is missing")
    if not _NUMBER.fullmatch(cell):
        raise Invalid(f"{cell!r} is not a number")
    value = float(cell)
    if not math.isfinite(value):
        raise Invalid(f"{cell!r} is not finite")
    return value


def _in_range(name: str, value: Any) -> float:
    """A TOML number in the catalogue range of ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise Invalid(f"{name}: {value!r} is not a number")
    try:
        number = float(value)
    except OverflowError:
        raise Invalid(f"{name}: {value} is out of range") from None
    variable = cat.get(name)
    if not (math.isfinite(number) and variable.min - 1e-9 <= number <= variable.max + 1e-9):
        raise Invalid(f"{name}: {value!r} is out of range")
    return number


def _names(value: Any, allowed, what: str, empty_ok: bool = False) -> list[str]:
    """A list of distinct names from ``allowed``."""
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise Invalid(f"{what}: {value!r} is not a list of names")
    if (not value and not empty_ok) or len(set(value)) < len(value) or any(v not in allowed for v in value):
        raise Invalid(f"{what}: {value!r}")
    return value


def _only(table: dict, allowed, what: str) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise Invalid(f"unknown key {unknown[0]!r} in {what}")


def _expected_descriptor(site_dir: Path, raw: bytes) -> dict[str, Any]:
    try:
        data = tomllib.loads(raw.decode("utf-8-sig"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise Invalid(f"site.toml: {exc}") from None
    _only(data, TOP_LEVEL_KEYS, "the top level")
    for key in ("name", "weather", "geometry"):
        if key not in data:
            raise Invalid(f"{key!r} is missing")
    for key in ("name", "weather"):
        if not isinstance(data[key], str) or not data[key].strip():
            raise Invalid(f"{key}: {data[key]!r}")
    weather = data["weather"]
    if weather not in shipped_weather():
        path = site_dir / Path(weather).expanduser()
        if not path.is_file():
            raise Invalid(f"weather {weather!r} is neither shipped nor a file")
        weather = str(path.resolve())
    for key, default in (("measurements", MEAS), ("settings", SETS)):
        if data.get(key, default) != default:
            raise Invalid(f"{key}: {data[key]!r} (no corruption here makes another valid one)")
    tables = {key: data.get(key, {}) for key in ("geometry", "known", "meters", "bms", "source")}
    for key, table in tables.items():
        if not isinstance(table, dict):
            raise Invalid(f"{key} is not a table")
    geometry, meters, bms = tables["geometry"], tables["meters"], tables["bms"]
    _only(geometry, GEOMETRY_KEYS, "[geometry]")
    if set(geometry) != set(GEOMETRY_KEYS):
        raise Invalid("[geometry] lacks a key")
    floors = geometry["number_of_floors"]
    if isinstance(floors, float) and floors.is_integer():
        floors = int(floors)
    if isinstance(floors, bool) or not isinstance(floors, int):
        raise Invalid(f"number_of_floors: {floors!r} is not whole")
    effects = _names(data.get("effects", []), [e for e in EFFECTS if e != "holidays"], "effects", empty_ok=True)
    _only(tables["known"], KNOWN_KEYS, "[known]")
    _only(meters, METER_KEYS, "[meters]")
    _only(bms, BMS_KEYS, "[bms]")
    controllable = _names(bms.get("controllable", list(cat.SETTING_NAMES)), cat.SETTING_NAMES, "controllable")
    limits = bms.get("limits", {})
    if not isinstance(limits, dict):
        raise Invalid("[bms] limits is not a table")
    setting_limits = {}
    for name, pair in limits.items():
        if name not in controllable or not isinstance(pair, list) or len(pair) != 2:
            raise Invalid(f"limits {name} = {pair!r}")
        low, high = (_in_range(name, v) for v in pair)
        if low > high:
            raise Invalid(f"limits {name}: min above max")
        setting_limits[name] = (low, high)
    return {
        "name": data["name"].strip(),
        "weather": weather,
        "floor_area_m2": _in_range("floor_area_m2", geometry["floor_area_m2"]),
        "number_of_floors": int(_in_range("number_of_floors", floors)),
        "effects": tuple(effects),
        "known": {k: _in_range(k, v) for k, v in tables["known"].items()},
        "consumption_end_uses": tuple(
            _names(meters["consumption"], list(cat.END_USE_OUTPUTS), "[meters] consumption")
            if "consumption" in meters
            else cat.DEFAULT_END_USES
        ),
        "controllable": tuple(n for n in cat.SETTING_NAMES if n in controllable),
        "setting_limits": setting_limits,
        "source": dict(tables["source"]),
    }


def _stamp(cell: str) -> dt.datetime:
    m = _STAMP.fullmatch(cell)
    if m is None:
        raise Invalid(f"timestamp {cell!r}")
    year, month, day, hour, minute, second = (int(g) if g else 0 for g in m.groups())
    if minute or second:
        raise Invalid(f"timestamp {cell!r} is not on the hour")
    try:
        return dt.datetime(year, month, day, hour)  # 24:00 is an error too (no stamped = "end")
    except ValueError:
        raise Invalid(f"timestamp {cell!r}") from None


def _expected_measurements(raw: bytes, desc: dict, settings_days: int) -> tuple[dt.date, np.ndarray, np.ndarray]:
    rows = _csv_rows(raw, MEAS)
    if not rows or tuple(rows[0]) != MEASUREMENT_COLUMNS:
        raise Invalid("measurements.csv: header")
    if len(rows) < 2 or any(len(r) != len(MEASUREMENT_COLUMNS) for r in rows[1:]):
        raise Invalid("measurements.csv: no rows, or a row of the wrong width")
    stamps = [_stamp(r[0]) for r in rows[1:]]
    temperature = np.array([_value(r[1], gap=True) for r in rows[1:]])
    consumption = np.array([_value(r[2], gap=True) for r in rows[1:]])
    lo, hi = TEMPERATURE_RANGE_C
    if ((temperature < lo) | (temperature > hi)).any():
        raise Invalid("a temperature outside its range")
    if ((consumption < 0) | (consumption > MAX_KWH_PER_M2_PER_HOUR * desc["floor_area_m2"])).any():
        raise Invalid("a consumption below 0 or above 1 kWh/m2")
    if any(later <= earlier for earlier, later in zip(stamps, stamps[1:])):
        raise Invalid("timestamps out of order or repeated")
    first, last = stamps[0], stamps[-1]
    if (first.weekday(), first.hour, last.weekday(), last.hour) != (0, 0, 6, 23):
        raise Invalid("not whole weeks from a Monday 00:00 to a Sunday 23:00")
    weeks = ((last - first) // _HOUR + 1) // cat.HOURS_PER_WEEK
    if weeks * 7 != settings_days:
        raise Invalid(f"{weeks} weeks measured, {settings_days} days of settings")
    hours = np.array([(s - first) // _HOUR for s in stamps])
    t_out, q_out = (np.full(weeks * cat.HOURS_PER_WEEK, np.nan) for _ in range(2))
    t_out[hours], q_out[hours] = temperature, consumption
    powers = {"lighting": "lighting_power_w_m2", "plug_loads": "plug_load_w_m2"}
    metered = [p for use, p in powers.items() if use in desc["consumption_end_uses"]]
    least_w_m2 = MIN_PEAK_SHARE_OF_LEAST_POWER * sum(cat.get(p).min for p in metered)
    if metered and np.isfinite(q_out).any() and 0 < np.nanmax(q_out) * 1000 / desc["floor_area_m2"] < least_w_m2:
        raise Invalid("the consumption peaks below the least plausible power (MWh or GJ?)")
    shape = (weeks, cat.HOURS_PER_WEEK)
    return first.date(), t_out.reshape(shape), q_out.reshape(shape)


def _expected_settings(rows: list[list[str]], start: dt.date, weeks: int) -> np.ndarray:
    values = np.ones((weeks * 7, len(cat.SETTINGS)))  # hvac_operating, when left out: every day operates
    for k, cells in enumerate(rows[1:]):
        m = _DAY.fullmatch(cells[0]) if len(cells) == len(rows[0]) else None
        try:
            day = dt.date(*(int(g) for g in m.groups())) if m else None
        except ValueError:
            day = None
        if day != start + dt.timedelta(days=k):
            raise Invalid(f"settings.csv row {k + 1}: width or date")
        for i, variable in enumerate(cat.SETTINGS[: len(rows[0]) - 1]):
            values[k, i] = _in_range(variable.name, _value(cells[i + 1], gap=False))
            if variable.is_switch and values[k, i] not in (variable.min, variable.max):
                raise Invalid(f"settings.csv row {k + 1}: {variable.name} neither on nor off")
    return values.reshape(weeks, 7, len(cat.SETTINGS))


def _expected(site_dir: Path, files: dict[str, bytes], original: dict[str, Any]) -> dict[str, Any]:
    """The snapshot (:func:`_snapshot`) the files mean; raises :class:`Invalid` where they break a rule."""
    desc = _expected_descriptor(site_dir, files[TOML])
    settings_rows = _csv_rows(files[SETS], SETS)
    if not settings_rows or tuple(settings_rows[0]) not in (SETTINGS_COLUMNS, SETTINGS_COLUMNS[:-1]):
        raise Invalid("settings.csv: header")
    start, temperature, consumption = _expected_measurements(files[MEAS], desc, len(settings_rows) - 1)
    return {
        **desc,
        "start": start,
        "settings": _expected_settings(settings_rows, start, temperature.shape[0]),
        "temperature_c": temperature,
        "consumption_kwh": consumption,
        "calibration": original["calibration"],  # not corrupted here
        "truth": original["truth"],
    }


def _snapshot(site) -> dict[str, Any]:
    """What a loaded site holds, as plain values."""
    fields = ("name", "weather", "start", "floor_area_m2", "number_of_floors", "settings", "temperature_c")
    fields += ("consumption_kwh", "known", "effects", "consumption_end_uses", "controllable", "setting_limits")
    return {f: getattr(site, f) for f in (*fields, "source", "calibration", "truth")}


def _same(a: Any, b: Any) -> bool:
    """``a == b``, NaN equal to NaN (a ``[source]`` entry may be ``nan``)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _differences(got: dict[str, Any], want: dict[str, Any]) -> str:
    """'' when equal (NaN equal to NaN), else the first difference of each field that differs."""
    out = []
    for key, expected in want.items():
        value = got[key]
        if isinstance(expected, np.ndarray):
            if value.shape != expected.shape:
                out.append(f"{key} shape {value.shape} instead of {expected.shape}")
            elif not np.array_equal(value, expected, equal_nan=True):
                at = np.argwhere(~((value == expected) | (np.isnan(value) & np.isnan(expected))))[0]
                out.append(f"{key}{list(at)} = {value[tuple(at)]!r} instead of {expected[tuple(at)]!r}")
        elif not _same(value, expected):
            out.append(f"{key} = {value!r:.200} instead of {expected!r:.200}")
    return "; ".join(out)


def _judge(site_dir: Path, original: dict[str, Any]) -> tuple[str, str | None]:
    """``(outcome, problem)``: outcome ``"same"``, ``"changed"`` or ``"error"``; problem None when right."""
    files = {name: (site_dir / name).read_bytes() for name in (TOML, MEAS, SETS)}
    try:
        expected, rule = _expected(site_dir, files, original), ""
    except Invalid as exc:
        expected, rule = None, str(exc)
    try:
        site = load_site(site_dir)
    except BuildenvError as exc:
        message = str(exc)
        where = rf"{re.escape(str(site_dir))}/(site\.toml|measurements\.csv|settings\.csv)(:\d+)?: \S"
        if "\n" in message or not re.match(where, message):
            return "error", f"unclear {type(exc).__name__}: {message!r}"
        if expected is not None:
            return "error", f"{type(exc).__name__} on files that follow the format: {message}"
        return "error", None
    except Exception as exc:  # a traceback: what this test is for
        return "error", "traceback:\n" + "".join(traceback.format_exception(exc))[-2000:]
    if expected is None:
        return "changed", f"loaded, but the files break a rule: {rule}"
    got = _snapshot(site)
    problem = _differences(got, expected)
    return ("same" if not _differences(got, original) else "changed"), (f"loaded with {problem}" if problem else None)


# ------------------------------------------------------------------------------------------------------------
# The corruptions.

_CHARS = (*"0123456789.-+eE ,;:T_x#\"'", "\t", "\n", "\r", "\x00", "\u00a0", "é", "\u0663")  # '\u0663': Arabic 3
_CELLS = (
    *("", " ", "NaN", "nan", "NAN", "-", "n/a", "#N/A", "None", "null", "abc", "TRUE", "inf", "-inf", "Infinity"),
    *("1e400", "1_0", "0x1A", "1.2.3", "1,5", "22,5", "'22.5'", '"22.5"', "+", "e3", ".", "--1", "1e", "\u0662\u0662"),
    *("2019-11-04 00:00", "2019-11-04T00:00", "2019-11-04 24:00", "2019-11-04 00:30", "2019-11-04 00:00+01:00"),
)
_TOML_VALUES = (
    *('"text"', '""', '"  "', "42", "-1", "0", "4.5", "1e400", "nan", "inf", "true", "[]", "[1, 2]", '["a"]'),
    *("{ a = 1 }", "2019-11-04", "1" + "0" * 30, "1" + "0" * 400, '"usa_il_chicago"', "3.0", "[0.45, 0.7]"),
    *('["night_cycle_cold_air"]', '["holidays"]', '["heating"]', "{ ventilation_ach = [0.7, 0.45] }"),
)
_TOML_LINES = (
    *('colour = "blue"', "floor_area = 5000", "nmae = 1", "[known]", "[meters]", "[geometry]", "[bms.limits]"),
    *("[known]\npc_night_percent = 44", "[known]\npc_night = 44", '[meters]\nconsumption = ["heating"]'),
    *('[meters]\nconsumption = ["heating", "fans"]', "[measurements]\ntime_zone = 5", "effects = []", "x"),
)


@dataclass(frozen=True)
class Case:
    seed: int
    number: int
    file: str
    what: str
    data: bytes

    def __str__(self) -> str:
        return f"seed={self.seed} case={self.number} {self.file}: {self.what}"


def _pick(rng: np.random.Generator, options):
    return options[int(rng.integers(len(options)))]


def _show(text: str) -> str:
    return repr(text if len(text) <= 90 else text[:60] + "..." + text[-25:])


def _truncated(data: bytes, cut: int) -> str:
    end = data[max(cut - 30, 0) : cut].decode("utf-8", "replace")
    return f"truncated to {cut} of {len(data)} bytes, ending {_show(end)}"


def _char_edit(rng: np.random.Generator, lines: list[str], i: int) -> str:
    """Flip, delete or insert one character of line ``i`` (in place); the description."""
    op = _pick(rng, ("flip", "delete", "insert"))
    line = lines[i]
    at = int(rng.integers(len(line) + (op == "insert"))) if line or op == "insert" else 0
    char = _pick(rng, _CHARS)
    lines[i] = line[:at] + ("" if op == "delete" else char) + line[at + (op != "insert") :]
    return f"line {i + 1}: {op} character {at}: {_show(line)} -> {_show(lines[i])}"


def _csv_case(rng: np.random.Generator, text: str) -> tuple[bytes, str]:
    lines = text.splitlines()
    nl = "\r\n" if "\r\n" in text else "\n"  # settings.csv has CRLF line ends, measurements.csv LF
    n = len(lines)
    r = rng.random()
    row = 1 if r < 0.15 else n - 1 if r < 0.3 else int(rng.integers(1, n))  # the first and last rows often
    cells = lines[row].split(",")  # the valid files quote nothing
    op = _pick(rng, ("char", "char", "magnitude", "cell", "cell", "delete_row", "duplicate_row", "swap_rows"))
    op = op if rng.random() < 0.8 else _pick(rng, ("swap_columns", "truncate", "header", "blank", "bytes", "sep"))
    what = ""
    if op == "char":
        what = _char_edit(rng, lines, 0 if rng.random() < 0.1 else row)
    elif op in ("magnitude", "cell"):
        col = int(rng.integers(1 if op == "magnitude" else 0, len(cells)))
        old = cells[col]
        if op == "magnitude":
            k = int(_pick(rng, (-6, -3, -2, -1, 1, 2, 3, 400)))
            cells[col] = f"{old}e400" if k == 400 else f"{float(old) * 10.0**k:.6g}"
        else:
            cells[col] = _pick(rng, _CELLS)
        lines[row] = ",".join(cells)
        what = f"line {row + 1} column {col + 1}: {old!r} -> {cells[col]!r}"
    elif op == "delete_row":
        row = 0 if rng.random() < 0.05 else row
        what = f"line {row + 1} deleted: {_show(lines.pop(row))}"
    elif op == "duplicate_row":
        to = int(rng.integers(1, n + 1)) if rng.random() < 0.3 else row + 1
        lines.insert(to, lines[row])
        what = f"line {row + 1} copied to line {to + 1}"
    elif op == "swap_rows":
        other = row + 1 if rng.random() < 0.5 and row + 1 < n else int(rng.integers(1, n))
        lines[row], lines[other] = lines[other], lines[row]
        what = f"lines {row + 1} and {other + 1} swapped"
    elif op == "swap_columns":
        a, b = sorted(int(x) for x in rng.choice(len(cells), 2, replace=False))
        first = 0 if rng.random() < 0.5 else 1
        for i in range(first, n):
            c = lines[i].split(",")
            c[a], c[b] = c[b], c[a]
            lines[i] = ",".join(c)
        what = f"columns {a + 1} and {b + 1} swapped from line {first + 1}"
    elif op == "truncate":
        data = (nl.join(lines) + nl).encode()
        cut = int(rng.integers(len(data))) if rng.random() < 0.5 else len(data) - int(rng.integers(1, 80))
        return data[:cut], _truncated(data, cut)
    elif op == "header":
        old = lines[0]
        names = old.split(",")
        lines[0] = _pick(
            rng,
            (
                old.upper(),
                ";".join(names),
                "\t".join(names),
                ",".join(reversed(names)),
                ", ".join(names),
                old + ",extra",
                ",".join(names[:-1]),
                old.replace("_c,", "_f,").replace("_kwh", "_wh"),
                old.replace("timestamp", "time"),
            ),
        )
        what = f"header {old!r} -> {lines[0]!r}"
    elif op == "blank":
        at = int(rng.integers(n + 1))
        lines.insert(at, _pick(rng, ("", "   ", ",", ",,", "\t")))
        what = f"line {at + 1}: {lines[at]!r} inserted"
    elif op == "bytes":
        kind = _pick(rng, ("bom", "other line ends", "latin-1"))
        body = nl.join(lines) + nl
        if kind == "latin-1":
            return body.replace(lines[row], lines[row] + "é").encode("latin-1"), f"line {row + 1} given a latin-1 é"
        other = "\n" if nl == "\r\n" else "\r\n"
        data = ("\ufeff" + body).encode() if kind == "bom" else body.replace(nl, other).encode()
        return data, f"re-encoded: {kind}"
    else:  # sep
        lines[row] = lines[row].replace(",", _pick(rng, (";", "\t", " ")))
        what = f"line {row + 1} separated by another character: {_show(lines[row])}"
    return (nl.join(lines) + nl).encode(), what


def _toml_case(rng: np.random.Generator, text: str) -> tuple[bytes, str]:
    lines = text.splitlines()
    n = len(lines)
    keyed = [i for i, line in enumerate(lines) if re.match(r"\s*[\w\"]+\s*=", line)]
    numbers = [  # number values: not in comments or strings
        (i, m)
        for i in keyed
        for m in re.finditer(r"(?<![\w.])\d+(?:\.\d+)?(?![\w.])", lines[i].split("#")[0])
        if lines[i][: m.start()].count('"') % 2 == 0
    ]
    op = _pick(rng, ("remove", "duplicate", "retype", "retype", "add", "magnitude", "magnitude", "char", "truncate"))
    if op == "remove":
        i = _pick(rng, keyed) if rng.random() < 0.6 else int(rng.integers(n))
        return ("\n".join(lines[:i] + lines[i + 1 :]) + "\n").encode(), f"line {i + 1} removed: {_show(lines[i])}"
    if op == "duplicate":
        i = _pick(rng, keyed) if rng.random() < 0.7 else int(rng.integers(n))
        lines.insert(i + 1, lines[i])
        what = f"line {i + 1} duplicated: {_show(lines[i])}"
    elif op == "retype":
        i = _pick(rng, keyed)
        old = lines[i]
        key = old.split("=", 1)[0]
        lines[i] = f"{key}= {_pick(rng, _TOML_VALUES)}"
        what = f"line {i + 1}: {_show(old)} -> {_show(lines[i])}"
    elif op == "add":
        at = int(rng.integers(n + 1))
        lines.insert(at, _pick(rng, _TOML_LINES))
        what = f"line {at + 1}: {lines[at]!r} inserted"
    elif op == "magnitude":
        i, m = _pick(rng, numbers)
        k = int(_pick(rng, (-3, -1, 1, 3, 400)))
        whole, dot, fraction = m.group().partition(".")
        new = whole + "0" * 400 + dot + fraction if k == 400 else f"{float(m.group()) * 10.0**k:g}"
        old = lines[i]
        lines[i] = old[: m.start()] + new + old[m.end() :]
        what = f"line {i + 1}: {m.group()} -> {_show(new)} in {_show(old)}"
    elif op == "char":
        what = _char_edit(rng, lines, _pick(rng, keyed) if rng.random() < 0.7 else int(rng.integers(n)))
    else:  # truncate
        data = text.encode()
        cut = int(rng.integers(len(data)))
        return data[:cut], _truncated(data, cut)
    return ("\n".join(lines) + "\n").encode(), what


def _case(seed: int, number: int, originals: dict[str, bytes]) -> Case:
    """Corruption ``number`` of seed ``seed``: one file of the site with one random corruption."""
    rng = np.random.default_rng([seed, number])
    r = rng.random()
    name = MEAS if r < 0.45 else SETS if r < 0.7 else TOML
    make = _toml_case if name == TOML else _csv_case
    data, what = make(rng, originals[name].decode())
    return Case(seed, number, name, what, data)


def _originals(site_dir: Path) -> dict[str, bytes]:
    return {name: (site_dir / name).read_bytes() for name in (TOML, MEAS, SETS)}


@pytest.fixture()
def site_copy(tmp_path: Path) -> Path:
    """A copy of the shipped default site (its calibration.json and truth.json included, its plot left out)."""
    site_dir = (tmp_path / "site").resolve()
    shutil.copytree(DEFAULT_SITE, site_dir, ignore=shutil.ignore_patterns("*.png"))
    return site_dir


def test_the_expected_reading_reads_the_valid_site_as_the_reader_does(site_copy: Path):
    original = _snapshot(load_site(site_copy))
    assert not _differences(original, _expected(site_copy, _originals(site_copy), original))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", SEEDS)
def test_a_corrupted_site_loads_as_the_files_say_or_fails_in_one_line(seed: int, site_copy: Path):
    originals = _originals(site_copy)
    original = _snapshot(load_site(site_copy))
    failures, outcomes = [], {"same": 0, "changed": 0, "error": 0}
    for number in range(CASES):
        case = _case(seed, number, originals)
        (site_copy / case.file).write_bytes(case.data)
        try:
            outcome, problem = _judge(site_copy, original)
        finally:
            (site_copy / case.file).write_bytes(originals[case.file])
        outcomes[outcome] += 1
        if problem:
            failures.append(f"{case}\n    -> {problem}")
    assert not failures, f"{len(failures)} of {CASES} corruptions went wrong:\n" + "\n".join(failures)
    assert outcomes["error"] and outcomes["same"] + outcomes["changed"], outcomes  # both kinds were tried


_BIG = "1" + "0" * 400  # a TOML integer (TOML's are unbounded in Python) beyond any float
#: Corruptions the fuzzing found the reader getting wrong (a traceback, ``site.toml:?``, '2_40' read as 240).
_FOUND = {
    "site.toml cut inside a string": (TOML, lambda t: t[:38]),
    "site.toml cut inside a table header": (TOML, lambda t: t[: t.index("[source]") + 3]),
    "measurements.csv 2_40": (MEAS, lambda t: t.replace(",24.0000\n", ",2_40\n", 1)),
    "settings.csv 1_3": (SETS, lambda t: t.replace(",13,0.7", ",1_3,0.7", 1)),
    "number_of_floors 10**400": (TOML, lambda t: t.replace("number_of_floors = 3", f"number_of_floors = {_BIG}")),
    "floor_area_m2 10**400": (TOML, lambda t: t.replace("floor_area_m2 = 4982.2", f"floor_area_m2 = {_BIG}")),
    "[bms] limit 10**400": (TOML, lambda t: t.replace("[0.45, 0.7]", f"[0.45, {_BIG}]")),
    "[known] 10**400": (TOML, lambda t: t.replace("[bms]", f"[known]\npc_night_percent = {_BIG}\n\n[bms]")),
}


@pytest.mark.parametrize("name", list(_FOUND))
def test_the_corruptions_fuzzing_found_fail_in_one_line(name: str, site_copy: Path):
    original = _snapshot(load_site(site_copy))
    file, edit = _FOUND[name]
    text = (site_copy / file).read_bytes().decode()
    assert edit(text) != text
    (site_copy / file).write_bytes(edit(text).encode())
    assert _judge(site_copy, original) == ("error", None)


# ------------------------------------------------------------------------------------------------------------
# The command line.

#: Per command: arguments that fail fast (before EnergyPlus, training or calibration), and the options whose
#: values make them fail (left alone by the mutations). ``{missing}``: a path that does not exist; ``{tmp}``: a
#: scratch folder.
_BASES: dict[str, tuple[list[str], tuple[str, ...]]] = {
    "catalogue": (["catalogue", "--group", "nonsense"], ("--group",)),
    "weather": (["weather", "{missing}/x.epw"], ()),
    "morph-weather": (["morph-weather", "--epw", "{missing}/x.epw", "--out", "{tmp}/m.epw"], ("--epw",)),
    "week": (["week", "--set", "nonsense=1", "--out", "{tmp}/week"], ("--set",)),
    "simulate": (["simulate", "--weeks", "2", "--out", "{tmp}/ds", "--epw", "{missing}/x.epw", "--quiet"], ("--epw",)),
    "train": (["train", "--model", "ffn", "--data", "{missing}", "--out", "{tmp}/ck.pt", "--quiet"], ("--data",)),
    "evaluate": (["evaluate", "--data", "{missing}", "--checkpoint", "{missing}/ck.pt"], ("--data", "--checkpoint")),
    "site show": (["site", "show", "{missing}"], ()),
    "site reference": (["site", "reference", "--start", "11-05", "--out", "{tmp}/site"], ("--start", "--year")),
    "calibrate": (["calibrate", "--site", "{missing}", "--checkpoint", "{missing}/ck.pt", "--quiet"], ("--site",)),
    "diagnose": (["diagnose", "--site", "{missing}", "--checkpoint", "{missing}/ck.pt", "--quiet"], ("--site",)),
    "diagnose-check": (
        ["diagnose-check", "--checkpoint", "{missing}/ck.pt", "--out", "{tmp}/dc", "--quiet"],
        ("--checkpoint",),
    ),
    "effects": (["effects", "unexpected"], ()),
    "suite list": (["suite", "list", "--buildings", "nonsense"], ("--buildings",)),
    "suite make": (["suite", "make", "--out", "{tmp}/suite", "--buildings", "nonsense", "--quiet"], ("--buildings",)),
    "suite calibrate": (["suite", "calibrate", "--suite", "{missing}", "--quiet"], ("--suite",)),
    "suite verify": (["suite", "verify", "--suite", "{missing}", "--quiet"], ("--suite",)),
    "optimize": (["optimize", "--method", "rules", "--site", "{missing}"], ("--site",)),
    "verify": (["verify", "--site", "{missing}"], ("--site",)),
    "demo": (["demo", "unexpected"], ()),
}
_WRONG = ("abc", "1.5", "", "3x", "0x10", "1,5", "one", "1e3.5")
_GARBAGE = ("", " ", "-", "{bad", "[1]", "../..", "a,b", "nan", "é", "=", "x=", "%s")
_ARGPARSE_ERROR = re.compile(r"buildenv(?: [\w-]+)*: error: \S.*")
_ONE_LINE_ERROR = re.compile(r"buildenv [\w -]+: error: \S.*")


def _fill(arg: str, tmp: Path) -> str:
    return arg.replace("{missing}", str(tmp / "missing")).replace("{tmp}", str(tmp))


def _parser_of(words: list[str]) -> argparse.ArgumentParser:
    parser = build_parser()
    for word in words:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        if word not in sub.choices:
            break
        parser = sub.choices[word]
    return parser


def _options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and a.nargs != 0 and not isinstance(a, argparse._HelpAction)]


def _cli_case(rng: np.random.Generator, tmp: Path) -> tuple[str, list[str]]:
    """A random invalid argument list: a base of :data:`_BASES` with one to three mutations."""
    command = _pick(rng, sorted(_BASES))
    base, protected = _BASES[command]
    argv = [_fill(a, tmp) for a in base]
    options = [a for a in _options(_parser_of(command.split())) if a.option_strings[-1] not in protected]
    what = []
    for _ in range(1 + (rng.random() < 0.4) + (rng.random() < 0.1)):
        # argparse stops at the first of its errors: the value mutations that reach the command come most often
        op = _pick(
            rng, ("unknown", "wrong_type", "choice", "required", "no_value", *("negative",) * 3, *("garbage",) * 4)
        )
        numeric = [a for a in options if a.type not in (None, str) and not a.choices]
        typed = {"wrong_type": numeric, "negative": numeric, "choice": [a for a in options if a.choices]}
        pool = typed.get(op, [a for a in options if a.type in (None, str) and not a.choices])
        if op == "required":
            required = [a for a in _options(_parser_of(command.split())) if a.required]
            flag = _pick(rng, required).option_strings[-1] if required else None
            if flag in argv:
                at = argv.index(flag)
                del argv[at : at + 2]
                what.append(f"required {flag} left out")
                continue
        if op == "unknown" or op == "required" or not pool:
            flag = "--no-such-" + "".join(_pick(rng, "abcdefghij") for _ in range(4))
            at = int(rng.integers(len(command.split()), len(argv) + 1))
            argv[at:at] = [flag] if rng.random() < 0.5 else [flag, "1"]
            what.append(f"unknown {flag}")
            continue
        action = _pick(rng, pool)
        flag = action.option_strings[-1]
        if op == "no_value":
            argv.append(flag)
            what.append(f"{flag} without a value")
            continue
        value = {
            "wrong_type": lambda: _pick(rng, _WRONG),
            "negative": lambda: str(-int(rng.integers(1, 1000))),
            "choice": lambda: "nonsense",
            "garbage": lambda: _pick(rng, _GARBAGE),
        }[op]()
        argv += [flag, value]
        what.append(f"{op} {flag} {value!r}")
    return f"{command}: {', '.join(what)}", argv


def _stub_energyplus(monkeypatch):
    """Fail the test, instead of running EnergyPlus, should an argument list get that far."""

    def refuse(*args, **kwargs):
        raise AssertionError("the arguments got as far as an EnergyPlus run")

    modules = ("buildenv.energyplus.runner", "buildenv.energyplus.reference", "buildenv.energyplus.simulate")
    for module in modules:  # imported before any is patched: one imported after would keep the stub as its own
        importlib.import_module(module)
    for module in modules:
        monkeypatch.setattr(f"{module}.run_energyplus", refuse)


def _cli_problem(argv: list[str], capsys) -> str | None:
    """None when ``main(argv)`` refuses the arguments cleanly, else what went wrong."""
    argparse_exit = False
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
    except SystemExit as exc:
        code, argparse_exit = exc.code, True
    except Exception as exc:  # a traceback
        capsys.readouterr()
        return "traceback:\n" + "".join(traceback.format_exception(exc))[-1500:]
    err = capsys.readouterr().err.strip().splitlines()
    if code in (0, None):
        return f"accepted (exit {code})"
    if argparse_exit:  # usage lines, then the error
        if not err or not err[0].startswith("usage:") or not _ARGPARSE_ERROR.fullmatch(err[-1]):
            return f"exit {code}, stderr {err!r}"
        if any(not line.startswith(" ") for line in err[1:-1]):
            return f"exit {code}, more than usage and one error line: {err!r}"
        return None
    if len(err) != 1 or not _ONE_LINE_ERROR.fullmatch(err[0]):
        return f"exit {code}, stderr {err!r}"
    return None


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", range(3))
def test_invalid_command_line_arguments_fail_in_one_line(seed, tmp_path, monkeypatch, capsys):
    _stub_energyplus(monkeypatch)
    monkeypatch.chdir(tmp_path)  # whatever a garbage path writes stays here
    rng = np.random.default_rng(seed)
    failures = []
    for number in range(CLI_CASES):
        what, argv = _cli_case(rng, tmp_path)
        problem = _cli_problem(argv, capsys)
        if problem:
            failures.append(f"seed={seed} case={number} {what}\n    argv={argv}\n    -> {problem}")
    assert not failures, f"{len(failures)} of {CLI_CASES} argument lists went wrong:\n" + "\n".join(failures)


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--weeks", "-3", "--out", "{tmp}/ds"],
        ["simulate", "--weeks", "2", "--weeks-per-run", "-1", "--out", "{tmp}/ds"],
        ["simulate", "--out", "{tmp}/ds"],
        ["week", "--week", "-1", "--out", "{tmp}/week"],
        ["week", "--week", "two"],
        ["morph-weather", "--epw", "usa_il_chicago", "--out", "{tmp}/m.epw", "--stretch", "-5"],
        ["morph-weather", "--epw", "usa_il_chicago", "--out", "{tmp}/m.epw", "--solar-scale", "nan"],
        ["train", "--model", "ffn", "--data", "{missing}", "--out", "{tmp}/ck.pt", "--minutes", "-1"],
        ["train", "--model", "ffn", "--data", "{missing}", "--out", "{tmp}/ck.pt", "--model-config", "{bad"],
        ["train", "--model", "ffn", "--data", "{missing}", "--out", "{tmp}/ck.pt", "--model-config", "[1]"],
        ["train", "--model", "ffn", "--data", "{missing}", "--out", ""],
        ["site", "reference", "--out", "{tmp}/s", "--year", "-5"],
        ["site", "reference", "--out", "{tmp}/s", "--known", "pc_night_percent=-4"],
        ["site", "show", "{missing}"],
        ["site", "show", "{tmp}/bad-site"],
        ["weather", "{missing}/x.epw"],
        ["suite", "list", "--seasons", "winter"],
        ["calibrate", "--site", "{tmp}/site", "--weeks", "a,b", "--checkpoint", "{missing}/ck.pt"],
        # refused before EnergyPlus or a campaign starts
        ["simulate", "--weeks", "0", "--out", "{tmp}/c"],
        ["simulate", "--weeks", "4", "--max-failed-share", "2", "--out", "{tmp}/c"],
        ["site", "reference", "--weeks", "0", "--out", "{tmp}/s"],
        ["site", "reference", "--floors", "-1", "--out", "{tmp}/s"],
        ["site", "reference", "--epw", "nowhere", "--out", "{tmp}/s"],
        ["diagnose-check", "--cases", "-1", "--out", "{tmp}/d"],
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
def test_named_invalid_arguments_fail_in_one_line(argv, tmp_path, monkeypatch, capsys):
    _stub_energyplus(monkeypatch)
    monkeypatch.chdir(tmp_path)
    for name in ("site", "bad-site"):  # a valid site, and one whose measurements break a rule
        shutil.copytree(DEFAULT_SITE, tmp_path / name, ignore=shutil.ignore_patterns("*.png"))
    bad = tmp_path / "bad-site" / MEAS
    bad.write_text(bad.read_text().replace(",22.500,", ",72.5,", 1))
    argv = [_fill(a, tmp_path) for a in argv]
    assert _cli_problem(argv, capsys) is None
