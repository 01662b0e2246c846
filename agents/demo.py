"""``make demo``: the whole pipeline on the shipped default site, in about three minutes on 2 cores.

1. calibrate the shipped metamodel to a copy of the default site (CMA-ES; ``calibration.png``);
2. optimise one held-out week on ``BuildingWeek-v0``: the NSGA-II Pareto front and its point of equal
   comfort (the paper's choice), CMA-ES on the scalarised reward, the rule-based schedule;
3. run the historical and the chosen settings on the site's real-building EnergyPlus model;
4. diagnose the gap between the calibrated model and the site (:func:`buildenv.diagnosis.gap.diagnose`: where it
   misses, which unmodelled effect explains it; ``diagnosis.png``), without changing the site's model;
5. write ``report.md`` with ``pareto.png``, ``before_after.png`` and ``diagnosis.png``.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

from agents.report import markdown_table, plot_before_after, plot_pareto
from buildenv.jsonio import dumps

COLUMNS = [
    ("settings", "label", ""),
    ("energy vs historical", "energy_term", ".3f"),
    ("predicted savings %", "savings_percent", ".1f"),
    ("comfort K", "comfort_k", ".3f"),
    ("reward", "reward", ".3f"),
    ("evaluations", "evaluations", "d"),
    ("seconds", "seconds", ".1f"),
]


def _calibrate(site_dir: Path, seed: int, progress: bool) -> dict:
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.calibration.plot import plot_calibration
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site

    surrogate = load_metamodel()
    site = load_site(site_dir)
    result = calibrate_site(site, surrogate, method="cmaes", seed=seed, progress=progress)
    plot_calibration(load_site(site_dir), surrogate, result, site_dir / "calibration.png")
    return result


def _diagnose(site_dir: Path, out: Path, seed: int, progress: bool) -> dict:
    from buildenv.diagnosis.gap import DiagnosisSettings, diagnose
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site

    result = diagnose(
        load_site(site_dir),
        load_metamodel("diagnosis"),
        DiagnosisSettings(seed=seed),
        progress=progress,
        plot=out / "diagnosis.png",
    )
    result.pop("_fit")
    return result


def _diagnosis_text(d: dict) -> str:
    rows = [
        {
            "label": e["name"],
            "score": 100 * e["score"],
            "p": e["p_value"] if e["p_value"] is not None else float("nan"),
            "status": e["status"],
            "parameters": ", ".join(f"{k} {v:g}" for k, v in e["parameters"].items()),
        }
        for e in d["effects"]
    ]
    cols = [
        ("effect", "label", ""),
        ("held-out gain %", "score", ".1f"),
        ("p-value", "p", ".2g"),
        ("answer", "status", ""),
        ("estimated", "parameters", ""),
    ]
    text = f"Verdict: **{d['verdict']}** ({d['seconds']:.0f} s).\n\n{markdown_table(rows, cols)}"
    if d.get("heldout_after"):
        b, a = d["heldout_before"], d["heldout_after"]
        text += (
            f"\nWith {', '.join(d['selected'])} in the model, held-out CV(RMSE)_Q {b['cv_rmse_q_percent']:.1f} "
            f"-> {a['cv_rmse_q_percent']:.1f} %, RMSE_T {b['rmse_t_celsius']:.2f} -> {a['rmse_t_celsius']:.2f} "
            f"degC, R2_Q {b['r2_q']:.3f} -> {a['r2_q']:.3f}.\n"
        )
    loc = d["localisation"]
    return text + f"\nWhere it misses: {loc['temperature']['summary']} {loc['consumption']['summary']}\n"


def run_demo(out: Path, seed: int = 0, progress: bool = False) -> Path:
    """Run the demo into ``out`` and return the path of ``report.md``."""
    from agents.cli import default_week, make_env, optimise
    from agents.verify import verify
    from buildenv.env.actions import settings_table
    from buildenv.env.building_week import DEFAULT_SITE

    out = Path(out)
    started = time.perf_counter()
    site_dir = out / "site"
    if site_dir.exists():
        shutil.rmtree(site_dir)
    shutil.copytree(DEFAULT_SITE, site_dir, ignore=shutil.ignore_patterns("calibration.*"))
    calib = _calibrate(site_dir, seed, progress)

    env = make_env(str(site_dir))
    week = default_week(env)
    runs = {m: optimise(env, m, week, seed=seed, progress=progress) for m in ("nsga2", "cmaes", "rules")}
    chosen = runs["nsga2"]
    check = verify(env, week, chosen["action"])
    hist = chosen["historical"]
    rows = [{"label": "historical", **hist, "evaluations": None, "seconds": None}]
    names = {"nsga2": "NSGA-II, equal comfort", "cmaes": "CMA-ES, reward", "rules": "rule-based schedule"}
    rows += [
        {"label": names[m], **r["chosen"], "evaluations": r["evaluations"], "seconds": r["seconds"]}
        for m, r in runs.items()
    ]
    points = {row["label"]: (row["energy_term"], row["comfort_k"]) for row in rows}
    week_start = env.unwrapped.week_start(week)
    plot_pareto(chosen["front"], points, out / "pareto.png", f"week of {week_start}: energy vs comfort (metamodel)")
    plot_before_after(
        check, out / "before_after.png", title=f"week of {week_start}: historical vs NSGA-II equal-comfort settings"
    )
    s = check.summary
    summary = {
        "week": week,
        "week_start": week_start.isoformat(),
        "calibration": {k: calib[k] for k in ("fit", "heldout", "seconds", "evaluations")},
        "verification": s,
        "methods": {m: {k: v for k, v in r.items() if k not in ("action", "front", "pareto")} for m, r in runs.items()},
        "chosen_settings": settings_table(env.unwrapped.decode(chosen["action"])),
        "seconds_total": round(time.perf_counter() - started, 1),
    }
    diagnosis = _diagnose(site_dir, out, seed, progress)
    summary["diagnosis"] = {k: diagnosis[k] for k in ("verdict", "selected", "effects", "seconds")}
    summary["seconds_total"] = round(time.perf_counter() - started, 1)
    (out / "report.json").write_text(
        dumps(summary, where=str(out / "report.json"), nonfinite="null", indent=2, default=float)
    )
    held = calib["heldout"]
    text = f"""# buildenv demo: calibrate, optimise, verify

