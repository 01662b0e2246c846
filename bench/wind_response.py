"""Does the metamodel answer an hourly wind-driven infiltration as EnergyPlus does?

The diagnosis's ``wind_infiltration`` candidate feeds the metamodel an hourly infiltration input, ``calibrated air
changes + k x share x wind speed`` (``buildenv.effects_model.transform_inputs``; ``share`` is 1, or
:data:`buildenv.effects_model.VENTILATED_WIND_SHARE` in hours the air handling unit runs). The metamodel was
trained on campaigns whose infiltration is one constant per building (``infiltration_ach`` in the catalogue), so
the hourly part of that input is outside anything it saw. On the blind checks the candidate finds the wind on
the cases and not on their clean twins, but it gains only 4-14 % of the held-out error
(``bench/results/effect_on_twin.md``). This probe separates two explanations:

1. the metamodel does not reproduce EnergyPlus's answer to an hourly infiltration (then a campaign with a wind
   term would help);
2. most of the wind's footprint is a level that a constant, higher infiltration explains as well (then the base
   calibration absorbs it whatever the model, and what is left to gain is small).

For sampled buildings (theta_build from the catalogue, the default settings and occupancy) and runs of
``--weeks`` weeks in ``--epw``, the same weeks are simulated three ways, by the EnergyPlus shoebox and by the
metamodel alike: as modelled (``base``), with the wind term ``--k`` air changes per hour per m/s of the weather
file's wind speed (``wind``: in EnergyPlus a second infiltration object whose hourly schedule is ``share x wind
speed``, so that both see exactly the same infiltration), and with the wind term's mean over the run added to the
constant infiltration instead (``level``). The metamodel reads each run's own EnergyPlus temperature over its
context hours, as it reads a site's measured temperature; a run's first week, with no week before it, is not
scored. Reported for the indoor temperature (degC) and the summed heat consumption of a site
(``buildenv.catalogue.HEAT_CONSUMPTION_OUTPUTS``, Wh/m2 per hour), over the scored hours:

- ``footprint``: RMS of EnergyPlus's ``wind - base``;
- ``mm_error``: RMS of the metamodel's ``base`` against EnergyPlus's (what a calibrated model misses anyway);
- ``reproduced``: 1 - SS(metamodel's ``wind - base`` - EnergyPlus's) / SS(EnergyPlus's), and ``slope``, the
  least-squares factor from EnergyPlus's footprint to the metamodel's (1: the same size);
- ``level_share``: the share of EnergyPlus's footprint that the ``level`` run explains, 1 - SS(wind - level) /
  SS(wind - base);
- ``hourly_rms``: RMS of EnergyPlus's ``wind - level``, the part no constant infiltration explains, and
  ``hourly_reproduced``: how much of it the metamodel's ``wind - level`` reproduces (as ``reproduced``).

    .venv/bin/python bench/wind_response.py [--buildings 6] [--starts 40,44,48] [--k 0.03] [--seed 0]

Writes ``bench/results/wind_response.{md,json}`` (about 5 minutes on 2 cores for the defaults).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from unittest import mock

import numpy as np
from _training_runs import RESULTS, machine
from tqdm import tqdm

from buildenv import catalogue as cat
from buildenv import effects_model as em
from buildenv import surrogate as sg
from buildenv.defaults import default_week
from buildenv.energyplus import shoebox
from buildenv.energyplus.simulate import simulate_weeks
from buildenv.sampling import sample_group
from buildenv.weather import load_weather

T = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
Q = [cat.OUTPUT_NAMES.index(n) for n in cat.HEAT_CONSUMPTION_OUTPUTS]
WIND_SCHEDULE = "wind infiltration share x speed"
VARIANTS = ("base", "wind", "level")


def wind_hours(weather_hours: np.ndarray, ventilation_on: np.ndarray) -> np.ndarray:
    """``share x wind speed`` (m/s) of each hour: the weather's wind speed, at
    :data:`buildenv.effects_model.VENTILATED_WIND_SHARE` of itself where the ventilation runs (the model side's
    convention)."""
    share = np.where(ventilation_on > 0, em.VENTILATED_WIND_SHARE, 1.0)
    return share * weather_hours


def _with_infiltration(ach: float, schedule: str, csv: Path | None):
    """A wrapper of :func:`buildenv.energyplus.shoebox.build_epjson` that adds a second infiltration object of
    ``ach`` air changes per hour times ``schedule``: column 1 of ``csv`` (one value per hour of the year) or, with
    ``csv`` None, an existing schedule of the shoebox."""
    build = shoebox.build_epjson

    def built(theta, weather, schedule_csv, start_week, n_weeks, zoning=shoebox.DEFAULT_ZONING, check=True):
        model = build(theta, weather, schedule_csv, start_week, n_weeks, zoning, check)
        objects = model["ZoneInfiltration:DesignFlowRate"]
        (name, base), = objects.items()
        volume = shoebox.Geometry.from_theta(shoebox.theta_dict(theta, check)).volume_m3
        flow_m3_s = round(ach * volume / 3600.0, 6)
        objects[f"{name} added"] = {**base, "schedule_name": schedule, "design_flow_rate": flow_m3_s}
        if csv is not None:
            model["Schedule:File"][schedule] = {**model["Schedule:File"]["occupancy_fraction"],
                                                "file_name": str(csv.resolve()), "column_number": 1}
        return model

    return built


def energyplus_runs(theta: np.ndarray, epw: str, start: int, weeks: int, k: float) -> dict[str, np.ndarray]:
    """EnergyPlus outputs ``(weeks, 168, 8)`` of the three variants (module docstring) of one building, and
    ``level_ach``, the constant of the ``level`` run (1/h)."""
    settings, occupancy = default_week(weeks)
    weather = load_weather(epw)
    vent = shoebox.schedule_table(shoebox.theta_dict(theta), settings, occupancy, start)[
        :, shoebox.SCHEDULE_COLUMNS.index("ventilation_on")]
    wind = wind_hours(weather.channel("WIND_SPEED")[:len(vent)], vent)
    hours = slice(start * cat.HOURS_PER_WEEK, (start + weeks) * cat.HOURS_PER_WEEK)
    level = k * float(wind[hours].mean())
    runs = {"base": simulate_weeks(theta, settings, occupancy, epw, start).outputs}
    with tempfile.TemporaryDirectory(prefix="buildenv-wind-") as tmp:
        csv = Path(tmp) / "wind.csv"
        np.savetxt(csv, wind, fmt="%.4f", header="share_x_wind_m_s", comments="")
        for variant, added in (("wind", _with_infiltration(k, WIND_SCHEDULE, csv)),
                               ("level", _with_infiltration(level, "Always on", None))):
            with mock.patch("buildenv.energyplus.simulate.build_epjson", added):
                runs[variant] = simulate_weeks(theta, settings, occupancy, epw, start).outputs
    return {**runs, "level_ach": np.array(level)}


def metamodel_runs(model: sg.Surrogate, theta: np.ndarray, epw: str, start: int, weeks: int, k: float,
                   level: float, measured: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Metamodel outputs ``(weeks - 1, 168, 8)`` of weeks 2.. of the run, three variants; each reads the
    temperature of its own EnergyPlus run over the context hours."""
    settings, occupancy = default_week(weeks)
    weather = load_weather(epw)
    w = weather.weeks(start, weeks)
    ctx = model.context_hours
    first = (start + np.arange(1, weeks)) * cat.HOURS_PER_WEEK
    ground = sg.ground_hours(shoebox.hourly_ground_temperature_c(weather), first, ctx)
    thetas = np.repeat(np.asarray(theta, dtype=np.float32)[None], weeks - 1, 0)
    out = {}
    for variant in VARIANTS:
        before = measured[variant][:-1, -ctx:, T]
        x = sg.encode_weeks(thetas, settings[1:], occupancy[1:], w[1:], (settings[:-1], occupancy[:-1], w[:-1]),
                            None, ctx, ground, before if model.uses_temperature_before else None)
        if variant == "wind":
            x = em.transform_inputs(x, {"wind_infiltration": np.array([[k]])})
        elif variant == "level":
            x[..., sg.INPUT_CHANNELS.index("infiltration_ach")] += level
        out[variant] = model.predict_encoded(x)
    return out


