"""``buildenv site ...`` and ``buildenv calibrate``: sites (measured buildings) and calibrating to them."""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

from buildenv.cli.argtypes import daily_weight_argument, positive_int
from buildenv.errors import BuildenvError
from buildenv.jsonio import dumps


def parse_start(text: str, year: int) -> dt.date:
    """``MM-DD`` (in ``year``) or ``YYYY-MM-DD`` -> a date that must be a Monday."""
    try:
        day = dt.date.fromisoformat(text) if text.count("-") == 2 else dt.date.fromisoformat(f"{year}-{text}")
    except ValueError:
        raise BuildenvError(f"--start {text!r}: expected MM-DD or YYYY-MM-DD") from None
    if day.weekday() != 0:
        before = day - dt.timedelta(days=day.weekday())
        raise BuildenvError(f"--start {day} is a {day.strftime('%A')}; weeks start on Mondays (e.g. {before})")
    return day


def _parse_map(items: list[str]):
    from buildenv.energyplus.reference import SCHEDULE_ROLES, ScheduleMap

    if not items:
        return None
    mapping: dict[str, list[str]] = {}
    for item in items:
        role, sep, names = item.partition("=")
        if not sep or role not in SCHEDULE_ROLES:
            raise BuildenvError(
                f"--map {item!r}: expected ROLE=SCHEDULE[,SCHEDULE...] with ROLE one of {', '.join(SCHEDULE_ROLES)}"
            )
        mapping[role] = [n.strip() for n in names.split(",") if n.strip()]
    missing = [r for r in SCHEDULE_ROLES if r not in mapping]
    if missing:
        raise BuildenvError(f"--map: give every role ({', '.join(missing)} missing)")
    return ScheduleMap(**mapping)


def parse_effects(items: list[str]) -> list[tuple[str, float]]:
    """``--effect NAME[=MAGNITUDE]`` values -> ``[(name, magnitude)]``; raises
    :class:`~buildenv.diagnosis.effects.EffectError` (one line) for an unknown effect, a bad magnitude or an
    effect given twice."""
    from buildenv.diagnosis.effects import EffectError, parse_effect

    effects = [(e.name, m) for e, m in (parse_effect(item) for item in items)]
    names = [n for n, _ in effects]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise EffectError(f"--effect {', '.join(twice)} given more than once")
    return effects


def parse_known(items: list[str]) -> dict[str, float]:
    """``--known NAME=VALUE`` values -> ``{name: value}`` (see :func:`buildenv.sites.known_parameter`); raises
    :class:`~buildenv.errors.SiteError` (one line) naming the bad item."""
    from buildenv.errors import SiteError
    from buildenv.sites import known_parameter

    known: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        try:
            value = float(text)
        except ValueError:
            value = text
        try:
            if not sep:
                raise SiteError("expected NAME=VALUE")
            if name in known:
                raise SiteError(f"{name} given more than once")
            known[name] = known_parameter(name, value)
        except SiteError as exc:
            raise SiteError(f"--known {item!r}: {exc}") from exc
    return known


def parse_meter(text: str | None, flag: str = "--meter") -> tuple[str, ...]:
    """``--meter USE[,USE...]`` -> the end uses the consumption meter sums (default
    :data:`buildenv.catalogue.DEFAULT_END_USES`); raises :class:`~buildenv.errors.SiteError` (one line naming
    ``flag``)."""
    from buildenv import catalogue as cat
    from buildenv.errors import SiteError
    from buildenv.sites.reader import check_end_uses

    if text is None:
        return cat.DEFAULT_END_USES
    try:
        return check_end_uses([u.strip() for u in text.split(",") if u.strip()])
    except SiteError as exc:
        raise SiteError(f"{flag} {text!r}: {exc}") from None


