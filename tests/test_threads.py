"""numpy's BLAS on one thread while the metamodel runs, and the metamodel's calls spread over workers
(buildenv.metamodel.threads)."""

from __future__ import annotations

import multiprocessing
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from threadpoolctl import threadpool_info

from buildenv import catalogue as cat
from buildenv.calibration.calibrate import calibrate_site
from buildenv.campaign.sampling import sample_group, sample_weeks
from buildenv.diagnosis.gap import diagnose
from buildenv.metamodel.surrogate import CheckpointError, encode_weeks, ground_hours, load_metamodel, weather_ground_c
from buildenv.metamodel.threads import MIN_WEEKS_PER_CALL, MetamodelWorkers, one_blas_thread, split_calls
from buildenv.weather.epw import load_weather


def _blas_threads() -> list[int]:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def test_one_blas_thread_limits_numpy_blas_only_and_restores_it():
    np.ones((4, 4)) @ np.ones((4, 4))  # numpy's BLAS is loaded
    before, torch_threads = _blas_threads(), torch.get_num_threads()
    assert before
    with one_blas_thread():
        assert _blas_threads() == [1] * len(before)
        assert torch.get_num_threads() == torch_threads  # the metamodel keeps its threads
    assert _blas_threads() == before


def test_calibration_and_diagnosis_run_with_one_blas_thread(monkeypatch):
    # both alternate CMA-ES steps in numpy with metamodel batches in torch thousands of times: each records the
    # BLAS threads at its first step, then stops
    seen = []

    def first_step(*args, **kwargs):
        seen.append(_blas_threads())
        raise InterruptedError

    monkeypatch.setattr("buildenv.calibration.calibrate.check_declared_effects", first_step)
    monkeypatch.setattr("buildenv.diagnosis.gap.with_declared_effects", first_step)
    for call in (lambda: calibrate_site(SimpleNamespace(effects=()), None), lambda: diagnose(None, None)):
        with pytest.raises(InterruptedError):
            call()
    assert len(seen) == 2 and all(threads and set(threads) == {1} for threads in seen)


def _weeks(n: int, surrogate, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    settings, occupancy = sample_weeks(n, rng)
    year = load_weather("usa_il_chicago").weeks(0, cat.WEEKS_PER_YEAR)
    first = np.arange(n) % cat.WEEKS_PER_YEAR
    return {
        "theta": sample_group("theta_build", n, rng),
        "settings": settings,
        "occupancy": occupancy,
        "weather": year[first],
        "ground_c": ground_hours(weather_ground_c("usa_il_chicago"), first * 168, surrogate.context_hours),
    }


@pytest.mark.parametrize(
    "n,batch,workers",
    [
        (0, 64, 2),
        (5, 64, 2),
        (15, 64, 2),
        (16, 64, 2),
        (130, 128, 2),
        (4096, 64, 2),
        (100, 64, 8),
        (100, 3, 2),
        (9, 64, 1),
    ],
)
def test_split_calls_covers_the_weeks_in_even_calls_of_at_least_the_minimum(n, batch, workers):
    calls = split_calls(n, batch, workers)
    assert [w for c in calls for w in range(n)[c]] == list(range(n))
    sizes = [c.stop - c.start for c in calls]
    assert not sizes or max(sizes) - min(sizes) <= 1
    assert all(s <= max(batch, MIN_WEEKS_PER_CALL) for s in sizes)
    if batch >= MIN_WEEKS_PER_CALL:  # a split into workers never makes a call under the minimum
        assert len(calls) == max(-(-n // batch), min(workers, n // MIN_WEEKS_PER_CALL), 1 if n else 0)
        assert len(calls) <= 1 or min(sizes) >= MIN_WEEKS_PER_CALL


def test_predict_spread_over_workers_gives_the_outputs_of_torch_alone():
    surrogate = load_metamodel()
    weeks = _weeks(70, surrogate)
    threads = torch.get_num_threads()
    outputs = {}
    for workers in (1, 2, 3):
        surrogate.workers = workers
        outputs[workers] = surrogate.predict(**weeks, batch_size=16)
        assert torch.get_num_threads() == threads  # the process keeps its thread count
    encoded = encode_weeks(
        weeks["theta"],
        weeks["settings"],
        weeks["occupancy"],
        weeks["weather"],
        context_hours=surrogate.context_hours,
        ground_c=weeks["ground_c"],
    )
    outputs["encoded"] = surrogate.predict_encoded(encoded)  # two calls of 35 weeks
    assert np.array_equal(outputs[2], outputs[3])  # the same calls, each on one thread
    # torch's own threads, or calls of other sizes, may change float32 rounding on some CPUs (on ours, nothing)
    assert all(np.allclose(outputs[1], o, rtol=0, atol=1e-4) for o in outputs.values())
    assert np.isfinite(outputs[1]).all()


def test_an_error_in_a_worker_reaches_the_caller_and_restores_torch_threads():
    surrogate = load_metamodel()
    weeks = _weeks(40, surrogate)
    weeks["ground_c"] = None  # the default reads the ground temperature
    surrogate.workers = 2
    threads = torch.get_num_threads()
    with pytest.raises(CheckpointError, match="ground temperature"):
        surrogate.predict(**weeks, batch_size=16)
    assert torch.get_num_threads() == threads
    with pytest.raises(ValueError, match="workers"):
        MetamodelWorkers(0)


def _predict_in_child(queue, surrogate, weeks) -> None:
    queue.put(surrogate.predict(**weeks))


def test_a_forked_child_predicts_with_workers_of_its_own():
    # a process forked after the parent's workers ran (as EnergyPlus runs are, beside a calibration) has none of
    # their threads: its calls must not wait for them
    surrogate = load_metamodel()
    surrogate.workers = 2
    weeks = _weeks(40, surrogate)
    expected = surrogate.predict(**weeks)
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_predict_in_child, args=(queue, surrogate, weeks))
    child.start()
    try:
        assert np.array_equal(queue.get(timeout=120), expected)
    finally:
        child.join(timeout=30)
        if child.is_alive():
            child.kill()
    assert child.exitcode == 0
