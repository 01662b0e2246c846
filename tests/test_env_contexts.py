"""BuildingWeek-v0 with many buildings as contexts: site lists, a library and its split, the native vector env
grouped by site, evaluate(site=), the sites a context set refuses, the library command."""

from __future__ import annotations

import copy
import json
import pickle
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from vector_info import same_info

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from buildenv import catalogue as cat
from buildenv.cli.main import main
from buildenv.env.building_week import DEFAULT_SITE, BuildingWeekEnv
from buildenv.errors import BuildenvError, BuildingEnvError
from buildenv.sites import load_site
from buildenv.sites.library import LIBRARY_FILES, LIBRARY_INDEX, SHIPPED_LIBRARY, common_limits, read_library
from buildenv.sites.suite import write_manifest

N_ACTION = 7 * 12  # the default site's BMS changes 12 of the 13 settings
NEWARK = "medium_office-usa_nj_newark-heating"
TRAIN = ("medium_office-usa_co_denver-cooling", "medium_office-usa_il_chicago-heating")


def _copy_default(folder: Path, weather: str | None = None, **theta: float) -> Path:
    """A copy of the shipped site in ``folder``, in another shipped ``weather`` if given, its calibrated theta_build
    changed by ``theta``."""
    shutil.copytree(DEFAULT_SITE, folder)
    if weather:
        toml = (folder / "site.toml").read_text(encoding="utf-8")
        (folder / "site.toml").write_text(toml.replace('weather = "usa_il_chicago"', f'weather = "{weather}"', 1))
    if theta:
        path = folder / "calibration.json"
        calibration = json.loads(path.read_text(encoding="utf-8"))
        calibration["theta"].update(theta)
        path.write_text(json.dumps(calibration), encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def two_sites(tmp_path_factory) -> list[str]:
    """Two calibrated sites that differ (the second has Miami's weather, leaks more air and has more plug loads)."""
    root = tmp_path_factory.mktemp("sites")
    leaky = _copy_default(root / "leaky", "usa_fl_miami", plug_load_w_m2=12.0, infiltration_ach=0.5)
    return [str(_copy_default(root / "chicago")), str(leaky)]


@pytest.fixture(scope="module")
def suite(tmp_path_factory) -> Path:
    """A fake calibrated suite: three calibrated copies of the default site (one in a held-out climate), one made
    but not calibrated and one refused."""
    out = tmp_path_factory.mktemp("suite")
    records = []
    for name, part, theta in (
        ("medium_office-usa_il_chicago-heating", "development", {}),
        ("medium_office-usa_co_denver-cooling", "development", {"plug_load_w_m2": 8.0}),
        (NEWARK, "held_out", {"infiltration_ach": 0.5}),
        ("small_office-usa_fl_miami-heating", "development", {}),
    ):
        building, climate, season = name.split("-")
        _copy_default(out / name, **theta)
        record = {"building": building, "climate": climate, "season": season, "part": part, "site": str(out / name)}
        records.append({**record, "status": "made"})
    (Path(records[-1]["site"]) / "calibration.json").unlink()  # made, not calibrated: left out of a library
    refused = {"building": "large_office", "climate": "usa_az_phoenix", "season": "cooling", "part": "held_out"}
    records.append({**refused, "site": str(out / "large_office-usa_az_phoenix-cooling"), "status": "refused"})
    write_manifest(out, records)
    return out


@pytest.fixture(scope="module")
def library(suite, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("library") / "library"
    assert main(["suite", "library", "--suite", str(suite), "--out", str(out), "--quiet"]) == 0
    return out


def test_two_sites_are_drawn_per_episode_reproducibly_under_a_seed(two_sites):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("BuildingWeek-v0", site=two_sites)
    base = env.unwrapped
    assert base.site_names == ("chicago", "leaky") and env.action_space.shape == (N_ACTION,)
    draws = [env.reset(seed=s) for s in range(12)]
    assert {info["site"] for _, info in draws} == {"chicago", "leaky"}  # both drawn, uniformly
    for s, (obs, info) in enumerate(draws):  # the site and the week under the seed
        again_obs, again = env.reset(seed=s)
        assert again == info and np.array_equal(again_obs, obs) and base.site_name == info["site"]
    _, info = env.reset(seed=0, options={"site": "leaky", "week": 10})
    assert (info["site"], info["week"]) == ("leaky", 10) and base.site.path.name == "leaky"
    _, reward, terminated, _, step_info = env.step(base.historical_action)
    assert step_info["site"] == "leaky" and terminated and np.isfinite(reward)
    assert step_info["energy_term"] == pytest.approx(1.0)  # the site's own historical settings
    actions = np.random.default_rng(0).uniform(-1, 1, (4, N_ACTION))
    chicago, leaky = (base.evaluate(actions, week=10, site=s)["energy_kwh"] for s in (0, "leaky"))
    assert not np.allclose(chicago, leaky, rtol=1e-3)  # two buildings, not one twice
    check_env(base, skip_render_check=True)
    sb3_check_env(base, warn=True)


def test_evaluate_scores_the_episode_site_or_the_one_named(two_sites):
    env = BuildingWeekEnv(site=two_sites)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, N_ACTION))
    with pytest.raises(BuildingEnvError, match="call reset\\(\\) or pass site="):
        env.evaluate(actions, week=5)
    env.reset(seed=0, options={"site": "chicago", "week": 5})
    current = env.evaluate(actions)["reward"]
    np.testing.assert_array_equal(env.evaluate(actions, site="chicago")["reward"], current)
    np.testing.assert_array_equal(env.evaluate(actions, week=5, site=0)["reward"], current)
    other = env.evaluate(actions, week=5, site="leaky")["reward"]
    alone = BuildingWeekEnv(site=two_sites[1]).evaluate(actions, week=5)["reward"]
    np.testing.assert_allclose(other, alone, rtol=1e-6)  # as the site on its own
    assert not np.allclose(other, current)
    with pytest.raises(BuildingEnvError, match="another site than the episode's; pass week="):
        env.evaluate(actions, site="leaky")
    with pytest.raises(BuildingEnvError, match="'nowhere' is not one of the environment's sites \\(chicago, leaky"):
        env.evaluate(actions, week=5, site="nowhere")


