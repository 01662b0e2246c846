"""What declaring an effect the building is known to have buys: the default site calibrated without and with it.

The default site is the DOE medium office, a VAV system with terminal reheat; its night cycle sends the cooling
supply air (12.8 degC) to every zone whenever one needs heat, which our model lacks.
``buildenv calibrate --effect night_cycle_cold_air`` adds the effect's model side in a second calibration stage
(:func:`buildenv.calibration.problem.fit_declared_effects`); the
shipped site declares its effects in ``site.toml`` (``effects``). This script calibrates two copies of the site,
one plain (``--no-site-effects``), one with the declared effects (``--effect``, by default the site's own),
scores both models on the held-out weeks, then lets NSGA-II
choose each model's equal-comfort settings for some weeks and runs both choices on the site's EnergyPlus
reference: how close predicted savings, comfort and energy come to what the building realises.
Writes ``bench/results/{name}.md`` and ``.json``.

    .venv/bin/python bench/declared_effects.py [--effect night_cycle_cold_air ...] [--weeks 44,45,46,47]
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import shutil
from pathlib import Path

import harness

from agents.cli import make_env, optimise
from agents.verify import verify
from buildenv.calibration.calibrate import calibrate_site
from buildenv.env.building_week import DEFAULT_SITE
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site

HELDOUT = ("r2_t", "rmse_t_celsius", "r2_q", "cv_rmse_q_percent", "nmbe_q_percent")
CHECKS = (
    "predicted_savings_percent",
    "realised_savings_percent",
    "comfort_chosen_predicted",
    "comfort_chosen",
    "energy_historical_predicted_kwh",
    "energy_historical_kwh",
)


def main() -> None:
    """Calibrate with the declared effects, compare held-out metrics and verified optimisations."""
    parser = harness.parser(__doc__, first_line=True)
    parser.add_argument("--effect", action="append", default=None, help="declared effect (repeatable)")
    parser.add_argument("--weeks", default="44,45,46,47", help="weeks of the year optimised and verified")
    parser.add_argument("--name", default="declared_effects")
    args = parser.parse_args()
    effects = tuple(args.effect or load_site(DEFAULT_SITE).effects)
    weeks = [int(w) for w in args.weeks.split(",")]
    out = Path("out") / args.name.replace("_", "-")
    if out.exists():
        shutil.rmtree(out)
    load = os.getloadavg()[0]
    models = {}
    for label, folder, declare in (
        ("plain (no declared effect)", out / "plain", ()),
        (f"declared {', '.join(effects)}", out / "declared", effects),
    ):
        shutil.copytree(DEFAULT_SITE, folder, ignore=shutil.ignore_patterns("calibration.*"))
        models[label] = (str(folder), calibrate_site(load_site(folder), load_metamodel(), effects=declare))
    plain = next(iter(models.values()))[1]
    checks: dict[str, dict] = {label: {} for label in models}
    for label, (site, _) in models.items():
        env = make_env(site)
        for week in weeks:
            run = optimise(env, "nsga2", week)
            checks[label][week] = verify(env, week, run["action"]).summary
    command = (
        "python bench/declared_effects.py"
        + "".join(f" --effect {e}" for e in args.effect or [])
        + (f" --weeks {args.weeks}" if args.weeks != "44,45,46,47" else "")
        + (f" --name {args.name}" if args.name != "declared_effects" else "")
    )
    record = {
        "date": dt.date.today().isoformat(),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "load_average_at_start": load,
        "command": command,
        "effects": effects,
        "calibration": {
            label: {
                k: c.get(k)
                for k in ("cost", "cost_without_effects", "effects", "seconds", "evaluations", "heldout", "fit_weeks")
            }
            for label, (_, c) in models.items()
        },
        "nsga2_checks": checks,
    }
    lines = [
        f"# Declared effects on the default site: {', '.join(effects)}",
        "",
        f"Calibration (CMA-ES, seed 0) on the fit weeks {plain['fit_weeks']}, scored on the held-out weeks "
        f"{plain['heldout_weeks']}; the declared effects' parameters are fitted after the building's "
        "(`buildenv.calibration.problem`, declared effects):",
        "",
        "| model | fit cost | " + " | ".join(f"held-out {k}" for k in HELDOUT) + " | estimated |",
        "|---" * (len(HELDOUT) + 3) + "|",
    ]
    for label, (_, c) in models.items():
        estimated = (
            "; ".join(
                f"{e} " + ", ".join(f"{p} {v:g}" for p, v in ps.items()) for e, ps in (c.get("effects") or {}).items()
            )
            or "-"
        )
        lines.append(
            f"| {label} | {c['cost']:.4f} | "
            + " | ".join(f"{c['heldout'][k]:.3f}" for k in HELDOUT)
            + f" | {estimated} |"
        )
    lines += [
        "",
        "NSGA-II (equal comfort to the historical settings) on each model, the chosen settings and the "
        "historical ones run on the site's EnergyPlus reference (`agents.verify`); comfort in K, energy "
        "the week's HVAC energy in kWh:",
        "",
        "| model | week | " + " | ".join(CHECKS) + " |",
        "|---" * (len(CHECKS) + 2) + "|",
    ]
    for label, per_week in checks.items():
        for week, s in per_week.items():
            lines.append(
                f"| {label} | {week} | "
                + " | ".join(f"{s[k]:.3f}" if "comfort" in k else f"{s[k]:.1f}" for k in CHECKS)
                + " |"
            )
    lines += [
        "",
        "Mean absolute error of the prediction against EnergyPlus over the weeks:",
        "",
        "| model | savings points | comfort of the chosen settings K | historical energy % |",
        "|---|---|---|---|",
    ]
    for label, per_week in checks.items():
        s = list(per_week.values())
        err = [
            sum(abs(x[a] - x[b]) for x in s) / len(s)
            for a, b in (
                ("predicted_savings_percent", "realised_savings_percent"),
                ("comfort_chosen_predicted", "comfort_chosen"),
            )
        ]
        energy = sum(abs(x["energy_historical_predicted_kwh"] / x["energy_historical_kwh"] - 1) for x in s) / len(s)
        lines.append(f"| {label} | {err[0]:.2f} | {err[1]:.3f} | {100 * energy:.1f} |")
    harness.write_results(args.name, lines, record, echo=True)


if __name__ == "__main__":
    main()
