"""The suite: reference-office stand-ins over buildings x climates x seasons, to develop against and judge on.

Each case is one shipped reference office (:data:`buildenv.energyplus.reference.REFERENCE_BUILDINGS`) run in one
shipped climate over one season (8 weeks by default) under a BMS history whose settings change from week to week
(:func:`bms_history`), read as sensors into a site folder (:func:`buildenv.energyplus.reference.make_reference_site`).
The climates run from hot (Miami) to cold (Denver); the seasons are a heating season from mid-January and a
cooling season from July. A site's consumption meter sums the end uses of its season (:data:`SEASON_END_USES`):
heating + lighting + plug loads, and cooling too in the cooling season; with ``meters="split"``
(:data:`SPLIT_METERS`) the heat (and chilled water) and the electricity are metered apart.

**Held out.** The climates of :data:`HELD_OUT_CLIMATES` (both seasons, every building) are set aside before any
tuning: figures meant to judge a model are reported on them apart from the development part. Newark is one of
them because the shipped metamodel never trained on it.

:func:`make_suite` writes ``<out>/<case>/`` site folders and ``<out>/suite.json`` (one record per case: made,
refused with the one-line reason, or failed); it is resumable (a case whose site folder loads is not run again).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import multiprocessing
import os
import shutil
import time
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.defaults import default_week
from buildenv.errors import BuildenvError
from buildenv.jsonio import dumps

log = logging.getLogger(__name__)

#: Climates of the suite, hot to cold (shipped TMY3 short names), with their ASHRAE 169 climate zone.
SUITE_CLIMATES: dict[str, str] = {
    "usa_fl_miami": "1A",
    "usa_az_phoenix": "2B",
    "usa_ca_san_francisco": "3C",
    "usa_ok_oklahoma": "3A",
    "usa_nj_newark": "4A",
    "usa_il_chicago": "5A",
    "usa_co_denver": "5B",
}
#: Climates set aside for judging; never used to choose or tune anything.
HELD_OUT_CLIMATES: tuple[str, ...] = ("usa_az_phoenix", "usa_nj_newark")
#: Season -> (month, day) on or after which its first Monday falls.
SEASONS: dict[str, tuple[int, int]] = {"heating": (1, 14), "cooling": (7, 1)}
#: Season -> the end uses its sites' consumption meter sums (``site.toml`` ``[meters] consumption``).
SEASON_END_USES: dict[str, tuple[str, ...]] = {
    "heating": cat.DEFAULT_END_USES,
    "cooling": ("heating", "cooling", "lighting", "plug_loads"),
}
#: ``meters="split"``: season -> (the thermal meter's end uses, the electricity meter's): a building that meters the
#: heat (and chilled water) its plant delivers apart from the electricity of its lights and plug loads.
SPLIT_METERS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "heating": (("heating",), ("lighting", "plug_loads")),
    "cooling": (("heating", "cooling"), ("lighting", "plug_loads")),
}
#: How a suite's sites meter: ``one`` meter (:data:`SEASON_END_USES`) or heat and electricity ``split``.
METERING = ("one", "split")
SUITE_YEAR = 2019
SUITE_WEEKS = 8
MANIFEST = "suite.json"
#: the fields of a case's record that every table of the suite repeats
CASE_FIELDS: tuple[str, ...] = ("building", "climate", "season", "part", "site")


def _check_metering(metering: str) -> None:
    """A BuildenvError unless ``metering`` is one of :data:`METERING`."""
    if metering not in METERING:
        raise BuildenvError(f"metering {metering!r} is not one of {', '.join(METERING)}")


@dataclass(frozen=True)
class SuiteCase:
    """One site of the suite: a reference office in a climate over a season."""

    building: str
    climate: str
    season: str

    @property
    def name(self) -> str:
        return f"{self.building}-{self.climate}-{self.season}"

    @property
    def part(self) -> str:
        """``held_out`` or ``development`` (see :data:`HELD_OUT_CLIMATES`)."""
        return "held_out" if self.climate in HELD_OUT_CLIMATES else "development"

    @property
    def end_uses(self) -> tuple[str, ...]:
        """End uses the case's consumption meter sums (:data:`SEASON_END_USES`)."""
        return SEASON_END_USES[self.season]

    def meters(self, metering: str = "one") -> tuple[tuple[str, ...], tuple[str, ...]]:
        """``(the consumption meter's end uses, the electricity meter's)`` under ``metering`` (:data:`METERING`);
        one meter: the second is empty."""
        _check_metering(metering)
        return SPLIT_METERS[self.season] if metering == "split" else (self.end_uses, ())

    def start(self, year: int = SUITE_YEAR) -> dt.date:
        """The first Monday of the season in ``year``."""
        month, day = SEASONS[self.season]
        first = dt.date(year, month, day)
        return first + dt.timedelta(days=(7 - first.weekday()) % 7)

    def seed(self, suite_seed: int = 0) -> int:
        """A seed that depends only on the case's name and ``suite_seed`` (stable across Python runs)."""
        return zlib.crc32(f"{self.name}:{suite_seed}".encode())