def test_native_and_sync_vector_envs_draw_the_same_sites_and_weeks(two_sites):
    kwargs = {"site": two_sites, "num_envs": 3, "episode_weeks": 2, "weeks": "all", "forecast_noise": 1.0}
    native = gym.make_vec("BuildingWeek-v0", **kwargs)
    sync = gym.make_vec("BuildingWeek-v0", vectorization_mode="sync", **kwargs)
    drawn = set()
    for seed in ([1, 2, 3], 11, 5, 7):
        obs, info = native.reset(seed=seed)
        expected_obs, expected = sync.reset(seed=seed)
        same_info(info, expected)
        np.testing.assert_allclose(obs, expected_obs, atol=1e-6)
        drawn |= set(info["site"])
    assert drawn == {"chicago", "leaky"}
    seed = next(s for s in range(50) if len(set(native.reset(seed=s)[1]["site"])) == 2)
    sync.reset(seed=seed)
    calls = []  # one metamodel call per site present in the batch, on its rows
    for i, context in enumerate(native.unwrapped._b.contexts):
        context.score = lambda a, *rest, i=i, f=context.score: calls.append((i, len(a))) or f(a, *rest)
    rng = np.random.default_rng(0)
    for _ in range(5):  # 2-week episodes: step, step (terminates), the reset step, ...
        sites = native.unwrapped._sites.copy()
        resetting = native.unwrapped._done.copy()
        calls.clear()
        actions = rng.uniform(-1, 1, native.action_space.shape).astype(np.float32)
        got, expected = native.step(actions), sync.step(actions)
        present = sorted(set(sites[~resetting].tolist()))
        assert [i for i, _ in calls] == present
        assert [k for _, k in calls] == [int((sites[~resetting] == i).sum()) for i in present]
        np.testing.assert_allclose(got[0], expected[0], atol=1e-6)
        np.testing.assert_allclose(got[1], expected[1], rtol=1e-5)
        np.testing.assert_array_equal(got[2], expected[2])
        np.testing.assert_array_equal(got[3], expected[3])
        same_info(got[4], expected[4])
    rows = native.unwrapped.historical_actions
    assert rows.shape == (3, N_ACTION)
    for row, site in zip(rows, native.unwrapped._sites):
        np.testing.assert_array_equal(row, BuildingWeekEnv(site=two_sites[site]).historical_action)
    with pytest.raises(BuildingEnvError, match="with several sites use historical_actions") as error:
        _ = native.unwrapped.historical_action
    assert "\n" not in str(error.value)
    with pytest.raises(BuildingEnvError, match="evaluate\\(\\) needs site="):
        native.unwrapped.evaluate(np.zeros(N_ACTION), week=3)
    assert native.unwrapped.evaluate(np.zeros((2, N_ACTION)), week=3, site="leaky")["reward"].shape == (2,)


