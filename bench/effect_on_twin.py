"""An injected effect's candidate tried on its blind case and on the case's clean twin.

A blind check (``bench/gap_check.py``) records how much of a case's held-out error its effect left after the
base calibration (``gap_left``), but not what the effect's candidate does where nothing was injected. This
script answers that for chosen cases: each case and its clean twin (same period, same sensor noise) are
calibrated as the diagnosis calibrates them (:func:`buildenv.gap.base_fit`, the blind check's settings), the
injected effect is added and refitted (:func:`buildenv.gap.refit`, its control alongside), and the held-out gain
is scored as the diagnosis scores it (the smaller of the gains against the control and against the refit with
the effect taken out). A candidate that gains about as much on the twin as on the case finds something the
clean building has too, and held-out attribution cannot tell the two apart. The page also lists the building
parameters that the base calibrations of case and twin put furthest apart (in shares of their ranges): where an
absorbed effect went, or parameters the fit weeks barely constrain (the cooling power in a heating season).

    .venv/bin/python bench/effect_on_twin.py --out out/diagnose-check-seed0-tb-16 --seed 0 --cases 3 \\
        --name effect_on_twin

With ``--model-side`` an effect carried by a building parameter (a heating capacity limit, night plug loads) is
taken too and refitted with its own model-side addition on top of the base calibration, as the diagnosis does
for a site that declares that parameter known (otherwise it judges such an effect by pinning the parameter).

``--out`` must hold the sites ``case_NNN`` and ``case_NNN_twin`` of that seed's plan (they are made when
missing, which runs EnergyPlus). Writes ``bench/results/<name>.{md,json}``; reruns add to the page.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from buildenv import calibration as cal
from buildenv import effects_model as em
from buildenv import gap
from buildenv.effects import get_effect
from buildenv.gap_check import NONE, StandIn, _site, plan_cases
from buildenv.site import load_site
from buildenv.surrogate import load_metamodel

RESULTS = Path(__file__).resolve().parent / "results"
BASE_EFFECTS = ("night_cycle_cold_air", "evening_departure")


def try_effect(site, effect: str, surrogate, settings: gap.DiagnosisSettings) -> dict:
    """Base model of ``site`` and the ``effect`` candidate refitted on it, scored on the held-out weeks
    (``baseline``: the model the gain was judged against, ``heldout_baseline`` its held-out metrics)."""
    ctx = gap._context(site, surrogate, gap.with_declared_effects(site, settings))
    base = gap.base_fit(ctx)
    ctx.sigma = gap.residual_sigma(ctx, base)
    control = gap.refit(ctx, base, None)
    trial = gap.refit(ctx, base, effect)
    k = len(em.none_parameters(effect))
    score = gap.stricter_score(gap.heldout_score(ctx, control, trial, k),
                               gap.heldout_score(ctx, gap.without_new_effect(base, trial), trial, k))
    return {"theta": base.params[:len(cal.free_theta())], "base_cost": base.cost, "gain": score["gain"],
            "gain_vs_control": score["gain_vs_control"], "p_value": score["p_value"],
            "estimate": trial.effect_parameters()[effect], "baseline": score["baseline"],
            "heldout_baseline": score["metrics_before"]}


def moved_most(case_theta: np.ndarray, twin_theta: np.ndarray, site, n: int = 3) -> list[dict]:
    """The ``n`` building parameters the two base calibrations put furthest apart, in shares of their ranges."""
    problem = cal.build_problem(site, [0])
    names = cal.free_theta()
    span = np.maximum(problem.hi[:len(names)] - problem.lo[:len(names)], 1e-12)
    move = (case_theta - twin_theta) / span
    order = np.argsort(-np.abs(move))[:n]
    return [{"parameter": names[i], "case": round(float(case_theta[i]), 3), "twin": round(float(twin_theta[i]), 3),
             "share_of_range": round(float(move[i]), 3)} for i in order]


def main() -> None:
    """Try each chosen case's effect on the case and its twin, and write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True, help="blind-check folder with the case and twin sites")
    parser.add_argument("--seed", type=int, required=True, help="seed of the check's plan")
    parser.add_argument("--cases", required=True, help="comma-separated case numbers (cases with an effect)")
    parser.add_argument("--plan-cases", type=int, default=16, help="cases of the check's plan")
    parser.add_argument("--weeks", type=int, default=8)
    parser.add_argument("--split", default="alternate")
    parser.add_argument("--name", default="effect_on_twin", help="stem of the result files")
    parser.add_argument("--model-side", action="store_true",
                        help="also take effects carried by a building parameter (heating capacity limit, night plug "
                        "loads), refitted with their own model-side addition on top of the base calibration, as "
                        "for a site that declares that parameter known")
    args = parser.parse_args()
    settings = gap.DiagnosisSettings(evaluations=1500, base_restarts=3, split=args.split, base_effects=BASE_EFFECTS)
    stand_in = StandIn(weeks=args.weeks, split=args.split)
    plan = plan_cases(args.plan_cases, args.seed, BASE_EFFECTS, None, args.weeks)
    numbers = [int(c) for c in args.cases.split(",")]
    for number in numbers:  # every case checked before any is run
        if not 0 <= number < len(plan):
            raise SystemExit(f"effect_on_twin: --cases {number}: the plan has cases 0-{len(plan) - 1}")
        effect = get_effect(plan[number]["true"]) if plan[number]["true"] != NONE else None
        if effect is None or (effect.building_parameter and not args.model_side) or effect.name == gap.HOLIDAYS:
            raise SystemExit(f"effect_on_twin: case {number} of seed {args.seed}: "
                             + ("no effect injected" if effect is None else f"{effect.name} is not refitted by the "
                                "diagnosis (carried by a building parameter: --model-side; or detected day by day)"))
    surrogate = load_metamodel()
    record_path = RESULTS / f"{args.name}.json"
    rows = json.loads(record_path.read_text())["rows"] if record_path.is_file() else []
    for number in numbers:
        case = plan[number]
        started = time.perf_counter()
        sites = {side: load_site(_site(Path(args.out), case, stand_in, inject=side == "case"))
                 for side in ("case", "twin")}
        tried = {f"on_{side}": try_effect(site, case["true"], surrogate, settings) for side, site in sites.items()}
        row = {"seed": args.seed, "case": number, "effect": case["true"], "magnitude": case["magnitude"],
               "start": case["start"], "seconds": round(time.perf_counter() - started, 1),
               "model_side": bool(get_effect(case["true"]).building_parameter),
               "moved_most": moved_most(tried["on_case"]["theta"], tried["on_twin"]["theta"], sites["case"])}
        for side, t in tried.items():
            row[side] = {k: v for k, v in t.items() if k != "theta"}
        rows = [r for r in rows if (r["seed"], r["case"]) != (args.seed, number)] + [row]
        sides = {s: (round(row[s]["gain"], 3), row[s]["estimate"]) for s in ("on_case", "on_twin")}
        print(json.dumps({k: row[k] for k in ("seed", "case", "effect")} | sides), flush=True)
        rows.sort(key=lambda r: (r["seed"], r["case"]))
        record_path.write_text(json.dumps(  # after every case, so that a stopped run keeps the cases it finished
            {"date": time.strftime("%Y-%m-%d"), "machine": platform.platform(),
             "settings": {"evaluations": settings.evaluations, "base_restarts": settings.base_restarts,
                          "split": settings.split, "weeks": args.weeks, "base_effects": list(settings.base_effects)},
             "rows": rows}, indent=1, default=float) + "\n")
    lines = [f"# An injected effect's candidate on its blind case and on the clean twin ({time.strftime('%Y-%m-%d')})",
             "", f"{platform.platform()}; `python bench/effect_on_twin.py --out DIR --seed S --cases N[,N...] --name "
             f"{args.name}{' --model-side' if args.model_side else ''}` once per seed (the blind checks' sites, gap_check_tb_seed*). Gain: share of the held-out "
             "standardised squared error the candidate removes, scored as the diagnosis scores it; the bar to name "
             f"an effect is {settings.min_gain:.0%}. `bench/effect_on_twin.py` states the method.", "",
             "| seed | case | effect | magnitude | first Monday | gain on the case | estimate | gain on the twin | "
             "estimate | base parameters furthest apart (case / twin) | seconds |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        est = {s: ", ".join(f"{v:.3g}" for v in r[s]["estimate"].values()) for s in ("on_case", "on_twin")}
        moved = "; ".join(f"{m['parameter']} {m['case']:g} / {m['twin']:g}" for m in r["moved_most"])
        lines.append(f"| {r['seed']} | {r['case']} | {r['effect']} | {r['magnitude']:.1f} | {r['start']} | "
                     f"{r['on_case']['gain']:+.3f} | {est['on_case']} | "
                     f"{r['on_twin']['gain']:+.3f} | {est['on_twin']} | "
                     f"{moved} | {r['seconds']:.0f} |")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
