"""``buildenv suite ...``: the matrix of reference-office stand-ins to develop against and judge on."""

from __future__ import annotations

import argparse
import sys

from buildenv.cli.argtypes import daily_weight_argument, positive_int
from buildenv.jsonio import dumps


def _split(text: str | None) -> list[str] | None:
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def _cases(args: argparse.Namespace):
    from buildenv.sites.suite import suite_cases

    return suite_cases(_split(args.buildings), _split(args.climates), _split(args.seasons))


def _cmd_suite_list(args: argparse.Namespace) -> int:
    from buildenv.sites.suite import SUITE_CLIMATES

    cases = _cases(args)
    if args.json:
        cases_json = [{"name": c.name, "part": c.part, "start": c.start().isoformat()} for c in cases]
        print(dumps(cases_json, where="the suite cases"))
        return 0
    print(f"{'case':<52} {'zone':<5} {'part':<12} start")
    for c in cases:
        print(f"{c.name:<52} {SUITE_CLIMATES[c.climate]:<5} {c.part:<12} {c.start()}")
    held = sum(c.part == "held_out" for c in cases)
    print(f"{len(cases)} cases, {held} held out")
    return 0


def _cmd_suite_make(args: argparse.Namespace) -> int:
    from buildenv.sites.suite import make_suite

    records = make_suite(
        args.out,
        _cases(args),
        weeks=args.weeks,
        workers=args.workers,
        suite_seed=args.seed,
        progress=not args.quiet,
        metering=args.meters,
    )
    made = sum(r["status"] in ("made", "reused") for r in records)
    for r in records:
        if r["status"] == "refused":
            print(f"refused {r['building']}-{r['climate']}-{r['season']}: {r['reason']}", file=sys.stderr)
    made_json = {"suite": args.out, "cases": len(records), "sites": made, "refused": len(records) - made}
    print(dumps(made_json, where="the suite"))
    return 0


def _cmd_suite_calibrate(args: argparse.Namespace) -> int:
    from buildenv.calibration.suite import calibrate_suite, summarise

    parts = ("development", "held_out") if args.part == "all" else (args.part,)
    rows = calibrate_suite(
        args.suite,
        parts,
        args.checkpoint,
        seed=args.seed,
        max_evaluations=args.evaluations,
        progress=not args.quiet,
        prior=not args.no_prior,
        daily_weight=args.daily_weight,
    )
    if args.json:
        print(dumps({"rows": rows, "summary": summarise(rows)}, where="the suite calibration", nonfinite="null"))
        return 0
    split = any("cv_rmse_e_percent" in r for r in rows)  # a second meter: its columns too
    second = f" {'CV_E %':>7} {'NMBE_E %':>8}" if split else ""
    print(f"{'site':<52} {'part':<12} {'CV_Q %':>7} {'NMBE_Q %':>8}{second} {'R2_T':>6} {'G14':>4} {'bounds':>6}")
    for r in rows:
        name = f"{r['building']}-{r['climate']}-{r['season']}"
        e = [r.get(k, float("nan")) for k in ("cv_rmse_e_percent", "nmbe_e_percent")]
        second = f" {e[0]:>7.1f} {e[1]:>8.1f}" if split else ""
        print(
            f"{name:<52} {r['part']:<12} {r['cv_rmse_q_percent']:>7.1f} {r['nmbe_q_percent']:>8.1f}{second} "
            f"{r['r2_t']:>6.3f} {'yes' if r['guideline14'] else 'no':>4} {r['at_bounds']:>6}"
        )
    for part, s in summarise(rows).items():
        print(
            f"{part}: {s['sites']} sites, Guideline 14 met by {s['guideline14_share']:.0%}, "
            f"CV <= 15 % and |NMBE| <= 5 % by {s['tight_share']:.0%}, R2_T >= 0.9 by {s['r2_t_above_0_9_share']:.0%}, "
            f"{s['mean_at_bounds']} parameters at a bound on average"
        )
    return 0


