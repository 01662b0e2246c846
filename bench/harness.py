"""The benchmarks' shared harness: arguments, a provenance header, and one writer of ``bench/results/<name>``.

Every benchmark is run from the repository root as ``python bench/NAME.py [options]`` and imports this module
from its own folder. :func:`write_results` writes ``bench/results/<name>.md`` (the page, with the provenance line
under its title) and ``<name>.json`` (the record, with the provenance under ``"provenance"``).

The rest are measurement helpers more than one benchmark uses: the metamodel runs and timings, the calibration
benches' machine and CPU meter, and the blind checks' records judged as the current diagnosis judges them.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import re
import shlex
import sys
import time
from collections.abc import Mapping
from pathlib import Path

from buildenv.jsonio import dumps

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
_LOAD_AT_START = os.getloadavg()


# --- arguments -----------------------------------------------------------------------------------------------


def parser(doc: str | None, first_line: bool = False) -> argparse.ArgumentParser:
    """An argument parser described by the first paragraph of a script's docstring (its first line only with
    ``first_line``)."""
    text = (doc or "").strip()
    return argparse.ArgumentParser(description=text.splitlines()[0] if first_line else text.split("\n\n")[0])


# --- provenance and the writer -------------------------------------------------------------------------------


def provenance(argv: list[str] | None = None) -> dict:
    """When, where and how a benchmark ran: ISO date and time, the machine (platform, CPU count), the command
    line as run from the repository root, and the 1/5/15-minute load averages at the start and now."""
    argv = sys.argv if argv is None else argv
    script = Path(argv[0]) if argv else Path("bench")
    shown = f"bench/{script.name}" if script.suffix == ".py" else str(script)
    return {
        "date": dt.datetime.now().isoformat(timespec="seconds"),
        "machine": f"{platform.platform()}, {platform.machine()}",
        "cpu_count": os.cpu_count(),
        "command": shlex.join(["python", shown, *argv[1:]]),
        "load_average_at_start": [round(x, 2) for x in _LOAD_AT_START],
        "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
    }


def provenance_line(p: Mapping) -> str:
    """The provenance as one Markdown line."""
    return (
        f"Run {p['date']} on {p['machine']}, {p['cpu_count']} CPUs, load average {p['load_average_at_start'][0]}"
        f" at start, {p['load_average_at_end'][0]} at end: `{p['command']}`."
    )


def _jsonable(value):
    """What :func:`json.dumps` cannot write: numpy scalars and arrays as numbers and lists, the rest as text."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "item"):
        return value.item()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    return str(value)


def write_results(
    name: str,
    page: str | list[str],
    data: Mapping | str,
    out: Path | None = None,
    keep: str | None = None,
    echo: bool = False,
    run: Mapping | None = None,
) -> Path:
    """Write ``<out>/<name>.md`` and ``<out>/<name>.json`` (``out``: ``bench/results``) and return the page's path.

    ``page``: Markdown text or lines, its first line the title; the provenance line goes under it. ``data``: the
    record (the provenance is added under ``"provenance"``), or JSON text written as it is. ``keep``: a heading
    whose section of the old page is kept at the end of the new one (a hand-written reading of the run). ``echo``:
    print the page. ``run``: the provenance of the run the page shows, when the page is written again from its record.
    """
    out = RESULTS if out is None else Path(out)
    out.mkdir(parents=True, exist_ok=True)
    p = dict(run) if run is not None else provenance()
    lines = page.rstrip("\n").split("\n") if isinstance(page, str) else list(page)
    title, rest = (lines[:1], lines[1:]) if lines and lines[0].startswith("# ") else ([], lines)
    text = "\n".join([*title, "", provenance_line(p), *rest]).rstrip("\n") + "\n"
    path = out / f"{name}.md"
    if keep:
        old = path.read_text() if path.is_file() else ""
        text += ("\n" + old[old.index(keep) :]) if keep in old else ""
    path.write_text(text)
    if isinstance(data, str):
        (out / f"{name}.json").write_text(data if data.endswith("\n") else data + "\n")
    else:
        record = {"provenance": p, **{k: v for k, v in data.items() if k != "provenance"}}
        body = dumps(record, where=str(out / f"{name}.json"), nonfinite="null", indent=1, default=_jsonable)
        (out / f"{name}.json").write_text(body + "\n")
    if echo:
        print(text)
    return path