def suite_cases(
    buildings: Sequence[str] | None = None,
    climates: Sequence[str] | None = None,
    seasons: Sequence[str] | None = None,
) -> list[SuiteCase]:
    """The cases of the suite (all of them by default), buildings x climates x seasons.

    Raises:
        BuildenvError: an unknown building, climate or season, named with the known ones.
    """
    from buildenv.energyplus.reference import REFERENCE_BUILDINGS

    chosen = []
    for label, given, known in (
        ("building", buildings, tuple(REFERENCE_BUILDINGS)),
        ("climate", climates, tuple(SUITE_CLIMATES)),
        ("season", seasons, tuple(SEASONS)),
    ):
        values = tuple(known if not given else given)
        unknown = [v for v in values if v not in known]
        if unknown:
            raise BuildenvError(f"unknown suite {label} {', '.join(unknown)}; choose from {', '.join(known)}")
        chosen.append(values)
    return [SuiteCase(b, c, s) for b in chosen[0] for c in chosen[1] for s in chosen[2]]


#: The ventilation change of a BMS history, 1/h: an outdoor air damper reset by a third or more of an office's design.
VENTILATION_CHANGE_ACH = 0.3


def _step(settings: np.ndarray, names: Iterable[str], delta: float) -> None:
    """Add ``delta`` to the named settings of every day, snapped to their catalogue step and range (in place)."""
    for name in names:
        var = cat.get(name)
        j = cat.SETTING_NAMES.index(name)
        settings[..., j] = var.snap(np.clip(settings[..., j] + delta, var.min, var.max))


