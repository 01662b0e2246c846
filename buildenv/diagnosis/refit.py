"""The models a diagnosis compares: the base calibration, each candidate's refit and its control, the models
without a carried effect, and the days found absent.

A site that meters heat and electricity apart is calibrated on both meters; the diagnosis reads its consumption as
the meters summed (:func:`measured_consumption`), in its residuals, tests and metrics.

A :class:`ModelFit` is a calibrated model, possibly extended with effects (:mod:`buildenv.diagnosis.model_effects`);
a :class:`Context` holds what every model of one diagnosis shares (the site, the metamodel, the split, the settings
and the residual scales).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from buildenv import catalogue as cat
from buildenv.calibration import problem as cal
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import DERIVED_SIZES, DIAGNOSIS_SPLITS, EFFECTS, EffectError, get_effect
from buildenv.diagnosis.split import split_weeks
from buildenv.metamodel import surrogate as sg

# Share of a day's standardised squared error that modelling it absent must remove (:func:`detect_absent_days`).
ABSENCE_THRESHOLD = 0.15


@dataclass
class DiagnosisSettings:
    """Knobs of :func:`diagnose`. ``alpha`` is the one knob of the evidence; ``split`` says which weeks are held out,
    ``candidates`` and ``max_effects`` which effects can be named, the others how long the searches run. The blind
    checks and ``buildenv diagnose`` set ``split``, ``base_restarts`` and ``max_effects`` to
    :data:`.effects.CHECKED_DIAGNOSIS`.

    Attributes:
        candidates: effects tried (default: the whole catalogue).
        evaluations: CMA-ES cost evaluations per candidate refit.
        refit_step: CMA-ES initial step of the building parameters and occupancy in a refit (share of each range;
            the new effect's parameters start at a step of 1). Wide enough to take back what the base calibration
            absorbed of an effect, at the price of some drift of theta_build on few or mild fit weeks.
        effect_first_evaluations: CMA-ES evaluations of a refit's first stage, the new effect's parameters alone
            (at most half the budget; 0: joint refit only). Off by default: it mostly changes which path each
            CMA-ES run takes.
        refit_restarts: CMA-ES runs of every refit, control and candidates alike (seeds ``seed``, ``seed + 1``,
            ...), the lowest fit cost kept.
        refit_anchor: weight of a refit's pull towards the model it starts from: the squared move of each
            parameter the model already had, in units of its range, times this, is added to the fit cost (0: no
            pull; the new effect's parameters are never pulled).
        base_evaluations: CMA-ES cost evaluations of a calibration from scratch (:func:`from_scratch`).
        base_restarts: CMA-ES runs of a calibration from scratch, the lowest fit cost kept.
        alpha: family-wise significance level of a step (Bonferroni over its candidates,
            :mod:`buildenv.diagnosis.rules`).
        max_effects: most effects selected.
        seed: seed of every CMA-ES run.
        base_effects: effects the building is known to have: in the model from the start, not candidates.
        own_refit_baseline: judge each candidate also against its own refit with the effect taken out and keep
            the smaller gain (:func:`stricter_score`), so that better building parameters are not credited to it.
        split: fit and held-out weeks (:func:`split_weeks`): the first half reuses the site's calibration; every
            other week sees the whole season on both sides.
    """

    candidates: tuple[str, ...] = tuple(EFFECTS)
    evaluations: int = 1500
    refit_step: float = 0.25
    effect_first_evaluations: int = 0
    refit_restarts: int = 1
    refit_anchor: float = 0.0
    base_evaluations: int = 6000
    base_restarts: int = 1
    alpha: float = 0.05
    max_effects: int = 3
    seed: int = 0
    base_effects: tuple[str, ...] = ()
    own_refit_baseline: bool = True
    split: str = DIAGNOSIS_SPLITS[0]


@dataclass
class ModelFit:
    """A calibrated model, possibly extended with effects.

    Attributes:
        effects: effects in the model (``holidays`` included when absent days are modelled).
        params: physical parameters in problem order (theta, occupancy, then the non-holiday effects').
        absent: ``(site weeks, 7)`` absence fractions of the days (0: a normal day; see
            :func:`detect_absent_days`).
        cost: calibration cost on the fit weeks.
        evaluations: cost evaluations spent on it.
        carried: effects carried by a building parameter rather than by parameters of their own.
        pinned: building parameters held at a value (``{name: value}``, catalogue units) while calibrating.
    """

    effects: tuple[str, ...]
    params: np.ndarray
    absent: np.ndarray
    cost: float = float("nan")
    evaluations: int = 0
    carried: tuple[str, ...] = ()
    pinned: dict[str, float] = field(default_factory=dict)

    @property
    def model_effects(self) -> tuple[str, ...]:
        """Effects with calibrated parameters of their own (all but holidays and those carried by a building
        parameter)."""
        return tuple(e for e in self.effects if not get_effect(e).found_by_day and e not in self.carried)

    def effect_parameters(self) -> dict[str, dict[str, float]]:
        """``{effect: {parameter: value}}`` in physical units (holidays: the number of absent days)."""
        n_base = len(cal.parameter_names())
        values = em.split_parameters(self.model_effects, self.params[None, n_base:])
        out = {
            e: {p.name: round(float(v), 5) for p, v in zip(get_effect(e).parameters, values[e][0])}
            for e in self.model_effects
        }
        theta = dict(zip(cal.parameter_names(), self.params[:n_base].tolist()))
        for e in self.carried:
            effect = get_effect(e)
            out[e] = {effect.building_parameter: round(theta[effect.building_parameter], 5)}
            if effect.judged_on is not None:  # e.g. the night electricity both night shares add up to
                out[e][effect.judged_on] = round(DERIVED_SIZES[effect.judged_on][0](theta), 5)
        for e in self.effects:
            if get_effect(e).found_by_day:
                out[e] = {"absent_days": int((self.absent > 0).sum())}
        return out


@dataclass
class Context:
    site: object
    surrogate: sg.Surrogate
    fit_weeks: list[int]
    heldout: list[int]
    settings: DiagnosisSettings
    sigma: tuple[float, float] = (1.0, 1.0)  # base residual std on the fit weeks: temperature K, consumption Wh/m2
    scale: dict = field(default_factory=dict)


def problem_for(ctx: Context, fit: ModelFit, weeks: list[int], absent: np.ndarray | None = None) -> cal.Problem:
    mask = fit.absent if absent is None else absent
    problem = cal.build_problem(
        ctx.site,
        weeks,
        fit.model_effects,
        mask if mask.any() else None,
        ctx.surrogate.context_hours,
        ctx.surrogate.uses_temperature_before,
        ctx.surrogate,
    )
    for name, value in fit.pinned.items():
        j = problem.names.index(name)
        problem.lo[j] = problem.hi[j] = value
    return problem


def carried_by(ctx: Context, effect: str) -> str | None:
    """The building parameter that carries ``effect`` in this site's calibration
    (:attr:`buildenv.diagnosis.effects.Effect.building_parameter`), or None when the effect has none or the site
    declares it known (then the effect's own model-side addition is tried)."""
    name = get_effect(effect).building_parameter
    return name if name is not None and name not in ctx.site.theta_known() else None


def without_carried_effect(ctx: Context, current: ModelFit, effect: str) -> ModelFit:
    """``current`` with the building parameter that carries ``effect`` pinned at the end of its catalogue
    range where the effect vanishes (an unlimited heating power, no lighting at night), recalibrated like the
    control: the model a carried effect is judged against."""
    name = carried_by(ctx, effect)
    end = get_effect(effect).vanishing_value()
    params = current.params.copy()
    params[cal.parameter_names().index(name)] = end
    pinned = dataclasses.replace(current, params=params, pinned={**current.pinned, name: end})
    return refit(ctx, pinned, None)


def carried_trial(ctx: Context, current: ModelFit, control: ModelFit, effect: str) -> ModelFit:
    """The model a carried ``effect`` is tested with: of ``control`` (``current`` recalibrated, :func:`refit`)
    and ``current`` recalibrated from each of the effect's :attr:`buildenv.diagnosis.effects.Effect.carried_starts` (the
    building parameter that carries it set there, the rest as calibrated), the one with the lowest fit-week
    cost, marked as carrying the effect. The choice uses the fit weeks only."""
    best = control
    j = cal.parameter_names().index(carried_by(ctx, effect))
    for start in get_effect(effect).carried_starts:
        params = current.params.copy()
        params[j] = start
        fit = refit(ctx, dataclasses.replace(current, params=params), None)
        if fit.cost < best.cost:
            best = fit
    return dataclasses.replace(best, effects=(*best.effects, effect), carried=(*best.carried, effect))


def measured_consumption(site) -> np.ndarray:
    """The consumption a diagnosis reads, Wh/m2 in each hour ``(weeks, 168)``: the site's meters summed (NaN where
    one of them was not read)."""
    return sum(wh_m2 for _, wh_m2, _ in site.meters())


def _total(problem: cal.Problem, outputs: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The model's consumption over every meter of the problem's site: ``q`` plus the second meter's series."""
    e = cal.electricity_series(problem, outputs)
    return q if e is None else q + e


def predict(ctx: Context, fit: ModelFit, weeks: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Sensor temperature (degC) and consumption (Wh/m2, every meter summed) ``(weeks, 168)`` of a model on some
    site weeks."""
    problem = problem_for(ctx, fit, weeks)
    out, t, q = cal.simulate(problem, ctx.surrogate, fit.params[None])
    return t[0], _total(problem, out, q)[0]


def standardised_residuals(ctx: Context, weeks: list[int], t: np.ndarray, q: np.ndarray) -> dict[str, np.ndarray]:
    """``{series: (weeks, 168)}`` residuals (measured - model) divided by the base model's residual standard
    deviation on the fit weeks; NaN where nothing was measured."""
    return {
        "temperature": (ctx.site.temperature_c[weeks] - t) / ctx.sigma[0],
        "consumption": (measured_consumption(ctx.site)[weeks] - q) / ctx.sigma[1],
    }


def detect_absent_days(ctx: Context, fit: ModelFit, weeks: list[int]) -> np.ndarray:
    """``(len(weeks), 7)`` absence fractions: for each weekday, the share ``f`` of its occupancy that did not
    come, fitted by least squares to the day's measured temperature and consumption (standardised residuals,
    both series) from what the model predicts for the day with nobody in (:func:`buildenv.diagnosis.model_effects.
    absent_days_inputs`: the model as it is, and with each weekday absent in turn); a day is
    kept (``f > 0``) when ``f >= 0.5`` and its standardised squared error falls by more than
    :data:`ABSENCE_THRESHOLD`, else 0."""
    n_days = len(cat.WEEKDAYS)
    shape = (len(weeks), 7, cat.HOURS_PER_DAY)
    runs = []  # (temperature, consumption) of the model as it is, then with weekday d absent, each (weeks, 7, 24)
    for d in range(-1, n_days):
        absent = np.zeros((ctx.site.weeks, 7))
        if d >= 0:
            absent[:, d] = 1.0
        problem = problem_for(ctx, fit, weeks, absent)
        out, t, q = cal.simulate(problem, ctx.surrogate, fit.params[None])
        runs.append((t[0].reshape(shape), _total(problem, out, q)[0].reshape(shape)))
    measured = (ctx.site.temperature_c[weeks], measured_consumption(ctx.site)[weeks])
    terms = []  # per series: residual and an absent day's change, standardised, (weeks, weekdays, 24)
    for j, (y, sigma) in enumerate(zip(measured, ctx.sigma)):
        y = y.reshape(shape)[:, :n_days]
        base = runs[0][j][:, :n_days]
        change = np.stack([runs[1 + d][j][:, d] - base[:, d] for d in range(n_days)], axis=1)
        terms.append((np.nan_to_num((y - base) / sigma), np.where(np.isfinite(y), change / sigma, 0.0)))
    f = np.clip(
        sum((r * c).sum(-1) for r, c in terms) / np.maximum(sum((c**2).sum(-1) for _, c in terms), 1e-9), 0.0, 1.0
    )
    before = sum((r**2).sum(-1) for r, _ in terms)
    after = sum(((r - f[..., None] * c) ** 2).sum(-1) for r, c in terms)
    keep = (f >= 0.5) & (after < (1.0 - ABSENCE_THRESHOLD) * before)
    found = np.zeros((len(weeks), 7))
    found[:, :n_days] = np.where(keep, f, 0.0)
    return found


def refit(ctx: Context, current: ModelFit, effect: str | None) -> ModelFit:
    """``current`` extended with ``effect`` and recalibrated on the fit weeks (warm start); ``effect=None``
    recalibrates ``current`` alone with the same budget (the control each candidate is compared with, so
    that the extra calibration effort is not credited to the effect)."""
    effects = current.effects if effect is None else (*current.effects, effect)
    absent = current.absent.copy()
    if effect is None:
        new = np.zeros(0)
    elif get_effect(effect).found_by_day:
        absent[ctx.fit_weeks] = detect_absent_days(ctx, current, ctx.fit_weeks)
        new = np.zeros(0)
    else:
        new = em.none_parameters(effect)
    fit = dataclasses.replace(current, effects=effects, params=np.concatenate([current.params, new]), absent=absent)
    problem = problem_for(ctx, fit, ctx.fit_weeks)
    n_old = len(current.params)
    n_base = len(cal.parameter_names())
    start, budget, spent, new_step = fit.params, ctx.settings.evaluations, 0, 1.0
    first = min(ctx.settings.effect_first_evaluations, budget // 2)
    if first and len(new):
        start, info = cal.fit_last_parameters(problem, ctx.surrogate, fit.params, n_old, ctx.settings.seed, first)
        spent, new_step = info["evaluations"], 0.5
    stds = np.concatenate(
        [np.full(n_base, ctx.settings.refit_step), np.full(n_old - n_base, 0.5), np.full(len(new), new_step)]
    )
    anchored = np.arange(len(fit.params)) < n_old  # the new effect's parameters move freely
    params, info = cal.calibrate_cmaes(
        problem,
        ctx.surrogate,
        ctx.settings.seed,
        budget - spent,
        start=start,
        stds=stds,
        restarts=ctx.settings.refit_restarts,
        anchor=ctx.settings.refit_anchor,
        anchored=anchored,
    )
    return dataclasses.replace(fit, params=params, cost=info["cost"], evaluations=info["evaluations"] + spent)


def without_new_effect(current: ModelFit, trial: ModelFit) -> ModelFit:
    """``trial`` (``current`` extended with one effect and refitted) with that effect taken out again: the
    refitted building parameters and occupancy, the effects ``current`` had, and no newly flagged absent day."""
    return dataclasses.replace(
        trial, effects=current.effects, params=trial.params[: len(current.params)], absent=current.absent.copy()
    )


def base_fit(ctx: Context, progress: bool = False) -> ModelFit:
    """The base model: the site's calibration when made by least squares (no prior, whose pull would stand in for
    an effect) on the fit weeks with the declared effects, else a new one; then extended with the known
    ``base_effects`` one by one (:func:`refit`)."""
    calib = ctx.site.calibration or {}
    none = np.zeros((ctx.site.weeks, 7))
    declared = declared_effects(ctx.site)
    if (
        calib
        and calib.get("fit_weeks") == ctx.fit_weeks
        and set(calib.get("effects") or ()) == set(declared)
        and calib.get("catalogue_hash") in (cat.catalogue_hash(), *cat.EARLIER_CATALOGUES)  # read upgraded
        and cal.metamodel_mismatch(calib, ctx.surrogate) is None
        and not calib.get("prior")
    ):
        fit = ModelFit(declared, cal.calibrated_parameters(calib, declared), none, float(calib.get("cost", np.nan)), 0)
    else:
        fit = from_scratch(ctx, ModelFit((), np.zeros(0), none), progress)
    unanchored = dataclasses.replace(ctx, settings=dataclasses.replace(ctx.settings, refit_anchor=0.0))
    for effect in ctx.settings.base_effects:  # known effects: part of the calibration, searched unanchored
        if effect not in fit.effects:
            fit = refit(unanchored, fit, effect)
    return fit


def from_scratch(ctx: Context, model: ModelFit, progress: bool = False) -> ModelFit:
    """``model``'s structure (its effects, the effects it carries and its absent days) calibrated from scratch on
    the fit weeks (``base_evaluations`` per CMA-ES run, ``base_restarts`` runs, the lowest fit cost kept): its
    parameters are not used as a start."""
    problem = problem_for(ctx, dataclasses.replace(model, pinned={}), ctx.fit_weeks)
    params, info = cal.calibrate_cmaes(
        problem,
        ctx.surrogate,
        ctx.settings.seed,
        ctx.settings.base_evaluations,
        progress=progress,
        restarts=ctx.settings.base_restarts,
    )
    return dataclasses.replace(model, params=params, pinned={}, cost=info["cost"], evaluations=info["evaluations"])


def declared_effects(site) -> tuple[str, ...]:
    """The effects the site declares (``site.toml``'s ``effects``) and those its calibration was declared to
    have (``buildenv calibrate --effect``)."""
    saved = tuple((site.calibration or {}).get("declared_effects") or ())
    return tuple(site.effects) + tuple(e for e in saved if e not in site.effects)


def with_declared_effects(site, settings: DiagnosisSettings) -> DiagnosisSettings:
    """``settings`` with the site's declared effects (:func:`declared_effects`) among the base effects: the
    owner said the building has them, so they are in the model from the start and are not candidates."""
    extra = tuple(e for e in declared_effects(site) if e not in settings.base_effects)
    return dataclasses.replace(settings, base_effects=extra + settings.base_effects) if extra else settings


def with_heldout_absences(ctx: Context, fit: ModelFit) -> ModelFit:
    """The model with its held-out weeks' absent days detected (when it models holidays)."""
    if not any(get_effect(e).found_by_day for e in fit.effects) or not ctx.heldout:
        return fit
    absent = fit.absent.copy()
    absent[ctx.heldout] = detect_absent_days(ctx, fit, ctx.heldout)
    return dataclasses.replace(fit, absent=absent)


def metrics(ctx: Context, fit: ModelFit, weeks: list[int], t: np.ndarray, q: np.ndarray) -> dict:
    """:func:`buildenv.calibration.problem.score_series` of a model's temperature and consumption (every meter
    summed, as :func:`predict` gives it) on some site weeks."""
    problem = problem_for(ctx, fit, weeks)
    problem = dataclasses.replace(
        problem, consumption_wh_m2=measured_consumption(ctx.site)[weeks], electricity_wh_m2=None
    )
    out = cal.score_series(problem, t, q, fit.params, ctx.scale)
    return {k: (round(v, 5) if isinstance(v, float) else v) for k, v in out.items()}


def make_context(site, surrogate: sg.Surrogate, settings: DiagnosisSettings) -> Context:
    """The fit / held-out split of a site (:func:`split_weeks`) and its metric scales.

    Raises:
        buildenv.diagnosis.effects.EffectError: a base effect found day by day (holidays), which is always a
            candidate.
    """
    for name in settings.base_effects:
        if get_effect(name).found_by_day:
            raise EffectError(
                f"base effect {name!r}: its days are found from the data, so it is a candidate, not a base effect"
            )
    fit_weeks, heldout = split_weeks(site.weeks, settings.split)
    ctx = Context(site, surrogate, fit_weeks, heldout, settings)
    problem = cal.build_problem(site, fit_weeks)
    ctx.scale = cal._scale(dataclasses.replace(problem, consumption_wh_m2=measured_consumption(site)[fit_weeks]))
    return ctx


def residual_sigma(ctx: Context, fit: ModelFit) -> tuple[float, float]:
    """Standard deviations of a model's residuals on the fit weeks: temperature (K), consumption (Wh/m2); the
    units the diagnosis standardises every residual in (1 where a series has no spread or nothing measured)."""
    t, q = predict(ctx, fit, ctx.fit_weeks)
    out = []
    measured = measured_consumption(ctx.site)[ctx.fit_weeks]
    for residual in (ctx.site.temperature_c[ctx.fit_weeks] - t, measured - q):
        sd = float(np.nanstd(residual)) if np.isfinite(residual).any() else 0.0
        out.append(sd if sd > 0 else 1.0)
    return out[0], out[1]


def base_model_gap(site, surrogate: sg.Surrogate, settings: DiagnosisSettings | None = None) -> dict:
    """A site's base model (calibrated on its fit weeks, with the settings' ``base_effects`` and no other effect):
    ``{"heldout": metrics on the held-out weeks (:func:`buildenv.metrics.site_metrics`), "residual_sigma":
    [K, Wh/m2] (:func:`residual_sigma`)}``, as :func:`diagnose` reports them under ``heldout_base`` and
    ``residual_sigma``."""
    ctx = make_context(site, surrogate, with_declared_effects(site, settings or DiagnosisSettings()))
    fit = base_fit(ctx)
    t, q = predict(ctx, fit, ctx.heldout)
    return {"heldout": metrics(ctx, fit, ctx.heldout, t, q), "residual_sigma": list(residual_sigma(ctx, fit))}
