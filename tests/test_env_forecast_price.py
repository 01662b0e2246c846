"""BuildingWeek-v0's forecast noise (``forecast_noise=``) and time-of-use price (``price=``): the tariff prices the
energy bought (cooling over a COP, heating over an efficiency) on the week's dates, daylight saving included."""

from __future__ import annotations

import copy
import datetime as dt
import pickle

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from buildenv import catalogue as cat
from buildenv.env import tariff as tar
from buildenv.env.observations import forecast
from buildenv.errors import BuildingEnvError

N_ACTION = 7 * 12  # the default site's 12 controllable settings, each day
BOTH = {"forecast_noise": 2.0, "price": "tou"}


@pytest.fixture(scope="module")
def plain():
    return gym.make("BuildingWeek-v0", observation="forecast", episode_weeks=2, weeks="all")


@pytest.fixture(scope="module")
def noisy():
    return gym.make("BuildingWeek-v0", observation="forecast", episode_weeks=2, weeks="all", forecast_noise=2.0)


# ---------------------------------------------------------------------------------------------------- forecast noise
def test_zero_noise_is_todays_observation_exactly(plain):
    zero = gym.make("BuildingWeek-v0", observation="forecast", episode_weeks=2, weeks="all", forecast_noise=0.0)
    action = plain.unwrapped.historical_action
    np.testing.assert_array_equal(zero.reset(seed=5)[0], plain.reset(seed=5)[0])
    np.testing.assert_array_equal(zero.step(action)[0], plain.step(action)[0])
    # and the generator is left alone: the next unseeded reset draws the same week
    assert zero.reset()[1]["week"] == plain.reset()[1]["week"]


def test_noise_changes_the_observation_not_the_reward(plain, noisy):
    rng = np.random.default_rng(0)
    action = rng.uniform(-1, 1, N_ACTION).astype(np.float32)
    obs, info = noisy.reset(seed=3)
    true_obs, true_info = plain.reset(seed=3)
    assert info["week"] == true_info["week"]  # the week is drawn before the forecast
    differs = obs != true_obs
    daily = differs[:42].reshape(7, 6)  # mean/min/max temperature, irradiance, wind, humidity per day
    assert daily[:, [0, 1, 2, 5]].all() and differs[-168 * 8 :].any()  # the summary and the hourly part
    assert not differs[42:76].any()  # occupancy, calendar and building are known exactly
    got, expected = noisy.step(action), plain.step(action)
    assert got[1] == expected[1] and got[4]["energy_term"] == expected[4]["energy_term"]  # scored on the truth
    assert not np.array_equal(got[0], expected[0])  # the next week's forecast is noisy too


def test_same_seed_same_noise_other_seed_other_noise(noisy):
    first = noisy.reset(seed=8, options={"week": 20})[0]
    np.testing.assert_array_equal(noisy.reset(seed=8, options={"week": 20})[0], first)
    assert not np.array_equal(noisy.reset(seed=9, options={"week": 20})[0], first)
    twin = gym.make("BuildingWeek-v0", observation="forecast", episode_weeks=2, weeks="all", forecast_noise=2.0)
    np.testing.assert_array_equal(twin.reset(seed=8, options={"week": 20})[0], first)


def test_noise_model_grows_with_lead_time_and_stays_physical(plain):
    """Errors' standard deviation sd * sqrt((d + 1) / 7) at the end of day d; irradiance and wind >= 0 (night
    stays dark), humidity in [0, 100]."""
    truth = np.asarray(plain.unwrapped.site_model.weather(np.array([26])), float)  # a summer week
    n, sd = 4000, 2.0
    weeks = np.broadcast_to(truth, (n, *truth.shape[1:]))
    noisy = forecast(weeks, sd, [np.random.default_rng(s) for s in range(n)])
    assert np.array_equal(forecast(truth, 0.0, []), truth)
    col = cat.WEATHER_NAMES.index
    error = noisy[..., col("TAMB")] - truth[..., col("TAMB")]
    day_ends = np.arange(7) * 24 + 23
    np.testing.assert_allclose(error[:, day_ends].std(0), sd * np.sqrt(np.arange(1, 8) / 7), rtol=0.06)
    assert abs(error.mean()) < 0.1
    for name in ("IGLOB_H", "DNI", "IDIFF_H", "WIND_SPEED"):
        assert (noisy[..., col(name)] >= 0).all()
    dark = truth[0, :, col("IGLOB_H")] == 0
    assert dark.any() and (noisy[:, dark, col("IGLOB_H")] == 0).all()
    assert (noisy[..., col("RHUM")] >= 0).all() and (noisy[..., col("RHUM")] <= 100).all()
    np.testing.assert_array_equal(noisy[..., col("WIND_DIR")], weeks[..., col("WIND_DIR")])
    # the same factor on every irradiance channel: global = beam + diffuse still holds
    np.testing.assert_allclose(
        noisy[..., col("IGLOB_H")] * truth[..., col("IDIFF_H")], noisy[..., col("IDIFF_H")] * truth[..., col("IGLOB_H")]
    )


