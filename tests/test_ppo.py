"""PPO on BuildingWeek-v0: the SB3 VecEnv adapter, a tiny training run, scoring on held-out weeks, save/load."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecCheckNan

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from agents.ppo import BuildingVecEnv, evaluate_policy_weeks, load_policy, policy_actions, save_policy, train_ppo
from buildenv.env.observations import observation_size
from buildenv.errors import BuildingEnvError

# the default site's BMS changes 12 of the 13 settings (not the supply air), each day of the week
N_ACTION = 7 * 12

N_ENVS = 8


@pytest.fixture(scope="module")
def vec():
    return BuildingVecEnv(num_envs=N_ENVS, weeks=[12, 13])


@pytest.fixture(scope="module")
def env():
    return gym.make("BuildingWeek-v0", weeks="test")


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    path = tmp_path_factory.mktemp("ppo") / "tiny.zip"
    model = train_ppo(
        {"weeks": [0, 1, 2, 3]},
        timesteps=2 * N_ENVS * 16,
        num_envs=N_ENVS,
        seed=0,
        save=path,
        n_steps=16,
        batch_size=64,
        n_epochs=2,
    )
    return model, path


def test_adapter_steps_with_same_step_autoreset_and_terminal_observation(vec):
    checked = VecCheckNan(vec, raise_exception=True)  # SB3's VecEnv sanity wrapper: no NaN/inf in or out
    vec.seed(7)
    obs = checked.reset()
    assert (
        obs.shape == (N_ENVS, observation_size("compact"))
        and obs.dtype == np.float32
        and vec.observation_space.contains(obs[0])
    )
    weeks = np.array([info["week"] for info in vec.reset_infos])
    assert set(weeks) <= {12, 13}
    vec.seed(7)
    assert np.array_equal(checked.reset(), obs)  # seeded resets are reproducible
    actions = np.random.default_rng(0).uniform(-1, 1, (N_ENVS, N_ACTION)).astype(np.float32)
    new_obs, rewards, dones, infos = checked.step(actions)
    assert rewards.shape == (N_ENVS,) and rewards.dtype == np.float32 and dones.all()  # one-week episodes
    assert isinstance(infos, list) and len(infos) == N_ENVS
    for i, info in enumerate(infos):
        assert np.array_equal(info["terminal_observation"], obs[i])  # the finished episode's observation
        assert info["TimeLimit.truncated"] is False and info["week"] == weeks[i]
        assert info["reward"] == pytest.approx(rewards[i])
    # the rewards are the environment's scores of these actions on these weeks
    same = weeks == weeks[0]
    scored = vec.evaluate(actions, week=int(weeks[0]))["reward"]
    np.testing.assert_allclose(rewards[same], scored[same], rtol=1e-5)
    # same-step autoreset: each returned observation starts a new episode on week 12 or 13 (without the
    # reset, a week-13 episode would have moved on to week 14)
    assert set(weeks) == {12, 13}
    starts = [obs[weeks == w][0] for w in (12, 13)]
    assert all(any(np.array_equal(row, start) for start in starts) for row in new_obs)
    assert vec.get_attr("num_envs", [0, 1]) == [N_ENVS, N_ENVS] and vec.env_is_wrapped(gym.Wrapper) == [False] * N_ENVS


def test_adapter_needs_step_async_and_a_native_vector_env(vec):
    with pytest.raises(BuildingEnvError, match="step_async"):
        vec.step_wait()
    with pytest.raises(BuildingEnvError, match="not both"):
        BuildingVecEnv(vec.venv, weeks="train")


def test_tiny_ppo_trains_and_is_scored_on_a_held_out_week(tiny_model, env):
    model, _ = tiny_model
    assert model.num_timesteps == 2 * N_ENVS * 16
    [result] = evaluate_policy_weeks(model, weeks=[12], env=env)
    assert result.week == 12 and result.action.shape == (N_ACTION,) and np.all(np.abs(result.action) <= 1.0)
    assert np.isfinite(result.scores["reward"]) and result.scores["energy_term"] > 0
    assert 0.0 < result.seconds < 1.0
    # started at the historical settings, a barely trained policy stays close to them
    hist = env.unwrapped.evaluate(env.unwrapped.historical_action[None], week=12)["reward"][0]
    assert abs(result.scores["reward"] - hist) < 0.5


def test_save_and_load_reproduce_actions(tiny_model, env, tmp_path):
    model, path = tiny_model
    obs = np.stack([env.reset(options={"week": w})[0] for w in (12, 28, 44)])
    loaded = load_policy(path)
    np.testing.assert_array_equal(policy_actions(loaded, obs), policy_actions(model, obs))
    again = save_policy(loaded, tmp_path / "copy")
    assert again.suffix == ".zip"
    np.testing.assert_array_equal(policy_actions(load_policy(again), obs), policy_actions(model, obs))
    with pytest.raises(BuildingEnvError, match="not found"):
        load_policy(tmp_path / "missing.zip")


def test_ppo_on_the_library_starts_at_the_mean_of_the_sites_historical_settings():
    model = train_ppo(
        {"site": "library", "sites": "train"},
        timesteps=N_ENVS * 2,
        num_envs=N_ENVS,
        n_steps=2,
        batch_size=16,
        n_epochs=1,
        learning_rate=1e-9,
    )
    venv = gym.make_vec("BuildingWeek-v0", num_envs=2, site="library", sites="train").unwrapped
    each = venv.site_historical_actions
    assert each.shape == (len(venv.site_names), N_ACTION) and len(venv.site_names) > 1
    bias = model.policy.action_net.bias.detach().numpy()
    np.testing.assert_allclose(bias, each.mean(axis=0), atol=1e-4)


class _Zeros:
    """A policy whose actions are all 0 (the middle of every range)."""

    def __init__(self, size: int) -> None:
        self.size = size

    def predict(self, observations, deterministic=True):
        return np.zeros((len(observations), self.size), np.float32), None


def test_policy_weeks_are_a_split_of_a_given_env_or_any_iterable_of_weeks(env):
    policy = _Zeros(env.action_space.shape[0])
    every = gym.make("BuildingWeek-v0", weeks="all")
    test = [r.week for r in evaluate_policy_weeks(policy, env=every)]
    assert test == gym.make("BuildingWeek-v0", weeks="test").unwrapped.weeks
    assert [r.week for r in evaluate_policy_weeks(policy, weeks=(w for w in test[:2]))] == test[:2]


def test_the_sb3_adapter_renders_each_environment_s_last_week():
    vec = BuildingVecEnv(num_envs=2, render_mode="rgb_array")
    vec.reset()
    vec.step(np.zeros((2, vec.action_space.shape[0]), np.float32))
    images = vec.get_images()
    assert len(images) == 2 and images[0].ndim == 3 and images[0].shape[-1] == 3
