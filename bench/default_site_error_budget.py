"""Where the calibrated default metamodel misses the default site: the held-out squared error by time of day.

Takes the default site's saved calibration (``buildenv/data/sites/default/calibration.json``, the metamodel's
CMA-ES on weeks 0-2), predicts the held-out weeks 3-5 and splits each series' squared error into blocks of
the week (occupied weekday hours, the hour the heating period ends, evenings, nights, weekends), with the mean
residual (measured - predicted) of each block and, for consumption, the model's outputs in the block. It also
reruns the held-out prediction with the night setback raised by 0.5-3 K (no recalibration), the simplest
stand-in for the reference's night-cycle heating.

Then it measures what the model side of the ``night_cycle_cold_air`` effect buys on its own: the reference is
a VAV system with terminal reheat, whose fans cycle on at night whenever a zone needs heat and then supply
every zone air at the cooling supply temperature (12.8 degC), so the zones that need no heat cool down while
the others reheat the air. Our model has no such path. The term (:mod:`buildenv.effects_model`) lowers the
predicted temperature by ``cooling_k_per_wh_m2`` per Wh/m2 of the model's heating in the hours its ventilation
is off and adds ``reheat_share`` times that heating to the consumption; both are fitted (Nelder-Mead on the
calibration cost) on the fit weeks with the calibrated parameters unchanged, and scored on the held-out weeks. With
``--reference-probe`` it also reruns the stand-in (EnergyPlus, a few seconds each) with the effect injected
(the VAV boxes' minimum air flow raised out of hours) and with the outdoor-air dampers closed out of hours, to
check the mechanism: more cold air at night must make the nights colder, and the cold air is the cooling
coil's 12.8 degC supply, not outdoor air let in by the economizer.
Writes ``bench/results/default_site_error_budget.md``.

    .venv/bin/python bench/default_site_error_budget.py [--reference-probe]
"""

from __future__ import annotations

import argparse
import datetime as dt

import numpy as np
from scipy.optimize import minimize

from buildenv import calibration as cal
from buildenv import catalogue as cat
from buildenv import surrogate as sg
from buildenv.env import DEFAULT_SITE
from buildenv.site import load_site
from buildenv.surrogate import load_metamodel

from _training_runs import RESULTS, machine

HELDOUT = [3, 4, 5]
# (label, days, hours) blocks of the week; hours are hour-of-day indices (hour h = h:00-h+1:00)
BLOCKS = (("weekday 07-17 (heating period)", range(5), range(7, 18)),
          ("weekday 18 (heating ended, ventilation on)", range(5), range(18, 19)),
          ("weekday 19-22 (evening)", range(5), range(19, 23)),
          ("nights 23-06, every day", range(7), [23, *range(0, 7)]),
          ("weekend 07-22", range(5, 7), range(7, 23)))


def _share(sq: np.ndarray, days, hours) -> float:
    return float(sq[:, list(days)][:, :, list(hours)].sum() / sq.sum())


def _mean(r: np.ndarray, days, hours) -> float:
    return float(np.nanmean(r[:, list(days)][:, :, list(hours)]))


NIGHT_EFFECT = "night_cycle_cold_air"


def _night_term_rows(site, surrogate: sg.Surrogate, params: np.ndarray, fit_weeks: list[int]) -> list[str]:
    """Fit the night-cycle term (the model side of ``night_cycle_cold_air``, :mod:`buildenv.effects_model`) on
    the fit weeks with the calibrated parameters kept, score it on the held-out weeks (table rows)."""
    fit_problem = cal.build_problem(site, fit_weeks, (NIGHT_EFFECT,))
    held_problem = cal.build_problem(site, HELDOUT, (NIGHT_EFFECT,))

    def cost(v: np.ndarray) -> float:
        v = np.clip(v, 0.0, None)
        return float(cal.evaluate(fit_problem, surrogate, np.r_[params, v, 0.0][None])[0])

    best = min((minimize(cost, [g0, 0.1], method="Nelder-Mead") for g0 in (0.02, 0.1, 0.3)), key=lambda r: r.fun)
    rows = []
    for name, v in (("none (the saved calibration)", np.zeros(2)),
                    (f"cooling_k_per_wh_m2 = {max(best.x[0], 0):.3f}, reheat_share = {max(best.x[1], 0):.2f}",
                     np.clip(best.x, 0.0, None))):
        full = np.r_[params, v, 0.0]  # the night hours' term only (supply_shortfall_k at none)
        t, q = cal.predict(held_problem, surrogate, full)
        m = cal.score_series(held_problem, t, q, full, cal._scale(fit_problem))
        rows.append(f"| {name} | {cost(v):.4f} | {m['r2_t']:.3f} | {m['rmse_t_celsius']:.3f} | "
                    f"{m['r2_q']:.3f} | {m['cv_rmse_q_percent']:.1f} | {m['nmbe_q_percent']:+.1f} |")
    return rows


def _dampers_closed_out_of_hours(prepare):
    """``prepare_model`` wrapped so that every outdoor-air controller's maximum outdoor-air fraction follows the
    BMS outdoor-air schedule (0 out of hours: the economizer cannot open the dampers at night)."""
    from buildenv.energyplus.idf import format_idf, of_type, read_idf

    def wrapped(*args, **kwargs):
        idf, mapping = prepare(*args, **kwargs)
        objects = read_idf(idf)
        for o in of_type(objects, "Controller:OutdoorAir"):
            o.extend([""] * (20 - len(o)))
            o[19] = "buildenv_outdoor_air"  # Maximum Fraction of Outdoor Air Schedule Name
        idf.write_text(format_idf(objects))
        return idf, mapping
    return wrapped