def percent(part: int, whole: int, digits: int = 0) -> str:
    """``part/whole (percent %)``, or ``-`` where there is nothing to count."""
    return f"{part}/{whole} ({100 * part / whole:.{digits}f} %)" if whole else "-"


# --- machines and CPU time (calibration benches) --------------------------------------------------------------


def machine() -> str:
    """One line describing this machine and torch."""
    import torch

    return f"{platform.platform()}, {os.cpu_count()} cores, torch {torch.__version__}"


def machine_details() -> dict:
    """What ran a bench: CPU model and count, OS, load before starting, versions."""
    from importlib.metadata import version

    from buildenv.energyplus.runner import energyplus_version

    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        names = [
            line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines() if line.startswith("model name")
        ]
        model = names[0] if names else model
    return {
        "cpu": model,
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "load_average_1min_at_start": round(os.getloadavg()[0], 2),
        "versions": {
            "energyplus": energyplus_version(),
            "cma": version("cma"),
            "torch": version("torch"),
            "numpy": version("numpy"),
        },
    }


class CpuMeter:
    """CPU time the whole machine and this process tree used between :meth:`start` and :meth:`stop`, s.

    ``others_cpu_s`` is the machine's busy time (``/proc/stat``) minus this process's and its finished
    children's (``getrusage``): how idle the CPU really was.
    """

    def start(self) -> CpuMeter:
        self._t, self._busy, self._own = time.perf_counter(), self._machine_busy(), self._own_cpu()
        return self

    def stop(self) -> dict:
        import math

        wall = time.perf_counter() - self._t
        busy, own = self._machine_busy() - self._busy, self._own_cpu() - self._own
        cores = os.cpu_count() or 1
        others = float("nan") if math.isnan(busy) else max(busy - own, 0.0)
        return {
            "wall_s": round(wall, 1),
            "machine_busy_cpu_s": round(busy, 1),
            "own_cpu_s": round(own, 1),
            "others_cpu_s": round(others, 1),
            "others_share_of_capacity": round(others / (cores * wall), 3),
        }

    @staticmethod
    def _machine_busy() -> float:
        try:
            fields = [float(x) for x in Path("/proc/stat").read_text().split("\n")[0].split()[1:]]
        except OSError:
            return float("nan")
        user, nice, system, _idle, _iowait, irq, softirq, steal = fields[:8]
        return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")

    @staticmethod
    def _own_cpu() -> float:
        import resource

        total = 0.0
        for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
            usage = resource.getrusage(who)
            total += usage.ru_utime + usage.ru_stime
        return total


def cpu_sentence(cpu: dict) -> str:
    """What the CPU meter saw, in words."""
    return (
        f"During the {cpu['wall_s']:.0f} s of the bench, other processes used {cpu['others_cpu_s']:.0f} CPU s "
        f"({100 * cpu['others_share_of_capacity']:.1f} % of the {os.cpu_count()} cores' capacity)."
    )


# --- metamodel runs and timings -------------------------------------------------------------------------------

# An earlier default (8-hour tokens, 2+2 layers, hourly read-out): the learning curve's model.
PREVIOUS_TRANSFORMER = {"patch_hours": 8, "layers": 2, "d_ff": 128, "hourly_head": 64}


def shipped_transformer() -> dict:
    """Architecture of the metamodel shipped in the package."""
    from buildenv.metamodel import surrogate as sg

    return dict(sg.load_metamodel("default").checkpoint.config)


def run_tag(config: dict) -> str:
    """Short stable name of a model configuration (for run file names)."""
    import hashlib

    return hashlib.sha1(json.dumps(config, sort_keys=True).encode()).hexdigest()[:8]


def trained(tag: str, runs: Path, data: str, model: str, config: dict, **options) -> dict:
    """Result of :func:`buildenv.metamodel.training.train_metamodel` for the run ``<runs>/<tag>.pt``, trained
    unless its result ``<tag>.json`` is there (an unfinished run resumes from ``<tag>.pt.last``)."""
    from buildenv.metamodel.training import train_metamodel

    runs.mkdir(parents=True, exist_ok=True)
    result_path = runs / f"{tag}.json"
    if result_path.exists():
        return json.loads(result_path.read_text())
    result = train_metamodel(data, model, runs / f"{tag}.pt", model_config=config, **options)
    result_path.write_text(json.dumps(result) + "\n")
    return result


