"""Guards on the estimate-alone rule replayed on the headline's sites: what each would hold back or name.

A first step that selects nothing names a candidate beyond every clean site's by its estimate alone
(:func:`buildenv.gap.named_by_estimate`), unless it is a sensor effect reading its own series worse held out (the
sensor rule, :func:`buildenv.gap.sensor_reading_made_worse`). From seed 29 to seed 86 it also had to gain at least
-10 % held out (:data:`buildenv.effects.ESTIMATE_ALONE_LOWEST_GAIN`, None since): that guard was dropped once fresh
seeds showed it held back only right namings beside the sensor rule. This shows, on every site the headline counts
(``bench/gap_headline.py``'s sources, judged as it judges them, first step only):

- every site the sensor rule holds back (what the rule would name without it), right or wrong;
- each site whose naming changes with a guard at each ``--lowest-gain``, and what that nets;
- every site named by the estimate alone now, with its held-out gain on each measured series, worst first (what a
  guard on each series would hold back).

It is an in-sample replay of recorded first steps: a guard read off it is tested only by fresh seeds. Run from the
repository root with the headline's sources (or its ``--rediagnosed`` and ``--run`` pages one by one)::

    .venv/bin/python bench/gap_guard_replay.py --lowest-gain -0.05 --lowest-gain -0.1 --lowest-gain -0.15 \\
        --lowest-gain -0.2 --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_guard_estimate_alone``).
"""

from __future__ import annotations

import argparse
import time

from gap_floor_replay import net_change
from gap_headline import add_sources, judge, judged_sources, judged_with, replay_scope, write_results

import buildenv.gap as gap
from buildenv.effects import get_effect


def renamed(records: dict[str, tuple[dict, str, str]], lowest_gain: float | None,
            before: dict[str, str]) -> list[dict]:
    """The sites whose first step names something else with a guard at ``lowest_gain`` (a held-out gain, -0.15 for
    -15 %; None: no guard), each with the held-out gain and the estimate (its ceiling's quantity) of what it names
    then, or of what it named before where it names nothing then."""
    return _changed(records, before, judged_with(records, "ESTIMATE_ALONE_LOWEST_GAIN", lowest_gain))


def without_sensor_rule(record: dict) -> dict:
    """``record`` without its sensor effects' held-out gains by series: judged so, the estimate-alone rule names a
    sensor effect that reads its series worse held out (:func:`buildenv.gap.sensor_reading_made_worse` needs those
    gains; no other rule reads a sensor effect's)."""
    series = {name: gains for name, gains in record.get("gains_by_series", {}).items()
              if get_effect(name).kind != "sensor"}
    return record | {"gains_by_series": series}


def held_back_by_sensor_rule(records: dict[str, tuple[dict, str, str]], before: dict[str, str]) -> list[dict]:
    """The sites whose first step would name otherwise without the sensor rule (:func:`without_sensor_rule`), as
    :func:`renamed` lists them."""
    after = {site: judge(without_sensor_rule(record))[0] for site, (record, _, _) in records.items()}
    return _changed(records, before, after)


def _changed(records: dict[str, tuple[dict, str, str]], before: dict[str, str], after: dict[str, str]) -> list[dict]:
    """The sites named otherwise ``after`` than ``before`` (:func:`renamed`'s rows)."""
    rows = []
    for site, (record, truth, _) in records.items():
        if after[site] != before[site]:
            named = after[site] if after[site] in record["scores"] else before[site]
            size = get_effect(named).ceiling_on
            rows.append({"site": site, "true": truth, "before": before[site], "after": after[site],
                         "gain": record["scores"][named], "estimate": record["estimates"][named].get(size)})
    return rows


