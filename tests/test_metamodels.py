"""Metamodels: every model learns, checkpoints round-trip exactly, catalogue mismatches are refused."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from buildenv import catalogue as cat
from buildenv.campaign.dataset import SPLIT_VERSION
from buildenv.campaign.runs import CampaignConfig, run_campaign
from buildenv.errors import BuildenvError, DatasetError
from buildenv.metamodel import surrogate as sg
from buildenv.metamodel.training import evaluate_metamodel, train_metamodel
from metamodels.checkpoint import Checkpoint, load_checkpoint
from metamodels.loss import paper_loss, response_loss
from metamodels.models import MODELS, band_mask, build, with_more_inputs
from metamodels.normalisation import StandardisedModel, Standardiser

SMALL_CONFIGS = {
    "transformer": {"layers": 1},
    "bigru": {"layers": 1},
    "lstm": {"layers": 1},
    "convgru": {"layers": 1},
    "ffn": {"layers": 2},
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_model_overfits_a_tiny_batch(name):
    torch.manual_seed(0)
    x = torch.randn(4, 48, 6)
    # a target every architecture can represent: a smoothed nonlinear function of the inputs
    y = torch.stack([torch.tanh(x[..., 0] + 0.5 * x[..., 1]), x[..., 2] * x[..., 3]], -1)
    model = build(name, 6, 2, **SMALL_CONFIGS[name])
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(300):
        loss = paper_loss(model(x), y, [0], [1])
        first = loss.item() if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.25 * first, (name, first, loss.item())


def test_paper_loss_is_log_of_rmse():
    pred, target = torch.zeros(1, 10, 2), torch.zeros(1, 10, 2)
    target[..., 0], target[..., 1] = 2.0, 3.0  # RMSE_T = 2, RMSE_Q = 3
    loss = paper_loss(pred, target, [0], [1], alpha=1.0, beta=0.3)
    assert float(loss) == pytest.approx(np.log(3.0) + 0.3 * np.log(4.0), rel=1e-5)
    mask = torch.zeros(1, 10, dtype=torch.bool)
    mask[0, :5] = True
    target[0, 5:] = 100.0  # masked hours do not count
    assert float(paper_loss(pred, target, [0], [1], mask=mask)) == pytest.approx(float(loss), rel=1e-5)


def test_response_loss_is_the_rms_savings_error_between_partners():
    def week(energy: float) -> torch.Tensor:  # one HVAC channel, standardised with mean 2 and deviation 4
        return torch.full((1, 5, 2), (energy - 2.0) / 4.0)

    args = ([1], torch.tensor([2.0]), torch.tensor([4.0]), 0.5)
    # simulated: 8 against a partner's 10 (20 % saved); predicted: 9 against 10 (10 %): an error of 0.1
    assert float(response_loss(week(9.0), week(10.0), week(8.0), week(10.0), *args)) == pytest.approx(0.1, rel=1e-4)
    # a constant error on both weeks leaves the difference, and so the savings, right
    assert float(response_loss(week(11.0), week(13.0), week(8.0), week(10.0), *args)) == pytest.approx(0.0, abs=1e-5)


def test_transformer_attention_is_local():
    torch.manual_seed(0)
    model = build("transformer", 3, 1, layers=1, window=2).eval()
    x = torch.randn(1, 30, 3)
    y = model(x)
    x2 = x.clone()
    x2[0, 29] += 10.0  # hour 29 can reach hour 29-4 at most through two attention hops (encoder, decoder)
    y2 = model(x2)
    assert torch.allclose(y[0, :24], y2[0, :24], atol=1e-6)
    assert not torch.allclose(y[0, 26:], y2[0, 26:])
    assert band_mask(5, 1).sum() == 13


def test_standardiser_uses_only_what_it_is_given():
    train = np.random.default_rng(0).normal(5.0, 2.0, (100, 3))
    norm = Standardiser.fit(train)
    np.testing.assert_allclose(norm.transform(train).mean(0), 0, atol=1e-5)
    np.testing.assert_allclose(norm.inverse(norm.transform(train)), train, rtol=1e-5)


def test_standardiser_fitted_in_chunks_matches_one_float64_pass(monkeypatch):
    import metamodels.normalisation as normalisation

    x = np.random.default_rng(1).normal(300.0, 0.5, (40, 24, 6)).astype(np.float32)  # a large mean, a small spread
    flat = x.astype(np.float64).reshape(-1, 6)
    monkeypatch.setattr(normalisation, "FIT_CHUNK_VALUES", 50)  # 8 rows a chunk, 120 chunks
    norm = Standardiser.fit(x)
    np.testing.assert_allclose(norm.mean, flat.mean(0), rtol=1e-7)
    np.testing.assert_allclose(norm.std, flat.std(0), rtol=1e-6)


def test_a_time_budget_stops_mid_epoch_and_spreads_the_cosine_decay_over_it(tmp_path, monkeypatch):
    from types import SimpleNamespace

    import metamodels.train as training_loop

    clock = iter(range(10_000))  # one second per reading of the clock: 39 steps of a 64-step epoch fit 40 s
    monkeypatch.setattr(training_loop, "time", SimpleNamespace(perf_counter=lambda: float(next(clock))))
    torch.manual_seed(0)
    x, y = torch.randn(64, 24, 5), torch.randn(64, 24, 2)
    norm_in, norm_out = Standardiser.fit(np.random.rand(10, 5)), Standardiser.fit(np.random.rand(10, 2))
    hours = torch.ones(24, dtype=torch.bool)

    def run(name: str, **options) -> dict:
        ck = Checkpoint("ffn", {"layers": 1}, build("ffn", 5, 2, layers=1), norm_in, norm_out, sg.metadata())
        cfg = training_loop.TrainConfig(batch_size=1, temperature_channels=[0], consumption_channels=[1], **options)
        return training_loop.fit(ck, x, y, x[:8], y[:8], hours, cfg, tmp_path / name, progress=False)

    budget = run("budget.pt", epochs=50, patience=50, minutes=40 / 60)
    assert budget["epochs_run"] == 1 and budget["weeks_seen"] == 39  # stopped inside its first epoch
    assert budget["seconds"] == pytest.approx(41.0)  # the budget, then the validation's reading of the clock
    lr = load_checkpoint(tmp_path / "budget.pt.last").training["optimiser"]["param_groups"][0]["lr"]
    assert lr == pytest.approx(0.5e-3 * (1 + np.cos(np.pi * 39 / 40)))  # the last step's rate, near 0
    unlimited = run("epochs.pt", epochs=2, patience=2)
    assert unlimited["epochs_run"] == 2 and unlimited["weeks_seen"] == 128
    with pytest.raises(ValueError, match="positive minutes"):
        run("none.pt", minutes=0)


def test_checkpoint_round_trip_is_bit_exact(tmp_path):
    torch.manual_seed(1)
    model = build("transformer", 5, 3, layers=1)
    norm_in, norm_out = Standardiser.fit(np.random.rand(10, 5)), Standardiser.fit(np.random.rand(10, 3))
    ck = Checkpoint("transformer", {"layers": 1}, model, norm_in, norm_out, {"note": "x"})
    path = ck.save(tmp_path / "m.pt")
    loaded = load_checkpoint(path)
    x = torch.randn(2, 20, 5)
    model.eval()
    with torch.no_grad():
        assert torch.equal(model(x), loaded.model(x))
    assert loaded.metadata == {"note": "x"}
    np.testing.assert_array_equal(loaded.input_norm.mean, norm_in.mean)


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("mm") / "data"
    run_campaign(
        CampaignConfig(weeks=12, seed=2, epw=["usa_il_chicago", "usa_co_golden"], weeks_per_run=3),
        out,
        workers=2,
        progress=False,
    )
    return out


def test_train_evaluate_resume_and_catalogue_check(tiny_dataset, tmp_path, monkeypatch):
    ckpt = tmp_path / "lstm.pt"
    result = train_metamodel(
        tiny_dataset, "lstm", ckpt, split="random", model_config={"layers": 1}, epochs=2, batch_size=4, progress=False
    )
    assert result["fit"]["epochs_run"] == 2 and np.isfinite(result["test"]["loss"])
    assert (tmp_path / "lstm.pt.last").exists() and (tmp_path / "lstm.pt.csv").exists()
    # rerunning with more epochs resumes from epoch 2 instead of starting over
    again = train_metamodel(
        tiny_dataset, "lstm", ckpt, split="random", model_config={"layers": 1}, epochs=3, batch_size=4, progress=False
    )
    assert again["fit"]["epochs_run"] == 3
    assert len((tmp_path / "lstm.pt.csv").read_text().strip().splitlines()) == 1 + 3
    evaluated = evaluate_metamodel(ckpt, tiny_dataset)
    assert evaluated["subset"] == "test" and evaluated["weeks"] == result["test_weeks"]
    assert evaluated["loss"] == pytest.approx(again["test"]["loss"], rel=1e-5)
    surrogate = sg.load_metamodel(ckpt)
    from buildenv.campaign.dataset import open_dataset

    with open_dataset(tiny_dataset) as ds:
        x, y = sg.encode_dataset(ds, np.arange(3))
        assert x.shape == (3, sg.CONTEXT_HOURS + 168, len(sg.INPUT_CHANNELS))
        week = [a[:3] for a in (ds.theta, ds.settings, ds.occupancy, ds.weather)]
    pred = surrogate.predict(*week, ground_c=x[..., -1])
    assert pred.shape == (3, 168, len(cat.OUTPUT_NAMES)) and np.isfinite(pred).all()
    with pytest.raises(sg.CheckpointError, match="ground temperature"):
        surrogate.predict(*week)
    monkeypatch.setattr(cat, "catalogue_hash", lambda: "0000000000000000")
    with pytest.raises(sg.CheckpointError, match="catalogue"):
        sg.load_metamodel(ckpt)


def test_training_with_a_response_weight_runs_each_weeks_partner_under_other_settings(tmp_path):
    data = tmp_path / "pairs"
    config = CampaignConfig(weeks=12, seed=2, epw=["usa_il_chicago"], weeks_per_run=3, settings_draws=2)
    run_campaign(config, data, workers=2, progress=False)
    runs = {}
    for weight in (0.0, 1.0):
        runs[weight] = train_metamodel(
            data,
            "ffn",
            tmp_path / f"w{weight}.pt",
            split="random",
            model_config={"layers": 1},
            epochs=1,
            batch_size=4,
            progress=False,
            response_weight=weight,
        )
    assert runs[1.0]["paired_train_weeks"] > 0
    first = [r["fit"]["best_val_loss"] for r in runs.values()]
    assert first[0] != pytest.approx(first[1], rel=1e-6)  # the partners' savings error moved the weights
    assert np.isfinite(first).all()


def test_a_longer_context_carries_the_previous_days_or_repeats_the_first_day(tiny_dataset):
    from buildenv.campaign.dataset import open_dataset

    with open_dataset(tiny_dataset) as ds:
        previous = ds.previous_week()
        i = int(np.flatnonzero(previous >= 0)[0])  # a week with a real preceding week, and that week
        week = [a[[i]] for a in (ds.theta, ds.settings, ds.occupancy, ds.weather)]
        prev = tuple(a[[previous[i]]] for a in (ds.settings, ds.occupancy, ds.weather))
    one_day = sg.encode_weeks(*week, prev, np.array([True]))
    three_days = sg.encode_weeks(*week, prev, np.array([True]), context_hours=72)
    assert three_days.shape == (1, 72 + 168, len(sg.INPUT_CHANNELS))
    np.testing.assert_array_equal(three_days[:, 48:], one_day)  # the last day before the week, then the week
    w = [sg.INPUT_CHANNELS.index(c) for c in sg.WEATHER_INPUTS]
    np.testing.assert_array_equal(
        three_days[0, :72, w], prev[2][0, -72:][:, [cat.WEATHER_NAMES.index(c) for c in sg.WEATHER_INPUTS]].T
    )
    is_context = sg.INPUT_CHANNELS.index("is_context")
    assert (three_days[0, :72, is_context] == 1).all() and (three_days[0, 72:, is_context] == 0).all()
    # no preceding week: the week's first day, repeated, as EnergyPlus's warm-up
    cold = sg.encode_weeks(*week, context_hours=48)
    np.testing.assert_array_equal(cold[:, :24, :is_context], cold[:, 48:72, :is_context])
    np.testing.assert_array_equal(cold[:, 24:48, :is_context], cold[:, 48:72, :is_context])
    np.testing.assert_array_equal(cold[:, 24:], sg.encode_weeks(*week))
    for bad in (0, 30, 168):
        with pytest.raises(sg.CheckpointError, match="whole number of days"):
            sg.encode_weeks(*week, context_hours=bad)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_a_model_widened_by_an_input_computes_what_it_did_and_can_learn_its_use(name):
    torch.manual_seed(0)
    config = {**SMALL_CONFIGS[name], **({"patch_hours": 4, "hourly_head": 8} if name == "transformer" else {})}
    model = build(name, 6, 2, **config).eval()
    wide = with_more_inputs(model, name, config, 6, 2, 1).eval()
    x = torch.randn(3, 48, 7)
    torch.testing.assert_close(wide(x), model(x[..., :6]), rtol=0, atol=1e-6)
    wide(x).square().sum().backward()  # the new input's weights get a gradient: training can use it
    grads = [p.grad for p in wide.parameters() if p.grad is not None and p.grad.ndim >= 2]
    assert any(g.abs().sum() > 0 for g in grads)
    with pytest.raises(ValueError, match="cannot widen"):
        with_more_inputs(model, name, config, 5, 2, 1)  # not the input count it was built with


def test_the_ground_temperature_is_the_weather_files_monthly_value_in_every_encoded_hour(tiny_dataset):
    from buildenv.campaign.dataset import open_dataset
    from buildenv.energyplus.shoebox import ground_temperatures_c
    from buildenv.weather.epw import load_weather, month_of_hour

    with open_dataset(tiny_dataset) as ds:
        x, _ = sg.encode_dataset(ds, np.arange(len(ds)), context_hours=48)
        names, climate, week = ds.weather_names, ds.weather_index[:], ds.week_of_year[:]
    for i in range(len(x)):
        monthly = ground_temperatures_c(load_weather(names[climate[i]]))
        hours = (int(week[i]) * 168 + np.arange(-48, 168)) % 8760
        np.testing.assert_allclose(x[i, :, -1], np.array(monthly)[month_of_hour()[hours]], rtol=1e-6)
    assert len(np.unique(x[:, 0, -1])) > 1  # two climates, several months
    # a week starting on January 1st takes its context from the end of December
    year = np.arange(8760.0)
    np.testing.assert_array_equal(sg.ground_hours(year, [0], 24)[0], np.r_[np.arange(8736, 8760), np.arange(168)])
    assert sg.INPUT_CHANNELS[-1] == sg.GROUND_CHANNEL and sg.NO_GROUND_CHANNELS == sg.INPUT_CHANNELS[:-1]
    assert np.isnan(sg.encode_weeks(*(a[None] for a in _one_week(tiny_dataset)))[..., -1]).all()


def _one_week(dataset) -> list[np.ndarray]:
    from buildenv.campaign.dataset import open_dataset

    with open_dataset(dataset) as ds:
        return [a[0] for a in (ds.theta, ds.settings, ds.occupancy, ds.weather)]


def test_a_checkpoint_without_the_ground_temperature_is_fine_tuned_with_it(tiny_dataset, tmp_path):
    from buildenv.campaign.dataset import open_dataset

    config = {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 2}
    base, tuned = tmp_path / "noground.pt", tmp_path / "ground.pt"
    train_metamodel(
        tiny_dataset,
        "transformer",
        base,
        split="random",
        model_config=config,
        epochs=1,
        batch_size=4,
        progress=False,
        ground_temperature=False,
    )
    old = sg.load_metamodel(base)
    assert not old.uses_ground and old.checkpoint.inputs == len(sg.NO_GROUND_CHANNELS)
    train_metamodel(
        tiny_dataset, "transformer", tuned, split="random", epochs=1, batch_size=4, progress=False, init=base, lr=0.0
    )
    new = sg.load_metamodel(tuned)
    assert new.uses_ground and new.checkpoint.inputs == len(sg.INPUT_CHANNELS)
    assert new.checkpoint.metadata["initialised_from"]["added_inputs"] == [sg.GROUND_CHANNEL]
    with open_dataset(tiny_dataset) as ds:
        x, _ = sg.encode_dataset(ds, np.arange(6))
    np.testing.assert_allclose(new.predict_encoded(x), old.predict_encoded(x), rtol=0, atol=1e-4)  # zero weights
    unknown = x.copy()
    unknown[..., -1] = np.nan
    np.testing.assert_array_equal(old.predict_encoded(unknown), old.predict_encoded(x))  # never read by it
    with pytest.raises(sg.CheckpointError, match="ground temperature"):
        new.predict_encoded(unknown)
    with pytest.raises(sg.CheckpointError, match="channels"):
        new.predict_encoded(x[..., :-1])
    with pytest.raises(BuildenvError, match="reads the ground temperature"):
        train_metamodel(
            tiny_dataset,
            "transformer",
            tmp_path / "back.pt",
            split="random",
            epochs=1,
            init=tuned,
            progress=False,
            ground_temperature=False,
        )
    with pytest.raises(BuildenvError, match="without the ground temperature"):  # resuming it another way
        train_metamodel(
            tiny_dataset,
            "transformer",
            base,
            split="random",
            model_config=config,
            epochs=2,
            batch_size=4,
            progress=False,
        )


def test_a_metamodel_reads_the_temperature_measured_before_the_week(tiny_dataset, tmp_path):
    """``--temperature-before``: the previous week's simulated indoor temperature over the context hours (unknown
    on a run's first week), added to a checkpoint with zero weights, hidden on a share of the training weeks."""
    from buildenv.campaign.dataset import open_dataset
    from buildenv.metamodel.training import hide_temperature_before

    config = {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 2}
    base, tuned, scratch = tmp_path / "base.pt", tmp_path / "before.pt", tmp_path / "scratch.pt"
    train_metamodel(
        tiny_dataset,
        "transformer",
        base,
        split="random",
        model_config=config,
        epochs=1,
        batch_size=4,
        progress=False,
        context_hours=48,
    )
    train_metamodel(
        tiny_dataset,
        "transformer",
        tuned,
        split="random",
        epochs=1,
        batch_size=4,
        progress=False,
        init=base,
        lr=0.0,
        context_hours=48,
        temperature_before=True,
    )
    old, new = sg.load_metamodel(base), sg.load_metamodel(tuned)
    assert not old.uses_temperature_before and new.uses_temperature_before
    assert new.checkpoint.inputs == len(sg.ALL_CHANNELS)
    assert new.checkpoint.metadata["initialised_from"]["added_inputs"] == list(sg.TEMPERATURE_BEFORE_CHANNELS)
    value, known = len(sg.INPUT_CHANNELS), len(sg.INPUT_CHANNELS) + 1
    t_out = cat.OUTPUT_NAMES.index("T_INT_OFFICE")
    with open_dataset(tiny_dataset) as ds:
        previous = ds.previous_week()
        x, _ = sg.encode_dataset(ds, np.arange(len(previous)), context_hours=48, temperature_before=True)
        outputs = ds.outputs[:]
        week = [a[:] for a in (ds.theta, ds.settings, ds.occupancy, ds.weather)]
    first, later = previous < 0, previous >= 0
    assert first.any() and later.any()
    np.testing.assert_array_equal(x[later, :48, value], outputs[previous[later], -48:, t_out])
    assert (x[later, :48, known] == 1).all() and (x[:, 48:, known] == 0).all() and (x[first, :, known] == 0).all()
    assert np.isnan(x[first, :, value]).all() and np.isnan(x[:, 48:, value]).all()
    # zero weights: the widened model predicts what it did, with the temperature or without it
    without = x[..., : len(sg.INPUT_CHANNELS)]
    np.testing.assert_allclose(new.predict_encoded(x), old.predict_encoded(without), rtol=0, atol=1e-4)
    np.testing.assert_allclose(new.predict_encoded(without), old.predict_encoded(without), rtol=0, atol=1e-4)
    np.testing.assert_array_equal(old.predict_encoded(x), old.predict_encoded(without))  # never read by it
    ground = x[..., sg.INPUT_CHANNELS.index(sg.GROUND_CHANNEL)]
    before = x[:, :48, value]
    np.testing.assert_array_equal(
        new.predict(*week, ground_c=ground, temperature_before_c=before),
        new.predict_encoded(sg.encode_weeks(*week, context_hours=48, ground_c=ground, temperature_before_c=before)),
    )
    # trained from scratch with it: a quarter of the weeks hidden, every week predicted, evaluated the same way
    result = train_metamodel(
        tiny_dataset,
        "transformer",
        scratch,
        split="random",
        model_config=config,
        epochs=1,
        batch_size=4,
        progress=False,
        context_hours=48,
        temperature_before=True,
    )
    assert np.isfinite(result["test"]["loss"])
    assert evaluate_metamodel(scratch, tiny_dataset)["loss"] == pytest.approx(result["test"]["loss"], rel=1e-5)
    assert np.isfinite(sg.load_metamodel(scratch).predict(*week, ground_c=ground)).all()
    hidden = hide_temperature_before(x.copy(), 1.0, 0)
    assert np.isnan(hidden[..., value]).all() and (hidden[..., known] == 0).all()
    with pytest.raises(BuildenvError, match="pass --temperature-before"):
        train_metamodel(
            tiny_dataset,
            "transformer",
            tmp_path / "back.pt",
            split="random",
            epochs=1,
            init=tuned,
            progress=False,
            context_hours=48,
        )
    with pytest.raises(BuildenvError, match="without the temperature before the week"):  # resumed another way
        train_metamodel(
            tiny_dataset,
            "transformer",
            base,
            split="random",
            model_config=config,
            epochs=2,
            batch_size=4,
            progress=False,
            context_hours=48,
            temperature_before=True,
        )
    with pytest.raises(sg.CheckpointError, match="ground temperature"):
        sg.input_channels(ground=False, temperature_before=True)