def _cmd_site_reference(args: argparse.Namespace) -> int:
    from buildenv.energyplus.reference import make_reference_site
    from buildenv.weather.epw import resolve_epw

    resolve_epw(args.epw)  # a missing weather file is refused before EnergyPlus starts
    start = parse_start(args.start, args.year)
    effects = parse_effects(args.effect)
    end_uses = parse_meter(args.meter)
    path = make_reference_site(
        args.out,
        args.building,
        args.epw,
        start,
        args.weeks,
        seed=args.seed,
        floors=args.floors,
        schedule_map=_parse_map(args.map),
        effects=effects,
        effect_seed=args.effect_seed,
        known=parse_known(args.known),
        end_uses=end_uses,
    )
    info = {"site": str(path), "building": args.building, "weather": args.epw, "start": str(start), "weeks": args.weeks}
    info["meters"] = list(end_uses)
    if effects:
        info["effects"] = [{"name": n, "magnitude": m} for n, m in effects]
    print(dumps(info, where="the site", nonfinite="null"))
    return 0


def parse_units(items: list[str]) -> dict[str, str]:
    """``--unit COLUMN=UNIT`` values -> ``{column: unit}`` (the unit checked by the importer); raises
    :class:`~buildenv.errors.SiteError` (one line) naming the bad item."""
    from buildenv.errors import SiteError

    units: dict[str, str] = {}
    for item in items:
        column, sep, unit = item.rpartition("=")
        if not sep or not column.strip() or not unit.strip():
            raise SiteError(f"--unit {item!r}: expected COLUMN=UNIT, e.g. 'Temp (F)=degF'")
        units[column.strip()] = unit.strip()
    return units


def _cmd_site_import(args: argparse.Namespace) -> int:
    from buildenv.sites.importer import ImportOptions, import_export

    options = ImportOptions(
        time_column=args.time_column,
        temperature_column=args.temperature_column,
        consumption_columns=tuple(args.consumption_column),
        electricity_columns=tuple(args.electricity_column),
        units=parse_units(args.unit),
        time_format=args.time_format,
        time_zone=args.time_zone,
        stamped=args.stamped,
        cumulative=args.cumulative,
        fill_temperature_gaps=args.fill_temperature_gaps,
    )
    report = import_export(
        args.export,
        args.out,
        name=args.name or Path(args.export).stem,
        weather=args.epw,
        floor_area_m2=args.floor_area,
        number_of_floors=args.floors,
        options=options,
        settings=args.settings,
        known=parse_known(args.known),
        end_uses=parse_meter(args.meter),
        electricity_end_uses=parse_meter(args.electricity_meter, "--electricity-meter")
        if args.electricity_meter
        else (),
    )
    info = report.as_dict()
    notes = info.pop("notes")
    print(dumps(info, where="the import", nonfinite="null", indent=2))
    for note in notes:
        print(note, file=sys.stderr)
    return 0


def _cmd_site_show(args: argparse.Namespace) -> int:
    import numpy as np

    from buildenv.sites import load_site

    site = load_site(args.site)
    info = {
        "site": str(site.path),
        "name": site.name,
        "weather": site.weather,
        "start": str(site.start),
        "weeks": site.weeks,
        "floor_area_m2": site.floor_area_m2,
        "number_of_floors": site.number_of_floors,
        "known": site.known,
        "effects": list(site.effects),
        "meters": list(site.consumption_end_uses),
        **({"electricity_meter": list(site.electricity_end_uses)} if site.electricity_kwh is not None else {}),
        "temperature_hours": int(site.temperature_mask.sum()),
        "consumption_hours": int(site.consumption_mask.sum()),
        "mean_temperature_c": round(float(np.nanmean(site.temperature_c)), 2),
        "consumption_kwh_per_week": np.round(np.nansum(site.consumption_kwh, axis=1), 1).tolist(),
        "calibrated": site.calibration is not None,
    }
    if site.electricity_kwh is not None:
        info["electricity_hours"] = int(np.isfinite(site.electricity_kwh).sum())
        info["electricity_kwh_per_week"] = np.round(np.nansum(site.electricity_kwh, axis=1), 1).tolist()
    print(dumps(info, where="the site summary", nonfinite="null", indent=2))
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from buildenv.calibration.calibrate import calibrate_site
    from buildenv.calibration.plot import plot_calibration
    from buildenv.calibration.problem import at_bounds_note, runs_note
    from buildenv.metamodel.surrogate import load_metamodel
    from buildenv.sites import load_site

    site = load_site(args.site)
    try:
        weeks = [int(w) for w in args.weeks.split(",")] if args.weeks else None
    except ValueError:
        raise BuildenvError(
            f"--weeks {args.weeks!r}: give week indices of the site separated by commas, e.g. 0,1"
        ) from None
    result = calibrate_site(
        site,
        load_metamodel(args.checkpoint),
        weeks,
        method=args.method,
        seed=args.seed,
        max_evaluations=args.evaluations,
        progress=not args.quiet,
        restarts=args.restarts,
        effects=declared_for_calibration(site, args.effect, args.no_site_effects),
        prior=not args.no_prior,
        daily_weight=args.daily_weight,
    )
    result["plot"] = str(
        plot_calibration(
            load_site(args.site), load_metamodel(args.checkpoint), result, Path(args.site) / "calibration.png"
        )
    )
    print(dumps(result, where="the calibration", nonfinite="null", indent=None if args.json else 2))
    for note in (at_bounds_note(result), runs_note(result), result["verdict"]["line"]):
        if note:
            print(note, file=sys.stderr)
    return 0


