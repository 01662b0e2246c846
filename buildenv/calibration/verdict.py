"""Whether a calibration may be used: ASHRAE Guideline 14 on its fit and held-out weeks, in one line.

:func:`calibration_verdict` judges a calibration result (``calibration.json``) hourly (CV(RMSE) <= 30 %, |NMBE| <=
10 %) and monthly (the bias of the monthly totals within 5 %; CV(RMSE) of monthly totals <= 15 % once there are
:data:`buildenv.metrics.MONTHLY_CV_MIN_MONTHS` months); a calibration passes when its held-out weeks (its fit weeks
where none were held out) pass both. :func:`check_calibration` is what the environment, the optimisers and the
diagnosis call before they use a site: one warning per site, or :class:`CalibrationFailed` when asked to be strict.
"""

from __future__ import annotations

import logging
import math

from buildenv.errors import BuildenvError
from buildenv.metrics import (
    GUIDELINE14_HOURLY_CV_PERCENT,
    GUIDELINE14_HOURLY_NMBE_PERCENT,
    GUIDELINE14_MONTHLY_CV_PERCENT,
    GUIDELINE14_MONTHLY_NMBE_PERCENT,
)

log = logging.getLogger(__name__)
_warned: set[str] = set()


class CalibrationFailed(BuildenvError):
    """A site's calibration fails ASHRAE Guideline 14 and the caller asked for a passing one."""


def _within(value: float | None, limit: float) -> bool | None:
    """``|value| <= limit``, or ``None`` where there is no value."""
    if value is None or not math.isfinite(value):
        return None
    return abs(value) <= limit


def _judge(metrics: dict) -> dict:
    """Hourly and monthly pass/fail of one set of weeks' metrics (``score_weeks``'s keys); a site with a second meter
    (``_e`` keys) passes where both meters do."""
    meters = ["q", "e"] if "cv_rmse_e_percent" in metrics else ["q"]
    hourly = [
        _within(metrics.get(f"{key}_{m}_percent"), limit)
        for m in meters
        for key, limit in (("cv_rmse", GUIDELINE14_HOURLY_CV_PERCENT), ("nmbe", GUIDELINE14_HOURLY_NMBE_PERCENT))
    ]
    monthly = [
        _within(metrics.get(f"{key}_{m}_monthly_percent"), limit)
        for m in meters
        for key, limit in (("cv_rmse", GUIDELINE14_MONTHLY_CV_PERCENT), ("nmbe", GUIDELINE14_MONTHLY_NMBE_PERCENT))
    ]
    judged = [m for m in monthly if m is not None]
    # weeks without a measured consumption have no hourly figures: not judged, rather than failed
    return {"hourly": None if None in hourly else all(hourly), "monthly": all(judged) if judged else None}


def calibration_verdict(result: dict) -> dict:
    """The Guideline 14 verdict of a calibration result (``calibration.json``).

    Returns:
        ``{"fit": {"hourly", "monthly"}, "heldout": {...} or None, "judged_on": "heldout" | "fit", "passed",
        "at_bounds", "line"}``; ``monthly`` is ``None`` where the result has no monthly figures (a calibration
        saved before they were scored), and is then not held against it; ``hourly`` is ``None`` on weeks with no
        measured consumption, and the verdict is then judged on the fit weeks.
    """
    fit = _judge(result.get("fit") or {})
    heldout = _judge(result["heldout"]) if result.get("heldout") else None
    judged_on = "heldout" if heldout and heldout["hourly"] is not None else "fit"
    judged = heldout if judged_on == "heldout" else fit
    passed = judged["hourly"] is True and judged["monthly"] is not False
    verdict = {
        "fit": fit,
        "heldout": heldout,
        "judged_on": judged_on,
        "passed": bool(passed),
        "at_bounds": len(result.get("at_bounds") or []),
    }
    verdict["line"] = verdict_line(result, verdict)
    return verdict


def _part(name: str, metrics: dict, judged: dict) -> str:
    """``held-out weeks: hourly pass (CV(RMSE) 10.7 %, NMBE 2.0 %), monthly pass (NMBE 1.9 %)``; a second meter's
    figures follow the consumption's after ``electricity``."""
    word = {True: "pass", False: "FAIL", None: "not judged"}
    meters = [("q", "")] + ([("e", "electricity ")] if "cv_rmse_e_percent" in metrics else [])
    hourly, monthly = [], []
    for m, label in meters:
        hourly.append(
            f"{label}CV(RMSE) {metrics.get(f'cv_rmse_{m}_percent', float('nan')):.1f} %, "
            f"NMBE {metrics.get(f'nmbe_{m}_percent', float('nan')):.1f} %"
        )
        monthly_cv = metrics.get(f"cv_rmse_{m}_monthly_percent")
        cv = f"CV(RMSE) {monthly_cv:.1f} %, " if monthly_cv is not None and math.isfinite(monthly_cv) else ""
        if metrics.get(f"nmbe_{m}_monthly_percent") is not None:
            monthly.append(f"{label}{cv}NMBE {metrics[f'nmbe_{m}_monthly_percent']:.1f} %")
    text = f"monthly {word[judged['monthly']]}"
    if monthly:
        text += f" ({'; '.join(monthly)} of {metrics.get('months', '?')} month(s))"
    return f"{name}: hourly {word[judged['hourly']]} ({'; '.join(hourly)}), {text}"


def verdict_line(result: dict, verdict: dict) -> str:
    """One line a building engineer reads: pass or fail, on which weeks, and the parameters at a bound."""
    parts = [_part("held-out weeks", result["heldout"], verdict["heldout"])] if verdict["heldout"] else []
    parts.append(_part("fit weeks", result.get("fit") or {}, verdict["fit"]))
    head = "PASSES" if verdict["passed"] else "FAILS"
    return f"Guideline 14: {head} ({'; '.join(parts)}); {verdict['at_bounds']} parameter(s) at a bound of their range"


def check_calibration(calibration: dict, where: str, strict: bool = False) -> dict:
    """Warn once per ``where`` (a site folder) when ``calibration`` fails Guideline 14 (:func:`calibration_verdict`);
    returns the verdict.

    Raises:
        CalibrationFailed: it fails and ``strict``.
    """
    verdict = calibration_verdict(calibration)
    if not verdict["passed"]:
        message = f"site {where}: calibration {verdict['line']}"
        if strict:
            raise CalibrationFailed(f"{message}; recalibrate it or check its data before using it")
        if where not in _warned:
            _warned.add(where)
            log.warning("%s; what is predicted for this site may be far off", message)
    return verdict
