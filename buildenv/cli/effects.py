"""``buildenv effects``: list the catalogue of unmodelled effects (:mod:`buildenv.diagnosis.effects`).

The ``--effect`` / ``--effect-seed`` options of ``buildenv site reference`` (which inject them into the
reference-building stand-in, :mod:`buildenv.energyplus.injections`) are defined in :mod:`buildenv.cli.sites`.
"""

from __future__ import annotations

import argparse
from typing import Any

from buildenv.jsonio import dumps


def catalogue_rows() -> list[dict[str, Any]]:
    """One JSON-ready row per effect: name, title, kind, magnitude unit, practice range, default, injection
    limits, no-effect magnitude, series, the model-side parameters, the smallest estimate a diagnosis names and
    the size beyond which any significant held-out gain names it (the clean-site ceiling; on a site declaring
    building parameters known, the one measured on such sites), the size beyond which its estimate alone names it
    when nothing else is named (``Effect.estimate_ceiling``), both ceilings per W/m2 of the fit weeks' irradiance
    where they grow with it (blinds: ``Effect.sunshine_ceiling``), when the estimate alone names it under its floor
    too (night plug loads: :func:`alone_under_floor_text`), the size from which it is named first ahead of every
    held-out gain (night plug loads: :func:`named_first_text`), and for an effect carried by a building parameter
    that parameter and the values a diagnosis also recalibrates from (``Effect.carried_starts``)."""
    from buildenv.diagnosis.effects import EFFECTS, INJECTION_LIMITS, NO_EFFECT_MAGNITUDE

    return [
        {
            "name": e.name,
            "title": e.title,
            "kind": e.kind,
            "magnitude_unit": e.magnitude_unit,
            "magnitude_range": list(e.magnitude_range),
            "default_magnitude": e.default_magnitude,
            "injection_limits": list(INJECTION_LIMITS[e.name]),
            "no_effect_magnitude": NO_EFFECT_MAGNITUDE[e.name],
            "series": list(e.series),
            "model": e.model,
            "named_from": e.named_from() or None,
            "named_beyond": e.clean_ceiling_text() or None,
            "named_beyond_on_declaring_sites": e.on_declared_site().clean_ceiling_text() or None,
            "named_by_estimate_alone_beyond": e.estimate_ceiling_text() or None,
            "ceilings_in_sunshine": e.sunshine_ceiling_text() or None,
            "named_by_estimate_alone_under_the_floor": alone_under_floor_text(e.name),
            "named_first_beyond": named_first_text(e.name),
            "building_parameter": e.building_parameter,
            "carried_starts": list(e.carried_starts),
            "also_recalibrated_from": e.carried_starts_text() or None,
            "parameters": [
                {"name": p.name, "unit": p.unit, "lo": p.lo, "hi": p.hi, "none": p.none, "description": p.description}
                for p in e.parameters
            ],
        }
        for e in EFFECTS.values()
    ]


def alone_under_floor_text(name: str) -> str | None:
    """When the estimate alone names effect ``name`` with its building parameter under the floor it is named from
    (only night plug loads: :func:`buildenv.diagnosis.gap.plausible_alone`), as a person reads it, or None."""
    from buildenv.diagnosis.effects import get_effect

    if name != "night_plug_loads":
        return None
    effect = get_effect(name)
    return (
        f"{effect.ceiling_on} > {effect.estimate_ceiling:g} W/m2 with {effect.building_parameter} under "
        f"{effect.carried_limit():g} %, the temperature sensor bias refit at 0 K or colder (the floor is the "
        "held-out test's, which pins that share at 0 %; the night electricity counts both night shares)"
    )


def named_first_text(name: str) -> str | None:
    """When a first step names effect ``name`` ahead of every held-out gain, as a person reads it (only night plug
    loads: :func:`buildenv.diagnosis.gap.night_load_named_first`), or None."""
    from buildenv.diagnosis.effects import NIGHT_LOAD_FIRST_BEYOND, get_effect

    if name != "night_plug_loads" or NIGHT_LOAD_FIRST_BEYOND is None:
        return None
    effect = get_effect(name)
    return (
        f"{effect.ceiling_on} > {NIGHT_LOAD_FIRST_BEYOND * effect.estimate_ceiling:.3g} W/m2 "
        f"({NIGHT_LOAD_FIRST_BEYOND:g} times the estimate ceiling) with the temperature sensor bias refit at 0 K "
        "or colder (a sensor reading warm makes a calibration add heat at night too)"
    )


def _cmd_effects(args: argparse.Namespace) -> int:
    rows = catalogue_rows()
    if args.json:
        print(dumps(rows, where="the effects catalogue"))
        return 0
    for r in rows:
        lo, hi = r["magnitude_range"]
        params = ", ".join(f"{p['name']} [{p['unit']}] {p['lo']:g}..{p['hi']:g}" for p in r["parameters"])
        params = f"{r['model']}" + (f" ({params})" if params else "")
        print(
            f"{r['name']}  ({r['title']}; {r['kind']})\n"
            f"    magnitude: {lo:g} to {hi:g} {r['magnitude_unit']} in practice, default {r['default_magnitude']:g}\n"
            f"    shows in: {', '.join(r['series'])}\n"
            f"    model side: {params}"
            + (f"\n    named from: {r['named_from']}" if r["named_from"] else "")
            + (f"\n    named by significance alone when: {r['named_beyond']}" if r["named_beyond"] else "")
            + (
                f"\n    on a site declaring building parameters known: {r['named_beyond_on_declaring_sites']}"
                if r["named_beyond_on_declaring_sites"]
                else ""
            )
            + (
                f"\n    named by its estimate alone (nothing else named) when: {r['named_by_estimate_alone_beyond']}"
                if r["named_by_estimate_alone_beyond"]
                else ""
            )
            + (
                f"\n    named by its estimate alone under that floor too, when: "
                f"{r['named_by_estimate_alone_under_the_floor']}"
                if r["named_by_estimate_alone_under_the_floor"]
                else ""
            )
            + (
                f"\n    both ceilings, on a site whose fit weeks' irradiance is known: {r['ceilings_in_sunshine']}"
                if r["ceilings_in_sunshine"]
                else ""
            )
            + (
                f"\n    named first, ahead of any held-out gain, when: {r['named_first_beyond']}"
                if r["named_first_beyond"]
                else ""
            )
            + (
                f"\n    also recalibrated from: {r['also_recalibrated_from']} (the best fit on the fit weeks kept)"
                if r["also_recalibrated_from"]
                else ""
            )
        )
    print("\ninject with: buildenv site reference --out SITE --effect NAME[=MAGNITUDE] [--effect-seed N]")
    return 0


def register(sub) -> None:
    """Add the ``effects`` subcommand to the main parser's subparsers."""
    p = sub.add_parser("effects", help="list the unmodelled effects (gap diagnosis catalogue)")
    p.add_argument("--json", action="store_true", help="one-line JSON")
    p.set_defaults(func=_cmd_effects)