def test_standardiser_statistics_leave_unknown_values_out():
    data = np.array([[1.0, np.nan, np.nan], [3.0, 5.0, np.nan], [5.0, 7.0, np.nan]], dtype=np.float32)
    norm = Standardiser.fit(data)
    np.testing.assert_allclose(norm.mean, [3.0, 6.0, 0.0])
    np.testing.assert_allclose(norm.std, [np.sqrt(8 / 3), 1.0, 1.0], rtol=1e-6)


def test_a_checkpoint_trained_with_two_days_of_context_keeps_them(tiny_dataset, tmp_path):
    ckpt = tmp_path / "ctx48.pt"
    config = {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 2}
    result = train_metamodel(
        tiny_dataset,
        "transformer",
        ckpt,
        split="random",
        model_config=config,
        epochs=1,
        batch_size=4,
        progress=False,
        context_hours=48,
    )
    assert np.isfinite(result["test"]["loss"])
    surrogate = sg.load_metamodel(ckpt)
    assert surrogate.context_hours == 48 and surrogate.checkpoint.metadata["context_hours"] == 48
    from buildenv.campaign.dataset import open_dataset

    with open_dataset(tiny_dataset) as ds:
        week = [a[:3] for a in (ds.theta, ds.settings, ds.occupancy, ds.weather)]
        ground = sg.encode_dataset(ds, np.arange(3), context_hours=48)[0][..., -1]
        evaluated = evaluate_metamodel(ckpt, tiny_dataset)
    pred = surrogate.predict(*week, ground_c=ground)
    np.testing.assert_array_equal(
        pred, surrogate.predict_encoded(sg.encode_weeks(*week, context_hours=48, ground_c=ground))
    )
    assert evaluated["loss"] == pytest.approx(result["test"]["loss"], rel=1e-5)
    with pytest.raises(sg.CheckpointError, match="48"):  # inputs encoded for the default one-day context
        surrogate.predict_encoded(sg.encode_weeks(*week, ground_c=ground[:, 24:]))
    with pytest.raises(BuildenvError, match="--context-hours 48"):  # resuming it with another context
        train_metamodel(
            tiny_dataset,
            "transformer",
            ckpt,
            split="random",
            model_config=config,
            epochs=2,
            batch_size=4,
            progress=False,
            context_hours=72,
        )


