"""Optimisers over BuildingWeek-v0: NSGA-II, CMA-ES, the rule-based schedule, the CLI and the report."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import buildenv  # noqa: F401
from agents.cmaes import optimise_week
from agents.nsga2 import equal_comfort_choice, hypervolume, pareto_front
from agents.report import markdown_table
from agents.rules import rule_based_action, rule_based_settings
from buildenv import catalogue as cat

# the default site's BMS changes 12 of the 13 settings (not the supply air), each day of the week
N_ACTION = 7 * 12

WEEK = 46


@pytest.fixture(scope="module")
def env():
    return gym.make("BuildingWeek-v0", weeks="all")


def test_nsga2_front_is_non_dominated_and_beats_historical(env):
    front = pareto_front(env, WEEK, population=24, generations=6, seed=0)
    assert front.evaluations == 24 * 6 and front.hypervolume > 0
    f = np.column_stack([front.energy_term, front.comfort_k])
    for i in range(len(f)):  # no point dominates another
        assert not ((f <= f[i]).all(axis=1) & (f < f[i]).any(axis=1)).any()
    assert front.history == sorted(front.history)  # the front only improves
    hist = env.unwrapped.evaluate(env.unwrapped.historical_action[None], week=WEEK)
    i = equal_comfort_choice(front, float(hist["comfort_k"][0]))
    # the historical point is in the first population (evaluated there in a batch: float32 rounding apart)
    assert front.comfort_k[i] <= hist["comfort_k"][0] + 1e-6
    assert front.energy_term[i] <= 1.0 + 1e-6


def test_hypervolume_of_the_reference_corner_is_zero():
    assert hypervolume(np.array([1.5]), np.array([3.0])) == 0.0
    assert hypervolume(np.array([0.5]), np.array([1.0])) == pytest.approx(1.0 * 2.0)


def test_cmaes_improves_on_the_historical_reward(env):
    result = optimise_week(env, WEEK, evaluations=300, population=32, seed=0)
    hist = env.unwrapped.evaluate(env.unwrapped.historical_action[None], week=WEEK)["reward"][0]
    assert result.scores["reward"] >= hist
    assert result.evaluations <= 300 + 32 and result.history == sorted(result.history)


def test_rule_based_schedule_follows_occupancy(env):
    occupancy = np.array([[8, 18]] * 5, dtype=float)
    s = rule_based_settings(occupancy)
    cat.check_values("settings", s)
    col = cat.SETTING_NAMES.index
    assert (s[:5, col("heating_start_hour")] == 7).all() and (s[:5, col("ventilation_end_hour")] == 18).all()
    assert (s[:, col("heating_setback_c")] == 17).all()
    assert (s[:5, col("hvac_operating")] == 1).all() and (s[5:, col("hvac_operating")] == 0).all()  # weekends off
    action = rule_based_action(env)
    assert action.shape == (N_ACTION,) and np.abs(action).max() <= 1.0


def test_optimize_command_prints_json(capsys):
    from buildenv.cli.main import main

    assert main(["optimize", "--method", "rules", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "rules" and out["week"] == WEEK  # the default site's first held-out week
    assert set(out["settings"]) == set(cat.DAYS)
    assert {"predicted_savings_percent", "comfort_historical_predicted", "comfort_chosen_predicted"} <= set(out)


def test_the_optimisers_run_on_the_library_site_they_are_given(capsys):
    from agents.cli import default_week, optimise
    from buildenv.cli.main import main
    from buildenv.errors import BuildingEnvError
    from buildenv.sites.library import SHIPPED_LIBRARY, read_library

    sites = read_library(SHIPPED_LIBRARY)
    names = [s.name for s in sites]
    env = gym.make("BuildingWeek-v0", site="library", weeks="all")
    with pytest.raises(BuildingEnvError, match="give site="):
        optimise(env, "rules", 0)  # several sites and no episode: which one is not guessed
    single = gym.make("BuildingWeek-v0", site=str(sites[-1].folder), weeks="all")
    week = default_week(single)
    result = optimise(env, "rules", week, site=names[-1])
    assert result["site"] == names[-1] == env.unwrapped.site_name
    alone = optimise(single, "rules", week)
    assert alone["predicted_savings_percent"] == pytest.approx(result["predicted_savings_percent"], abs=1e-4)

    assert main(["optimize", "--method", "rules", "--site", "library", "--library-site", names[0], "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["site"] == names[0]
    assert main(["optimize", "--method", "rules", "--site", "library"]) == 2
    assert "choose one with --library-site NAME" in capsys.readouterr().err
    assert main(["optimize", "--method", "rules", "--library-site", names[0]]) == 2
    assert "is one site, not a library" in capsys.readouterr().err
    assert main(["optimize", "--method", "rules", "--site", "library", "--library-site", "shed"]) != 0
    assert "'shed' is not one of the environment's sites" in capsys.readouterr().err


def test_markdown_table_prints_missing_values_as_dash():
    table = markdown_table([{"a": 1.234, "b": None}], [("A", "a", ".1f"), ("B", "b", "d")])
    assert "| 1.2 | - |" in table
