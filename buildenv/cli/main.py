"""The ``buildenv`` command line.

Subcommands:
    catalogue   list the variable catalogue (names, units, ranges, steps, granularity)
    weather     list the shipped weather files, or summarise one
    morph-weather  write EPW files with shifted / stretched temperature, scaled solar and wind
    week        simulate one week of a building with EnergyPlus, print a summary and plot it
    simulate    run a simulation campaign into a dataset directory (parallel, resumable, Dask-capable)
    train       train a metamodel on campaigns' datasets
    evaluate    score a metamodel checkpoint on a dataset
    site        make a site from a reference building (`site reference`) or inspect one (`site show`)
    calibrate   calibrate the metamodel's building and occupancy to a site's measurements
    diagnose    where the calibrated model misses a site, and which unmodelled effect explains it
    diagnose-check  the diagnosis's blind check on sites with a withheld effect (or none) injected
    effects     list the unmodelled effects of the gap diagnosis
    optimize    (from the agents package) optimise a week's settings with NSGA-II, CMA-ES, PPO or rules
    demo        (from the agents package) what `make demo` runs: calibrate, optimise, verify, report
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.campaign.dataset import SPLITS
from buildenv.campaign.runs import MAX_FAILED_SHARE
from buildenv.campaign.sampling import FLOOR_AREA_SCALES
from buildenv.cli.argtypes import positive_int, positive_minutes, share
from buildenv.energyplus.shoebox import DEFAULT_ZONING, ZONINGS
from buildenv.errors import BuildenvError
from buildenv.jsonio import dumps
from buildenv.metamodel.surrogate import CONTEXT_HOURS
from buildenv.metamodel.threads import one_blas_thread


def _parse_assignments(items: list[str]) -> dict[str, float]:
    values: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise BuildenvError(f"--set {item!r}: expected NAME=VALUE")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise BuildenvError(f"--set {item!r}: {value!r} is not a number") from None
    return values


def _cmd_catalogue(args: argparse.Namespace) -> int:
    rows = cat.describe([args.group] if args.group else None)
    if args.json:
        print(dumps({"catalogue_hash": cat.catalogue_hash(), "variables": rows}, where="the catalogue", indent=2))
        return 0
    print(f"catalogue {cat.catalogue_hash()}")
    fmt = "{:<14} {:<32} {:>10} {:>9} {:>9} {:>7} {:<12} {}"
    print(fmt.format("group", "name", "unit", "min", "max", "step", "granularity", "paper name"))
    for r in rows:
        step = "" if r["step"] is None else f"{r['step']:g}"
        print(
            fmt.format(
                r["group"],
                r["name"],
                r["unit"],
                f"{r['min']:g}",
                f"{r['max']:g}",
                step,
                r["granularity"],
                r["paper_name"],
            )
        )
    return 0


def _cmd_weather(args: argparse.Namespace) -> int:
    from buildenv.weather.epw import load_weather, shipped_weather

    if not args.name:
        for name, path in shipped_weather().items():
            print(f"{name:<26} {path}")
        return 0
    w = load_weather(args.name)
    tamb = w.channel("TAMB")
    info = {
        "name": w.name,
        "path": str(w.path),
        "latitude_deg": w.latitude_deg,
        "longitude_deg": w.longitude_deg,
        "tamb_mean_c": round(float(tamb.mean()), 2),
        "tamb_min_c": float(tamb.min()),
        "tamb_max_c": float(tamb.max()),
        "ghi_annual_kwh_m2": round(float(w.channel("IGLOB_H").sum()) / 1000, 1),
    }
    print(dumps(info, where=f"the summary of {w.path}", indent=2))
    return 0


def _cmd_morph_weather(args: argparse.Namespace) -> int:
    from buildenv.weather.morph import MORPH_RANGES, Morph, morph_epw, morph_many

    fixed = {name: getattr(args, name) for name in MORPH_RANGES if getattr(args, name) is not None}
    if args.out:
        if len(args.epw) != 1:
            raise BuildenvError("--out writes one file: give one --epw, or use --out-dir for several")
        if args.seed is not None:
            raise BuildenvError("--seed draws random morphs into --out-dir; with --out give the values to change")
        records = [{"file": str(morph_epw(args.epw[0], args.out, Morph(**fixed))), "source": args.epw[0], **fixed}]
    elif args.out_dir:
        records = morph_many(args.epw, args.out_dir, 0 if args.seed is None else args.seed, **fixed)
    else:
        raise BuildenvError(
            "give --out FILE (one morph, the values given) or --out-dir DIR (a random morph per "
            "--epw, values not given drawn with --seed)"
        )
    print(dumps(records, where="the morphs", indent=2))
    return 0


def _simulate_one_week(epw: str, week: int, overrides: dict[str, float], out: Path, as_json: bool) -> int:
    from buildenv.defaults import DEFAULT_THETA, default_week
    from buildenv.energyplus.simulate import simulate_weeks
    from buildenv.metrics import week_summary
    from buildenv.plotting import plot_week
    from buildenv.schedules import hourly_schedules

    theta_values = dict(DEFAULT_THETA)
    settings, occupancy = default_week()
    for name, value in overrides.items():
        var = cat.get(name)
        if var.group == "theta_build":
            theta_values[var.name] = value
        elif var.group == "settings":
            var.check(value, f"--set {name}")
            settings[..., cat.SETTING_NAMES.index(var.name)] = value
        elif var.group == "occupancy":
            var.check(value, f"--set {name}")
            occupancy[..., cat.OCCUPANCY_NAMES.index(var.name)] = value
        else:
            raise BuildenvError(f"--set {name}: only theta_build, settings and occupancy variables can be set")
    theta = cat.from_mapping("theta_build", theta_values, where="--set")
    if not 0 <= week < cat.WEEKS_PER_YEAR:
        raise BuildenvError(f"--week {week}: weeks of the year run from 0 to {cat.WEEKS_PER_YEAR - 1}")
    result = simulate_weeks(theta, settings, occupancy, epw, week)
    sched = {k: v[0] for k, v in hourly_schedules(settings, occupancy).items()}
    area = float(theta[cat.THETA_NAMES.index("floor_area_m2")])
    summary = week_summary(result.outputs[0], sched["occupancy_fraction"], area)
    out.mkdir(parents=True, exist_ok=True)
    png = plot_week(
        result.outputs[0],
        result.weather[0],
        sched,
        out / "week.png",
        title=f"default building, {epw}, week {week} of the year ({area:.0f} m2)",
    )
    np.savez(
        out / "week.npz",
        outputs=result.outputs[0],
        weather=result.weather[0],
        theta=theta,
        settings=settings[0],
        occupancy=occupancy[0],
    )
    record = {
        "epw": epw,
        "week_of_year": week,
        "floor_area_m2": area,
        "summary": summary,
        "plot": str(png),
        "settings_every_day": dict(zip(cat.SETTING_NAMES, settings[0, 0].tolist())),
        "occupancy_every_weekday": dict(zip(cat.OCCUPANCY_NAMES, occupancy[0, 0].tolist())),
        "theta_build": dict(zip(cat.THETA_NAMES, theta.tolist())),
    }
    text = dumps(record, where="the simulated week", hint="EnergyPlus gave non-finite outputs", indent=2)
    (out / "week.json").write_text(text)
    if as_json:
        print(text)
    else:
        print(f"One simulated week: {epw}, week {week} of the year, {area:.0f} m2 office (EnergyPlus shoebox)")
        for key, value in summary.items():
            unit = "kWh" if key.endswith("_kwh") else "degC"
            print(f"  {key[:-4] if key.endswith('_kwh') else key:<28} {value:10.1f} {unit}")
        print(f"  plot: {png}")
    return 0


def _cmd_week(args: argparse.Namespace) -> int:
    return _simulate_one_week(args.epw, args.week, _parse_assignments(args.set), Path(args.out), args.json)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from buildenv.campaign.runs import DEFAULT_CLIMATES, CampaignConfig, run_campaign
    from buildenv.sites.suite import calibrated_buildings

    config = CampaignConfig(
        weeks=args.weeks,
        seed=args.seed,
        epw=args.epw or list(DEFAULT_CLIMATES),
        weeks_per_run=args.weeks_per_run,
        sampling=args.sampling,
        zoning=args.zoning,
        floor_area_scale=args.floor_area_scale,
        around=calibrated_buildings(args.around) if args.around else [],
        spread=args.spread,
        settings_draws=args.settings_draws,
    )
    path = run_campaign(
        config,
        Path(args.out),
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.quiet,
        max_failed_share=args.max_failed_share,
    )
    manifest = json.loads((Path(args.out) / "manifest.json").read_text())
    failed = manifest.get("failed_runs", [])
    for run in failed:
        print(
            f"buildenv simulate: run {run['run_id']} ({run['weeks']} weeks) left out: {run['error']}", file=sys.stderr
        )
    print(
        dumps(
            {
                "dataset": str(path),
                "weeks": manifest["weeks"],
                "runs": manifest["runs"],
                "failed_runs": len(failed),
                "seconds_last_session": manifest["seconds_last_session"],
            },
            where="the campaign summary",
        )
    )
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from buildenv.metamodel.training import train_metamodel

    try:
        config = json.loads(args.model_config) if args.model_config else None
    except json.JSONDecodeError:
        config = args.model_config  # not JSON: refused as not an object
    if config is not None and not isinstance(config, dict):
        raise BuildenvError(f"--model-config {args.model_config!r}: expected a JSON object, e.g. '{{\"layers\": 2}}'")
    if not Path(args.out).name:
        raise BuildenvError(f"--out {args.out!r}: expected the checkpoint's file path, e.g. out/model.pt")
    result = train_metamodel(
        args.data,
        args.model,
        Path(args.out),
        split=args.split,
        max_weeks=args.max_weeks,
        model_config=config,
        seed=args.seed,
        holdout_climates=args.holdout_climate,
        progress=not args.quiet,
        context_hours=args.context_hours,
        init=args.init,
        ground_temperature=not args.no_ground_temperature,
        temperature_before=args.temperature_before,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        schedule=args.schedule,
        patience=args.patience,
        device=args.device,
        minutes=args.minutes,
        response_weight=args.response_weight,
    )
    hint = f"the training diverged or the dataset holds non-finite values ({args.out} is saved)"
    print(dumps(result, where="the training result", hint=hint, indent=None if args.json else 2))
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from buildenv.metamodel.training import evaluate_metamodel

    result = evaluate_metamodel(args.checkpoint, args.data, subset=args.subset)
    hint = f"the metamodel's predictions or the outputs in {args.data} hold non-finite values"
    print(dumps(result, where="the evaluation result", hint=hint, indent=None if args.json else 2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``buildenv`` command."""
    parser = argparse.ArgumentParser(prog="buildenv", description=__doc__.split("\n\n")[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("catalogue", help="list the variable catalogue")
    p.add_argument("--group", choices=list(cat.GROUPS), help="only this group")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=_cmd_catalogue)

    p = sub.add_parser("weather", help="list shipped weather files or summarise one")
    p.add_argument("name", nargs="?", help="short name (usa_il_chicago) or EPW path")
    p.set_defaults(func=_cmd_weather)

    p = sub.add_parser(
        "morph-weather", help="write EPW files with shifted / stretched temperature, scaled solar and wind"
    )
    p.add_argument("--epw", nargs="+", required=True, help="weather short names or EPW paths to morph")
    p.add_argument("--out", default=None, help="the morphed EPW (one --epw; values not given are left unchanged)")
    p.add_argument(
        "--out-dir",
        default=None,
        help="one random morph per --epw into this directory, with morphs.json; values given are fixed",
    )
    p.add_argument("--seed", type=int, default=None, help="seed of the random morphs (--out-dir; default 0)")
    p.add_argument("--shift-k", dest="shift_k", type=float, default=None, help="K added to the dry bulb")
    p.add_argument("--stretch", type=float, default=None, help="factor on departures from the monthly mean")
    p.add_argument("--solar-scale", dest="solar_scale", type=float, default=None, help="factor on solar radiation")
    p.add_argument("--wind-scale", dest="wind_scale", type=float, default=None, help="factor on wind speed")
    p.set_defaults(func=_cmd_morph_weather)

    p = sub.add_parser("week", help="simulate one week of the default building (values overridable)")
    p.add_argument("--epw", default="usa_il_chicago", help="weather short name or EPW path")
    p.add_argument("--week", type=int, default=2, help="week of the year, 0-51 (weeks start Mondays)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a theta_build variable, or a setting/occupancy variable on every day",
    )
    p.add_argument("--out", default="out/week", help="directory for week.png, week.json, week.npz")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=_cmd_week)

    p = sub.add_parser("simulate", help="run a simulation campaign into a dataset directory")
    p.add_argument("--weeks", type=int, required=True, help="number of one-week samples")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="dataset directory (rerun the same command to resume)")
    p.add_argument("--epw", nargs="+", help="weather short names or EPW paths (default: all 16 shipped TMY3)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://host:8786")
    p.add_argument(
        "--weeks-per-run",
        type=int,
        default=cat.WEEKS_PER_YEAR,
        help=f"consecutive weeks per EnergyPlus run (1-{cat.WEEKS_PER_YEAR})",
    )
    p.add_argument("--sampling", choices=["uniform", "lhs"], default="uniform")
    p.add_argument(
        "--zoning",
        choices=list(ZONINGS),
        default=DEFAULT_ZONING,
        help="the simulated building: a core and four perimeter zones whose VAV systems night-cycle on the "
        "warmest one (five_zone), a core and a perimeter ring, or the paper's single zone",
    )
    p.add_argument(
        "--floor-area-scale",
        choices=list(FLOOR_AREA_SCALES),
        default="linear",
        help="draw the floor area evenly on the catalogue's grid (linear) or evenly in its logarithm (log: small "
        "offices as often as large ones)",
    )
    p.add_argument(
        "--around",
        action="append",
        metavar="DIR",
        help="draw the buildings around calibrated ones instead of over the catalogue: a calibrated site folder, or "
        "a suite folder (its development sites); repeatable",
    )
    p.add_argument(
        "--spread",
        type=share,
        default=0.1,
        help="with --around, each building parameter's random step as a share of its range (default 0.1)",
    )
    p.add_argument(
        "--settings-draws",
        type=positive_int,
        default=1,
        metavar="K",
        help="simulate each drawn building, weather and occupancy under K settings draws, so that `buildenv "
        "evaluate` can score the response to settings (default 1: every run drawn anew)",
    )
    p.add_argument(
        "--max-failed-share",
        type=share,
        default=MAX_FAILED_SHARE,
        help=f"share of runs EnergyPlus may refuse; they are left out and listed (default {MAX_FAILED_SHARE})",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("train", help="train a metamodel on one or more datasets")
    p.add_argument("--model", required=True, choices=["transformer", "bigru", "lstm", "convgru", "ffn"])
    p.add_argument(
        "--data",
        required=True,
        action="append",
        metavar="DIR",
        help="dataset directory; repeat it to train on several campaigns of one zoning together",
    )
    p.add_argument("--out", required=True, help="checkpoint path (rerun to resume from CKPT.last)")
    p.add_argument(
        "--split",
        default="weather_weeks",
        choices=list(SPLITS),
        help="weather_weeks: test weeks' weather never seen in training; buildings: test weeks' "
        "buildings never seen in training",
    )
    p.add_argument("--max-weeks", type=int, default=None, help="at most this many training weeks")
    p.add_argument(
        "--holdout-climate",
        action="append",
        default=None,
        metavar="WEATHER",
        help="keep this climate's weeks out of training and score them apart (repeatable)",
    )
    p.add_argument("--model-config", default=None, help="JSON keyword arguments of the model, e.g. '{\"layers\": 2}'")
    p.add_argument(
        "--context-hours",
        type=int,
        default=CONTEXT_HOURS,
        help=f"hours before each week the model sees, whole days (default {CONTEXT_HOURS}: the day before)",
    )
    p.add_argument(
        "--init",
        default=None,
        metavar="CKPT",
        help="fine-tune this checkpoint ('default': the shipped one), e.g. with a longer "
        "--context-hours; inputs it lacks are added",
    )
    p.add_argument(
        "--no-ground-temperature",
        action="store_true",
        help="leave the ground temperature under the slab out of the inputs",
    )
    p.add_argument(
        "--temperature-before",
        action="store_true",
        help="give the model the indoor temperature measured over the context hours (in training the "
        "previous week's simulated one, hidden on a quarter of the weeks); calibration feeds it "
        "the site's measured previous week (with --init, added to the checkpoint's inputs)",
    )
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--batch-size", type=int, default=64)
    p.add_argument("--lr", type=float, default=1e-3, help="initial learning rate of Adam")
    p.add_argument(
        "--schedule",
        default="cosine",
        choices=["cosine", "constant"],
        help="learning rate: cosine decay to 0 over --epochs, or constant",
    )
    p.add_argument("--patience", type=int, default=10, help="early stopping: epochs without improvement")
    p.add_argument(
        "--response-weight",
        type=float,
        default=0.0,
        help="weight of the savings error between a week and the same week under other settings (campaigns of "
        "`buildenv simulate --settings-draws`) beside the paper's loss (default 0: the paper's loss alone)",
    )
    p.add_argument(
        "--minutes",
        type=positive_minutes,
        default=None,
        help="a training-time budget (validation included): stop when it is spent, mid-epoch if need "
        "be, with the cosine decay spread over it instead of over --epochs",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default="auto", help="auto (CUDA when present), cpu, cuda")
    p.add_argument("--json", action="store_true", help="one-line JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("evaluate", help="score a metamodel checkpoint on a dataset")
    p.add_argument("--checkpoint", default="default", help="checkpoint path or 'default'")
    p.add_argument("--data", required=True, help="dataset directory")
    p.add_argument(
        "--subset",
        default="test",
        choices=["test", "holdout_climate", "all"],
        help="test: the checkpoint's held-out weeks when DATA is its training dataset; "
        "holdout_climate: the climates kept out of its training",
    )
    p.add_argument("--json", action="store_true", help="one-line JSON")
    p.set_defaults(func=_cmd_evaluate)

    from buildenv.cli.sites import register

    register(sub)
    from buildenv.cli.diagnosis import register as register_gap

    register_gap(sub)
    from buildenv.cli.effects import register as register_effects

    register_effects(sub)
    from buildenv.cli.suite import register as register_suite

    register_suite(sub)
    for plugin in sorted(entry_points(group="buildenv.commands"), key=lambda e: e.name):
        plugin.load()(sub)  # e.g. `optimize` and `demo` from the agents package
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``buildenv`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    try:
        with one_blas_thread():  # numpy's BLAS threads would fight the metamodel's (buildenv.metamodel.threads)
            return args.func(args)
    except BuildenvError as exc:
        print(f"buildenv {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print(f"buildenv {args.command}: interrupted; finished work is kept (rerun to resume)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
