"""Sim-to-real gap diagnosis: which unmodelled effect makes the calibrated model miss, and what adding it buys.

Forward selection, as in grey-box modelling: add the extension with the most significant gain, stop when none is.

1. The site's weeks are split into fit and held-out weeks (:func:`split_weeks`); the base model (theta_build,
   occupancy, the declared base effects) is calibrated on the fit weeks (:func:`base_fit`).
2. Each candidate of :mod:`buildenv.diagnosis.effects` is added to the model (:mod:`buildenv.diagnosis.model_effects`)
   and recalibrated on the fit weeks, warm-started (:func:`refit`); the control is the current model recalibrated
   with the same budget. An effect carried by a building parameter is judged against the model with it pinned
   where the effect vanishes (:func:`without_carried_effect`); absent days are detected (:func:`detect_absent_days`).
3. Each candidate is judged on the held-out weeks (:func:`heldout_score`): residuals of both series standardised
   by the base model's fit-week residual standard deviations, gain ``1 - SSE_after / SSE_before`` (the smaller of
   those against the control and against its own refit without the effect), F-test with the number of values
   corrected for lag-1 autocorrelation, Bonferroni over the step's candidates. It qualifies
   (:func:`candidate_qualifies`) when significant, plausible and beyond every clean site's estimate (its
   clean-site ceiling) or, for an effect without a ceiling, gaining at least ``min_gain``.
4. First step: loads left on at night are selected first when the night electricity the model carries is far
   beyond every clean site's (:func:`night_load_named_first`). When nothing qualifies, candidates the base
   calibration may have absorbed are tested by joint calibration (:func:`joint_fallback`), and if the first step
   still selects nothing, one beyond every clean site's estimate is named by it alone (:func:`named_by_estimate`).
5. The best qualifying candidate joins the model and step 2 repeats, until none qualifies or ``max_effects`` are in.

:func:`diagnose` returns the selected effects, their parameters and the held-out metrics before and after;
:func:`save_extended_model` makes the extended model the site's model (``calibration.json`` gains ``effects``).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import stats

from buildenv import catalogue as cat
from buildenv.calibration import problem as cal
from buildenv.diagnosis import model_effects as em
from buildenv.diagnosis.effects import (
    CHECKED_DIAGNOSIS,
    DERIVED_SIZES,
    DIAGNOSIS_SPLITS,
    EFFECTS,
    ESTIMATE_ALONE_LOWEST_GAIN,
    JUDGES,
    MIN_GAIN,
    NIGHT_LOAD_FIRST_BEYOND,
    EffectError,
    ceilings_in_sunshine,
    declared_ceilings,
    get_effect,
)
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.threads import one_blas_thread

log = logging.getLogger(__name__)

# Share of a day's standardised squared error that modelling it absent must remove (:func:`detect_absent_days`).
ABSENCE_THRESHOLD = 0.15
HOLIDAYS = "holidays"
NIGHT_LOADS = "night_plug_loads"
SENSOR_BIAS = "temperature_sensor_bias"
SERIES = ("temperature", "consumption")
# Share (%) of held-out hours colder than every fit hour above which the diagnosis says so (:func:`split_weather`).
COLDER_HELDOUT_NOTE_PERCENT = 20.0


def split_weeks(n_weeks: int, split: str = DIAGNOSIS_SPLITS[0]) -> tuple[list[int], list[int]]:
    """Fit and held-out weeks of a site of ``n_weeks`` weeks: ``"first_half"`` fits the first half (rounded up,
    :func:`buildenv.calibration.problem.default_weeks`) and holds out the rest; ``"alternate"`` fits weeks 0, 2, 4, ...
    and holds out 1, 3, 5, ..., so both see the season's whole range of weather (an autumn site's first half
    is milder than its second, and an effect that only shows in the cold, such as an undersized heating plant,
    cannot be estimated from mild fit weeks)."""
    if split == "first_half":
        return cal.default_weeks(n_weeks)
    if split == "alternate":
        return list(range(0, n_weeks, 2)), list(range(1, n_weeks, 2))
    raise ValueError(f"unknown split {split!r}; choose {' or '.join(DIAGNOSIS_SPLITS)}")


def split_weather(site, split: str = DIAGNOSIS_SPLITS[0]) -> dict:
    """The outdoor temperature (degC) the fit and the held-out weeks of ``site`` saw under ``split``
    (:func:`split_weeks`): ``{"fit": {"mean_c", "min_c"}, "heldout": {...}, "heldout_colder_than_fit_percent",
    "note"}``.

    ``heldout_colder_than_fit_percent`` is the share of held-out hours colder than every fit hour. Over
    :data:`COLDER_HELDOUT_NOTE_PERCENT`, ``note`` says so (else None): an effect that only shows in the cold (a
    heating plant short of power) cannot be estimated from the fit weeks."""
    tamb = site.weather_hours()[:, :, cat.WEATHER_NAMES.index("TAMB")]

    def colder_percent(fit: list[int], heldout: list[int]) -> float:
        return round(100.0 * float((tamb[heldout] < tamb[fit].min()).mean()), 1)

    fit_weeks, heldout_weeks = split_weeks(site.weeks, split)
    sides = {
        name: {"mean_c": round(float(tamb[weeks].mean()), 2), "min_c": round(float(tamb[weeks].min()), 2)}
        for name, weeks in (("fit", fit_weeks), ("heldout", heldout_weeks))
    }
    colder = colder_percent(fit_weeks, heldout_weeks)
    note = None
    if colder > COLDER_HELDOUT_NOTE_PERCENT:
        note = (
            f"{colder:.0f} % of the held-out hours are colder than every fit hour: an effect that only shows "
            "in the cold cannot be estimated from the fit weeks"
        )
        if split != "alternate" and colder_percent(*split_weeks(site.weeks, "alternate")) < colder:
            note += " (--split alternate fits every other week)"
    return {**sides, "heldout_colder_than_fit_percent": colder, "note": note}


@dataclass
class DiagnosisSettings:
    """Knobs of :func:`diagnose`. The blind checks and ``buildenv diagnose`` set ``split``, ``base_restarts`` and
    ``max_effects`` to :data:`.effects.CHECKED_DIAGNOSIS`; the other defaults are theirs too.

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
        base_evaluations: CMA-ES cost evaluations of a calibration from scratch (:func:`joint_fit`).
        base_restarts: CMA-ES runs of a calibration from scratch, the lowest fit cost kept.
        alpha: family-wise significance level of a step (Bonferroni over its candidates).
        min_gain: smallest held-out gain (share of the standardised squared error removed) to select an effect
            that has no clean-site ceiling, or every effect when ``clean_ceilings`` is off.
        clean_ceilings: name an effect that has a clean-site ceiling when it is significant and its estimate is
            beyond the ceiling, at any held-out gain (:func:`site_ceilings`), since a calibrated candidate absorbs
            structural misses on clean sites too; False: every effect by ``min_gain``.
        joint_fallback: when no candidate of a step qualifies, test those whose refit estimate is beyond their
            ceiling by calibrating from scratch without and with them (:func:`joint_fallback`), since the base
            calibration may have absorbed the effect into the building parameters.
        estimate_alone: when the first step selects nothing, name a candidate whose estimate is beyond every clean
            site's by that estimate alone (:func:`named_by_estimate`; not added to the model). Off on sites that
            declare building parameters known and when ``clean_ceilings`` is off.
        night_load_first: in the first step, select loads left on at night ahead of the held-out gains when the
            night electricity the model carries is far beyond every clean site's and the sensor bias refits cold
            (:func:`night_load_named_first`); off where ``estimate_alone`` is.
        max_effects: most effects selected.
        seed: seed of every CMA-ES run.
        base_effects: effects the building is known to have: in the model from the start, not candidates.
        judge: ``"pooled"``: each candidate is scored on both series; ``"effect_series"``: on the series it
            shows in (:attr:`buildenv.diagnosis.effects.Effect.series`).
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
    min_gain: float = MIN_GAIN
    clean_ceilings: bool = True
    joint_fallback: bool = True
    estimate_alone: bool = True
    night_load_first: bool = True
    max_effects: int = 3
    seed: int = 0
    base_effects: tuple[str, ...] = ()
    judge: str = "pooled"
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
        return tuple(e for e in self.effects if e != HOLIDAYS and e not in self.carried)

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
        if HOLIDAYS in self.effects:
            out[HOLIDAYS] = {"absent_days": int((self.absent > 0).sum())}
        return out


