"""The check the paper could not do: run the historical and the chosen settings on the real building.

The site's reference-building EnergyPlus model (``BuildingWeek-v0`` with ``backend="energyplus"``) runs the
same week under both settings; realised savings and comfort are compared with what the metamodel predicted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from agents.cmaes import scalar_scores
from buildenv.env.response import energyplus_env
from buildenv.errors import BuildingEnvError


@dataclass
class Verification:
    """Predicted and realised figures of a chosen action, and the hourly series behind them.

    Attributes:
        summary: predicted and realised (EnergyPlus) savings (%), comfort (K) and week energy (kWh) of the
            historical and chosen settings, and ``seconds_energyplus`` (keys: :func:`verify`).
        predicted: metamodel ``evaluate`` scores of ``[historical, chosen]`` (hourly series included).
        realised: EnergyPlus ``evaluate`` scores of ``[historical, chosen]``.
        occupied: ``(168,)`` occupied hours.
    """

    summary: dict[str, float]
    predicted: dict
    realised: dict
    occupied: np.ndarray


def verify(env, week: int, action: np.ndarray) -> Verification:
    """Run the historical settings and ``action`` on the site's EnergyPlus model (about 10 s on 2 cores).

    Args:
        env: the metamodel ``BuildingWeek-v0`` the action was chosen on (its arguments are reused).
        week: week of the year.
        action: ``(A,)`` chosen action (A: the action size).
    Returns:
        the :class:`Verification`; its ``summary`` keys: ``predicted_savings_percent``,
        ``realised_savings_percent``, ``comfort_historical``, ``comfort_chosen``, ``comfort_historical_predicted``,
        ``comfort_chosen_predicted``, ``energy_historical_kwh``, ``energy_chosen_kwh``,
        ``energy_historical_predicted_kwh``, ``energy_chosen_predicted_kwh``, ``seconds_energyplus``.
    Raises:
        BuildingEnvError: an environment with morphed weather years (EnergyPlus runs the site's own weather file).
    """
    base = env.unwrapped
    if base.arguments.get("weather_years", 1) not in (1, [0], (0,)):
        raise BuildingEnvError(
            "verify: the EnergyPlus model runs the site's own weather file, not morphed weather years; verify on an "
            "environment made with weather_years=1"
        )
    both = np.stack([base.historical_action, np.asarray(action, dtype=np.float32)])
    predicted = base.evaluate(both, week=week)
    started = time.perf_counter()
    realised = energyplus_env(env).unwrapped.evaluate(both, week=week)
    seconds = time.perf_counter() - started
    p, r = scalar_scores(predicted, 1), scalar_scores(realised, 1)
    summary = {
        "predicted_savings_percent": p["savings_percent"],
        "realised_savings_percent": r["savings_percent"],
        "comfort_historical": r["comfort_historical_k"],
        "comfort_chosen": r["comfort_k"],
        "comfort_historical_predicted": p["comfort_historical_k"],
        "comfort_chosen_predicted": p["comfort_k"],
        "energy_historical_kwh": r["energy_historical_kwh"],
        "energy_chosen_kwh": r["energy_kwh"],
        "energy_historical_predicted_kwh": p["energy_historical_kwh"],
        "energy_chosen_predicted_kwh": p["energy_kwh"],
        "seconds_energyplus": round(seconds, 1),
    }
    return Verification(summary, predicted, realised, base.occupied_hours)
