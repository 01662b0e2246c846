"""The blind checks' headline: every seed's sites at their latest judgement, counted in one table.

Each site counts once, from the latest source that holds it (a later one replaces an earlier one, site by site):

1. ``--replayed``: records judged again with later rules without a new diagnosis (their ``named`` as given);
2. ``--checks``: the merged records of ``bench/gap_check.py`` (default ``bench/results/gap_check.json``, every
   seed's sites at their latest diagnosis);
3. ``--rediagnosed``: records of sites diagnosed again (a json with ``records``, clean twins included);
4. ``--run``: one run's json of ``bench/gap_check.py``.

Sources 2-4 are judged here with the catalogue's current ceilings (:func:`harness.judge`), so each of their sites
counts as today's code names it. Run from the repository root::

    python bench/gap_headline.py

Writes ``bench/results/NAME.{md,json}`` (``--name``, default ``gap_headline``).
"""

from __future__ import annotations

import json
from pathlib import Path

import harness
from harness import (  # noqa: F401
    ALONE,
    SITE,
    add_sources,
    check_files,
    diagnosed_records,
    headline_sources,
    judge,
    percent,
    records_from_checks,
    records_from_rediagnosis,
    records_from_run,
    source_pages,
)

from buildenv.diagnosis.blind_check import NONE


def sites_from_replay(path: str) -> dict[str, dict]:
    """``{site: {"true", "named", "ranked_first", "source"}}`` of a replay page's sites (ranked first unknown)."""
    page = json.loads(Path(path).read_text())
    return {
        s["key"]: {
            "true": NONE if s["key"].endswith("_twin") else s["true"],
            "named": s["night electricity"],
            "ranked_first": None,
            "source": Path(path).stem,
        }
        for s in page["sites"]
    }


def _site(record: dict, truth: str, source: str) -> dict:
    """A diagnosis record judged now."""
    ranked = record.get("ranked") or [NONE]
    named, how = judge(record)
    return {
        "true": truth,
        "named": named,
        "how": how,
        "recorded": record["named"],
        "ranked_first": ranked[0] == truth if truth != NONE else None,
        "source": source,
    }


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
        row = seeds.setdefault(
            int(seed),
            {
                "seed": int(seed),
                "sources": set(),
                "cases": 0,
                "right": 0,
                "alone": 0,
                "wrong": 0,
                "ranked": 0,
                "ranked_known": 0,
                "clean": 0,
                "clean_right": 0,
                "twins": 0,
                "twins_right": 0,
                "clean_alone": 0,
            },
        )
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
    for s in sites.values():
        if s["true"] == NONE:
            continue
        _count_case(rows.setdefault(s["true"], {"cases": 0, "right": 0, "alone": 0, "wrong": 0}), s)
    return dict(sorted(rows.items()))


def main() -> None:
    parser = harness.parser(__doc__)
    parser.add_argument("--replayed", action="append", default=[], help="a replay json (its sites' namings)")
    add_sources(parser)
    parser.add_argument("--name", default="gap_headline")
    args = parser.parse_args()
    sites: dict[str, dict] = {}
    for path in args.replayed:
        sites |= sites_from_replay(path)
    checks = check_files(args)
    rediagnosed, runs = source_pages(args)
    sites |= {site: _site(*r) for site, r in diagnosed_records(rediagnosed, runs, checks).items()}
    seeds = tally(sites)
    total = {
        k: sum(r[k] for r in seeds)
        for k in (
            "cases",
            "right",
            "alone",
            "wrong",
            "ranked",
            "ranked_known",
            "clean",
            "clean_right",
            "twins",
            "twins_right",
            "clean_alone",
        )
    }
    effects = by_effect(sites)
    judged_now = [s for s in sites.values() if "recorded" in s]
    changed = sorted(k for k, s in sites.items() if "recorded" in s and s["named"] != s["recorded"])
    command = (
        "python bench/gap_headline.py "
        + " ".join(
            [f"--replayed {p}" for p in args.replayed]
            + [f"--checks {p}" for p in checks]
            + [f"--rediagnosed {p}" for p in rediagnosed]
            + [f"--run {p}" for p in runs]
        )
        + f" --name {args.name}"
    )
    lines = [
        "# Gap diagnosis: the blind checks' headline",
        "",
        "Each site counts at its latest record (`bench/gap_headline.py` states the precedence), judged with "
        f"the catalogue's clean-site and estimate ceilings; {len(judged_now) - len(changed)} of the "
        f"{len(judged_now)} diagnosed sites name what their diagnosis named (the others are listed in the "
        "json). Ranked first: the injected effect had the best held-out gain, named or not.",
        "",
        "| | value | target |",
        "|---|---|---|",
        f"| seeds | {len(seeds)} ({seeds[0]['seed']}-{seeds[-1]['seed']}) | |",
        f"| injected effect named first | **{percent(total['right'], total['cases'])}** | >= 90 % |",
        f"| of which named by the estimate alone | {total['alone']} | |",
        f"| named another effect | {total['wrong']} | |",
        f"| ranked first (where known) | {percent(total['ranked'], total['ranked_known'])} | |",
        f"| clean cases recognised | {percent(total['clean_right'], total['clean'])} | >= 90 % |",
        f"| clean twins recognised (where diagnosed) | {percent(total['twins_right'], total['twins'])} | |",
        f"| clean sites named an effect by the estimate alone | {total['clean_alone']} | |",
        "",
        "## By seed",
        "",
        "| seed | judged from | named first | named wrong | ranked first | clean cases | clean twins |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in seeds:
        lines.append(
            f"| {r['seed']} | {', '.join(r['sources'])} | {r['right']}/{r['cases']} | {r['wrong']} | "
            + (f"{r['ranked']}/{r['ranked_known']}" if r["ranked_known"] else "-")
            + f" | {r['clean_right']}/{r['clean']} | "
            + (f"{r['twins_right']}/{r['twins']}" if r["twins"] else "-")
            + " |"
        )
    lines += [
        "",
        "## By injected effect",
        "",
        "| effect | cases | named first | of which by the estimate alone | named another effect |",
        "|---|---|---|---|---|",
    ]
    for name, row in effects.items():
        lines.append(
            f"| {name} | {row['cases']} | {percent(row['right'], row['cases'])} | {row['alone']} | {row['wrong']} |"
        )
    harness.write_results(
        args.name,
        lines,
        {"command": command, "total": total, "seeds": seeds, "by_effect": effects, "changed": changed, "sites": sites},
        echo=True,
    )


if __name__ == "__main__":
    main()
