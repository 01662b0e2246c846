"""Registers ``BuildingWeek-v0`` and ``mo-BuildingWeek-v0`` with gymnasium without importing the environment
modules (cheap on import)."""

from __future__ import annotations

ENV_ID = "BuildingWeek-v0"
MO_ENV_ID = "mo-BuildingWeek-v0"


def register_envs() -> None:
    """Register ``BuildingWeek-v0`` and its multi-objective version ``mo-BuildingWeek-v0`` (single and native
    vector entry points) if not registered yet.

    Called by ``import buildenv``; also declared as the ``gymnasium.envs`` entry point for gymnasium versions
    that load environment plugins (gymnasium 1.x no longer does: there, ``import buildenv`` or
    ``gymnasium.make("buildenv:BuildingWeek-v0")`` registers it; use that id where environments are made in
    fresh processes, as ``SubprocVecEnv`` and ``AsyncVectorEnv`` with ``spawn``/``forkserver`` do).

    The registered spec leaves ``max_episode_steps`` None on purpose: an episode lasts ``episode_weeks`` weeks,
    an argument, and a registered time limit would cut longer episodes short. The environments fill it into
    the spec they are made with instead (``gymnasium.make("BuildingWeek-v0", episode_weeks=3).spec
    .max_episode_steps == 3``), which is what ``TimeAwareObservation`` and similar wrappers read.

    ``mo-BuildingWeek-v0`` (:mod:`buildenv.env.multi_objective`) returns a ``(2,)`` vector reward; its spec
    disables gymnasium's passive environment checker, which warns on any reward that is not a scalar (as
    ``mo_gymnasium.make`` does for MO-Gymnasium's environments). ``gymnasium.utils.env_checker.check_env``
    still passes on it.
    """
    import gymnasium

    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            entry_point="buildenv.env.building_week:BuildingWeekEnv",
            vector_entry_point="buildenv.env.vector:BuildingWeekVectorEnv",
        )
    if MO_ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=MO_ENV_ID,
            entry_point="buildenv.env.multi_objective:MOBuildingWeekEnv",
            vector_entry_point="buildenv.env.multi_objective:MOBuildingWeekVectorEnv",
            disable_env_checker=True,
        )
