"""Naming an effect by its estimate alone: the estimate ceilings, measured, and the rule replayed on every seed.

A candidate whose calibrated size lies beyond every clean site's is an effect no clean site produced, even when
adding it improves no held-out week (the base calibration absorbed it into the building parameters: a
wind-driven infiltration into a constant air change rate). ``buildenv.gap.DiagnosisSettings.estimate_alone``
names such a candidate when the first step selected nothing (:func:`buildenv.gap.named_by_estimate`). This
script

- measures the estimate ceilings on every clean site of the given records (clean cases and clean twins
  diagnosed with the current diagnosis) and checks them against the catalogue's
  (:attr:`buildenv.effects.Effect.estimate_ceiling`, the largest rounded outwards to 3 significant digits);
- judges every record's first step without the rule, with the catalogue's estimate ceilings (in-sample: the
  clean sites set them) and with each seed's ceilings taken from the *other* seeds' clean sites (the honest
  estimate of what the rule does on a new seed);
- lists every site the rule names, with its estimate and held-out gain.

Takes the headline's sources (``bench/gap_headline.py``: ``--rediagnosed`` pages, then ``--run`` pages, a later
one replacing an earlier one site by site). Run from the repository root::

    .venv/bin/python bench/gap_estimate_alone.py --rediagnosed bench/results/gap_wind_centred_all.json ... \\
        --run bench/results/gap_check_rerun_seed0.json ... --name gap_estimate_alone

Writes ``bench/results/NAME.{md,json}``. It reads the records only.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from gap_check_rejudge import ALONE, naming
from gap_clean_ceiling import oriented, round_up, size
from gap_headline import ALPHA, SITE, _count_case, _percent, diagnosed_records

from buildenv.effects import EFFECTS, MIN_GAIN, get_effect
from buildenv.gap_check import NONE

RESULTS = Path(__file__).resolve().parent / "results"


def seed_of(site: str) -> int:
    """The blind check's seed of a site key (``seed12_case_003_twin`` -> 12)."""
    return int(SITE.match(site).group(1))


def furthest(records: Mapping[str, tuple[dict, str, str]], leave_out: int | None = None
             ) -> dict[str, tuple[float, str]]:
    """``{effect: (furthest size, site)}`` over the clean sites of ``records`` (sizes oriented as
    ``bench/gap_clean_ceiling.size``: larger is further from no effect), the sites of seed ``leave_out`` left
    out. Holidays are left out (detected, not calibrated)."""
    out: dict[str, tuple[float, str]] = {}
    for site, (record, truth, _) in records.items():
        if truth != NONE or seed_of(site) == leave_out:
            continue
        for name, estimate in record["estimates"].items():
            value = size(name, estimate)
            if name != "holidays" and value is not None and value > out.get(name, (-float("inf"), ""))[0]:
                out[name] = (value, site)
    return out


def as_ceilings(sizes: Mapping[str, tuple[float, str]]) -> dict[str, float]:
    """Furthest sizes as estimate ceilings in the catalogue's units (a heating power, not its negation)."""
    return {name: oriented(name, value) for name, (value, _) in sizes.items()}


def judge_all(records: Mapping[str, tuple[dict, str, str]], ceilings_of: Callable[[int], bool | Mapping[str, float]]
              ) -> dict[str, tuple[str, str]]:
    """``{site: (named, how)}`` of every record's first step with the estimate ceilings ``ceilings_of(seed)``."""
    return {site: naming(record, ALPHA, MIN_GAIN, estimate_ceilings=ceilings_of(seed_of(site)))
            for site, (record, _, _) in records.items()}


