"""The withheld-effect check: sites with one effect (or none) injected, diagnosed blind, scored.

``run_check(out, cases, seed)`` makes ``cases`` reference-building sites (:mod:`buildenv.energyplus.reference`),
each with one effect of :mod:`buildenv.diagnosis.effects` injected at a random magnitude, or none, over ``weeks``
weeks of the heating season (first Monday between :data:`FIRST_MONDAYS`, moved back where the period would cross
the new year: :func:`plan_cases`), with its own sensor-noise seed; labels cycle through "none" and every effect in
a random order. Magnitudes are drawn from each effect's practice range (:func:`draw_magnitude`; a sensor bias
of at least 0.5 K, 2-3 holidays so that one falls in the held-out weeks). Each site is diagnosed
(:func:`buildenv.diagnosis.gap.diagnose`) knowing nothing of the injection; its answer is the first selected
effect, else "not enough data to tell" when the diagnosis said so of the injected effect, else "none".

The stand-in's own effects (``base_effects="auto"``) are found first by diagnosing a clean reference site
(:func:`known_effects`); they enter every case's model and are not injected. ``known_parameters`` makes every
site declare those building parameters known (:class:`StandIn`).

**Scores** (:func:`summarise`): confusion matrix (true x named), top-1 accuracy over effect cases, false-alarm
rate over "none" cases, ranked-first accuracy (:func:`ranked_first`) and the shrinkage of the effect's gap on its
main series, ``(MSE_before - MSE_after) / (MSE_before - MSE_twin)``, where the twin is the same site without the
injection. The footprint of an effect (:func:`footprint`) is the RMS of case - twin on the held-out weeks; it is
*visible* at :data:`VISIBLE_NOISE_MULTIPLE` times the sensor noise. The gap it left after calibration
(:func:`gap_left`) is the share of the case's held-out error it added as the calibrated base models see it.

Each case is written as ``case_NNN.json`` in ``out``; a rerun skips finished cases and reuses the sites after
checking that each was made for its case.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from buildenv.diagnosis import rules
from buildenv.diagnosis.effects import DIAGNOSIS_SPLITS, EFFECTS, get_effect
from buildenv.diagnosis.evidence import SERIES
from buildenv.diagnosis.gap import DiagnosisSettings, diagnose
from buildenv.diagnosis.refit import base_model_gap
from buildenv.errors import ReferenceBuildingError, SimulationError
from buildenv.jsonio import dumps

NONE = "none"
#: The answer of a case whose injected effect the diagnosis said it had not enough data to tell about.
NOT_ENOUGH_DATA = rules.NOT_ENOUGH_DATA
REFUSED = "refused"
FIRST_MONDAYS = (dt.date(2019, 10, 7), dt.date(2019, 12, 2))
REFERENCE_START = dt.date(2019, 11, 4)
WEEKS = 4
VISIBLE_NOISE_MULTIPLE = 2.0
#: Share of a case's standardised held-out error its effect must add to count as a gap left after calibration
#: (:func:`gap_left`): a tenth, well above what two noise draws of one site differ by.
GAP_LEFT_SHARE = 0.10


@dataclass(frozen=True)
class StandIn:
    """The building every case is made of: a reference building, its weather, the building parameters its
    sites declare known (``site.toml``'s ``[known]``, catalogue units; none by default) and the weeks each site
    measures, split into fit and held-out weeks by :attr:`split` (:func:`buildenv.diagnosis.gap.split_weeks`)."""

    building: str = "medium_office"
    epw: str = "usa_il_chicago"
    known: dict[str, float] = field(default_factory=dict)
    weeks: int = WEEKS
    split: str = DIAGNOSIS_SPLITS[0]
    end_uses: tuple[str, ...] | None = None
    history_seed: int | None = None

    def for_case(self, case: dict) -> StandIn:
        """The stand-in of one case: itself, or for a suite case (:func:`plan_suite_cases`) its building and
        climate, its season's meter and a BMS history drawn from its seed, as ``buildenv suite make`` makes them."""
        if "building" not in case:
            return self
        from buildenv.sites.suite import SEASON_END_USES

        return replace(
            self,
            building=case["building"],
            epw=case["climate"],
            end_uses=SEASON_END_USES[case["season"]],
            history_seed=case["history_seed"],
        )

    def history(self) -> np.ndarray:
        """A suite case's BMS history ``(weeks, 7, 13)``, drawn from :attr:`history_seed` as ``buildenv suite make``
        draws its sites' (:func:`buildenv.sites.suite.reference_history`)."""
        from buildenv.sites.suite import reference_history

        return reference_history(self.building, self.weeks, np.random.default_rng(self.history_seed))

    def plan(self, start: dt.date, effects: list | None, effect_seed: int) -> list:
        """The effects' random choices fixed (:func:`buildenv.energyplus.injections.plan_effects`): holidays with one
        absent day in the weeks the diagnosis fits (:attr:`split`) and one in those it holds out."""
        from buildenv.diagnosis.split import split_weeks
        from buildenv.energyplus.injections import plan_effects

        return plan_effects(effects, start, self.weeks, effect_seed, split_weeks(self.weeks, self.split)[0])

    def make(self, path: Path, start: dt.date, seed: int, effects: list | None = None, effect_seed: int = 0) -> Path:
        """Run the stand-in over :attr:`weeks` weeks from ``start`` and write the site folder ``path``."""
        from buildenv.energyplus.reference import make_reference_site

        suite = {} if self.history_seed is None else {"settings": self.history(), "end_uses": self.end_uses}
        return make_reference_site(
            path,
            self.building,
            self.epw,
            start,
            self.weeks,
            seed=seed,
            effects=self.plan(start, effects, effect_seed),
            effect_seed=effect_seed,
            known=self.known,
            record_supply_air=False,  # the stand-in's checks run histories at the default supply air
            **suite,
        )


def draw_magnitude(name: str, rng: np.random.Generator) -> float:
    """A random magnitude of effect ``name`` in its magnitude unit: uniform over its practice range
    (:attr:`buildenv.diagnosis.effects.Effect.magnitude_range`), except a sensor bias, ``+-U(0.5, max |range|)`` K
    (a smaller one hides in the noise and the model's own error), and holidays, 2 to the range's top absent days
    (so that one falls in the held-out weeks)."""
    effect = get_effect(name)
    lo, hi = effect.magnitude_range
    if name == "temperature_sensor_bias":
        return float(rng.choice([-1.0, 1.0]) * rng.uniform(0.5, max(abs(lo), abs(hi))))
    if name == "holidays":
        return float(rng.integers(2, int(hi) + 1))
    return float(rng.uniform(lo, hi))


def latest_first_monday(weeks: int) -> dt.date:
    """The last first Monday from which ``weeks`` weeks end within :data:`FIRST_MONDAYS`' year (the stand-in
    checks' window): 2 December 2019 for 4 weeks, 4 November for 8."""
    latest = dt.date(FIRST_MONDAYS[1].year, 12, 31) - dt.timedelta(days=7 * weeks - 1)
    return min(FIRST_MONDAYS[1], latest - dt.timedelta(days=latest.weekday()))


def reference_start(weeks: int) -> dt.date:
    """First Monday of the clean reference site whose diagnosis names the stand-in's own effects
    (``--base-effects auto``): :data:`REFERENCE_START`, moved back like the cases' (:func:`latest_first_monday`)
    when ``weeks`` weeks from it would cross the new year (9 weeks or more)."""
    return min(REFERENCE_START, latest_first_monday(weeks))


def plan_cases(
    cases: int, seed: int, exclude: tuple[str, ...] = (), effects: tuple[str, ...] | None = None, weeks: int = WEEKS
) -> list[dict]:
    """The cases of a check: label, magnitude, first Monday and seeds, all from ``seed``; labels cycle through
    "none" and ``effects`` (default: the whole catalogue) less ``exclude``. A first Monday from which ``weeks``
    weeks would run into the next year is moved back to :func:`latest_first_monday` (never for 4 weeks), and
    every other draw stays as it is, so longer sites keep the cases' labels, magnitudes and seeds."""
    rng = np.random.default_rng(seed)
    labels = [NONE] + [e for e in (effects or EFFECTS) if e not in exclude]
    order = list(rng.permutation(labels))
    mondays = (FIRST_MONDAYS[1] - FIRST_MONDAYS[0]).days // 7 + 1
    plan = []
    for i in range(cases):
        label = str(order[i % len(order)])
        if i and i % len(order) == 0:
            order = list(rng.permutation(labels))
            label = str(order[0])
        start = min(FIRST_MONDAYS[0] + dt.timedelta(weeks=int(rng.integers(mondays))), latest_first_monday(weeks))
        plan.append(
            {
                "case": i,
                "true": label,
                "magnitude": None if label == NONE else draw_magnitude(label, rng),
                "start": start.isoformat(),
                "noise_seed": int(rng.integers(1_000_000)),
                "effect_seed": int(rng.integers(1_000_000)),
            }
        )
    return plan


#: Weeks after its season's first Monday (:data:`buildenv.sites.suite.SEASONS`) a suite case may start.
SUITE_OFFSETS_WEEKS = 4


def plan_suite_cases(
    cases: int, seed: int, effects: tuple[str, ...] | None = None, weeks: int = WEEKS, part: str = "both"
) -> list[dict]:
    """The cases of a blind check over the suite's matrix: each a label (cycling through "none" and ``effects`` as
    :func:`plan_cases`), a magnitude, and a building, climate and season drawn uniformly from the suite
    (:func:`buildenv.sites.suite.suite_cases`; ``part`` ``development``, ``held_out`` or ``both``), starting 0 to
    :data:`SUITE_OFFSETS_WEEKS` - 1 weeks after the season's first Monday, with seeds for its noise, its BMS history
    and its effect's choices. A clean case's twin is the same site with another noise draw."""
    from buildenv.sites.suite import suite_cases

    matrix = [c for c in suite_cases() if part in ("both", c.part)]
    if not matrix:
        raise ValueError(f"part={part!r}: choose development, held_out or both")
    rng = np.random.default_rng([seed, 1])  # a stream of its own, apart from the labels' and seeds'
    plan = []
    for row in plan_cases(cases, seed, (), effects, weeks):
        suite_case = matrix[int(rng.integers(len(matrix)))]
        start = suite_case.start() + dt.timedelta(weeks=int(rng.integers(SUITE_OFFSETS_WEEKS)))
        plan.append(
            {
                **row,
                "building": suite_case.building,
                "climate": suite_case.climate,
                "season": suite_case.season,
                "part": suite_case.part,
                "start": start.isoformat(),
                "history_seed": int(rng.integers(1_000_000)),
            }
        )
    return plan


def _site(out: Path, case: dict, stand_in: StandIn, inject: bool) -> Path:
    effects = [(case["true"], case["magnitude"])] if inject and case["true"] != NONE else []
    path = out / (f"case_{case['case']:03d}" if inject else f"case_{case['case']:03d}_twin")
    stand_in = stand_in.for_case(case)
    # a clean suite case's twin is another noise draw of it (an effect case's differs by its effect alone)
    noise = case["noise_seed"] + (1 if "building" in case and not inject and case["true"] == NONE else 0)
    if (path / "site.toml").is_file():
        _check_site_matches(path, case, effects, stand_in)
    else:
        stand_in.make(path, dt.date.fromisoformat(case["start"]), noise, effects, case["effect_seed"])
    return path


def _check_site_matches(path: Path, case: dict, effects: list[tuple[str, float]], stand_in: StandIn) -> None:
    """Raise when a site folder left by an earlier run was made for another case (another plan: other seed or
    other known effects), declares other known parameters or measures another number of weeks, instead of
    diagnosing it under the wrong label."""
    from buildenv.energyplus.reference import STAND_IN_VERSION, stand_in_version
    from buildenv.sites import load_site

    site = load_site(path)
    version = stand_in_version(site)
    if version != STAND_IN_VERSION:
        raise ValueError(
            f"{path}: made by stand-in version {version}, not this buildenv's {STAND_IN_VERSION}; "
            "run the check into a fresh --out"
        )
    truth_path = path / "truth.json"
    truth = json.loads(truth_path.read_text()) if truth_path.is_file() else {"effects": []}
    made = [(e["name"], float(e["magnitude"])) for e in truth["effects"]]
    same = (
        site.start.isoformat() == case["start"]
        and len(made) == len(effects)
        and all(a == b and abs(m - n) < 1e-9 for (a, m), (b, n) in zip(made, effects))
    )
    if same and effects:  # the same planned choices too (holiday dates depend on the split)
        planned = stand_in.plan(site.start, effects, case["effect_seed"])
        same = all(
            {k: e.get("details", {}).get(k) for k in p.details} == p.details for e, p in zip(truth["effects"], planned)
        )
    if not same:
        raise ValueError(
            f"{path}: this site was made for another case ({made or 'no effect'}, from "
            f"{site.start}), not case {case['case']} ({effects or 'no effect'}, from {case['start']}); "
            "give the check a fresh --out folder"
        )
    if site.known != dict(stand_in.known):
        raise ValueError(
            f"{path}: this site declares known parameters {site.known or 'none'}, the check "
            f"{dict(stand_in.known) or 'none'}; give the check a fresh --out folder"
        )
    if site.weeks != stand_in.weeks:
        raise ValueError(
            f"{path}: this site measures {site.weeks} weeks, the check {stand_in.weeks}; give the "
            "check a fresh --out folder"
        )
    if stand_in.history_seed is not None and (
        site.weather != stand_in.epw
        or tuple(site.consumption_end_uses) != tuple(stand_in.end_uses)
        or not np.allclose(site.settings, stand_in.history(), atol=1e-3)
    ):
        raise ValueError(
            f"{path}: this site was made in {site.weather} with another meter or BMS history than case "
            f"{case['case']} ({stand_in.building} in {stand_in.epw}); give the check a fresh --out folder"
        )


def footprint(out: Path, case: dict, stand_in: StandIn) -> dict:
    """What the injected effect changed in a case's held-out measurements: ``{"temperature_k": RMS of case -
    twin (K), "consumption_percent": RMS of case - twin (% of the twin's mean), "visible": either reaches
    VISIBLE_NOISE_MULTIPLE times the sensor noise}``."""
    from buildenv.diagnosis.split import split_weeks
    from buildenv.energyplus.reference import CONSUMPTION_NOISE_FRACTION, TEMPERATURE_NOISE_K
    from buildenv.sites import load_site

    site = load_site(_site(out, case, stand_in, inject=True))
    twin = load_site(_site(out, case, stand_in, inject=False))
    weeks = split_weeks(site.weeks, stand_in.split)[1]
    dt_k = site.temperature_c[weeks] - twin.temperature_c[weeks]
    twin_q = twin.consumption_wh_m2()[weeks]
    dq = site.consumption_wh_m2()[weeks] - twin_q
    t_rms = float(np.sqrt(np.nanmean(dt_k**2)))
    q_percent = float(100.0 * np.sqrt(np.nanmean(dq**2)) / np.nanmean(twin_q))
    visible = (
        t_rms >= VISIBLE_NOISE_MULTIPLE * TEMPERATURE_NOISE_K
        or q_percent >= VISIBLE_NOISE_MULTIPLE * 100.0 * CONSUMPTION_NOISE_FRACTION
    )
    return {"temperature_k": round(t_rms, 4), "consumption_percent": round(q_percent, 3), "visible": bool(visible)}


def gap_left(case_heldout: dict, twin_heldout: dict, sigma: list[float], least: float = GAP_LEFT_SHARE) -> dict:
    """The share of a case's held-out error its injected effect added, as the calibrated base models see it:
    ``1 - SSE_twin / SSE_case``, both series standardised by ``sigma`` and pooled, as the diagnosis scores a
    candidate. Returns ``{"share", "by_series": {series: share}, "left": share >= least}``.

    Args:
        case_heldout, twin_heldout: held-out metrics of the base models of the case and of its clean twin
            (:func:`buildenv.diagnosis.refit.base_model_gap`), with ``rmse_t_celsius`` (K) and ``rmse_q_wh_m2`` (Wh/m2).
        sigma: the case's fit-week residual standard deviations [K, Wh/m2].
        least: the share from which the effect counts as having left a gap.
    """

    def standardised(m: dict) -> list[float]:
        return [m["rmse_t_celsius"] ** 2 / sigma[0] ** 2, m["rmse_q_wh_m2"] ** 2 / sigma[1] ** 2]

    case, twin = standardised(case_heldout), standardised(twin_heldout)
    share = 1.0 - sum(twin) / sum(case) if sum(case) > 0 else 0.0
    by_series = {s: round(1.0 - b / a, 4) if a > 0 else 0.0 for s, a, b in zip(SERIES, case, twin)}
    return {"share": round(share, 4), "by_series": by_series, "left": bool(share >= least)}


def _gap_left_row(
    out: Path,
    case: dict,
    row: dict,
    surrogate,
    settings: DiagnosisSettings,
    stand_in: StandIn,
    twin: dict | None = None,
) -> dict:
    """``row`` with ``gap_left`` and the base models' held-out metrics: the case's from its diagnosis (calibrated
    again for a case finished before they were recorded), its clean twin's from the twin's diagnosis ``twin``
    (held-out metrics of its base model) when given, else calibrated here."""
    from buildenv.sites import load_site

    if "heldout_base" not in row:
        base = base_model_gap(load_site(_site(out, case, stand_in, inject=True)), surrogate, settings)
        row = {**row, "heldout_base": base["heldout"], "residual_sigma": base["residual_sigma"]}
    if twin is None:
        twin = base_model_gap(load_site(_site(out, case, stand_in, inject=False)), surrogate, settings)["heldout"]
    return {
        **row,
        "twin_heldout_base": twin,
        "gap_left": gap_left(row["heldout_base"], twin, row["residual_sigma"]),
    }


def _mse(metrics: dict, series: str) -> float:
    return metrics["rmse_t_celsius"] ** 2 if series == "temperature" else metrics["rmse_q_wh_m2"] ** 2


def _diagnosis_record(result: dict) -> dict:
    """What a blind check keeps of one diagnosis: the effects named, the first step's candidates (gains, p-values,
    thresholds, estimates, the rules each failed), the effects it had not enough data to tell about, the base
    model's held-out metrics, the residual standard deviations the gains are standardised by and the diagnosis'
    own time (s)."""
    first = result["effects"]
    return {
        "named": result["selected"][0] if result["selected"] else NONE,
        "selected": result["selected"],
        "answer": result["answer"],
        "not_enough_data": sorted(result["not_enough_data"]),
        "ranked": [e["name"] for e in first],
        "scores": {e["name"]: e["score"] for e in first},
        "gains_by_series": {e["name"]: (e["evidence"] or {}).get("gain_by_series") for e in first},
        "p_values": {e["name"]: e["p_value"] for e in first},
        "thresholds": {e["name"]: e["threshold"] for e in first},
        "estimates": {e["name"]: e["parameters"] for e in first},
        "failed": {e["name"]: sorted(e["failed"]) for e in first},
        "fit_costs": {e["name"]: e.get("fit_cost") for e in first},
        "hours_showing": result["hours_showing"],
        "verdict": result["verdict"],
        "heldout_base": result["heldout_base"],
        "residual_sigma": result["residual_sigma"],
        "diagnosis_seconds": result["seconds"],
    }


def answer(named: str, true: str, not_enough_data: list[str]) -> str:
    """A case's answer: the effect named first, else "not enough data to tell" when the diagnosis said it had not enough
    data to tell about the injected effect ``true``, else "none"."""
    return NOT_ENOUGH_DATA if named == NONE and true in not_enough_data else named


def run_case(
    out: Path, case: dict, surrogate, settings: DiagnosisSettings, stand_in: StandIn, twin: dict | None = None
) -> dict:
    """Make, diagnose and score one case (and its clean twin when an effect is injected: the held-out metrics of
    its base model from ``twin``, its diagnosis' record, when given, else calibrated here)."""
    from buildenv.sites import load_site

    started = time.perf_counter()
    site = load_site(_site(out, case, stand_in, inject=True))
    result = diagnose(site, surrogate, settings, localisation=False)
    result.pop("_fit", None)
    record = _diagnosis_record(result)
    record["named"] = answer(record["named"], case["true"], record["not_enough_data"])
    row = {**case, **record, "correct": record["named"] == case["true"]}
    if case["true"] != NONE:
        twin_base = twin["heldout_base"] if twin else None
        row = _gap_left_row(out, case, row, surrogate, settings, stand_in, twin_base)
    if case["true"] != NONE and case["true"] in result["selected"]:
        row["shrinkage"] = shrinkage(result, case["true"], row["heldout_base"], row["twin_heldout_base"])
    if case["true"] != NONE:
        row["footprint"] = footprint(out, case, stand_in)
    row["seconds"] = round(time.perf_counter() - started, 1)
    return row


def shrinkage(result: dict, effect: str, case_base: dict, twin_base: dict) -> dict:
    """What a selected ``effect`` removed of the gap it made, on its main series, held out: ``of_effect_gap`` =
    (MSE before - MSE after it joined the model, at its own step) / (MSE of the case's base model - that of its
    clean twin's), so that effects selected beside it are not credited to it; ``of_total_gap`` = the share of the
    MSE before its step it removed (None where a denominator is not positive).

    Args:
        result: the case's diagnosis (:func:`buildenv.diagnosis.gap.diagnose`), ``effect`` among its selected.
        case_base, twin_base: held-out metrics of the case's and its twin's base models.
    """
    series = get_effect(effect).series[0]
    step, entry = next(
        (i, e)
        for i, s in enumerate(result["steps"])
        for e in s["candidates"]
        if e["name"] == effect and e["status"] == rules.NAMED
    )
    b, a = _mse(entry["heldout_before"], series), _mse(entry["heldout_after"], series)
    gap = _mse(case_base, series) - _mse(twin_base, series)
    return {
        "series": series,
        "step": step,
        "mse_before": b,
        "mse_after": a,
        "gap": gap,
        "of_total_gap": 1.0 - a / b if b > 0 else None,
        "of_effect_gap": (b - a) / gap if gap > 1e-12 else None,
        "parameters": entry["parameters"],
    }


def diagnose_twin(out: Path, case: dict, surrogate, settings: DiagnosisSettings, stand_in: StandIn) -> dict:
    """Diagnose an effect case's clean twin blind, as one more site with no effect: the record of
    :func:`run_case` for a clean case (``true`` is ``none``), the twin made first if the check has not made it.
    Twins measure the naming rules' false alarms on many more clean sites than a check's own clean cases."""
    from buildenv.sites import load_site

    started = time.perf_counter()
    result = diagnose(load_site(_site(out, case, stand_in, inject=False)), surrogate, settings, localisation=False)
    result.pop("_fit", None)
    record = _diagnosis_record(result)
    return {
        **case,
        "true": NONE,
        "twin_of": case["true"],
        **record,
        "correct": record["named"] == NONE,
        "seconds": round(time.perf_counter() - started, 1),
    }


def _make_sites(out: Path, case: dict, stand_in: StandIn) -> str | None:
    """Make a suite case's site and its clean twin; None when both ran, else why EnergyPlus or the stand-in could
    not make them (one line; as ``buildenv suite make`` refuses such a case, nothing of them is left behind)."""
    try:
        _site(out, case, stand_in, inject=True)
        _site(out, case, stand_in, inject=False)
    except (SimulationError, ReferenceBuildingError) as error:
        for folder in (out / f"case_{case['case']:03d}", out / f"case_{case['case']:03d}_twin"):
            shutil.rmtree(folder, ignore_errors=True)
        return str(error).splitlines()[0][:400]
    return None


def beyond_twin(row: dict, twin: dict) -> dict:
    """A suite case judged beyond its clean twin (:func:`diagnose_twin`): the effects the twin names are the site's
    own structural misses, not false alarms; the case's answer is the first effect it names that its twin does
    not, else "not enough data to tell" or "none" (:func:`answer`). ``named_raw`` keeps the diagnosis' own answer."""
    own = sorted(twin["selected"])
    beyond = [e for e in row["selected"] if e not in own]
    named = answer(beyond[0] if beyond else NONE, row["true"], row.get("not_enough_data", []))
    seconds = {"twin_diagnosis_seconds": twin["diagnosis_seconds"]} if "diagnosis_seconds" in twin else {}
    return {
        **row,
        "named_raw": row["named"],
        "twin_named": own,
        "named": named,
        "correct": named == row["true"],
        **seconds,
    }


def known_effects(out: Path, surrogate, settings: DiagnosisSettings, stand_in: StandIn) -> list[str]:
    """Effects the clean stand-in already has (diagnosis of a clean reference site under ``settings``), cached in
    ``out``."""
    from buildenv.sites import load_site

    path, cache = out / "reference", out / "reference_diagnosis.json"
    start = reference_start(stand_in.weeks)
    if (path / "site.toml").is_file():
        _check_site_matches(path, {"case": "reference", "start": start.isoformat()}, [], stand_in)
        if cache.is_file():
            cached = json.loads(cache.read_text())
            if cached.get("settings") == json.loads(dumps(asdict(settings), where="the settings")):
                return cached["selected"]  # (a diagnosis under other settings is made again)
    else:
        stand_in.make(path, start, seed=0)
    result = diagnose(load_site(path), surrogate, settings, localisation=False)
    result.pop("_fit", None)
    cache.write_text(dumps(result, where="the reference diagnosis", nonfinite="null", indent=1, default=float) + "\n")
    return result["selected"]


def ranked_first(row: dict) -> bool:
    """Whether the diagnosis ranked a case's injected effect first with a positive held-out gain, named or not:
    the attribution alone. A candidate with the best gain may still fail the naming rules
    (:mod:`buildenv.diagnosis.rules`), and one with no gain ranks first only
    among candidates that all made the held-out error worse."""
    ranked = row.get("ranked") or []
    return bool(ranked) and ranked[0] == row["true"] and row["scores"].get(row["true"], 0.0) > 0.0


def _record(row: dict) -> str:
    """A case's record as standard JSON (a shrinkage that is undefined as null)."""
    return dumps(row, where="a blind-check case", nonfinite="null", indent=1, default=float)


def _shrinkage(row: dict, key: str) -> float | None:
    """A case's shrinkage ``key`` (``of_effect_gap`` or ``of_total_gap``), None where not measured or undefined
    (null in the record, NaN in an older one)."""
    x = (row.get("shrinkage") or {}).get(key)
    return float(x) if x is not None and np.isfinite(x) else None


def summarise(rows: list[dict], labels: list[str]) -> dict:
    """Confusion matrix, top-1 accuracy, false-alarm rate and shrinkage of finished cases.

    The shrinkage of an effect's gap is what it removed at its step over what it added to the base model
    (:func:`shrinkage`), on the effect's main series over held-out weeks. Its mean is over the found cases whose
    effect left a gap (``gap_left``), where that denominator is more than noise; its median over every found
    case."""
    names = labels + [n for n in sorted({r["named"] for r in rows}) if n not in labels]
    confusion = {t: {n: sum(1 for r in rows if r["true"] == t and r["named"] == n) for n in names} for t in labels}
    effect_rows = [r for r in rows if r["true"] != NONE]
    none_rows = [r for r in rows if r["true"] == NONE]
    shrink = [x for r in effect_rows if (x := _shrinkage(r, "of_effect_gap")) is not None]
    total = [x for r in effect_rows if (x := _shrinkage(r, "of_total_gap")) is not None]
    visible = [r for r in effect_rows if r.get("footprint", {}).get("visible")]
    seconds = [t for r in rows for t in (r.get("diagnosis_seconds"), r.get("twin_diagnosis_seconds")) if t is not None]
    left = [r for r in effect_rows if r.get("gap_left", {}).get("left")]
    # an effect that left next to no gap divides by next to nothing: the mean is taken where it left a gap
    shrink_left = [x for r in left if (x := _shrinkage(r, "of_effect_gap")) is not None]
    return {
        "cases": len(rows),
        "effect_cases": len(effect_rows),
        "none_cases": len(none_rows),
        "top1_accuracy": float(np.mean([r["correct"] for r in effect_rows])) if effect_rows else None,
        "ranked_first_accuracy": float(np.mean([ranked_first(r) for r in effect_rows])) if effect_rows else None,
        "none_recognised": float(np.mean([r["named"] == NONE for r in none_rows])) if none_rows else None,
        "false_alarm_rate": float(np.mean([r["named"] != NONE for r in none_rows])) if none_rows else None,
        "mean_shrinkage_of_effect_gap": float(np.mean(shrink_left)) if shrink_left else None,
        "shrinkage_cases_gap_left": len(shrink_left),
        "median_shrinkage_of_effect_gap": float(np.median(shrink)) if shrink else None,
        "mean_shrinkage_of_total_gap": float(np.mean(total)) if total else None,
        "visible_effect_cases": len(visible),
        "top1_accuracy_visible": float(np.mean([r["correct"] for r in visible])) if visible else None,
        "gap_left_cases": len(left) if any("gap_left" in r for r in effect_rows) else None,
        "top1_accuracy_gap_left": float(np.mean([r["correct"] for r in left])) if left else None,
        # an effect case answered "not enough data to tell", and one where another effect was named
        "not_enough_data_rate": float(np.mean([r["named"] == NOT_ENOUGH_DATA for r in effect_rows]))
        if effect_rows
        else None,
        "wrong_effect_rate": float(np.mean([r["named"] not in (r["true"], NONE, NOT_ENOUGH_DATA) for r in effect_rows]))
        if effect_rows
        else None,
        # what a short site should answer: the effect, or that its weeks cannot tell
        "right_or_not_enough_data_rate": float(
            np.mean([r["named"] in (r["true"], NOT_ENOUGH_DATA) for r in effect_rows])
        )
        if effect_rows
        else None,
        "named_where_no_gap_left": {
            r["case"]: r["named"] for r in effect_rows if "gap_left" in r and not r["gap_left"]["left"]
        },
        "median_diagnosis_seconds": float(np.median(seconds)) if seconds else None,
        "labels": labels,
        "confusion": confusion,
    }


def _rediagnosed(
    out: Path, case: dict, row: dict, surrogate, settings: DiagnosisSettings, stand_in: StandIn, suite: bool
) -> dict:
    """A finished case diagnosed again (:func:`run_case`), a suite case's twin read back from its record."""
    if not suite:
        return run_case(out, case, surrogate, settings, stand_in)
    twin = {"selected": row["twin_named"], "heldout_base": row["twin_heldout_base"]}
    if "twin_diagnosis_seconds" in row:
        twin["diagnosis_seconds"] = row["twin_diagnosis_seconds"]
    return beyond_twin(run_case(out, case, surrogate, settings, stand_in, twin), twin)


def run_check(
    out: str | Path,
    cases: int,
    seed: int,
    surrogate=None,
    settings: DiagnosisSettings | None = None,
    building: str = "medium_office",
    epw: str = "usa_il_chicago",
    base_effects: str | list[str] = "auto",
    effects: tuple[str, ...] | None = None,
    progress: bool = False,
    known_parameters: dict[str, float] | None = None,
    weeks: int = WEEKS,
    matrix: str = "stand_in",
    part: str = "both",
) -> dict:
    """Run (or resume) a blind check and summarise it.

    Args:
        out: folder for the sites and per-case results.
        cases: number of cases.
        seed: seed of the plan (labels, magnitudes, periods, noise).
        surrogate: the metamodel (default: the shipped one).
        settings: diagnosis settings (``base_effects`` is set from ``base_effects``).
        building, epw: the reference building and weather of every case.
        base_effects: ``"auto"`` (diagnose a clean reference site first), or a list of known effects.
        effects: the effects injected (default: the whole catalogue).
        progress: progress bar over cases.
        known_parameters: building parameters every site declares known (:class:`StandIn`).
        weeks: weeks each site measures (split as ``settings.split`` says, :func:`buildenv.diagnosis.gap.split_weeks`).
        matrix: ``"stand_in"`` (every case of ``building`` in ``epw``, the stand-in's own effects from a clean
            reference site) or ``"suite"``: each case drawn from the suite's buildings, climates and seasons
            (:func:`plan_suite_cases`, ``part`` of it), diagnosed with no base effects and judged beyond its clean
            twin's own namings (:func:`beyond_twin`); the summary is given per part.
        part: with ``matrix="suite"``, ``development``, ``held_out`` or ``both``.
    Returns:
        ``{"summary": ..., "cases": [...], "base_effects": [...], "plan": {...}}``.
    """
    from tqdm import tqdm

    from buildenv.metamodel.surrogate import load_metamodel

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    surrogate = surrogate or load_metamodel("diagnosis")
    settings = settings or DiagnosisSettings()
    stand_in = StandIn(building, epw, dict(known_parameters or {}), weeks, settings.split)
    suite = matrix == "suite"
    if suite:
        known = []
    elif base_effects == "auto":
        known = known_effects(out, surrogate, settings, stand_in)
    else:
        known = [get_effect(e).name for e in base_effects]
    settings = DiagnosisSettings(**{**settings.__dict__, "base_effects": tuple(known)})
    plan = (
        plan_suite_cases(cases, seed, effects, weeks, part)
        if suite
        else plan_cases(cases, seed, tuple(known), effects, weeks)
    )
    rows = []
    for case in tqdm(plan, desc="blind cases", disable=not progress):
        path = out / f"case_{case['case']:03d}.json"
        if path.is_file():
            row = json.loads(path.read_text())
            # a record of the same case by this diagnosis (one from before its naming rules carries no "answer")
            same = {k: row.get(k) for k in case} == case
            if same and row.get("shrinkage") and "step" not in row["shrinkage"]:
                # its shrinkage credited the effects selected beside the injected one: diagnosed again
                row = _rediagnosed(out, case, row, surrogate, settings, stand_in, suite)
                path.write_text(_record(row) + "\n")
                rows.append(row)
                continue
            if same and ("answer" in row or row.get("status") == REFUSED):
                refused = row.get("status") == REFUSED
                if not refused and case["true"] != NONE and ("footprint" not in row or "gap_left" not in row):
                    # a case finished before footprints or the gap left after calibration were recorded
                    row["footprint"] = row.get("footprint") or footprint(out, case, stand_in)
                    if "gap_left" not in row:
                        row = _gap_left_row(out, case, row, surrogate, settings, stand_in)
                    path.write_text(_record(row) + "\n")
                rows.append(row)
                continue
        refused = _make_sites(out, case, stand_in) if suite else None
        if refused:
            row = {**case, "status": REFUSED, "reason": refused}
        elif suite:  # the twin first: the case's gap left reuses its base model
            twin = diagnose_twin(out, case, surrogate, settings, stand_in)
            row = beyond_twin(run_case(out, case, surrogate, settings, stand_in, twin), twin)
        else:
            row = run_case(out, case, surrogate, settings, stand_in)
        path.write_text(_record(row) + "\n")
        rows.append(row)
    labels = [NONE] + [e for e in (effects or EFFECTS) if e not in known]
    scored = [r for r in rows if r.get("status") != REFUSED]
    summary = summarise(scored, labels)
    if suite:
        # an effect its clean twin already names cannot be named beyond it: counted apart
        masked = [r for r in scored if r["true"] != NONE and r["true"] in r.get("twin_named", [])]
        summary["twin_names_the_injected_effect"] = {r["case"]: r["true"] for r in masked}
        rest = [r for r in scored if r["true"] != NONE and r not in masked]
        summary["top1_accuracy_beyond_masked"] = float(np.mean([r["correct"] for r in rest])) if rest else None
        summary["refused"] = {
            r["case"]: f"{r['building']} in {r['climate']}: {r['reason']}" for r in rows if r not in scored
        }
        summary["by_part"] = {
            name: summarise([r for r in scored if r["part"] == name], labels)
            for name in ("development", "held_out")
            if any(r["part"] == name for r in scored)
        }
    return {
        "summary": summary,
        "cases": rows,
        "base_effects": known,
        "plan": {
            "cases": cases,
            "seed": seed,
            "matrix": matrix,
            "part": part if suite else None,
            "building": None if suite else building,
            "epw": None if suite else epw,
            "weeks": weeks,
            "known_parameters": stand_in.known,
            "settings": {k: v for k, v in settings.__dict__.items() if k != "candidates"},
        },
    }
