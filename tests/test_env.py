"""BuildingWeek-v0: gymnasium and SB3 checkers, determinism, actions, batching, arguments, backends."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from vector_info import same_info

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from buildenv import catalogue as cat
from buildenv.env import actions as act
from buildenv.env.building_week import BuildingWeekEnv, BuildingWeekVectorEnv, split_weeks
from buildenv.env.observations import observation_size
from buildenv.errors import BuildingEnvError

# the default site's BMS changes 12 of the 13 settings (not the supply air), each day of the week
N_ACTION = 7 * 12


@pytest.fixture(scope="module")
def env():
    return gym.make("BuildingWeek-v0")


def test_make_without_arguments_passes_both_checkers(env):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    assert isinstance(env.unwrapped, BuildingWeekEnv)
    # compact observation: daily forecast 42 + occupancy 10 + calendar 2 + theta_build 22
    assert env.action_space.shape == (N_ACTION,) and env.observation_space.shape == (observation_size("compact"),)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)


def test_reset_is_deterministic_under_a_seed(env):
    obs1, info1 = env.reset(seed=123)
    obs2, info2 = env.reset(seed=123)
    assert info1 == info2 and np.array_equal(obs1, obs2)
    r1 = env.step(env.action_space.sample())[1]
    env.reset(seed=123)
    assert env.unwrapped.evaluate(np.zeros((1, N_ACTION)))["reward"].shape == (1,)
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
    settings, clipped = act.decode(np.full(91, 3.0))
    assert clipped == 91
    assert np.allclose(settings[0, 0], 9.0)  # cooling_start_hour at its maximum
    settings, _ = act.decode(np.full(91, 0.03))  # between grid points: snapped onto the catalogue step
    assert set(np.unique(settings[:, 0])) <= {7.0, 8.0, 9.0}
    assert set(np.unique(settings[:, -1])) == {1.0}  # hvac_operating: operating above the middle, else set back
    assert set(np.unique(act.decode(np.full(91, -0.03))[0][:, -1])) == {0.0}
    bad = np.zeros(91)
    bad[5] = np.nan
    with pytest.raises(BuildingEnvError, match="heating_end_hour_monday"):
        act.decode(bad)


def test_out_of_range_actions_are_reported(env):
    env.reset(seed=1)
    info = env.step(np.full(N_ACTION, 2.0, dtype=np.float32))[4]
    assert info["clipped_components"] == N_ACTION


def test_unknown_and_bad_arguments_are_rejected():
    with pytest.raises(BuildingEnvError, match="allowed: site, metamodel"):
        gym.make("BuildingWeek-v0", comfort_wieght=2.0)
    with pytest.raises(BuildingEnvError, match="backend"):
        gym.make("BuildingWeek-v0", backend="trnsys")
    # the reference building's run does not split heating from cooling, so it cannot price them apart
    with pytest.raises(BuildingEnvError, match="price='flat' with backend='energyplus'"):
        gym.make("BuildingWeek-v0", backend="energyplus", price="flat")
    with pytest.raises(BuildingEnvError, match=r'options\["week"\]=12.5'):
        gym.make("BuildingWeek-v0", weeks="test").reset(options={"week": 12.5})


def test_week_splits_are_disjoint():
    train, test = split_weeks(52, "train"), split_weeks(52, "test")
    assert not set(train) & set(test) and sorted(train + test) == list(range(52))
    assert test[:4] == [12, 13, 14, 15]


def test_evaluate_batch_equals_steps(env):
    base = env.unwrapped
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (3, N_ACTION)).astype(np.float32)
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
    assert obs.shape == (4, observation_size("compact"))
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
    assert obs.shape == (observation_size("compact") + 168 * 8,)
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
    assert env.action_space.shape == (84,) and "supply_air_c_monday" not in base.action_names
    supply, vent = cat.SETTING_NAMES.index("supply_air_c"), cat.SETTING_NAMES.index("ventilation_ach")
    for a in (-1.0, 1.0):
        settings = base.decode(np.full(84, a, np.float32))
        np.testing.assert_array_equal(settings[:, supply], site.settings[0][:, supply])  # the historical value
        assert set(settings[:, vent]) == {0.7 if a < 0 else 1.0}  # within the site's limits
    np.testing.assert_array_equal(base.decode(base.historical_action), site.settings[0])
    env.reset(seed=0)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert info["settings"][:, supply].tolist() == site.settings[0][:, supply].tolist()


def _site_declaring(limits: dict) -> object:
    site = type("Site", (), {"setting_limits": limits, "controllable": cat.SETTING_NAMES})
    site.setting_ranges = lambda self: (
        np.array([v.min for v in cat.SETTINGS]),
        np.array([v.max for v in cat.SETTINGS]),
    )
    return site()


def test_outdoor_air_keeps_to_the_code_minimum_unless_the_site_declares_its_limits():
    env = gym.make("BuildingWeek-v0").unwrapped
    occupants = env._b.model.theta[cat.THETA_NAMES.index("occupant_density_per_m2")]
    minimum = act.code_minimum_ventilation_ach(occupants)
    assert minimum == pytest.approx((2.5 * occupants + 0.3) * 3.6 / 3.5)  # ASHRAE 62.1, office, 3.5 m storeys
    j = cat.SETTING_NAMES.index("ventilation_ach")
    free = act.ActionMap.for_site(_site_declaring({}), {}, env._b.model.historical, occupants)
    lowest = free.decode(-np.ones(free.size))[0][:, j]
    assert (lowest >= minimum).all() and (lowest < minimum + cat.SETTINGS[j].step).all()  # the first step above
    own = act.ActionMap.for_site(
        _site_declaring({"ventilation_ach": (0.1, 1.0)}), {}, env._b.model.historical, occupants
    )
    assert own.lo[j] == cat.SETTINGS[j].min  # the operator's limits stand
    # the default site, a stand-in, declares the code minimum for its design occupants up to its design: both ends
    # and the outdoor air between them are settings
    assert env.decode(-np.ones(env.action_space.shape))[:, j] == pytest.approx(0.45)
    assert env.decode(np.ones(env.action_space.shape))[:, j] == pytest.approx(0.7)
    middle = env.decode(np.zeros(env.action_space.shape))[:, j]
    assert 0.45 < middle.min() and middle.max() < 0.7


# ---------------------------------------------------------------------------------------------------------------
# gymnasium and SB3 idioms: rendering, vector autoreset modes and seeds, pickling, spec, errors (issue 85 items 1-4)

AutoresetMode = gym.vector.AutoresetMode


@pytest.fixture(scope="module")
def native_and_sync():
    """The native vector env and gymnasium's SyncVectorEnv of the single env, 3 environments, 2-week episodes."""
    kwargs = {"num_envs": 3, "episode_weeks": 2, "weeks": "all"}
    return (
        gym.make_vec("BuildingWeek-v0", **kwargs),
        gym.make_vec("BuildingWeek-v0", vectorization_mode="sync", **kwargs),
    )


