"""Clean-site ceilings set at the k-th largest clean estimate instead of the largest, judged on blind checks.

The catalogue's ceilings (:attr:`buildenv.effects.Effect.clean_ceiling`) are the largest estimate any clean site
gave a candidate, so one unusual clean site sets them. A ceiling at the second or third largest is a test with a
stated false-alarm rate (about k in the number of clean sites per effect) and names more of the effects that
the base calibration half absorbs. This script replays every recorded first step of the given pages with the
ceilings each seed would get from the *other* seeds' clean sites (as ``bench/gap_clean_ceiling.py``'s honest
rule) at each rank, and lists the sites whose naming changes from rank 1:

    .venv/bin/python bench/gap_ceiling_rank.py --page bench/results/gap_check_tb_seed0.json ... \\
        --twin-records bench/results/gap_clean_ceiling.json [--twins bench/results/gap_check_tb_seed15.json] \\
        --ranks 1,2,3,4 --name gap_ceiling_rank

``--twins PAGE`` reads a page's clean twins from its check folder (``bench/gap_check_bar.py`` makes them). Run it
from the repository root. Writes ``bench/results/NAME.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import time
from functools import partial
from pathlib import Path

from gap_check_bar import judge, twin_records
from gap_check_rejudge import first_named
from gap_clean_ceiling import clean_records, clean_sizes, oriented, read_twin_records

from buildenv.effects import MIN_GAIN
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def ranked_ceilings(records: list[dict], rank: int) -> dict[str, float]:
    """``{effect: rank-th largest size}`` over clean records, in the catalogue's units (rank 1: the largest, as
    :func:`gap_clean_ceiling.ceilings`); an effect with fewer sizes than ``rank`` gets none."""
    return {n: oriented(n, sorted(v for v, _ in sizes)[-rank]) for n, sizes in clean_sizes(records).items()
            if len(sizes) >= rank}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result (.json)")
    parser.add_argument("--twin-records", action="append", default=[],
                        help="a json keeping clean twins' records (bench/gap_clean_ceiling.py's, gap_check_bar's)")
    parser.add_argument("--twins", action="append", default=[], help="a page whose twins its check folder keeps")
    parser.add_argument("--ranks", default="1,2,3,4", help="ranks of the clean estimate used as the ceiling")
    parser.add_argument("--name", default="gap_ceiling_rank")
    args = parser.parse_args()
    started = time.perf_counter()
    ranks = [int(r) for r in args.ranks.split(",")]
    pages = {p: json.loads(Path(p).read_text()) for p in args.page}
    twins = read_twin_records(args.twin_records)
    for p in args.twins:
        twins[p] = twin_records(pages[p], False, False)
    seed = {p: page["plan"]["seed"] for p, page in pages.items()}
    clean = {p: clean_records(pages[p], twins.get(p, []), f"seed {seed[p]}") for p in pages}
    alpha = next(iter(pages.values()))["plan"]["settings"]["alpha"]
    totals, by_effect, naming = {}, {}, {}
    for rank in ranks:
        t = totals[rank] = {"right": 0, "cases": 0, "wrong": 0, "clean": 0, "clean_sites": 0}
        for p, page in pages.items():
            ceilings = ranked_ceilings([r for q in pages if seed[q] != seed[p] for r in clean[q]], rank)
            name_of = partial(first_named, alpha=alpha, min_gain=MIN_GAIN, clean_ceilings=ceilings)
            counts = judge(page["cases"], twins.get(p, []), name_of)
            t["right"] += counts["named_right"]
            t["cases"] += counts["effect_cases"]
            t["wrong"] += counts["named_wrong"]
            t["clean"] += counts["clean_recognised"] + counts["twins_recognised"]
            t["clean_sites"] += counts["clean_cases"] + counts["twins"]
            for row in page["cases"]:
                site = f"seed {seed[p]} case {row['case']}"
                named = naming.setdefault(site, {"true": row["true"], "magnitude": row.get("magnitude"),
                                                 "named": {}})["named"]
                named[rank] = name_of(row)
                if row["true"] != NONE:
                    e = by_effect.setdefault(row["true"], {}).setdefault(rank, [0, 0])
                    e[0] += named[rank] == row["true"]
                    e[1] += 1
            for row in twins.get(p, []):
                site = f"seed {seed[p]} twin of case {row['case']}"
                naming.setdefault(site, {"true": NONE, "magnitude": None, "named": {}})["named"][rank] = name_of(row)
    command = ("python bench/gap_ceiling_rank.py " + " ".join(f"--page {p}" for p in args.page)
               + "".join(f" --twin-records {p}" for p in args.twin_records)
               + "".join(f" --twins {p}" for p in args.twins) + f" --ranks {args.ranks} --name {args.name}")
    lines = [f"# Clean-site ceilings at the k-th largest clean estimate ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}` ({time.perf_counter() - started:.0f} s).", "",
             "Every recorded first step judged again (`bench/gap_check_rejudge.py`), each seed with ceilings set at "
             "the given rank of the other seeds' clean estimates (rank 1: the largest, the catalogue's rule).", "",
             "| rank | injected effect named first | named another effect | clean sites recognised |",
             "|---|---|---|---|"]
    for rank, t in totals.items():
        lines.append(f"| {rank} | {t['right']}/{t['cases']} ({100 * t['right'] / t['cases']:.0f} %) | {t['wrong']} | "
                     f"{t['clean']}/{t['clean_sites']} |")
    lines += ["", "## By effect (named right)", "", "| effect | " + " | ".join(f"rank {r}" for r in ranks) + " |",
              "|---|" + "---|" * len(ranks)]
    for name, counts in sorted(by_effect.items()):
        lines.append(f"| {name} | " + " | ".join(f"{counts[r][0]}/{counts[r][1]}" for r in ranks) + " |")
    lines += ["", f"## Sites named differently from rank {ranks[0]}", "",
              "| site | injected | magnitude | " + " | ".join(f"rank {r}" for r in ranks) + " |",
              "|---|---|---|" + "---|" * len(ranks)]
    for site, n in naming.items():
        if len(set(n["named"].values())) > 1:
            magnitude = "-" if n["magnitude"] is None else f"{n['magnitude']:.3g}"
            lines.append(f"| {site} | {n['true']} | {magnitude} | " + " | ".join(n["named"][r] for r in ranks) + " |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "totals": totals, "by_effect": by_effect, "naming": naming}, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
