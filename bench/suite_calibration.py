"""The suite calibrated with the unchanged commands: ASHRAE Guideline 14 on every office, climate and season.

Makes the suite (``buildenv suite make``: the six reference offices x seven climates x a heating and a cooling
season, 8 weeks each under BMS histories that change week to week; resumable) and calibrates every site it could
make (``buildenv suite calibrate``: the default calibration, first half fitted, second half held out). The
development part and the held-out climates (Phoenix, Newark) are reported apart; the held-out part is what the
any-office targets are judged on.
"""

from __future__ import annotations

import time

import harness

from buildenv.calibration.suite import TIGHT_CV_PERCENT, TIGHT_NMBE_PERCENT, calibrate_suite, summarise
from buildenv.metrics import GUIDELINE14_HOURLY_CV_PERCENT, GUIDELINE14_HOURLY_NMBE_PERCENT
from buildenv.sites.suite import HELD_OUT_CLIMATES, make_suite, suite_cases


def _table(rows: list[dict]) -> list[str]:
    lines = [
        "| site | CV(RMSE)_Q % | NMBE_Q % | R2_T | RMSE_T K | Guideline 14 | at a bound | s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['building']} {r['climate']} {r['season']} | {r['cv_rmse_q_percent']:.1f} | "
            f"{r['nmbe_q_percent']:.1f} | {r['r2_t']:.3f} | {r['rmse_t_celsius']:.2f} | "
            f"{'yes' if r['guideline14'] else 'no'} | {r['at_bounds']} | {r['seconds']:.0f} |"
        )
    return lines


def main() -> None:
    p = harness.parser(__doc__, first_line=True)
    p.add_argument("--suite", default="out/suite", help="suite folder (made or reused)")
    p.add_argument("--workers", type=int, default=None, help="EnergyPlus processes (default: the CPUs)")
    p.add_argument("--evaluations", type=int, default=6000, help="CMA-ES budget per site")
    p.add_argument("--name", default="suite_calibration")
    args = p.parse_args()

    started = time.perf_counter()
    made = make_suite(args.suite, suite_cases(), workers=args.workers)
    make_seconds = time.perf_counter() - started
    started = time.perf_counter()
    rows = calibrate_suite(args.suite, max_evaluations=args.evaluations)
    calibrate_seconds = time.perf_counter() - started
    summary = summarise(rows)
    refused = [r for r in made if r["status"] == "refused"]

    lines = [
        "# The suite calibrated: Guideline 14 on every office, climate and season",
        "",
        f"{len(made)} cases, {len(made) - len(refused)} sites made, {len(refused)} refused; held-out climates: "
        f"{', '.join(HELD_OUT_CLIMATES)}. Making took {make_seconds / 60:.1f} min (EnergyPlus, sites already "
        f"made reused), calibrating {calibrate_seconds / 60:.1f} min. Guideline 14 hourly: CV(RMSE)_Q <= "
        f"{GUIDELINE14_HOURLY_CV_PERCENT:.0f} % and |NMBE_Q| <= {GUIDELINE14_HOURLY_NMBE_PERCENT:.0f} %; the "
        f"tighter band: {TIGHT_CV_PERCENT:.0f} % and {TIGHT_NMBE_PERCENT:.0f} %. All figures on held-out weeks.",
        "",
        "| part | sites | Guideline 14 | tighter band | R2_T >= 0.9 | at a bound (mean) | s a site (median) |",
        "|---|---|---|---|---|---|---|",
    ]
    for part, s in summary.items():
        lines.append(
            f"| {part} | {s['sites']} | {s['guideline14_share']:.0%} | {s['tight_share']:.0%} | "
            f"{s['r2_t_above_0_9_share']:.0%} | {s['mean_at_bounds']} | {s['median_seconds']} |"
        )
    for part in ("held_out", "development"):
        lines += ["", f"## {part.replace('_', '-')} sites", "", *_table([r for r in rows if r["part"] == part])]
    if refused:
        lines += ["", "## Refused", ""]
        lines += [
            f"- {r['building']} {r['climate']} {r['season']}: {r['reason'].replace(r['site'] + '/', '')}"
            for r in refused
        ]
    harness.write_results(
        args.name,
        lines,
        {
            "summary": summary,
            "rows": rows,
            "refused": refused,
            "make_seconds": round(make_seconds, 1),
            "calibrate_seconds": round(calibrate_seconds, 1),
        },
    )


if __name__ == "__main__":
    main()
