"""Blind-check sites diagnosed again with the carried effects' extra starts (``Effect.carried_starts``).

A carried effect's candidate (the heating capacity limit, through the heating power) used to be tested with the
control refit alone. The calibration can settle where the heating power is high and something else absorbs the
limit (two capacity limits at 49 % of design calibrated at 89-95 W/m2, and a 0.7 h sensor lag was named); the
diagnosis now also refits from the effect's ``carried_starts`` and keeps the lowest fit-week cost
(:func:`buildenv.gap.carried_trial`). This script diagnoses chosen sites of recorded blind checks again with
the current code and sets the new verdicts beside the recorded ones:

    .venv/bin/python bench/gap_carried_starts.py --page bench/results/gap_check_tb_seed12.json ... \\
        --effects heating_capacity_limit,none,temperature_sensor_lag --twins-of heating_capacity_limit \\
        [--shard 0/2] [--no-diagnose] --name gap_carried_starts

The sites are read from each page's check folder (``case_NNN``, ``case_NNN_twin``); the records go to
``--folder`` (one json a site, reused when present, so shards run side by side and a stopped run resumes).
The page's ``measured`` gives the lowest heating power the capacity candidate took on a rediagnosed clean site,
as the check recorded it or now (the clean-site ceiling must lie beyond both searches). Run it from the
repository root. Writes ``bench/results/NAME.{md,json}`` when run without ``--shard``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from gap_check_bar import check_folder, recorded_settings

from buildenv.effects import get_effect
from buildenv.gap import diagnose
from buildenv.gap_check import NONE, _diagnosis_record
from buildenv.site import load_site

RESULTS = Path(__file__).resolve().parent / "results"
CAPACITY = "heating_capacity_limit"


def sites(pages: dict[str, dict], effects: set[str], twins_of: set[str]) -> list[tuple[str, dict, bool]]:
    """``(page, case row, twin?)`` of every site to diagnose: the cases injected with ``effects`` (``none``: the
    clean cases), then the clean twins of the cases injected with ``twins_of``."""
    chosen = [(p, r, False) for p, page in pages.items() for r in page["cases"] if r["true"] in effects]
    return chosen + [(p, r, True) for p, page in pages.items() for r in page["cases"] if r["true"] in twins_of]


def key(page: dict, row: dict, twin: bool) -> str:
    """The record's file stem: ``seedS_case_NNN`` (``_twin``)."""
    return f"seed{page['plan']['seed']}_case_{row['case']:03d}" + ("_twin" if twin else "")


def recorded(page: dict, row: dict, twin: bool) -> dict | None:
    """The diagnosis recorded by the check (a twin's from its check folder, None where never diagnosed)."""
    if not twin:
        return row
    path = check_folder(page) / f"twin_{row['case']:03d}.json"
    return json.loads(path.read_text()) if path.is_file() else None


def site_folder(page: dict, row: dict, twin: bool) -> Path:
    """Where the check keeps a site (it may be gone: ``bench/gap_regenerate_site.py`` makes it again)."""
    return check_folder(page) / (f"case_{row['case']:03d}" + ("_twin" if twin else ""))


def rediagnose(page: dict, row: dict, twin: bool, surrogate) -> dict:
    """Diagnose one recorded site again with the current code, as the check did (its settings, no localisation)."""
    settings = recorded_settings(page["plan"]["settings"])
    folder = site_folder(page, row, twin)
    started = time.perf_counter()
    result = diagnose(load_site(folder), surrogate, settings, localisation=False)
    result.pop("_fit", None)
    return {"case": row["case"], "true": NONE if twin else row["true"], "twin_of": row["true"] if twin else None,
            "magnitude": row.get("magnitude"), **_diagnosis_record(result),
            "seconds": round(time.perf_counter() - started, 1)}


def heating_power(record: dict | None) -> float | None:
    """The heating power (W/m2) the capacity candidate was tested at, None where not recorded."""
    if record is None:
        return None
    return record["estimates"].get(CAPACITY, {}).get("heating_power_w_m2")