def test_sb3_make_vec_env_with_defaults_trains_ppo():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env("BuildingWeek-v0", n_envs=2, seed=0)  # SB3 passes render_mode="rgb_array"
    model = PPO("MlpPolicy", venv, n_steps=4, batch_size=8, n_epochs=1, seed=0, device="cpu")
    model.learn(8)
    assert model.num_timesteps == 8
    images = venv.get_images()
    assert len(images) == 2 and images[0].shape == (540, 960, 3) and images[0].dtype == np.uint8


def test_render_the_last_week_as_a_picture_and_as_text():
    from gymnasium.utils.env_checker import check_env

    assert BuildingWeekEnv.metadata["render_modes"] == ["rgb_array", "ansi"]
    env = gym.make("BuildingWeek-v0", render_mode="rgb_array")
    with pytest.raises(gym.error.ResetNeeded):
        env.render()  # gymnasium's order enforcing; the bare env raises ResetNeededError the same way
    env.reset(seed=0, options={"week": 43})
    ahead = env.render()  # the week ahead: the forecast, nothing simulated yet
    assert ahead.shape == (540, 960, 3) and ahead.dtype == np.uint8
    env.step(env.unwrapped.historical_action)
    week = env.render()
    assert week.shape == ahead.shape and not np.array_equal(week, ahead) and week.std() > 10
    check_env(env.unwrapped)  # gymnasium's checker, rendering included (both modes, through the spec)

    text = gym.make("BuildingWeek-v0", render_mode="ansi")
    text.reset(options={"week": 43})
    assert "week 43, 2019-11-04 to 2019-11-10" in text.render() and "no settings applied yet" in text.render()
    _, _, _, _, info = text.step(text.unwrapped.historical_action)
    summary = text.render()
    assert f"{info['energy_kwh']:.1f} kWh vs {info['energy_historical_kwh']:.1f} kWh historical" in summary
    assert f"comfort {info['comfort_k']:.2f} K rms" in summary and "0.0 % less than historical" in summary
    with pytest.raises(BuildingEnvError, match="render_mode='video'; choose None or one of rgb_array, ansi"):
        BuildingWeekEnv(render_mode="video")


