"""PPO trained across the training weeks vs per-week CMA-ES vs the historical settings, on the held-out weeks.

PPO (:func:`agents.ppo.train_ppo`, the hyper-parameters of ``--variant``) learns one policy on the default
site's training weeks; on each held-out test week (12-15, 28-31, 44-47) its deterministic action is scored
and compared with CMA-ES run on that very week (:func:`agents.cmaes.optimise_week`, default budget of 6000
scored weeks, the reference optimum) and with the site's historical settings. Reported per week and on
average: reward, energy_term, comfort_k, the gap of PPO to CMA-ES in % of CMA-ES's reward, the time to
choose a week's settings (PPO: one policy forward pass; CMA-ES: its whole optimisation), PPO's training time.

    .venv/bin/python bench/ppo_vs_cmaes.py [--variant default] [--timesteps 400000] [--num-envs 256]
        [--seed 0] [--cmaes-evaluations 6000] [--model PATH] [--tag NAME]

``--model`` scores a saved policy instead of training one (no training time then). ``--variant`` picks one
of :data:`VARIANTS` (the settings tried while tuning; see the results file). Writes
``bench/results/ppo_vs_cmaes{_TAG}.{md,json}`` and the trained policy to ``out/ppo/ppo_{variant}.zip``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from agents.cmaes import optimise_week
from agents.ppo import PPO_DEFAULTS, evaluate_policy_weeks, load_policy, policy_actions, train_ppo

RESULTS = Path(__file__).resolve().parent / "results"
ROOT = Path(__file__).resolve().parent.parent
TERMS = ("reward", "energy_term", "comfort_k")

#: PPO settings tried (``train_ppo`` keyword arguments on top of :data:`agents.ppo.PPO_DEFAULTS`).
VARIANTS: dict[str, dict] = {
    "default": {},
}


class _Curve(BaseCallback):
    """Mean reward of each rollout's sampled (exploring) actions, and the policy's mean exploration std."""

    def __init__(self) -> None:
        super().__init__()
        self.points: list[dict] = []

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        std = float(torch.exp(self.model.policy.log_std).mean()) if hasattr(self.model.policy, "log_std") else 0.0
        self.points.append({"timesteps": int(self.num_timesteps),
                            "rollout_reward": float(self.model.rollout_buffer.rewards.mean()), "action_std": std})


def train_weeks_reward(model, env: gym.Env, weeks: list[int]) -> float:
    """Mean reward of the policy's deterministic actions over ``weeks`` (in-sample, for tuning)."""
    obs = np.stack([env.reset(options={"week": w})[0] for w in weeks])
    actions = policy_actions(model, obs)
    return float(np.mean([env.unwrapped.evaluate(actions[i:i + 1], week=w)["reward"][0]
                          for i, w in enumerate(weeks)]))


def scores_of(result) -> dict:
    """Reward terms of a week result."""
    return {k: float(result.scores[k]) for k in TERMS}


