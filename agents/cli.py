"""``buildenv optimize`` and ``buildenv demo``: subcommands that the agents package adds to the ``buildenv``
command (declared under the ``buildenv.commands`` entry point, so :mod:`buildenv` never imports agents)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from buildenv.cli.argtypes import positive_int, strict_calibration_argument
from buildenv.jsonio import dumps

METHODS = ("nsga2", "cmaes", "ppo", "rules")


def make_env(
    site: str, metamodel: str = "default", comfort_weight: float = 1.0, library_site: str | None = None, **kwargs
):
    """``BuildingWeek-v0`` on every week of a site (``"default"`` or a folder), or of one site of a library
    (``site`` ``"library"`` or a library folder, ``library_site`` the site's name), reset onto that site.

    Raises:
        buildenv.errors.BuildenvError: a library without ``library_site``, or ``library_site`` with a single site.
        buildenv.errors.BuildingEnvError: a ``library_site`` the library does not hold.
    """
    import gymnasium as gym

    import buildenv  # noqa: F401  (registers BuildingWeek-v0)
    from buildenv.env.contexts import is_set, listing
    from buildenv.errors import BuildenvError

    if not is_set(site) and library_site is not None:
        raise BuildenvError(f"--library-site {library_site}: --site {site} is one site, not a library")
    env = gym.make(
        "BuildingWeek-v0", site=site, metamodel=metamodel, comfort_weight=comfort_weight, weeks="all", **kwargs
    )
    names = env.unwrapped.site_names
    if is_set(site) and library_site is None:
        raise BuildenvError(
            f"--site {site} holds {len(names)} site(s); choose one with --library-site NAME ({listing(names)})"
        )
    if library_site is not None:
        env.reset(options={"site": library_site})
    return env


def default_week(env) -> int:
    """The week to optimise when none is given: the site's first held-out (not calibrated-on) measured week,
    else its last measured week."""
    from buildenv.env.response import first_heldout_week

    return first_heldout_week(env)


def optimise(
    env,
    method: str,
    week: int,
    seed: int = 0,
    evaluations: int = 6000,
    generations: int = 1000,
    population: int = 100,
    policy: str | None = None,
    progress: bool = False,
    site: str | int | None = None,
) -> dict:
    """Run one method on one week of one site; returns the chosen action, its scores and the method's figures.

    ``nsga2`` picks the front's point of equal comfort to the historical settings (the paper's choice);
    ``cmaes`` maximises the scalarised reward; ``ppo`` applies a trained policy (``policy`` path);
    ``rules`` is the rule-based schedule of :mod:`agents.rules`. With several sites (a list or a library) the
    environment is first reset onto ``site`` (name or index); without it, onto the current episode's site.

    Returns:
        ``{"method", "site", "week", "week_start", "seconds", "action" (A,), "chosen", "historical"
        (scalar scores), "predicted_savings_percent", "comfort_historical_predicted",
        "comfort_chosen_predicted"}`` and the method's ``"evaluations"`` (NSGA-II: also ``"hypervolume"``,
        ``"front"``, ``"pareto"``).
    Raises:
        SystemExit: an unknown method, or ``ppo`` without a ``policy``.
        buildenv.errors.BuildingEnvError: several sites, no ``site`` and no episode yet (or a site not among them).
    """
    from agents.cmaes import scalar_scores
    from buildenv.env.contexts import listing
    from buildenv.errors import BuildingEnvError

    base = env.unwrapped
    if not hasattr(base, "site_names") or hasattr(base, "num_envs"):
        raise BuildingEnvError(f"optimise: give a single BuildingWeek-v0 environment, not {type(base).__name__}")
    if site is not None:
        env.reset(options={"site": site})  # the methods score the given week, whatever weeks= lets episodes start on
    elif len(base.site_names) > 1 and base.week is None:
        raise BuildingEnvError(
            f"optimise: the environment has {len(base.site_names)} sites and no episode yet; give site= "
            f"({listing(base.site_names)}) or reset(options={{'site': ...}}) first"
        )
    hist = scalar_scores(base.evaluate(base.historical_action[None], week=week), 0)
    started = time.perf_counter()
    extra: dict = {}
    if method == "nsga2":
        from agents.nsga2 import equal_comfort_choice, pareto_front

        front = pareto_front(env, week, population=population, generations=generations, seed=seed, progress=progress)
        action = front.actions[equal_comfort_choice(front, hist["comfort_k"])]
        extra = {
            "hypervolume": front.hypervolume,
            "evaluations": front.evaluations,
            "front": front,
            "pareto": np.column_stack([front.energy_term, front.comfort_k]).round(4).tolist(),
        }
    elif method == "cmaes":
        from agents.cmaes import optimise_week

        result = optimise_week(env, week, evaluations=evaluations, seed=seed)
        action, extra = result.action, {"evaluations": result.evaluations}
    elif method == "ppo":
        from agents.ppo import load_policy, policy_actions

        if not policy:
            raise SystemExit(
                "buildenv optimize --method ppo: give --policy PATH (train a policy with agents.ppo.train_ppo)"
            )
        obs, _ = env.reset(options={"week": week, "site": base.site_name})
        action, extra = policy_actions(load_policy(policy), obs[None])[0], {"evaluations": 1}
    elif method == "rules":
        from agents.rules import rule_based_action

        action, extra = rule_based_action(env), {"evaluations": 1}
    else:
        raise SystemExit(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    seconds = time.perf_counter() - started
    chosen = scalar_scores(base.evaluate(np.asarray(action)[None], week=week), 0)
    return {
        "method": method,
        "site": base.site_name,
        "week": int(week),
        "week_start": base.week_start(week).isoformat(),
        "seconds": round(seconds, 2),
        "action": np.asarray(action, dtype=np.float32),
        "chosen": chosen,
        "historical": hist,
        "predicted_savings_percent": chosen["savings_percent"],
        "comfort_historical_predicted": hist["comfort_k"],
        "comfort_chosen_predicted": chosen["comfort_k"],
        **extra,
    }


def _public(result: dict, env) -> dict:
    """The JSON-able part of an :func:`optimise` result (settings by day and name)."""
    from buildenv.env.actions import settings_table

    out = {k: v for k, v in result.items() if k not in ("action", "front")}
    out["settings"] = settings_table(env.unwrapped.decode(result["action"]))
    return out


def _cmd_optimize(args: argparse.Namespace) -> int:
    env = make_env(
        args.site,
        args.metamodel,
        args.comfort_weight,
        library_site=args.library_site,
        strict_calibration=args.strict_calibration,
    )
    week = default_week(env) if args.week is None else args.week
    result = optimise(
        env,
        args.method,
        week,
        seed=args.seed,
        evaluations=args.evaluations,
        generations=args.generations,
        population=args.population,
        policy=args.policy,
        progress=not args.json,
    )
    out = _public(result, env)
    if args.verify:
        from agents.verify import verify

        out.update(verify(env, week, result["action"]).summary)
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        text = dumps(out, where="the optimisation", nonfinite="null", indent=2)
        name = env.unwrapped.site_name
        (Path(args.out) / f"optimize_{args.method}_{name}_week{week}.json").write_text(text)
    print(dumps(out, where="the optimisation", nonfinite="null", indent=None if args.json else 2))
    return 0


def _print_levers(rows: list[dict], week: int) -> None:
    """The lever check as a table, then the lever the model gets most wrong in one line."""
    print(
        f"{'setting':<22} {'end':<4} {'historical':>10} {'value':>6} {'savings predicted %':>20} {'realised %':>10} "
        f"{'shoebox %':>9} {'error':>6}"
    )
    for r in rows:
        shoebox = r.get("shoebox_savings_percent")
        print(
            f"{r['setting']:<22} {r['end']:<4} {r['historical']:>10.2f} {r['value']:>6.2f} "
            f"{r['predicted_savings_percent']:>20.1f} {r['realised_savings_percent']:>10.1f} "
            f"{'-' if shoebox is None else f'{shoebox:.1f}':>9} {r['savings_error_points']:>6.1f}"
        )
    if rows[0].get("baseline_shifted"):
        print(
            f"historical {', '.join(rows[0]['baseline_shifted'])} outside the BMS range or off its grid: each lever "
            "is measured from the historical settings with them at their nearest (percent of the historical energy)"
        )
    worst = max(rows, key=lambda r: abs(r["savings_error_points"]))
    print(
        f"week {week}: the lever most mispredicted is {worst['setting']} at its {worst['end']} end "
        f"({worst['savings_error_points']:+.1f} points: predicted {worst['predicted_savings_percent']:.1f} %, "
        f"realised {worst['realised_savings_percent']:.1f} %)"
    )


def _cmd_verify(args: argparse.Namespace) -> int:
    from buildenv.env.response import response_check

    env = make_env(
        args.site, args.metamodel, library_site=args.library_site, strict_calibration=args.strict_calibration
    )
    week = default_week(env) if args.week is None else args.week
    if args.levers:
        from buildenv.env.levers import lever_check

        rows = lever_check(env, week)
        if args.json:
            print(dumps({"week": week, "levers": rows}, where="the lever check", nonfinite="null"))
        else:
            _print_levers(rows, week)
        return 0
    check = response_check(env, week, n=args.random or 20, seed=args.seed)
    if args.json:
        print(dumps(check.summary, where="the response check", nonfinite="null"))
        return 0
    s, shoebox = check.summary, check.shoebox_savings
    print(
        f"{'setting':>7} {'savings predicted %':>20} {'realised %':>10} {'shoebox %':>9} "
        f"{'comfort predicted K':>20} {'realised K':>10}"
    )
    for i in range(len(check.actions)):
        print(
            f"{i:>7} {check.predicted_savings[i]:>20.1f} {check.realised_savings[i]:>10.1f} "
            f"{'-' if shoebox is None else f'{shoebox[i]:.1f}':>9} "
            f"{check.predicted_comfort[i]:>20.3f} {check.realised_comfort[i]:>10.3f}"
        )
    print(
        f"week {week}: savings error {s['savings_error_mean_abs_points']} points on average "
        f"({s['savings_error_p90_abs_points']} at the 90th percentile, bias {s['savings_bias_points']}), "
        f"Spearman {s['savings_spearman']}; comfort error {s['comfort_error_mean_abs_k']} K, "
        f"Spearman {s['comfort_spearman']}"
    )
    if shoebox is not None:
        print(
            f"split at the EnergyPlus shoebox of the calibrated parameters: metamodel - shoebox "
            f"{s['metamodel_vs_shoebox_p90_abs_points']} points at the 90th percentile (bias "
            f"{s['metamodel_vs_shoebox_bias_points']}), shoebox - building {s['shoebox_vs_building_p90_abs_points']} "
            f"(bias {s['shoebox_vs_building_bias_points']}, Spearman {s['shoebox_spearman']}); the shoebox "
            "lacks the declared effects"
        )
    for key, what in (
        ("savings_error_drivers", "the savings error"),
        ("metamodel_vs_shoebox_drivers", "metamodel - shoebox"),
        ("shoebox_vs_building_drivers", "shoebox - building"),
    ):
        if key in s:
            follows = ", ".join(f"{d['setting']} (Spearman {d['spearman']:+.2f})" for d in s[key]) or "no one setting"
            print(f"{what} follows {follows}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from agents.demo import run_demo

    report = run_demo(Path(args.out), seed=args.seed, progress=True)
    print(f"report: {report}")
    return 0


def _library_site_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--library-site",
        default=None,
        metavar="NAME",
        help="with --site a library ('library' or a folder holding library.toml): the site of it to use",
    )


def register(sub) -> None:
    """Add ``optimize``, ``verify`` and ``demo`` to the ``buildenv`` subcommands."""
    p = sub.add_parser("optimize", help="find the week's settings that save energy at equal comfort")
    p.add_argument("--method", required=True, choices=METHODS)
    p.add_argument("--site", default="default", help="calibrated site folder, 'default', or a library")
    _library_site_argument(p)
    p.add_argument(
        "--week",
        type=int,
        default=None,
        help="week of the site's year (0-based Mondays); default: its first held-out measured week",
    )
    p.add_argument("--metamodel", default="default", help="checkpoint path or 'default'")
    p.add_argument("--comfort-weight", type=float, default=1.0, help="w of reward = -(energy + w * comfort)")
    p.add_argument("--evaluations", type=int, default=6000, help="CMA-ES budget of scored weeks")
    p.add_argument("--generations", type=int, default=1000, help="NSGA-II generations")
    p.add_argument("--population", type=int, default=100, help="NSGA-II population")
    p.add_argument("--policy", default=None, help="trained PPO policy (for --method ppo)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--verify",
        action="store_true",
        help="run the historical and chosen settings on the site's EnergyPlus model (about 10 s)",
    )
    p.add_argument("--out", default=None, help="also write the JSON into this folder")
    p.add_argument("--json", action="store_true", help="one-line JSON, no progress bar")
    strict_calibration_argument(p)
    p.set_defaults(func=_cmd_optimize)

    p = sub.add_parser("verify", help="the response check: random settings on the metamodel and on EnergyPlus")
    p.add_argument(
        "--site", required=True, help="calibrated site folder made by `buildenv site reference`, or a library"
    )
    _library_site_argument(p)
    what = p.add_mutually_exclusive_group()
    what.add_argument("--random", type=positive_int, default=None, help="random settings to check (default 20)")
    p.add_argument("--week", type=int, default=None, help="week of the site's year; default its first held-out week")
    p.add_argument("--metamodel", default="default", help="checkpoint path or 'default'")
    p.add_argument("--seed", type=int, default=0, help="seed of the random settings")
    what.add_argument(
        "--levers",
        action="store_true",
        help="instead of random settings, each setting the BMS can change moved alone to either end of its range",
    )
    p.add_argument("--json", action="store_true", help="the summary as one JSON line")
    strict_calibration_argument(p)
    p.set_defaults(func=_cmd_verify)

    p = sub.add_parser("demo", help="the end-to-end pipeline on the default site: calibrate, optimise, verify, report")
    p.add_argument("--out", default="out/demo", help="folder of the report (report.md and PNGs)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=_cmd_demo)
