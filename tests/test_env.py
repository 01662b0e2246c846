"""BuildingWeek-v0: gymnasium and SB3 checkers, determinism, actions, batching, arguments, backends."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from buildenv import catalogue as cat
from buildenv.env import actions as act
from buildenv.env.building_week import BuildingWeekEnv, BuildingWeekVectorEnv, split_weeks
from buildenv.errors import BuildingEnvError


@pytest.fixture(scope="module")
def env():
    return gym.make("BuildingWeek-v0")


def test_make_without_arguments_passes_both_checkers(env):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    assert isinstance(env.unwrapped, BuildingWeekEnv)
    # compact observation: daily forecast 42 + occupancy 10 + calendar 2 + theta_build 21
    assert env.action_space.shape == (84,) and env.observation_space.shape == (75,)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)


def test_reset_is_deterministic_under_a_seed(env):
    obs1, info1 = env.reset(seed=123)
    obs2, info2 = env.reset(seed=123)
    assert info1 == info2 and np.array_equal(obs1, obs2)
    r1 = env.step(env.action_space.sample())[1]
    env.reset(seed=123)
    assert env.unwrapped.evaluate(np.zeros((1, 84)))["reward"].shape == (1,)
    assert np.isfinite(r1)


def test_historical_settings_score_one_and_round_trip(env):
    base = env.unwrapped
    env.reset(seed=0, options={"week": 2})
    hist = base.historical_action
    assert np.array_equal(base.decode(hist), base.site_model.historical)
    _, reward, terminated, truncated, info = env.step(hist)
    assert info["energy_term"] == pytest.approx(1.0) and info["savings_percent"] == pytest.approx(0.0, abs=1e-6)
    assert reward == pytest.approx(-(1.0 + info["comfort_k"]))
    assert terminated and not truncated
    assert info["reward_vector"].shape == (2,) and info["week"] == 2
    assert 15.0 < info["mean_temperature_occupied_c"] < 30.0


def test_actions_are_snapped_clipped_and_nan_is_an_error():
    settings, clipped = act.decode(np.full(84, 3.0))
    assert clipped == 84
    assert np.allclose(settings[0, 0], 9.0)  # cooling_start_hour at its maximum
    settings, _ = act.decode(np.full(84, 0.03))  # between grid points: snapped onto the catalogue step
    assert set(np.unique(settings[:, 0])) <= {7.0, 8.0, 9.0}
    bad = np.zeros(84)
    bad[5] = np.nan
    with pytest.raises(BuildingEnvError, match="heating_end_hour_monday"):
        act.decode(bad)


def test_out_of_range_actions_are_reported(env):
    env.reset(seed=1)
    info = env.step(np.full(84, 2.0, dtype=np.float32))[4]
    assert info["clipped_components"] == 84


def test_unknown_and_bad_arguments_are_rejected():
    with pytest.raises(BuildingEnvError, match="allowed: site, metamodel"):
        gym.make("BuildingWeek-v0", comfort_wieght=2.0)
    with pytest.raises(BuildingEnvError, match="backend"):
        gym.make("BuildingWeek-v0", backend="trnsys")


def test_week_splits_are_disjoint():
    train, test = split_weeks(52, "train"), split_weeks(52, "test")
    assert not set(train) & set(test) and sorted(train + test) == list(range(52))
    assert test[:4] == [12, 13, 14, 15]


def test_evaluate_batch_equals_steps(env):
    base = env.unwrapped
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (3, 84)).astype(np.float32)
    env.reset(options={"week": 5})
    batch = base.evaluate(actions)
    for i in range(3):
        env.reset(options={"week": 5})
        assert env.step(actions[i])[1] == pytest.approx(batch["reward"][i], rel=1e-5)
    assert batch["temperature_c"].shape == (3, 168) and batch["hvac_wh_m2"].shape == (3, 168)


def test_native_vector_env_matches_single_env(env):
    venv = gym.make_vec("BuildingWeek-v0", num_envs=4, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    assert isinstance(venv.unwrapped if hasattr(venv, "unwrapped") else venv, BuildingWeekVectorEnv)
    obs, info = venv.reset(seed=7)
    assert obs.shape == (4, 75)
    actions = np.tile(env.unwrapped.historical_action, (4, 1))
    weeks = info["week"].copy()
    _, rewards, terminated, _, step_info = venv.step(actions)
    assert terminated.all() and "final_obs" in step_info
    for i, week in enumerate(weeks):
        expected = env.unwrapped.evaluate(actions[:1], week=int(week))["reward"][0]
        assert rewards[i] == pytest.approx(expected, rel=1e-5)


def test_several_weeks_per_episode_and_forecast_observation():
    env = gym.make("BuildingWeek-v0", episode_weeks=2, observation="forecast", weeks="all")
    obs, info = env.reset(seed=0)
    assert obs.shape == (75 + 168 * 8,)
    action = env.unwrapped.historical_action
    _, _, terminated, _, first = env.step(action)
    assert not terminated
    _, _, terminated, _, second = env.step(action)
    assert terminated and second["week"] == first["week"] + 1


def test_energyplus_backend_runs_the_reference_building():
    env = gym.make("BuildingWeek-v0", backend="energyplus", weeks="all")
    scores = env.unwrapped.evaluate(env.unwrapped.historical_action[None], week=46)
    assert scores["savings_percent"][0] == pytest.approx(0.0, abs=1e-6)
    assert 18.0 < scores["mean_temperature_occupied_c"][0] < 26.0
    assert scores["energy_kwh"][0] > 0


def test_a_metamodel_with_a_longer_context_runs_the_environment(tmp_path):
    """A checkpoint trained with two days of context (``buildenv train --context-hours 48``; here the default's
    weights, which take any length) simulates the site's weeks with its site effects, encoded with two days."""
    from buildenv.metamodel.surrogate import load_metamodel

    checkpoint = load_metamodel().checkpoint
    checkpoint.metadata = {**checkpoint.metadata, "context_hours": 48}
    path = checkpoint.save(tmp_path / "two_days.pt")
    env = gym.make("BuildingWeek-v0", metamodel=str(path))
    assert env.unwrapped.site_model.surrogate.context_hours == 48
    env.reset(seed=0, options={"week": 2})
    _, reward, *_, info = env.step(env.unwrapped.historical_action)
    assert info["energy_term"] == pytest.approx(1.0) and np.isfinite(reward)


