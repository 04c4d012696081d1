"""Dask glue: connect to a cluster and run a sweep's chunks on it as tasks.

Dask is imported lazily, so the core package does not need it. Each task
integrates one chunk with the *serial* grid kernel: the kernels release the
GIL and Dask owns the threads (one numba thread pool per worker process would
fight Dask for the cores). Results come back to the client, which writes the
parts, so workers need no shared file system; they do need the ``sweep``
package importable (``pip install rsf-sweep[distributed]`` or ``-e .``).

Before any task is submitted, the parent compiles the serial kernel
(``backends.DaskTasks.compile``), so the numba cache on disk is written by one
process only (concurrent writers can crash, numba#4807); workers on the same
machine and CPU then load it.
"""

import logging
from contextlib import contextmanager

import numpy as np

from ..errors import InputError, RunError

log = logging.getLogger(__name__)

#: Seconds between checks for a stop request while waiting for tasks.
POLL = 0.5


def chunk_task(params, y0, settings):
    """Task body: integrate the systems of one chunk one after another.

    Arguments as for ``dispatch.integrate_grid``; arrays arriving from
    the network may be read-only or strided, and are made C-contiguous and
    writable so the kernel's compiled signature (and cache entry) is reused.
    Returns ``(results, y_final)``.
    """
    from ..kernels.layout import result_width
    from .dispatch import integrate_grid

    params, y0, settings = (np.require(a, np.float64, ["C", "W"]) for a in (params, y0, settings))
    results = np.empty((params.shape[0], result_width(settings)))
    y_final = np.empty_like(y0)
    integrate_grid(params, y0, settings, results, y_final)
    return results, y_final


@contextmanager
def connect(scheduler=None, local_workers=None):
    """A Dask client: for ``scheduler``, or to a new LocalCluster.

    ``scheduler``: a scheduler address (``"tcp://host:8786"``), a running
    ``distributed.Client`` (used as it is and left open) or a Cluster (e.g. a
    ``LocalCluster``; a client is opened on it and closed after).
    ``local_workers``: number of single-threaded worker processes of a new
    LocalCluster. Logs the dashboard link when there is one. Raises
    :class:`~sweep.errors.RunError` if Dask is missing or the scheduler cannot be
    reached (the connect timeout is Dask's ``distributed.comm.timeouts.connect``,
    e.g. env ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=10s``), and
    :class:`~sweep.errors.InputError` for a ``scheduler`` of another type.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise RunError(
            "Dask is not installed; install it with pip install 'rsf-sweep[distributed]'"
        ) from None
    cluster = None
    if isinstance(scheduler, Client):
        client, owned = scheduler, False
    elif scheduler is not None:
        client, owned = _open_client(Client, scheduler), True
    else:
        cluster = LocalCluster(
            n_workers=local_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        client, owned = Client(cluster), True
    link = dashboard_link(client)
    if link:
        log.info("Dask dashboard: %s", link)
    try:
        yield client
    finally:
        if owned:
            client.close()
        if cluster is not None:
            cluster.close()


def _open_client(Client, scheduler):
    """A new Client on a scheduler address or a Cluster; errors in the tool's terms."""
    is_cluster = hasattr(scheduler, "scheduler_address")
    if not isinstance(scheduler, str) and not is_cluster:
        raise InputError(
            "client",
            [
                f"must be a dask distributed Client, a Cluster or a scheduler address such as "
                f"'tcp://host:8786'; got {type(scheduler).__name__}"
            ],
        )
    try:
        return Client(scheduler)
    except (OSError, ValueError, TypeError) as exc:
        where = getattr(scheduler, "scheduler_address", scheduler)
        raise RunError(f"cannot reach the Dask scheduler at {where}: {exc}") from None


def dashboard_link(client):
    """The URL of the Dask dashboard of ``client``'s scheduler, or None without one."""
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # a scheduler that does not answer has no link to give
        return None
    return client.dashboard_link if "dashboard" in services else None


def worker_threads(client):
    """Total threads over the cluster's current workers."""
    return sum(client.nthreads().values())


def submit_chunks(client, params, y0, settings, ranges, stop=None):
    """Integrate ``ranges`` of systems as Dask tasks; yield results as they finish.

    Yields ``(start, stop, results, y_final)`` per range, in completion order.
    At most a few tasks per worker thread are in flight, so the client's memory
    does not hold a second copy of the whole grid. ``stop`` (a
    :class:`~sweep.engine.run_control.StopRequest`) is checked every ``POLL`` seconds;
    when set, unfinished tasks are cancelled and the generator returns.
    """
    from distributed import wait

    todo = list(reversed(ranges))
    flying = {}
    try:
        while todo or flying:
            # (asked again each round: adaptive clusters grow and shrink)
            window = max(8, 4 * worker_threads(client)) if todo else 0
            while todo and len(flying) < window:
                a, b = todo.pop()
                future = client.submit(chunk_task, params[a:b], y0[a:b], settings, pure=False)
                flying[future] = (a, b)
            try:
                done = wait(list(flying), timeout=POLL, return_when="FIRST_COMPLETED").done
            except TimeoutError:
                done = ()
            for future in done:
                a, b = flying.pop(future)
                try:
                    results, y_final = future.result()
                except ImportError as exc:
                    raise RunError(
                        f"a Dask worker cannot import the sweep package ({exc}); install it "
                        "in the workers' environment"
                    ) from None
                yield a, b, results, y_final
            if stop:
                return
    finally:
        client.cancel(list(flying))
