"""Orchestration: config → grid → kernels in chunks → Dataset → NetCDF.

Knows about chunks and threads, never about friction. Every system is integrated
independently and deterministically, so results do not depend on the chunk size
or the number of threads.
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from . import accelerate
from .config import check_writable
from .dataset import build_dataset, write_netcdf
from .grid import physical_parameters, system_arrays
from .progress import Progress


@dataclass
class SweepResult:
    """What a finished sweep hands back: the Dataset, where it went, how long it took (s)."""

    dataset: object
    path: object
    elapsed: float


def default_chunk_size(n_systems, n_threads):
    """Chunks small enough for regular progress, large enough to keep threads busy."""
    return max(16 * n_threads, math.ceil(n_systems / 100))


def integrate_chunks(params, y0, settings, threads=None, chunk_size=None, progress=None):
    """Integrate all systems chunk by chunk on numba threads.

    Returns ``(results, y_final)``. Within a chunk, systems are handed to threads
    one at a time (dynamic scheduling), since run lengths differ by orders of
    magnitude between steady and runaway runs.
    """
    import numba

    from .kernels import N_RESULTS, integrate_grid_parallel

    n = params.shape[0]
    n_threads = accelerate.set_threads(threads)
    chunk = chunk_size or default_chunk_size(n, n_threads)
    results = np.empty((n, N_RESULTS))
    y_final = np.empty_like(y0)
    old = numba.set_parallel_chunksize(1)
    try:
        for start in range(0, n, chunk):
            sl = slice(start, min(start + chunk, n))
            integrate_grid_parallel(params[sl], y0[sl], settings, results[sl], y_final[sl])
            if progress is not None:
                progress.update(sl.stop - sl.start)
    finally:
        numba.set_parallel_chunksize(old)
    return results, y_final


def compute(config, threads=None, chunk_size=None, show_progress=True):
    """Run every system of ``config`` and return the result Dataset (nothing written)."""
    phys = physical_parameters(config)
    params, y0, settings, time_unit = system_arrays(config, phys)
    progress = Progress(params.shape[0], desc=config.name, enabled=show_progress)
    try:
        results, y_final = integrate_chunks(params, y0, settings, threads, chunk_size, progress)
    finally:
        progress.close()
    return build_dataset(config, phys, results, y_final, time_unit)


def run_sweep(config, out=None, threads=None, chunk_size=None, show_progress=True):
    """Run ``config`` and write its result to ``out`` (default: the config's output)."""
    path = out or config.output
    check_writable(path, config.source, "output" if out is None else "--out")
    start = time.perf_counter()
    ds = compute(config, threads, chunk_size, show_progress)
    write_netcdf(ds, path)
    return SweepResult(ds, path, time.perf_counter() - start)
