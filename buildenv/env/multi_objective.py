"""``mo-BuildingWeek-v0``: :class:`.BuildingWeekEnv` with its two objectives as a vector reward.

The environment is ``BuildingWeek-v0`` in every respect (arguments, spaces, episodes, ``info``, ``evaluate``)
except that ``step`` returns the reward as a ``(2,)`` ``float32`` vector ``[energy, comfort]`` and the
environment has a ``reward_space`` and a ``reward_dim``, MO-Gymnasium's conventions, so its wrappers
(``LinearReward``, ``MORecordEpisodeStatistics``, the ``wrappers.vector`` ones) and multi-objective agents
take it as it is. It needs gymnasium only; ``mo-gymnasium`` is the optional extra ``buildenv[mo]``.
``gymnasium.make_vec("mo-BuildingWeek-v0", num_envs=N)`` gives the native batched version, whose rewards
are ``(N, 2)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from buildenv.env.building_week import BuildingWeekEnv
from buildenv.env.vector import BuildingWeekVectorEnv

#: the reward vector's components, in order
REWARD_NAMES = ("energy", "comfort")


def reward_space() -> spaces.Box:
    """``Box(-inf, 0, (2,), float32)``: ``[-energy_term, -comfort_term]``. Both terms are >= 0 (HVAC energy
    counts each hour from 0; every comfort kind is a deviation) and have no upper bound (a metamodel's or
    EnergyPlus's outputs are not bounded), so each component is at most 0 and has no lower bound."""
    return spaces.Box(low=-np.inf, high=0.0, shape=(len(REWARD_NAMES),), dtype=np.float32)


class _VectorReward:
    """What both multi-objective environments add to their base: ``reward_space``, ``reward_dim`` and
    ``reward_weights``."""

    def __init__(self, **kwargs: Any) -> None:
        """Arguments as the base environment's."""
        super().__init__(**kwargs)
        self.reward_space = reward_space()
        self.reward_dim = len(REWARD_NAMES)

    @property
    def reward_weights(self) -> np.ndarray:
        """``(2,)`` ``float32`` ``[1, comfort_weight]`` (comfort weight per K): the weights that turn the vector
        reward into ``BuildingWeek-v0``'s scalar reward."""
        return np.array([1.0, self._b.comfort_weight], dtype=np.float32)


class MOBuildingWeekEnv(_VectorReward, BuildingWeekEnv):
    """``BuildingWeek-v0`` with a vector reward (MO-Gymnasium's ``mo-`` convention).

    ## Reward Space
    :func:`reward_space`, ``Box(-inf, 0, (2,), float32)``, both components "higher is better":

    * 0, energy: ``-energy_term``, the week's mean hourly HVAC energy over the same week's under the site's
      historical settings (dimensionless; -1.0 = as today, -0.9 = 10 % saved); with ``price=`` (a time-of-use
      tariff, :mod:`buildenv.env.tariff`) the week's HVAC energy cost over the historical settings' cost
      instead (-1.0 = today's cost);
    * 1, comfort: ``-comfort_term``, the deviation from ``target_temperature_c`` over the occupied hours, K
      (by ``comfort``: ``rms``, ``band`` or ``mean_abs``).

    The vector equals ``info["reward_vector"]``. ``BuildingWeek-v0``'s scalar reward is its dot product with
    :attr:`reward_weights` ``= [1, comfort_weight]`` (to float32 precision), so
    ``mo_gymnasium.wrappers.LinearReward(env, weight=env.unwrapped.reward_weights)`` is ``BuildingWeek-v0``.

    ## Everything else
    As :class:`.BuildingWeekEnv` (same arguments, action and observation spaces, episodes, ``info``,
    ``evaluate``, rendering, pickling). ``reward_dim`` is 2.

    ## Version History
    * v0: first version.
    """

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, bool, dict]:
        """As :meth:`.BuildingWeekEnv.step`, with the reward a ``(2,)`` ``float32`` vector ``[energy, comfort]``
        (see Reward Space in the class docstring)."""
        obs, _, terminated, truncated, info = super().step(action)
        return obs, info["reward_vector"].copy(), terminated, truncated, info


class MOBuildingWeekVectorEnv(_VectorReward, BuildingWeekVectorEnv):
    """N copies of :class:`MOBuildingWeekEnv` stepped in one metamodel call (``gymnasium.make_vec``).

    As :class:`.BuildingWeekVectorEnv` (arguments, autoreset modes, infos, seeds), with rewards ``(N, 2)``
    ``float32``: row i is sub-environment i's :class:`MOBuildingWeekEnv` reward, zeros where a step only
    reset it (``AutoresetMode.NEXT_STEP``), as ``mo_gymnasium.wrappers.vector.MOSyncVectorEnv`` gives.
    ``reward_space`` is one sub-environment's, ``Box(-inf, 0, (2,), float32)``, as in ``MOSyncVectorEnv``
    (what ``mo_gymnasium.wrappers.vector.MORecordEpisodeStatistics`` reads); ``reward_dim`` is 2.
    """

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """As :meth:`.BuildingWeekVectorEnv.step`, with rewards ``(num_envs, 2)`` ``float32`` (class docstring)."""
        obs, _, terminated, truncated, info = super().step(actions)
        rewards = np.zeros((self.num_envs, self.reward_dim), dtype=np.float32)
        for source in (info, info.get("final_info", {})):  # finished rows' step info is in final_info (SAME_STEP)
            if "reward_vector" in source:
                mask = source["_reward_vector"]
                rewards[mask] = source["reward_vector"][mask]
        return obs, rewards, terminated, truncated, info
