"""The numerical libraries' thread pools while the metamodel runs.

numpy's BLAS (OpenBLAS) and PyTorch (OpenMP) each keep a pool of worker threads, which spin for a while after a
call before they sleep. Calibration and diagnosis alternate the two thousands of times (a CMA-ES step in numpy,
then a batch of weeks through the metamodel in torch), and on a 2-core machine the two pools fight for the cores.
Measured on 2 cores, one 8-week site (seed 12 case 6 of the blind check, clean) diagnosed with the checks'
settings: 249 s with both pools at two threads, 49 s with torch at one, 32 s with numpy's BLAS at one and torch
at two, with the same verdict and scores in all three. The metamodel alone runs faster on two threads (5,900
against 3,800 weeks/s in batches of 256), while the matrices numpy handles here are small (CMA-ES's covariance
of a few dozen parameters), so BLAS gets one thread and torch keeps its own.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with the BLAS libraries loaded for numpy and scipy on one thread each (the thread counts
    they had are restored on leaving); PyTorch's own threads are left alone."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
