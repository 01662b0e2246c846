"""Running EnergyPlus through the ``pyenergyplus`` API shipped by ``pyenergyplus-lbnl``.

One call runs one model in the calling process with a fresh EnergyPlus state. EnergyPlus states are not
thread-safe and each run leaves a few MB behind in the process, so parallel campaigns run this in worker
processes that are recycled (see :mod:`buildenv.campaign.runs`).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import os
import re
from pathlib import Path

import numpy as np

from buildenv.errors import SimulationError

_SEVERE = re.compile(r"\*\*\s+(Severe|Fatal)\s+\*\*")
_ALL_LINES = 10_000
_TEMP_COMPARISON = re.compile(r"Temp Comparison\s*=\s*([0-9.Ee+-]+)")
#: day-to-day change of a zone temperature (K) up to which an unconverged warm-up is accepted (EnergyPlus's
#: largest temperature convergence tolerance), see :func:`warmup_settled`
WARMUP_TEMPERATURE_LIMIT_K = 0.5
log = logging.getLogger(__name__)


def energyplus_version() -> str:
    """Version string of the EnergyPlus library shipped with pyenergyplus-lbnl (e.g. ``25.2.0``)."""
    import pyenergyplus

    lib_dir = Path(pyenergyplus.__file__).resolve().parent.parent
    for lib in sorted(lib_dir.glob("libenergyplusapi.so.*")):
        return lib.name.split(".so.")[-1]
    return "unknown"


def severe_lines(err_path: Path, limit: int = 8, accepted: tuple[str, ...] = ()) -> list[str]:
    """The severe/fatal lines of an ``eplusout.err`` and their continuation lines (at most ``limit``), but for
    the reports whose first line holds one of ``accepted``."""
    if not err_path.is_file():
        return []
    out: list[str] = []
    keep = False
    for line in err_path.read_text(errors="replace").splitlines():
        if _SEVERE.search(line):
            keep = not any(text in line for text in accepted)
        elif not line.lstrip().startswith("**   ~~~   **"):
            keep = False
        if keep:
            out.append(line.strip())
        if len(out) >= limit:
            break
    return out


def warmup_settled(severe: list[str], limit_k: float = WARMUP_TEMPERATURE_LIMIT_K) -> bool:
    """Whether the severe errors of a run (:func:`severe_lines`) are only warm-up non-convergence of a thermal
    state that did settle: every zone's loads, and its temperatures within :data:`WARMUP_TEMPERATURE_LIMIT_K`.

    EnergyPlus warms a run up by repeating its first day until each zone's temperatures and loads change
    less than a tolerance from one day to the next, and reports a zone that did not within the maximum number
    of warm-up days as Severe, then simulates the run period anyway. Two such reports leave a sound run:

    - only the loads comparison failed (a zone whose small cooling load keeps changing by a few % a day), so
      the temperatures the run starts from have converged;
    - a temperature comparison failed by less than ``limit_k`` (0.5 K, the largest temperature tolerance
      EnergyPlus accepts, ``Building``): a thermostat whose setpoints lie 0.5 K apart can switch between heating
      and cooling on alternate warm-up days. A run whose first simulated week is discarded (a reference run's
      warm-up week) starts its measured weeks from that week's state, so any settled warm-up will do there
      (``limit_k=inf``).

    A larger day-to-day temperature change, or any other severe error, still fails the run.
    """
    headers = [line for line in severe if _SEVERE.search(line)]
    if not headers or not all("Severe" in h and "CheckWarmupConvergence" in h for h in headers):
        return False
    failed = [_TEMP_COMPARISON.search(line) for line in severe if "Temp Comparison" in line and "Fail" in line]
    return all(m is not None and float(m.group(1)) <= limit_k for m in failed)


def run_energyplus(
    model: dict | Path,
    epw: Path,
    workdir: Path,
    label: str = "model",
    warmup_limit_k: float = WARMUP_TEMPERATURE_LIMIT_K,
    accepted_severe: tuple[str, ...] = (),
) -> Path:
    """Run one EnergyPlus simulation and return the output directory.

    Args:
        model: an epJSON dict (written to ``workdir/<label>.epJSON``) or the path of an IDF/epJSON file.
        epw: weather file.
        workdir: directory for the model and EnergyPlus outputs (created).
        label: file stem of the written model, used in error messages.
        warmup_limit_k: the day-to-day temperature change a warm-up may end with (:func:`warmup_settled`).
        accepted_severe: severe reports the model is known to raise in a sound run (:func:`severe_lines`).
    Raises:
        SimulationError: EnergyPlus returned non-zero or reported a severe error (quoting ``eplusout.err``);
            a warm-up that settled without meeting every tolerance (:func:`warmup_settled`) only logs a warning.
    """
    from pyenergyplus.api import EnergyPlusAPI

    workdir.mkdir(parents=True, exist_ok=True)
    if isinstance(model, dict):
        model_path = workdir / f"{label}.epJSON"
        model_path.write_text(json.dumps(model))
    else:
        model_path = Path(model).resolve()
    api = EnergyPlusAPI()
    state = api.state_manager.new_state()
    try:
        api.runtime.set_console_output_status(state, False)
        code = api.runtime.run_energyplus(state, ["-w", str(epw), "-d", str(workdir), str(model_path)])
    finally:
        api.state_manager.delete_state(state)
    err = workdir / "eplusout.err"
    severe = severe_lines(err, limit=_ALL_LINES, accepted=accepted_severe)
    if code == 0 and warmup_settled(severe, warmup_limit_k):
        log.warning("%s: warm-up did not fully converge (accepted): %s", model_path, " | ".join(severe[:8]))
        severe = []
    if code != 0 or severe:
        detail = " | ".join(severe[:8]) if severe else f"exit code {code}, see {err}"
        raise SimulationError(f"EnergyPlus failed on {model_path}: {detail}")
    return workdir


def read_hourly_csv(csv_path: Path, columns: dict[str, tuple[str, str]]) -> dict[str, np.ndarray]:
    """Read hourly EnergyPlus CSV output into ``{output name: (hours,) array}`` in the file's units.

    Args:
        csv_path: ``eplusout.csv``.
        columns: ``{output name: (key value, report variable name)}``; keys match case-insensitively.
    """
    import pandas as pd

    frame = pd.read_csv(csv_path)
    headers = {h.upper(): h for h in frame.columns}
    out: dict[str, np.ndarray] = {}
    for name, (key, variable) in columns.items():
        wanted = f"{key}:{variable}".upper()
        match = [orig for upper, orig in headers.items() if upper.startswith(wanted + " [")]
        if not match:
            raise SimulationError(f"{csv_path}: no column for {key}:{variable} (is the Output:Variable present?)")
        out[name] = frame[match[0]].to_numpy(dtype=float)
    return out


def run_period_rows(frame, first_day: dt.date, hours: int, csv: Path):
    """The rows of ``frame`` (an ``eplusout.csv``) stamped with the run period's ``hours`` hours from ``first_day``.

    Models with "Do HVAC Sizing Simulation for Sizing Periods" (the DOE large office: coincident plant
    sizing) also report their design days. EnergyPlus's CSV keys rows by their ``MM/DD  HH:MM:SS`` stamp:
    the design days' rows come on top of the run's, and on a date the run shares with a design day the
    run period (simulated last) has overwritten them. A run past Dec 31 is listed January first; the rows come
    back in the run's order.

    Raises:
        SimulationError: the frame lacks some of those hours (or the run holds a calendar day twice).
    """
    day0 = dt.datetime(first_day.year, first_day.month, first_day.day)
    expected = [(day0 + dt.timedelta(hours=h)).strftime("%m/%d") + f"  {h % 24 + 1:02d}:00:00" for h in range(hours)]
    stamps = frame["Date/Time"].astype(str).str.strip()
    row_of = {stamp: i for i, stamp in enumerate(stamps)}  # a run across a new year is listed January first
    found = [row_of[e] for e in expected if e in row_of]
    if len(found) != hours or len(set(expected)) != hours:
        raise SimulationError(
            f"{csv}: {len(found)} hourly rows stamped {first_day} and after ({len(frame)} "
            f"in all), expected {hours} consecutive hours"
        )
    return frame.iloc[found].reset_index(drop=True)


def clean_outputs(workdir: Path, keep: tuple[str, ...] = ("eplusout.err",)) -> None:
    """Delete EnergyPlus output files of a finished run except ``keep``."""
    for path in workdir.iterdir():
        if path.is_file() and path.name not in keep:
            os.unlink(path)
