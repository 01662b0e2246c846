"""The blind checks' headline: every seed's sites at their latest judgement, counted in one table.

The withheld-effect checks ran over many sessions while the diagnosis changed, so a seed's sites are judged from
the most recent source that holds them, in this order of precedence (a later one replaces an earlier one, site by
site):

1. ``--replayed``: the records of the checks' own day judged again with later rules, without a new diagnosis
   (``bench/gap_night_electricity.py``'s json: its night-electricity rule, other seeds' ceilings, joint tests);
2. ``--rediagnosed``: records of sites diagnosed again with the code of their day
   (``bench/gap_wind_centred.py``'s json, twins included);
3. ``--run``: ``bench/gap_check.py`` pages run with the current diagnosis (fresh seeds, or old seeds run again).

Sources 2 and 3 are judged again here with the catalogue's ceilings (``bench/gap_check_rejudge.first_named``),
so each of their sites counts as today's code names it; source 1 keeps the naming its replay gave. Run from the
repository root::

    .venv/bin/python bench/gap_headline.py --rediagnosed bench/results/gap_wind_centred_all.json \\
        --rediagnosed bench/results/gap_wind_centred_rerun_0_5.json --rediagnosed ... \\
        --run bench/results/gap_check_rerun_seed0.json ... --name gap_headline

(``bench/results/gap_headline.md`` starts with the full command of its last run. Since every recorded seed's
sites were run or diagnosed again with the current code, the headline needs no ``--replayed`` page; with
``bench/results/gap_night_electricity.json`` added it counts the same.) To add a seed, start from the last run's
sources: ``--sources-of bench/results/gap_headline.json --run bench/results/gap_check_tb_seedN.json`` (the page
records the command in full). The replays (``bench/gap_guard_replay.py``, ``bench/gap_floor_replay.py``,
``bench/gap_joint_replay.py``) take ``--sources-of bench/results/gap_headline.json`` to judge the headline's sites.

Writes ``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import re
import shlex
import time
from pathlib import Path

from gap_check_rejudge import ALONE, naming

import buildenv.gap as gap
from buildenv.effects import MIN_GAIN
from buildenv.gap import DiagnosisSettings, fit_irradiance_w_m2, split_weeks
from buildenv.gap_check import NONE
from buildenv.weather import epw_hours, load_weather

RESULTS = Path(__file__).resolve().parent / "results"
ALPHA = DiagnosisSettings().alpha  # the checks' significance level (their plans' settings.alpha)
SITE = re.compile(r"seed(\d+)_case_(\d+)(_twin)?$")


def judge(record: dict) -> tuple[str, str]:
    """The effect a diagnosis record's first step names under the catalogue's current ceilings, and how
    (``bench/gap_check_rejudge.naming``, its estimate-alone rule included)."""
    return naming(record, ALPHA, MIN_GAIN, estimate_ceilings=True)


def judged_with(records: dict[str, tuple[dict, str, str]], setting: str, value) -> dict[str, str]:
    """``{site: named}`` for ``records`` judged (:func:`judge`) with ``buildenv.gap``'s ``setting`` (a module
    attribute: a knob such as ``NIGHT_LOAD_FIRST_BEYOND`` or a rule function) set to ``value``, restored after."""
    now = getattr(gap, setting)
    setattr(gap, setting, value)
    try:
        return {site: judge(record)[0] for site, (record, _, _) in records.items()}
    finally:
        setattr(gap, setting, now)


def sites_from_replay(path: str) -> dict[str, dict]:
    """``{site: {"true", "named", "ranked_first", "source"}}`` of a replay page's sites (ranked first unknown)."""
    page = json.loads(Path(path).read_text())
    return {s["key"]: {"true": NONE if s["key"].endswith("_twin") else s["true"], "named": s["night electricity"],
                       "ranked_first": None, "source": Path(path).stem} for s in page["sites"]}


def _site(record: dict, truth: str, source: str) -> dict:
    """A diagnosis record judged now."""
    ranked = record.get("ranked") or [NONE]
    named, how = judge(record)
    return {"true": truth, "named": named, "how": how, "recorded": record["named"],
            "ranked_first": ranked[0] == truth if truth != NONE else None, "source": source}