def test_each_site_keeps_its_own_weather_and_prices(two_sites):
    """A context set's site observes, scores and prices as that site on its own (Miami is not Chicago)."""
    kwargs = {"weeks": "all", "price": "tou"}
    env = BuildingWeekEnv(site=two_sites, **kwargs)
    actions = np.random.default_rng(4).uniform(-1, 1, (3, N_ACTION))
    observed = {}
    for name, path in zip(("chicago", "leaky"), two_sites):
        alone = BuildingWeekEnv(site=path, **kwargs)
        obs, info = env.reset(seed=0, options={"site": name, "week": 26})
        np.testing.assert_array_equal(obs, alone.reset(seed=0, options={"week": 26})[0])
        assert info["week_start"] == alone.week_start(26).isoformat() and env.weeks == alone.weeks
        got, expected = env.evaluate(actions, week=26, site=name), alone.evaluate(actions, week=26)
        for key in ("reward", "cost", "cost_historical", "energy_kwh"):
            np.testing.assert_allclose(got[key], expected[key], rtol=1e-6, err_msg=key)
        observed[name] = obs
    mean_c = {name: obs[:42].reshape(7, 6)[:, 0].mean() * 20 for name, obs in observed.items()}  # daily means
    assert mean_c["leaky"] > mean_c["chicago"] + 2  # a Miami summer week is warmer than Chicago's


def test_single_site_vector_env_keeps_one_historical_action():
    native = gym.make_vec("BuildingWeek-v0", num_envs=2)
    single = native.unwrapped.historical_action
    assert single.shape == (N_ACTION,)
    np.testing.assert_array_equal(native.unwrapped.historical_actions, np.stack([single, single]))


def test_same_step_autoreset_with_two_sites_matches_sync(two_sites):
    kwargs = {"site": two_sites, "num_envs": 4, "weeks": [3, 4, 5]}
    native = gym.make_vec("BuildingWeek-v0", autoreset_mode=gym.vector.AutoresetMode.SAME_STEP, **kwargs)
    sync = gym.make_vec(
        "BuildingWeek-v0",
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": "SameStep"},
        **kwargs,
    )
    native.reset(seed=3)
    sync.reset(seed=3)
    for _ in range(2):
        actions = np.random.default_rng(2).uniform(-1, 1, native.action_space.shape)
        got, expected = native.step(actions), sync.step(actions)
        np.testing.assert_allclose(got[0], expected[0], atol=1e-6)
        same_info(got[4], expected[4])
        assert set(got[4]["final_info"]["site"]) <= {"chicago", "leaky"}


def _edited_default(folder: Path, *edits: tuple[str, str]) -> Path:
    """A copy of the default site whose site.toml has each ``(old, new)`` text replaced."""
    site = _copy_default(folder)
    toml = (site / "site.toml").read_text(encoding="utf-8")
    for old, new in edits:
        toml = toml.replace(old, new)
    (site / "site.toml").write_text(toml, encoding="utf-8")
    return site


def test_sites_with_different_action_spaces_are_refused_in_one_line(two_sites, tmp_path):
    fewer = _edited_default(
        tmp_path / "fewer", ('    "ventilation_ach",\n', ""), ("limits = { ventilation_ach = [0.45, 0.7] }\n", "")
    )
    with pytest.raises(BuildingEnvError) as error:
        BuildingWeekEnv(site=[two_sites[0], str(fewer)])
    message = str(error.value)
    assert "\n" not in message and "site 'fewer' gives another action space than site 'chicago'" in message
    assert "acts on 11 settings (77 actions)" in message and "lacks ventilation_ach" in message


def test_sites_with_different_action_ranges_are_refused_in_one_line(two_sites, tmp_path):
    narrow = _edited_default(tmp_path / "narrow", ("ventilation_ach = [0.45, 0.7]", "ventilation_ach = [0.45, 0.6]"))
    with pytest.raises(BuildingEnvError) as error:
        BuildingWeekEnv(site=[two_sites[0], str(narrow)])
    message = str(error.value)
    assert "\n" not in message and "site 'narrow' gives ventilation_ach the range [" in message
    assert ", 0.6] where site 'chicago' gives [" in message and ", 0.7]" in message


