"""Simulation speed: simulated weeks per second per core, buildenv shoebox vs. the DOE medium office.

Measures, in one process (one core) on this machine:
  1. the buildenv shoebox: ``simulate_weeks`` for a full year (52 weeks, sampled I_k/O_k, default theta),
     wall time of the whole call and of the EnergyPlus run inside it;
  2. the DOE reference medium office shipped with pyenergyplus-lbnl (RefBldgMediumOfficeNew2004_Chicago.idf),
     made to simulate its weather-file run period (one year) after autosizing, with every output file off;
and writes ``bench/results/simulation_speed.{md,json}``.

Run:  .venv/bin/python bench/simulation_speed.py [--repeats N] [--skip-reference]
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

import harness
import numpy as np

import buildenv.energyplus.simulate as sim
from buildenv.campaign.sampling import sample_weeks
from buildenv.defaults import default_theta
from buildenv.energyplus.idf import format_idf, read_idf
from buildenv.energyplus.runner import energyplus_version, run_energyplus
from buildenv.weather.epw import resolve_epw

EPW = "usa_il_chicago"
CAMPAIGN_WEEKS, CAMPAIGN_CORES = 40_000, 2
OUTPUT_FILES = (
    "csv mtr eso eio tabular sqlite json audit space_sizing zone_sizing system_sizing dxf bnd rdd mdd "
    "mtd end shd dfs glhe delightin delighteldmp delightdfdmp edd dbg perflog sln sci wrl screen extshd "
    "tarcog plant_component_sizing"
).split()  # OutputControl:Files field order (IDD / model.py)


def time_shoebox(repeats: int, seed: int = 0) -> dict:
    """Time ``simulate_weeks`` for 52 weeks ``repeats`` times; also the EnergyPlus call inside each run."""
    rng = np.random.default_rng(seed)
    theta = default_theta()
    settings, occupancy = sample_weeks(52, rng)
    inner, eplus, total = sim.run_energyplus, [], []

    def timed(*args, **kwargs):  # wraps the run_energyplus that simulate.py calls
        t0 = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            eplus.append(time.perf_counter() - t0)

    sim.run_energyplus = timed
    try:
        for _ in range(repeats):
            t0 = time.perf_counter()
            result = sim.simulate_weeks(theta, settings, occupancy, EPW, start_week=0)
            total.append(time.perf_counter() - t0)
    finally:
        sim.run_energyplus = inner
    assert result.outputs.shape[:2] == (52, 168)
    median = statistics.median(total)
    return {
        "name": "buildenv shoebox (1 zone, ideal loads, 4 timesteps/h)",
        "days": 364,
        "weeks": 52,
        "times_s": total,
        "median_s": median,
        "weeks_per_s_core": 52 / median,
        "eplus_median_s": statistics.median(eplus),
        "overhead_median_s": statistics.median(t - e for t, e in zip(total, eplus)),
    }


def prepare_reference(workdir: Path, run_period: bool = True) -> tuple[Path, dict]:
    """Write the medium office IDF set up for one weather-file year (or sizing only) with all output files off."""
    from pyenergyplus.dataset import ref_models

    source = Path(ref_models["medium_office"])
    objects = read_idf(source)
    drop = re.compile(r"^(OutputControl:Files|Output:SQLite|Output:Table:.*|OutputControl:Table:Style)$", re.I)
    objects = [o for o in objects if not drop.match(o[0])]
    kinds = {o[0].lower(): o for o in objects}
    runs = [o for o in objects if o[0].lower() == "runperiod"]
    assert len(runs) == 1, f"expected one RunPeriod, found {len(runs)}"
    bm, bd, em, ed = (int(runs[0][i]) for i in (2, 3, 5, 6))
    days = (dt.date(2001, em, ed) - dt.date(2001, bm, bd)).days + 1
    # zone/system/plant sizing on the design days stays; design days are not simulated as extra environments
    kinds["simulationcontrol"][1:6] = ["Yes", "Yes", "Yes", "No", "Yes" if run_period else "No"]
    objects.append(["OutputControl:Files"] + ["No"] * len(OUTPUT_FILES))
    idf = workdir / (source.name if run_period else "sizing_only.idf")
    idf.write_text(format_idf(objects))
    n_design, building = sum(o[0].lower() == "sizingperiod:designday" for o in objects), kinds["building"]
    info = {
        "name": f"DOE reference medium office ({source.name}, "
        f"{sum(o[0].lower() == 'zone' for o in objects)} zones, 3 VAV systems with DX cooling and reheat, "
        f"{kinds['timestep'][1]} timesteps/h)",
        "days": days,
        "weeks": days / 7,
        "sizing": f"{n_design} design days for autosizing (+ warm-up days, {building[8]}-{building[7]} "
        "per environment) on top of the run period; Output:SQLite/Output:Table:* objects removed",
    }
    return idf, info


def time_reference(repeats: int) -> dict:
    """Run the prepared reference IDF ``repeats`` times with :func:`run_energyplus`; report times and outputs."""
    epw = resolve_epw(EPW)
    with tempfile.TemporaryDirectory(prefix="bench-refbldg-") as tmp:
        idf, info = prepare_reference(Path(tmp))
        times: list[float] = []
        for i in range(repeats):
            out = Path(tmp) / f"run{i}"
            t0 = time.perf_counter()
            run_energyplus(idf, epw, out)
            times.append(time.perf_counter() - t0)
        err = (out / "eplusout.err").read_text(errors="replace")
        info["output_files"] = sorted(p.name for p in out.iterdir())
        info["warnings"] = [ln.strip() for ln in err.splitlines() if "** Warning **" in ln]
        info["err_summary"] = [ln.strip(" *") for ln in err.splitlines() if "EnergyPlus Completed" in ln]
        sizing_idf, _ = prepare_reference(Path(tmp), run_period=False)  # autosizing alone, timed once
        t0 = time.perf_counter()
        run_energyplus(sizing_idf, epw, Path(tmp) / "sizing")
        info["sizing_only_s"] = time.perf_counter() - t0
    median = statistics.median(times)
    info.update(times_s=times, median_s=median, weeks_per_s_core=info["weeks"] / median)
    return info


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark, print a table and write the results files."""
    p = harness.parser(__doc__, first_line=True)
    p.add_argument("--repeats", type=int, default=3, help="runs per model (median reported)")
    p.add_argument("--skip-reference", action="store_true", help="time only the shoebox")
    args = p.parse_args(argv)
    rows = [time_shoebox(args.repeats)]
    if not args.skip_reference:
        rows.append(time_reference(args.repeats))
    for r in rows:
        r["projection_h_40k_weeks_2_cores"] = CAMPAIGN_WEEKS / (r["weeks_per_s_core"] * CAMPAIGN_CORES) / 3600
    ratio = rows[0]["weeks_per_s_core"] / rows[1]["weeks_per_s_core"] if len(rows) > 1 else None
    record = {
        "date": dt.datetime.now().isoformat(timespec="seconds"),
        "machine": {
            "processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
        },
        "energyplus": energyplus_version(),
        "command": " ".join([".venv/bin/python"] + sys.argv),
        "repeats": args.repeats,
        "models": rows,
        "speed_ratio_shoebox_over_reference": ratio,
    }
    head = "| model | simulated days | median wall s | weeks/s/core | 40k weeks on 2 cores (h, projection) |"
    lines = [head, "|---|---|---|---|---|"]
    lines += [
        f"| {r['name']} | {r['days']} | {r['median_s']:.2f} | {r['weeks_per_s_core']:.3f} | "
        f"{r['projection_h_40k_weeks_2_cores']:.2f} |"
        for r in rows
    ]
    print("\n".join(lines))
    sb = rows[0]
    notes = [
        f"- Shoebox: 52 weeks from Monday January 1st (+ warm-up days, no sizing); EnergyPlus call "
        f"{sb['eplus_median_s']:.2f} s, Python overhead (schedules, epJSON, "
        f"CSV read) {sb['overhead_median_s']:.2f} s (medians); all times: "
        f"{', '.join(f'{t:.2f}' for t in sb['times_s'])} s."
    ]
    if ratio is not None:
        ref = rows[1]
        print(f"shoebox / reference speed ratio: {ratio:.1f}x")
        notes += [
            f"- Reference: {ref['sizing']}; {ref['weeks']:.2f} weeks per run; all times: "
            f"{', '.join(f'{t:.2f}' for t in ref['times_s'])} s; autosizing alone (run period off) "
            f"{ref['sizing_only_s']:.2f} s; files written: {', '.join(ref['output_files'])}.",
            f"- Reference eplusout.err: {'; '.join(ref['err_summary'])}. Warnings: "
            + " / ".join(f"`{w.replace('** Warning **', '').strip(' *')}`" for w in ref["warnings"])
            + ".",
            f"- Speed ratio shoebox / reference (weeks/s/core): **{ratio:.1f}x**.",
        ]
    md = [
        "# Simulation speed",
        "",
        f"EnergyPlus {record['energyplus']}; {args.repeats} repeats, median reported. "
        "Single-process measurement (one core); other processes may have been running on the machine at the "
        "same time.",
        "",
        *lines,
        "",
        *notes,
        "- The last column is a **projection**, not a measurement: 40,000 weeks / (weeks/s/core x 2 cores), "
        "assuming perfect scaling over 2 processes.",
        "",
    ]
    harness.write_results("simulation_speed", md, record)


if __name__ == "__main__":
    main()