def inference_speed(model: str, config: dict, batch: int | None = None, weeks: int = 4096, repeats: int = 3) -> float:
    """Best-of-``repeats`` weeks per second of batched inference (all cores, random encoded weeks, eager
    PyTorch) for an architecture; weights do not matter."""
    return inference_speeds({"": (model, config)}, batch, weeks, repeats)[""]


def inference_speeds(
    archs: dict[str, tuple[str, dict]], batch: int | None = None, weeks: int = 4096, repeats: int = 3
) -> dict[str, float]:
    """:func:`inference_speed` of several architectures (label -> (model, config)), timed in turn within each
    of ``repeats`` rounds, so that a slow spell of a shared machine falls on all of them alike."""
    import torch

    from buildenv.metamodel import surrogate as sg
    from metamodels.models import build

    batch = sg.INFERENCE_BATCH if batch is None else batch
    torch.manual_seed(0)
    nets = {label: build(model, len(sg.INPUT_CHANNELS), 8, **config).eval() for label, (model, config) in archs.items()}
    x = torch.randn(weeks, sg.CONTEXT_HOURS + 168, len(sg.INPUT_CHANNELS))
    best = dict.fromkeys(nets, float("inf"))
    with torch.inference_mode():
        for net in nets.values():
            net(x[:batch])
        for _ in range(repeats):
            for label, net in nets.items():
                started = time.perf_counter()
                for start in range(0, weeks, batch):
                    net(x[start : start + batch])
                best[label] = min(best[label], time.perf_counter() - started)
    return {label: weeks / seconds for label, seconds in best.items()}


def energyplus_weeks_per_second(weeks: int, zoning: str) -> float:
    """Time a real campaign of ``weeks`` weeks of the ``zoning`` shoebox with all cores; weeks per second."""
    import shutil
    import tempfile

    from buildenv.campaign.runs import CampaignConfig, run_campaign

    out = Path(tempfile.mkdtemp(prefix="bench-eplus-")) / "data"
    try:
        started = time.perf_counter()
        run_campaign(
            CampaignConfig(weeks=weeks, seed=0, epw=["usa_il_chicago", "usa_fl_miami"], zoning=zoning),
            out,
            progress=False,
        )
        return weeks / (time.perf_counter() - started)
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)


def product_arrays(surrogate, weeks: int) -> dict:
    """Catalogue arrays of ``weeks`` dataset-like weeks for :meth:`Surrogate.predict` (Chicago's weather)."""
    import numpy as np

    from buildenv import catalogue as cat
    from buildenv.campaign.sampling import sample_group, sample_weeks
    from buildenv.metamodel import surrogate as sg
    from buildenv.weather.epw import load_weather

    rng = np.random.default_rng(0)
    theta = sample_group("theta_build", weeks, rng)
    settings, occupancy = sample_weeks(weeks, rng)
    year = load_weather("usa_il_chicago").weeks(0, cat.WEEKS_PER_YEAR)
    week_of_year = np.arange(weeks) % cat.WEEKS_PER_YEAR
    ground = sg.ground_hours(
        sg.weather_ground_c("usa_il_chicago"), week_of_year * cat.HOURS_PER_WEEK, surrogate.context_hours
    )
    return {
        "theta": theta,
        "settings": settings,
        "occupancy": occupancy,
        "weather": year[week_of_year],
        "ground_c": ground,
    }


def predict_weeks_per_second(surrogate, arrays: dict, batch: int, repeats: int, workers: int | None = None) -> float:
    """Best-of-``repeats`` speed of ``surrogate.predict`` on ``arrays`` (:func:`product_arrays`) with ``workers``
    threads (``None``: the default, as many as torch has threads; 1: torch alone)."""
    surrogate.workers = workers
    weeks = len(arrays["theta"])
    surrogate.predict(**{k: v[:batch] for k, v in arrays.items()})
    best = float("inf")
    for _ in range(repeats):
        started = time.perf_counter()
        surrogate.predict(**arrays, batch_size=batch)
        best = min(best, time.perf_counter() - started)
    return weeks / best


