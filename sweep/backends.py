"""Where the chunks run: numba threads on this machine, or Dask tasks on a cluster.

Both backends offer the same small protocol, so the runner does not care which
one it has:

* ``compile()``: compile (or load from numba's cache) the grid kernel it calls,
  in this process, before any chunk runs;
* ``run(params, y0, settings, ranges, stop)``: integrate row ``ranges`` of the
  kernels' arrays, yielding ``(start, stop, results, y_final)`` per range as each
  finishes;
* ``threads``: the threads that work on the chunks (for chunk sizes and logs).

Threads have one owner (``sweep/accelerate.py``): :class:`NumbaThreads` calls the
parallel grid kernel (``prange`` owns the cores); :class:`DaskTasks` submits the
serial one as tasks (``sweep/distributed.py``) and Dask owns the threads.
"""

import logging
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from . import accelerate

log = logging.getLogger(__name__)

#: Numba signature of the grid kernels as the backends call them (C-contiguous float64).
GRID_SIGNATURE = (
    "(float64[:, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1])"
)


@dataclass(frozen=True)
class Resources:
    """What a run may use: ``threads`` numba threads (None: all cores), or Dask: the
    scheduler at ``scheduler`` (an address, a Client or a Cluster) or a new LocalCluster
    of ``dask_local`` single-threaded worker processes."""

    threads: int = None
    scheduler: object = None
    dask_local: int = None

    @property
    def dask(self):
        """Whether the chunks run as Dask tasks."""
        return self.scheduler is not None or self.dask_local is not None


def compile_grid_kernel(kernel):
    """Compile (or load from the numba cache) a grid kernel for :data:`GRID_SIGNATURE`.

    Says "compiling kernels (first run only)" when that takes longer than a second
    (a cold cache; loading a warm one takes about a second). Nothing to do under
    ``NUMBA_DISABLE_JIT=1``, where kernels are plain Python.
    """
    if not hasattr(kernel, "compile"):
        return
    notice = threading.Timer(1.0, log.info, ("compiling kernels (first run only) ...",))
    notice.start()
    try:
        kernel.compile(GRID_SIGNATURE)
    finally:
        notice.cancel()


def load_kernels(parallel=False):
    """Load (or compile) the serial grid kernel in this process, e.g. on every Dask
    worker; with ``parallel``, the threaded one as well (to warm the cache before job
    arrays)."""
    from . import kernels

    compile_grid_kernel(kernels.integrate_grid_serial)
    if parallel:
        compile_grid_kernel(kernels.integrate_grid_parallel)


class NumbaThreads:
    """Chunks on numba's thread pool: ``prange`` over the systems of each chunk."""

    def __init__(self, threads=None):
        self.threads = accelerate.thread_count(threads)
        self._asked = threads

    def __str__(self):
        return "numba threads"

    def compile(self):
        from . import kernels

        compile_grid_kernel(kernels.integrate_grid_parallel)

    def run(self, params, y0, settings, ranges, stop=None):
        """Integrate ``ranges`` of systems one after another; yield each as it finishes.

        Each chunk's rows are shuffled (:func:`balanced_order`) so that threads share
        the costly runs; run lengths differ by orders of magnitude between steady and
        runaway runs. ``stop`` is checked by the caller between chunks.
        """
        from .kernels import N_RESULTS, integrate_grid_parallel

        accelerate.set_threads(self._asked)
        for a, b in ranges:
            order = balanced_order(b - a)  # row a + order[j] is computed in place j
            shuffled = np.empty((b - a, N_RESULTS)), np.empty((b - a, y0.shape[1]))
            integrate_grid_parallel(params[a + order], y0[a + order], settings, *shuffled)
            results, y_final = np.empty_like(shuffled[0]), np.empty_like(shuffled[1])
            results[order], y_final[order] = shuffled
            yield a, b, results, y_final


class DaskTasks:
    """Chunks as tasks of a Dask ``client``, each calling the serial grid kernel."""

    def __init__(self, client):
        self.client = client

    def __str__(self):
        return f"Dask ({self.threads} threads)"

    @property
    def threads(self):
        """Total threads over the cluster's current workers (adaptive clusters change)."""
        from .distributed import worker_threads

        return worker_threads(self.client)

    def compile(self):
        """Compile the serial kernel here, before any task, so only this process writes
        numba's cache (numba#4807); workers on the same machine then load it."""
        load_kernels()

    def run(self, params, y0, settings, ranges, stop=None):
        """Integrate ``ranges`` as Dask tasks; yield each in completion order."""
        from .distributed import submit_chunks

        return submit_chunks(self.client, params, y0, settings, ranges, stop)


def balanced_order(n_rows):
    """A fixed shuffle of ``n_rows`` rows that spreads costly runs over the threads.

    Costly runs (slow decay or growth near Kc) sit next to each other in the grid,
    and numba's OpenMP layer splits a ``prange`` into equal contiguous blocks
    (``numba.set_parallel_chunksize(1)`` made no difference there): on
    ``configs/twoblock.yaml`` two threads were 1.15x faster than one in grid
    order and 1.85x after this shuffle. Every system is integrated
    independently, so the numbers do not change; only the order in which the
    threads meet them does.
    """
    return np.random.default_rng(0).permutation(n_rows)


@contextmanager
def open_backend(resources=None, client=None):
    """The backend for ``resources`` (default: all numba threads), open for the block.

    ``client``: an open Dask client to use instead (left open). A Dask backend
    connects first (:func:`sweep.distributed.connect`) and closes what it opened.
    """
    resources = resources or Resources()
    if client is not None:
        yield DaskTasks(client)
    elif resources.dask:
        from .distributed import connect

        with connect(resources.scheduler, resources.dask_local) as opened:
            yield DaskTasks(opened)
    else:
        yield NumbaThreads(resources.threads)
