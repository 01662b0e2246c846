"""The suite calibrated and checked with the unchanged commands: Guideline 14 and the response to settings.

Makes the suite (``buildenv suite make``: the six reference offices x seven climates x a heating and a cooling
season, 8 weeks each under BMS histories that change week to week; resumable) and calibrates every site it could
make (``buildenv suite calibrate``: the default calibration, first half fitted, second half held out). The
development part and the held-out climates (Phoenix, Newark) are reported apart; the held-out part is what the
any-office targets are judged on. With ``--random N`` (default 20) the response check (``buildenv suite verify``)
runs N random settings on each held-out site's calibrated metamodel and on its EnergyPlus model, and beside them
NSGA-II's point of equal comfort (``--generations``, 0: none): its predicted savings against those realised.
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import harness
import numpy as np

from buildenv.calibration.suite import TIGHT_CV_PERCENT, TIGHT_NMBE_PERCENT, calibrate_suite, summarise
from buildenv.env.response import TARGET_CHOSEN_POINTS, TARGET_P90_POINTS, TARGET_SPEARMAN, check_suite
from buildenv.metrics import GUIDELINE14_HOURLY_CV_PERCENT, GUIDELINE14_HOURLY_NMBE_PERCENT
from buildenv.sites.suite import HELD_OUT_CLIMATES, failed_sites, make_suite, suite_cases


def _table(rows: list[dict]) -> list[str]:
    split = any("cv_rmse_e_percent" in r for r in rows)
    extra = " electricity CV / NMBE % | the sum CV / NMBE % |" if split else ""
    lines = [
        "| site | CV(RMSE)_Q % | NMBE_Q % |" + extra + " R2_T | RMSE_T K | Guideline 14 | at a bound | s |",
        "|---|---|---|" + ("---|---|" if split else "") + "---|---|---|---|---|",
    ]
    for r in rows:
        meters = ""
        if split:
            keys = ("cv_rmse_e", "nmbe_e", "cv_rmse_total", "nmbe_total")
            cells = [r.get(f"{k}_percent", float("nan")) for k in keys]
            meters = f" {cells[0]:.1f} / {cells[1]:.1f} | {cells[2]:.1f} / {cells[3]:.1f} |"
        lines.append(
            f"| {r['building']} {r['climate']} {r['season']} | {r['cv_rmse_q_percent']:.1f} | "
            f"{r['nmbe_q_percent']:.1f} |{meters} {r['r2_t']:.3f} | {r['rmse_t_celsius']:.2f} | "
            f"{'yes' if r['guideline14'] else 'no'} | {r['at_bounds']} | {r['seconds']:.0f} |"
        )
    return lines


def _refusals(refused: list[dict]) -> list[str]:
    """One line per building and reason, the cases it refused counted (paths and EnergyPlus detail left out)."""
    groups: dict[tuple[str, str], list[str]] = {}
    for r in refused:
        reason = re.sub(r"\S*/", "", r["reason"])  # no folders
        reason = re.sub(r"^site\.toml:\d+: ", "", reason).split(" | ")[0][:200]
        groups.setdefault((r["building"], reason), []).append(f"{r['climate']} {r['season']}")
    return [f"- {b} ({len(cases)} of its cases): {reason}" for (b, reason), cases in groups.items()]


def render(record: dict, random: int) -> list[str]:
    """The page of a run's record."""
    made, rows, response, summary = record["made"], record["rows"], record["response"], record["summary"]
    refused = [r for r in made if r["status"] == "refused"]
    lines = [
        "# The suite calibrated and checked: Guideline 14 and the response to settings",
        "",
        f"{len(made)} cases, {len(made) - len(refused)} sites made, {len(refused)} refused; held-out climates: "
        f"{', '.join(HELD_OUT_CLIMATES)}. Making took {record['make_seconds'] / 60:.1f} min (EnergyPlus, sites "
        f"already made reused), "
        + (
            "calibrations read back from an earlier run"
            if record.get("calibrations_read_back")
            else f"calibrating {record['calibrate_seconds'] / 60:.1f} min"
        )
        + ". Guideline 14 hourly: "
        f"CV(RMSE)_Q <= {GUIDELINE14_HOURLY_CV_PERCENT:.0f} % and |NMBE_Q| <= {GUIDELINE14_HOURLY_NMBE_PERCENT:.0f} %;"
        f" the tighter band: {TIGHT_CV_PERCENT:.0f} % and {TIGHT_NMBE_PERCENT:.0f} %. All figures on held-out weeks."
        + (
            " Heat and electricity metered apart (`--meters split`): a site meets Guideline 14 when both meters do;"
            " the sum of the two is scored too."
            if record.get("meters") == "split"
            else ""
        )
        + f" Metamodel: {record.get('checkpoint', 'default')}; calibration "
        f"{'under the building parameters prior (the default)' if record.get('prior') else 'by least squares'}.",
        "",
        "| part | sites | Guideline 14 | tighter band | R2_T >= 0.9 | at a bound (mean) | s a site (median) |",
        "|---|---|---|---|---|---|---|",
    ]
    for part, s in summary.items():
        lines.append(
            f"| {part} | {s['sites']} | {s['guideline14_share']:.0%} | {s['tight_share']:.0%} | "
            f"{s['r2_t_above_0_9_share']:.0%} | {s['mean_at_bounds']} | {s['median_seconds']} |"
        )
    failed = record.get("response_errors") or []
    if failed:
        lines += [
            "",
            f"The response check could not check {len(failed)} held-out site(s): "
            + "; ".join(f"{e['building']} {e['climate']} {e['season']}: {e['error']}" for e in failed),
        ]
    if response:
        met = sum(r["meets_target"] for r in response)
        lines += [
            "",
            "## The response check, held-out sites",
            "",
            f"{random} random settings on each site's first held-out week, through the calibrated metamodel "
            f"and the site's EnergyPlus model ({record['response_seconds'] / 60:.1f} min"
            f"{', NSGA-II included' if record.get('generations') else ''}): savings against the "
            f"historical settings, predicted - realised, in points. {met} of {len(response)} sites within "
            f"{TARGET_P90_POINTS:.0f} points at the 90th percentile with Spearman >= {TARGET_SPEARMAN}. The same "
            "settings on the EnergyPlus shoebox at the calibrated parameters split the error: the metamodel against "
            "its shoebox, the shoebox against the building (p90 of the absolute, and bias; declared effects, which the "
            "shoebox lacks, count in the first).",
            "",
        ]
        chosen = [r for r in response if "chosen" in r]
        if chosen:
            met_chosen = sum(r["chosen_meets_target"] for r in chosen)
            lines += [
                f"NSGA-II's point of equal comfort ({record['generations']} generations of 100 on the calibrated "
                f"metamodel), run on the same week: realised within {TARGET_CHOSEN_POINTS:.0f} points of its "
                f"predicted savings on {met_chosen} of {len(chosen)} sites.",
                "",
                "| site | predicted savings % | realised % | error points | comfort predicted / realised K |",
                "|---|---|---|---|---|",
            ]
            for r in chosen:
                c = r["chosen"][0]
                lines.append(
                    f"| {r['building']} {r['climate']} {r['season']} | {c['predicted_savings_percent']:.1f} | "
                    f"{c['realised_savings_percent']:.1f} | {c['savings_error_points']:.1f} | "
                    f"{c['predicted_comfort_k']:.3f} / {c['realised_comfort_k']:.3f} |"
                )
            lines.append("")
        lines += [
            "| site | error mean abs | error p90 | bias | Spearman | comfort error K | comfort Spearman "
            "| metamodel - shoebox p90 / bias | shoebox - building p90 / bias |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in response:
            split = [
                f"{r[f'{k}_p90_abs_points']:.1f} / {r[f'{k}_bias_points']:.1f}" if f"{k}_p90_abs_points" in r else "-"
                for k in ("metamodel_vs_shoebox", "shoebox_vs_building")
            ]
            lines.append(
                f"| {r['building']} {r['climate']} {r['season']} | {r['savings_error_mean_abs_points']:.1f} | "
                f"{r['savings_error_p90_abs_points']:.1f} | {r['savings_bias_points']:.1f} | "
                f"{r['savings_spearman']:.2f} | {r['comfort_error_mean_abs_k']:.3f} | {r['comfort_spearman']:.2f} | "
                f"{split[0]} | {split[1]} |"
            )
    for part in ("held_out", "development"):
        lines += [
            "",
            f"## Calibration, {part.replace('_', '-')} sites",
            "",
            *_table([r for r in rows if r["part"] == part]),
        ]
    if refused:
        lines += ["", "## Refused", "", *_refusals(refused)]
    return lines


def _nsga2_choice(generations: int):
    """``(env, week) -> (1, A)``: NSGA-II's point of equal comfort to the historical settings on the week."""
    from agents.cli import optimise

    return lambda env, week: np.asarray(optimise(env, "nsga2", week, generations=generations)["action"])[None]


def main() -> None:
    p = harness.parser(__doc__, first_line=True)
    p.add_argument("--suite", default="out/suite", help="suite folder (made or reused)")
    p.add_argument("--workers", type=int, default=None, help="EnergyPlus processes (default: the CPUs)")
    p.add_argument("--evaluations", type=int, default=6000, help="CMA-ES budget per site")
    p.add_argument("--random", type=int, default=20, help="random settings of the response check (0: none)")
    p.add_argument("--render", default=None, metavar="JSON", help="only write the page again from a run's record")
    p.add_argument("--checkpoint", default="default", help="metamodel checkpoint (default: the shipped one)")
    p.add_argument("--no-prior", action="store_true", help="calibrate by least squares only")
    p.add_argument(
        "--generations", type=int, default=300, help="NSGA-II generations of the point checked with --random (0: none)"
    )
    p.add_argument(
        "--meters", default="one", choices=["one", "split"], help="one meter a site, or heat and electricity"
    )
    p.add_argument(
        "--calibrated",
        action="store_true",
        help="read the calibrations SUITE/calibration.json holds (an earlier run's) instead of calibrating again",
    )
    p.add_argument("--name", default="suite")
    args = p.parse_args()
    if args.render:
        record = json.loads(Path(args.render).read_text())
        run = record.pop("provenance", None)
        harness.write_results(args.name, render(record, args.random), record, run=run)
        return

    started = time.perf_counter()
    made = make_suite(args.suite, suite_cases(), workers=args.workers, metering=args.meters)
    make_seconds = time.perf_counter() - started
    started = time.perf_counter()
    if args.calibrated:
        rows = json.loads((Path(args.suite) / "calibration.json").read_text())["rows"]
    else:
        rows = calibrate_suite(
            args.suite, checkpoint=args.checkpoint, max_evaluations=args.evaluations, prior=not args.no_prior
        )
    calibrate_seconds = time.perf_counter() - started
    started = time.perf_counter()
    chosen = _nsga2_choice(args.generations) if args.generations else None
    response = (
        check_suite(args.suite, ("held_out",), n=args.random, metamodel=args.checkpoint, chosen=chosen)
        if args.random
        else []
    )
    response_errors = failed_sites(args.suite, "response.json") if args.random else []
    record = {
        "checkpoint": args.checkpoint,
        "meters": args.meters,
        "generations": args.generations,
        "prior": not args.no_prior,
        "summary": summarise(rows),
        "rows": rows,
        "response": response,
        "response_errors": response_errors,
        "made": made,
        "make_seconds": round(make_seconds, 1),
        "calibrate_seconds": round(calibrate_seconds, 1),
        "calibrations_read_back": args.calibrated,
        "response_seconds": round(time.perf_counter() - started, 1),
    }
    harness.write_results(args.name, render(record, args.random), record)


if __name__ == "__main__":
    main()