def surrogate_weeks_per_second(weeks: int, batch: int, repeats: int, checkpoint: str | None = None) -> float:
    """Best-of-``repeats`` speed of ``load_metamodel(checkpoint).predict`` on dataset-like catalogue arrays
    (``None``: the shipped default), its default workers."""
    from buildenv.metamodel import surrogate as sg

    surrogate = sg.load_metamodel(checkpoint)
    return predict_weeks_per_second(surrogate, product_arrays(surrogate, weeks), batch, repeats)


def mean_std(result: dict, key: str, scale: float = 1.0, digits: int = 3) -> str:
    """``"mean (std)"`` of a metric of a result's test block."""
    test = result["test"]
    return f"{test[key] * scale:.{digits}f} ({test[key + '_std'] * scale:.{digits}f})"


def speed_lines(speed: dict, eplus: float, label: str = "model") -> list[str]:
    """Markdown lines of a speed table: ``speed`` ``{name: weeks/s}`` of ``load_metamodel(CKPT).predict``
    against the core + perimeter EnergyPlus shoebox's ``eplus`` weeks/s, timed in the same run."""
    lines = [
        "",
        "Speed in the same run, `load_metamodel(CKPT).predict` of 4,096 weeks from catalogue arrays "
        "(encoding included, traced, batches of 128, best of 3), against the core + perimeter EnergyPlus "
        f"shoebox ({eplus:.1f} weeks/s):",
        "",
        f"| {label} | weeks/s | x EnergyPlus |",
        "|---|---|---|",
    ]
    return lines + [f"| {name} | {value:,.0f} | {value / eplus:.0f} |" for name, value in speed.items()]


# --- the blind checks' records ----------------------------------------------------------------------------------
#
# ``bench/results/gap_check.json`` holds every blind-check site at its latest diagnosis record, one a site
# (``seed<S>_case_<NNN>``, a clean twin ``..._twin``), slimmed to what judging its first step needs. A record's
# candidates are stored as ``{effect: [held-out gain, p-value, gain on the temperature, gain on the consumption,
# estimate]}`` in the diagnosis's order; :func:`expand_record` gives back the diagnosis's own fields.

ALONE = "estimate alone"  # how :func:`naming` says a record names its effect by the estimate alone
NIGHT_FIRST = "night electricity"  # ... and by the night electricity its model carries
SITE = re.compile(r"seed(\d+)_case_(\d+)(_twin)?$")
SERIES = ("temperature", "consumption")
CHECKS = RESULTS / "gap_check.json"


def slim_record(record: dict) -> dict:
    """A diagnosis record as ``gap_check.json`` keeps it: the case, its truth and naming, its fit weeks'
    irradiance and its first step's candidates (``ranked`` follows from the gains and is left out)."""
    keep = ("case", "true", "twin_of", "magnitude", "start", "named", "fit_irradiance_w_m2", "source")
    out = {k: record[k] for k in keep if k in record}
    if record.get("joint_tests"):
        out["joint_tests"] = record["joint_tests"]
    gains = record.get("gains_by_series", {})
    out["candidates"] = {
        name: [
            record["scores"][name],
            record["p_values"][name],
            *(gains.get(name, {}).get(s) for s in SERIES),
            record["estimates"][name],
        ]
        for name in record["scores"]
    }
    return out


def expand_record(slim: dict) -> dict:
    """The diagnosis record a :func:`slim_record` stands for (``scores``, ``p_values``, ``gains_by_series``,
    ``estimates`` and ``ranked`` by held-out gain)."""
    record = {k: v for k, v in slim.items() if k != "candidates"}
    candidates = slim["candidates"]
    record["scores"] = {n: c[0] for n, c in candidates.items()}
    record["p_values"] = {n: c[1] for n, c in candidates.items()}
    record["gains_by_series"] = {
        n: dict(zip(SERIES, c[2:4])) for n, c in candidates.items() if c[2] is not None or c[3] is not None
    }
    record["estimates"] = {n: c[4] for n, c in candidates.items()}
    record["ranked"] = sorted(record["scores"], key=lambda n: -record["scores"][n])
    return record


