"""A library of calibrated sites: many buildings for ``BuildingWeek-v0`` (``site="library"``).

A library folder holds one site folder per site, with what a calibrated site needs (``site.toml``,
``measurements.csv``, ``settings.csv``, ``calibration.json``, ``truth.json``; not the calibration plot), and its
index ``library.toml``: one ``[[sites]]`` table per site with its ``name`` (its sub-folder), ``building``,
``climate``, ``season``, ``part`` (``train`` or ``test``, the split ``BuildingWeek-v0``'s ``sites=`` chooses by),
``guideline14`` (whether its calibration passes ASHRAE Guideline 14) and ``metamodel_id`` (the identity of the
metamodel it was calibrated with, :func:`buildenv.calibration.problem.metamodel_record`; left out when the
calibration does not record it).

:func:`write_library` makes one from a calibrated suite (:mod:`buildenv.sites.suite`, ``buildenv suite
calibrate``); the suite's held-out climates (:data:`buildenv.sites.suite.HELD_OUT_CLIMATES`) are the test part, its
development part the train part, so a policy trained on the library's train part is judged on climates nobody
tuned anything on. :func:`read_library` reads the index.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from buildenv.errors import BuildenvError, SiteError
from buildenv.sites.model import CALIBRATION_FILE, DEFAULT_MEASUREMENTS, DEFAULT_SETTINGS, DESCRIPTOR, TRUTH_FILE

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

LIBRARY_INDEX = "library.toml"
#: the library ``BuildingWeek-v0`` runs with ``site="library"`` (built by ``buildenv suite library``)
SHIPPED_LIBRARY = Path(__file__).resolve().parents[1] / "data" / "sites" / "library"
#: the files copied from each suite site (the last one is optional: a measured site has no truth)
LIBRARY_FILES: tuple[str, ...] = (DESCRIPTOR, DEFAULT_MEASUREMENTS, DEFAULT_SETTINGS, CALIBRATION_FILE, TRUTH_FILE)
#: the suite's part -> the library's
PARTS: dict[str, str] = {"development": "train", "held_out": "test"}
LIBRARY_PARTS: tuple[str, ...] = ("train", "test")


@dataclass(frozen=True)
class LibrarySite:
    """One site of a library: its name (sub-folder), folder, part, where it comes from and the metamodel it was
    calibrated with (``""`` when unknown)."""

    name: str
    folder: Path
    part: str
    building: str = ""
    climate: str = ""
    season: str = ""
    metamodel_id: str = ""


def is_library(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` holds a library index (``library.toml``)."""
    return (Path(folder).expanduser() / LIBRARY_INDEX).is_file()


def read_library(folder: str | os.PathLike) -> list[LibrarySite]:
    """The sites of a library folder, in the index's order.

    Raises:
        SiteError: no index, an index that is not TOML, a site without a name, a part other than train or test,
            a name twice, or a site whose folder holds no ``site.toml`` (one line naming the index and the site).
    """
    folder = Path(folder).expanduser()
    path = folder / LIBRARY_INDEX
    if not path.is_file():
        raise SiteError(
            f"{folder}: not a site library: {LIBRARY_INDEX} is missing "
            f"(build one with buildenv suite library --suite DIR --out {folder})"
        )
    try:
        rows = tomllib.loads(path.read_text(encoding="utf-8")).get("sites")
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise SiteError(f"{path}: not valid TOML ({error})") from None
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise SiteError(f"{path}: no [[sites]] tables; build the library again with buildenv suite library")
    sites: list[LibrarySite] = []
    for number, row in enumerate(rows, 1):
        name, part = row.get("name"), row.get("part")
        if not isinstance(name, str) or not name or Path(name).name != name:
            raise SiteError(f"{path}: site {number} has no name (a sub-folder of {folder}): name={name!r}")
        if part not in LIBRARY_PARTS:
            raise SiteError(f"{path}: site {name!r}: part={part!r}; give one of {', '.join(LIBRARY_PARTS)}")
        if any(s.name == name for s in sites):
            raise SiteError(f"{path}: site {name!r} is listed twice")
        if not (folder / name / DESCRIPTOR).is_file():
            raise SiteError(f"{path}: site {name!r}: {folder / name} holds no {DESCRIPTOR}")
        extra = {k: str(row.get(k, "")) for k in ("building", "climate", "season", "metamodel_id")}
        sites.append(LibrarySite(name, folder / name, part, **extra))
    return sites


