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
(``sweep/engine/distributed.py``) and Dask owns the threads.
"""

import logging
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from .. import accelerate
from .dispatch import integrate_grid, load_kernel

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Resources:
    """What a run may use: threads on this machine, or Dask.

    Give at most one of ``scheduler`` and ``dask_local``; with neither, the chunks
    run on ``threads`` local threads.

    Parameters
    ----------
    threads : int, optional
        Threads on this machine (default: all cores).
    scheduler : str, distributed.Client or Cluster, optional
        Run the chunks as Dask tasks on this scheduler (an address such as
        ``"tcp://host:8786"``, a Client or a Cluster).
    dask_local : int, optional
        Run them on a new LocalCluster of this many single-threaded worker
        processes.
    """

    threads: int | None = None
    scheduler: object = None
    dask_local: int | None = None

    @property
    def dask(self) -> bool:
        """Whether the chunks run as Dask tasks."""
        return self.scheduler is not None or self.dask_local is not None


#: Systems per batch a thread takes as it comes free: small, so that the costly runs
#: near Kc, which sit next to each other in the grid, are shared out, yet large
#: against the ~10 µs a kernel call costs in Python. 8 gave the best 2-thread speed-up
#: of the sizes measured (docs/internals.md, "Threads"). Small chunks get smaller
#: batches, at least four per thread.
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
        """Integrate ``ranges`` of systems; yield ``(start, stop, results, y_final)`` for
        each, in order, as soon as it and those before it are done.

        One thread calls the kernel once per range (signals reach Python when it
        returns). Several threads take batches from every range in turn, with no
        barrier at the end of a range: while one thread finishes the last batch of a
        range, the others start on the next. ``stop`` is checked by the caller
        between ranges; closing this generator abandons the batches not yet started
        and waits for the running ones.
        """
        if self.threads == 1:
            for a, b in ranges:
                res, yf = _outputs(b - a, y0.shape[1], settings)
                if b > a:
                    integrate_grid(params[a:b], y0[a:b], settings, res, yf)
                yield a, b, res, yf
            return
        batches = list(_batches(ranges, self.threads))
        left = [0] * len(ranges)  # batches of each range not yet done
        for k, _, _ in batches:
            left[k] += 1
        batches = iter(batches)
        out = [None] * len(ranges)
        done = [threading.Event() for _ in ranges]
        lock = threading.Lock()
        abandon = threading.Event()
        failures = []

        def work():
            while not abandon.is_set():
                with lock:
                    k, lo, hi = next(batches, (None, 0, 0))
                    if k is not None and out[k] is None:
                        out[k] = _outputs(ranges[k][1] - ranges[k][0], y0.shape[1], settings)
                if k is None:
                    return
                res, yf = out[k]
                a = ranges[k][0]
                try:
                    integrate_grid(
                        params[lo:hi],
                        y0[lo:hi],
                        settings,
                        res[lo - a : hi - a],
                        yf[lo - a : hi - a],
                    )
                except BaseException as exc:  # raised again by the generator
                    failures.append(exc)
                    abandon.set()
                    for event in done:
                        event.set()
                    return
                with lock:
                    left[k] -= 1
                    if left[k] == 0:
                        done[k].set()

        pool = [threading.Thread(target=work, daemon=True) for _ in range(self.threads)]
        for thread in pool:
            thread.start()
        try:
            for k, (a, b) in enumerate(ranges):
                if left[k]:
                    done[k].wait()
                if failures:
                    raise failures[0]
                res, yf = out[k] or _outputs(0, y0.shape[1], settings)
                out[k] = None  # the caller keeps its copy
                yield a, b, res, yf
        finally:
            abandon.set()
            for thread in pool:
                thread.join()


def _batches(ranges, threads):
    """``(range index, first row, end row)`` of every batch, range after range:
    :data:`BATCH` systems, fewer in a small range (at least four batches per thread)."""
    for k, (a, b) in enumerate(ranges):
        size = max(1, min(BATCH, (b - a) // (4 * threads)))
        for lo in range(a, b, size):
            yield k, lo, min(lo + size, b)


def _outputs(n, n_vars, settings):
    """Empty ``(results, y_final)`` for ``n`` systems of ``n_vars`` state variables."""
    from ..kernels.layout import result_width

    return np.empty((n, result_width(settings))), np.empty((n, n_vars))


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
        """Compile the serial kernels here, before any task, so only this process writes
        numba's cache (numba#4807); workers on the same machine then load them."""
        load_kernel(params, settings, every=True)

    def run(self, params, y0, settings, ranges, stop=None):
        """Integrate ``ranges`` as Dask tasks; yield each in completion order."""
        from .distributed import submit_chunks

        return submit_chunks(self.client, params, y0, settings, ranges, stop)


@contextmanager
def open_backend(resources=None, client=None):
    """The backend for ``resources`` (default: threads on all cores), open for the block.

    ``client``: an open Dask client to use instead (left open). A Dask backend
    connects first (:func:`sweep.engine.distributed.connect`) and closes what it opened.
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