def _cmd_suite_verify(args: argparse.Namespace) -> int:
    from buildenv.env.response import check_suite
    from buildenv.sites.suite import failed_sites

    parts = ("development", "held_out") if args.part == "all" else (args.part,)
    rows = check_suite(
        args.suite, parts, n=args.random, seed=args.seed, metamodel=args.metamodel, progress=not args.quiet
    )
    errors = failed_sites(args.suite, "response.json")
    if args.json:
        print(dumps({"rows": rows, "errors": errors}, where="the response check", nonfinite="null"))
        return _report_failed(errors, "response.json", quiet=True)
    print(f"{'site':<52} {'part':<12} {'error p90':>9} {'bias':>6} {'Spearman':>8} {'comfort K':>9}")
    for r in rows:
        name = f"{r['building']}-{r['climate']}-{r['season']}"
        print(
            f"{name:<52} {r['part']:<12} {r['savings_error_p90_abs_points']:>9.1f} {r['savings_bias_points']:>6.1f} "
            f"{r['savings_spearman']:>8.2f} {r['comfort_error_mean_abs_k']:>9.3f}"
        )
    met = sum(r["meets_target"] for r in rows)
    print(f"{met} of {len(rows)} sites within 5 points at the 90th percentile with Spearman >= 0.9")
    return _report_failed(errors, "response.json")


def _report_failed(errors: list[dict], results: str, quiet: bool = False) -> int:
    """Name on stderr the sites a suite check could not check (unless ``quiet``); the exit status: 1 if any."""
    if errors and not quiet:
        print(f"{len(errors)} site(s) could not be checked (errors in {results}):", file=sys.stderr)
        for e in errors:
            print(f"  {e['building']}-{e['climate']}-{e['season']}: {e['error']}", file=sys.stderr)
    return 1 if errors else 0


def _cmd_suite_levers(args: argparse.Namespace) -> int:
    from buildenv.env.levers import check_suite_levers, grouping, summarise_levers
    from buildenv.sites.suite import failed_sites

    parts = ("development", "held_out") if args.part == "all" else (args.part,)
    by = grouping(args.by)
    rows = check_suite_levers(args.suite, parts, metamodel=args.metamodel, progress=not args.quiet)
    errors = failed_sites(args.suite, "levers.json")
    summary = summarise_levers(rows, by)
    if args.json:
        print(dumps({"rows": rows, "summary": summary, "errors": errors}, where="the lever check", nonfinite="null"))
        return _report_failed(errors, "levers.json", quiet=True)
    print(
        f"{' '.join(by):<28} {'setting':<22} {'end':<4} {'sites':>5} {'error':>6} {'|error|':>7} "
        f"{'shoebox - building':>18}"
    )
    for s in summary:
        split = s.get("shoebox_vs_building_median_points")
        print(
            f"{' '.join(s[k] for k in by):<28} {s['setting']:<22} {s['end']:<4} {s['sites']:>5} "
            f"{s['error_median_points']:>6.1f} {s['error_median_abs_points']:>7.1f} "
            f"{'-' if split is None else f'{split:.1f}':>18}"
        )
    print("medians over the sites, in points of savings (predicted - realised); written to levers.json")
    return _report_failed(errors, "levers.json")


def _cmd_suite_library(args: argparse.Namespace) -> int:
    from buildenv.sites.library import write_library

    buildings = [b for b in (args.buildings or "").split(",") if b] or None
    summary = write_library(args.suite, args.out, n_sites=args.sites, progress=not args.quiet, buildings=buildings)
    print(dumps(summary, where="the library"))
    return 0


