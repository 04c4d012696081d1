"""Where the chunks run: threads on this machine, or Dask tasks on a cluster.

Both backends offer the same small protocol, so the runner does not care which
one it has:

* ``compile(params, settings)``: compile (or load from numba's cache) the grid
  kernel of the run's variant, in this process, before any chunk runs;
* ``run(params, y0, settings, ranges, stop)``: integrate row ``ranges`` of the
  kernels' arrays, yielding ``(start, stop, results, y_final)`` per range as each
  finishes;
* ``threads``: the threads that work on the chunks (for chunk sizes and logs).

Both call the same serial grid kernel, and threads have one owner
(``sweep/accelerate.py``): :class:`LocalThreads` runs it on its own Python threads
(the kernel releases the GIL); :class:`DaskTasks` submits it as tasks
(``sweep/distributed.py``) and Dask owns the threads.
"""

import logging
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from . import accelerate
from .dispatch import integrate_grid, load_kernel

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Resources:
    """What a run may use: ``threads`` threads on this machine (None: all cores), or Dask: the
    scheduler at ``scheduler`` (an address, a Client or a Cluster) or a new LocalCluster
    of ``dask_local`` single-threaded worker processes."""

    threads: int = None
    scheduler: object = None
    dask_local: int = None

    @property
    def dask(self):
        """Whether the chunks run as Dask tasks."""
        return self.scheduler is not None or self.dask_local is not None


#: Systems per batch a thread takes as it comes free: small, so that the costly runs
#: near Kc, which sit next to each other in the grid, are shared out, yet large
#: against the ~10 µs a kernel call costs in Python. 2-thread speed-up on a 10⁴-point
#: one-block sweep (benchmarks/bench.py): batches of 4: 1.65-1.67x; 8: 1.86x;
#: 16: 1.78-1.84x; 64: 1.40x (each chunk waits for its slowest batch). Small chunks
#: get smaller batches, at least four per thread.
BATCH = 8


class LocalThreads:
    """Chunks on this machine: ``threads`` Python threads call the grid kernel on
    batches of :data:`BATCH` systems, each taking the next batch as it comes free."""

    def __init__(self, threads=None):
        self.threads = accelerate.thread_count(threads)

    def __str__(self):
        return "threads"

    def compile(self, params, settings):
        load_kernel(params, settings)

    def run(self, params, y0, settings, ranges, stop=None):
        """Integrate ``ranges`` of systems one after another; yield each as it finishes.

        ``stop`` is checked by the caller between chunks.
        """
        for a, b in ranges:
            yield (a, b, *integrate_rows(params[a:b], y0[a:b], settings, self.threads))


def integrate_rows(params, y0, settings, threads):
    """``(results, y_final)`` of every row, computed by the grid kernel on ``threads``
    threads, each taking the next batch of rows (:data:`BATCH`, fewer for small
    chunks) as it comes free."""
    from .kernels import N_RESULTS

    n = params.shape[0]
    results, y_final = np.empty((n, N_RESULTS)), np.empty_like(y0)
    # one thread: one call (signals reach Python when it returns, as documented)
    size = max(1, n) if threads == 1 else max(1, min(BATCH, n // (4 * threads)))
    batches = iter(range(0, n, size))
    take = threading.Lock()

    def work():
        while True:
            with take:
                lo = next(batches, None)
            if lo is None:
                return
            hi = min(lo + size, n)
            integrate_grid(params[lo:hi], y0[lo:hi], settings, results[lo:hi], y_final[lo:hi])

    n_workers = min(threads, -(-n // size))
    if n_workers <= 1:
        work()  # in this thread: signals reach Python between kernel calls
    else:
        with ThreadPoolExecutor(n_workers) as pool:
            for done in [pool.submit(work) for _ in range(n_workers)]:
                done.result()
    return results, y_final


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

    def compile(self, params, settings):
        """Compile the serial kernel here, before any task, so only this process writes
        numba's cache (numba#4807); workers on the same machine then load it."""
        load_kernel(params, settings)

    def run(self, params, y0, settings, ranges, stop=None):
        """Integrate ``ranges`` as Dask tasks; yield each in completion order."""
        from .distributed import submit_chunks

        return submit_chunks(self.client, params, y0, settings, ranges, stop)


@contextmanager
def open_backend(resources=None, client=None):
    """The backend for ``resources`` (default: threads on all cores), open for the block.

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
        yield LocalThreads(resources.threads)