@pytest.mark.parametrize("mode", [gym.vector.AutoresetMode.NEXT_STEP, gym.vector.AutoresetMode.SAME_STEP])
def test_native_and_sync_vector_envs_draw_the_same_noise_and_costs(mode):
    kwargs = {"num_envs": 3, "episode_weeks": 2, "weeks": "all", "observation": "forecast", **BOTH}
    native = gym.make_vec("BuildingWeek-v0", autoreset_mode=mode, **kwargs)
    sync = gym.make_vec("BuildingWeek-v0", vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **kwargs)
    for seed in ([4, 5, 6], 11):
        obs, info = native.reset(seed=seed)
        expected, expected_info = sync.reset(seed=seed)
        np.testing.assert_array_equal(obs, expected)
        np.testing.assert_array_equal(info["week"], expected_info["week"])
    rng = np.random.default_rng(0)
    for _ in range(5):  # 2-week episodes: the next week's forecast, the end, the autoreset
        actions = rng.uniform(-1, 1, native.action_space.shape).astype(np.float32)
        got, want = native.step(actions), sync.step(actions)
        np.testing.assert_allclose(got[0], want[0], atol=1e-6)
        np.testing.assert_allclose(got[1], want[1], rtol=1e-5)
        for info, other in ((got[4], want[4]), (got[4].get("final_info", {}), want[4].get("final_info", {}))):
            assert sorted(info) == sorted(other)
            if "cost" in other:
                np.testing.assert_array_equal(info["_cost"], other["_cost"])
                np.testing.assert_allclose(info["cost"], other["cost"], rtol=1e-5)
                np.testing.assert_allclose(info["cost_historical"], other["cost_historical"], rtol=1e-5)
        if mode == gym.vector.AutoresetMode.SAME_STEP and "final_obs" in want[4]:
            for a, b in zip(got[4]["final_obs"], want[4]["final_obs"]):
                assert (a is None and b is None) or np.allclose(a, b, atol=1e-6)


# ---------------------------------------------------------------------------------------------------- price
@pytest.fixture(scope="module")
def priced():
    return gym.make("BuildingWeek-v0", price="tou", weeks="all")


def test_historical_settings_cost_one_and_info_reports_costs(priced, plain):
    priced.reset(seed=0, options={"week": 43})  # 2019-11-04, a Monday
    _, reward, _, _, info = priced.step(priced.unwrapped.historical_action)
    assert info["energy_term"] == pytest.approx(1.0) and info["cost"] == pytest.approx(info["cost_historical"])
    assert info["cost"] > 0 and reward == pytest.approx(-(1.0 + info["comfort_k"]))
    assert "cost" not in plain.unwrapped.evaluate(plain.unwrapped.historical_action[None], week=43)


def _delivered(base, scores: dict, week: int) -> tuple[np.ndarray, np.ndarray]:
    """Hourly cooling and heating delivered (Wh/m2) ``(N, 168)`` each of scored settings in ``week``."""
    out = base.site_model.simulate(scores["settings"], np.full(len(scores["settings"]), week))
    cooling, heating = (
        np.maximum(out[..., [cat.OUTPUT_NAMES.index(n) for n in names]], 0).sum(-1)
        for names in (("Q_AC_OFFICE", "Q_AHU_C"), ("Q_HEAT_OFFICE", "Q_AHU_H"))
    )
    np.testing.assert_allclose(cooling + heating, scores["hvac_wh_m2"], rtol=1e-6, atol=1e-9)
    return cooling, heating