def bms_history(
    weeks: int, ventilation_ach: float, rng: np.random.Generator, lowest_ach: float | None = None
) -> np.ndarray:
    """Historical settings ``(weeks, 7, 13)`` that change from week to week as BMS histories do.

    Starts from the typical settings (:func:`buildenv.defaults.default_week`) with ``ventilation_ach`` (1/h), then,
    from the second week on, each week may move the heating or cooling comfort setpoint by one step, a setback by
    1 K, or the occupied schedule (heating, cooling and ventilation together) by an hour; one week lowers the
    ventilation by :data:`VENTILATION_CHANGE_ACH`, not below ``lowest_ach`` (1/h, the lower limit of the site's BMS,
    its ASHRAE 62.1 minimum: down to it where the full change would pass it, none where the ventilation is already
    there); without ``lowest_ach`` it is raised where it would fall below the catalogue's minimum. Each change holds
    until the next; every value stays on its catalogue step and range. Weeks >= 3 always hold at least one setpoint
    and one schedule change, and a ventilation change where the BMS range allows one, all within the weeks a
    calibration fits by default (:func:`buildenv.calibration.problem.default_weeks`, from its second week), so that
    it sees how the building responds to each; the later weeks may hold further setpoint and schedule changes.
    """
    from buildenv.calibration.problem import default_weeks

    settings = default_week(weeks)[0].copy()
    vent = cat.get("ventilation_ach")
    settings[..., cat.SETTING_NAMES.index("ventilation_ach")] = vent.snap(np.clip(ventilation_ach, vent.min, vent.max))
    if weeks < 2:
        return settings
    moves = {
        "heating_comfort": (("heating_comfort_c",), 0.5),
        "cooling_comfort": (("cooling_comfort_c",), 0.5),
        "heating_setback": (("heating_setback_c",), 1.0),
        "cooling_setback": (("cooling_setback_c",), 1.0),
        "schedule_start": (("heating_start_hour", "cooling_start_hour", "ventilation_start_hour"), 1.0),
        "schedule_end": (("heating_end_hour", "cooling_end_hour", "ventilation_end_hour"), 1.0),
    }
    weeks_changed = list(range(1, weeks))
    plan: dict[int, list[str]] = {w: [m for m in moves if rng.random() < 0.25] for w in weeks_changed}
    fitted = max(len(default_weeks(weeks)[0]), 2)  # the changes that must be seen: weeks 1 .. fitted - 1
    if weeks >= 3:  # at least one setpoint, one schedule and one ventilation change
        plan[int(rng.integers(1, fitted))].append(str(rng.choice(["heating_comfort", "cooling_comfort"])))
        plan[int(rng.integers(1, fitted))].append(str(rng.choice(["schedule_start", "schedule_end"])))
    vent_week = (fitted + 1) // 2  # half the fitted weeks on each side of it
    for w in weeks_changed:
        for move in dict.fromkeys(plan[w]):
            names, size = moves[move]
            sign = 1.0 if rng.random() < 0.5 else -1.0
            var, j = cat.get(names[0]), cat.SETTING_NAMES.index(names[0])
            if not var.min <= settings[w, 0, j] + sign * size <= var.max:  # a move that would hit the bound turns
                sign = -sign
            _step(settings[w:], names, sign * size)
        if w == vent_week:  # down, as a building can act on it (outdoor air above its design it cannot deliver)
            j = cat.SETTING_NAMES.index("ventilation_ach")
            current = settings[w, 0, j]
            if lowest_ach is not None:  # down, to the BMS's lowest at most
                delta = min(0.0, max(-VENTILATION_CHANGE_ACH, lowest_ach - current))
            else:
                down = current - VENTILATION_CHANGE_ACH >= vent.min - 1e-9
                delta = -VENTILATION_CHANGE_ACH if down else VENTILATION_CHANGE_ACH
            _step(settings[w:], ("ventilation_ach",), delta)
    cat.check_values("settings", settings, "bms_history")
    return settings


def reference_history(building: str, weeks: int, rng: np.random.Generator) -> np.ndarray:
    """The BMS history ``(weeks, 7, 13)`` of a reference office: :func:`bms_history` from its design outdoor air,
    its ventilation change kept within its BMS limits
    (:func:`buildenv.energyplus.reference.reference_bms`), shut down on the days the office's own schedules shut
    it down (:func:`buildenv.energyplus.reference.operating_days`: Sunday, or the weekend)."""
    from buildenv.energyplus.reference import historical_ventilation_ach, operating_days, reference_bms

    lowest = reference_bms(building)[1]["ventilation_ach"][0]
    settings = bms_history(weeks, historical_ventilation_ach(building), rng, lowest_ach=lowest)
    settings[..., cat.SETTING_NAMES.index("hvac_operating")] = np.asarray(operating_days(building), float)
    return settings


def make_case(
    case: SuiteCase, out: str | Path, weeks: int = SUITE_WEEKS, suite_seed: int = 0, metering: str = "one"
) -> dict:
    """Make one case's site folder ``<out>/<case.name>`` (or reuse it when it already loads with the case's
    weeks, start and meters, :meth:`SuiteCase.meters` under ``metering``).

    Returns:
        the case's record: its fields, ``part``, ``start``, ``meters`` (end uses), ``site`` (folder), ``status``
        (``made``, ``reused``, ``refused``: the stand-in or the site format cannot take the case, ``reason`` says
        why in one line), ``seconds``.
    """
    from buildenv.energyplus.reference import (
        STAND_IN_VERSION,
        make_reference_site,
        reference_bms,
        stand_in_version,
    )
    from buildenv.sites.reader import load_site

    folder = Path(out) / case.name
    record = {
        **asdict(case),
        "part": case.part,
        "start": case.start().isoformat(),
        "weeks": weeks,
        "meters": list(case.meters(metering)[0]),
        **({"electricity_meter": list(case.meters(metering)[1])} if metering == "split" else {}),
        "site": str(folder),
    }
    started = time.perf_counter()
    existed = folder.exists()
    try:
        settings = reference_history(case.building, weeks, np.random.default_rng(case.seed(suite_seed)))
        if (folder / "site.toml").is_file():
            site = load_site(folder)
            metered = (site.consumption_end_uses, site.electricity_end_uses)
            same = (site.weeks, site.start, metered) == (weeks, case.start(), case.meters(metering))
            same = same and stand_in_version(site) == STAND_IN_VERSION  # an earlier stand-in's site is made again
            # another history is made again (the supply air is what the building recorded)
            kept = [j for j, name in enumerate(cat.SETTING_NAMES) if name != "supply_air_c"]
            same = same and np.allclose(site.settings[..., kept], settings[..., kept])
            if same and (site.controllable, site.setting_limits) == reference_bms(case.building):
                return {**record, "status": "reused", "seconds": 0.0}
        make_reference_site(
            folder,
            case.building,
            case.climate,
            case.start(),
            weeks,
            settings=settings,
            seed=case.seed(suite_seed),
            end_uses=case.meters(metering)[0],
            electricity_end_uses=case.meters(metering)[1],
        )
        status = {"status": "made"}
    except BuildenvError as error:
        status = {"status": "refused", "reason": str(error).splitlines()[0]}
        if not existed:  # a refused case leaves nothing behind
            shutil.rmtree(folder, ignore_errors=True)
    return {**record, **status, "seconds": round(time.perf_counter() - started, 1)}