def cell(value: float | None, digits: int = 1) -> str:
    """A table cell: ``value`` with ``digits`` decimals, or "-" where not recorded."""
    return "-" if value is None else f"{value:.{digits}f}"


def site_arguments(parser: argparse.ArgumentParser, effects: str, twins_of: str, folder: str, name: str) -> None:
    """The options that choose and keep the sites diagnosed again (defaults as given)."""
    parser.add_argument("--page", action="append", required=True, help="a bench/gap_check.py result (.json)")
    parser.add_argument("--effects", default=effects,
                        help="injected effects whose cases are diagnosed again (none: the clean cases)")
    parser.add_argument("--twins-of", default=twins_of,
                        help="injected effects whose clean twins are diagnosed again ('' for none)")
    parser.add_argument("--folder", default=folder, help="where the new records are kept")
    parser.add_argument("--shard", default="", help="K/N: diagnose every N-th site from the K-th (no page)")
    parser.add_argument("--no-diagnose", action="store_true", help="read the kept records only")
    parser.add_argument("--name", default=name)


def chosen_sites(args: argparse.Namespace) -> tuple[dict[str, dict], list[tuple[str, dict, bool]]]:
    """The pages read from ``--page`` and the sites :func:`sites` chooses from them."""
    pages = {p: json.loads(Path(p).read_text()) for p in args.page}
    effects = {e.strip() for e in args.effects.split(",") if e.strip()}
    twins_of = {e.strip() for e in args.twins_of.split(",") if e.strip()}
    if NONE in twins_of:
        raise SystemExit("--twins-of: the clean cases have no twins (name injected effects)")
    for name in (effects | twins_of) - {NONE}:
        get_effect(name)
    return pages, sites(pages, effects, twins_of)


