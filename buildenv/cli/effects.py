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
    limits, no-effect magnitude, series, the model-side parameters, the smallest estimate a diagnosis names, the
    hours a site's weeks need for the effect to show (:mod:`buildenv.diagnosis.data_needs`), and for an effect
    carried by a building parameter that parameter and the values a diagnosis also recalibrates from
    (``Effect.carried_starts``)."""
    from buildenv.diagnosis.data_needs import NEEDS
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
            "needs": NEEDS[e.shows_in] if e.shows_in else None,
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
            + (f"\n    needs: {r['needs']} in the fit and held-out weeks" if r["needs"] else "")
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
