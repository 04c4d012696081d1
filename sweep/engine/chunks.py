"""Chunks: a grid's rows run chunk by chunk, the finished chunks kept as parts on disk,
the result file written atomically.

The machinery that uniform sweeps (``sweep/engine/runner.py``) and refinements
(``sweep/engine/refined.py``) share.
"""

from __future__ import annotations

import logging
import math
import signal
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import Interrupted, RunError
from ..io import parts as store
from ..kernels.layout import result_width
from ..results.dataset import write_netcdf
from .backends import DaskTasks, LocalThreads
from .grid import settings_array

log = logging.getLogger(__name__)


class StopRequest:
    """Set by a signal handler; the runner stops after the chunk that is running.

    ``signum`` is the signal received (``None`` until then); a second signal
    raises ``KeyboardInterrupt`` at once.
    """

    def __init__(self):
        self.signum = None

    def __bool__(self):
        return self.signum is not None

    def __call__(self, signum, frame):
        if self:
            raise KeyboardInterrupt
        self.signum = signum
        log.warning(
            "received %s: stopping after the chunks in progress (again to stop at once)",
            signal.Signals(signum).name,
        )


@contextmanager
def stop_on_signals(signums=(signal.SIGINT, signal.SIGTERM)):
    """Within the block, SIGINT/SIGTERM set the yielded :class:`StopRequest`.

    For command-line use: nothing is installed on import.
    """
    stop = StopRequest()
    old = {s: signal.signal(s, stop) for s in signums}
    try:
        yield stop
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


@dataclass
class SweepResult:
    """A finished sweep or shard.

    ``dataset``: the result (``None`` for a shard); ``path``: the NetCDF file
    written, or for a shard its parts folder; ``elapsed``: wall time (s);
    ``computed`` / ``reused``: runs integrated now / read back from parts;
    ``timings``: for a refinement, wall time (s) by activity (``sweep/engine/refined.py``).
    """

    dataset: object
    path: object
    elapsed: float
    computed: int = 0
    reused: int = 0
    timings: dict = None


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


def run_chunks(backend, params, y0, settings, ranges, results, y_final, progress=None,
               save=None, stop=None):  # fmt: skip
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
    """:func:`run_chunks` of ``grid``'s rows ``ranges`` into ``run`` (a :class:`PartStore`
    or alike), each finished chunk saved by ``run.save``; ``progress`` is closed after,
    and a ``KeyboardInterrupt`` stops the run like a first SIGINT (``stop``)."""
    try:
        run_chunks(backend, grid.params, grid.y0, grid.settings, ranges, run.results,
                   run.y_final, progress, run.save, stop)  # fmt: skip
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
        log.warning("%s%s came after every chunk had finished", where,
                    signal.Signals(stop.signum).name)  # fmt: skip
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


def fill_from_parts(entries, run, have, wanted):
    """Rows ``wanted`` and not yet ``have`` read from the parts ``entries`` (one hash,
    ``store.scan``) into ``run``'s arrays; ``have`` is updated. Unusable parts are
    reported and removed, so their runs are computed again. Returns the parts read."""
    used, bad = store.fill_from_parts(entries, run.results, run.y_final, have, wanted)
    for path, reason in bad:
        log.warning("unusable part, its runs will be recomputed: %s", reason)
        path.unlink(missing_ok=True)
    return used


def rows_missing(gaps):
    """Row ranges (from :func:`missing_ranges`) as said in an error: the first five."""
    return ", ".join(f"{a}:{b}" for a, b in gaps[:5]) + (" ..." if len(gaps) > 5 else "")


def integrate_in_memory(params, y0, settings, threads=None, chunk_size=None, progress=None,
                        backend=None):  # fmt: skip
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
    run_chunks(backend, params, y0, settings, chunk_ranges(n, chunk_size), results, y_final,
               progress)  # fmt: skip
    return results, y_final


class PartStore:
    """The result arrays of a run and the parts folder each finished chunk is saved to;
    parts are named by ``chash`` (default: the config's hash)."""

    def __init__(self, folder, config, n, n_vars, chash=None):
        self.folder = folder
        self.config = config
        self.chash = chash or store.config_hash(config)
        self.n = n
        self.results = np.empty((n, result_width(settings_array(config))))
        self.y_final = np.empty((n, n_vars))
        self.saved = 0

    def save(self, a, b):
        """Write rows ``a:b`` as a part; a failure is a :class:`RunError` saying what is kept."""
        try:
            store.write_part(self.folder, self.config, self.chash, a, b, self.n,
                             self.results[a:b], self.y_final[a:b])  # fmt: skip
        except OSError as exc:
            raise RunError(
                f"cannot write a part to {self.folder}: {exc.strerror or exc}; the parts "
                "written so far are kept, rerun with --resume once this is fixed"
            ) from None
        self.saved += b - a


def count_rows(ranges):
    return sum(b - a for a, b in ranges)


def chunk_size_for(n, backend, shard):
    """Chunk size for this run: per backend, or (shards) from the grid size alone."""
    if shard:
        return default_chunk_size(n)
    if isinstance(backend, DaskTasks):
        return default_chunk_size(n, dask_threads=max(1, backend.threads))
    return default_chunk_size(n, backend.threads)


def make_parts_folder(parts_dir):
    try:
        parts_dir.mkdir(exist_ok=True)
    except OSError as exc:
        raise RunError(
            f"cannot create the parts folder {parts_dir}: {exc.strerror or exc}"
        ) from None


def write_result(ds, path, kept):
    """Write the NetCDF atomically; on failure say what is kept (``kept``) and how to go on."""
    try:
        write_netcdf(ds, path)
    except (OSError, RuntimeError) as exc:
        raise RunError(
            f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}; the finished "
            f"chunks stay in {kept}, rerun once this is fixed"
        ) from None


def remove_merged(used, paths):
    """After a merge: remove the parts ``used``, then in the folders of ``paths`` the
    temporary files of killed writers, then those folders if empty."""
    for f in used:
        f.unlink()
    for folder in {Path(p) for p in paths if Path(p).is_dir()}:
        for f in store.stale_temp_files(folder):
            f.unlink(missing_ok=True)
        if not any(folder.iterdir()):
            folder.rmdir()