def records_from_rediagnosis(path: str) -> dict[str, tuple[dict, str, str]]:
    """``{site: (record, true effect, source)}`` of a ``bench/gap_wind_centred.py`` json (its ``records``; a clean
    twin's true effect is none)."""
    page = json.loads(Path(path).read_text())
    return {site: (r, NONE if r.get("twin_of") else r["true"], Path(path).stem) for site, r in page["records"].items()}


def records_from_run(path: str) -> dict[str, tuple[dict, str, str]]:
    """``{site: (record, true effect, source)}`` of a ``bench/gap_check.py`` page's cases."""
    page = json.loads(Path(path).read_text())
    seed = page["plan"]["seed"]
    return {f"seed{seed}_case_{r['case']:03d}": (r, r["true"], Path(path).stem) for r in page["cases"]}


def diagnosed_records(rediagnosed: list[str], runs: list[str]) -> dict[str, tuple[dict, str, str]]:
    """Every diagnosed site's latest record (runs over rediagnoses, later pages over earlier ones), each with its
    fit weeks' irradiance (``fit_irradiance_w_m2``, W/m2: :func:`irradiance_of_sites` where the record predates
    it; none where no page gives the weeks' weather), so that the catalogue's ceilings are judged at it as a
    diagnosis does."""
    out: dict[str, tuple[dict, str, str]] = {}
    for paths, read in ((rediagnosed, records_from_rediagnosis), (runs, records_from_run)):
        for path in paths:
            out |= read(path)
    irradiance = irradiance_of_sites(runs + [p for path in rediagnosed for p in pages_of(path)])
    for site, (record, truth, source) in out.items():
        if "fit_irradiance_w_m2" not in record and site.removesuffix("_twin") in irradiance:
            out[site] = ({**record, "fit_irradiance_w_m2": irradiance[site.removesuffix("_twin")]}, truth, source)
    return out


def pages_of(path: str) -> list[str]:
    """The ``bench/gap_check.py`` pages a ``bench/gap_wind_centred.py`` json diagnosed the sites of (its command's
    ``--page`` options)."""
    words = shlex.split(json.loads(Path(path).read_text())["command"])
    return [page for option, page in zip(words, words[1:]) if option == "--page"]


def irradiance_of_sites(pages: list[str]) -> dict[str, float]:
    """``{site: W/m2}``: the fit weeks' mean global horizontal irradiance (:func:`buildenv.gap.fit_irradiance_w_m2`)
    of every case of ``bench/gap_check.py`` pages (a clean twin has its case's weeks), from each case's first
    Monday and the page's weather, weeks and split (none for a page without them)."""
    out: dict[str, float] = {}
    for path in dict.fromkeys(pages):
        page = json.loads(Path(path).read_text())
        plan = page["plan"]
        if not {"epw", "weeks", "settings"} <= set(plan):
            continue
        hourly = load_weather(plan["epw"]).hourly
        fit = split_weeks(plan["weeks"], plan["settings"]["split"])[0]
        for case in page["cases"]:
            weather = hourly[epw_hours(dt.date.fromisoformat(case["start"]), plan["weeks"])]
            out[f"seed{plan['seed']}_case_{case['case']:03d}"] = fit_irradiance_w_m2(weather, fit)
    return out


def _count_case(row: dict, site: dict) -> None:
    """Add one effect case to ``row``'s ``cases``, ``right`` (its effect named first; ``alone`` counts those
    named by the estimate alone) and ``wrong`` (another)."""
    row["cases"] += 1
    row["right"] += site["named"] == site["true"]
    row["alone"] += site["named"] == site["true"] and site.get("how") == ALONE
    row["wrong"] += site["named"] not in (site["true"], NONE)