def test_a_site_calibrated_with_another_metamodel_is_refused_in_a_context_set(two_sites, tmp_path):
    other = _copy_default(tmp_path / "other")
    path = other / "calibration.json"
    calibration = json.loads(path.read_text(encoding="utf-8"))
    calibration["metamodel_id"] = "0123456789abcdef"
    path.write_text(json.dumps(calibration), encoding="utf-8")
    with pytest.raises(BuildingEnvError) as error:
        BuildingWeekEnv(site=[two_sites[0], str(other)])
    message = str(error.value)
    assert "\n" not in message and "site 'other' of the context set: calibration made with" in message
    assert BuildingWeekEnv(site=str(other)).site_name == "other"  # one site on its own: a warning only


def test_sites_of_the_same_folder_name_are_named_by_full_path(tmp_path):
    first, second = (_copy_default(tmp_path / part / "office") for part in ("a", "b"))
    for sites in ([str(first), str(second)], [load_site(first), load_site(second)]):
        env = BuildingWeekEnv(site=sites)
        assert env.site_names == (str(first.resolve()), str(second.resolve()))
    with pytest.raises(BuildingEnvError, match="lists .*office' twice"):
        BuildingWeekEnv(site=[load_site(first), load_site(first)])


def test_the_library_command_copies_calibrated_sites_and_their_split(library, suite, tmp_path, capsys):
    sites = read_library(library)
    assert [s.name for s in sites] == sorted([*TRAIN, NEWARK])  # the uncalibrated and the refused left out
    assert {s.name: s.part for s in sites} == {TRAIN[0]: "train", TRAIN[1]: "train", NEWARK: "test"}
    assert {(s.building, s.climate, s.season) for s in sites if s.part == "test"} == {
        ("medium_office", "usa_nj_newark", "heating")
    }
    for site in sites:
        assert sorted(p.name for p in site.folder.iterdir()) == sorted(LIBRARY_FILES)  # no calibration.png
    index = (library / LIBRARY_INDEX).read_text(encoding="utf-8")
    assert 'climate = "usa_nj_newark"' in index and "guideline14 = " in index
    made_with = json.loads((DEFAULT_SITE / "calibration.json").read_text(encoding="utf-8"))["metamodel_id"]
    assert f'metamodel_id = "{made_with}"' in index and {s.metamodel_id for s in sites} == {made_with}

    out = tmp_path / "two"
    capsys.readouterr()
    assert main(["suite", "library", "--suite", str(suite), "--out", str(out), "--sites", "2", "--quiet"]) == 0
    assert json.loads(capsys.readouterr().out) == {"library": str(out), "sites": 2, "train": 1, "test": 1}
    assert main(["suite", "library", "--suite", str(suite), "--out", str(out), "--sites", "1", "--quiet"]) == 0
    assert len(read_library(out)) == 1 and not (tmp_path / "two.partial").exists()  # an earlier library replaced
    one = tmp_path / "one"
    assert main(["suite", "library", "--suite", str(suite), "--out", str(one), "--buildings", "medium_office"]) == 0
    assert [s.name for s in read_library(one)] == [s.name for s in sites]
    assert main(["suite", "library", "--suite", str(suite), "--out", str(tmp_path / "x"), "--buildings", "shed"]) == 2
    assert "--buildings shed: no calibrated site of it" in capsys.readouterr().err and not (tmp_path / "x").exists()
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine", encoding="utf-8")
    assert main(["suite", "library", "--suite", str(suite), "--out", str(other), "--quiet"]) == 2
    assert "exists and is not a site library" in capsys.readouterr().err
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]


def test_a_library_of_offices_with_other_outdoor_air_ranges_shares_their_overlap(tmp_path):
    records = []
    for name, limits in (("medium_office-usa_il_chicago-heating", None), ("small_office-usa_fl_miami-heating", 0.55)):
        folder = _copy_default(tmp_path / "suite" / name)
        if limits is not None:  # a smaller design outdoor air: its BMS goes up to 0.55 1/h only
            toml = (folder / "site.toml").read_text(encoding="utf-8")
            (folder / "site.toml").write_text(toml.replace("[0.45, 0.7]", f"[0.45, {limits}]"), encoding="utf-8")
        building, climate, season = name.split("-")
        records.append(
            {"building": building, "climate": climate, "season": season, "part": "development", "site": str(folder)}
        )
        records[-1]["status"] = "made"
    write_manifest(tmp_path / "suite", records)
    suite, lib = str(tmp_path / "suite"), str(tmp_path / "lib")
    assert main(["suite", "library", "--suite", suite, "--out", lib, "--quiet"]) == 0
    for site in read_library(lib):
        assert load_site(site.folder).setting_limits == {"ventilation_ach": (0.45, 0.55)}
    env = gym.make("BuildingWeek-v0", site=lib)
    vent = list(env.unwrapped.decode(np.ones(N_ACTION))[:, cat.SETTING_NAMES.index("ventilation_ach")])
    assert vent == pytest.approx([0.55] * 7)
    with pytest.raises(BuildenvError, match="ventilation_ach: site 'b' limits it to \\[0.8, 1\\] and site 'a'"):
        common_limits({"a": {"ventilation_ach": (0.45, 0.7)}, "b": {"ventilation_ach": (0.8, 1.0)}})


