"""Chunks: a grid's rows run chunk by chunk on a backend, each finished chunk handed to
a sink (``sweep.io.parts.PartStore``) as it comes.

The machinery that uniform sweeps (``sweep/engine/uniform.py``) and refinements
(``sweep/engine/refined.py``) share.
"""

from __future__ import annotations

import logging
import math
import signal
from contextlib import closing

import numpy as np

from ..errors import Interrupted
from ..kernels.layout import result_width
from .backends import DaskTasks, LocalThreads

log = logging.getLogger(__name__)


def default_chunk_size(n_systems, n_threads=1, dask_threads=0):
    """Systems per chunk when none is given.

    On local threads: at least 16 systems per thread (runs differ in length by
    orders of magnitude; threads share a chunk's systems out in batches), and at
    most about 100 chunks. On Dask (``dask_threads`` > 0, the cluster's
    total threads): at least 4 tasks per thread and about 100 in all.
    """
    if dask_threads:
        return max(1, math.ceil(n_systems / max(100, 4 * dask_threads)))
    return max(16 * n_threads, math.ceil(n_systems / 100))


def chunk_ranges(n_systems, chunk_size, shard=(0, 1)):
    """Row ranges ``(start, stop)`` of the chunks owned by ``shard = (i, n_shards)``."""
    i, n_shards = shard
    starts = range(i * chunk_size, n_systems, n_shards * chunk_size)
    return [(a, min(a + chunk_size, n_systems)) for a in starts]


def missing_ranges(ranges, have):
    """Sub-ranges of ``ranges`` whose rows are not yet in ``have`` (boolean mask)."""
    out = []
    for a, b in ranges:
        missing = np.flatnonzero(~have[a:b]) + a
        if missing.size:
            breaks = np.flatnonzero(np.diff(missing) > 1)
            firsts = np.concatenate(([missing[0]], missing[breaks + 1]))
            lasts = np.concatenate((missing[breaks], [missing[-1]]))
            out.extend((int(f), int(t) + 1) for f, t in zip(firsts, lasts, strict=True))
    return out


def run_chunks(
    backend, params, y0, settings, ranges, results, y_final, progress=None, save=None, stop=None
):
    """Integrate row ``ranges`` on ``backend`` into ``results``/``y_final`` (rows in place).

    After each chunk: ``save(start, stop)`` (e.g. write a part), then
    ``progress.update``. Stops early, between chunks, once ``stop`` is set. The
    caller compiles the backend's kernel first (``backend.compile``).
    """
    chunks = backend.run(params, y0, settings, ranges, stop)
    with closing(chunks):
        for a, b, res, yf in chunks:
            results[a:b] = res
            y_final[a:b] = yf
            if save is not None:
                save(a, b)
            if progress is not None:
                progress.update(b - a)
            if stop:
                break


def run_saving(backend, grid, ranges, run, progress, stop):
    """:func:`run_chunks` of ``grid``'s rows ``ranges`` into ``run`` (a
    :class:`~sweep.io.parts.PartStore` or alike), each finished chunk saved by
    ``run.save``; ``progress`` is closed after, and a ``KeyboardInterrupt`` stops the run
    like a first SIGINT (``stop``)."""
    try:
        run_chunks(
            backend,
            grid.params,
            grid.y0,
            grid.settings,
            ranges,
            run.results,
            run.y_final,
            progress,
            run.save,
            stop,
        )
    except KeyboardInterrupt:
        stop.signum = stop.signum or signal.SIGINT
    finally:
        progress.close()


def check_saved(run, total, left, stop, where=""):
    """Raise :class:`Interrupted` when ``run`` saved fewer than the ``left`` runs it was
    to run (a stop request), saying how many of ``total`` are kept and where; ``where``
    (e.g. ``"level 2: "``) says which part of the work stopped. A stop that came after
    the last chunk had finished stopped nothing here, and says so."""
    if stop and run.saved >= left:
        log.warning(
            "%s%s came after every chunk had finished", where, signal.Signals(stop.signum).name
        )
    if run.saved < left:
        raise Interrupted(
            stop.signum,
            f"interrupted by {signal.Signals(stop.signum).name}: {where}"
            f"{total - left + run.saved} of {total} runs are saved in {run.folder}; rerun "
            "with --resume to continue",
        )


def ranges_mask(n, ranges):
    """A boolean mask over ``n`` rows, true in the row ``ranges``."""
    mask = np.zeros(n, bool)
    for a, b in ranges:
        mask[a:b] = True
    return mask


def rows_missing(gaps):
    """Row ranges (from :func:`missing_ranges`) as said in an error: the first five."""
    return ", ".join(f"{a}:{b}" for a, b in gaps[:5]) + (" ..." if len(gaps) > 5 else "")


def integrate_in_memory(
    params, y0, settings, threads=None, chunk_size=None, progress=None, backend=None
):
    """Integrate every system (row) of the kernels' arrays, chunk by chunk, in memory.

    On ``backend`` (default: :class:`~sweep.engine.backends.LocalThreads` with ``threads``).
    Returns ``(results, y_final)``.
    """
    backend = backend or LocalThreads(threads)
    backend.compile(params, settings)
    n = params.shape[0]
    chunk_size = chunk_size or chunk_size_for(n, backend, shard=None)
    results = np.empty((n, result_width(settings)))
    y_final = np.empty_like(y0)
    run_chunks(
        backend, params, y0, settings, chunk_ranges(n, chunk_size), results, y_final, progress
    )
    return results, y_final


def count_rows(ranges):
    return sum(b - a for a, b in ranges)


def chunk_size_for(n, backend, shard):
    """Chunk size for this run: per backend, or (shards) from the grid size alone."""
    if shard:
        return default_chunk_size(n)
    if isinstance(backend, DaskTasks):
        return default_chunk_size(n, dask_threads=max(1, backend.threads))
    return default_chunk_size(n, backend.threads)