def checks_json(sites: Mapping[str, dict], sources: list[dict], about: str) -> str:
    """``gap_check.json``'s text: ``about``, the ``sources`` (the runs that recorded the sites) and the slim
    ``sites`` in seed and case order, one a line."""

    def order(site: str) -> tuple:
        seed, case, twin = SITE.match(site).groups()
        return int(seed), int(case), bool(twin)

    body = ",\n".join(
        f"{json.dumps(site)}:{json.dumps(sites[site], separators=(',', ':'))}" for site in sorted(sites, key=order)
    )
    listed = ",\n".join(json.dumps(source, separators=(",", ":")) for source in sources)
    return f'{{"about": {json.dumps(about)},\n"sources": [\n{listed}\n],\n"sites": {{\n{body}\n}}}}\n'


def naming(
    row: dict,
    alpha: float,
    min_gain: float,
    clean_ceilings: bool | Mapping[str, float] = True,
    estimate_ceilings: bool | Mapping[str, float] = False,
) -> tuple[str, str]:
    """The effect a recorded case's first step names under the current plausibility rules, and how: ``(name,
    "held-out gain" | "joint test" | "estimate alone" | "night electricity")``, or ``("none", "")``.

    The candidates are judged as :func:`buildenv.diagnosis.gap.candidate_qualifies` judges them; when none
    qualifies, the joint tests the record ran, then the estimates against ``estimate_ceilings``
    (:func:`buildenv.diagnosis.gap.named_by_estimate`); with estimate ceilings on, a night electricity far beyond
    its ceiling names night plug loads first (:func:`buildenv.diagnosis.gap.night_load_named_first`). A record
    with its fit weeks' irradiance (``fit_irradiance_w_m2``, W/m2) has the catalogue's ceilings judged at it.
    """
    from buildenv.diagnosis.effects import ceilings_in_sunshine
    from buildenv.diagnosis.gap import NIGHT_LOADS, night_load_named_first

    irradiance = row.get("fit_irradiance_w_m2")
    if clean_ceilings is True and irradiance is not None:
        clean_ceilings = ceilings_in_sunshine(irradiance)
    if estimate_ceilings is True and irradiance is not None:
        estimate_ceilings = ceilings_in_sunshine(irradiance, "estimate")
    name, how = _naming_by_gain(row, alpha, min_gain, clean_ceilings, estimate_ceilings)
    ceilings = False if clean_ceilings is False else estimate_ceilings
    if (name, how) != (NIGHT_LOADS, "held-out gain") and night_load_named_first(row["estimates"], ceilings):
        return NIGHT_LOADS, NIGHT_FIRST
    return name, how


def _naming_by_gain(
    row: dict,
    alpha: float,
    min_gain: float,
    clean_ceilings: bool | Mapping[str, float],
    estimate_ceilings: bool | Mapping[str, float],
) -> tuple[str, str]:
    """:func:`naming` without the night-electricity rule."""
    from buildenv.diagnosis.blind_check import NONE
    from buildenv.diagnosis.gap import absorbed_candidate, candidate_qualifies, joint_test_qualifies, named_by_estimate

    threshold = alpha / len(row["p_values"])
    ranked = sorted(row["scores"], key=lambda n: -row["scores"][n])
    for name in ranked:
        if candidate_qualifies(
            name,
            row["scores"][name],
            row["p_values"][name],
            threshold,
            min_gain,
            row["estimates"][name],
            row.get("gains_by_series", {}).get(name),
            clean_ceilings,
        ):
            return name, "held-out gain"
    joint = row.get("joint_tests", {})
    for name in ranked:
        if absorbed_candidate(name, row["estimates"][name], clean_ceilings):
            if name in joint and joint_test_qualifies(name, joint[name], threshold, clean_ceilings):
                return name, "joint test"
    alone = named_by_estimate(
        row["estimates"],
        row["scores"],
        False if clean_ceilings is False else estimate_ceilings,
        row.get("gains_by_series"),
    )
    return (alone[0], ALONE) if alone else (NONE, "")


