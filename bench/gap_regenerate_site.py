"""Make a recorded blind check's site again, where its check folder no longer keeps it.

A blind check's sites (``bench/gap_check.py``) are EnergyPlus runs of the stand-in fixed by the check's plan: the
first Monday, the sensor-noise seed and the effect's seed of each case, all recorded in its page. This runs the
stand-in again for chosen cases (their clean twin with ``--twin``) and writes the site where the check kept it
(``case_NNN`` or ``case_NNN_twin`` in the page's ``--out`` folder), so the scripts that diagnose recorded sites
again (``bench/gap_wind_centred.py``, ``bench/gap_carried_starts.py``) find it. A site already there is left as it
is. One EnergyPlus run of the check's weeks per site:

    .venv/bin/python bench/gap_regenerate_site.py --page bench/results/gap_check_tb_seed6.json --case 12 --twin

Run it from the repository root.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gap_check_bar import check_folder, recorded_settings

from buildenv.gap_check import StandIn, _site


def regenerate(page: dict, case: int, twin: bool) -> Path:
    """The site of ``case`` (its clean twin when ``twin``) of a check's ``page``, made again where the check kept
    it unless it is still there; returns its folder."""
    plan = page["plan"]
    stand_in = StandIn(plan["building"], plan["epw"], plan.get("known_parameters", {}), plan["weeks"],
                       recorded_settings(plan["settings"]).split)
    row = next(c for c in page["cases"] if c["case"] == case)
    out = check_folder(page)
    out.mkdir(parents=True, exist_ok=True)
    return _site(out, row, stand_in, inject=not twin)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", required=True, help="a bench/gap_check.py result (.json)")
    parser.add_argument("--case", type=int, action="append", required=True, help="a case number (repeatable)")
    parser.add_argument("--twin", action="store_true", help="the cases' clean twins instead of the cases")
    args = parser.parse_args()
    page = json.loads(Path(args.page).read_text())
    for case in args.case:
        started = time.perf_counter()
        path = regenerate(page, case, args.twin)
        print(f"{path} ({time.perf_counter() - started:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