def settings_note(settings: DiagnosisSettings) -> str:
    """One line saying which of the settings that change what a diagnosis names differ from the blind checks'
    (:data:`.effects.CHECKED_DIAGNOSIS`), for which the clean-site ceilings were measured; empty if none."""
    differ = [
        f"{k} {getattr(settings, k)} (checks: {v})" for k, v in CHECKED_DIAGNOSIS.items() if getattr(settings, k) != v
    ]
    if not differ:
        return ""
    return (
        "settings other than the blind checks', for which the clean-site ceilings and the checks' figures were "
        "measured: " + ", ".join(differ)
    )


@dataclass
class _Context:
    site: object
    surrogate: sg.Surrogate
    fit_weeks: list[int]
    heldout: list[int]
    settings: DiagnosisSettings
    sigma: tuple[float, float] = (1.0, 1.0)  # base residual std on the fit weeks: temperature K, consumption Wh/m2
    scale: dict = field(default_factory=dict)
    irradiance: float | None = None  # the fit weeks' mean global horizontal irradiance, W/m2 (fit_irradiance_w_m2)

    @property
    def declared(self) -> bool:
        """Whether the candidates are judged by the ceilings of sites declaring building parameters known."""
        return judged_as_declared(self.site, self.settings.clean_ceilings)

    @property
    def ceilings(self) -> bool | Mapping[str, float]:
        """The clean-site ceilings this site's candidates are judged by (:func:`site_ceilings`)."""
        return site_ceilings(self.site, self.settings.clean_ceilings, self.irradiance)

    @property
    def catalogue(self) -> bool:
        """Whether the candidates are judged by the catalogue's ceilings (neither turned off nor those of sites
        declaring building parameters known): the estimate-alone and night-electricity rules apply only then."""
        return self.settings.clean_ceilings is True and not self.declared

    @property
    def estimate_ceilings(self) -> bool | Mapping[str, float]:
        """The estimate ceilings this site's first step is judged by (:func:`named_by_estimate`): the catalogue's
        at its fit-week irradiance (:func:`buildenv.diagnosis.effects.ceilings_in_sunshine`), or False where
        :attr:`catalogue` is not."""
        return ceilings_in_sunshine(self.irradiance, "estimate") if self.catalogue else False

    def effect(self, name: str):
        """The catalogue's effect ``name`` as this site's candidates are judged (its ceilings at the site's
        fit-week irradiance, :meth:`buildenv.diagnosis.effects.Effect.in_sunshine`)."""
        return get_effect(name).in_sunshine(self.irradiance)


def _problem(ctx: _Context, fit: ModelFit, weeks: list[int], absent: np.ndarray | None = None) -> cal.Problem:
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


def carried_by(ctx: _Context, effect: str) -> str | None:
    """The building parameter that carries ``effect`` in this site's calibration
    (:attr:`buildenv.diagnosis.effects.Effect.building_parameter`), or None when the effect has none or the site
    declares it known (then the effect's own model-side addition is tried)."""
    name = get_effect(effect).building_parameter
    return name if name is not None and name not in ctx.site.theta_known() else None


def without_carried_effect(ctx: _Context, current: ModelFit, effect: str) -> ModelFit:
    """``current`` with the building parameter that carries ``effect`` pinned at the end of its catalogue
    range where the effect vanishes (an unlimited heating power, no lighting at night), recalibrated like the
    control: the model a carried effect is judged against."""
    name = carried_by(ctx, effect)
    end = get_effect(effect).vanishing_value()
    params = current.params.copy()
    params[cal.parameter_names().index(name)] = end
    pinned = dataclasses.replace(current, params=params, pinned={**current.pinned, name: end})
    return refit(ctx, pinned, None)


def carried_trial(ctx: _Context, current: ModelFit, control: ModelFit, effect: str) -> ModelFit:
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


