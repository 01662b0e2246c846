"""Each candidate of a diagnosis step refitted and scored on the held-out weeks (:mod:`buildenv.diagnosis.evidence`),
after checking that the site's weeks can show it at all (:mod:`buildenv.diagnosis.data_needs`)."""

from __future__ import annotations

from buildenv.calibration import problem as cal
from buildenv.diagnosis import data_needs, rules
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import EFFECTS, get_effect
from buildenv.diagnosis.evidence import Evidence, heldout_test
from buildenv.diagnosis.refit import (
    Context,
    ModelFit,
    carried_by,
    carried_trial,
    detect_absent_days,
    metrics,
    predict,
    problem_for,
    refit,
    standardised_residuals,
    with_heldout_absences,
    without_carried_effect,
    without_new_effect,
)
from buildenv.metamodel import surrogate as sg


def stricter_score(against_control: Evidence, against_own_refit: Evidence) -> tuple[Evidence, str]:
    """Of a candidate's two held-out tests (against the control, and against its own refit with the effect taken
    out, :func:`without_new_effect`), the one it gains least in and what it was measured against: better building
    parameters found on the way are not credited to the effect."""
    if against_own_refit.gain < against_control.gain:
        return against_own_refit, "own refit without the effect"
    return against_control, "control"


def heldout_score(ctx: Context, before: ModelFit, after: ModelFit, k: int) -> tuple[Evidence, dict, dict]:
    """The held-out test of ``after`` against ``before`` (:func:`buildenv.diagnosis.evidence.heldout_test`) and
    both models' held-out metrics (:func:`buildenv.metrics.site_metrics`); a model of holidays counts one parameter
    per held-out day it newly flags."""
    b, a = with_heldout_absences(ctx, before), with_heldout_absences(ctx, after)
    tb, qb = predict(ctx, b, ctx.heldout)
    ta, qa = predict(ctx, a, ctx.heldout)
    if after.effects and get_effect(after.effects[-1]).found_by_day:
        k = max(1, int((a.absent[ctx.heldout] > 0).sum() - (b.absent[ctx.heldout] > 0).sum()))
    evidence = heldout_test(
        standardised_residuals(ctx, ctx.heldout, tb, qb), standardised_residuals(ctx, ctx.heldout, ta, qa), k
    )
    return evidence, metrics(ctx, b, ctx.heldout, tb, qb), metrics(ctx, a, ctx.heldout, ta, qa)


def hours_showing(ctx: Context, fit: ModelFit) -> dict[str, tuple[int, int]]:
    """``{need: (fit-week hours, held-out hours)}`` in which each data need of the catalogue
    (:data:`buildenv.diagnosis.data_needs.NEEDS`) is met under a model ``fit`` (the base model)."""
    out = {}
    for side, weeks in enumerate((ctx.fit_weeks, ctx.heldout)):
        problem = problem_for(ctx, fit, weeks)
        x = cal.encode_candidates(problem, fit.params[None])
        outputs = cal.simulate(problem, ctx.surrogate, fit.params[None])[0][0]
        week_inputs = x[:, sg.context_of(x) :]
        for effect in EFFECTS.values():
            if effect.shows_in is not None:
                share = effect.magnitude_range[0] / 100.0
                mask = data_needs.hours_showing(effect.shows_in, outputs, week_inputs, share)
                out.setdefault(effect.shows_in, [0, 0])[side] = int(mask.sum())
    return {need: (fit_h, held_h) for need, (fit_h, held_h) in out.items()}


def days_lacking(ctx: Context, trial: ModelFit) -> str | None:
    """Why an effect found day by day (holidays) cannot be judged: days flagged in the held-out weeks, none in the
    fit weeks to estimate them from; None otherwise."""
    fit_days = int((trial.absent[ctx.fit_weeks] > 0).sum())
    held_days = int((detect_absent_days(ctx, trial, ctx.heldout) > 0).sum()) if ctx.heldout else 0
    if fit_days == 0 and held_days > 0:
        return f"{held_days} absent day(s) in the held-out weeks and none in the fit weeks to estimate them from"
    return None


def try_candidate(
    ctx: Context, current: ModelFit, control: ModelFit, name: str, lacking: str | None
) -> tuple[rules.Candidate, ModelFit | None, dict]:
    """One candidate of a step: ``current`` extended with effect ``name`` and recalibrated (a carried effect: the
    model carrying it against the model without it), scored on the held-out weeks; not tried when the site's
    weeks cannot show it (``lacking``). Returns the candidate, its model (None when not tried) and what the
    report adds (held-out metrics, fit costs, the model without a carried effect)."""
    if lacking is not None:
        return rules.Candidate(name, None, lacking=lacking), None, {}
    if carried_by(ctx, name):  # in the model already: judged against the model without it
        trial = carried_trial(ctx, current, control, name)
        without = without_carried_effect(ctx, current, name)
        evidence, before, after = heldout_score(ctx, without, trial, 1)
        baseline, costs = (
            "model without the carried effect",
            {"candidate": trial.cost, "model_without_it": without.cost},
        )
        extra = {"without": without}
    else:
        trial = refit(ctx, current, name)
        k = len(em.none_parameters(name))
        evidence, before, after = heldout_score(ctx, control, trial, k)
        baseline = "control"
        if ctx.settings.own_refit_baseline:
            own = heldout_score(ctx, without_new_effect(current, trial), trial, k)
            evidence, baseline = stricter_score(evidence, own[0])
            if baseline != "control":
                before, after = own[1], own[2]
        costs, extra = {"candidate": trial.cost, "control": control.cost}, {}
        if get_effect(name).found_by_day:
            lacking = days_lacking(ctx, trial)
    candidate = rules.Candidate(
        name, evidence, trial.effect_parameters().get(name, {}), baseline=baseline, lacking=lacking
    )
    costs = {key: round(float(value), 6) for key, value in costs.items()}
    return candidate, trial, {"heldout_before": before, "heldout_after": after, "fit_cost": costs, **extra}
