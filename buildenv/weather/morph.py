"""Morphed weather: new EPW files made from a shipped one by shifting and stretching its temperature, scaling
its solar radiation and its wind.

The 16 TMY3 files of ``pyenergyplus-lbnl`` are all the real climates a campaign can draw from; morphing widens
what a metamodel trains on without a download. It is the shift-and-stretch engineers use for future-climate
weather (Belcher, Hacker and Powell, 2005: ``T' = T + shift + (stretch - 1) (T - <T>_month)``).

What a morph changes in each hourly row (EPW field numbers, 1-based):

- dry bulb (7): ``T' = T + shift_k + (stretch - 1) * (T - monthly mean of T)``;
- dew point (8): moved by the same amount as the dry bulb, kept at or below it, so the dew-point depression
  (and roughly the relative humidity) is kept;
- relative humidity (9): scaled by the change in the ratio of the dew point's to the dry bulb's saturation
  pressure (Magnus formula), so an hour whose temperatures are unchanged keeps its value;
- horizontal infrared radiation from the sky (13): scaled by ``((T' + 273.15) / (T + 273.15))**4``;
- global, direct normal and diffuse horizontal radiation (14-16) and their illuminances (17-19): ``* solar_scale``;
- wind speed (22): ``* wind_scale``;
- the header's monthly ground temperatures: ``+ shift_k``.

Everything else (the site, the calendar, pressure, sky cover, precipitation) is kept, and so is a value
marked missing (EPW's 9999-style codes). A ``COMMENTS 2`` header line records the morph.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import WeatherError
from buildenv.weather.epw import HOURS_PER_YEAR, Weather, month_of_hour, resolve_epw

#: Ranges the random morphs are drawn from (uniform), spanning neighbouring US climate zones' differences in
#: mean temperature, synoptic swings, annual irradiation and exposure to wind
MORPH_RANGES: dict[str, tuple[float, float]] = {
    "shift_k": (-4.0, 4.0),
    "stretch": (0.8, 1.2),
    "solar_scale": (0.85, 1.15),
    "wind_scale": (0.7, 1.3),
}

_DRY_BULB, _DEW_POINT, _RH, _IR, _WIND = 7, 8, 9, 13, 22
_SOLAR = (14, 15, 16, 17, 18, 19)  # GHI, DNI, DHI (Wh/m2) and their illuminances (lux)
#: EPW's "missing" codes of the fields a morph changes (EnergyPlus Auxiliary Programs, "Weather Data Format").
_MISSING = {
    _DRY_BULB: 99.9,
    _DEW_POINT: 99.9,
    _RH: 999.0,
    _IR: 9999.0,
    14: 9999.0,
    15: 9999.0,
    16: 9999.0,
    17: 999999.0,
    18: 999999.0,
    19: 999999.0,
    _WIND: 999.0,
}
_FIELDS = 35
_HEADER_LINES = 8
_NOTE = "COMMENTS 2,buildenv morph of "


@dataclass(frozen=True)
class Morph:
    """How a weather file is changed (see the module docstring).

    Attributes:
        shift_k: added to every dry-bulb temperature, K.
        stretch: factor on each hour's departure from its monthly mean temperature, -.
        solar_scale: factor on the solar radiation and illuminance fields, -.
        wind_scale: factor on the wind speed, -.
    """

    shift_k: float = 0.0
    stretch: float = 1.0
    solar_scale: float = 1.0
    wind_scale: float = 1.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not np.isfinite(value):
                raise WeatherError(f"morph {name}: {value} is not a number")
        for name in ("stretch", "solar_scale", "wind_scale"):
            if getattr(self, name) < 0:
                raise WeatherError(f"morph {name}: {getattr(self, name)} must be >= 0")


def draw_morph(rng: np.random.Generator, **fixed: float) -> Morph:
    """A random :class:`Morph` from :data:`MORPH_RANGES`; keyword arguments fix some of its values."""
    unknown = set(fixed) - set(MORPH_RANGES)
    if unknown:
        raise WeatherError(f"unknown morph value(s) {sorted(unknown)}; known: {', '.join(MORPH_RANGES)}")
    values = {name: float(rng.uniform(*bounds)) for name, bounds in MORPH_RANGES.items()}
    return Morph(**{**values, **{k: float(v) for k, v in fixed.items()}})


def weather_year(year: int) -> Morph:
    """The morph that makes synthetic weather year ``year`` of any weather file: no change for year 0, else a
    :func:`draw_morph` seeded with ``year`` (the same morph for every site and every run)."""
    return Morph() if year == 0 else draw_morph(np.random.default_rng(year))


def _magnus(t_c: np.ndarray) -> np.ndarray:
    """Saturation vapour pressure up to a constant factor (Magnus, over water), for ratios only."""
    return np.exp(17.625 * t_c / (243.04 + t_c))


def morph_rows(rows: np.ndarray, morph: Morph) -> np.ndarray:
    """Apply a morph to the numeric fields of an EPW's 8,760 data rows.

    Args:
        rows: ``(8760, 35)`` float array of the data rows' fields (0-based columns: field ``n`` is column
            ``n - 1``; only the fields a morph changes are read).
        morph: what to change.
    Returns:
        a new ``(8760, 35)`` array.
    """
    out = rows.copy()
    t = rows[:, _DRY_BULB - 1]
    t_new = _stretched(t, morph)
    dew = np.minimum(rows[:, _DEW_POINT - 1] + (t_new - t), t_new)
    out[:, _DRY_BULB - 1] = t_new
    out[:, _DEW_POINT - 1] = dew
    saturation = (_magnus(dew) / _magnus(t_new)) / (_magnus(rows[:, _DEW_POINT - 1]) / _magnus(t))
    out[:, _RH - 1] = np.clip(rows[:, _RH - 1] * saturation, 0.0, 100.0)
    out[:, _IR - 1] = rows[:, _IR - 1] * ((t_new + 273.15) / (t + 273.15)) ** 4
    for field in _SOLAR:
        out[:, field - 1] = rows[:, field - 1] * morph.solar_scale
    out[:, _WIND - 1] = rows[:, _WIND - 1] * morph.wind_scale
    for field, code in _MISSING.items():  # a value marked missing stays missing
        gone = rows[:, field - 1] >= code
        out[gone, field - 1] = rows[gone, field - 1]
    return out


def _stretched(t: np.ndarray, morph: Morph) -> np.ndarray:
    """Hourly dry-bulb temperatures ``(8760,)`` shifted and stretched about their monthly means."""
    month = month_of_hour()
    monthly = np.array([t[month == m].mean() for m in range(12)])[month]
    return t + morph.shift_k + (morph.stretch - 1.0) * (t - monthly)


def morph_weather(weather: Weather, morph: Morph) -> Weather:
    """``weather`` changed as :func:`morph_epw` changes its file, in memory: the dry bulb shifted and stretched
    about its monthly means, the relative humidity kept at the same dew-point depression (the dew point from
    the temperature and humidity by the Magnus formula), the solar channels times ``solar_scale``, the wind speed
    times ``wind_scale``; the wind direction and the site's metadata kept.

    Returns:
        a new :class:`buildenv.weather.epw.Weather` (``name`` the source's with ``+morph``, ``path`` the source's).
    """
    hourly = np.array(weather.hourly, dtype=float)
    column = {name: cat.WEATHER_NAMES.index(name) for name in cat.WEATHER_NAMES}
    t = hourly[:, column["TAMB"]]
    t_new = _stretched(t, morph)
    gamma = np.log(np.clip(hourly[:, column["RHUM"]], 0.1, 100.0) / 100.0) + 17.625 * t / (243.04 + t)
    dew = 243.04 * gamma / (17.625 - gamma)
    dew_new = np.minimum(dew + (t_new - t), t_new)
    hourly[:, column["RHUM"]] = np.clip(100.0 * _magnus(dew_new) / _magnus(t_new), 0.0, 100.0)
    hourly[:, column["TAMB"]] = t_new
    for name in ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H"):
        hourly[:, column[name]] *= morph.solar_scale
    hourly[:, column["WIND_SPEED"]] *= morph.wind_scale
    hourly.setflags(write=False)
    return replace(weather, name=f"{weather.name}+morph", hourly=hourly)


def morph_epw(source: str | os.PathLike, out: str | os.PathLike, morph: Morph) -> Path:
    """Write a morphed copy of an EPW file.

    Args:
        source: shipped short name (``usa_il_chicago``) or EPW path.
        out: path of the new EPW file (its directory is created).
        morph: what to change (:class:`Morph`).
    Returns:
        the path written.
    Raises:
        WeatherError: the source is missing, or not an hourly 8,760-row EPW (naming the line).
    """
    path = resolve_epw(source)
    lines = path.read_text(encoding="latin-1").splitlines()
    header, data = lines[:_HEADER_LINES], [line for line in lines[_HEADER_LINES:] if line.strip()]
    if len(data) != HOURS_PER_YEAR:
        raise WeatherError(f"{path}: expected {HOURS_PER_YEAR} hourly rows, found {len(data)}")
    fields = [line.split(",") for line in data]
    numeric = np.zeros((HOURS_PER_YEAR, _FIELDS))
    for i, row in enumerate(fields):
        if len(row) < _FIELDS:
            raise WeatherError(f"{path}, line {i + _HEADER_LINES + 1}: {len(row)} fields, an EPW row has {_FIELDS}")
        for j in (_DRY_BULB, _DEW_POINT, _RH, _IR, _WIND, *_SOLAR):
            try:
                numeric[i, j - 1] = float(row[j - 1])
            except ValueError:
                raise WeatherError(
                    f"{path}, line {i + _HEADER_LINES + 1}, field {j}: {row[j - 1]!r} is not a number"
                ) from None
    new = morph_rows(numeric, morph)
    for i, row in enumerate(fields):
        for j in (_DRY_BULB, _DEW_POINT):
            row[j - 1] = f"{new[i, j - 1]:.1f}"
        row[_RH - 1] = str(int(round(new[i, _RH - 1])))
        row[_IR - 1] = str(int(round(new[i, _IR - 1])))
        row[_WIND - 1] = f"{new[i, _WIND - 1]:.1f}"
        for j in _SOLAR:
            row[j - 1] = str(int(round(new[i, j - 1])))
    header = [
        _shift_ground(line, morph.shift_k) if line.upper().startswith("GROUND TEMPERATURES") else line
        for line in header
    ]
    note = _NOTE + path.name + " " + json.dumps(asdict(morph), allow_nan=False).replace(",", ";")
    header = [note if line.upper().startswith("COMMENTS 2") else line for line in header]
    target = Path(out)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text("\r\n".join(header + [",".join(row) for row in fields]) + "\r\n", encoding="latin-1")
    return target


def _shift_ground(line: str, shift_k: float) -> str:
    """The EPW ``GROUND TEMPERATURES`` header with each depth's 12 monthly values raised by ``shift_k``."""
    parts = line.split(",")
    try:
        depths = int(parts[1])
        for d in range(depths):
            start = 2 + d * 16 + 4  # depth, conductivity, density, specific heat, then 12 months
            for k in range(start, start + 12):
                parts[k] = f"{float(parts[k]) + shift_k:.2f}"
    except (ValueError, IndexError):
        return line  # a header without usable ground temperatures: EnergyPlus uses its own then
    return ",".join(parts)