def _make_case_star(job: tuple) -> dict:
    return make_case(*job)


def make_suite(
    out: str | Path,
    cases: Sequence[SuiteCase] | None = None,
    weeks: int = SUITE_WEEKS,
    workers: int | None = None,
    suite_seed: int = 0,
    progress: bool = True,
    metering: str = "one",
) -> list[dict]:
    """Make the suite's site folders under ``out`` and write ``out/suite.json``.

    Args:
        out: the suite folder (created if needed).
        cases: the cases to make; default every case (:func:`suite_cases`).
        weeks: measured weeks per site.
        workers: EnergyPlus processes side by side; default the CPU count.
        suite_seed: seed of the BMS histories and the sensor noise (each case draws its own from it).
        progress: a progress bar.
        metering: ``one`` meter a site or heat and electricity ``split`` (:data:`METERING`).
    Returns:
        one record per case (:func:`make_case`), in the order of ``cases``; the manifest keeps every record,
        earlier ones of cases not in ``cases`` included.
    """
    from tqdm import tqdm

    cases = list(suite_cases() if cases is None else cases)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    _check_metering(metering)
    jobs = [(case, folder, weeks, suite_seed, metering) for case in cases]
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    records: list[dict] = []
    bar = tqdm(total=len(jobs), desc="suite", unit="site", disable=not progress)
    if workers == 1:
        for job in jobs:
            records.append(_make_case_star(job))
            bar.update()
    else:  # fresh processes: EnergyPlus leaves state behind in the process that ran it
        with multiprocessing.get_context("spawn").Pool(workers, maxtasksperchild=1) as pool:
            for record in pool.imap(_make_case_star, jobs):
                records.append(record)
                bar.update()
    bar.close()
    write_manifest(folder, records)
    return records


def read_manifest(out: str | Path) -> list[dict]:
    """The records of ``out/suite.json``, one per site folder, each ``site`` inside ``out`` (a suite folder may be
    copied or moved: a record names its folder, which is taken from ``out``); raises :class:`BuildenvError` when
    the folder has none."""
    path = Path(out) / MANIFEST
    if not path.is_file():
        raise BuildenvError(f"{path}: not found; make the suite first (buildenv suite make --out {out})")
    try:
        cases = json.loads(path.read_text(encoding="utf-8"))["cases"]
        return list(_by_folder(Path(out), cases).values())
    except (json.JSONDecodeError, KeyError, TypeError) as error:
        raise BuildenvError(f"{path}: not a suite manifest ({error}); make the suite again") from error


def _by_folder(out: Path, records: Iterable[dict]) -> dict[str, dict]:
    """``{site folder name: record}`` with each record's ``site`` in ``out`` (later records replace earlier)."""
    return {Path(r["site"]).name: {**r, "site": str(out / Path(r["site"]).name)} for r in records}


