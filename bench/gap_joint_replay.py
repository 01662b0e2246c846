"""The joint test's clean-site ceiling replayed on the headline's sites: what a joint test names with and without it.

When nothing qualifies, a candidate whose refit estimate lies beyond every clean site's is calibrated from scratch
with and without it (:func:`buildenv.gap.joint_fallback`), and named when that test gains significantly held out
with an estimate still beyond its ceiling (:func:`buildenv.gap.joint_test_qualifies`). A fresh seed's clean twin
named a 0.41 h sensor lag by a joint test whose estimate had fallen back among the clean sites' (seed 47's case 7
twin), so the ceiling was replayed on every site the headline counts (``bench/gap_headline.py``'s sources, judged
as it judges them, first step only):

- every site a joint test names with the ceiling off (its refit and joint estimates, the ceiling, the joint gain);
- the sites the ceiling names otherwise, and what that nets.

It is an in-sample replay of recorded first steps: only fresh seeds test it. A record that did not run the joint
test of a candidate the ceiling would reach next names nothing there (``bench/gap_check_rejudge.naming``). Run from
the repository root with the headline's sources (or its ``--rediagnosed`` and ``--run`` pages one by one)::

    .venv/bin/python bench/gap_joint_replay.py --sources-of bench/results/gap_headline.json

Writes ``bench/results/<name>.{md,json}`` (default name ``gap_joint_replay``).
"""

from __future__ import annotations

import argparse
import time

import gap_check_rejudge
from gap_floor_replay import net_change
from gap_headline import add_sources, judge, judged_sources, replay_scope, write_results

from buildenv.effects import get_effect


def judged_without_ceiling(records: dict[str, tuple[dict, str, str]]) -> dict[str, tuple[str, str]]:
    """``{site: (named, how)}`` with the joint test judged by its gain, significance and plausibility alone."""
    qualifies = gap_check_rejudge.joint_test_qualifies
    gap_check_rejudge.joint_test_qualifies = lambda name, test, threshold, _ceilings=True: qualifies(
        name, test, threshold, False)
    try:
        return {site: judge(record) for site, (record, _, _) in records.items()}
    finally:
        gap_check_rejudge.joint_test_qualifies = qualifies


def joint_namings(records: dict[str, tuple[dict, str, str]], without: dict[str, tuple[str, str]],
                  before: dict[str, str]) -> list[dict]:
    """The sites a joint test names with the ceiling off: the candidate's refit and joint estimates (its ceiling's
    quantity), the ceiling, the joint test's held-out gain and what the site names with the ceiling."""
    rows = []
    for site, (record, truth, _) in records.items():
        named, how = without[site]
        if how != "joint test":
            continue
        effect, test = get_effect(named), record["joint_tests"][named]
        rows.append({"site": site, "true": truth, "named": named, "with_ceiling": before[site],
                     "refit": record["estimates"][named].get(effect.ceiling_on),
                     "joint": test["estimate"].get(effect.ceiling_on), "ceiling": effect.clean_ceiling,
                     "gain": test["gain"]})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_sources(parser)
    parser.add_argument("--name", default="gap_joint_replay")
    args = parser.parse_args()
    records, before, right, sources = judged_sources(args)
    without = judged_without_ceiling(records)
    rows = joint_namings(records, without, before)
    changed = [{"site": site, "true": truth, "before": before[site], "after": without[site][0]}
               for site, (_, truth, _) in records.items() if without[site][0] != before[site]]
    command = "python bench/gap_joint_replay.py" + sources + f" --name {args.name}"
    lines = [f"# Gap diagnosis: the joint test's clean-site ceiling replayed ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}`.", "",
             replay_scope(records, right) + " A joint test now names its candidate only with an estimate beyond "
             "the candidate's clean-site ceiling.", "",
             "## Sites a joint test names without the ceiling", "",
             "| site | injected | named by the joint test | refit estimate | joint estimate | ceiling | joint gain "
             "| named with the ceiling |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['site']} | {r['true']} | {r['named']} | {r['refit']:.4g} | {r['joint']:.4g} | {r['ceiling']:g} "
              f"| {100 * r['gain']:.1f} % | {r['with_ceiling']} |" for r in rows]
    lines += ["", "## Sites named otherwise without the ceiling", "", "| site | injected | named now | without |",
              "|---|---|---|---|", *[f"| {r['site']} | {r['true']} | {r['before']} | {r['after']} |" for r in changed],
              f"| **net without the ceiling** | | | {net_change(changed)} |"]
    write_results(args.name, lines, {"command": command, "sites": len(records), "right_now": right,
                                     "joint_namings": rows, "renamed": changed})


if __name__ == "__main__":
    main()