def test_native_vector_env_offers_next_step_autoreset_seeded_as_sync(native_and_sync):
    native, sync = native_and_sync
    assert native.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    for seed in ([1, 2, 3], 11):  # an int seeds environment i with seed + i, as SyncVectorEnv does
        obs, info = native.reset(seed=seed)
        expected_obs, expected = sync.reset(seed=seed)
        same_info(info, expected)
        np.testing.assert_array_equal(obs, expected_obs)
    assert len(set(native.reset(seed=[1, 9, 9])[1]["week"][1:])) == 1  # per-environment seeds are honoured
    native.reset(seed=11)
    rng = np.random.default_rng(0)
    for _ in range(5):  # 2-week episodes: step, step (terminates), the reset step, ...
        actions = rng.uniform(-1, 1, native.action_space.shape).astype(np.float32)
        got, expected = native.step(actions), sync.step(actions)
        np.testing.assert_allclose(got[0], expected[0], atol=1e-6)
        np.testing.assert_allclose(got[1], expected[1], rtol=1e-5)
        np.testing.assert_array_equal(got[2], expected[2])
        np.testing.assert_array_equal(got[3], expected[3])
        same_info(got[4], expected[4])


def test_same_step_autoreset_reports_final_obs_and_final_info():
    kwargs = {"num_envs": 2, "weeks": [3, 4, 5], "autoreset_mode": AutoresetMode.SAME_STEP}
    native = gym.make_vec("BuildingWeek-v0", **kwargs)
    assert native.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    sync = gym.make_vec(
        "BuildingWeek-v0",
        num_envs=2,
        weeks=[3, 4, 5],
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": "SameStep"},
    )
    obs, reset_info = native.reset(seed=3)
    sync.reset(seed=3)
    actions = np.tile(native.unwrapped.historical_action, (2, 1))
    got, expected = native.step(actions), sync.step(actions)
    info = got[4]
    assert got[2].all() and info["_final_obs"].all() and info["_final_info"].all()
    np.testing.assert_array_equal(np.stack(info["final_obs"]), obs)  # the finished episodes' last observations
    np.testing.assert_array_equal(info["final_info"]["week"], reset_info["week"])  # their step info
    np.testing.assert_allclose(info["final_info"]["energy_term"], 1.0, rtol=1e-6)  # float32 actions
    assert "reward" not in info  # the top-level info is the new episodes' reset info, as gymnasium lays it out
    same_info(info, expected[4])
    np.testing.assert_allclose(got[0], expected[0], atol=1e-6)


