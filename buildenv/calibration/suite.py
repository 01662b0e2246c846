"""Calibrating every site of the suite with the unchanged calibration, one table of held-out figures.

Each made site of a suite folder (:mod:`buildenv.sites.suite`) is calibrated by
:func:`buildenv.calibration.calibrate.calibrate_site` with its defaults (first half fitted, second half held out) and
scored on its held-out weeks: CV(RMSE)_Q and NMBE_Q (ASHRAE Guideline 14), R2_T, RMSE_T, seconds and the parameters
left at a catalogue bound. A site that meters heat and electricity apart is scored on each meter (``_e`` keys: the
electricity) and on their sum (``_total`` keys, comparable with a one-meter suite); it meets Guideline 14 when both
meters do. :func:`summarise` gives the shares that meet Guideline 14 per part of the suite (development, held
out), reported apart.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from buildenv.calibration.problem import DAILY_WEIGHT
from buildenv.errors import BuildenvError
from buildenv.jsonio import dumps
from buildenv.metrics import GUIDELINE14_HOURLY_CV_PERCENT, GUIDELINE14_HOURLY_NMBE_PERCENT, guideline14
from buildenv.sites.suite import CASE_FIELDS, read_manifest

RESULTS = "calibration.json"
#: a tighter band than Guideline 14's, which a site calibrated well should meet: CV(RMSE)_Q and |NMBE_Q|, percent
TIGHT_CV_PERCENT, TIGHT_NMBE_PERCENT = 15.0, 5.0


def calibrate_case(
    record: dict,
    surrogate,
    seed: int = 0,
    max_evaluations: int = 6000,
    prior: bool = True,
    daily_weight: float = DAILY_WEIGHT,
) -> dict:
    """Calibrate one suite site (a :func:`buildenv.sites.suite.make_case` record; ``prior`` and ``daily_weight`` as
    :func:`buildenv.calibration.calibrate.calibrate_site`) and return its row."""
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.sites.reader import load_site

    site = load_site(record["site"])
    started = time.perf_counter()
    result = calibrate_site(
        site, surrogate, seed=seed, max_evaluations=max_evaluations, prior=prior, daily_weight=daily_weight
    )
    held = result["heldout"]
    cv, nmbe = held["cv_rmse_q_percent"], held["nmbe_q_percent"]
    meters = {}
    if "cv_rmse_e_percent" in held:
        meters = {k: round(held[k], 2) for k in ("cv_rmse_e_percent", "nmbe_e_percent")}
        meters |= _total_guideline14(site, surrogate, result)
    return {
        **{k: record[k] for k in CASE_FIELDS},
        "cv_rmse_q_percent": round(cv, 2),
        "nmbe_q_percent": round(nmbe, 2),
        **meters,
        "r2_t": round(held["r2_t"], 4),
        "r2_q": round(held["r2_q"], 4),
        "rmse_t_celsius": round(held["rmse_t_celsius"], 3),
        "guideline14": _every_meter_within(held, GUIDELINE14_HOURLY_CV_PERCENT, GUIDELINE14_HOURLY_NMBE_PERCENT),
        "at_bounds": len(result["at_bounds"]),
        "at_bound_names": [b["name"] for b in result["at_bounds"]],
        "seconds": round(time.perf_counter() - started, 1),
    }


def _total_guideline14(site, surrogate, result: dict) -> dict[str, float]:
    """Guideline 14 (``cv_rmse_total_percent``, ``nmbe_total_percent``) of the sum of a two-meter site's meters on
    its held-out weeks, at the calibrated parameters."""
    from buildenv.calibration.problem import build_problem, calibrated_parameters, predict_meters

    weeks = result["heldout_weeks"]
    effects = tuple(result.get("declared_effects", ()))
    problem = build_problem(
        site, weeks, effects, None, surrogate.context_hours, surrogate.uses_temperature_before, surrogate
    )
    _, q, e = predict_meters(problem, surrogate, calibrated_parameters(result, effects))
    cv, nmbe = guideline14(problem.consumption_wh_m2 + problem.electricity_wh_m2, q + e)
    return {"cv_rmse_total_percent": round(cv, 2), "nmbe_total_percent": round(nmbe, 2)}


def calibrate_suite(
    suite: str | Path,
    parts: Sequence[str] = ("development", "held_out"),
    checkpoint: str | None = None,
    seed: int = 0,
    max_evaluations: int = 6000,
    progress: bool = True,
    prior: bool = True,
    daily_weight: float = DAILY_WEIGHT,
) -> list[dict]:
    """Calibrate every made site of ``suite`` in ``parts`` (``prior`` and ``daily_weight``: as
    :func:`buildenv.calibration.calibrate.calibrate_site`); rows are also written to ``<suite>/calibration.json``.

    Raises:
        BuildenvError: the folder has no suite manifest or no made site in ``parts``.
    """
    from tqdm import tqdm

    from buildenv.metamodel.surrogate import load_metamodel

    records = [r for r in read_manifest(suite) if r["status"] in ("made", "reused") and r["part"] in parts]
    if not records:
        raise BuildenvError(f"{suite}: no made site in the parts {', '.join(parts)}; run buildenv suite make")
    surrogate = load_metamodel(checkpoint)
    rows = []
    for record in tqdm(records, desc="calibrate", unit="site", disable=not progress):
        rows.append(calibrate_case(record, surrogate, seed, max_evaluations, prior, daily_weight))
    path = Path(suite) / RESULTS
    text = dumps({"rows": rows, "summary": summarise(rows)}, where=str(path), nonfinite="null", indent=1)
    path.write_text(text + "\n", encoding="utf-8")
    return rows


def _every_meter_within(metrics: dict, cv_percent: float, nmbe_percent: float) -> bool:
    """Whether every meter of ``metrics`` (``_q``, and ``_e`` where there is a second) has CV(RMSE) and |NMBE| within
    the limits, percent."""
    return all(
        metrics[f"cv_rmse_{m}_percent"] <= cv_percent and abs(metrics[f"nmbe_{m}_percent"]) <= nmbe_percent
        for m in ("q", "e")
        if f"cv_rmse_{m}_percent" in metrics
    )


def _tight(row: dict) -> bool:
    """Every meter of the row within the tighter band."""
    return _every_meter_within(row, TIGHT_CV_PERCENT, TIGHT_NMBE_PERCENT)


def summarise(rows: Sequence[dict]) -> dict[str, dict]:
    """Per part (and ``all``): sites, shares meeting Guideline 14 hourly and the tighter band, R2_T >= 0.9,
    mean parameters at a bound, median seconds."""
    out = {}
    for part in ("development", "held_out", "all"):
        sel = [r for r in rows if part == "all" or r["part"] == part]
        if not sel:
            continue

        def share(test, sel=sel) -> float:
            return round(float(np.mean([test(r) for r in sel])), 3)

        out[part] = {
            "sites": len(sel),
            "guideline14_share": share(lambda r: r["guideline14"]),
            "tight_share": share(_tight),
            "r2_t_above_0_9_share": share(lambda r: r["r2_t"] >= 0.9),
            "mean_at_bounds": round(float(np.mean([r["at_bounds"] for r in sel])), 2),
            "median_seconds": round(float(np.median([r["seconds"] for r in sel])), 1),
        }
    return out