def _reference_probe() -> list[str]:
    """Rerun the stand-in with ``night_cycle_cold_air`` injected, and with its outdoor-air dampers closed out of
    hours (table rows)."""
    from buildenv import reference as ref

    settings = ref.historical_settings(6, ref.historical_ventilation_ach("medium_office"))
    night = np.isin(np.arange(cat.HOURS_PER_WEEK) % cat.HOURS_PER_DAY, [23, *range(0, 7)])
    rows, prepare = [], ref.prepare_model
    for label, magnitude, closed in (("the site as shipped", 0.0, False),
                                     (f"{NIGHT_EFFECT} = 20 (boxes' minimum 50 % out of hours)", 20.0, False),
                                     ("outdoor-air dampers closed out of hours", 0.0, True)):
        ref.prepare_model = _dampers_closed_out_of_hours(prepare) if closed else prepare
        try:
            run = ref.run_reference("medium_office", "usa_il_chicago", dt.date(2019, 11, 4), settings,
                                    effects=[(NIGHT_EFFECT, magnitude)])
        finally:
            ref.prepare_model = prepare
        t = run.temperature_c
        rows.append(f"| {label} | {t[:3][:, night].mean():.2f} | {t[3:][:, night].mean():.2f} | "
                    f"{run.consumption_kwh[:, night].sum() / 1000:.1f} |")
    return rows


def main() -> None:
    """Write the error budget of the default site's held-out weeks."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference-probe", action="store_true",
                        help="also rerun the stand-in with the effect injected and without night outdoor air")
    args = parser.parse_args()
    site = load_site(DEFAULT_SITE)
    calib = site.calibration
    params = cal.calibrated_parameters(calib)
    surrogate = load_metamodel()
    problem = cal.build_problem(site, HELDOUT)
    out, t, q = cal.simulate(problem, surrogate, params[None])
    shape = (len(HELDOUT), 7, cat.HOURS_PER_DAY)
    rt = (site.temperature_c[HELDOUT] - t[0]).reshape(shape)
    rq = (site.consumption_wh_m2()[HELDOUT] - q[0]).reshape(shape)
    days = out[0].reshape(*shape, -1)
    sqt, sqq = np.nan_to_num(rt) ** 2, np.nan_to_num(rq) ** 2
    lines = ["# The default site's held-out error, block by block", "",
             f"{machine()}; `python bench/default_site_error_budget.py`. Default metamodel, the site's saved "
             f"calibration (fit weeks {calib['fit_weeks']}), held-out weeks {HELDOUT} (hourly, 504 hours).", "",
             "| block | hours | share of T squared error | mean T residual K | share of Q squared error | "
             "mean Q residual Wh/m2 | model Q_AHU_H Wh/m2 | model Q_HEAT_OFFICE Wh/m2 |",
             "|---|---|---|---|---|---|---|---|"]
    for label, d, h in BLOCKS:
        n = len(HELDOUT) * len(d) * len(h)
        ahu = days[:, list(d)][:, :, list(h), cat.OUTPUT_NAMES.index("Q_AHU_H")].mean()
        zone = days[:, list(d)][:, :, list(h), cat.OUTPUT_NAMES.index("Q_HEAT_OFFICE")].mean()
        lines.append(f"| {label} | {n} | {100 * _share(sqt, d, h):.0f} % | {_mean(rt, d, h):+.2f} | "
                     f"{100 * _share(sqq, d, h):.0f} % | {_mean(rq, d, h):+.1f} | {ahu:.1f} | {zone:.1f} |")
    lines += ["", "Night setback raised by `d` K in the model's inputs (outside the heating period), same parameters:",
              "", "| d K | held-out CV(RMSE)_Q % | held-out RMSE_T K | mean night Q residual Wh/m2 | "
              "mean night T residual K |", "|---|---|---|---|---|"]
    x0 = cal.encode_candidates(problem, params[None])
    setpoint, comfort = sg.INPUT_CHANNELS.index("heating_setpoint_c"), sg.INPUT_CHANNELS.index("heating_comfort_on")
    measured_t, measured_q = site.temperature_c[HELDOUT], site.consumption_wh_m2()[HELDOUT]
    for d in (0.0, 0.5, 1.0, 1.5, 2.0, 3.0):
        x = x0.copy()
        x[..., setpoint] += np.where(x[..., comfort] > 0, 0.0, d)
        tt, qq = cal.model_series(problem, surrogate.predict_encoded(x))
        r_q, r_t = (measured_q - qq).reshape(shape), (measured_t - tt).reshape(shape)
        cv, _ = cal.guideline14(measured_q, qq)
        lines.append(f"| {d:.1f} | {cv:.1f} | {np.sqrt(np.nanmean(r_t ** 2)):.3f} | {np.nanmean(r_q[..., :6]):+.2f} | "
                     f"{np.nanmean(r_t[..., :6]):+.2f} |")
    lines += ["", "Night-cycle term (the model side of `night_cycle_cold_air`, see the script's docstring): fitted on the fit weeks "
              f"{calib['fit_weeks']}, calibrated parameters unchanged, scored on the held-out weeks:", "",
              "| term | fit cost | held-out R2_T | RMSE_T K | R2_Q | CV(RMSE)_Q % | NMBE_Q % |",
              "|---|---|---|---|---|---|---|", *_night_term_rows(site, surrogate, params, calib["fit_weeks"])]
    if args.reference_probe:
        lines += ["", "The stand-in rerun (EnergyPlus, same settings and weather) with more cold air at night, "
                  "and without outdoor air at night:", "",
                  "| stand-in | night (23-06) mean T, weeks 0-2 degC | weeks 3-5 degC | "
                  "night consumption MWh |", "|---|---|---|---|", *_reference_probe()]
    (RESULTS / "default_site_error_budget.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
