"""``buildenv diagnose`` and ``buildenv diagnose-check``: the sim-to-real gap diagnosis on the command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from buildenv.cli.argtypes import positive_int, strict_calibration_argument
from buildenv.diagnosis.effects import CHECKED_DIAGNOSIS, DIAGNOSIS_SPLITS
from buildenv.jsonio import dumps


def _settings(args: argparse.Namespace):
    from buildenv.diagnosis.effects import EFFECTS, get_effect
    from buildenv.diagnosis.gap import DiagnosisSettings

    candidates = (
        tuple(get_effect(e.strip()).name for e in args.candidates.split(",")) if args.candidates else tuple(EFFECTS)
    )
    step = {} if args.refit_step is None else {"refit_step": args.refit_step}
    if args.effect_first is not None:
        step["effect_first_evaluations"] = args.effect_first
    if args.refit_restarts is not None:
        step["refit_restarts"] = args.refit_restarts
    if args.refit_anchor is not None:
        step["refit_anchor"] = args.refit_anchor
    return DiagnosisSettings(
        candidates=candidates,
        evaluations=args.evaluations,
        **step,
        alpha=args.alpha,
        max_effects=args.max_effects,
        seed=args.seed,
        base_restarts=args.base_restarts,
        split=args.split,
        base_effects=tuple(getattr(args, "base_effect", None) or ()),
    )


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from buildenv.diagnosis.gap import diagnose, save_extended_model
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site

    site = load_site(args.site)
    # nothing goes into the site folder unless asked: the plot's default place is there only with --save
    plot = Path(args.plot) if args.plot else (Path(args.site) / "diagnosis.png" if args.save else None)
    settings = _settings(args)
    surrogate = load_metamodel(args.checkpoint)
    result = diagnose(
        site, surrogate, settings, progress=not args.quiet, plot=plot, strict_calibration=args.strict_calibration
    )
    saved = save_extended_model(site, result) if args.save else None
    result.pop("_fit")
    result["saved"] = str(saved) if saved else None
    text = dumps(result, where="the diagnosis", nonfinite="null", indent=None if args.json else 2, default=float)
    if args.out:
        Path(args.out).write_text(text + "\n")
    print(text, flush=True)
    print(_save_note(args, result, saved, plot), file=sys.stderr)
    return 0


def _save_note(args: argparse.Namespace, result: dict, saved: Path | None, plot: Path | None = None) -> str:
    """The last line of ``buildenv diagnose``: what it wrote (the extended model, the localisation plot), or how to
    make it do so."""
    plotted = f"; localisation plotted in {plot}" if plot else ""
    if saved:
        return f"saved: {saved} holds the extended model (the previous calibration under 'without_effects'){plotted}"
    if not result["selected"]:
        return f"no effect selected: the site's model in {args.site} left as it was{plotted}"
    return (
        f"not saved: {args.site} left as it was; rerun with --save to make the extended model "
        f"({', '.join(result['selected'])}) the site's model (calibration.json) and plot diagnosis.png there"
    )


def _cmd_diagnose_check(args: argparse.Namespace) -> int:
    from buildenv.cli.sites import parse_known
    from buildenv.diagnosis.blind_check import WEEKS, run_check
    from buildenv.metamodel.surrogate import load_metamodel

    base = "auto" if args.base_effects == "auto" else [e for e in args.base_effects.split(",") if e and e != "none"]
    result = run_check(
        args.out,
        args.cases,
        args.seed,
        load_metamodel(args.checkpoint),
        _settings(args),
        args.building,
        args.epw,
        base,
        progress=not args.quiet,
        known_parameters=parse_known(args.known),
        weeks=WEEKS if args.weeks is None else args.weeks,
        matrix=args.matrix,
        part=args.part,
    )
    (Path(args.out) / "check.json").write_text(
        dumps(result, where="the blind check", nonfinite="null", indent=1, default=float) + "\n"
    )
    shown = result if args.json else result["summary"]
    print(dumps(shown, where="the blind check", nonfinite="null", indent=None if args.json else 2, default=float))
    return 0


def _common(p: argparse.ArgumentParser) -> None:
    """The options ``diagnose`` and ``diagnose-check`` share. The split, base runs and most effects default to the
    blind checks' settings (``CHECKED_DIAGNOSIS``), so that the check checks what the diagnosis does."""
    p.add_argument(
        "--checkpoint",
        default="diagnosis",
        help="metamodel checkpoint, 'default' or 'diagnosis' (the one the blind checks ran with)",
    )
    p.add_argument("--candidates", default=None, help="comma-separated effects to try (default: all)")
    p.add_argument("--evaluations", type=positive_int, default=1500, help="CMA-ES evaluations per candidate refit")
    p.add_argument(
        "--refit-step",
        type=float,
        default=None,
        help="CMA-ES initial step of the building parameters in a refit (share of their ranges; default 0.25)",
    )
    p.add_argument(
        "--effect-first",
        type=int,
        default=None,
        metavar="EVALUATIONS",
        help="evaluations of a refit's first stage, the new effect alone (default 0: joint refit only)",
    )
    p.add_argument(
        "--refit-restarts",
        type=positive_int,
        default=None,
        help="CMA-ES runs of every refit (control and candidates), lowest fit cost kept (default 1)",
    )
    p.add_argument(
        "--refit-anchor",
        type=float,
        default=None,
        help="pull of every refit towards the model it starts from: weight of the squared move of "
        "its parameters, in units of their ranges, added to the fit cost (default 0: none)",
    )
    p.add_argument(
        "--split",
        choices=DIAGNOSIS_SPLITS,
        default=CHECKED_DIAGNOSIS["split"],
        help="fit weeks: the first half (held out: the rest; reuses the site's calibration) or every "
        "other week from the first (held out: the others), so both see the whole season's weather "
        "(default %(default)s)",
    )
    p.add_argument(
        "--base-restarts",
        type=positive_int,
        default=CHECKED_DIAGNOSIS["base_restarts"],
        help="CMA-ES runs of the base calibration (when the site has none for its fit weeks), "
        "lowest fit cost kept (default %(default)s)",
    )
    p.add_argument(
        "--alpha",
        type=float,
        default=0.05,
        help="significance level of each step, shared by its candidates (Bonferroni; default %(default)s)",
    )
    p.add_argument(
        "--max-effects",
        type=positive_int,
        default=CHECKED_DIAGNOSIS["max_effects"],
        help="most effects selected (default %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="one-line JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def register(sub) -> None:
    """Add ``diagnose`` and ``diagnose-check`` to the main parser's subparsers."""
    from buildenv.cli.sites import add_known_argument

    p = sub.add_parser(
        "diagnose",
        help="where the calibrated model misses a site, which unmodelled effect "
        "causes it, and how far the gap shrinks once it is added",
    )
    p.add_argument("--site", required=True, help="site folder")
    p.add_argument(
        "--base-effect",
        action="append",
        default=[],
        metavar="NAME",
        help="an effect the building is known to have (modelled from the start); repeatable",
    )
    p.add_argument("--plot", default=None, help="localisation PNG (default: SITE/diagnosis.png with --save, else none)")
    p.add_argument("--out", default=None, help="also write the JSON here")
    p.add_argument(
        "--save",
        action="store_true",
        help="make the extended model the site's model (SITE/calibration.json) and plot SITE/diagnosis.png; "
        "without it nothing is written into the site folder",
    )
    p.add_argument("--no-save", dest="save", action="store_false", help="the default: the site folder left as it is")
    strict_calibration_argument(p)
    _common(p)
    p.set_defaults(func=_cmd_diagnose)

    p = sub.add_parser(
        "diagnose-check",
        help="blind check: sites with a withheld effect (or none) injected, "
        "diagnosed, scored (confusion matrix, accuracy, shrinkage)",
    )
    p.add_argument("--cases", type=positive_int, default=16)
    p.add_argument("--out", default="out/diagnose-check", help="folder of the cases (a rerun resumes)")
    p.add_argument("--building", default="medium_office")
    p.add_argument("--epw", default="usa_il_chicago")
    p.add_argument(
        "--matrix",
        choices=("stand_in", "suite"),
        default="stand_in",
        help="stand_in: every case of --building in --epw; suite: each case a building, climate and season of the "
        "suite, judged beyond its clean twin's own namings, scored per part",
    )
    p.add_argument(
        "--part",
        choices=("development", "held_out", "both"),
        default="both",
        help="with --matrix suite: the suite's part to draw from (held_out: its held-out climates)",
    )
    p.add_argument(
        "--weeks",
        type=int,
        default=None,
        help="weeks each site measures (default: buildenv.diagnosis.blind_check.WEEKS; fit and held-out weeks: "
        "--split)",
    )
    p.add_argument(
        "--base-effects",
        default="auto",
        help="'auto' (diagnose a clean site of the building first), 'none', or comma-separated known effects",
    )
    add_known_argument(p)
    _common(p)
    p.set_defaults(func=_cmd_diagnose_check)
