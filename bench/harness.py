"""The benchmarks' shared harness: arguments, a provenance header, and one writer of ``bench/results/<name>``.

Every benchmark is run from the repository root as ``python bench/NAME.py [options]`` and imports this module
from its own folder. :func:`write_results` writes ``bench/results/<name>.md`` (the page, with the provenance line
under its title) and ``<name>.json`` (the record, with the provenance under ``"provenance"``).

The rest are helpers more than one benchmark uses: the metamodel runs and timings, the calibration
benches' machine and CPU meter, and the blind checks' merged records (``bench/gap_check.py``).
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
# ``bench/results/gap_check.json`` holds the cases of every run of ``bench/gap_check.py`` of one setup (matrix,
# weeks, diagnosis settings, base effects), one a line under ``sites`` (``seed<S>_case_<NNN>``, over the suite
# ``seed<S>_<part>_case_<NNN>``), slimmed to what the
# scores (:func:`buildenv.diagnosis.blind_check.summarise`) read.

SITE = re.compile(r"seed(\d+)_(?:([a-z_]+)_)?case_(\d+)$")
CHECKS = RESULTS / "gap_check.json"
#: The fields of a blind-check case :func:`slim_case` keeps as they are.
KEPT = (
    *("case", "true", "magnitude", "start", "building", "climate", "season", "part", "status", "reason"),
    *("named", "answer", "selected", "not_enough_data", "named_raw", "twin_named", "correct", "seconds"),
    *("diagnosis_seconds", "twin_diagnosis_seconds"),
)


def slim_case(row: dict) -> dict:
    """A blind-check case as ``gap_check.json`` keeps it: the fields of :data:`KEPT`, the shrinkage of its effect's
    gap (``of_effect_gap``, ``of_total_gap``), the gap its effect left (``share``, ``left``), whether its footprint
    is visible, and the first step's candidates as ``{effect: [held-out gain, p-value, [rules failed]]}``, best
    gain first (a refused case has none)."""
    out = {k: row[k] for k in KEPT if k in row}
    if row.get("shrinkage"):
        out["shrinkage"] = {k: row["shrinkage"][k] for k in ("of_effect_gap", "of_total_gap")}
    if "gap_left" in row:
        out["gap_left"] = {k: row["gap_left"][k] for k in ("share", "left")}
    if "footprint" in row:
        out["footprint"] = {"visible": row["footprint"]["visible"]}
    if "ranked" in row:
        out["candidates"] = {n: [row["scores"][n], row["p_values"][n], row["failed"][n]] for n in row["ranked"]}
    return out


def expand_case(slim: dict) -> dict:
    """The case a :func:`slim_case` stands for: ``ranked``, ``scores``, ``p_values`` and ``failed`` back from its
    candidates, a shrinkage written as null (not defined) back to NaN."""
    row = {k: v for k, v in slim.items() if k != "candidates"}
    if "shrinkage" in slim:
        row["shrinkage"] = {k: float("nan") if v is None else v for k, v in slim["shrinkage"].items()}
    if "candidates" in slim:
        candidates = slim["candidates"]
        row["ranked"] = list(candidates)
        for i, key in enumerate(("scores", "p_values", "failed")):
            row[key] = {n: c[i] for n, c in candidates.items()}
    return row


def checks_json(header: Mapping, sites: Mapping[str, dict]) -> str:
    """``gap_check.json``'s text: each entry of ``header`` on a line, then the slim ``sites`` in seed and case order,
    one a line (non-finite numbers as null)."""

    def line(value) -> str:
        return dumps(value, where="gap_check.json", nonfinite="null", separators=(",", ":"), default=_jsonable)

    def order(site: str) -> tuple[int, str, int]:
        seed, part, case = SITE.match(site).groups()
        return int(seed), part or "", int(case)

    head = "".join(f"{json.dumps(key)}: {line(value)},\n" for key, value in header.items() if key != "sites")
    body = ",\n".join(f"{json.dumps(site)}:{line(sites[site])}" for site in sorted(sites, key=order))
    return f'{{{head}"sites": {{\n{body}\n}}}}\n'


def read_checks(path: str | Path = CHECKS) -> dict:
    """A ``gap_check.json`` (``path`` as given, else from the repository root), its sites slim (:func:`slim_case`).

    Raises:
        ValueError: the file holds no ``setup`` or a site without an ``answer``: records of an earlier diagnosis.
    """
    path = Path(path)
    path = path if path.is_absolute() or path.exists() else ROOT / path
    checks = json.loads(path.read_text())
    old = next(
        (s for s, r in checks.get("sites", {}).items() if "answer" not in r and r.get("status") != "refused"), None
    )
    if "setup" not in checks or old is not None:
        raise ValueError(
            f"{path}: records of an earlier diagnosis ({old or 'no setup'}); run bench/gap_check.py with the "
            "current one, or give the file it wrote"
        )
    return checks