def test_fine_tuning_starts_from_the_checkpoint_and_keeps_its_normalisation(tiny_dataset, tmp_path):
    config = {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 2}
    base = tmp_path / "base.pt"
    train_metamodel(
        tiny_dataset, "transformer", base, split="random", model_config=config, epochs=1, batch_size=4, progress=False
    )
    start = sg.load_metamodel(base).checkpoint
    start.metadata["split_version"] = 1  # a start split the earlier way: its fine-tune splits its weeks alike
    start.save(base)
    tuned = tmp_path / "tuned72.pt"
    # lr 0: the run starts from the base's weights and its normalisation, so nothing moves but the context
    train_metamodel(
        tiny_dataset,
        "transformer",
        tuned,
        split="random",
        epochs=1,
        batch_size=4,
        progress=False,
        context_hours=72,
        init=base,
        lr=0.0,
    )
    ck = sg.load_metamodel(tuned).checkpoint
    assert ck.config == config and ck.metadata["context_hours"] == 72 and ck.metadata["split_version"] == 1
    assert ck.metadata["initialised_from"] == {
        "checkpoint": str(base),
        "dataset": start.metadata["dataset"],
        "datasets": start.metadata["datasets"],
        "train_weeks": start.metadata["train_weeks"],
        "context_hours": 24,
        "zoning": "core_perimeter",
    }
    np.testing.assert_array_equal(ck.input_norm.mean, start.input_norm.mean)
    np.testing.assert_array_equal(ck.output_norm.std, start.output_norm.std)
    for name, value in start.model.state_dict().items():
        torch.testing.assert_close(ck.model.state_dict()[name], value, rtol=0, atol=0)
    with pytest.raises(BuildenvError, match="is a transformer, not a lstm"):
        train_metamodel(tiny_dataset, "lstm", tmp_path / "x.pt", split="random", init=base, progress=False)
    with pytest.raises(BuildenvError, match="--split random --seed 0"):  # its test weeks could be trained on
        train_metamodel(
            tiny_dataset, "transformer", tmp_path / "y.pt", split="random", seed=1, init=base, progress=False
        )
    with pytest.raises(BuildenvError, match="leave --model-config out"):
        train_metamodel(
            tiny_dataset,
            "transformer",
            tmp_path / "z.pt",
            split="random",
            init=base,
            model_config={**config, "layers": 2},
            progress=False,
        )