def test_disabled_autoreset_needs_a_masked_reset():
    venv = gym.make_vec("BuildingWeek-v0", num_envs=2, autoreset_mode="Disabled")
    with pytest.raises(gym.error.ResetNeeded, match="call reset"):
        venv.step(np.zeros((2, N_ACTION)))
    venv.reset(seed=0)
    assert venv.step(np.zeros((2, N_ACTION)))[2].all()
    with pytest.raises(gym.error.ResetNeeded, match=r"sub-environment\(s\) \[0, 1\] finished"):
        venv.step(np.zeros((2, N_ACTION)))
    _, info = venv.reset(options={"reset_mask": np.array([True, False])})
    assert info["_week"].tolist() == [True, False]
    with pytest.raises(gym.error.ResetNeeded, match=r"\[1\] finished"):
        venv.step(np.zeros((2, N_ACTION)))


#: gymnasium's vector wrappers, each with the arguments it needs beyond the env
VECTOR_WRAPPERS = {
    "NormalizeObservation": {},
    "FlattenObservation": {},
    "NormalizeReward": {},
    "RecordEpisodeStatistics": {},
    "ClipReward": {"min_reward": -2.0, "max_reward": 0.0},
    "DtypeObservation": {"dtype": np.float64},
    "RescaleObservation": {"min_obs": -1.0, "max_obs": 1.0},
    "TransformObservation": {"func": lambda obs: 2.0 * obs, "observation_space": None},
    "TransformReward": {"func": lambda reward: 0.5 * reward},
    "ClipAction": {},
    "RescaleAction": {"min_action": 0.0, "max_action": 1.0},
    "DictInfoToList": {},
}


@pytest.mark.parametrize("name", sorted(VECTOR_WRAPPERS))
def test_gymnasium_vector_wrappers_accept_the_native_env(native_and_sync, name):
    from gymnasium.wrappers import vector as wrappers

    wrapped = getattr(wrappers, name)(native_and_sync[0], **VECTOR_WRAPPERS[name])
    obs, info = wrapped.reset(seed=0)
    for _ in range(3):
        obs, reward, terminated, truncated, info = wrapped.step(wrapped.action_space.sample())
    assert obs.shape == (3, observation_size("compact")) and np.isfinite(obs).all() and np.isfinite(reward).all()
    assert isinstance(info, list if name == "DictInfoToList" else dict) and len(terminated) == 3


def test_pickle_and_deepcopy_after_a_step_predict_the_same():
    import copy
    import pickle

    env = gym.make("BuildingWeek-v0", episode_weeks=2, weeks="all")
    env.reset(seed=4)
    env.step(env.unwrapped.historical_action)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, N_ACTION)).astype(np.float32)
    expected = env.unwrapped.evaluate(actions)["reward"]
    for twin in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        np.testing.assert_array_equal(twin.unwrapped.evaluate(actions)["reward"], expected)
        assert twin.unwrapped.week == env.unwrapped.week
        _, reward, terminated, _, _ = twin.step(actions[0])  # the episode goes on where it was
        assert terminated and reward == pytest.approx(expected[0], rel=1e-6)


def test_native_vector_env_pickles_after_a_step(native_and_sync):
    import pickle

    native = native_and_sync[0]
    native.reset(seed=5)
    native.step(np.zeros((3, N_ACTION)))
    twin = pickle.loads(pickle.dumps(native))
    actions = np.random.default_rng(2).uniform(-1, 1, (3, N_ACTION))
    got, expected = twin.step(actions), native.step(actions)
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_array_equal(got[1], expected[1])


def test_sb3_subprocess_vector_env_makes_the_env_by_its_module_qualified_id():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # a fresh process imports nothing: "buildenv:" registers the env there (docs/environment.md)
    venv = make_vec_env("buildenv:BuildingWeek-v0", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv)
    try:
        obs = venv.reset()
        obs, reward, done, _ = venv.step(np.zeros((2, N_ACTION), np.float32))
        assert obs.shape == (2, observation_size("compact")) and np.isfinite(reward).all() and done.all()
    finally:
        venv.close()


def test_async_vector_env_steps():
    venv = gym.vector.AsyncVectorEnv([lambda: gym.make("BuildingWeek-v0")] * 2)
    try:
        _, info = venv.reset(seed=0)
        assert info["week"].tolist() == [BuildingWeekEnv().reset(seed=s)[1]["week"] for s in (0, 1)]
        for _ in range(2):
            _, rewards, terminated, *_ = venv.step(np.zeros((2, N_ACTION), np.float32))
        assert np.isfinite(rewards).all() and terminated.dtype == bool
    finally:
        venv.close()


