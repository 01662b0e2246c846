"""A prior on the building parameters: calibration as a maximum a posteriori estimate.

A few weeks of one temperature and one meter do not pin every building parameter. Where the data say little
about a parameter, least squares leaves it wherever the metamodel's small errors push it, often at a bound of
its range (all the glazing on the north wall, no insulation): a building that fits the measured weeks but
answers a change of settings unlike any real office. A prior says what the catalogue's ranges already say:
they run from the lowest to the highest values of practice (ASHRAE 90.1 tables, DOE reference buildings), so most
buildings lie well inside them: each parameter is drawn from a normal distribution centred on its range (the
catalogue's within the metamodel's) with :data:`PRIOR_SD_SHARE` of the range as standard deviation (a bound is
about three standard deviations from the centre).

**Weight from the site's own data.** With residuals of unknown variance, the negative log-likelihood of a
channel is ``n / 2 * log(SSE)``, whose slope at the fit is ``n / (2 * cost)`` per unit of the paper's cost
(``1 - R2``). Hourly residuals are not independent: ``n`` is the effective number of hours, the channel's hours
divided by the integrated autocorrelation time of its residuals (:func:`effective_hours`). Averaged over the
two channels (a site's meters averaged first), the prior enters the paper's cost as ``anchor * sum(dz ** 2)``
(``dz``: each parameter's distance from the centre of its range, as a share of the range) with
``anchor = 1 / (a * sd ** 2)``, ``a`` the mean of ``n / cost`` over the channels, read off a first fit without the
prior; the search under it starts from that fit.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

#: standard deviation of the prior, as a share of a parameter's range (the range spans about +-3.3 of them)
PRIOR_SD_SHARE = 0.15


def effective_hours(residual: np.ndarray) -> float:
    """The number of independent hours in residuals ``(weeks, 168)`` (NaN where not measured): the measured hours
    over the integrated autocorrelation time, summed over lags up to a week until the autocorrelation first
    falls to zero or below (at least 1 hour)."""
    r = np.asarray(residual, float)
    measured = np.isfinite(r)
    n = int(measured.sum())
    if n < 2:
        return float(max(n, 1))
    centred = np.where(measured, r - r[measured].mean(), 0.0)
    energy = float((centred**2).sum())
    if energy == 0.0:
        return float(n)
    tau = 1.0
    for lag in range(1, min(cat.HOURS_PER_WEEK, centred.shape[-1] - 1) + 1):
        rho = float((centred[:, lag:] * centred[:, :-lag]).sum()) / energy
        if rho <= 0.0:
            break
        tau += 2.0 * rho
    return max(1.0, n / tau)


def prior_anchor(
    observed: list[np.ndarray], modelled: list[np.ndarray], sd_share: float = PRIOR_SD_SHARE
) -> tuple[float, dict]:
    """The prior's weight in the paper's cost (``anchor``, per squared share of a range) from each channel's
    observed and modelled series at an unweighted fit (``[(weeks, 168)]``, temperature then each meter: a site's
    meters share the consumption's half of the weight, as they share its term of the cost).

    Returns:
        ``(anchor, record)``: record holds ``sd_share``, ``anchor`` and per channel ``effective_hours`` and
        ``cost`` (``1 - R2``).
    """
    ratios, channels = [], []
    for obs, mod in zip(observed, modelled):
        obs = np.asarray(obs, float)
        residual = obs - np.asarray(mod, float)
        m = np.isfinite(residual)
        total = float(((obs[m] - obs[m].mean()) ** 2).sum())
        cost = float((residual[m] ** 2).sum()) / total if total > 0 else 1.0
        n = effective_hours(residual)
        ratios.append(n / max(cost, 1e-6))
        channels.append({"effective_hours": round(n, 1), "cost": round(cost, 5)})
    meters = float(np.mean(ratios[1:])) if len(ratios) > 1 else ratios[0]
    anchor = 1.0 / (float(np.mean([ratios[0], meters])) * sd_share**2)
    return anchor, {"sd_share": sd_share, "anchor": round(anchor, 6), "channels": channels}