def main() -> None:
    """Train (or load) PPO, run CMA-ES and the historical settings on every test week, write the results."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variant", default="default", choices=sorted(VARIANTS))
    parser.add_argument("--timesteps", type=int, default=400_000, help="PPO training weeks")
    parser.add_argument("--num-envs", type=int, default=256, help="weeks stepped per PPO step (one model call)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cmaes-evaluations", type=int, default=6000)
    parser.add_argument("--model", type=Path, default=None, help="score this saved policy instead of training")
    parser.add_argument("--skip-cmaes", action="store_true", help="PPO and historical only (for tuning)")
    parser.add_argument("--tag", default="", help="suffix of the result files")
    args = parser.parse_args()

    variant = VARIANTS[args.variant]
    env = gym.make("BuildingWeek-v0", weeks="all")
    base = env.unwrapped
    test_weeks = gym.make("BuildingWeek-v0", weeks="test").unwrapped.weeks
    train_weeks = [w for w in base.weeks if w not in test_weeks]

    curve = _Curve()
    if args.model is None:
        import agents.ppo as ppo_module

        learn = ppo_module.PPO.learn

        def learn_with_curve(self, total_timesteps, callback=None, **kwargs):
            return learn(self, total_timesteps, callback=[curve] + ([callback] if callback else []), **kwargs)

        ppo_module.PPO.learn = learn_with_curve  # record the learning curve without touching train_ppo
        model_path = ROOT / "out" / "ppo" / f"ppo_{args.variant}.zip"
        started = time.perf_counter()
        model = train_ppo({}, timesteps=args.timesteps, num_envs=args.num_envs, seed=args.seed, save=model_path,
                          **variant)
        train_seconds = time.perf_counter() - started
        ppo_module.PPO.learn = learn
    else:
        model_path, model, train_seconds = args.model, load_policy(args.model), None

    ppo = {r.week: r for r in evaluate_policy_weeks(model, weeks=test_weeks, env=env)}
    in_sample = train_weeks_reward(model, env, train_weeks)
    hist_action = base.historical_action
    rows = []
    for week in test_weeks:
        hist = base.evaluate(hist_action[None], week=week)
        row = {"week": week, "week_start": base.week_start(week).isoformat(),
               "historical": {k: float(hist[k][0]) for k in TERMS},
               "ppo": {**scores_of(ppo[week]), "seconds": ppo[week].seconds}}
        if not args.skip_cmaes:
            cma = optimise_week(env, week, evaluations=args.cmaes_evaluations, seed=args.seed)
            row["cmaes"] = {**scores_of(cma), "seconds": cma.seconds, "evaluations": cma.evaluations}
            row["gap_percent"] = 100.0 * (cma.scores["reward"] - row["ppo"]["reward"]) / abs(cma.scores["reward"])
        rows.append(row)
        print(f"week {week}: " + ", ".join(f"{m} {row[m]['reward']:.4f}" for m in ("historical", "ppo", "cmaes")
                                           if m in row), file=sys.stderr, flush=True)

    methods = ["historical", "ppo"] + ([] if args.skip_cmaes else ["cmaes"])
    mean = {m: {k: float(np.mean([r[m][k] for r in rows])) for k in TERMS} for m in methods}
    for m in ("ppo", "cmaes"):
        if m in mean:
            mean[m]["seconds"] = float(np.mean([r[m]["seconds"] for r in rows]))
    summary = {"mean": mean, "train_weeks_deterministic_reward": in_sample}
    if not args.skip_cmaes:
        gaps = [r["gap_percent"] for r in rows]
        summary.update({
            "gap_percent_of_mean_reward": 100.0 * (mean["cmaes"]["reward"] - mean["ppo"]["reward"])
            / abs(mean["cmaes"]["reward"]),
            "gap_percent_mean_of_weeks": float(np.mean(gaps)), "gap_percent_worst_week": float(np.max(gaps)),
            "weeks_within_5_percent": int(sum(g <= 5.0 for g in gaps)),
            "inference_speedup": mean["cmaes"]["seconds"] / mean["ppo"]["seconds"],
        })
        summary["target_met"] = summary["gap_percent_of_mean_reward"] <= 5.0
    command = "PYTHONPATH=. .venv/bin/python bench/ppo_vs_cmaes.py " + " ".join(sys.argv[1:])
    result = {
        "date": dt.date.today().isoformat(), "command": command.strip(),
        "machine": {"platform": platform.platform(), "cores": os.cpu_count(), "gpu": torch.cuda.is_available(),
                    "torch": torch.__version__, "torch_threads": torch.get_num_threads()},
        "variant": args.variant, "ppo_settings": {**PPO_DEFAULTS, **variant}, "timesteps": args.timesteps,
        "num_envs": args.num_envs, "seed": args.seed, "model": str(model_path), "train_seconds": train_seconds,
        "cmaes_evaluations": args.cmaes_evaluations, "test_weeks": test_weeks, "summary": summary,
        "weeks": rows, "learning_curve": curve.points[:: max(1, len(curve.points) // 40)],
    }
    suffix = f"_{args.tag}" if args.tag else ""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"ppo_vs_cmaes{suffix}.json").write_text(json.dumps(result, indent=1, default=str) + "\n")
    if not args.skip_cmaes:
        (RESULTS / f"ppo_vs_cmaes{suffix}.md").write_text(markdown(result))
    print(json.dumps(summary, indent=1), flush=True)


def markdown(result: dict) -> str:
    """The results as a Markdown report."""
    s = result["summary"]
    m = s["mean"]
    lines = [
        f"# PPO across weeks vs per-week CMA-ES ({result['date']})", "",
        f"Machine: {result['machine']['platform']}, {result['machine']['cores']} cores, no GPU; torch "
        f"{result['machine']['torch']} ({result['machine']['torch_threads']} threads). "
        f"Command: `{result['command']}`.", "",
        f"PPO (variant `{result['variant']}`): {result['timesteps']} training weeks drawn from the default site's "
        f"training weeks, {result['num_envs']} environments per step, "
        + (f"trained in **{result['train_seconds']:.0f} s**" if result["train_seconds"] else "a saved policy")
        + f". CMA-ES: per week, {result['cmaes_evaluations']} scored weeks, population 64, from the historical "
        "settings. Reward = -(energy_term + comfort_k); energy_term = HVAC energy / the historical settings' "
        "(1.0 = today's), comfort_k = RMS deviation from 22.5 degC over occupied hours (K). Gap = "
        "(CMA-ES reward - PPO reward) / |CMA-ES reward|: positive when PPO is worse.", "",
        "| week | start | historical reward | CMA-ES reward | PPO reward | gap % | CMA-ES energy / comfort K "
        "| PPO energy / comfort K | CMA-ES s | PPO ms |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["weeks"]:
        h, c, p = r["historical"], r["cmaes"], r["ppo"]
        lines.append(f"| {r['week']} | {r['week_start']} | {h['reward']:.3f} | {c['reward']:.3f} | {p['reward']:.3f} "
                     f"| {r['gap_percent']:+.1f} | {c['energy_term']:.3f} / {c['comfort_k']:.3f} "
                     f"| {p['energy_term']:.3f} / {p['comfort_k']:.3f} | {c['seconds']:.1f} "
                     f"| {1000 * p['seconds']:.2f} |")
    lines.append(f"| **mean** | | {m['historical']['reward']:.3f} | {m['cmaes']['reward']:.3f} "
                 f"| {m['ppo']['reward']:.3f} | **{s['gap_percent_of_mean_reward']:+.1f}** "
                 f"| {m['cmaes']['energy_term']:.3f} / {m['cmaes']['comfort_k']:.3f} "
                 f"| {m['ppo']['energy_term']:.3f} / {m['ppo']['comfort_k']:.3f} | {m['cmaes']['seconds']:.1f} "
                 f"| {1000 * m['ppo']['seconds']:.2f} |")
    verdict = "met" if s["target_met"] else "NOT met"
    lines += [
        "", f"Target (PPO on held-out weeks within 5 % of per-week CMA-ES reward): **{verdict}**: gap of the "
        f"mean reward {s['gap_percent_of_mean_reward']:+.1f} % (mean of the weekly gaps "
        f"{s['gap_percent_mean_of_weeks']:+.1f} %, worst week {s['gap_percent_worst_week']:+.1f} %, "
        f"{s['weeks_within_5_percent']}/{len(result['weeks'])} weeks within 5 %). Choosing a week's settings: "
        f"PPO {1000 * m['ppo']['seconds']:.2f} ms (one policy forward pass) vs CMA-ES {m['cmaes']['seconds']:.1f} s "
        f"({result['cmaes_evaluations']} metamodel-scored weeks): **{s['inference_speedup']:.0f}x** less time. "
        f"PPO's deterministic reward on its training weeks: {s['train_weeks_deterministic_reward']:.3f}.", "",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
