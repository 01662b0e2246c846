"""Where the calibrated default metamodel misses the default site: the held-out squared error by time of day.

Takes the default site's saved calibration (``buildenv/data/sites/default/calibration.json``, the metamodel's
CMA-ES on weeks 0-2), predicts the held-out weeks 3-5 and splits each series' squared error into blocks of
the week (occupied weekday hours, the hour the heating period ends, evenings, nights, weekends), with the mean
residual (measured - predicted) of each block and, for consumption, the model's outputs in the block. It also
reruns the held-out prediction with the night setback raised by 0.5-3 K (no recalibration), the simplest
stand-in for the reference's night-cycle heating. Writes ``bench/results/default_site_error_budget.md``.

    .venv/bin/python bench/default_site_error_budget.py
"""

from __future__ import annotations

import numpy as np

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


def main() -> None:
    """Write the error budget of the default site's held-out weeks."""
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
    (RESULTS / "default_site_error_budget.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