@pytest.mark.parametrize(
    "name,config",
    [
        ("transformer", {"patch_hours": 8, "layers": 1, "hourly_head": 16}),
        ("transformer", {"patch_hours": 8, "layers": 1, "hourly_head": 16, "hourly_gru": 8}),
        ("transformer", {"patch_hours": 8, "layers": 1, "hourly_head": 16, "hourly_state": 4}),
        (
            "transformer",
            {"patch_hours": 8, "layers": 1, "hourly_head": 16, "hourly_state": 4, "hourly_state_layers": 2},
        ),
        ("lstm", {"layers": 1}),
        ("ffn", {"layers": 1}),
    ],
)
def test_traced_inference_matches_eager(name, config):
    torch.manual_seed(0)
    channels = len(sg.INPUT_CHANNELS)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(300, sg.CONTEXT_HOURS + 168, channels)).astype(np.float32)
    ck = Checkpoint(
        name,
        config,
        build(name, channels, 8, **config),
        Standardiser.fit(x.reshape(-1, channels)),
        Standardiser.fit(rng.normal(size=(50, 8))),
        sg.metadata(),
    )
    eager = sg.Surrogate(ck, jit=False).predict_encoded(x, batch_size=128)
    fast = sg.Surrogate(ck)
    traced = fast.predict_encoded(x, batch_size=128)  # batches of 128, 128 and 44 weeks
    assert isinstance(fast._inference_model(), torch.jit.ScriptModule)
    np.testing.assert_allclose(traced, eager, rtol=1e-4, atol=1e-4)