def tally(sites: dict[str, dict]) -> list[dict]:
    """One row a seed: its sources, effect cases, named right and wrong, ranked first, clean cases and twins."""
    seeds: dict[int, dict] = {}
    for site, s in sites.items():
        seed, _, twin = SITE.match(site).groups()
        row = seeds.setdefault(int(seed), {"seed": int(seed), "sources": set(), "cases": 0, "right": 0, "alone": 0,
                                           "wrong": 0, "ranked": 0, "ranked_known": 0, "clean": 0,
                                           "clean_right": 0, "twins": 0, "twins_right": 0, "clean_alone": 0})
        row["sources"].add(s["source"])
        if s["true"] == NONE:
            row["clean_alone"] += s.get("how") == ALONE
        if twin:
            row["twins"] += 1
            row["twins_right"] += s["named"] == NONE
        elif s["true"] == NONE:
            row["clean"] += 1
            row["clean_right"] += s["named"] == NONE
        else:
            _count_case(row, s)
            if s["ranked_first"] is not None:
                row["ranked_known"] += 1
                row["ranked"] += s["ranked_first"]
    return [seeds[k] | {"sources": sorted(seeds[k]["sources"])} for k in sorted(seeds)]


def by_effect(sites: dict[str, dict]) -> dict[str, dict]:
    """``{effect: {"cases", "right", "wrong"}}`` over the effect cases."""
    rows: dict[str, dict] = {}
    for site, s in sites.items():
        if s["true"] == NONE:
            continue
        _count_case(rows.setdefault(s["true"], {"cases": 0, "right": 0, "alone": 0, "wrong": 0}), s)
    return dict(sorted(rows.items()))


def add_sources(parser: argparse.ArgumentParser) -> None:
    """The headline's sources as options: ``--rediagnosed`` and ``--run`` pages (repeatable), or ``--sources-of``
    a headline's json, whose recorded command gives them."""
    parser.add_argument("--rediagnosed", action="append", default=[], help="a bench/gap_wind_centred.py json")
    parser.add_argument("--run", action="append", default=[], help="a bench/gap_check.py json run with today's code")
    parser.add_argument("--sources-of", default="", metavar="HEADLINE_JSON",
                        help="take --rediagnosed and --run from this headline's command (bench/results/"
                             "gap_headline.json: the sites the headline counts)")


def headline_sources(path: str | Path) -> tuple[list[str], list[str]]:
    """The ``--rediagnosed`` and ``--run`` pages of the headline json at ``path``, read off its recorded command;
    a headline built from ``--replayed`` pages too cannot be replayed and raises ``ValueError``."""
    words = shlex.split(json.loads(Path(path).read_text())["command"])
    pairs = list(zip(words, words[1:]))
    if any(option == "--replayed" for option, _ in pairs):
        raise ValueError(f"{path}: its headline counts --replayed pages, which a replay cannot judge again")
    return ([p for option, p in pairs if option == "--rediagnosed"], [p for option, p in pairs if option == "--run"])