def test_cost_is_the_energy_bought_at_the_weeks_prices(priced):
    """Cost = sum over hours of price x (cooling delivered / 3.0 + heating delivered / 1.0) x floor area."""
    base = priced.unwrapped
    actions = np.random.default_rng(1).uniform(-1, 1, (4, N_ACTION)).astype(np.float32)
    week = 40  # 2019-10-07: heating and cooling both
    scores = base.evaluate(actions, week=week)
    cooling, heating = _delivered(base, scores, week)
    assert (cooling.sum(-1) > 1).all() and (heating.sum(-1) > 1).all()
    day = np.where((np.arange(24) >= 8) & (np.arange(24) < 20), 0.25, 0.10)
    prices = np.concatenate([day] * 5 + [np.full(24, 0.10)] * 2)  # peak 08-20 Monday to Friday
    area = base.site_model.floor_area_m2
    bought = cooling / 3.0 + heating / 1.0
    np.testing.assert_allclose(scores["cost"], (bought * prices).sum(-1) * area / 1000, rtol=1e-6)
    np.testing.assert_allclose(scores["energy_term"], scores["cost"] / scores["cost_historical"], rtol=1e-9)
    gas = gym.make("BuildingWeek-v0", price={**tar.PRESETS["tou"], "cooling_cop": 4.0, "heating_efficiency": 0.9})
    bought = cooling / 4.0 + heating / 0.9
    np.testing.assert_allclose(
        gas.unwrapped.evaluate(actions, week=week)["cost"], (bought * prices).sum(-1) * area / 1000, rtol=1e-6
    )
    assert base.week_start(43) == dt.date(2019, 11, 4)
    for day in ("2019-11-04", dt.date(2019, 11, 4), dt.datetime(2019, 11, 4, 9), pd.Timestamp("2019-11-04")):
        holiday = tar.tariff_from({"peak": 0.25, "offpeak": 0.10, "holidays": [day]})
        assert holiday.holidays == (dt.date(2019, 11, 4),)
        assert (holiday.hourly(dt.date(2019, 11, 4))[:24] == 0.10).all()
        assert (holiday.hourly(dt.date(2019, 11, 4))[24 + 8 : 24 + 20] == 0.25).all()


def test_peak_hours_follow_the_local_clock_with_a_time_zone():
    july, january = dt.date(2019, 7, 8), dt.date(2019, 1, 7)  # Mondays; Chicago is on daylight saving in July
    standard = tar.tariff_from("tou")
    local = tar.tariff_from({**tar.PRESETS["tou"], "time_zone": "America/Chicago"})

    def peak(prices: np.ndarray) -> list[int]:  # Monday's peak hours
        return np.flatnonzero(prices[:24] == 0.25).tolist()

    assert peak(standard.hourly(july)) == list(range(8, 20))
    assert peak(local.hourly(july)) == list(range(7, 19))  # 08-20 daylight time is 07-19 standard time
    assert (local.hourly(july)[5 * 24 :] == 0.10).all()  # the weekend stays off-peak
    np.testing.assert_array_equal(local.hourly(january), standard.hourly(january))
    priced = gym.make("BuildingWeek-v0", weeks="all", price={**tar.PRESETS["tou"], "time_zone": "America/Chicago"})
    base = priced.unwrapped
    week = next(k for k in base.weeks if base.week_start(k) == july)
    actions = np.zeros((1, N_ACTION), np.float32)
    scores = base.evaluate(actions, week=week)
    cooling, heating = _delivered(base, scores, week)
    bought = cooling / 3.0 + heating
    area = base.site_model.floor_area_m2
    expected = (bought * local.hourly(july)).sum(-1) * area / 1000
    np.testing.assert_allclose(scores["cost"], expected, rtol=1e-6)


def test_a_tariff_made_directly_is_checked_and_normalised():
    tariff = tar.Tariff(0.2, 0.1, peak_days="weekends", holidays=[pd.Timestamp("2019-12-25 00:00")])
    assert tariff.peak_days == (5, 6) and tariff.holidays == (dt.date(2019, 12, 25),)
    assert tar.tariff_from(tariff) is tariff
    for kwargs, message in (
        ({"peak": -0.2, "offpeak": 0.1}, "Tariff: peak=-0.2; give a positive price"),
        ({"peak": 0.2, "offpeak": 0.1, "peak_hours": (20, 8)}, "0 <= start < end <= 24"),
        ({"peak": 0.2, "offpeak": 0.1, "cooling_cop": 0}, "Tariff: cooling_cop=0; give a number > 0"),
        ({"peak": 0.2, "offpeak": 0.1, "time_zone": "Chicago"}, "time_zone='Chicago' is no IANA time zone"),
    ):
        with pytest.raises(BuildingEnvError, match=message) as caught:
            tar.Tariff(**kwargs)
        assert "\n" not in str(caught.value)


def test_a_flat_price_on_delivered_energy_is_relative_energy(plain):
    flat = gym.make(
        "BuildingWeek-v0",
        observation="forecast",
        weeks="all",
        price=tar.Tariff(0.15, 0.15, peak_hours=(0, 24), peak_days="all", cooling_cop=1.0),
    )
    actions = np.random.default_rng(2).uniform(-1, 1, (4, N_ACTION)).astype(np.float32)
    np.testing.assert_allclose(
        flat.unwrapped.evaluate(actions, week=30)["energy_term"],
        plain.unwrapped.evaluate(actions, week=30)["energy_term"],
        rtol=1e-6,  # float32 metamodel outputs summed in another order
    )