def calibrated_records(out: str | Path, parts: Sequence[str]) -> list[dict]:
    """The records of the suite's made sites in ``parts`` that hold a ``calibration.json``.

    Raises:
        BuildenvError: none (run ``buildenv suite calibrate`` first), or the folder has no manifest.
    """
    records = [
        r
        for r in read_manifest(out)
        if r["status"] in ("made", "reused") and r["part"] in parts and (Path(r["site"]) / "calibration.json").is_file()
    ]
    if not records:
        raise BuildenvError(f"{out}: no calibrated site in {', '.join(parts)}; run buildenv suite calibrate first")
    return records


def calibrated_buildings(paths: Sequence[str | Path]) -> list[dict]:
    """The calibrated buildings of site folders, or of a suite's development sites (its held-out part is never
    used), to draw a campaign around (``buildenv simulate --around``).

    Args:
        paths: calibrated site folders (with a ``calibration.json``) or suite folders (with a ``suite.json``).
    Returns:
        ``[{"site": folder, "theta": {name: value}}]``, every theta_build variable in catalogue units, the geometry
        the site's.
    Raises:
        BuildenvError: a folder that is neither, or a suite without a calibrated development site.
    """
    from buildenv.sites.model import CALIBRATION_FILE
    from buildenv.sites.reader import load_site

    buildings = []
    for path in map(Path, paths):
        if (path / MANIFEST).is_file():
            folders = [Path(r["site"]) for r in calibrated_records(path, ("development",))]
        elif (path / CALIBRATION_FILE).is_file():
            folders = [path]
        else:
            raise BuildenvError(
                f"{path}: neither a calibrated site (no {CALIBRATION_FILE}) nor a suite (no {MANIFEST}); calibrate "
                "it first (buildenv calibrate --site, buildenv suite calibrate)"
            )
        for folder in folders:
            site = load_site(folder)
            theta = {**site.calibration.get("theta", {}), **{n: getattr(site, n) for n in cat.GEOMETRY_NAMES}}
            buildings.append({"site": str(folder), "theta": {k: float(v) for k, v in theta.items()}})
    return buildings


def check_calibrated_sites(
    out: str | Path,
    parts: Sequence[str],
    check: Callable[[dict], list[dict]],
    results: str,
    desc: str,
    progress: bool = True,
) -> list[dict]:
    """Run ``check(record)`` on every calibrated site of the suite in ``parts`` (:func:`calibrated_records`) and keep
    its rows, each led by the case's fields. A site whose check raises :class:`BuildenvError` is logged and recorded
    under ``errors`` (the message's first line), and the others go on. ``out/<results>`` (``{"rows", "errors"}``,
    standard JSON) is rewritten after each site, so an interrupted run keeps what it finished.

    Raises:
        BuildenvError: no calibrated site in ``parts``.
    """
    from tqdm import tqdm

    rows, errors = [], []
    for r in tqdm(calibrated_records(out, parts), desc=desc, unit="site", disable=not progress):
        case = {k: r[k] for k in CASE_FIELDS}
        try:
            rows += [{**case, **row} for row in check(r)]
        except BuildenvError as error:
            reason = (str(error).splitlines() or [type(error).__name__])[0]
            log.warning("%s: %s failed: %s", r["site"], desc, reason)
            errors.append({**case, "error": reason})
        path = Path(out, results)
        text = dumps({"rows": rows, "errors": errors}, where=str(path), nonfinite="null", indent=1)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text + "\n", encoding="utf-8")
        os.replace(tmp, path)
    return rows


def failed_sites(out: str | Path, results: str) -> list[dict]:
    """The ``errors`` of a results file :func:`check_calibrated_sites` wrote (``[]`` where it holds none)."""
    path = Path(out, results)
    try:
        return list(json.loads(path.read_text(encoding="utf-8")).get("errors", []))
    except (OSError, json.JSONDecodeError, AttributeError) as error:
        raise BuildenvError(f"{path}: not a results file of the suite checks ({error}); run the check again") from error


def write_manifest(out: Path, records: Sequence[dict]) -> Path:
    """Merge ``records`` into ``out/suite.json`` by site folder (later records replace earlier ones)."""
    path = out / MANIFEST
    merged = _by_folder(out, read_manifest(out) if path.is_file() else [])
    merged.update(_by_folder(out, records))
    manifest = {"held_out_climates": list(HELD_OUT_CLIMATES), "cases": list(merged.values())}
    text = dumps(manifest, where=str(path), indent=1)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(text + "\n", encoding="utf-8")
    tmp.replace(path)
    return path