def declared_for_calibration(site, extra: list[str], no_site_effects: bool = False) -> tuple[str, ...]:
    """The effects ``buildenv calibrate`` models: the site's own (``site.toml``'s ``effects``) unless
    ``no_site_effects``, then the ``--effect`` ones not already among them."""
    own = () if no_site_effects else site.effects
    return own + tuple(e for e in extra if e not in own)


def add_known_argument(p: argparse.ArgumentParser) -> None:
    """``--known NAME=VALUE`` (repeatable): building parameters written to the site's ``[known]`` table."""
    p.add_argument(
        "--known",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a building parameter the owner knows, catalogue units (repeatable), e.g. "
        "occupant_density_per_m2=0.0538; written to site.toml's [known], fixed in calibration",
    )


def register(sub) -> None:
    """Add the ``site`` and ``calibrate`` subcommands to the main parser's subparsers."""
    from buildenv.energyplus.reference import REFERENCE_BUILDINGS

    site = sub.add_parser("site", help="make or inspect a site (a measured building)")
    site_sub = site.add_subparsers(dest="site_command", required=True)
    p = site_sub.add_parser("reference", help="a reference building run under historical settings, read as sensors")
    p.add_argument(
        "--building",
        default="medium_office",
        help=f"one of {', '.join(REFERENCE_BUILDINGS)}, or an IDF path (then --floors)",
    )
    p.add_argument("--epw", default="usa_il_chicago", help="weather short name or EPW path")
    p.add_argument("--start", default="11-04", help="first Monday, MM-DD (in --year) or YYYY-MM-DD")
    p.add_argument("--year", type=int, default=2019, help="calendar year of --start MM-DD (weekdays)")
    p.add_argument("--weeks", type=positive_int, default=4, help="measured weeks")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument("--floors", type=positive_int, default=None, help="storeys (for a user IDF)")
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="ROLE=SCHEDULE",
        help="schedules of a user IDF to replace: heating_setpoint, cooling_setpoint, "
        "hvac_availability, outdoor_air (all four)",
    )
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME[=MAGNITUDE]",
        help="inject an unmodelled effect (repeatable; `buildenv effects` lists them; the truth goes to truth.json)",
    )
    p.add_argument("--effect-seed", type=int, default=0, help="seed of the effects' random choices (holiday dates)")
    add_known_argument(p)
    p.add_argument(
        "--meter",
        default=None,
        metavar="USE[,USE...]",
        help="end uses the consumption meter sums: heating, cooling, lighting, plug_loads (default "
        "heating,lighting,plug_loads); written to site.toml's [meters]",
    )
    p.add_argument("--out", required=True, help="site folder to write")
    p.set_defaults(func=_cmd_site_reference)
    p = site_sub.add_parser(
        "import",
        help="a site folder from a BMS export (sub-hourly, local time, end stamps, other units, meter registers)",
    )
    p.add_argument("export", help="the BMS export: a CSV file with a header (',', ';' or tab separated)")
    p.add_argument("--out", required=True, help="site folder to write (new or empty)")
    p.add_argument("--epw", required=True, help="weather short name or EPW path")
    p.add_argument("--floor-area", type=float, required=True, metavar="M2", help="conditioned floor area, m2")
    p.add_argument("--floors", type=positive_int, required=True, help="storeys")
    p.add_argument("--name", default=None, help="free text (default: the export's file name)")
    p.add_argument("--time-column", default=None, help="timestamp column (default: the one named *time*/*date*)")
    p.add_argument("--temperature-column", default=None, help="indoor temperature column (default: the one *temp*)")
    p.add_argument(
        "--consumption-column",
        action="append",
        default=[],
        metavar="COLUMN",
        help="a consumption column, summed (repeatable; default: each column named with an energy or power unit)",
    )
    p.add_argument(
        "--electricity-column",
        action="append",
        default=[],
        metavar="COLUMN",
        help="a column of a second meter, summed (repeatable), where heat and electricity are metered apart",
    )
    p.add_argument(
        "--unit",
        action="append",
        default=[],
        metavar="COLUMN=UNIT",
        help="a column's unit where its name does not say it (repeatable): degC, degF, K; Wh, kWh, MWh, MJ, GJ "
        "(energy in the interval); W, kW, MW (power, averaged)",
    )
    p.add_argument(
        "--time-format",
        default=None,
        help="strptime format of the timestamps, e.g. '%%m/%%d/%%Y %%H:%%M' (%%z: UTC offsets, converted to the EPW's "
        "standard time)",
    )
    p.add_argument(
        "--time-zone",
        default=None,
        help="IANA zone whose clock (daylight saving) the export keeps; standard time the EPW's",
    )
    p.add_argument(
        "--stamped", default="start", choices=["start", "end"], help="a row stamps its interval's start or end"
    )
    p.add_argument("--cumulative", action="store_true", help="the energy columns hold meter register readings")
    p.add_argument(
        "--fill-temperature-gaps", action="store_true", help="interpolate temperature gaps of up to 2 h (else gaps)"
    )
    p.add_argument("--settings", default=None, metavar="CSV", help="settings.csv of the weeks (default: typical ones)")
    add_known_argument(p)
    p.add_argument(
        "--meter",
        default=None,
        metavar="USE[,USE...]",
        help="end uses the consumption sums (default heating,lighting,plug_loads); written to site.toml's [meters]",
    )
    p.add_argument(
        "--electricity-meter",
        default=None,
        metavar="USE[,USE...]",
        help="end uses the --electricity-column meter sums (e.g. lighting,plug_loads,cooling; none of --meter's)",
    )
    p.set_defaults(func=_cmd_site_import)
    p = site_sub.add_parser("show", help="summarise a site folder (validates it)")
    p.add_argument("site", help="site folder")
    p.set_defaults(func=_cmd_site_show)

    p = sub.add_parser("calibrate", help="calibrate the metamodel's building and occupancy to a site")
    p.add_argument("--site", required=True, help="site folder")
    p.add_argument("--weeks", default=None, help="calibration weeks, e.g. 0,1 (default: the first half)")
    p.add_argument("--method", default="cmaes", choices=["cmaes", "adam"])
    p.add_argument("--evaluations", type=int, default=6000, help="CMA-ES budget of cost evaluations (per run)")
    p.add_argument(
        "--restarts",
        type=int,
        default=1,
        help="independent CMA-ES runs (seeds SEED, SEED+1, ...), the lowest cost kept; a note says "
        "when runs that fit alike predict the held-out weeks apart",
    )
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME",
        help="an effect the building is known to have (repeatable; `buildenv effects` lists them), "
        "e.g. night_cycle_cold_air for a VAV system with terminal reheat: its parameters are "
        "fitted after the building's, and the site's model keeps it; added to the effects site.toml "
        "declares",
    )
    p.add_argument(
        "--no-site-effects",
        action="store_true",
        help="leave out the effects site.toml declares (calibrate the plain model, for comparison)",
    )
    p.add_argument(
        "--no-prior",
        action="store_true",
        help="least squares only: leave out the prior that keeps parameters the data do not pin near the middle "
        "of their ranges (CMA-ES)",
    )
    daily_weight_argument(p)
    p.add_argument("--checkpoint", default="default", help="metamodel checkpoint or 'default'")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="one-line JSON")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_calibrate)