def test_peak_heavy_settings_cost_relatively_more_than_off_peak_heavy(priced):
    actions = np.random.default_rng(3).uniform(-1, 1, (32, N_ACTION)).astype(np.float32)
    cost = priced.unwrapped.evaluate(actions, week=43)
    cooling, heating = _delivered(priced.unwrapped, cost, 43)
    bought = cooling / 3.0 + heating
    prices = tar.tariff_from("tou").hourly(dt.date(2019, 11, 4))
    share = (bought * (prices == 0.25)).sum(-1) / bought.sum(-1)  # energy bought in peak hours
    relative = cost["cost"] / bought.sum(-1)  # cost per energy bought
    heavy, light = np.argmax(share), np.argmin(share)
    assert share[heavy] > share[light] + 0.02
    assert relative[heavy] > relative[light]
    order = np.argsort(share)  # the cost per kWh rises with the peak share, exactly
    assert np.all(np.diff(relative[order]) > 0)


def test_mo_env_energy_objective_becomes_cost():
    mo = gym.make("mo-BuildingWeek-v0", price="tou", weeks="all")
    mo.reset(seed=0, options={"week": 43})
    reward, info = mo.step(np.zeros(N_ACTION, np.float32))[1::3]
    assert reward[0] == pytest.approx(-info["cost"] / info["cost_historical"], rel=1e-6)
    assert reward[1] == pytest.approx(-info["comfort_k"], rel=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"price": {"peak": -0.25, "offpeak": 0.1}}, "peak=-0.25; give a positive price, currency per kWh"),
        ({"price": {"peak": 0.25, "offpeak": 0}}, "offpeak=0; give a positive price"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "peak_hours": (8, 25)}}, r"peak_hours=\(8, 25\); give \(start"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "peak_hours": (20, 8)}}, "0 <= start < end <= 24"),
        ({"price": "tuo"}, "price='tuo' is no preset; choose one of tou, flat"),
        ({"price": {"peak": 0.2}}, "price has missing offpeak"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "peek_hours": (8, 20)}}, "unknown key.*peek_hours"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "peak_days": "weekend"}}, "peak_days='weekend'; give"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "holidays": "2019-12-25"}}, "holidays='2019-12-25'; give a list"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "cooling_cop": 0}}, "cooling_cop=0; give a number > 0"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "heating_efficiency": -0.9}}, "heating_efficiency=-0.9; give a"),
        ({"price": {"peak": 0.2, "offpeak": 0.1, "time_zone": "Mars/Olympus"}}, "time_zone='Mars/Olympus' is no"),
        ({"price": 0.2}, "price=0.2; give None, a preset"),
        ({"forecast_noise": -1.0}, "forecast_noise=-1.0; give a finite number >= 0"),
        ({"forecast_noise": "high"}, "forecast_noise='high'; give a finite number >= 0"),
    ],
)
def test_bad_arguments_get_one_line(kwargs, message):
    for make in (gym.make, lambda i, **k: gym.make_vec(i, num_envs=2, **k)):
        with pytest.raises(BuildingEnvError, match=message) as caught:
            make("BuildingWeek-v0", **kwargs)
        assert "\n" not in str(caught.value) and str(caught.value).startswith("BuildingWeek-v0: ")


# ---------------------------------------------------------------------------------------------------- both, tooling
def test_checkers_pass_with_both_options():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("BuildingWeek-v0", observation="forecast", **BOTH)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    mo = gym.make("mo-BuildingWeek-v0", **BOTH)
    with pytest.warns(UserWarning, match="must be a float"):  # the vector reward, the point of the MO env
        check_env(mo.unwrapped, skip_render_check=True)
    assert env.unwrapped.arguments["price"] == "tou" and env.unwrapped.arguments["forecast_noise"] == 2.0


def test_pickle_mid_episode_keeps_the_noise_generator_and_the_tariff():
    env = gym.make("BuildingWeek-v0", episode_weeks=3, weeks="all", **BOTH)
    env.reset(seed=4)
    env.step(env.unwrapped.historical_action)
    action = np.random.default_rng(5).uniform(-1, 1, N_ACTION).astype(np.float32)
    twins = (pickle.loads(pickle.dumps(env)), copy.deepcopy(env))
    expected = env.step(action)  # the next week's noisy forecast, drawn from the pickled generator's state
    assert expected[4]["cost"] > 0
    for twin in twins:
        got = twin.step(action)
        np.testing.assert_array_equal(got[0], expected[0])
        assert got[1] == pytest.approx(expected[1], rel=1e-6) and got[4]["cost"] == pytest.approx(expected[4]["cost"])
