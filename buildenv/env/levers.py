"""The lever check: each setting the BMS can change, moved alone, on the model and on the building.

A random setting moves every lever at once: when its savings are mispredicted, the response check
(:mod:`buildenv.env.response`) cannot say which lever the model gets wrong. Here each controllable setting is
pulled, on all seven days (a day set back entirely: on the weekend), to either end of its action range with every
other setting historical, and run through the calibrated metamodel, the site's EnergyPlus model and the EnergyPlus
shoebox at the calibrated parameters: the savings error of each lever, and where it arises (the metamodel against
its shoebox, the shoebox against the building).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError
from buildenv.sites.suite import CASE_FIELDS, check_calibrated_sites

#: the ends a lever is pulled to, with their action value
ENDS: dict[str, float] = {"low": -1.0, "high": 1.0}
#: the days a lever pulls where not all seven: a switch (a day set back entirely) is tried on the weekend (no
#: building is shut down all week)
LEVER_DAYS: dict[str, tuple[str, ...]] = {v.name: cat.DAYS[5:] for v in cat.SETTINGS if v.is_switch}


def lever_actions(env) -> tuple[list[tuple[str, str]], np.ndarray]:
    """The settings of the lever check: ``([(setting, end)], actions (L, A))``.

    For each controllable setting (in the action's order) the historical action with that setting's seven
    components (those of :data:`LEVER_DAYS` where it names the setting) at -1 (``"low"``) and at 1 (``"high"``);
    an end whose settings are the historical action's on every
    day (a range of one grid point, or a historical value at that end) is left out. A controllable setting whose
    historical value no action holds (outside its action range, or off the grid) is at its nearest action in every
    lever (:func:`shifted_settings`; :func:`lever_check` measures the levers from there).

    Raises:
        BuildenvError: no setting can be moved (none controllable, or each range holds only its historical value).
    """
    base = env.unwrapped
    historical = np.asarray(base.historical_action, np.float32)
    start = base.decode(historical)  # the site's historical settings, shifted ones at their nearest
    setting_of, day_of = zip(*(name.rsplit("_", 1) for name in base.action_names))  # "<setting>_<day>"
    controllable = list(dict.fromkeys(setting_of))
    column = {s: cat.SETTING_NAMES.index(s) for s in controllable}
    levers, actions = [], []
    for setting in controllable:
        days = LEVER_DAYS.get(setting, cat.DAYS)
        components = [i for i, (s, d) in enumerate(zip(setting_of, day_of)) if s == setting and d in days]
        for end, value in ENDS.items():
            action = historical.copy()
            action[components] = value
            if np.allclose(base.decode(action)[:, column[setting]], start[:, column[setting]]):
                continue
            levers.append((setting, end))
            actions.append(action)
    if not actions:
        raise BuildenvError(
            f"site {base.site_name}: no setting can be moved (controllable: {', '.join(controllable) or 'none'}; "
            "each range holds only its historical value): widen the site's [bms] limits"
        )
    return levers, np.stack(actions)


def shifted_settings(env) -> list[str]:
    """The controllable settings whose historical values no action holds (outside the action range, or off its
    grid): the historical action (:attr:`historical_action`) holds them at their nearest."""
    base = env.unwrapped
    truth = np.asarray(base.site_model.historical, float)
    nearest = base.decode(np.asarray(base.historical_action, np.float32))
    controllable = dict.fromkeys(name.rsplit("_", 1)[0] for name in base.action_names)
    column = {s: cat.SETTING_NAMES.index(s) for s in controllable}
    return [s for s in controllable if not np.allclose(nearest[:, column[s]], truth[:, column[s]])]


def lever_check(env, week: int, shoebox: bool = True) -> list[dict]:
    """Pull each lever alone (:func:`lever_actions`) on ``week`` of ``env``'s site and compare.

    Args:
        env: the metamodel ``BuildingWeek-v0`` of a site with an EnergyPlus model (made by ``buildenv site
            reference``).
        week: week of the site's year.
        shoebox: also run the levers on the EnergyPlus shoebox at the calibrated parameters.
    Returns:
        one row per lever: ``setting``, ``end``, ``historical`` (the site's) and ``value`` (the setting's mean over
        the week's days, catalogue units), then predicted and realised savings (percent) and comfort (K),
        ``savings_error_points`` (predicted - realised) and, with the shoebox, ``shoebox_savings_percent``. Where
        historical settings lie outside the action range (:func:`shifted_settings`), the savings are the lever's
        alone: from the historical action, which holds them at their nearest, in percent of the historical
        settings' energy, and each row names them in ``"baseline_shifted"``.
    Raises:
        BuildingEnvError: the site has no EnergyPlus model.
        BuildenvError: no setting can be moved (:func:`lever_actions`).
    """
    from buildenv.env.response import chosen_figures, response_check

    levers, actions = lever_actions(env)
    shifted = shifted_settings(env)
    if shifted:  # the historical action, at the end: what every lever moves from
        actions = np.vstack([actions, np.asarray(env.unwrapped.historical_action, np.float32)[None]])
    check = response_check(env, week, n=0, extra=actions, shoebox=shoebox)
    figures = check.summary["chosen"]
    if shifted:
        start = figures.pop()
        keys = ("predicted_savings_percent", "realised_savings_percent", "shoebox_savings_percent")
        for f in figures:
            moved = {k: f[k] - start[k] for k in keys if k in f and k in start}
            f.update(
                chosen_figures(
                    moved["predicted_savings_percent"],
                    moved["realised_savings_percent"],
                    f["predicted_comfort_k"],
                    f["realised_comfort_k"],
                ),
                **{k: round(v, 2) for k, v in moved.items() if k == "shoebox_savings_percent"},
            )
    settings = env.unwrapped.decode(actions)
    historical = np.asarray(env.unwrapped.site_model.historical, float)
    rows = []
    for i, ((setting, end), row) in enumerate(zip(levers, figures)):
        j = cat.SETTING_NAMES.index(setting)
        rows.append(
            {
                "setting": setting,
                "end": end,
                "historical": round(float(historical[:, j].mean()), 2),
                "value": round(float(settings[i, :, j].mean()), 2),
                **row,
                **({"baseline_shifted": shifted} if shifted else {}),
            }
        )
    return rows


def check_suite_levers(suite, parts=("development",), metamodel: str = "default", progress: bool = True) -> list[dict]:
    """The lever check on every calibrated site of a suite folder in ``parts``, on each site's first held-out week;
    one row per site and lever (the case's fields, ``week``, then :func:`lever_check`'s), written to
    ``<suite>/levers.json`` after each site (with ``errors``: the sites that could not be checked, and why).

    Raises:
        BuildenvError: no calibrated site in ``parts`` (run ``buildenv suite calibrate`` first).
    """
    from buildenv.env.response import first_heldout_week

    def levers(record: dict) -> list[dict]:
        env = gym.make("BuildingWeek-v0", site=record["site"], metamodel=metamodel, weeks="all")
        week = first_heldout_week(env)
        return [{"week": week, **row} for row in lever_check(env, week)]

    return check_calibrated_sites(suite, parts, levers, "levers.json", "levers", progress)


def grouping(text: str) -> tuple[str, ...]:
    """The case fields of a comma-separated ``text`` (``"building,season"``) to group sites by.

    Raises:
        BuildenvError: a name that is not a case field, named with the ones there are.
    """
    by = tuple(k.strip() for k in text.split(",") if k.strip())
    unknown = [k for k in by if k not in CASE_FIELDS]
    if unknown:
        raise BuildenvError(f"--by {text}: {', '.join(unknown)} is not a case field; use {', '.join(CASE_FIELDS)}")
    return by


def summarise_levers(rows: list[dict], by: tuple[str, ...] = ("season",)) -> list[dict]:
    """Per group of sites (case fields ``by``, see :func:`grouping`), setting and end: ``sites``, the median savings
    error (points) and its median absolute, and, where the shoebox ran, the median of the shoebox against the
    building and of the metamodel against the shoebox (points)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((*(r[k] for k in by), r["setting"], r["end"]), []).append(r)
    out = []
    for key, rs in sorted(groups.items()):
        error = np.array([r["savings_error_points"] for r in rs])
        entry = {
            **dict(zip(by, key)),
            "setting": key[-2],
            "end": key[-1],
            "sites": len(rs),
            "error_median_points": round(float(np.median(error)), 2),
            "error_median_abs_points": round(float(np.median(np.abs(error))), 2),
        }
        with_shoebox = [r for r in rs if "shoebox_savings_percent" in r]
        if with_shoebox:
            sb = np.array([r["shoebox_savings_percent"] for r in with_shoebox])
            real = np.array([r["realised_savings_percent"] for r in with_shoebox])
            pred = np.array([r["predicted_savings_percent"] for r in with_shoebox])
            entry["shoebox_vs_building_median_points"] = round(float(np.median(sb - real)), 2)
            entry["metamodel_vs_shoebox_median_points"] = round(float(np.median(pred - sb)), 2)
        out.append(entry)
    return out