def calibrated_cases(suite: str | os.PathLike) -> list[dict]:
    """The suite's made sites that carry a calibration (``buildenv suite calibrate``), sorted by name, each its
    manifest record with ``name`` (its folder's) and ``folder`` (``<suite>/<name>``, as
    :func:`buildenv.sites.suite.read_manifest` places it) added."""
    from buildenv.sites.suite import read_manifest

    cases = []
    for record in read_manifest(suite):
        folder = Path(record["site"])
        if record.get("status") in ("made", "reused") and (folder / CALIBRATION_FILE).is_file():
            cases.append({**record, "name": folder.name, "folder": folder})
    return sorted(cases, key=lambda c: c["name"])


def _spread(items: list[dict], k: int) -> list[dict]:
    """``k`` of ``items`` spread evenly (the middle of ``k`` equal bins)."""
    return [items[(2 * i + 1) * len(items) // (2 * k)] for i in range(k)] if k > 0 else []


def choose(cases: list[dict], n: int | None) -> list[dict]:
    """``n`` of the suite's ``cases`` (all with None), both parts in proportion (each at least one when both exist
    and ``n >= 2``), spread evenly over the cases sorted by name (building, climate, season); sorted by name."""
    if n is None or n >= len(cases):
        return list(cases)
    if n < 1:
        raise BuildenvError(f"--sites {n}: give 1 or more")
    test = [c for c in cases if c["part"] == "held_out"]
    train = [c for c in cases if c["part"] != "held_out"]
    n_test = round(n * len(test) / len(cases))
    if n >= 2 and test and train:
        n_test = min(max(n_test, 1), n - 1)
    n_test = min(len(test), max(n_test, n - len(train)))
    return sorted(_spread(train, n - n_test) + _spread(test, n_test), key=lambda c: c["name"])


def _index(rows: list[dict]) -> str:
    """``library.toml`` of ``rows``: a comment, then one ``[[sites]]`` table per row (``tomli_w``)."""
    import tomli_w

    from buildenv.sites.suite import HELD_OUT_CLIMATES
    from buildenv.sites.writer import _toml_plain

    lines = [
        "# A library of calibrated sites for BuildingWeek-v0 (site=...; sites='train' | 'test' | 'all'),",
        "# written by `buildenv suite library` from a calibrated suite. part: train = the suite's development part,",
        f"# test = its held-out climates ({', '.join(HELD_OUT_CLIMATES)}).",
    ]
    return "\n".join(lines) + "\n\n" + tomli_w.dumps(_toml_plain({"sites": rows}, LIBRARY_INDEX))


def common_limits(limits: dict[str, dict[str, tuple[float, float]]]) -> dict[str, tuple[float, float]]:
    """The ``[bms] limits`` sites share: for each setting any of them limits, the overlap of their ranges (a site
    that does not limit it contributes the catalogue's range). ``limits``: ``{site name: its limits}``.

    Raises:
        BuildenvError: the ranges of a setting do not overlap, naming the two sites furthest apart.
    """
    from buildenv import catalogue as cat

    common: dict[str, tuple[float, float]] = {}
    for name in sorted({n for site in limits.values() for n in site}):
        var = cat.get(name)
        ranges = {site: own.get(name, (var.min, var.max)) for site, own in limits.items()}
        low, high = max(ranges, key=lambda k: ranges[k][0]), min(ranges, key=lambda k: ranges[k][1])
        if ranges[low][0] > ranges[high][1] + 1e-9:
            raise BuildenvError(
                f"{name}: site {low!r} limits it to [{ranges[low][0]:g}, {ranges[low][1]:g}] and site {high!r} to "
                f"[{ranges[high][0]:g}, {ranges[high][1]:g}]: no shared range; put them in libraries of their own"
            )
        common[name] = (float(ranges[low][0]), float(ranges[high][1]))
    return common


def _write_limits(descriptor: Path, limits: dict[str, tuple[float, float]]) -> None:
    """Set ``[bms] limits`` of a copied ``site.toml`` to ``limits`` where they differ (the file rewritten)."""
    import tomli_w

    data = tomllib.loads(descriptor.read_text(encoding="utf-8"))
    bms = data.setdefault("bms", {})
    own = {k: tuple(map(float, v)) for k, v in bms.get("limits", {}).items()}
    if not limits or own == limits:
        return
    bms["limits"] = {k: [lo, hi] for k, (lo, hi) in limits.items()}
    descriptor.write_text(tomli_w.dumps(data), encoding="utf-8")


def write_library(
    suite: str | os.PathLike,
    out: str | os.PathLike,
    n_sites: int | None = None,
    progress: bool = True,
    buildings: list[str] | None = None,
) -> dict:
    """Copy calibrated sites of a suite into a library folder ``out`` and write its index.

    Args:
        suite: a suite folder (``buildenv suite make``) whose sites were calibrated (``buildenv suite calibrate``).
        out: the library folder; replaced when it holds an earlier library, refused when it holds anything else.
        n_sites: how many sites (:func:`choose`); default every calibrated one.
        buildings: only the sites of these buildings (the suite's names, e.g. ``medium_office``); default all.
            A context set of ``BuildingWeek-v0`` needs one action space: each copied site declares the limits
            the chosen sites share (:func:`common_limits`; the DOE 2004 offices' outdoor air from the ASHRAE 62.1
            minimum to the smallest design), rewriting its ``site.toml``.
        progress: a progress bar.
    Returns:
        ``{"library", "sites", "train", "test"}``.
    Raises:
        BuildenvError: no suite manifest, no calibrated site (of ``buildings``), ``out`` not a library, ``n_sites``
            below 1, chosen sites whose limits of a setting do not overlap.
        SiteError: a copied site that does not load (nothing is left behind).
    """
    from tqdm import tqdm

    from buildenv.sites.reader import load_site

    cases = calibrated_cases(suite)
    if buildings:
        unknown = sorted(set(buildings) - {c["building"] for c in cases})
        if unknown:
            known = ", ".join(sorted({c["building"] for c in cases}))
            raise BuildenvError(f"--buildings {','.join(unknown)}: no calibrated site of it in {suite} ({known})")
        cases = [c for c in cases if c["building"] in buildings]
    if not cases:
        raise BuildenvError(f"{suite}: no calibrated site; run buildenv suite calibrate --suite {suite} first")
    chosen = choose(cases, n_sites)
    limits = common_limits({c["name"]: load_site(c["folder"]).setting_limits for c in chosen})
    out = Path(out).expanduser()
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not is_library(out))):
        raise BuildenvError(f"{out}: exists and is not a site library; give a new or empty folder")
    partial = out.with_name(out.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    rows = []
    try:
        for case in tqdm(chosen, desc="library", unit="site", disable=not progress):
            folder = partial / case["name"]
            folder.mkdir()
            for name in LIBRARY_FILES:
                if (case["folder"] / name).is_file():
                    shutil.copy2(case["folder"] / name, folder / name)
            _write_limits(folder / DESCRIPTOR, limits)
            site = load_site(folder)  # it loads, calibrated, where it now lies
            calibration = site.calibration or {}
            verdict = calibration.get("verdict") or {}
            rows.append(
                {
                    "name": case["name"],
                    "building": case["building"],
                    "climate": case["climate"],
                    "season": case["season"],
                    "part": PARTS[case["part"]],
                    "guideline14": bool(verdict.get("passed", False)),
                    **({"metamodel_id": str(calibration["metamodel_id"])} if calibration.get("metamodel_id") else {}),
                }
            )
        (partial / LIBRARY_INDEX).write_text(_index(rows), encoding="utf-8")
        read_library(partial)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    partial.replace(out)
    parts = [r["part"] for r in rows]
    return {"library": str(out), "sites": len(rows), "train": parts.count("train"), "test": parts.count("test")}
