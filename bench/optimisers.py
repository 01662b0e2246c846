"""The optimisers compared: NSGA-II, CMA-ES, PPO, the historical and a rule-based schedule on held-out weeks,
NSGA-II convergence, batched evaluation speed, and realised vs predicted savings on the real building.

    .venv/bin/python bench/optimisers.py [--weeks 44,45,46,47] [--policy out/ppo/ppo_default_seed0.zip]

Everything runs on ``BuildingWeek-v0`` with the shipped metamodel and calibrated default site; the held-out
weeks default to the env's ``test`` split (weeks 12-15, 28-31, 44-47). Writes ``bench/results/optimisers.md``
and ``.json``, ``optimisers_pareto_week46.png`` and ``optimisers_before_after_week46.png``.
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import time

import gymnasium as gym
import harness
import numpy as np
from harness import RESULTS

import buildenv  # noqa: F401
from agents.cli import optimise
from agents.nsga2 import hypervolume
from agents.report import markdown_table, plot_before_after, plot_pareto
from agents.verify import verify

PAPER_WEEK = 46  # the default site's first held-out measured week (2019-11-25)
METHODS = ("historical", "rules", "nsga2", "cmaes", "ppo")
LABELS = {
    "historical": "historical settings",
    "rules": "rule-based schedule",
    "nsga2": "NSGA-II, equal comfort",
    "cmaes": "CMA-ES, reward",
    "ppo": "PPO policy",
}


def evaluation_speed(env, n: int = 4096, repeats: int = 3) -> float:
    """Weeks per second of one batched ``evaluate`` call of ``n`` random actions (best of ``repeats``)."""
    actions = np.random.default_rng(0).uniform(-1, 1, (n, *env.action_space.shape)).astype(np.float32)
    env.unwrapped.evaluate(actions[:256], week=PAPER_WEEK)
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        env.unwrapped.evaluate(actions, week=PAPER_WEEK)
        best = min(best, time.perf_counter() - start)
    return n / best


def main() -> None:
    """Run the comparison and write the results."""
    parser = harness.parser(__doc__)
    parser.add_argument("--weeks", default=None, help="comma-separated weeks (default: the test split)")
    parser.add_argument("--policy", default=None, help="a trained PPO policy (agents.ppo) to include")
    parser.add_argument("--generations", type=int, default=1000)
    parser.add_argument(
        "--verify-weeks", default="44,45,46,47", help="weeks whose chosen settings are run on EnergyPlus"
    )
    args = parser.parse_args()
    env = gym.make("BuildingWeek-v0", weeks="all")
    weeks = (
        [int(w) for w in args.weeks.split(",")]
        if args.weeks
        else gym.make("BuildingWeek-v0", weeks="test").unwrapped.weeks
    )
    methods = [m for m in METHODS if m != "ppo" or args.policy]
    started = time.perf_counter()
    load = os.getloadavg()[0]
    speed = evaluation_speed(env)
    rows, per_week, fronts = [], {}, {}
    for week in weeks:
        per_week[week] = {}
        for method in methods:
            if method == "historical":
                base = env.unwrapped
                scores = base.evaluate(base.historical_action[None], week=week)
                r = {
                    "chosen": {k: float(v[0]) for k, v in scores.items() if np.ndim(v) == 1},
                    "evaluations": 0,
                    "seconds": 0.0,
                    "action": base.historical_action,
                }
            else:
                r = optimise(env, method, week, generations=args.generations, policy=args.policy)
            if method == "nsga2":
                fronts[week] = r["front"]
            c = r["chosen"]
            per_week[week][method] = {
                "energy_term": c["energy_term"],
                "comfort_k": c["comfort_k"],
                "reward": c["reward"],
                "savings_percent": c["savings_percent"],
                "evaluations": r["evaluations"],
                "seconds": r["seconds"],
                "hypervolume": (
                    fronts[week].hypervolume
                    if method == "nsga2"
                    else hypervolume(np.array([c["energy_term"]]), np.array([c["comfort_k"]]))
                ),
                "action": np.asarray(r["action"]).round(4).tolist(),
            }
    for method in methods:
        vals = [per_week[w][method] for w in weeks]
        rows.append(
            {
                "label": LABELS[method],
                **{
                    k: float(np.mean([v[k] for v in vals]))
                    for k in (
                        "energy_term",
                        "comfort_k",
                        "reward",
                        "savings_percent",
                        "hypervolume",
                        "evaluations",
                        "seconds",
                    )
                },
            }
        )
    checks = {}
    for week in [int(w) for w in args.verify_weeks.split(",") if int(w) in per_week]:
        for method in ("nsga2", "cmaes", "rules"):
            check = verify(env, week, np.asarray(per_week[week][method]["action"], dtype=np.float32))
            checks[f"{week}/{method}"] = check.summary
            if week == PAPER_WEEK and method == "nsga2":
                plot_before_after(
                    check,
                    RESULTS / f"optimisers_before_after_week{week}.png",
                    title=f"week {week}: historical vs NSGA-II equal-comfort settings",
                )
    if PAPER_WEEK in fronts:
        points = {
            LABELS[m]: (per_week[PAPER_WEEK][m]["energy_term"], per_week[PAPER_WEEK][m]["comfort_k"]) for m in methods
        }
        plot_pareto(
            fronts[PAPER_WEEK],
            points,
            RESULTS / f"optimisers_pareto_week{PAPER_WEEK}.png",
            f"week {PAPER_WEEK} (2019-11-25), default site, metamodel",
        )
    record = {
        "date": dt.date.today().isoformat(),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "command": "python bench/optimisers.py" + (f" --policy {args.policy}" if args.policy else ""),
        "weeks": weeks,
        "evaluate_weeks_per_second": round(speed, 1),
        "load_average_at_start": load,
        "generations": args.generations,
        "mean": rows,
        "per_week": per_week,
        "energyplus_checks": checks,
        "seconds_total": round(time.perf_counter() - started, 1),
    }
    RESULTS.mkdir(exist_ok=True)
    cols = [
        ("method", "label", ""),
        ("energy vs historical", "energy_term", ".3f"),
        ("predicted savings %", "savings_percent", ".1f"),
        ("comfort K", "comfort_k", ".3f"),
        ("reward", "reward", ".3f"),
        ("hypervolume", "hypervolume", ".3f"),
        ("evaluations", "evaluations", ".0f"),
        ("seconds per week", "seconds", ".1f"),
    ]
    check_rows = [{"label": k, **v} for k, v in checks.items()]
    check_cols = [
        ("week/method", "label", ""),
        ("predicted savings %", "predicted_savings_percent", ".1f"),
        ("realised savings %", "realised_savings_percent", ".1f"),
        ("comfort hist. predicted K", "comfort_historical_predicted", ".3f"),
        ("comfort hist. realised K", "comfort_historical", ".3f"),
        ("comfort chosen predicted K", "comfort_chosen_predicted", ".3f"),
        ("comfort chosen realised K", "comfort_chosen", ".3f"),
    ]
    text = f"""# Optimisers on BuildingWeek-v0

{record["seconds_total"]:.0f} s in all. NSGA-II: population 100, {args.generations}
generations per week (convergence: `nsga2_convergence.md`).
Default site (DOE medium office, Chicago, calibrated), shipped metamodel, comfort weight 1 per K, T* 22.5 degC.

## Held-out weeks {weeks} (means over weeks; each method optimises each week)
{markdown_table(rows, cols)}
Hypervolume against (1.5, 3.0 K) in the (energy vs historical, comfort) plane: the NSGA-II front's; for
single-setting methods, that of their one point.

## Batched evaluation
`env.unwrapped.evaluate` of 4,096 weekly settings in one call: {speed:,.0f} weeks/s (target 1,000).

## Realised on the real building (EnergyPlus reference model) vs predicted by the metamodel
{markdown_table(check_rows, check_cols)}
![Pareto front](optimisers_pareto_week{PAPER_WEEK}.png)
![before and after](optimisers_before_after_week{PAPER_WEEK}.png)
"""
    harness.write_results("optimisers", text, record, echo=True)


if __name__ == "__main__":
    main()
