"""The optimisation's two objectives: HVAC energy and thermal comfort of a week (the paper's section 5).

- **Energy**, the paper's Delta_Q^opt: the mean hourly HVAC energy over the week's 168 hours, Wh/m2 per
  hour (numerically W/m2), where HVAC energy is the heating and cooling delivered by the zone units and the
  air handling unit (:data:`buildenv.catalogue.HVAC_OUTPUTS`). The environment reports it relative to the
  same week under the site's historical settings (1.0 = as today; 0.9 = 10 % saved). With a time-of-use tariff
  (``price=``, :mod:`buildenv.env.tariff`) the term is the week's HVAC energy cost relative to the same week's
  cost under the historical settings instead (:func:`cost_ratio`).
- **Comfort**, the paper's Delta_T^opt against ``T* = 22.5 degC`` over the occupied hours, in K:
  ``rms`` (default): the root-mean-square deviation ``sqrt(mean((T - T*)^2))`` (the paper writes the
  ``1/N_occ`` outside the square root, which makes the value depend on the week's number of occupied
  hours; we use the RMS, whose unit is K); ``band``: the mean excursion outside ``T* +/- band`` (K, 0 when
  every occupied hour lies in the band); ``mean_abs``: the mean absolute deviation.
"""

from __future__ import annotations

import numpy as np

from buildenv import catalogue as cat

COMFORT_KINDS = ("rms", "band", "mean_abs")
T_STAR_C = 22.5
#: smallest historical energy a week is normalised by (Wh/m2 per hour): a week that needs almost no HVAC
#: (mild weather) would otherwise turn tiny absolute differences into huge relative ones.
ENERGY_FLOOR_WH_M2 = 0.5


def hvac_energy_hourly(outputs: np.ndarray) -> np.ndarray:
    """HVAC energy of each hour (Wh/m2) ``(..., 168)`` of outputs ``(..., 168, 8)``; each energy counts from 0
    (a regression metamodel can predict slightly negative energies for idle hours)."""
    idx = [cat.OUTPUT_NAMES.index(n) for n in cat.HVAC_OUTPUTS]
    return np.maximum(outputs[..., idx], 0.0).sum(-1)


def hvac_energy(outputs: np.ndarray) -> np.ndarray:
    """Mean hourly HVAC energy (Wh/m2 per hour) of outputs ``(..., 168, 8)`` -> ``(...)``."""
    return hvac_energy_hourly(outputs).mean(-1)


def indoor_temperature(outputs: np.ndarray) -> np.ndarray:
    """Hourly indoor temperature (degC) ``(..., 168)`` of outputs ``(..., 168, 8)``."""
    return outputs[..., cat.OUTPUT_NAMES.index("T_INT_OFFICE")]


def comfort_deviation(
    temperature_c: np.ndarray, occupied: np.ndarray, target_c: float = T_STAR_C, kind: str = "rms", band_k: float = 1.0
) -> np.ndarray:
    """Comfort term (K) of hourly temperatures ``(..., 168)`` over the ``occupied`` hours ``(168,)``.

    Raises ``ValueError`` for an unknown ``kind`` (see :data:`COMFORT_KINDS`).
    """
    dev = np.asarray(temperature_c)[..., np.asarray(occupied, bool)] - target_c
    if kind == "rms":
        return np.sqrt((dev**2).mean(-1))
    if kind == "band":
        return np.maximum(np.abs(dev) - band_k, 0.0).mean(-1)
    if kind == "mean_abs":
        return np.abs(dev).mean(-1)
    raise ValueError(f"unknown comfort kind {kind!r}; choose one of {', '.join(COMFORT_KINDS)}")


def energy_ratio(energy: np.ndarray, historical: np.ndarray) -> np.ndarray:
    """Energy relative to the historical settings' (dimensionless), with :data:`ENERGY_FLOOR_WH_M2`."""
    return np.asarray(energy) / np.maximum(np.asarray(historical), ENERGY_FLOOR_WH_M2)


def cost_ratio(cost: np.ndarray, historical_cost: np.ndarray, floor_cost: np.ndarray) -> np.ndarray:
    """Cost relative to the historical settings' (dimensionless), the historical cost floored at ``floor_cost``,
    the cost of :data:`ENERGY_FLOOR_WH_M2` in every hour of the week at its prices (as :func:`energy_ratio`)."""
    return np.asarray(cost) / np.maximum(np.asarray(historical_cost), np.asarray(floor_cost))