def register(sub) -> None:
    """Add the ``suite`` subcommands to the main parser's subparsers."""
    from buildenv.sites.suite import SUITE_WEEKS

    suite = sub.add_parser("suite", help="the matrix of reference-office sites (offices x climates x seasons)")
    suite_sub = suite.add_subparsers(dest="suite_command", required=True)
    for name, helptext, func in (
        ("list", "list the suite's cases and which are held out", _cmd_suite_list),
        ("make", "run every case's stand-in and write its site folder (resumable)", _cmd_suite_make),
    ):
        p = suite_sub.add_parser(name, help=helptext)
        p.add_argument("--buildings", default=None, help="comma-separated reference offices (default: all six)")
        p.add_argument("--climates", default=None, help="comma-separated weather short names (default: the suite's)")
        p.add_argument("--seasons", default=None, help="heating, cooling or both (default)")
        p.set_defaults(func=func)
        if name == "list":
            p.add_argument("--json", action="store_true", help="one JSON list")
        else:
            p.add_argument("--out", required=True, help="suite folder (one site folder per case, suite.json)")
            p.add_argument("--weeks", type=int, default=SUITE_WEEKS, help="measured weeks per site")
            p.add_argument("--workers", type=int, default=None, help="EnergyPlus processes (default: the CPUs)")
            p.add_argument("--seed", type=int, default=0, help="seed of the BMS histories and the sensor noise")
            p.add_argument(
                "--meters",
                default="one",
                choices=["one", "split"],
                help="one meter a site (default) or heat and electricity metered apart",
            )
            p.add_argument("--quiet", action="store_true", help="no progress bar")
    p = suite_sub.add_parser("calibrate", help="calibrate every made site (held-out weeks scored), one table")
    p.add_argument("--suite", required=True, help="suite folder (buildenv suite make --out)")
    p.add_argument("--part", default="all", choices=["all", "development", "held_out"], help="which sites")
    p.add_argument("--checkpoint", default=None, help="metamodel checkpoint (default: the shipped one)")
    p.add_argument("--evaluations", type=int, default=6000, help="CMA-ES budget of cost evaluations per site")
    p.add_argument("--seed", type=int, default=0, help="seed of CMA-ES")
    p.add_argument("--no-prior", action="store_true", help="least squares only (as buildenv calibrate --no-prior)")
    daily_weight_argument(p)
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_suite_calibrate)
    p = suite_sub.add_parser("verify", help="the response check on every calibrated site (runs EnergyPlus)")
    p.add_argument("--suite", required=True, help="suite folder (calibrated by buildenv suite calibrate)")
    p.add_argument("--part", default="held_out", choices=["all", "development", "held_out"], help="which sites")
    p.add_argument("--random", type=positive_int, default=20, help="random settings per site")
    p.add_argument("--metamodel", default="default", help="checkpoint path or 'default'")
    p.add_argument("--seed", type=int, default=0, help="seed of the random settings")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_suite_verify)
    p = suite_sub.add_parser(
        "levers", help="each setting moved alone on every calibrated site: model against building (runs EnergyPlus)"
    )
    p.add_argument("--suite", required=True, help="suite folder (calibrated by buildenv suite calibrate)")
    p.add_argument("--part", default="development", choices=["all", "development", "held_out"], help="which sites")
    p.add_argument("--metamodel", default="default", help="checkpoint path or 'default'")
    p.add_argument(
        "--by", default="season", help="case fields the medians group sites by, comma-separated (e.g. building,season)"
    )
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_suite_levers)
    p = suite_sub.add_parser(
        "library", help="copy calibrated sites into a library for BuildingWeek-v0 (site=DIR or 'library')"
    )
    p.add_argument("--suite", required=True, help="suite folder (calibrated by buildenv suite calibrate)")
    p.add_argument("--out", required=True, help="library folder (buildenv/data/sites/library is site='library')")
    p.add_argument("--sites", type=int, default=None, help="how many sites, both parts in proportion (default: all)")
    p.add_argument(
        "--buildings",
        default=None,
        metavar="A,B",
        help="only these buildings, e.g. small_office,medium_office,large_office (one action space: the 2004 "
        "offices share their BMS limits, the 2019 ones fix their outdoor air)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_suite_library)