def test_a_library_split_runs_only_its_part(library):
    test = gym.make("BuildingWeek-v0", site=str(library), sites="test")
    assert test.unwrapped.site_names == (NEWARK,)
    assert {test.reset(seed=s)[1]["site"] for s in range(5)} == {NEWARK}
    train = BuildingWeekEnv(site=library, sites="train")
    assert train.site_names == TRAIN
    assert {train.reset(seed=s)[1]["site"] for s in range(10)} == set(TRAIN)
    chosen = BuildingWeekEnv(site=library, sites=[NEWARK, TRAIN[0]])
    assert chosen.site_names == (NEWARK, TRAIN[0])


def test_the_shipped_library_trains_on_the_development_climates_and_tests_on_the_held_out_ones():
    from gymnasium.utils.env_checker import check_env

    from buildenv.sites.suite import HELD_OUT_CLIMATES

    sites = read_library(SHIPPED_LIBRARY)
    assert {s.building for s in sites} == {"small_office", "medium_office", "large_office"}  # one action space
    assert {s.part for s in sites if s.climate in HELD_OUT_CLIMATES} == {"test"}
    assert {s.part for s in sites if s.climate not in HELD_OUT_CLIMATES} == {"train"}
    assert {s.season for s in sites} == {"heating", "cooling"}
    test = gym.make("BuildingWeek-v0", site="library", sites="test")  # made with the default metamodel
    assert set(test.unwrapped.site_names) == {s.name for s in sites if s.part == "test"}
    check_env(test.unwrapped, skip_render_check=True)
    # its training sites drawn under a seed: the same sites, weeks and observations again, native as sync
    kwargs = {"site": "library", "sites": "train", "num_envs": 2}
    native = gym.make_vec("BuildingWeek-v0", **kwargs)
    sync = gym.make_vec("BuildingWeek-v0", vectorization_mode="sync", **kwargs)
    drawn = set()
    for seed in (0, 1, 2, 3):
        obs, info = native.reset(seed=seed)
        again_obs, again = native.reset(seed=seed)
        expected_obs, expected = sync.reset(seed=seed)
        same_info(info, again)
        same_info(info, expected)
        np.testing.assert_array_equal(obs, again_obs)
        np.testing.assert_allclose(obs, expected_obs, atol=1e-6)
        drawn |= {(site, int(week)) for site, week in zip(info["site"], info["week"])}
    assert len({site for site, _ in drawn}) > 2 and {site for site, _ in drawn} <= {s.name for s in sites}


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"site": ["default", "x"], "sites": "train"}, "a list of sites has no train/test split.*give sites= the list"),
        ({"sites": "test"}, "sites='test' chooses among several sites, but site= is one"),
        ({"site": ["default", "default"]}, "site= lists 'default' twice"),
        ({"site": []}, "site=\\[\\]; give at least one site"),
        ({"site": ["default"], "sites": "some"}, "sites='some'; choose one of train, test, all or a list"),
        ({"weeks": [99]}, "^BuildingWeek-v0: weeks=\\[99\\] on site 'default': give week indices in 0\\.\\.5"),
        ({"weeks": "summer"}, "^BuildingWeek-v0: weeks='summer' on site 'default': choose one of train, test, all"),
    ],
)
def test_bad_site_sets_get_one_clear_line(kwargs, message):
    with pytest.raises(BuildingEnvError, match=message) as error:
        BuildingWeekEnv(**kwargs)
    assert "\n" not in str(error.value)


def test_unknown_library_sites_are_refused(library):
    with pytest.raises(BuildingEnvError, match="unknown site\\(s\\) 'nowhere'; the sites are medium_office"):
        BuildingWeekEnv(site=library, sites=["nowhere"])


