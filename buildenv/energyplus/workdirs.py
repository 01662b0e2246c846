"""Temporary folders of EnergyPlus runs, named after the process that made them, and the sweep of those left behind.

A run started without a folder of its own works in ``buildenv-<kind>-<pid>-XXXXXXXX`` in the system's temporary
folder (kinds: :data:`KINDS`), removed when it ends. A process killed mid-run (SIGKILL, a power cut, a stopped
Dask worker) cannot remove its folder: the first folder a later process makes removes those whose process is gone
(:func:`remove_stale_run_folders`; this user's only, never one of a process still running).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

#: What runs in each kind of folder: a campaign's runs, one shoebox run, a shoebox run over a site's weeks
#: (calibration, the response check), a reference building's run and its outdoor-air sizing run.
KINDS = ("campaign", "eplus", "calib", "ref", "oa")
_FOLDER = re.compile(r"buildenv-(?:" + "|".join(KINDS) + r")-(\d+)-[a-z0-9_]{8}")  # mkdtemp: 8 random characters
_swept = False


def prefix(kind: str) -> str:
    """The name a folder of ``kind`` (one of :data:`KINDS`) made by this process starts with.

    Raises:
        ValueError: an unknown kind.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown run folder kind {kind!r}; choose from {', '.join(KINDS)}")
    return f"buildenv-{kind}-{os.getpid()}-"


def make_folder(kind: str) -> Path:
    """A new folder of ``kind`` in the system's temporary folder (the caller removes it); the first one a process
    makes sweeps the folders killed processes left."""
    _sweep_once()
    return Path(tempfile.mkdtemp(prefix=prefix(kind)))


def temporary_folder(kind: str) -> tempfile.TemporaryDirectory:
    """:func:`make_folder` as a context manager that removes the folder on leaving it."""
    _sweep_once()
    return tempfile.TemporaryDirectory(prefix=prefix(kind))


def _sweep_once() -> None:
    global _swept
    if not _swept:
        _swept = True
        remove_stale_run_folders()


def _process_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (POSIX; another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_run_folders(root: str | Path | None = None) -> list[Path]:
    """Remove the run folders killed processes left in ``root`` (default: the system's temporary folder): only this
    toolkit's (``buildenv-<kind>-<pid>-*``), only this user's, and only those whose process is gone, so that runs
    beside this one keep theirs. Does nothing where processes cannot be looked up (not POSIX). Returns the folders
    removed."""
    if os.name != "posix":
        return []
    root = Path(tempfile.gettempdir() if root is None else root)
    try:
        entries = list(os.scandir(root))
    except OSError:
        return []
    removed = []
    for entry in entries:
        match = _FOLDER.fullmatch(entry.name)
        try:
            if not match or not entry.is_dir(follow_symlinks=False):
                continue
            if entry.stat(follow_symlinks=False).st_uid != os.getuid():
                continue
            pid = int(match.group(1))
            if pid == os.getpid() or _process_alive(pid):
                continue
        except (OSError, OverflowError):
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        removed.append(Path(entry.path))
    return removed