def source_pages(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """``args``' ``--rediagnosed`` and ``--run`` pages (:func:`add_sources`): those of ``--sources-of`` first, then
    those given, each page once (a later page replaces an earlier one's sites)."""
    rediagnosed, runs = headline_sources(args.sources_of) if args.sources_of else ([], [])
    return (list(dict.fromkeys(rediagnosed + args.rediagnosed)), list(dict.fromkeys(runs + args.run)))


def judged_sources(args: argparse.Namespace) -> tuple[dict[str, tuple[dict, str, str]], dict[str, str], int, str]:
    """The sites of ``args``' sources (:func:`add_sources`) as the headline judges them: ``(records, {site: named
    now}, how many are named right, the sources as command-line options)``."""
    records = diagnosed_records(*source_pages(args))
    before = {site: judge(record)[0] for site, (record, _, _) in records.items()}
    right = sum(before[site] == truth for site, (_, truth, _) in records.items())
    options = ("".join(f" --rediagnosed {p}" for p in args.rediagnosed) + "".join(f" --run {p}" for p in args.run)
               + (f" --sources-of {args.sources_of}" if args.sources_of else ""))
    return records, before, right, options


def replay_scope(records: dict, right: int) -> str:
    """The replays' sentence on what they judge: ``records`` from :func:`judged_sources`, ``right`` of them named
    right now."""
    return (f"{len(records)} sites as `bench/gap_headline.py` judges them ({right} named right), first step only, "
            "in-sample.")


def write_results(name: str, lines: list[str], data: dict) -> None:
    """``bench/results/<name>.md`` (``lines``) and ``<name>.json`` (``data``), and the page printed."""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{name}.json").write_text(json.dumps(data, indent=1) + "\n")
    print("\n".join(lines))


def _percent(part: int, whole: int, digits: int = 0) -> str:
    """``part/whole (percent %)``, the percentage with ``digits`` decimals, or ``-`` where there is nothing to
    count."""
    return f"{part}/{whole} ({100 * part / whole:.{digits}f} %)" if whole else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replayed", action="append", default=[], help="a bench/gap_night_electricity.py json")
    add_sources(parser)
    parser.add_argument("--name", default="gap_headline")
    args = parser.parse_args()
    sites: dict[str, dict] = {}
    for path in args.replayed:
        sites |= sites_from_replay(path)
    rediagnosed, runs = source_pages(args)
    sites |= {site: _site(*r) for site, r in diagnosed_records(rediagnosed, runs).items()}
    seeds = tally(sites)
    total = {k: sum(r[k] for r in seeds) for k in ("cases", "right", "alone", "wrong", "ranked", "ranked_known",
                                                   "clean", "clean_right", "twins", "twins_right", "clean_alone")}
    effects = by_effect(sites)
    judged_now = [s for s in sites.values() if "recorded" in s]
    changed = sorted(k for k, s in sites.items() if "recorded" in s and s["named"] != s["recorded"])
    command = ("python bench/gap_headline.py " + " ".join(
        [f"--replayed {p}" for p in args.replayed] + [f"--rediagnosed {p}" for p in rediagnosed]
        + [f"--run {p}" for p in runs]) + f" --name {args.name}")
    lines = [f"# Gap diagnosis: the blind checks' headline ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}`.", "",
             "Each site counts at its latest judgement (`bench/gap_headline.py` states the precedence): a run of "
             "`bench/gap_check.py` with the current diagnosis, else a diagnosis again of its recorded site, else the "
             "replay of its record. Diagnosed sites are judged with the catalogue's clean-site and estimate ceilings; "
             f"{len(judged_now) - len(changed)} of the {len(judged_now)} diagnosed sites name what their diagnosis "
             "named" + (f" (the others: {', '.join(changed)})" if changed else "") + ". Ranked first: the "
             "injected effect had the best held-out gain, named or not (not known for replayed sites).", "",
             "| | value | target |", "|---|---|---|",
             f"| seeds | {len(seeds)} ({seeds[0]['seed']}-{seeds[-1]['seed']}) | |",
             f"| injected effect named first | **{_percent(total['right'], total['cases'])}** | >= 90 % |",
             f"| of which named by the estimate alone | {total['alone']} | |",
             f"| named another effect | {total['wrong']} | |",
             f"| ranked first (where known) | {_percent(total['ranked'], total['ranked_known'])} | |",
             f"| clean cases recognised | {_percent(total['clean_right'], total['clean'])} | >= 90 % |",
             f"| clean twins recognised (where diagnosed) | {_percent(total['twins_right'], total['twins'])} | |",
             f"| clean sites named an effect by the estimate alone | {total['clean_alone']} | |",
             "", "## By seed", "",
             "| seed | judged from | named first | named wrong | ranked first | clean cases | clean twins |",
             "|---|---|---|---|---|---|---|"]
    for r in seeds:
        lines.append(f"| {r['seed']} | {', '.join(r['sources'])} | {r['right']}/{r['cases']} | {r['wrong']} | "
                     + (f"{r['ranked']}/{r['ranked_known']}" if r["ranked_known"] else "-")
                     + f" | {r['clean_right']}/{r['clean']} | "
                     + (f"{r['twins_right']}/{r['twins']}" if r["twins"] else "-") + " |")
    lines += ["", "## By injected effect", "",
              "| effect | cases | named first | of which by the estimate alone | named another effect |",
              "|---|---|---|---|---|"]
    for name, row in effects.items():
        lines.append(f"| {name} | {row['cases']} | {_percent(row['right'], row['cases'])} | {row['alone']} | "
                     f"{row['wrong']} |")
    write_results(args.name, lines,
                  {"command": command, "total": total, "seeds": seeds, "by_effect": effects, "sites": sites})


if __name__ == "__main__":
    main()
