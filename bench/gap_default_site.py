"""The gap diagnosis of the default site, and what the extended model changes for the optimiser.

Copies the shipped default site, runs ``buildenv.diagnosis.gap.diagnose`` on it (the extended model is saved into the
copy), then optimises week 46 with NSGA-II (equal comfort) on the base and on the extended model and runs both
choices on the site's EnergyPlus reference. Writes ``bench/results/gap_default_site.{md,json}``;
``--refit-step S`` diagnoses with that refit step (:class:`buildenv.diagnosis.gap.DiagnosisSettings`) and writes
``gap_default_site_step{S}.{md,json}`` instead.

    .venv/bin/python bench/gap_default_site.py [--refit-step 0.05]
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import shutil
from pathlib import Path

import harness
from harness import RESULTS

from agents.cli import make_env, optimise
from agents.verify import verify
from buildenv.diagnosis.gap import DiagnosisSettings, diagnose, save_extended_model
from buildenv.env.building_week import DEFAULT_SITE
from buildenv.metamodel.surrogate import load_metamodel
from buildenv.sites import load_site

WEEK = 46
KEYS = (
    "predicted_savings_percent",
    "realised_savings_percent",
    "comfort_historical_predicted",
    "comfort_historical",
    "comfort_chosen_predicted",
    "comfort_chosen",
)


def main() -> None:
    """Diagnose, optimise on both models, verify, write the results."""
    parser = harness.parser(__doc__, first_line=True)
    parser.add_argument("--refit-step", type=float, default=DiagnosisSettings.refit_step)
    args = parser.parse_args()
    default_step = args.refit_step == DiagnosisSettings.refit_step
    stem = "gap_default_site" if default_step else f"gap_default_site_step{args.refit_step:g}".replace(".", "")
    command = "python bench/gap_default_site.py" + ("" if default_step else f" --refit-step {args.refit_step:g}")
    out = Path("out") / stem.replace("_", "-")
    if out.exists():
        shutil.rmtree(out)
    shutil.copytree(DEFAULT_SITE, out)
    load = os.getloadavg()[0]
    result = diagnose(
        load_site(out),
        load_metamodel("diagnosis"),
        DiagnosisSettings(refit_step=args.refit_step),
        plot=RESULTS / f"{stem}.png",
    )
    save_extended_model(load_site(out), result)
    result.pop("_fit")
    checks = {}
    for label, site in (("base model", str(DEFAULT_SITE)), ("extended model", str(out))):
        env = make_env(site)
        run = optimise(env, "nsga2", WEEK)
        checks[label] = verify(env, WEEK, run["action"]).summary
    record = {
        "date": dt.date.today().isoformat(),
        "machine": f"{platform.platform()}, {os.cpu_count()} cores",
        "load_average_at_start": load,
        "command": command,
        "diagnosis": result,
        "week": WEEK,
        "nsga2_checks": checks,
    }
    lines = [
        "# Gap diagnosis of the default site",
        "",
        f"Diagnosis {result['seconds']:.0f} s.",
        "",
        f"Answer: **{result['answer']}** ({', '.join(result['selected']) or 'no effect selected'}). Verdict: "
        f"{result['verdict']}. Fit weeks {result['fit_weeks']}, held-out weeks {result['heldout_weeks']}.",
        "",
        "| effect | status | held-out gain | p-value (threshold) | estimated | why not named |",
        "|---|---|---|---|---|---|",
    ]
    for e in result["effects"]:  # the first step's candidates, best held-out gain first
        est = ", ".join(f"{k} {v:g}" for k, v in e["parameters"].items()) or "-"
        p = "-" if e["p_value"] is None else f"{e['p_value']:.2g} ({e['threshold']:.2g})"
        why = "; ".join(e["failed"].values()) or ("-" if e["status"] == "named" else "another candidate gained more")
        lines.append(f"| {e['name']} | {e['status']} | {100 * e['score']:.1f} % | {p} | {est} | {why} |")
    if result.get("heldout_after"):
        b, a = result["heldout_before"], result["heldout_after"]
        lines += ["", "| held-out | base model | extended model |", "|---|---|---|"]
        for key, name in (
            ("cv_rmse_q_percent", "CV(RMSE)_Q %"),
            ("nmbe_q_percent", "NMBE_Q %"),
            ("rmse_t_celsius", "RMSE_T degC"),
            ("r2_t", "R2_T"),
            ("r2_q", "R2_Q"),
        ):
            lines.append(f"| {name} | {b[key]:.3f} | {a[key]:.3f} |")
    lines += [
        "",
        f"## NSGA-II (equal comfort) on week {WEEK}, checked on the EnergyPlus reference",
        "",
        "| model | " + " | ".join(KEYS) + " |",
        "|---" * (len(KEYS) + 1) + "|",
    ]
    for label, s in checks.items():
        lines.append(f"| {label} | " + " | ".join(f"{s[k]:.3f}" for k in KEYS) + " |")
    lines += ["", f"![localisation]({stem}.png)"]
    harness.write_results(stem, lines, record, echo=True)


if __name__ == "__main__":
    main()