def _series(outputs: np.ndarray) -> dict[str, np.ndarray]:
    """The two measured series of outputs ``(weeks, 168, 8)``, flattened."""
    return {"temperature": outputs[..., T].ravel(), "consumption": outputs[..., Q].sum(-1).ravel()}


def _reproduced(mm: np.ndarray, ep: np.ndarray) -> tuple[float, float]:
    """Share of EnergyPlus's difference ``ep`` that the metamodel's ``mm`` reproduces, and the LS slope."""
    ss = float((ep ** 2).sum())
    return 1.0 - float(((mm - ep) ** 2).sum()) / ss, float((mm * ep).sum()) / ss


def compare(ep: dict[str, np.ndarray], mm: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """The module docstring's figures for each series, from EnergyPlus runs ``ep`` (weeks 2.. scored) and the
    metamodel's ``mm`` of the same weeks."""
    e = {v: _series(ep[v][1:]) for v in VARIANTS}
    m = {v: _series(mm[v]) for v in VARIANTS}
    figures = {}
    for s in ("temperature", "consumption"):
        foot, hourly = e["wind"][s] - e["base"][s], e["wind"][s] - e["level"][s]
        reproduced, slope = _reproduced(m["wind"][s] - m["base"][s], foot)
        hourly_reproduced, _ = _reproduced(m["wind"][s] - m["level"][s], hourly)
        figures[s] = {"footprint": float(np.sqrt((foot ** 2).mean())),
                      "mm_error": float(np.sqrt(((m["base"][s] - e["base"][s]) ** 2).mean())),
                      "reproduced": reproduced, "slope": slope,
                      "level_share": 1.0 - float((hourly ** 2).sum() / (foot ** 2).sum()),
                      "hourly_rms": float(np.sqrt((hourly ** 2).mean())), "hourly_reproduced": hourly_reproduced}
    return figures


def main() -> None:
    """Run the probe, write the page."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--epw", default="usa_il_chicago")
    parser.add_argument("--buildings", type=int, default=6, help="buildings sampled from the catalogue")
    parser.add_argument("--starts", default="40,44,48", help="first weeks of the year of the runs, one a building "
                        "in turn")
    parser.add_argument("--weeks", type=int, default=4, help="weeks a run (the first is not scored)")
    parser.add_argument("--k", type=float, default=0.03, help="wind term, air changes per hour per m/s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoint", default="default")
    parser.add_argument("--name", default="wind_response")
    args = parser.parse_args()
    model = sg.load_metamodel(args.checkpoint)
    thetas = sample_group("theta_build", args.buildings, np.random.default_rng(args.seed))
    starts = [int(s) for s in args.starts.split(",")]
    if args.weeks < 2 or any(s < 0 or s + args.weeks > cat.WEEKS_PER_YEAR for s in starts):
        raise SystemExit(f"wind_response: --starts {args.starts} --weeks {args.weeks}: every run needs at least 2 "
                         f"weeks, all within weeks 0-{cat.WEEKS_PER_YEAR - 1} of the year")
    rows = []
    for i in tqdm(range(args.buildings), desc="buildings"):
        start = starts[i % len(starts)]
        ep = energyplus_runs(thetas[i], args.epw, start, args.weeks, args.k)
        mm = metamodel_runs(model, thetas[i], args.epw, start, args.weeks, args.k, float(ep["level_ach"]), ep)
        rows.append({"building": i, "start_week": start, "infiltration_ach": float(thetas[i][
            cat.THETA_NAMES.index("infiltration_ach")]), "level_ach": round(float(ep["level_ach"]), 4),
            **{s: {k: round(v, 4) for k, v in f.items()} for s, f in compare(ep, mm).items()}})
        print(json.dumps(rows[-1]))
    result = {"date": time.strftime("%Y-%m-%d"), "machine": machine(),
              "command": "bench/wind_response.py " + " ".join(f"--{k.replace('_', '-')} {v}"
                                                               for k, v in vars(args).items()),
              "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
    _write_page(result, args)


def _write_page(result: dict, args: argparse.Namespace) -> None:
    """The markdown page of ``result``."""
    head = ("| building | first week | infiltration, + level (1/h) | series | footprint | metamodel error | "
            "reproduced, slope | level share | hourly part | hourly reproduced |")
    lines = [f"# Wind-driven infiltration: EnergyPlus against the metamodel ({result['date']})", "",
             f"{result['machine']}. Command: `python {result['command']}`.", "",
             f"Buildings sampled from the catalogue in {args.epw}, the default settings and occupancy, runs of "
             f"{args.weeks} weeks (the first not scored), a wind term of {args.k} air changes per hour per m/s "
             "(`bench/wind_response.py` defines every column). Temperature in degC, consumption in Wh/m2 per hour "
             "(RMS over the scored hours).", "", head, "|" + "---|" * 10]
    for r in result["rows"]:
        for s in ("temperature", "consumption"):
            f = r[s]
            lines.append(f"| {r['building']} | {r['start_week']} | {r['infiltration_ach']:.2f}, "
                         f"+{r['level_ach']:.3f} | {s} | {f['footprint']:.3f} | {f['mm_error']:.3f} | "
                         f"{f['reproduced']:.2f}, {f['slope']:.2f} | {f['level_share']:.2f} | {f['hourly_rms']:.3f} | "
                         f"{f['hourly_reproduced']:.2f} |")
    lines += ["", "Medians over the buildings:", ""]
    for s in ("temperature", "consumption"):
        med = {k: float(np.median([r[s][k] for r in result["rows"]])) for k in result["rows"][0][s]}
        lines.append(f"- {s}: footprint {med['footprint']:.3f}, metamodel error {med['mm_error']:.3f}, reproduced "
                     f"{med['reproduced']:.2f} (slope {med['slope']:.2f}), level share {med['level_share']:.2f}, "
                     f"hourly part {med['hourly_rms']:.3f}, of which reproduced {med['hourly_reproduced']:.2f}.")
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