def test_standardised_model_is_the_numpy_chain_in_one_module():
    """Inference standardises inputs and rescales outputs inside the module: same numbers as doing it around it."""
    torch.manual_seed(0)
    rng = np.random.default_rng(1)
    x = (rng.normal(size=(5, 30, 6)) * [1, 10, 100, 0.1, 5, 50] + [0, 20, -3, 1, 8, 400]).astype(np.float32)
    net = build("lstm", 6, 3, layers=1).eval()
    inputs, outputs = Standardiser.fit(x), Standardiser.fit(rng.normal(3.0, 7.0, size=(40, 3)))
    with torch.no_grad():
        chain = outputs.inverse(net(torch.from_numpy(inputs.transform(x)))[:, 6:]).numpy()
        wrapped = StandardisedModel(net, inputs, outputs, skip_steps=6)(torch.from_numpy(x)).numpy()
    assert wrapped.shape == (5, 24, 3)
    np.testing.assert_allclose(wrapped, chain, rtol=1e-6, atol=1e-5)


@pytest.mark.parametrize(
    "config",
    [
        {"patch_hours": 8, "layers": 1},
        {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_gru": 4},
        {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 3},
        {"patch_hours": 8, "layers": 1, "hourly_head": 8, "hourly_state": 3, "hourly_state_layers": 2},
    ],
)
def test_a_transformer_skipping_the_context_outputs_gives_the_week_of_the_full_pass(config):
    # inference leaves out the context hours' read-out (and the last stage's backward states there): the week's
    # outputs must be those of the full pass, which training computes
    torch.manual_seed(0)
    net = build("transformer", 5, 3, **config).eval()
    x = torch.randn(4, 72 + 168, 5) * 3
    with torch.no_grad():
        full, skipped = net(x)[:, 72:], net(x, 72)
    assert skipped.shape == (4, 168, 3)
    torch.testing.assert_close(skipped, full, rtol=1e-5, atol=1e-5)
    norm_in, norm_out = Standardiser.fit(x.reshape(-1, 5).numpy()), Standardiser.fit(np.ones((2, 3)))
    assert StandardisedModel(net, norm_in, norm_out, skip_steps=72).skips_inside
    assert not StandardisedModel(build("lstm", 5, 3, layers=1), norm_in, norm_out, skip_steps=72).skips_inside


def test_hourly_head_sees_each_hour():
    torch.manual_seed(0)
    model = build("transformer", 3, 2, layers=1, patch_hours=6, hourly_head=8).eval()
    x = torch.randn(1, 24, 3)
    x2 = x.clone()
    x2[0, 7] += 5.0  # hour 7 (second token) changes its own output, not only its token's
    with torch.no_grad():
        y, y2 = model(x), model(x2)
    assert y.shape == (1, 24, 2)
    changed = (y - y2).abs().amax(-1)[0]
    assert changed[7] > 0 and changed[7] > 10 * changed[6]


def test_hourly_gru_carries_an_hour_to_the_neighbouring_tokens():
    torch.manual_seed(0)
    model = build("transformer", 3, 2, layers=1, window=1, patch_hours=6, hourly_head=8, hourly_gru=4).eval()
    x = torch.randn(1, 48, 3)
    x2 = x.clone()
    x2[0, 7] += 5.0  # hour 7: token 1; with a 1-hour window token 3 (hours 18-23) is beyond attention's reach
    with torch.no_grad():
        changed = (model(x) - model(x2)).abs().amax(-1)[0]
    assert changed[7] > 0 and changed[20] > 0 and changed[40] > 0


def test_thermal_states_are_the_normalised_exponential_recurrence():
    """The matrix form equals the hour-by-hour recurrence: num = a num + u, den = a den + 1, state = num / den."""
    from metamodels.models import ThermalStates

    torch.manual_seed(0)
    drive = torch.randn(2, 30, 3)
    for backward in (False, True):
        states = ThermalStates(3, backward=backward, tau_min_h=0.5, tau_max_h=20.0)
        with torch.no_grad():
            got = states(drive)
        decay = torch.exp(-1.0 / states.log_tau.exp()).detach()
        num, den, expected = torch.zeros(2, 3), torch.zeros(3), {}
        for hour in reversed(range(30)) if backward else range(30):
            num, den = decay * num + drive[:, hour], decay * den + 1.0
            expected[hour] = num / den
        torch.testing.assert_close(got, torch.stack([expected[h] for h in range(30)], 1), rtol=1e-5, atol=1e-5)
    # a constant drive gives that constant at every hour (no pull towards zero at the sequence's ends)
    torch.testing.assert_close(ThermalStates(4)(torch.full((1, 50, 4), 3.0)), torch.full((1, 50, 4), 3.0))


def test_hourly_state_carries_an_hour_to_distant_hours_both_ways():
    torch.manual_seed(0)
    model = build("transformer", 3, 2, layers=1, window=1, patch_hours=6, hourly_head=8, hourly_state=4).eval()
    x = torch.randn(1, 48, 3)
    x2 = x.clone()
    x2[0, 20] += 5.0  # hour 20: token 3; with a 1-hour window tokens 0 and 6 are beyond attention's reach
    with torch.no_grad():
        changed = (model(x) - model(x2)).abs().amax(-1)[0]
    assert changed[2] > 0 and changed[40] > 0
    with pytest.raises(ValueError, match="not both"):
        build("transformer", 3, 2, patch_hours=6, hourly_head=8, hourly_state=4, hourly_gru=4)


def test_stacked_state_stages_add_parameters_and_keep_one_stage_checkpoints_loadable():
    one = build("transformer", 3, 2, layers=1, patch_hours=6, hourly_head=8, hourly_state=4)
    two = build("transformer", 3, 2, layers=1, patch_hours=6, hourly_head=8, hourly_state=4, hourly_state_layers=2)
    extra = set(two.state_dict()) - set(one.state_dict())
    assert extra and all(k.startswith("head.stages.0.") for k in extra)
    assert set(one.state_dict()) <= set(two.state_dict())  # one stage: the same names as before stages existed
    with torch.no_grad():
        assert two(torch.randn(2, 48, 3)).shape == (2, 48, 2)
    with pytest.raises(ValueError, match="hourly_state_layers"):
        build("transformer", 3, 2, patch_hours=6, hourly_head=8, hourly_state=4, hourly_state_layers=0)


def test_attention_paths_agree():
    """Short sequences use explicit matmuls, long ones the fused kernel: the same attention either way."""
    import metamodels.models as mm

    torch.manual_seed(0)
    model = build("transformer", 4, 2, layers=1, window=3).eval()
    x = torch.randn(2, 96, 4)
    with torch.no_grad():
        fused = model(x)
        old = mm.DENSE_MATMUL_MAX_TOKENS
        try:
            mm.DENSE_MATMUL_MAX_TOKENS = 1000
            explicit = model(x)
        finally:
            mm.DENSE_MATMUL_MAX_TOKENS = old
    torch.testing.assert_close(fused, explicit, rtol=1e-4, atol=1e-5)


def test_a_fine_tune_may_start_from_shoeboxes_of_another_zoning(tiny_dataset, tmp_path):
    five = tmp_path / "five"
    run_campaign(
        CampaignConfig(weeks=12, seed=3, epw=["usa_il_chicago"], weeks_per_run=3, zoning="five_zone"),
        five,
        workers=2,
        progress=False,
    )
    base = tmp_path / "ring.pt"
    train_metamodel(tiny_dataset, "ffn", base, split="random", epochs=1, batch_size=4, progress=False)
    tuned = tmp_path / "five.pt"
    train_metamodel(five, "ffn", tuned, split="random", epochs=1, batch_size=4, progress=False, init=base)
    meta = sg.load_metamodel(tuned).checkpoint.metadata
    assert sg.load_metamodel(tuned).zoning == "five_zone"
    assert meta["initialised_from"]["zoning"] == "core_perimeter"
    assert meta["split_version"] == SPLIT_VERSION  # weather weeks split alike in every campaign
    with pytest.raises(BuildenvError, match="is five_zone: train on campaigns of one zoning"):
        train_metamodel([tiny_dataset, five], "ffn", tmp_path / "mixed.pt", split="random", epochs=1, progress=False)


def test_several_campaigns_train_one_metamodel_each_scored_on_its_own_test_weeks(tiny_dataset, tmp_path):
    from buildenv.campaign.dataset import open_dataset
    from buildenv.metamodel.training import training_split, training_splits

    other = tmp_path / "other"
    run_campaign(
        CampaignConfig(weeks=12, seed=4, epw=["usa_il_chicago"], weeks_per_run=3), other, workers=2, progress=False
    )
    with open_dataset(tiny_dataset) as a, open_dataset(other) as b:
        alone = [training_split(ds, "random", 0) for ds in (a, b)]
        subset = training_splits([a, b], "random", 0, max_weeks=10)
        assert training_split(a, "random", 0, max_weeks=5)["train"].tolist() == (
            training_splits([a], "random", 0, max_weeks=5)[0]["train"].tolist()
        )
    assert sum(len(p["train"]) for p in subset) == 10
    for mine, whole in zip(subset, alone):
        assert set(mine["train"]) <= set(whole["train"])
        assert mine["test"].tolist() == whole["test"].tolist()  # the subset cuts training weeks only
    ckpt = tmp_path / "both.pt"
    result = train_metamodel([tiny_dataset, other], "ffn", ckpt, split="random", epochs=1, batch_size=4, progress=False)
    assert result["train_weeks"] == sum(len(p["train"]) for p in alone)
    assert result["test_weeks"] == sum(len(p["test"]) for p in alone)
    meta = sg.load_metamodel(ckpt).checkpoint.metadata
    assert meta["datasets"] == [str(tiny_dataset.resolve()), str(other.resolve())]
    for data, part in zip((tiny_dataset, other), alone):
        scored = evaluate_metamodel(ckpt, data)
        assert scored["subset"] == "test" and scored["weeks"] == len(part["test"])
    with pytest.raises(BuildenvError, match="given twice"):
        train_metamodel([other, str(other)], "ffn", tmp_path / "twice.pt", split="random", epochs=1, progress=False)
    with pytest.raises(BuildenvError, match="rerun with those, in that order"):
        train_metamodel([other, tiny_dataset], "ffn", ckpt, split="random", epochs=2, batch_size=4, progress=False)
    with pytest.raises(BuildenvError, match="split climate"):
        train_metamodel([tiny_dataset, other], "ffn", tmp_path / "c.pt", split="climate", epochs=1, progress=False)

    # a climate one campaign lacks is held out of the one that has it
    def holding_out(climate: str) -> dict:
        out = tmp_path / f"{climate}.pt"
        both = [tiny_dataset, other]
        return train_metamodel(both, "ffn", out, split="random", holdout_climates=[climate], epochs=1, progress=False)

    apart = holding_out("usa_co_golden")
    with open_dataset(tiny_dataset) as a:
        golden = int((a.weather_index[:] == a.weather_names.index("usa_co_golden")).sum())
    assert apart["holdout_climate"]["weeks"] == golden > 0
    with pytest.raises(DatasetError, match="usa_fl_miami"):
        holding_out("usa_fl_miami")