def judge(record: dict) -> tuple[str, str]:
    """The effect a diagnosis record's first step names under the catalogue's current ceilings, and how
    (:func:`naming` at the diagnosis's significance level, estimate ceilings on)."""
    from buildenv.diagnosis.effects import MIN_GAIN
    from buildenv.diagnosis.gap import DiagnosisSettings

    return naming(record, DiagnosisSettings().alpha, MIN_GAIN, estimate_ceilings=True)


def records_from_checks(path: str | Path) -> dict[str, tuple[dict, str, str]]:
    """``{site: (record, true effect, source)}`` of a ``gap_check.json`` (a clean twin's true effect is none)."""
    from buildenv.diagnosis.blind_check import NONE

    sites = json.loads(_path(path).read_text())["sites"]
    return {
        site: (expand_record(s), NONE if s.get("twin_of") else s["true"], s.get("source", Path(path).stem))
        for site, s in sites.items()
    }


def records_from_rediagnosis(path: str) -> dict[str, tuple[dict, str, str]]:
    """``{site: (record, true effect, source)}`` of a rediagnosis json (its ``records``; a clean twin's true
    effect is none)."""
    from buildenv.diagnosis.blind_check import NONE

    page = json.loads(_path(path).read_text())
    return {site: (r, NONE if r.get("twin_of") else r["true"], Path(path).stem) for site, r in page["records"].items()}


def records_from_run(path: str) -> dict[str, tuple[dict, str, str]]:
    """``{site: (record, true effect, source)}`` of one run's json of ``bench/gap_check.py`` (its ``cases``)."""
    page = json.loads(_path(path).read_text())
    seed = page["plan"]["seed"]
    return {f"seed{seed}_case_{r['case']:03d}": (r, r["true"], Path(path).stem) for r in page["cases"]}


def diagnosed_records(
    rediagnosed: list[str], runs: list[str], checks: list[str] = ()
) -> dict[str, tuple[dict, str, str]]:
    """Every diagnosed site's latest record (``checks`` first, then rediagnoses, then runs; later pages over
    earlier ones), each with its fit weeks' irradiance (``fit_irradiance_w_m2``, W/m2: :func:`irradiance_of_sites`
    where the record lacks it and a page gives the weeks' weather)."""
    out: dict[str, tuple[dict, str, str]] = {}
    for path in checks:
        out |= records_from_checks(path)
    for paths, read in ((rediagnosed, records_from_rediagnosis), (runs, records_from_run)):
        for path in paths:
            out |= read(path)
    missing = [site for site, (record, _, _) in out.items() if "fit_irradiance_w_m2" not in record]
    if missing:
        irradiance = irradiance_of_sites(runs + [p for path in rediagnosed for p in pages_of(path)])
        for site in missing:
            record, truth, source = out[site]
            if site.removesuffix("_twin") in irradiance:
                out[site] = ({**record, "fit_irradiance_w_m2": irradiance[site.removesuffix("_twin")]}, truth, source)
    return out


def pages_of(path: str) -> list[str]:
    """The run pages a rediagnosis json diagnosed the sites of (its command's ``--page`` options)."""
    words = shlex.split(json.loads(_path(path).read_text())["command"])
    return [page for option, page in zip(words, words[1:]) if option == "--page"]


def irradiance_of_sites(pages: list[str]) -> dict[str, float]:
    """``{site: W/m2}``: the fit weeks' mean global horizontal irradiance
    (:func:`buildenv.diagnosis.gap.fit_irradiance_w_m2`) of every case of run pages (a clean twin has its case's
    weeks), from each case's first Monday and the page's weather, weeks and split (none for a page without them)."""
    from buildenv.diagnosis.gap import fit_irradiance_w_m2, split_weeks
    from buildenv.weather.epw import epw_hours, load_weather

    out: dict[str, float] = {}
    for path in dict.fromkeys(pages):
        page = json.loads(_path(path).read_text())
        plan = page["plan"]
        if not {"epw", "weeks", "settings"} <= set(plan):
            continue
        hourly = load_weather(plan["epw"]).hourly
        fit = split_weeks(plan["weeks"], plan["settings"]["split"])[0]
        for case in page["cases"]:
            weather = hourly[epw_hours(dt.date.fromisoformat(case["start"]), plan["weeks"])]
            out[f"seed{plan['seed']}_case_{case['case']:03d}"] = fit_irradiance_w_m2(weather, fit)
    return out


