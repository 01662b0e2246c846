"""A metamodel of the earlier catalogue under this one: same predictions, its own ranges, fine-tuned onto this one."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv import defaults
from buildenv.calibration import problem as cal
from buildenv.env import actions as act
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.training import _onto_catalogue
from buildenv.weather.epw import load_weather


@pytest.fixture(scope="module")
def shipped():
    return sg.load_metamodel("diagnosis")  # the earlier default, of the earlier catalogue


def _week(context: int):
    weather = np.asarray(load_weather("usa_il_chicago").hourly)[2 * 168 : 3 * 168][None]
    ground = sg.weather_ground_c("usa_il_chicago")[2 * 168 - context : 3 * 168][None]
    settings, occupancy = defaults.default_week()
    before = np.full((1, context), 20.0, np.float32)
    return sg.encode_weeks(
        defaults.default_theta()[None], settings, occupancy, weather, None, None, context, ground, before
    )


def test_renamed_channels_are_converted_and_unread_ones_dropped(shipped):
    assert shipped.earlier is not None
    index, scale = shipped.channel_map()
    channels = shipped.checkpoint.metadata["input_channels"]
    j = channels.index("pc_density_per_m2")
    assert sg.ALL_CHANNELS[index[j]] == "plug_load_w_m2" and scale[j] == pytest.approx(1 / 150)
    x = _week(shipped.context_hours)
    read = shipped.model_inputs(x)
    assert read.shape[-1] == len(channels)
    plug = x[0, 0, sg.ALL_CHANNELS.index("plug_load_w_m2")]
    assert read[0, 0, j] == pytest.approx(plug / 150)


def test_a_warning_when_a_building_sets_what_the_metamodel_does_not_read(shipped, caplog):
    model = sg.Surrogate(shipped.checkpoint, shipped.path)
    theta = defaults.default_theta()[None].copy()
    model.check_implied(theta)
    assert not caplog.records
    theta[0, cat.THETA_NAMES.index("lighting_power_w_m2")] = 6.0
    model.check_implied(theta)
    assert "lighting_power_w_m2" in caplog.text


def test_calibration_and_actions_stay_inside_what_the_metamodel_learnt(shipped):
    ranges = cal.parameter_ranges({}, shipped)
    assert ranges["lighting_power_w_m2"] == (10.0, 10.0) and ranges["heat_recovery_effectiveness"] == (0.0, 0.0)
    assert ranges["plug_load_w_m2"] == (5.25, 10.5) and ranges["capacitance_kj_per_k_m3"] == (50.0, 300.0)
    assert cal.parameter_ranges({}, None)["capacitance_kj_per_k_m3"] == (20.0, 300.0)  # the catalogue's
    lo, hi = act.bounds(shipped.domain)
    j = cat.SETTING_NAMES.index("ventilation_ach")
    assert (lo[j], hi[j]) == (0.7, 1.7)
    settings, _ = act.decode(-np.ones(act.ACTION_SIZE), (lo, hi))
    assert settings[0, j] == 0.7


def test_fine_tuning_onto_this_catalogue_starts_from_the_same_predictions(shipped):
    x = _week(shipped.context_hours)
    ck = shipped.checkpoint
    wanted = sg.input_channels(True, True)
    noisy = np.repeat(x, 4, 0) + np.random.default_rng(0).normal(size=(4, *x.shape[1:])).astype(np.float32)
    moved = _onto_catalogue(ck, shipped.earlier, tuple(ck.metadata["input_channels"]), wanted, noisy)
    moved.metadata = {**ck.metadata, **sg.metadata(shipped.context_hours, True, True)}
    assert moved.inputs == len(wanted)
    np.testing.assert_allclose(sg.Surrogate(moved).predict_encoded(x), shipped.predict_encoded(x), atol=1e-4)


class _Limited:
    """A site whose outdoor air is limited below what the shipped metamodel learnt (0.7-1.7 1/h)."""

    controllable = cat.SETTING_NAMES
    setting_limits = {"ventilation_ach": (0.1, 0.4), "heating_comfort_c": (22.2, 24.0)}

    def setting_ranges(self):
        lo, hi = cat.bounds("settings")
        j = cat.SETTING_NAMES.index("ventilation_ach")
        lo[j], hi[j] = 0.1, 0.4
        k = cat.SETTING_NAMES.index("heating_comfort_c")
        lo[k] = 22.2  # off the 0.5 K grid
        return lo, hi


def test_a_limit_outside_the_metamodels_range_is_no_action_and_snapping_stays_inside(shipped):
    historical = np.tile(cat.bounds("settings")[0], (7, 1))
    historical[:, cat.SETTING_NAMES.index("ventilation_ach")] = 0.4
    actions = act.ActionMap.for_site(_Limited(), shipped.domain, historical)
    assert actions.size == 77 and not any(n.startswith("ventilation_ach") for n in actions.names())
    # it knows operating days only: a day set back entirely is no action with it either
    assert not any(n.startswith("hvac_operating") for n in actions.names())
    settings, _ = actions.decode(-np.ones(actions.size))
    assert set(settings[:, cat.SETTING_NAMES.index("ventilation_ach")]) == {0.4}  # held at its history
    assert set(settings[:, cat.SETTING_NAMES.index("heating_comfort_c")]) == {22.5}  # the grid point inside
    assert np.abs(actions.encode(historical)).max() <= 1.0
