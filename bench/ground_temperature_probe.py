"""How much the ground under the slab moves the indoor temperature: the same weeks, the ground warmer or colder.

The core + perimeter shoebox puts its slab on ground at the climate's annual mean + 0.3 x (last month's mean -
annual mean) (``buildenv.energyplus.shoebox.ground_temperatures_c``). The metamodel has no input for it: on a
seen climate it learns it from the climate's weather, on an unseen one it must guess (the lead of
``bench/results/metamodel_climate_holdout.md``). This probe measures, with EnergyPlus, what a ground
``--delta-k`` K off does to the default building's indoor temperature level and heat consumption, for runs of
4 weeks starting at a few weeks of the year. The shoebox has no setting for its ground, so the probe replaces
``ground_temperatures_c`` for the duration of each run.

    .venv/bin/python bench/ground_temperature_probe.py [--epw usa_nj_newark] [--weeks 2,12,44] [--delta-k 2.5]

Writes ``bench/results/ground_temperature_probe.{md,json}`` (about a minute on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import time
from unittest import mock

import numpy as np
from _training_runs import RESULTS, machine

from buildenv import catalogue as cat
from buildenv.defaults import DEFAULT_THETA, default_week
from buildenv.energyplus import shoebox
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.weather import load_weather

WEEKS_PER_RUN = 4


def _run(epw: str, start: int, delta_k: float) -> np.ndarray:
    """Outputs ``(4, 168, 8)`` of the default building's 4 weeks from ``start``, the ground ``delta_k`` K off."""
    settings, occupancy = default_week()
    real = shoebox.ground_temperatures_c
    with mock.patch.object(shoebox, "ground_temperatures_c", lambda w: [v + delta_k for v in real(w)]):
        return simulate_weeks(DEFAULT_THETA, np.repeat(settings, WEEKS_PER_RUN, 0),
                              np.repeat(occupancy, WEEKS_PER_RUN, 0), epw, start).outputs


def main() -> None:
    """Run the probe, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--epw", default="usa_nj_newark")
    parser.add_argument("--weeks", default="2,12,44", help="first weeks of the year of the 4-week runs")
    parser.add_argument("--delta-k", type=float, default=2.5, help="how far the ground is moved, K")
    parser.add_argument("--name", default="ground_temperature_probe")
    args = parser.parse_args()
    t = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    q = [i for i in range(len(cat.OUTPUT_NAMES)) if i != t]
    rows = []
    for start in (int(w) for w in args.weeks.split(",")):
        runs = {dk: _run(args.epw, start, dk) for dk in (-args.delta_k, 0.0, args.delta_k)}
        for dk in (-args.delta_k, args.delta_k):
            diff = runs[dk] - runs[0.0]
            rows.append({"start_week": start, "delta_k": dk,
                         "indoor_level_k": round(float(diff[..., t].mean()), 4),
                         "indoor_level_by_week_k": [round(float(v), 4) for v in diff[..., t].mean(1)],
                         "heat_percent": round(float(100 * diff[..., q].sum() / runs[0.0][..., q].sum()), 3)})
            print(json.dumps(rows[-1]))
    w = load_weather(args.epw)
    result = {"date": time.strftime("%Y-%m-%d"), "machine": machine(),
              "command": "bench/ground_temperature_probe.py " + " ".join(f"--{k.replace('_', '-')} {v}"
                                                                         for k, v in vars(args).items()),
              "annual_mean_c": round(float(w.channel("TAMB").mean()), 2), "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    lines = [f"# The ground under the slab and the indoor temperature ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"The default building (`buildenv.defaults`) in {args.epw} (annual mean {result['annual_mean_c']} degC), "
             f"runs of {WEEKS_PER_RUN} weeks, the ground under the slab moved by the given K against the same run "
             "as modelled. Indoor level: mean change of the indoor temperature, degC; heat: change of the summed "
             "consumption.", "", "| first week | ground | indoor level | each week | heat |", "|---|---|---|---|---|"]
    lines += [f"| {r['start_week']} | {r['delta_k']:+.1f} K | {r['indoor_level_k']:+.3f} | "
              f"{', '.join(f'{v:+.3f}' for v in r['indoor_level_by_week_k'])} | {r['heat_percent']:+.2f} % |"
              for r in rows]
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