def counts(records: Mapping[str, tuple[dict, str, str]], named: Mapping[str, tuple[str, str]]) -> dict:
    """Effect cases named right (and by the estimate alone), named wrong, and clean sites named nothing."""
    out = {"cases": 0, "right": 0, "alone": 0, "wrong": 0, "clean": 0, "clean_right": 0, "clean_alone": 0}
    for site, (_, truth, _) in records.items():
        name, how = named[site]
        if truth == NONE:
            out["clean"] += 1
            out["clean_right"] += name == NONE
            out["clean_alone"] += how == ALONE
        else:
            _count_case(out, {"true": truth, "named": name, "how": how})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rediagnosed", action="append", default=[], help="a bench/gap_wind_centred.py json")
    parser.add_argument("--run", action="append", default=[], help="a bench/gap_check.py json")
    parser.add_argument("--name", default="gap_estimate_alone")
    args = parser.parse_args()
    records = diagnosed_records(args.rediagnosed, args.run)
    seeds = sorted({seed_of(s) for s in records})
    measured = furthest(records)
    others = {seed: as_ceilings(furthest(records, leave_out=seed)) for seed in seeds}
    rules = {"without the rule": lambda seed: False,
             "the catalogue's estimate ceilings (in-sample)": lambda seed: True,
             "each seed with the other seeds' clean sites": lambda seed: others[seed]}
    judged = {rule: judge_all(records, of) for rule, of in rules.items()}
    tallies = {rule: counts(records, named) for rule, named in judged.items()}
    n_clean = sum(1 for _, truth, _ in records.values() if truth == NONE)
    command = ("python bench/gap_estimate_alone.py " + " ".join(
        [f"--rediagnosed {p}" for p in args.rediagnosed] + [f"--run {p}" for p in args.run]) + f" --name {args.name}")
    lines = [f"# Gap diagnosis: naming an effect by its estimate alone ({time.strftime('%Y-%m-%d')})", "",
             f"Command: `{command}`.", "",
             f"{len(records)} diagnosed sites of {len(seeds)} seeds ({seeds[0]}-{seeds[-1]}), each at its latest "
             "record (as `bench/gap_headline.py` takes them). Every first step judged again "
             "(`bench/gap_check_rejudge.naming`): held-out gain, then the joint tests the record ran, then, where "
             "nothing was named, the estimates against the estimate ceilings (`buildenv.gap.named_by_estimate`).",
             "", "## Estimate ceilings", "",
             f"The furthest size on the {n_clean} clean sites; the catalogue's is it rounded outwards to 3 "
             "significant digits. Own cases: the injected effect's estimates in its effect cases.", "",
             "| effect | judged on | furthest on a clean site | where | catalogue | clean-site ceiling (gain route) "
             "| own cases beyond |", "|---|---|---|---|---|---|---|"]
    for name in sorted(measured):
        effect = EFFECTS[name]
        value, where = measured[name]
        expected = oriented(name, round_up(value))
        check = "" if effect.estimate_ceiling == expected else f" (measured gives {expected:g})"
        own = [size(name, r["estimates"][name]) for r, truth, _ in records.values()
               if truth == name and size(name, r["estimates"].get(name, {})) is not None]
        lines.append(f"| {name} | {effect.ceiling_on} | {oriented(name, value):.5g} | {where} | "
                     f"{effect.estimate_ceiling:g}{check} | {effect.clean_ceiling:g} | "
                     f"{sum(v > value for v in own)}/{len(own)} |")
    lines += ["", "## The rule replayed", "",
              "| estimate ceilings | injected effect named first | of which by the estimate alone | named another "
              "effect | clean sites recognised | clean sites named by the estimate alone |",
              "|---|---|---|---|---|---|"]
    for rule, t in tallies.items():
        lines.append(f"| {rule} | {_percent(t['right'], t['cases'], 1)} | {t['alone']} | {t['wrong']} | "
                     f"{_percent(t['clean_right'], t['clean'], 1)} | {t['clean_alone']} |")
    loso = judged["each seed with the other seeds' clean sites"]
    inside = judged["the catalogue's estimate ceilings (in-sample)"]
    lines += ["", "## Sites named by the estimate alone", "",
              "Under either set of ceilings. Gain: the candidate's first-step held-out gain (its refit); ceiling: "
              "the other seeds' furthest.", "",
              "| site | injected | magnitude | named (other seeds' ceilings) | named (catalogue's) | estimate | "
              "other seeds' ceiling | held-out gain |", "|---|---|---|---|---|---|---|---|"]
    for site in sorted(records, key=lambda s: (seed_of(s), s)):
        if ALONE not in (loso[site][1], inside[site][1]):
            continue
        record, truth, _ = records[site]
        name = loso[site][0] if loso[site][1] == ALONE else inside[site][0]
        effect = get_effect(name)
        estimate = record["estimates"][name]
        magnitude = "-" if truth == NONE else f"{record['magnitude']:.3g} {EFFECTS[truth].magnitude_unit}"
        lines.append(f"| {site} | {truth} | {magnitude} | "
                     f"{loso[site][0]} | {inside[site][0]} | {effect.estimate_text(estimate)} | "
                     f"{others[seed_of(site)].get(name, float('nan')):.4g} | "
                     f"{100 * record['scores'][name]:.1f} % |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command,
         "measured": {n: {"furthest": oriented(n, v), "where": w} for n, (v, w) in measured.items()},
         "other_seeds_ceilings": others, "tallies": tallies,
         "named": {rule: {s: list(v) for s, v in named.items()} for rule, named in judged.items()}}, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
