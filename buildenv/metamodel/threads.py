"""The numerical libraries' thread pools while the metamodel runs.

numpy's BLAS (OpenBLAS) and PyTorch (OpenMP) each keep a pool of worker threads that spin for a while after a
call. Calibration and diagnosis alternate the two thousands of times (a CMA-ES step in numpy, then a batch of
weeks through the metamodel in torch), and on few cores the two pools fight for them. numpy's matrices here are
small, so :func:`one_blas_thread` gives BLAS one thread and leaves torch its own.

The metamodel's calls of many weeks are split among workers (:class:`MetamodelWorkers`): as many threads as
torch has intra-op threads, each running the model on its own share with torch on one thread; the network is
small, so products side by side use the cores better than threads inside each product. Each share is at least
:data:`MIN_WEEKS_PER_CALL` weeks, so that the outputs are those of torch alone bit for bit.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

#: the fewest weeks in one model call when a call is split among workers: from 8 weeks on, a week's outputs do not
#: depend on the batch size, bit for bit (some smaller batches differ at float32 rounding)
MIN_WEEKS_PER_CALL = 8
#: torch's intra-op thread count belongs to the process: one split call at a time sets it to 1 and back
_TORCH_THREADS = threading.Lock()


def _one_torch_thread_in_forked_child() -> None:
    """Torch on one intra-op thread in a process forked from this one (``AsyncVectorEnv``, ``SubprocVecEnv``
    with ``fork``): torch's OpenMP threads do not survive a fork, and the child's first parallel torch call
    would wait for them forever once the parent has made one (the parent makes an environment before
    forking). One thread per worker process is what process-parallel environments want anyway."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


os.register_at_fork(after_in_child=_one_torch_thread_in_forked_child)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with the BLAS libraries loaded for numpy and scipy on one thread each (the thread counts
    they had are restored on leaving); PyTorch's own threads are left alone."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def split_calls(n: int, batch_size: int, workers: int, min_weeks: int = MIN_WEEKS_PER_CALL) -> list[slice]:
    """Consecutive slices covering ``range(n)`` weeks: at most ``batch_size`` weeks each (unless ``batch_size`` is
    under ``min_weeks``), at least ``workers`` of them where each can still hold ``min_weeks``, their sizes within
    one of each other; no slices for ``n = 0``."""
    if n <= 0:
        return []
    if batch_size < 1:
        raise ValueError(f"batch_size must be at least 1, got {batch_size}")
    calls = max(-(-n // batch_size), min(workers, n // min_weeks), 1)
    edges = [i * n // calls for i in range(calls + 1)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


class MetamodelWorkers:
    """Threads that run model calls side by side, each with torch on one intra-op thread.

    ``workers=None`` takes torch's intra-op thread count at each :meth:`run` (the cores, unless the user set
    ``torch.set_num_threads``); 1 runs every call in the caller's thread, as torch alone would. The threads are
    made on the first split call and kept (a thread's first model call costs more than the next ones).
    """

    def __init__(self, workers: int | None = None):
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.workers = workers
        self._pool: ThreadPoolExecutor | None = None
        self._pool_size = 0
        self._pool_pid = 0  # a forked child has none of its parent's threads: it makes its own

    def count(self) -> int:
        """Workers a call would use now."""
        import torch

        return self.workers if self.workers is not None else torch.get_num_threads()

    def run(self, calls: list[slice], work: Callable[[slice], None]) -> None:
        """``work(call)`` for every call (under ``torch.inference_mode``), spread over the workers; the first
        error raised by a call is raised here once every call has ended."""
        import torch

        workers = min(self.count(), len(calls))
        if workers < 2:
            with torch.inference_mode():
                for call in calls:
                    work(call)
            return

        def one(call: slice) -> None:
            with torch.inference_mode():
                work(call)

        with _TORCH_THREADS:
            if self._pool is None or self._pool_size != workers or self._pool_pid != os.getpid():
                if self._pool is not None and self._pool_pid == os.getpid():
                    self._pool.shutdown()
                self._pool = ThreadPoolExecutor(workers, thread_name_prefix="buildenv-metamodel")
                self._pool_size, self._pool_pid = workers, os.getpid()
            threads = torch.get_num_threads()
            torch.set_num_threads(1)  # read by each worker thread on its first call, and by none after
            try:
                futures = [self._pool.submit(one, call) for call in calls]
                errors = [f.exception() for f in futures]
            finally:
                torch.set_num_threads(threads)
        for error in errors:
            if error is not None:
                raise error