def by_worst_series(records: dict[str, tuple[dict, str, str]], before: dict[str, str]) -> list[dict]:
    """Every site named by the estimate alone now (``before``: what each site names now), with its candidate's
    held-out gain pooled and on each measured series (fractions; -0.26 for 26 % worse), worst series first (``worst``
    None, listed last, where the record keeps no series): what a guard on each series, not the pooled gain, would
    hold back."""
    rows = []
    for site, (record, truth, _) in records.items():
        if judge(record)[1] != "estimate alone":
            continue
        named = before[site]
        series = record.get("gains_by_series", {}).get(named, {})
        rows.append({"site": site, "true": truth, "named": named, "gain": record["scores"][named],
                     "series": series, "worst": min(series.values(), default=None)})
    return sorted(rows, key=lambda row: (row["worst"] is None, row["worst"] or 0.0))


def _row(row: dict) -> str:
    """A renamed site as a table row."""
    estimate = "-" if row["estimate"] is None else f"{row['estimate']:.4g}"
    return (f"| {row['site']} | {row['true']} | {row['before']} | {row['after']} | {100 * row['gain']:.1f} % "
            f"| {estimate} |")


def _series_gain(series: dict[str, float], key: str) -> str:
    """One series' held-out gain as a percentage, or ``-`` where the record does not keep it."""
    return f"{100 * series[key]:.1f} %" if key in series else "-"


def _guard_now() -> str:
    """The guard the diagnosis runs with, as a sentence."""
    lowest = gap.ESTIMATE_ALONE_LOWEST_GAIN
    if lowest is None:
        return "No guard on the held-out gain now (a -10 % one ran from seed 29 to seed 86)."
    return f"Guard now: a held-out gain of at least {100 * lowest:g} %."


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lowest-gain", type=float, action="append", required=True,
                        help="a guard to replay: the lowest held-out gain named by estimate (-0.15 for -15 %)")
    add_sources(parser)
    parser.add_argument("--name", default="gap_guard_estimate_alone")
    args = parser.parse_args()
    records, before, right, sources = judged_sources(args)
    sensor_held = held_back_by_sensor_rule(records, before)
    changes = {value: renamed(records, value, before) for value in args.lowest_gain}
    command = ("python bench/gap_guard_replay.py" + "".join(f" --lowest-gain {v:g}" for v in args.lowest_gain)
               + sources + f" --name {args.name}")
    header = ["| site | injected | named now | named then | its held-out gain | its estimate |",
              "|---|---|---|---|---|---|"]
    lines = [f"# Gap diagnosis: guards on the estimate-alone rule replayed ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}`.", "",
             replay_scope(records, right) + f" {_guard_now()}", "",
             "## Sites the sensor rule holds back (a sensor effect reading its series worse held out)", "",
             "`buildenv.gap.sensor_reading_made_worse`: set from seeds 0-80's records, tested by fresh seeds "
             "from 81.", "", *header, *[_row(r) for r in sorted(sensor_held, key=lambda r: -r["gain"])],
             f"| **net without the sensor rule** | | | | | {net_change(sensor_held)} |", "",
             "## Sites named otherwise with a guard on the held-out gain", "", "| guard | " + header[0][2:],
             "|---" + header[1]]
    for value, rows in changes.items():
        lines += [f"| {100 * value:g} % " + _row(r) for r in rows]
        lines.append(f"| {100 * value:g} % | **net** | | | | | {net_change(rows)} |")
    worst = by_worst_series(records, before)
    lines += ["", "## Sites named by the estimate alone now, by their worst series held out", "",
              "| site | injected | named | held-out gain | " + " | ".join(gap.SERIES) + " |",
              "|---|---|---|---" + "|---" * len(gap.SERIES) + "|",
              *[f"| {r['site']} | {r['true']} | {r['named']} | {100 * r['gain']:.1f} % | "
                + " | ".join(_series_gain(r["series"], key) for key in gap.SERIES) + " |"
                for r in worst]]
    write_results(args.name, lines, {
        "command": command, "lowest_gain_now": gap.ESTIMATE_ALONE_LOWEST_GAIN, "sites": len(records),
        "right_now": right, "held_back_by_sensor_rule": sensor_held,
        "renamed": {str(v): rows for v, rows in changes.items()},
        "named_by_estimate": worst})


if __name__ == "__main__":
    main()