def test_only_the_settings_the_building_can_act_on_are_actions():
    import dataclasses

    from buildenv.env.building_week import DEFAULT_SITE
    from buildenv.sites import load_site

    site = load_site(DEFAULT_SITE)
    controllable = tuple(n for n in cat.SETTING_NAMES if n != "supply_air_c")
    limited = dataclasses.replace(site, controllable=controllable, setting_limits={"ventilation_ach": (0.7, 1.0)})
    env = gym.make("BuildingWeek-v0", site=limited)
    base = env.unwrapped
    assert env.action_space.shape == (77,) and "supply_air_c_monday" not in base.action_names
    supply, vent = cat.SETTING_NAMES.index("supply_air_c"), cat.SETTING_NAMES.index("ventilation_ach")
    for a in (-1.0, 1.0):
        settings = base.decode(np.full(77, a, np.float32))
        np.testing.assert_array_equal(settings[:, supply], site.settings[0][:, supply])  # the historical value
        assert set(settings[:, vent]) == {0.7 if a < 0 else 1.0}  # within the site's limits
    np.testing.assert_array_equal(base.decode(base.historical_action), site.settings[0])
    env.reset(seed=0)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert info["settings"][:, supply].tolist() == site.settings[0][:, supply].tolist()


def test_outdoor_air_keeps_to_the_code_minimum_unless_the_site_declares_its_limits():
    env = gym.make("BuildingWeek-v0").unwrapped
    occupants = env._b.model.theta[cat.THETA_NAMES.index("occupant_density_per_m2")]
    minimum = act.code_minimum_ventilation_ach(occupants)
    assert minimum == pytest.approx((2.5 * occupants + 0.3) * 3.6 / 3.5)  # ASHRAE 62.1, office, 3.5 m storeys
    j = cat.SETTING_NAMES.index("ventilation_ach")
    lowest = env.decode(-np.ones(env.action_space.shape))[:, j]
    assert (lowest >= minimum).all() and (lowest < minimum + cat.SETTINGS[j].step).all()  # the first step above
    declared = type("Site", (), {"setting_limits": {"ventilation_ach": (0.1, 1.0)}, "controllable": cat.SETTING_NAMES})
    declared.setting_ranges = lambda self: (
        np.array([v.min for v in cat.SETTINGS]),
        np.array([v.max for v in cat.SETTINGS]),
    )
    own = act.ActionMap.for_site(declared(), {}, env._b.model.historical, occupants)
    assert own.lo[j] == cat.SETTINGS[j].min  # the operator's limits stand