def diagnosed_rows(args: argparse.Namespace, pages: dict[str, dict], todo: list[tuple[str, dict, bool]]
                   ) -> tuple[list[tuple], int]:
    """Diagnose the sites of ``todo`` not yet kept in ``--folder`` whose check folder keeps them (this shard's,
    none with ``--no-diagnose``), then ``(page, row, twin?, recorded diagnosis, new one)`` of every kept site and
    how many are still missing."""
    folder = Path(args.folder)
    folder.mkdir(parents=True, exist_ok=True)
    k, n = (int(x) for x in args.shard.split("/")) if args.shard else (0, 1)
    surrogate = None
    for i, (p, row, twin) in enumerate(todo):
        path = folder / f"{key(pages[p], row, twin)}.json"
        if args.no_diagnose or i % n != k or path.is_file() or not site_folder(pages[p], row, twin).is_dir():
            continue
        if surrogate is None:
            from buildenv.surrogate import load_metamodel
            surrogate = load_metamodel()
        record = rediagnose(pages[p], row, twin, surrogate)
        path.write_text(json.dumps(record, indent=1, default=float) + "\n")
        print(f"{path.stem}: {record['named']} ({record['seconds']} s)", flush=True)
    rows, missing = [], 0
    for p, row, twin in todo:
        path = folder / f"{key(pages[p], row, twin)}.json"
        if not path.is_file():
            missing += 1
            continue
        rows.append((p, row, twin, recorded(pages[p], row, twin), json.loads(path.read_text())))
    return rows, missing


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    site_arguments(parser, f"{CAPACITY},{NONE}", CAPACITY, "out/gap-carried-starts", "gap_carried_starts")
    args = parser.parse_args()
    started = time.perf_counter()
    pages, todo = chosen_sites(args)
    rows, missing = diagnosed_rows(args, pages, todo)
    if args.shard:
        return
    groups: dict[str, dict] = {}
    for _, row, twin, before, after in rows:
        truth = NONE if twin else row["true"]
        label = f"clean twins of {row['true']}" if twin else ("clean cases" if truth == NONE else truth)
        g = groups.setdefault(label, {"sites": 0, "right_before": 0, "right_after": 0, "recorded": 0})
        g["sites"] += 1
        g["right_after"] += after["named"] == truth
        if before is not None:
            g["recorded"] += 1
            g["right_before"] += before["named"] == truth
    # every heating power a clean site's capacity candidate took, with the search before (the check's record)
    # and now: the ceiling must lie beyond both
    clean_powers = [(heating_power(record), key(pages[p], row, twin) + label)
                    for p, row, twin, before, after in rows if twin or row["true"] == NONE
                    for record, label in ((before, ", recorded"), (after, ", now"))
                    if heating_power(record) is not None]
    lowest = min(clean_powers) if clean_powers else None
    command = ("python bench/gap_carried_starts.py " + " ".join(f"--page {p}" for p in args.page)
               + f" --effects {args.effects} --twins-of {args.twins_of} --folder {args.folder}"
               + (" --no-diagnose" if args.no_diagnose else "") + f" --name {args.name}")
    seconds = [after["seconds"] for *_, after in rows]
    starts = ", ".join(f"{v:g}" for v in get_effect(CAPACITY).carried_starts)
    lines = [f"# Blind-check sites diagnosed again with the carried effects' starts ({time.strftime('%Y-%m-%d')})",
             "", f"Command: `{command}` ({time.perf_counter() - started:.0f} s this run; the diagnoses "
             f"{sum(seconds):.0f} s, median {sorted(seconds)[len(seconds) // 2] if seconds else 0:.0f} s a site).",
             "", "The heating capacity limit's candidate is now the lowest fit-week cost of the control refit and "
             f"refits started from a heating power of {starts} W/m2 (`Effect.carried_starts`, "
             "`buildenv.gap.carried_trial`). Before: the verdict the check "
             "recorded (the rules of its day, so a difference can also come from a rule changed since).", "",
             f"{len(rows)} sites diagnosed again" + (f", {missing} still missing" if missing else "") + ".", "",
             "| sites | number | named right, recorded | named right, now |", "|---|---|---|---|"]
    for label, g in groups.items():
        before = f"{g['right_before']}/{g['recorded']}" if g["recorded"] else "-"
        lines.append(f"| {label} | {g['sites']} | {before} | {g['right_after']}/{g['sites']} |")
    lines += ["", "Lowest heating power of the capacity candidate on a clean site diagnosed again, as recorded or now: "
              + (f"{lowest[0]:.2f} W/m2 ({lowest[1]}); the catalogue's ceiling: {get_effect(CAPACITY).clean_ceiling:g}"
                 " W/m2." if lowest else "none."), "",
              "## Sites", "",
              "| site | injected | magnitude | named, recorded | named now | heating power, recorded | now | "
              "capacity gain now | lag estimate now |", "|---|---|---|---|---|---|---|---|---|"]
    for p, row, twin, before, after in rows:
        injected = f"none (twin of {row['true']})" if twin else row["true"]
        magnitude = "-" if twin or row.get("magnitude") is None else f"{row['magnitude']:.3g}"
        lag = after["estimates"].get("temperature_sensor_lag", {}).get("tau_h")
        gain = after["scores"].get(CAPACITY)
        lines.append(f"| {key(pages[p], row, twin)} | {injected} | {magnitude} | "
                     f"{before['named'] if before else '-'} | {after['named']} | {cell(heating_power(before))} | "
                     f"{cell(heating_power(after))} | {'-' if gain is None else f'{gain:.3f}'} | "
                     f"{'-' if lag is None else f'{lag:.3f}'} |")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    (RESULTS / f"{args.name}.json").write_text(json.dumps(
        {"command": command, "groups": groups,
         "measured": {CAPACITY: list(lowest)} if lowest else {},
         "records": {key(pages[p], row, twin): after for p, row, twin, _, after in rows}},
        indent=1, default=float) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