Site: `{site_dir}` (the shipped default: a DOE medium office in Chicago standing in for a real building).
Total time {summary["seconds_total"]:.0f} s.

## 1. Calibration (CMA-ES, {calib["evaluations"]} evaluations, {calib["seconds"]:.1f} s)
Held-out weeks {calib["heldout_weeks"]}: R2_T {held["r2_t"]:.3f}, R2_Q {held["r2_q"]:.3f}, RMSE_T
{held["rmse_t_celsius"]:.2f} degC, CV(RMSE)_Q {held["cv_rmse_q_percent"]:.1f} %, NMBE_Q {held["nmbe_q_percent"]:.1f} %
(ASHRAE Guideline 14 hourly limits: 30 % and 10 %).

![calibration](site/calibration.png)

## 2. Optimisation of the week of {week_start} (week {week} of the year), on the metamodel
{markdown_table(rows, COLUMNS)}
![Pareto front](pareto.png)

## 3. The chosen settings on the real building (EnergyPlus)
| | predicted (metamodel) | realised (EnergyPlus) |
|---|---|---|
| savings vs historical % | {s["predicted_savings_percent"]:.1f} | {s["realised_savings_percent"]:.1f} |
| comfort, historical settings (K) | {s["comfort_historical_predicted"]:.3f} | {s["comfort_historical"]:.3f} |
| comfort, chosen settings (K) | {s["comfort_chosen_predicted"]:.3f} | {s["comfort_chosen"]:.3f} |
| HVAC energy, historical (kWh) | {s["energy_historical_predicted_kwh"]:.0f} | {s["energy_historical_kwh"]:.0f} |
| HVAC energy, chosen (kWh) | {s["energy_chosen_predicted_kwh"]:.0f} | {s["energy_chosen_kwh"]:.0f} |

![before and after](before_after.png)

Chosen settings (Monday): {json.dumps(summary["chosen_settings"]["monday"])}

## 4. The sim-to-real gap: where the calibrated model misses and why
{_diagnosis_text(diagnosis)}
![diagnosis](diagnosis.png)
"""
    (out / "report.md").write_text(text)
    return out / "report.md"
