"""mo-BuildingWeek-v0: gymnasium's checker, the vector reward and its space, scalarisation, MO-Gymnasium wrappers."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import buildenv  # noqa: F401  (registers BuildingWeek-v0 and mo-BuildingWeek-v0)
from buildenv.env.multi_objective import MOBuildingWeekEnv, MOBuildingWeekVectorEnv

# the default site's BMS changes 12 of the 13 settings (not the supply air), each day of the week
N_ACTION = 7 * 12

ID = "mo-BuildingWeek-v0"


@pytest.fixture(scope="module")
def env():
    return gym.make(ID)


@pytest.fixture(scope="module")
def scalar_env():
    return gym.make("BuildingWeek-v0")


def test_gymnasium_env_checker_passes(env):
    from gymnasium.utils.env_checker import check_env

    assert isinstance(env.unwrapped, MOBuildingWeekEnv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    # the only complaint: the reward is a vector, which is the point of the environment
    assert all("reward returned by `step()` must be a float" in str(w.message) for w in caught)


def test_reward_space_and_attributes(env):
    base = env.unwrapped
    space = base.reward_space
    assert isinstance(space, gym.spaces.Box) and space.shape == (2,) and space.dtype == np.float32
    assert np.all(space.high == 0.0) and np.all(np.isneginf(space.low))
    assert base.reward_dim == 2
    assert env.spec.max_episode_steps == 1 and env.spec.disable_env_checker


def test_reward_is_the_reward_vector_inside_the_space(env):
    rng = np.random.default_rng(0)
    for i in range(3):
        env.reset(seed=10 + i)
        _, reward, terminated, _, info = env.step(rng.uniform(-1, 1, N_ACTION).astype(np.float32))
        assert isinstance(reward, np.ndarray) and reward.shape == (2,) and reward.dtype == np.float32
        assert env.unwrapped.reward_space.contains(reward)
        np.testing.assert_array_equal(reward, info["reward_vector"])
        assert reward[0] == pytest.approx(-info["energy_term"], rel=1e-6)
        assert reward[1] == pytest.approx(-info["comfort_k"], rel=1e-6)
        assert terminated


@pytest.mark.parametrize("comfort_weight", [1.0, 2.5])
def test_scalarised_reward_equals_building_week(comfort_weight):
    mo_env = gym.make(ID, comfort_weight=comfort_weight)
    scalar_env = gym.make("BuildingWeek-v0", comfort_weight=comfort_weight)
    weights = mo_env.unwrapped.reward_weights
    np.testing.assert_array_equal(weights, np.array([1.0, comfort_weight], np.float32))
    action = np.random.default_rng(1).uniform(-1, 1, N_ACTION).astype(np.float32)
    for seed in (0, 5):
        obs_mo, info_mo = mo_env.reset(seed=seed)
        obs, info = scalar_env.reset(seed=seed)
        assert info_mo == info and np.array_equal(obs_mo, obs)
        vector = mo_env.step(action)[1]
        reward = scalar_env.step(action)[1]
        assert float(vector @ weights) == pytest.approx(reward, rel=1e-6)


def test_native_vector_env_rewards(scalar_env):
    venv = gym.make_vec(ID, num_envs=3, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    assert isinstance(venv, MOBuildingWeekVectorEnv) and venv.reward_space.shape == (2,) and venv.reward_dim == 2
    _, info = venv.reset(seed=7)
    actions = np.random.default_rng(2).uniform(-1, 1, (3, N_ACTION)).astype(np.float32)
    _, rewards, terminated, _, step_info = venv.step(actions)
    assert rewards.shape == (3, 2) and rewards.dtype == np.float32 and terminated.all()
    for i, week in enumerate(info["week"]):
        scores = scalar_env.unwrapped.evaluate(actions[i : i + 1], week=int(week))
        expected = [-scores["energy_term"][0], -scores["comfort_k"][0]]
        np.testing.assert_allclose(rewards[i], expected, rtol=1e-5)
        np.testing.assert_array_equal(rewards[i], step_info["final_info"]["reward_vector"][i])
    # NEXT_STEP: the step after the end only resets, with a zero reward vector
    venv = gym.make_vec(ID, num_envs=2)
    venv.reset(seed=0)
    assert np.all(venv.step(actions[:2])[1] < 0)
    np.testing.assert_array_equal(venv.step(actions[:2])[1], np.zeros((2, 2), np.float32))


def test_mo_gymnasium_wrappers():
    mo_gym = pytest.importorskip("mo_gymnasium")
    from mo_gymnasium.wrappers import LinearReward, MORecordEpisodeStatistics

    make = getattr(mo_gym, "make", gym.make)
    env = make(ID, episode_weeks=2)
    assert isinstance(env.unwrapped, MOBuildingWeekEnv)
    weights = env.unwrapped.reward_weights
    wrapped = LinearReward(MORecordEpisodeStatistics(env, gamma=0.5), weight=weights)
    wrapped.reset(seed=0)
    action = wrapped.unwrapped.historical_action
    returns = np.zeros(2, np.float32)
    for step in range(2):
        _, scalar, terminated, _, info = wrapped.step(action)
        assert scalar == pytest.approx(float(info["vector_reward"] @ weights)) and scalar == pytest.approx(
            info["reward"]
        )
        returns += info["vector_reward"] * 0.5**step
    assert terminated
    np.testing.assert_allclose(info["episode"]["dr"], returns, rtol=1e-6)
    assert info["episode"]["r"].shape == (2,) and info["episode"]["l"] == 2


def test_mo_gymnasium_vector_wrappers():
    pytest.importorskip("mo_gymnasium")
    from mo_gymnasium.wrappers.vector import MORecordEpisodeStatistics

    venv = MORecordEpisodeStatistics(gym.make_vec(ID, num_envs=2))
    venv.reset(seed=0)
    _, rewards, terminated, _, info = venv.step(np.zeros((2, N_ACTION), np.float32))
    assert terminated.all() and info["_episode"].all()
    np.testing.assert_allclose(info["episode"]["r"], rewards)
