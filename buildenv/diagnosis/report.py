"""What a diagnosis reports: each candidate as JSON, the verdict in one sentence, the localisation of the base
model's residuals, and the extended model saved as the site's model."""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.calibration import problem as cal
from buildenv.calibration.verdict import calibration_verdict
from buildenv.diagnosis import rules
from buildenv.diagnosis.effects import get_effect
from buildenv.diagnosis.refit import Context, ModelFit, measured_consumption, predict, problem_for

#: Keys of ``calibration.json`` that describe the calibrated model's fit, kept only under ``without_effects`` once the
#: extended model is saved (:func:`save_extended_model`).
MODEL_FIGURES = (
    "cost",
    "fit",
    "at_bounds",
    "evaluations",
    "run_costs",
    "cost_without_effects",
    "seconds",
    "guideline14_p",
    "verdict",
)


def candidate_entry(c: rules.Candidate, extra: dict) -> dict:
    """A candidate as the diagnosis reports it (JSON-ready)."""
    return {
        "name": c.name,
        "title": get_effect(c.name).title,
        "status": c.status,
        "score": round(c.gain, 4),
        "p_value": c.evidence.p_value if c.evidence is not None else None,
        "threshold": c.threshold,
        "evidence": dataclasses.asdict(c.evidence) if c.evidence is not None else None,
        "parameters": c.parameters,
        "baseline": c.baseline,
        "lacking": c.lacking,
        "failed": c.failed,
        "qualifies": c.qualifies,
        **{k: v for k, v in extra.items() if k != "without"},
    }


def verdict(result: dict) -> str:
    """The diagnosis in one sentence a building engineer reads: the effects named with their estimates and held-out
    gains; else that none of the effects the site's weeks can show improves the held-out weeks (with the best
    candidate and why it was not named); and the effects there is not enough data to tell about."""
    named = [e for step in result["steps"] for e in step["candidates"] if e["status"] == rules.NAMED]
    lacking = result["not_enough_data"]
    short = (
        "; not enough data to tell for " + "; ".join(f"{name} ({why})" for name, why in lacking.items())
        if lacking
        else ""
    )
    if named:
        return (
            "unmodelled effect(s) found: "
            + ", ".join(
                f"{e['name']} ({e['title']}; {get_effect(e['name']).estimate_text(e['parameters'])}; held-out gain "
                f"{100 * e['score']:.1f} %, p = {e['p_value']:.2g})"
                for e in named
            )
            + short
        )
    judged = [e for e in result["effects"] if e["status"] != rules.NOT_ENOUGH_DATA]
    best = judged[0] if judged else None
    why = (
        f" (best candidate: {best['name']}, held-out gain {100 * best['score']:.1f} %: "
        + "; ".join(why for rule, why in best["failed"].items())
        + ")"
        if best
        else ""
    )
    return f"no unmodelled effect found among the {len(judged)} effects these weeks can show{why}{short}"


def absent_dates(site, fit: ModelFit) -> list[str]:
    return [(site.start + dt.timedelta(days=7 * int(w) + int(d))).isoformat() for w, d in zip(*np.nonzero(fit.absent))]


def localise_site(ctx: Context, fit: ModelFit, plot: str | Path | None = None) -> dict:
    """Residual localisation (:func:`buildenv.diagnosis.localise.localise`) of a model over all the site's weeks,
    plotted into ``plot`` (a PNG path) when given."""
    from buildenv.diagnosis.localise import localise, plot_localisation
    from buildenv.schedules import hourly_schedules

    weeks = list(range(ctx.site.weeks))
    t, q = predict(ctx, fit, weeks)
    problem = problem_for(ctx, fit, weeks)
    occupied = cal.problem_occupancy(problem, fit.params)
    _, occ = cal._split(problem, fit.params[None])
    heating = hourly_schedules(ctx.site.settings, np.broadcast_to(occ[0], (ctx.site.weeks, *occ.shape[1:])))
    occupied = np.asarray(occupied)
    result = localise(
        ctx.site.temperature_c,
        measured_consumption(ctx.site),
        t,
        q,
        ctx.site.weather_hours(),
        occupied,
        heating["heating_comfort_on"] > 0,
        ctx.site.week_starts(),
    )
    if plot is not None:
        result["plot"] = str(
            plot_localisation(result, plot, ctx.site.temperature_c, measured_consumption(ctx.site), t, q, occupied)
        )
    return result


def save_extended_model(site, result: dict) -> Path | None:
    """Make the diagnosis' extended model the site's model: ``calibration.json`` gains the selected effects.

    The theta and occupancy refitted with the effects replace the calibrated ones, ``effects`` holds
    ``{effect: {parameter: value}}`` and ``absent_days`` the dates modelled unoccupied; the previous calibration
    is kept under ``without_effects`` (with its fit-week figures, :data:`MODEL_FIGURES`); ``cost``, ``at_bounds``,
    ``heldout`` and the Guideline 14 ``verdict`` are the extended model's. Nothing is written when no effect was
    selected (returns None).
    """
    from buildenv.sites import save_calibration

    fit: ModelFit = result["_fit"]
    if not result["selected"]:
        return None
    previous = dict(site.calibration or {})
    previous.pop("without_effects", None)
    # what described the model without the effects stays under "without_effects" only
    kept = {k: v for k, v in previous.items() if k not in MODEL_FIGURES}
    theta, occ = cal._split(cal.build_problem(site, result["fit_weeks"][:1], fit.model_effects), fit.params[None])
    extended = {
        **kept,
        "method": "cmaes+effects",
        "cost": float(fit.cost),
        "at_bounds": result["model"].get("at_bounds", []),
        "theta": dict(zip(cat.THETA_NAMES, np.round(theta[0], 5).tolist())),
        "occupancy": np.round(occ[0], 3).tolist(),
        # an effect carried by a building parameter is in "theta" (and named in "diagnosis")
        "effects": {e: v for e, v in fit.effect_parameters().items() if e not in fit.carried},
        "absent_days": result["model"]["absent_days"],
        "fit_weeks": result["fit_weeks"],
        "heldout_weeks": result["heldout_weeks"],
        "diagnosis": {"selected": result["selected"], "verdict": result["verdict"]},
        "catalogue_hash": cat.catalogue_hash(),
        "metamodel": result.get("metamodel"),
        "metamodel_id": result.get("metamodel_id"),
        "without_effects": previous,
    }
    if "heldout_after" in result:  # a site with two meters: each meter's figures (the diagnosis read their sum)
        extended["heldout"] = result.get("heldout_meters", result["heldout_after"])
    extended["verdict"] = calibration_verdict(extended)
    return save_calibration(site.path, extended)