def _path(path: str | Path) -> Path:
    """A page's path as given, else from the repository root."""
    path = Path(path)
    return path if path.is_absolute() or path.exists() else ROOT / path


def add_sources(p: argparse.ArgumentParser) -> None:
    """The blind checks' records as options: ``--checks`` files (default ``bench/results/gap_check.json`` when no
    other source is given), ``--rediagnosed`` and ``--run`` pages (repeatable), or ``--sources-of`` a headline's
    json, whose recorded command gives them."""
    p.add_argument(
        "--checks",
        action="append",
        default=[],
        help="a merged gap_check.json (default: bench/results/gap_check.json when no other source is given)",
    )
    p.add_argument("--rediagnosed", action="append", default=[], help="a rediagnosis json (its records)")
    p.add_argument("--run", action="append", default=[], help="one run's json of bench/gap_check.py")
    p.add_argument(
        "--sources-of",
        default="",
        metavar="HEADLINE_JSON",
        help="take the sources from this headline's recorded command",
    )


def _options(path: str | Path) -> list[tuple[str, str]]:
    words = shlex.split(json.loads(_path(path).read_text())["command"])
    return list(zip(words, words[1:]))


def headline_sources(path: str | Path) -> tuple[list[str], list[str]]:
    """The ``--rediagnosed`` and ``--run`` pages of the headline json at ``path``, read off its recorded command;
    a headline built from ``--replayed`` pages too cannot be replayed and raises ``ValueError``."""
    pairs = _options(path)
    if any(option == "--replayed" for option, _ in pairs):
        raise ValueError(f"{path}: its headline counts --replayed pages, which a replay cannot judge again")
    return ([p for option, p in pairs if option == "--rediagnosed"], [p for option, p in pairs if option == "--run"])


def source_pages(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """``args``' ``--rediagnosed`` and ``--run`` pages (:func:`add_sources`): those of ``--sources-of`` first, then
    those given, each page once (a later page replaces an earlier one's sites)."""
    rediagnosed, runs = headline_sources(args.sources_of) if args.sources_of else ([], [])
    return (list(dict.fromkeys(rediagnosed + args.rediagnosed)), list(dict.fromkeys(runs + args.run)))


def check_files(args: argparse.Namespace, default: bool = True) -> list[str]:
    """``args``' ``--checks`` files: those of ``--sources-of`` first, then those given; with ``default``,
    ``bench/results/gap_check.json`` when no source at all is given."""
    given = list(getattr(args, "checks", []) or [])
    sources_of = getattr(args, "sources_of", "")
    checks = [p for option, p in _options(sources_of) if option == "--checks"] if sources_of else []
    checks = list(dict.fromkeys(checks + given))
    others = any(getattr(args, k, None) for k in ("rediagnosed", "run", "replayed", "sources_of"))
    if not checks and default and not others:
        checks = [os.path.relpath(CHECKS, Path.cwd()) if Path.cwd() == ROOT else str(CHECKS)]
    return checks


def judged_sources(args: argparse.Namespace) -> tuple[dict[str, tuple[dict, str, str]], dict[str, str], int, str]:
    """The sites of ``args``' sources (:func:`add_sources`) as the headline judges them: ``(records, {site: named
    now}, how many are named right, the sources as command-line options)``."""
    checks = check_files(args)
    records = diagnosed_records(*source_pages(args), checks)
    before = {site: judge(record)[0] for site, (record, _, _) in records.items()}
    right = sum(before[site] == truth for site, (_, truth, _) in records.items())
    shown = list(getattr(args, "checks", []) or []) if args.sources_of else checks
    options = (
        "".join(f" --checks {p}" for p in shown)
        + "".join(f" --rediagnosed {p}" for p in args.rediagnosed)
        + "".join(f" --run {p}" for p in args.run)
        + (f" --sources-of {args.sources_of}" if args.sources_of else "")
    )
    return records, before, right, options


def replay_scope(records: dict, right: int) -> str:
    """A sentence on what a page judges: ``records`` from :func:`judged_sources`, ``right`` of them named right."""
    return (
        f"{len(records)} sites as `bench/gap_headline.py` judges them ({right} named right), first step only, "
        "in-sample."
    )