def test_pickle_and_deepcopy_keep_one_shared_metamodel(two_sites):
    env = gym.make("BuildingWeek-v0", site=two_sites, episode_weeks=2, weeks="all")
    contexts = env.unwrapped._b.contexts
    assert contexts[0].model.surrogate is contexts[1].model.surrogate  # loaded once
    env.reset(seed=4)
    env.step(env.unwrapped.historical_action)
    actions = np.random.default_rng(1).uniform(-1, 1, (3, N_ACTION)).astype(np.float32)
    expected = env.unwrapped.evaluate(actions)["reward"]
    for twin in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        twins = twin.unwrapped._b.contexts
        assert twins[0].model.surrogate is twins[1].model.surrogate is twin.unwrapped._b.surrogate
        assert twin.unwrapped.site_name == env.unwrapped.site_name
        np.testing.assert_array_equal(twin.unwrapped.evaluate(actions)["reward"], expected)
        _, reward, terminated, _, _ = twin.step(actions[0])
        assert terminated and reward == pytest.approx(expected[0], rel=1e-6)
    native = gym.make_vec("BuildingWeek-v0", site=two_sites, num_envs=2)
    native.reset(seed=5)
    twin = pickle.loads(pickle.dumps(native))
    step = np.random.default_rng(2).uniform(-1, 1, (2, N_ACTION))
    np.testing.assert_array_equal(twin.step(step)[1], native.step(step)[1])


def test_render_names_the_site(two_sites):
    env = gym.make("BuildingWeek-v0", site=two_sites, render_mode="ansi")
    env.reset(seed=0, options={"site": "leaky", "week": 43})
    assert "site leaky, week 43, 2019-11-04 to 2019-11-10" in env.render()
    env.step(env.unwrapped.historical_action)
    assert "site leaky, week 43" in env.render()
    native = gym.make_vec("BuildingWeek-v0", site=two_sites, num_envs=2, render_mode="ansi")
    _, info = native.reset(seed=1)
    frames = native.render()
    assert all(f"site {name}, week {week}," in frame for frame, name, week in zip(frames, info["site"], info["week"]))


def test_weather_years_are_contexts_scored_under_their_own_weather():
    env = BuildingWeekEnv(weather_years=3)
    assert env.site_names == ("default", "default:year1", "default:year2")
    drawn = {env.reset(seed=seed)[1]["site"] for seed in range(16)}
    assert drawn == set(env.site_names)
    plain = BuildingWeekEnv()
    action = plain.historical_action[None]
    same = env.evaluate(action, week=46, site="default")
    np.testing.assert_allclose(same["reward"], plain.evaluate(action, week=46)["reward"], rtol=1e-6)
    other = env.evaluate(action, week=46, site="default:year1")
    assert other["energy_historical_kwh"][0] != pytest.approx(same["energy_historical_kwh"][0], rel=1e-3)
    assert other["energy_term"][0] == pytest.approx(1.0, abs=1e-5)  # the historical settings under that year's weather
    obs_plain, _ = env.reset(options={"site": "default", "week": 40})
    obs_year, _ = env.reset(options={"site": "default:year1", "week": 40})
    assert not np.allclose(obs_plain, obs_year)  # the forecast is the year's


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"weather_years": 0}, "weather_years=0; give a whole number, 1 or more"),
        ({"weather_years": [2, 2]}, "weather_years=\\[2, 2\\]; give distinct year numbers"),
        ({"weather_years": 2, "backend": "energyplus"}, "runs the site's own weather file; give weather_years=1"),
    ],
)
def test_bad_weather_years_get_one_clear_line(kwargs, message):
    with pytest.raises(BuildingEnvError, match=message) as error:
        BuildingWeekEnv(**kwargs)
    assert "\n" not in str(error.value)


def test_weather_years_of_one_site_share_its_historical_action_and_are_not_verified_on_energyplus():
    from agents.verify import verify

    vector = gym.make_vec("BuildingWeek-v0", num_envs=2, weather_years=2)
    np.testing.assert_array_equal(vector.unwrapped.historical_action, BuildingWeekEnv().historical_action)
    env = gym.make("BuildingWeek-v0", weather_years=2)
    env.reset(seed=0)
    with pytest.raises(BuildingEnvError, match="^verify: the EnergyPlus model runs the site's own weather file"):
        verify(env, 10, env.unwrapped.historical_action)