def predict(ctx: _Context, fit: ModelFit, weeks: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Sensor temperature (degC) and consumption (Wh/m2) ``(weeks, 168)`` of a model on some site weeks."""
    return cal.predict(_problem(ctx, fit, weeks), ctx.surrogate, fit.params)


def _standardised_residuals(ctx: _Context, weeks: list[int], t: np.ndarray, q: np.ndarray) -> dict[str, np.ndarray]:
    """``{series: (weeks, 168)}`` residuals (measured - model) divided by the base model's residual standard
    deviation on the fit weeks; NaN where nothing was measured."""
    return {
        "temperature": (ctx.site.temperature_c[weeks] - t) / ctx.sigma[0],
        "consumption": (ctx.site.consumption_wh_m2()[weeks] - q) / ctx.sigma[1],
    }


def detect_absent_days(ctx: _Context, fit: ModelFit, weeks: list[int]) -> np.ndarray:
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
        _, t, q = cal.simulate(_problem(ctx, fit, weeks, absent), ctx.surrogate, fit.params[None])
        runs.append((t[0].reshape(shape), q[0].reshape(shape)))
    measured = (ctx.site.temperature_c[weeks], ctx.site.consumption_wh_m2()[weeks])
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


def refit(ctx: _Context, current: ModelFit, effect: str | None) -> ModelFit:
    """``current`` extended with ``effect`` and recalibrated on the fit weeks (warm start); ``effect=None``
    recalibrates ``current`` alone with the same budget (the control each candidate is compared with, so
    that the extra calibration effort is not credited to the effect)."""
    effects = current.effects if effect is None else (*current.effects, effect)
    absent = current.absent.copy()
    if effect is None:
        new = np.zeros(0)
    elif effect == HOLIDAYS:
        absent[ctx.fit_weeks] = detect_absent_days(ctx, current, ctx.fit_weeks)
        new = np.zeros(0)
    else:
        new = em.none_parameters(effect)
    fit = dataclasses.replace(current, effects=effects, params=np.concatenate([current.params, new]), absent=absent)
    problem = _problem(ctx, fit, ctx.fit_weeks)
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


def stricter_score(against_control: dict, against_own_refit: dict) -> dict:
    """Of a candidate's two held-out tests, the one it gains least in (module docstring, step 3: the control
    and the candidate's own refit without its effect, :func:`without_new_effect`); both gains are recorded."""
    worse = against_own_refit if against_own_refit["gain"] < against_control["gain"] else against_control
    return worse | {
        "baseline": "own refit without the effect" if worse is against_own_refit else "control",
        "gain_vs_control": round(against_control["gain"], 4),
        "gain_vs_own_refit": round(against_own_refit["gain"], 4),
    }


def base_fit(ctx: _Context, progress: bool = False) -> ModelFit:
    """The base model: the site's calibration when made by least squares (no prior: the ceilings were measured on
    such fits) on the fit weeks with the declared effects, else a new one; then extended with the known
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
        fit = joint_fit(ctx, (), progress)
    unanchored = dataclasses.replace(ctx, settings=dataclasses.replace(ctx.settings, refit_anchor=0.0))
    for effect in ctx.settings.base_effects:  # known effects: part of the calibration, searched unanchored
        if effect not in fit.effects:
            fit = refit(unanchored, fit, effect)
    return fit


def joint_fit(ctx: _Context, effects: tuple[str, ...], progress: bool = False) -> ModelFit:
    """A calibration from scratch on the fit weeks with ``effects`` in the model from the start: the building
    parameters, the occupancy and the effects' parameters searched together (``base_evaluations`` per CMA-ES run,
    ``base_restarts`` runs, the lowest fit cost kept), where :func:`base_fit` calibrates the building first and
    refits with each effect after (its plain calibration is this with no effect). ``holidays`` is not calibrated
    this way (its days are detected, not fitted)."""
    if HOLIDAYS in effects:
        raise ValueError("holidays are detected day by day, not calibrated jointly")
    return from_scratch(ctx, ModelFit(tuple(effects), np.zeros(0), np.zeros((ctx.site.weeks, 7))), progress)


def from_scratch(ctx: _Context, model: ModelFit, progress: bool = False) -> ModelFit:
    """``model``'s structure (its effects, the effects it carries and its absent days) calibrated from scratch on
    the fit weeks, as :func:`joint_fit` calibrates: its parameters are not used as a start."""
    problem = _problem(ctx, dataclasses.replace(model, pinned={}), ctx.fit_weeks)
    params, info = cal.calibrate_cmaes(
        problem,
        ctx.surrogate,
        ctx.settings.seed,
        ctx.settings.base_evaluations,
        progress=progress,
        restarts=ctx.settings.base_restarts,
    )
    return dataclasses.replace(model, params=params, pinned={}, cost=info["cost"], evaluations=info["evaluations"])


def joint_calibration_tests(
    site, surrogate: sg.Surrogate, candidates: tuple[str, ...], settings: DiagnosisSettings | None = None
) -> list[dict]:
    """Held-out tests of ``candidates`` by joint calibration (:func:`joint_fit`): the site calibrated from
    scratch with the settings' base effects (and its declared ones), then once more for each candidate with it
    added; each judged against the first like a diagnosis candidate (:func:`heldout_score`, residuals
    standardised by the first model's fit-week residuals). Calibrated from scratch with the effect, the building
    parameters need not absorb it (wind-driven infiltration into a higher air change rate), as they may in a
    refit started from the base model. ``buildenv diagnose --joint-test NAME`` runs it after the diagnosis.

    Returns:
        one ``{"candidate", "gain", "gain_by_series", "p_value", "estimate", "cost_without", "cost_with",
        "heldout_without", "heldout_with"}`` per candidate (fit costs on the fit weeks, held-out metrics of both
        models).
    """
    settings = with_declared_effects(site, settings or DiagnosisSettings())
    check_joint_candidates(candidates, settings)
    ctx = _context(site, surrogate, settings)
    without = joint_fit(ctx, settings.base_effects)
    return [joint_test(ctx, without, name)[1] for name in candidates]


def joint_test(ctx: _Context, without: ModelFit, name: str) -> tuple[ModelFit, dict]:
    """One joint-calibration test (:func:`joint_calibration_tests`): ``without`` (a model calibrated from scratch
    by :func:`joint_fit`) calibrated from scratch once more with ``name`` added, judged against it on the held-out
    weeks with residuals standardised by ``without``'s fit-week residuals.

    Returns:
        the model with the candidate, and ``{"candidate", "gain", "gain_by_series", "p_value", "estimate",
        "cost_without", "cost_with", "heldout_without", "heldout_with"}``.
    """
    own = dataclasses.replace(ctx, sigma=residual_sigma(ctx, without))
    with_candidate = from_scratch(own, dataclasses.replace(without, effects=(*without.effects, name)))
    score = heldout_score(own, without, with_candidate, len(em.none_parameters(name)))
    return with_candidate, {
        "candidate": name,
        "gain": round(score["gain"], 4),
        "gain_by_series": score["gain_by_series"],
        "p_value": score["p_value"],
        "estimate": with_candidate.effect_parameters()[name],
        "cost_without": without.cost,
        "cost_with": with_candidate.cost,
        "heldout_without": score["metrics_before"],
        "heldout_with": score["metrics_after"],
    }


def joint_fallback(
    ctx: _Context, current: ModelFit, entries: list[dict], threshold: float
) -> tuple[str, ModelFit] | None:
    """A step's candidates that the base calibration may have absorbed (:func:`absorbed_candidate`, best refit
    gain first; ``entries`` are the step's, none qualified) tested by joint calibration (:func:`joint_test`)
    against ``current`` calibrated from scratch; the first whose test qualifies (:func:`joint_test_qualifies`)
    is returned with its model, else None. Each tested entry gets ``joint_test`` (the test, and ``qualifies``)."""
    without = None
    for entry in entries:
        name = entry["name"]
        if not absorbed_candidate(name, entry["parameters"], ctx.ceilings):
            continue
        if without is None:
            without = from_scratch(ctx, current)
        model, test = joint_test(ctx, without, name)
        entry["joint_test"] = test | {"qualifies": joint_test_qualifies(name, test, threshold, ctx.ceilings)}
        if entry["joint_test"]["qualifies"]:
            return name, model
    return None


def absorbed_candidate(
    name: str, parameters: dict[str, float], clean_ceilings: bool | Mapping[str, float] = True
) -> bool:
    """Whether a candidate that did not qualify is tested again by joint calibration (:func:`joint_test`): its
    refit estimate ``parameters`` is plausible and beyond every clean site's (:func:`beyond_clean_sites`), so the
    base calibration may have absorbed the effect into the building parameters (a wind infiltration into a higher
    air change rate). Not holidays (detected, not calibrated) nor an effect carried by a building parameter."""
    effect = get_effect(name)
    return (
        name != HOLIDAYS
        and effect.building_parameter not in parameters
        and effect.plausible(parameters)
        and beyond_clean_sites(name, parameters, clean_ceilings) is True
    )


def joint_test_qualifies(
    name: str, test: dict, threshold: float, clean_ceilings: bool | Mapping[str, float] = True
) -> bool:
    """Whether a joint test (:func:`joint_test`'s dict) names its candidate: a positive held-out gain,
    significant at the step's ``threshold``, with a plausible estimate that stays beyond its clean-site ceiling
    (``clean_ceilings`` as :func:`beyond_clean_sites`; an effect with no ceiling is judged by the gain alone).
    An estimate that falls back among the clean sites' has lost the evidence of size the test was run for
    (:func:`absorbed_candidate`), and its gain is then what one more free parameter buys."""
    return (
        test["gain"] > 0.0
        and test["p_value"] < threshold
        and get_effect(name).plausible(test["estimate"])
        and beyond_clean_sites(name, test["estimate"], clean_ceilings) is not False
    )


def named_by_estimate(
    estimates: Mapping[str, dict[str, float]],
    gains: Mapping[str, float],
    estimate_ceilings: bool | Mapping[str, float] = True,
    gains_by_series: Mapping[str, Mapping[str, float]] | None = None,
) -> list[str]:
    """The candidate a first step that selected nothing names by its estimate alone
    (``DiagnosisSettings.estimate_alone``), as a list of at most one name: of the candidates whose estimate
    (``{name: parameters}``, the first step's refits) is plausible and beyond every clean site's
    (:meth:`.effects.Effect.beyond_estimate_ceiling`), the one furthest beyond, relative to that ceiling.
    Not holidays (detected, not calibrated), nor one whose held-out gain (``{name: gain}``, the step's scores) is
    below :data:`.effects.ESTIMATE_ALONE_LOWEST_GAIN` where that guard is set (None: none), nor a sensor
    effect that makes its reading worse held out (:func:`sensor_reading_made_worse`, given ``gains_by_series``,
    ``{name: {series: gain}}``). ``estimate_ceilings``: the catalogue's (True), a mapping used instead (an effect
    missing from it has none), or none (False). Empty when no candidate is beyond."""
    if estimate_ceilings is False:
        return []
    beyond = []
    for name, parameters in estimates.items():
        effect = get_effect(name)
        if isinstance(estimate_ceilings, Mapping):
            effect = dataclasses.replace(effect, estimate_ceiling=estimate_ceilings.get(name))
        if (
            name == HOLIDAYS
            or not effect.beyond_estimate_ceiling(parameters)
            or not plausible_alone(name, parameters, estimates)
            or held_back_from_estimate(name, gains[name], (gains_by_series or {}).get(name, {}))
        ):
            continue
        ceiling = effect.estimate_ceiling
        size = parameters.get(effect.ceiling_on, 0.0)
        beyond.append((abs(abs(size) - abs(ceiling)) / abs(ceiling) if ceiling else float("inf"), name))
    return [max(beyond)[1]] if beyond else []


def plausible_alone(name: str, parameters: Mapping[str, float], estimates: Mapping[str, dict[str, float]]) -> bool:
    """Whether a first-step candidate's refit ``parameters`` describe an effect :func:`named_by_estimate` may name
    by its estimate alone (``estimates``: every candidate's refit, ``{name: parameters}``): plausible
    (:meth:`.effects.Effect.plausible`), or night plug loads whose night electricity the estimate ceiling
    judges (``night_electricity_w_m2``, both night shares) while the lights' night share stays under its floor, with
    the temperature sensor bias candidate refit at 0 K or colder. The lights' share floor serves the held-out
    test, which pins that share; the estimate alone judges the night electricity both shares add up to."""
    effect = get_effect(name)
    if effect.plausible(dict(parameters)):
        return True
    bias = estimates.get(SENSOR_BIAS, {}).get("bias_k")
    return name == NIGHT_LOADS and effect.judged_on in parameters and bias is not None and bias <= 0.0


def night_load_named_first(
    estimates: Mapping[str, dict[str, float]], estimate_ceilings: bool | Mapping[str, float] = True
) -> bool:
    """Whether a first step names loads left on at night ahead of every held-out gain
    (``DiagnosisSettings.night_load_first``): the night electricity its model carries (the night_plug_loads
    candidate's estimate ``night_electricity_w_m2``, W/m2) is beyond :data:`.effects.NIGHT_LOAD_FIRST_BEYOND`
    times that effect's estimate ceiling, and the temperature sensor bias candidate refits cold or at zero
    (``bias_k`` <= 0 K), since a calibration also adds electricity at night for a sensor reading warm; False
    without the bias candidate's estimate. ``estimate_ceilings``: as :func:`named_by_estimate`."""
    beyond = NIGHT_LOAD_FIRST_BEYOND
    if (
        beyond is None
        or estimate_ceilings is False
        or NIGHT_LOADS not in estimates
        or "bias_k" not in estimates.get(SENSOR_BIAS, {})
    ):
        return False
    effect = get_effect(NIGHT_LOADS)
    ceiling = estimate_ceilings.get(NIGHT_LOADS) if isinstance(estimate_ceilings, Mapping) else effect.estimate_ceiling
    size = estimates[NIGHT_LOADS].get(effect.ceiling_on)
    return (
        ceiling is not None and size is not None and size > beyond * ceiling and estimates[SENSOR_BIAS]["bias_k"] <= 0.0
    )


def _night_load_first(
    trials: list[tuple[str, ModelFit, dict]], entries: list[dict], estimate_ceilings: bool | Mapping[str, float] = True
) -> tuple[str, ModelFit] | None:
    """The night_plug_loads candidate of a first step (``(name, its trial)``) when :func:`night_load_named_first`
    (judged against ``estimate_ceilings``) names it ahead of the held-out gains and they did not already, its entry
    marked ``named_by_night_electricity``; else None."""
    if (
        not night_load_named_first({e["name"]: e["parameters"] for e in entries}, estimate_ceilings)
        or next((e["name"] for e in entries if e["qualifies"]), None) == NIGHT_LOADS
    ):
        return None
    next(e for e in entries if e["name"] == NIGHT_LOADS)["named_by_night_electricity"] = True
    return next((name, trial) for name, trial, _ in trials if name == NIGHT_LOADS)


def check_joint_candidates(candidates: tuple[str, ...], settings: DiagnosisSettings) -> None:
    """Raise :class:`buildenv.diagnosis.effects.EffectError` (one line) for a candidate :func:`joint_calibration_tests`
    cannot test: unknown, a base effect of the site (``settings`` with the site's declared effects), or
    holidays."""
    for name in candidates:
        get_effect(name)
        if name in settings.base_effects:
            raise EffectError(f"{name} is a base effect of this site: it is in both models of a joint test")
        if name == HOLIDAYS:
            raise EffectError("holidays are detected day by day, not calibrated jointly: no joint test")


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


def _heldout_fit(ctx: _Context, fit: ModelFit) -> ModelFit:
    """The model with its held-out weeks' absent days detected (when it models holidays)."""
    if HOLIDAYS not in fit.effects or not ctx.heldout:
        return fit
    absent = fit.absent.copy()
    absent[ctx.heldout] = detect_absent_days(ctx, fit, ctx.heldout)
    return dataclasses.replace(fit, absent=absent)


def heldout_score(ctx: _Context, before: ModelFit, after: ModelFit, k: int, series: tuple[str, ...] = SERIES) -> dict:
    """Held-out gain and F-test of ``after`` against ``before`` on the standardised residuals of ``series``
    (see the module docstring); ``gain_by_series`` gives each series' own gain, ``sse_by_series`` its
    standardised sums of squares ``[before, after]``."""
    b, a = _heldout_fit(ctx, before), _heldout_fit(ctx, after)
    tb, qb = predict(ctx, b, ctx.heldout)
    ta, qa = predict(ctx, a, ctx.heldout)
    rb, ra = _standardised_residuals(ctx, ctx.heldout, tb, qb), _standardised_residuals(ctx, ctx.heldout, ta, qa)
    by_series = {name: (float(np.nansum(rb[name] ** 2)), float(np.nansum(ra[name] ** 2))) for name in SERIES}
    sse_b = sum(by_series[name][0] for name in series)
    sse_a = sum(by_series[name][1] for name in series)
    if after.effects and after.effects[-1] == HOLIDAYS:
        k = max(1, int((a.absent[ctx.heldout] > 0).sum() - (b.absent[ctx.heldout] > 0).sum()))
    lags = [r for r in (_lag1(rb[name]) for name in series) if r is not None]
    r1 = float(np.clip(np.mean(lags), 0.0, 0.99)) if lags else 0.0
    n = int(sum(np.isfinite(rb[name]).sum() for name in series))
    n_eff = max(n * (1.0 - r1) / (1.0 + r1), k + 2.0)
    gain = 1.0 - sse_a / sse_b if sse_b > 0 else 0.0
    f = (sse_b - sse_a) / k / max(sse_a / (n_eff - k), 1e-12)
    p = float(stats.f.sf(f, k, n_eff - k)) if f > 0 else 1.0
    return {
        "gain": gain,
        "f": float(f),
        "p_value": p,
        "k": k,
        "n": n,
        "n_eff": round(float(n_eff), 1),
        "lag1_autocorrelation": round(float(r1), 3),
        "sse_before": sse_b,
        "sse_after": sse_a,
        "series": list(series),
        "sse_by_series": {name: [round(sb, 3), round(sa, 3)] for name, (sb, sa) in by_series.items()},
        "gain_by_series": {name: round(1.0 - sa / sb, 4) if sb > 0 else 0.0 for name, (sb, sa) in by_series.items()},
        "metrics_before": _metrics(ctx, b, ctx.heldout, tb, qb),
        "metrics_after": _metrics(ctx, a, ctx.heldout, ta, qa),
    }


def _lag1(residuals: np.ndarray) -> float | None:
    """Lag-1 autocorrelation of a residual series (gaps skipped); None when too short."""
    r = residuals.ravel()
    a, b = r[:-1], r[1:]
    ok = np.isfinite(a) & np.isfinite(b)
    return float(np.corrcoef(a[ok], b[ok])[0, 1]) if ok.sum() > 2 else None


def _metrics(ctx: _Context, fit: ModelFit, weeks: list[int], t: np.ndarray, q: np.ndarray) -> dict:
    problem = _problem(ctx, fit, weeks)
    out = cal.score_series(problem, t, q, fit.params, ctx.scale)
    return {k: (round(v, 5) if isinstance(v, float) else v) for k, v in out.items()}


def _context(site, surrogate: sg.Surrogate, settings: DiagnosisSettings) -> _Context:
    """The fit / held-out split of a site (:func:`split_weeks`) and its metric scales."""
    fit_weeks, heldout = split_weeks(site.weeks, settings.split)
    ctx = _Context(site, surrogate, fit_weeks, heldout, settings)
    ctx.scale = cal._scale(cal.build_problem(site, fit_weeks))
    ctx.irradiance = fit_irradiance_w_m2(site.weather_hours(), fit_weeks)
    return ctx


def fit_irradiance_w_m2(weather_hours: np.ndarray, fit_weeks: list[int]) -> float:
    """Mean global horizontal irradiance (W/m2) of the fit weeks ``fit_weeks`` of a site's weather
    ``weather_hours`` (``(weeks, 168, channels)``, :meth:`buildenv.sites.Site.weather_hours`): what blinds'
    clean-site ceiling grows with (:attr:`buildenv.diagnosis.effects.Effect.sunshine_ceiling`)."""
    return round(float(np.asarray(weather_hours)[fit_weeks, :, cat.WEATHER_NAMES.index("IGLOB_H")].mean()), 3)


def judged_as_declared(site, clean_ceilings: bool | Mapping[str, float]) -> bool:
    """Whether a diagnosis of ``site`` judges its candidates by the clean-site ceilings measured on sites that
    declare building parameters known (:attr:`buildenv.diagnosis.effects.Effect.declared_ceiling`) instead of the
    catalogue's: the site declares some (``[known]``) and ``clean_ceilings`` asks for the catalogue's (True)."""
    return clean_ceilings is True and bool(site.known)


def site_ceilings(
    site, clean_ceilings: bool | Mapping[str, float] = True, irradiance_w_m2: float | None = None
) -> bool | Mapping[str, float]:
    """The clean-site ceilings a diagnosis of ``site`` judges its candidates by (:func:`candidate_qualifies`'s
    ``clean_ceilings``): those of sites declaring building parameters known when it declares some
    (:func:`judged_as_declared`), else the catalogue's at the fit weeks' irradiance ``irradiance_w_m2`` (W/m2,
    :func:`buildenv.diagnosis.effects.ceilings_in_sunshine`) when ``clean_ceilings`` asks for the catalogue's and the
    irradiance is given, else ``clean_ceilings`` as given."""
    if judged_as_declared(site, clean_ceilings):
        return declared_ceilings()
    if clean_ceilings is True and irradiance_w_m2 is not None:
        return ceilings_in_sunshine(irradiance_w_m2)
    return clean_ceilings


def residual_sigma(ctx: _Context, fit: ModelFit) -> tuple[float, float]:
    """Standard deviations of a model's residuals on the fit weeks: temperature (K), consumption (Wh/m2); the
    units the diagnosis standardises every residual in (1 where a series has no spread)."""
    t, q = predict(ctx, fit, ctx.fit_weeks)
    return (
        float(np.nanstd(ctx.site.temperature_c[ctx.fit_weeks] - t)) or 1.0,
        float(np.nanstd(ctx.site.consumption_wh_m2()[ctx.fit_weeks] - q)) or 1.0,
    )


def base_model_gap(site, surrogate: sg.Surrogate, settings: DiagnosisSettings | None = None) -> dict:
    """A site's base model (calibrated on its fit weeks, with the settings' ``base_effects`` and no other effect):
    ``{"heldout": metrics on the held-out weeks (:func:`buildenv.metrics.site_metrics`), "residual_sigma":
    [K, Wh/m2] (:func:`residual_sigma`)}``, as :func:`diagnose` reports them under ``heldout_base`` and
    ``residual_sigma``."""
    ctx = _context(site, surrogate, with_declared_effects(site, settings or DiagnosisSettings()))
    fit = base_fit(ctx)
    t, q = predict(ctx, fit, ctx.heldout)
    return {"heldout": _metrics(ctx, fit, ctx.heldout, t, q), "residual_sigma": list(residual_sigma(ctx, fit))}


def base_heldout_metrics(site, surrogate: sg.Surrogate, settings: DiagnosisSettings | None = None) -> dict:
    """Held-out metrics (:func:`buildenv.metrics.site_metrics`) of a site's base model (:func:`base_model_gap`)."""
    return base_model_gap(site, surrogate, settings)["heldout"]


def _warn_not_measured_with(surrogate: sg.Surrogate) -> None:
    """Warn when ``surrogate`` is not the checkpoint the diagnosis' ceilings were measured with."""
    if surrogate.identity != sg.checkpoint_identity(sg.DIAGNOSIS_CHECKPOINT):
        log.warning(
            "the gap diagnosis' ceilings were measured with the shipped 'diagnosis' metamodel, not with %s: "
            "its verdicts may not hold (use --checkpoint diagnosis)",
            surrogate.name,
        )


@one_blas_thread()  # buildenv.metamodel.threads: numpy's BLAS threads would fight the metamodel's
def diagnose(
    site,
    surrogate: sg.Surrogate,
    settings: DiagnosisSettings | None = None,
    localisation: bool = True,
    progress: bool = False,
    plot: str | Path | None = None,
) -> dict:
    """Diagnose the gap between a site's measurements and its calibrated metamodel.

    Args:
        site: a :class:`buildenv.sites.Site` with at least 2 weeks.
        surrogate: the metamodel.
        settings: :class:`DiagnosisSettings`.
        localisation: include the residual localisation (:mod:`buildenv.diagnosis.localise`).
        progress: progress bar over the candidates.
        plot: PNG path of the localisation heatmaps (none if ``None``).
    Returns:
        ``{"localisation", "effects": [...] ranked best first, "selected", "named_by_estimate", "verdict", "steps",
        "model", "fit_weeks", "heldout_weeks", "heldout_base", "residual_sigma", "base_at_bounds", "split_weather",
        "seconds"}``; each effect entry has ``name, score, significance, heldout_before, heldout_after,
        parameters, selected``; ``named_by_estimate`` lists the effect named by its estimate alone when nothing was
        selected (:func:`named_by_estimate`; not in the model); ``heldout_base`` holds the base model's held-out
        metrics, ``residual_sigma`` its fit-week residual standard deviations ([K, Wh/m2], the units every residual
        is standardised in) and ``base_at_bounds`` its building parameters at a bound of their range
        (:func:`buildenv.calibration.problem.parameters_at_bounds`).
    Raises:
        ValueError: an unknown ``settings.judge``.
        buildenv.diagnosis.effects.EffectError: an unknown candidate or base effect.
        buildenv.calibration.problem.CalibrationError: the site has fewer than 2 weeks.
    """
    from tqdm import tqdm

    settings = with_declared_effects(site, settings or DiagnosisSettings())
    if settings.judge not in JUDGES:
        raise ValueError(f"unknown judge {settings.judge!r}; choose {' or '.join(JUDGES)}")
    for name in (*settings.candidates, *settings.base_effects):
        get_effect(name)
    started = time.perf_counter()
    if site.weeks < 2:
        raise cal.CalibrationError(f"{site.path}: the diagnosis needs at least 2 weeks (fit + held-out)")
    _warn_not_measured_with(surrogate)
    if site.calibration:
        from buildenv.calibration.verdict import check_calibration

        check_calibration(site.calibration, str(site.path))
    ctx = _context(site, surrogate, settings)
    fit_weeks, heldout = ctx.fit_weeks, ctx.heldout
    current = base_fit(ctx, progress)
    ctx.sigma = residual_sigma(ctx, current)
    base = current
    steps: list[dict] = []
    remaining = [e for e in settings.candidates if e not in settings.base_effects]
    first_step: list[dict] = []
    without_base: dict[str, ModelFit] = {}  # the base model without a carried effect (first step), reused below
    bar = tqdm(total=len(remaining), desc="effects", disable=not progress, leave=False)
    while remaining and len(current.effects) - len(base.effects) < settings.max_effects:
        trials = []
        control = refit(ctx, current, None)
        for name in remaining:
            series = SERIES if settings.judge == "pooled" else get_effect(name).series
            if carried_by(ctx, name):  # in the model already: judged against the model without it
                trial = carried_trial(ctx, current, control, name)
                without = without_carried_effect(ctx, current, name)
                if current is base:
                    without_base[name] = without
                score = heldout_score(ctx, without, trial, 1, series) | {
                    "baseline": "model without the carried effect",
                    "fit_cost": {"candidate": trial.cost, "model_without_it": without.cost},
                }
            else:
                trial = refit(ctx, current, name)
                k = len(em.none_parameters(name))
                score = heldout_score(ctx, control, trial, k, series)
                if settings.own_refit_baseline:
                    score = stricter_score(
                        score, heldout_score(ctx, without_new_effect(current, trial), trial, k, series)
                    )
                score["fit_cost"] = {"candidate": trial.cost, "control": control.cost}
            trials.append((name, trial, score))
            bar.update(1)
        threshold = settings.alpha / len(trials)
        trials.sort(key=lambda r: -r[2]["gain"])
        entries = [
            _entry(name, trial, score, threshold, settings.min_gain, ctx.ceilings, ctx.declared)
            for name, trial, score in trials
        ]
        steps.append({"model": list(current.effects), "candidates": entries})
        if not first_step:
            first_step = entries
        chosen = next(((n, tr) for (n, tr, _), e in zip(trials, entries) if e["qualifies"]), None)
        if current is base and settings.night_load_first and ctx.catalogue:
            chosen = _night_load_first(trials, entries, ctx.estimate_ceilings) or chosen
        if chosen is None and settings.joint_fallback:
            chosen = joint_fallback(ctx, current, entries, threshold)
        if chosen is None:
            break
        current = chosen[1]
        remaining.remove(chosen[0])
        bar.reset(total=len(remaining))
    bar.close()
    selected = [e for e in current.effects if e not in base.effects]
    for e in first_step:
        e["selected"] = e["name"] in selected
    by_estimate: list[str] = []
    if not selected and settings.estimate_alone and ctx.catalogue:
        for e in first_step:
            e["beyond_estimate_ceiling"] = ctx.effect(e["name"]).beyond_estimate_ceiling(e["parameters"])
        by_estimate = named_by_estimate(
            {e["name"]: e["parameters"] for e in first_step},
            {e["name"]: e["score"] for e in first_step},
            ctx.estimate_ceilings,
            {e["name"]: e["gain_by_series"] for e in first_step},
        )
    result = {
        "site": str(site.path),
        **cal.metamodel_record(surrogate),
        "fit_weeks": fit_weeks,
        "heldout_weeks": heldout,
        "fit_irradiance_w_m2": ctx.irradiance,
        "base_effects": list(settings.base_effects),
        "effects": first_step,
        "selected": selected,
        "named_by_estimate": by_estimate,
        "steps": steps,
        "heldout_base": _metrics(ctx, base, heldout, *predict(ctx, base, heldout)),
        "residual_sigma": list(ctx.sigma),
        "base_at_bounds": cal.parameters_at_bounds(
            dict(zip(cal.free_theta(), base.params[: len(cal.free_theta())].tolist())), site.known, ctx.surrogate
        ),
        "split_weather": split_weather(site, settings.split),
        "verdict": _verdict(selected, first_step, settings.min_gain, steps, by_estimate, ctx.irradiance),
        "model": {
            "effects": current.effect_parameters(),
            "absent_days": _absent_dates(site, current),
            "parameters": current.params.tolist(),
        },
        "settings": dataclasses.asdict(settings),
        "settings_note": settings_note(settings),
    }
    if selected:
        before = base  # the whole gain of the diagnosis, against the base model without any selected effect
        for name in selected:
            if name in current.carried:
                before = (
                    without_base[name]
                    if before is base and name in without_base
                    else without_carried_effect(ctx, before, name)
                )
        final = heldout_score(ctx, before, current, 1)
        result["heldout_before"], result["heldout_after"] = final["metrics_before"], final["metrics_after"]
    if localisation:
        result["localisation"] = localise_site(ctx, base, plot)
    result["seconds"] = round(time.perf_counter() - started, 1)
    result["_fit"] = current  # the extended model (dropped from JSON output)
    return result


def candidate_qualifies(
    name: str,
    gain: float,
    p_value: float,
    threshold: float,
    min_gain: float,
    parameters: dict[str, float],
    gain_by_series: dict[str, float] | None = None,
    clean_ceilings: bool | Mapping[str, float] = True,
) -> bool:
    """Whether a candidate may join the model (module docstring, step 3): significant (``p_value <
    threshold``) with a positive held-out gain, a plausible estimate ``parameters`` and enough evidence: an
    estimate beyond the effect's clean-site ceiling where it has one and ``clean_ceilings`` is on
    (:meth:`buildenv.diagnosis.effects.Effect.beyond_clean_sites`), else a gain of at least ``min_gain``; a carried
    effect also makes none of its series worse (:func:`carried_series_made_worse`, given ``gain_by_series``).
    ``clean_ceilings`` may also map effects to ceilings used instead of the catalogue's (an effect missing from
    it has none)."""
    beyond = beyond_clean_sites(name, parameters, clean_ceilings)
    return (
        p_value < threshold
        and gain > 0.0
        and (gain >= min_gain if beyond is None else beyond)
        and get_effect(name).plausible(parameters)
        and not carried_series_made_worse(name, parameters, gain_by_series or {})
    )


def beyond_clean_sites(
    name: str, parameters: dict[str, float], clean_ceilings: bool | Mapping[str, float] = True
) -> bool | None:
    """Whether a candidate's estimate lies beyond its clean-site ceiling (:func:`candidate_qualifies`'s
    ``clean_ceilings``: the catalogue's, a mapping used instead, or none when False); None where no ceiling
    applies, and the ``min_gain`` bar judges the candidate."""
    if clean_ceilings is False:
        return None
    effect = get_effect(name)
    if isinstance(clean_ceilings, Mapping):
        effect = dataclasses.replace(effect, clean_ceiling=clean_ceilings.get(name))
    return effect.beyond_clean_sites(parameters)


def series_made_worse(name: str, gain_by_series: dict[str, float]) -> list[str]:
    """The series of a carried effect (:attr:`buildenv.diagnosis.effects.Effect.building_parameter`) that its held-out
    test made worse (empty when none did). A heating plant short of power lowers both the consumption and the
    morning temperature; a calibrated heating power that improves one series at the other's expense is
    absorbing another miss."""
    return [s for s in get_effect(name).series if gain_by_series.get(s, 0.0) < 0.0]


def sensor_reading_made_worse(name: str, gain_by_series: Mapping[str, float]) -> list[str]:
    """The series a sensor effect (:attr:`.effects.Effect.kind` ``sensor``: its model changes only what a
    sensor reads) made worse on the held-out weeks (``gain_by_series``, ``{series: gain}``; empty for other effects
    or where no series gain is given): an estimate beyond every clean site's that reads its own series worse held
    out is no evidence the estimate alone names by."""
    return series_made_worse(name, gain_by_series) if get_effect(name).kind == "sensor" else []


def carried_series_made_worse(name: str, parameters: dict[str, float], gain_by_series: dict[str, float]) -> list[str]:
    """:func:`series_made_worse` when the estimate ``parameters`` is a carried effect's building parameter (the
    diagnosis judged it through that parameter), else empty."""
    carried = get_effect(name).building_parameter in parameters
    return series_made_worse(name, gain_by_series) if carried else []


def _entry(
    name: str,
    trial: ModelFit,
    score: dict,
    threshold: float,
    min_gain: float,
    clean_ceilings: bool | Mapping[str, float] = True,
    declared: bool = False,
) -> dict:
    significant = score["p_value"] < threshold
    parameters = trial.effect_parameters().get(name, {})
    plausible = get_effect(name).plausible(parameters)
    beyond = beyond_clean_sites(name, parameters, clean_ceilings)
    worse = carried_series_made_worse(name, parameters, score["gain_by_series"])
    qualifies = candidate_qualifies(
        name, score["gain"], score["p_value"], threshold, min_gain, parameters, score["gain_by_series"], clean_ceilings
    )
    return {
        "name": name,
        "title": get_effect(name).title,
        "score": round(score["gain"], 4),
        "significance": {
            "p_value": score["p_value"],
            "threshold": threshold,
            "f": round(score["f"], 3),
            "k": score["k"],
            "n_eff": score["n_eff"],
            "significant": significant,
            "test": "F-test on held-out standardised SSE, n corrected for lag-1 autocorrelation, "
            "Bonferroni over the step's candidates",
        },
        "judged_on": score["series"],
        "gain_by_series": score["gain_by_series"],
        "sse_by_series": score["sse_by_series"],
        "plausible": bool(plausible),
        # beyond every clean site's estimate (None: judged by the min_gain bar instead); the clean sites
        # declared building parameters known where the site does (judged_as_declared)
        "beyond_clean_sites": beyond,
        "ceilings_of_declaring_sites": declared,
        "series_made_worse": worse,
        "qualifies": bool(qualifies),
        "parameters": parameters,
        "baseline": score.get("baseline", "control"),  # what the gain is measured against
        **{key: score[key] for key in ("gain_vs_control", "gain_vs_own_refit") if key in score},
        "heldout_before": score["metrics_before"],
        "heldout_after": score["metrics_after"],
        # the calibration cost on the fit weeks, (1 - R2_T) + (1 - R2_Q), of the candidate's refit and of the
        # control (for a carried effect: of the model without it), what the searches themselves minimised
        "fit_cost": {key: round(float(value), 6) for key, value in score["fit_cost"].items()},
    }


def _verdict(
    selected: list[str],
    entries: list[dict],
    min_gain: float,
    steps: list[dict] = (),
    by_estimate: list[str] = (),
    irradiance_w_m2: float | None = None,
) -> str:
    """The diagnosis in one sentence: the selected effects (marked where a joint test named one), else the effect
    named by its estimate alone (:func:`named_by_estimate`), else why the best candidate of the first step
    ``entries`` was not named (the ceilings as judged at the fit weeks' irradiance ``irradiance_w_m2``, W/m2)."""
    if not selected and by_estimate:
        entry = next(e for e in entries if e["name"] == by_estimate[0])
        effect = get_effect(entry["name"]).in_sunshine(irradiance_w_m2)
        return (
            f"unmodelled effect named by its estimate alone: {entry['name']} ({effect.title}; "
            f"{effect.estimate_text(entry['parameters'])}, beyond {effect.estimate_ceiling_text()}). Its "
            f"held-out gain ({100 * entry['score']:.1f} %) does not qualify it, so the site's model stays without "
            "it: the base calibration's building parameters stand in for it"
        )
    if not selected:
        best = entries[0] if entries else None
        tested = "".join(f"; {e['name']} {_joint_text(e['joint_test'])}" for e in entries[1:] if "joint_test" in e)
        held = "".join(
            f"; {text}"
            for e in entries
            if e.get("beyond_estimate_ceiling") and e["plausible"] and (text := _held_back_text(e))
        )
        why = _why_not_named(best, min_gain, irradiance_w_m2) if best else ""
        return "no significant unmodelled effect" + (f" (best candidate: {why}{tested}{held})" if best else "")
    by_joint = {e["name"] for step in steps for e in step["candidates"] if e.get("joint_test", {}).get("qualifies")}
    by_night = {e["name"]: e for e in entries if e.get("named_by_night_electricity")}

    def how(name: str) -> str:
        if name in by_night:
            effect = get_effect(name)
            size = by_night[name]["parameters"][effect.ceiling_on]
            return (
                f"; named first by the night electricity the model carries, {size:.3g} W/m2, beyond "
                f"{NIGHT_LOAD_FIRST_BEYOND:g} times every clean site's {effect.estimate_ceiling:g} W/m2, "
                "with the sensor bias refit cold"
            )
        return "; named by joint calibration" if name in by_joint else ""

    return "unmodelled effect(s) found: " + ", ".join(f"{n} ({get_effect(n).title}{how(n)})" for n in selected)


def held_back_from_estimate(name: str, gain: float, gain_by_series: Mapping[str, float]) -> list[str]:
    """Why the held-out weeks keep a candidate beyond every clean site's from being named by its estimate alone
    (:func:`named_by_estimate`), one phrase per reason, empty when nothing does: a sensor effect's own series read
    worse (:func:`sensor_reading_made_worse`, from ``gain_by_series``), or its held-out ``gain`` below
    :data:`buildenv.diagnosis.effects.ESTIMATE_ALONE_LOWEST_GAIN` where that guard is set (None: no guard)."""
    lowest = ESTIMATE_ALONE_LOWEST_GAIN
    why = (
        [f"its held-out gain ({100 * gain:.1f} %) is below the {100 * lowest:.0f} % the estimate alone allows"]
        if lowest is not None and gain < lowest
        else []
    )
    return why + [
        f"with it the {s} reads {-100 * gain_by_series[s]:.0f} % worse held out (a sensor effect that is "
        "there reads its series better)"
        for s in sensor_reading_made_worse(name, gain_by_series)
    ]


def _held_back_text(entry: dict) -> str:
    """A first-step candidate beyond every clean site's and why it is not named by its estimate
    (:func:`held_back_from_estimate`); "" where nothing holds it back."""
    why = held_back_from_estimate(entry["name"], entry["score"], entry.get("gain_by_series", {}))
    estimate = get_effect(entry["name"]).estimate_text(entry["parameters"])
    return (
        (
            f"{entry['name']}'s estimate ({estimate}) is beyond every clean site's, but not named by it: "
            f"{' and '.join(why)}"
        )
        if why
        else ""
    )


def _why_not_named(entry: dict, min_gain: float, irradiance_w_m2: float | None = None) -> str:
    """The best candidate's figures and every rule of :func:`candidate_qualifies` it fails (its ceiling as judged at
    the fit weeks' irradiance ``irradiance_w_m2``, W/m2)."""
    sig = entry["significance"]
    reasons = []
    if sig["p_value"] >= sig["threshold"]:
        reasons.append(f"not significant at p < {sig['threshold']:.2g}")
    effect = get_effect(entry["name"])
    estimate = effect.estimate_text(entry["parameters"])
    beyond = entry.get("beyond_clean_sites")
    if beyond is False:
        judged = (
            effect.on_declared_site()
            if entry.get("ceilings_of_declaring_sites")
            else effect.in_sunshine(irradiance_w_m2)
        )
        reasons.append(f"its estimate ({estimate}) is not beyond every clean site's: {judged.clean_ceiling_text()}")
    elif beyond is None and entry["score"] < min_gain:
        reasons.append(f"under the {100 * min_gain:.0f} % held-out gain an effect must bring to be named")
    if entry.get("series_made_worse"):
        reasons.append(
            f"it makes the {' and '.join(entry['series_made_worse'])} worse: a building parameter "
            "trading one series against the other absorbs another miss"
        )
    if not entry["plausible"]:
        stated = "that estimate" if beyond is False else f"its estimate ({estimate})"
        reasons.append(f"{stated} is outside what the diagnosis names: {effect.named_from()}")
    if "joint_test" in entry:
        reasons.append(f"it {_joint_text(entry['joint_test'])}")
    return f"{entry['name']}, held-out gain {100 * entry['score']:.1f} %, p = {sig['p_value']:.2g}" + "".join(
        f"; {r}" for r in reasons
    )


def _joint_text(test: dict) -> str:
    """A joint test that did not name its candidate (:func:`joint_fallback`), as the verdict says it."""
    estimate = get_effect(test["candidate"]).estimate_text(test["estimate"])
    return (
        f"calibrated from scratch with and without it gains {100 * test['gain']:.1f} %, p = {test['p_value']:.2g}, "
        f"{estimate} (not named: a joint test must gain significantly with a plausible estimate beyond every "
        "clean site's)"
    )


def _absent_dates(site, fit: ModelFit) -> list[str]:
    return [(site.start + dt.timedelta(days=7 * int(w) + int(d))).isoformat() for w, d in zip(*np.nonzero(fit.absent))]


def localise_site(ctx: _Context, fit: ModelFit, plot: str | Path | None = None) -> dict:
    """Residual localisation (:func:`buildenv.diagnosis.localise.localise`) of a model over all the site's weeks,
    plotted into ``plot`` (a PNG path) when given."""
    from buildenv.diagnosis.localise import localise, plot_localisation
    from buildenv.schedules import hourly_schedules

    weeks = list(range(ctx.site.weeks))
    t, q = predict(ctx, fit, weeks)
    problem = _problem(ctx, fit, weeks)
    occupied = cal.problem_occupancy(problem, fit.params)
    _, occ = cal._split(problem, fit.params[None])
    heating = hourly_schedules(ctx.site.settings, np.broadcast_to(occ[0], (ctx.site.weeks, *occ.shape[1:])))
    occupied = np.asarray(occupied)
    result = localise(
        ctx.site.temperature_c,
        ctx.site.consumption_wh_m2(),
        t,
        q,
        ctx.site.weather_hours(),
        occupied,
        heating["heating_comfort_on"] > 0,
        ctx.site.week_starts(),
    )
    if plot is not None:
        result["plot"] = str(
            plot_localisation(result, plot, ctx.site.temperature_c, ctx.site.consumption_wh_m2(), t, q, occupied)
        )
    return result


def save_extended_model(site, result: dict) -> Path | None:
    """Make the diagnosis' extended model the site's model: ``calibration.json`` gains the selected effects.

    The theta and occupancy refitted with the effects replace the calibrated ones, ``effects`` holds
    ``{effect: {parameter: value}}`` and ``absent_days`` the dates modelled unoccupied; the previous calibration
    is kept under ``without_effects``. Nothing is written when no effect was selected (returns None).
    """
    from buildenv.sites import save_calibration

    fit: ModelFit = result["_fit"]
    if not result["selected"]:
        return None
    previous = dict(site.calibration or {})
    previous.pop("without_effects", None)
    theta, occ = cal._split(cal.build_problem(site, result["fit_weeks"][:1], fit.model_effects), fit.params[None])
    extended = {
        **previous,
        "method": "cmaes+effects",
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
    if "heldout_after" in result:
        extended["heldout"] = result["heldout_after"]
    return save_calibration(site.path, extended)
