"""Sim-to-real gap diagnosis: which unmodelled effect makes the calibrated model miss, and what adding it buys.

Forward selection, as in grey-box modelling: add the extension with the best significant held-out gain, stop when
none qualifies.

1. **split** (:mod:`.split`): the site's weeks into fit and held-out weeks;
2. **refit** (:mod:`.refit`): the base model (theta_build, occupancy, the declared base effects) calibrated on the
   fit weeks, then each candidate of :mod:`.effects` added to it (:mod:`.model_effects`) and recalibrated, against
   the control (the current model recalibrated with the same budget); an effect carried by a building parameter
   against the model with it pinned where the effect vanishes; absent days detected;
3. **score** (:mod:`.score`, :mod:`.evidence`): each candidate the site's weeks can show (:mod:`.data_needs`) on
   the held-out weeks only;
4. **select** (:mod:`.rules`): the qualifying candidate with the best gain joins the model and step 2 repeats, until
   none qualifies or ``max_effects`` are in;
5. **report** (:mod:`.report`): the verdict, every candidate's evidence and status, the held-out metrics before and
   after, the localisation (:mod:`.localise`); :func:`.report.save_extended_model` makes the extended model the
   site's model.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from buildenv.calibration import problem as cal
from buildenv.diagnosis import data_needs, rules
from buildenv.diagnosis.effects import get_effect
from buildenv.diagnosis.refit import (
    Context,
    DiagnosisSettings,
    ModelFit,
    base_fit,
    make_context,
    metrics,
    predict,
    refit,
    residual_sigma,
    with_declared_effects,
    without_carried_effect,
)
from buildenv.diagnosis.report import absent_dates, candidate_entry, localise_site, save_extended_model, verdict
from buildenv.diagnosis.score import heldout_score, hours_showing, try_candidate
from buildenv.diagnosis.split import split_weather, split_weeks
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.threads import one_blas_thread

#: what callers of the diagnosis use, from the stages that define them
__all__ = ["DiagnosisSettings", "diagnose", "save_extended_model", "split_weeks", "verdict"]


@one_blas_thread()  # buildenv.metamodel.threads: numpy's BLAS threads would fight the metamodel's
def diagnose(
    site,
    surrogate: sg.Surrogate,
    settings: DiagnosisSettings | None = None,
    localisation: bool = True,
    progress: bool = False,
    plot: str | Path | None = None,
    strict_calibration: bool = False,
) -> dict:
    """Diagnose the gap between a site's measurements and its calibrated metamodel.

    Args:
        site: a :class:`buildenv.sites.Site` with at least 2 weeks.
        surrogate: the metamodel.
        settings: :class:`DiagnosisSettings`.
        localisation: include the residual localisation (:mod:`buildenv.diagnosis.localise`).
        progress: progress bar over the candidates.
        plot: PNG path of the localisation heatmaps (none if ``None``).
        strict_calibration: refuse a site whose calibration fails ASHRAE Guideline 14 (by default a warning).
    Returns:
        ``{"site", "verdict", "answer", "selected", "not_enough_data", "effects", "steps", "model", "fit_weeks",
        "heldout_weeks", "base_effects", "heldout_base", "residual_sigma", "base_at_bounds", "hours_showing",
        "split_weather", "settings", "seconds", "_fit"}`` (``_fit`` the extended model, not for JSON), with
        ``"localisation"`` when asked for: ``answer`` is ``named`` or ``none``, ``not_enough_data`` the effects the
        weeks cannot tell about (``{effect: why}``, the third answer, per effect); ``effects``
        the first step's candidates, best held-out gain first (:func:`candidate_entry`), ``steps`` every step's;
        ``heldout_before``/``heldout_after``, when an effect is selected, the held-out metrics without and with the
        selected effects (a site with two meters: on their sum, and ``heldout_meters`` the extended model's per
        meter, :func:`buildenv.calibration.problem.score_weeks`); ``model["at_bounds"]`` the extended model's
        parameters at a bound.
    Raises:
        buildenv.diagnosis.effects.EffectError: an unknown candidate or base effect, or holidays as a base effect.
        buildenv.calibration.problem.CalibrationError: the site has fewer than 2 weeks.
        buildenv.calibration.verdict.CalibrationFailed: its calibration fails Guideline 14 and ``strict_calibration``.
    """
    from tqdm import tqdm

    settings = with_declared_effects(site, settings or DiagnosisSettings())
    for name in (*settings.candidates, *settings.base_effects):
        get_effect(name)
    started = time.perf_counter()
    if site.weeks < 2:
        raise cal.CalibrationError(f"{site.path}: the diagnosis needs at least 2 weeks (fit + held-out)")
    if site.calibration:
        from buildenv.calibration.verdict import check_calibration

        check_calibration(site.calibration, str(site.path), strict_calibration)
    ctx = make_context(site, surrogate, settings)
    current = base_fit(ctx, progress)
    ctx.sigma = residual_sigma(ctx, current)
    showing = hours_showing(ctx, current)
    base = current
    steps: list[dict] = []
    remaining = [e for e in settings.candidates if e not in settings.base_effects]
    without_base: dict[str, ModelFit] = {}  # the base model without a carried effect (first step)
    bar = tqdm(total=len(remaining), desc="effects", disable=not progress, leave=False)
    while remaining and len(current.effects) - len(base.effects) < settings.max_effects:
        control = refit(ctx, current, None)
        tried = []
        for name in remaining:
            need = get_effect(name).shows_in
            lacking = data_needs.lacking(need, *showing[need]) if need else None
            tried.append(try_candidate(ctx, current, control, name, lacking))
            bar.update(1)
        candidates = [c for c, _, _ in tried]
        judged = sum(c.lacking is None for c in candidates)
        for c in candidates:
            c.threshold = settings.alpha / judged if c.lacking is None else None
        rules.judge(candidates)
        chosen = rules.select(candidates)
        by_name = {c.name: (trial, extra) for c, trial, extra in tried}
        if chosen is not None:
            chosen.status = rules.NAMED
        steps.append(
            {
                "model": list(current.effects),
                "candidates": [candidate_entry(c, by_name[c.name][1]) for c in candidates],
            }
        )
        if current is base:
            without_base = {n: extra["without"] for n, (_, extra) in by_name.items() if "without" in extra}
        if chosen is None:
            break
        current = by_name[chosen.name][0]
        remaining.remove(chosen.name)
        bar.reset(total=len(remaining))
    bar.close()
    selected = [e for e in current.effects if e not in base.effects]
    first_step = steps[0]["candidates"] if steps else []
    lacking_data = {e["name"]: e["lacking"] for e in first_step if e["status"] == rules.NOT_ENOUGH_DATA}
    result = {
        "site": str(site.path),
        **cal.metamodel_record(surrogate),
        "fit_weeks": ctx.fit_weeks,
        "heldout_weeks": ctx.heldout,
        "base_effects": list(settings.base_effects),
        "answer": rules.NAMED if selected else "none",
        "selected": selected,
        "not_enough_data": lacking_data,
        "effects": first_step,
        "steps": steps,
        "hours_showing": {need: list(hours) for need, hours in showing.items()},
        "heldout_base": metrics(ctx, base, ctx.heldout, *predict(ctx, base, ctx.heldout)),
        "residual_sigma": list(ctx.sigma),
        "base_at_bounds": _at_bounds(ctx, base),
        "split_weather": split_weather(site, settings.split),
        "model": {
            "effects": current.effect_parameters(),
            "absent_days": absent_dates(site, current),
            "parameters": current.params.tolist(),
            "at_bounds": _at_bounds(ctx, current),
        },
        "settings": dataclasses.asdict(settings),
    }
    result["verdict"] = verdict(result)
    if selected:
        before = base  # the whole gain of the diagnosis, against the base model without any selected effect
        for name in selected:
            if name in current.carried:
                before = (
                    without_base[name]
                    if before is base and name in without_base
                    else without_carried_effect(ctx, before, name)
                )
        _, result["heldout_before"], result["heldout_after"] = heldout_score(ctx, before, current, 1)
        if ctx.site.electricity_kwh is not None:  # the saved model is judged meter by meter, as calibration judges it
            scale = cal._scale(cal.build_problem(ctx.site, ctx.fit_weeks))
            result["heldout_meters"] = cal.score_weeks(
                ctx.site, ctx.surrogate, ctx.heldout, current.params, scale, current.model_effects, current.absent
            )
    if localisation:
        result["localisation"] = localise_site(ctx, base, plot)
    result["seconds"] = round(time.perf_counter() - started, 1)
    result["_fit"] = current  # the extended model (dropped from JSON output)
    return result


def _at_bounds(ctx: Context, fit: ModelFit) -> list[dict]:
    """The free building parameters of a model at a bound of their catalogue range
    (:func:`buildenv.calibration.problem.parameters_at_bounds`)."""
    free = cal.free_theta()
    return cal.parameters_at_bounds(dict(zip(free, fit.params[: len(free)].tolist())), ctx.site.known, ctx.surrogate)
