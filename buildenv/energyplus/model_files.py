"""A user's building model file as the shipped engine reads it: an epJSON converted to IDF, and an IDF written
for another EnergyPlus version refused with what to do (the engine ships no version transition programs)."""

from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import tempfile
from pathlib import Path

from buildenv.energyplus.idf import of_type, read_idf
from buildenv.energyplus.runner import energyplus_version
from buildenv.errors import ReferenceBuildingError


def idf_version(path: Path) -> tuple[int, int] | None:
    """The ``major, minor`` EnergyPlus version an IDF declares in its ``Version`` object; ``None`` without one."""
    for obj in of_type(read_idf(path), "Version"):
        found = re.match(r"\s*([0-9]+)\.([0-9]+)", obj[1]) if len(obj) > 1 else None
        if found:
            return int(found.group(1)), int(found.group(2))
    return None


def check_version(path: Path) -> None:
    """Refuse an IDF written for another EnergyPlus version than the shipped engine's.

    Raises:
        ReferenceBuildingError: one line naming the file, both versions and how to upgrade it.
    """
    declared = idf_version(path)
    engine = energyplus_version()
    ours = tuple(int(part) for part in engine.split(".")[:2]) if engine[:1].isdigit() else None
    if declared is not None and ours is not None and declared != ours:
        raise ReferenceBuildingError(
            f"{path}: written for EnergyPlus {declared[0]}.{declared[1]}, the shipped engine is {engine}: upgrade "
            f"it to {ours[0]}.{ours[1]} with EnergyPlus's IDFVersionUpdater (its transition programs are not "
            "shipped with pyenergyplus) and pass the upgraded file"
        )


def epjson_as_idf(path: Path) -> Path:
    """The IDF of an epJSON model, converted by the shipped engine (``--convert-only``) into a folder of the
    system's temporary directory named after the file's contents, so a model is converted once.

    Raises:
        ReferenceBuildingError: the engine could not convert it (one line naming the file and its error log).
    """
    from pyenergyplus.api import EnergyPlusAPI

    data = Path(path).read_bytes()
    folder = Path(tempfile.gettempdir()) / f"buildenv-epjson-{hashlib.sha256(data).hexdigest()[:16]}"
    idf = folder / f"{Path(path).stem}.idf"
    if idf.is_file():
        return idf
    folder.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f"{folder.name}-", dir=folder.parent))  # parallel conversions do not meet
    source = work / f"{Path(path).stem}.epJSON"
    source.write_bytes(data)
    api = EnergyPlusAPI()
    state = api.state_manager.new_state()
    try:
        api.runtime.set_console_output_status(state, False)
        code = api.runtime.run_energyplus(state, ["--convert-only", "-d", str(work), str(source)])
    finally:
        api.state_manager.delete_state(state)
    if code != 0 or not (work / idf.name).is_file():
        raise ReferenceBuildingError(
            f"{path}: EnergyPlus could not convert this epJSON to IDF (see {work / 'eplusout.err'})"
        )
    try:
        os.replace(work, folder)
    except OSError:  # another process converted it first
        shutil.rmtree(work, ignore_errors=True)
    return idf


def user_model(path: Path) -> Path:
    """The IDF to read for a user's model file: an epJSON converted (:func:`epjson_as_idf`), the version checked
    (:func:`check_version`); once per file and modification time."""
    path = Path(path).resolve()
    return _user_model(path, path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=32)
def _user_model(path: Path, mtime_ns: int) -> Path:
    if path.suffix.lower() == ".epjson":
        path = epjson_as_idf(path)
    check_version(path)
    return path