def test_spec_carries_the_episode_length():
    env = gym.make("BuildingWeek-v0")
    assert env.spec.max_episode_steps == 1
    longer = gym.make("BuildingWeek-v0", episode_weeks=3, weeks="all")
    assert longer.spec.max_episode_steps == 3
    timed = gym.wrappers.TimeAwareObservation(longer)  # refused an env without max_episode_steps
    assert timed.reset(seed=0)[0].shape == (observation_size("compact") + 1,)
    _, _, terminated, truncated, _ = longer.step(longer.unwrapped.historical_action)
    assert not terminated and not truncated  # no registered time limit cuts a longer episode short
    venv = gym.make_vec("BuildingWeek-v0", num_envs=2, episode_weeks=3, weeks="all", max_episode_steps=2)
    assert venv.spec.max_episode_steps == 2
    venv.reset(seed=0)
    venv.step(np.zeros((2, N_ACTION)))
    _, _, terminated, truncated, _ = venv.step(np.zeros((2, N_ACTION)))
    assert truncated.all() and not terminated.any()  # max_episode_steps is a time limit, as gymnasium passes it


def test_step_before_reset_and_after_the_end_raise_reset_needed():
    from buildenv.env.building_week import ResetNeededError

    env = BuildingWeekEnv()
    with pytest.raises(ResetNeededError, match="call reset\\(\\) before step\\(\\)") as caught:
        env.step(env.historical_action)
    assert isinstance(caught.value, gym.error.ResetNeeded) and isinstance(caught.value, BuildingEnvError)
    env.reset(seed=0)
    assert env.step(env.historical_action)[2]
    with pytest.raises(gym.error.ResetNeeded, match="episode terminated after 1 week"):
        env.step(env.historical_action)
    with pytest.raises(gym.error.ResetNeeded, match="before render"):
        BuildingWeekEnv(render_mode="ansi").render()
    env.reset(seed=0)
    with pytest.raises(
        BuildingEnvError, match=rf"takes an action of shape \({N_ACTION},\).*got float64 \(1, {N_ACTION}\)"
    ):
        env.step(np.zeros((1, N_ACTION)))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"num_envs": 0}, "num_envs=0; give a whole number, 1 or more"),
        ({"comfort_weight": float("nan")}, "comfort_weight=nan; give a finite number >= 0"),
        ({"episode_weeks": 2.7}, "episode_weeks=2.7; give a whole number, 1 or more"),
        ({"target_temperature_c": "warm"}, "target_temperature_c='warm'; give a finite number"),
        ({"max_episode_steps": 0}, "max_episode_steps=0; give a whole number, 1 or more"),
        ({"autoreset_mode": "sometimes"}, "autoreset_mode='sometimes'; choose one of AutoresetMode.NEXT_STEP"),
        ({"wheeks": "all"}, "unknown argument.*allowed: .*num_envs, autoreset_mode, max_episode_steps"),
    ],
)
def test_bad_arguments_get_one_clear_line(kwargs, message):
    with pytest.raises(BuildingEnvError, match=message) as caught:
        gym.make_vec("BuildingWeek-v0", **{"num_envs": 2, **kwargs})
    assert "\n" not in str(caught.value)
    single = {k: v for k, v in kwargs.items() if k not in ("num_envs", "max_episode_steps", "autoreset_mode")}
    if single and "wheeks" not in single:
        with pytest.raises(BuildingEnvError, match=message):
            gym.make("BuildingWeek-v0", **single)


def test_vector_actions_of_another_shape_are_refused(native_and_sync):
    native = native_and_sync[0]
    native.reset(seed=0)
    with pytest.raises(
        BuildingEnvError, match=rf"takes an action of shape \(3, {N_ACTION}\).*got float64 \({N_ACTION},\)"
    ):
        native.step(np.zeros(N_ACTION))
