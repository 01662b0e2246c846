"""numpy's BLAS on one thread while the metamodel runs (buildenv.threads)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from threadpoolctl import threadpool_info

from buildenv.calibration import calibrate_site
from buildenv.gap import diagnose
from buildenv.threads import one_blas_thread


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

    monkeypatch.setattr("buildenv.calibration.check_declared_effects", first_step)
    monkeypatch.setattr("buildenv.gap.with_declared_effects", first_step)
    for call in (lambda: calibrate_site(SimpleNamespace(effects=()), None), lambda: diagnose(None, None)):
        with pytest.raises(InterruptedError):
            call()
    assert len(seen) == 2 and all(threads and set(threads) == {1} for threads in seen)