def morph_many(sources: list[str], out_dir: str | os.PathLike, seed: int, **fixed: float) -> list[dict]:
    """One morphed file per source, each with its own random :class:`Morph` (seeded), into ``out_dir``.

    Files are named ``<source stem>-morph<seed>-<i>.epw``; ``out_dir/morphs.json`` lists each file with its
    source and morph. Returns that list.
    """
    rng = np.random.default_rng(seed)
    records = []
    for i, source in enumerate(sources):
        morph = draw_morph(rng, **fixed)
        stem = Path(source).stem if Path(source).suffix.lower() == ".epw" else source
        path = morph_epw(source, Path(out_dir) / f"{stem}-morph{seed}-{i}.epw", morph)
        records.append({"file": str(path), "source": source, **{k: round(v, 4) for k, v in asdict(morph).items()}})
    (Path(out_dir) / "morphs.json").write_text(json.dumps(records, indent=2, allow_nan=False) + "\n")
    return records


def morph_source(path: str | os.PathLike) -> str | None:
    """The file name of the EPW a morphed file was made from (its ``COMMENTS 2`` line), or None when ``path``
    is not a morph (a shipped short name, an ordinary EPW, or a missing file)."""
    try:
        epw = resolve_epw(path)
    except WeatherError:
        return None
    with epw.open(encoding="latin-1") as f:
        for _, line in zip(range(_HEADER_LINES), f):
            if line.startswith(_NOTE):
                return line[len(_NOTE) :].rsplit(" {", 1)[0]
    return None
