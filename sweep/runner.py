"""Orchestration: config → grid → kernels in chunks → parts → Dataset → NetCDF.

Knows about chunks, threads and Dask, never about friction. Every system is
integrated independently and deterministically, so results do not depend on
the chunk size, the number of threads or workers, sharding or resumption.

A sweep of ``n`` systems (rows of the C-ordered grid) is cut into chunks of
``chunk_size`` rows. Chunks run on numba's thread pool (``prange`` over the
systems of a chunk) or as Dask tasks (see ``sweep/distributed.py``). Each
finished chunk is saved at once as a part file (``sweep/parts.py``); with
``resume=True`` the rows already saved are read back instead of recomputed.
The NetCDF is written once every row is known, and the parts are removed only
after that. ``shard=(i, n_shards)`` computes only the chunks ``k`` with
``k % n_shards == i`` and leaves them as parts, for job arrays.
"""

import logging
import math
import signal
import threading
import time
from contextlib import closing, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import accelerate, parts
from .config import ConfigError, check_writable, parse_config
from .dataset import build_dataset, write_netcdf
from .grid import physical_parameters, system_arrays
from .kernels import N_RESULTS
from .progress import Progress

log = logging.getLogger(__name__)


#: Numba signature of the grid kernels as the runner calls them (C-contiguous float64).
GRID_SIGNATURE = (
    "(float64[:, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1])"
)


class RunError(RuntimeError):
    """A sweep stopped by its surroundings (disk, cluster), not by its config."""


class Interrupted(RunError):
    """A sweep stopped by a signal; the finished chunks are kept as parts."""

    def __init__(self, signum, message):
        self.signum = int(signum)
        super().__init__(message)


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
    ``computed`` / ``reused``: runs integrated now / read back from parts.
    """

    dataset: object
    path: object
    elapsed: float
    computed: int = 0
    reused: int = 0


def default_chunk_size(n_systems, n_threads=1, dask_threads=0):
    """Systems per chunk when none is given.

    On numba threads: large enough to keep ``n_threads`` busy (runs differ in
    length by orders of magnitude, and every chunk ends with a barrier), small
    enough for about 100 chunks. On Dask (``dask_threads`` > 0, the cluster's
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


def compile_grid_kernel(kernel):
    """Compile (or load from the numba cache) a grid kernel for the runner's signature.

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


def compile_kernels_for(client=None):
    """Compile (or load) the grid kernel a run uses: the parallel one on numba threads,
    the serial one (in this process, before any task) under Dask."""
    from . import kernels

    compile_grid_kernel(
        kernels.integrate_grid_parallel if client is None else kernels.integrate_grid_serial
    )


def threaded_chunks(params, y0, settings, ranges, threads=None):
    """Integrate ``ranges`` of systems on numba threads; yield each as it finishes.

    Yields ``(start, stop, results, y_final)``. Each chunk's rows are shuffled
    (:func:`balanced_order`) so that threads share the costly runs; run lengths
    differ by orders of magnitude between steady and runaway runs.
    """
    from .kernels import integrate_grid_parallel

    accelerate.set_threads(threads)
    for a, b in ranges:
        order = balanced_order(b - a)  # row a + order[j] is computed in place j
        shuffled = np.empty((b - a, N_RESULTS)), np.empty((b - a, y0.shape[1]))
        integrate_grid_parallel(params[a + order], y0[a + order], settings, *shuffled)
        results, y_final = np.empty_like(shuffled[0]), np.empty_like(shuffled[1])
        results[order], y_final[order] = shuffled
        yield a, b, results, y_final


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


def integrate_ranges(params, y0, settings, ranges, results, y_final, threads=None, client=None,
                     progress=None, save=None, stop=None):  # fmt: skip
    """Integrate ``ranges`` of systems into ``results``/``y_final`` (rows in place).

    On numba threads, or as tasks of the Dask ``client``. After each chunk:
    ``save(start, stop)`` (e.g. write a part), then ``progress.update``.
    Stops early, between chunks, once ``stop`` is set. The kernel is compiled (or
    loaded) here first, in this process: under Dask before any task is submitted,
    so only one process writes numba's cache.
    """
    compile_kernels_for(client)
    if client is None:
        chunks = threaded_chunks(params, y0, settings, ranges, threads)
    else:
        from .distributed import dask_chunks

        chunks = dask_chunks(client, params, y0, settings, ranges, stop)
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


def integrate_chunks(params, y0, settings, threads=None, chunk_size=None, progress=None,
                     client=None):  # fmt: skip
    """Integrate all systems in memory, chunk by chunk; return ``(results, y_final)``."""
    n = params.shape[0]
    chunk_size = chunk_size or _default_chunk_size(n, threads, client, shard=None)
    results = np.empty((n, N_RESULTS))
    y_final = np.empty_like(y0)
    ranges = chunk_ranges(n, chunk_size)
    integrate_ranges(params, y0, settings, ranges, results, y_final, threads, client, progress)
    return results, y_final


def compute(config, threads=None, chunk_size=None, show_progress=True, client=None,
            command="run"):  # fmt: skip
    """Run every system of ``config`` and return the result Dataset (nothing written).

    ``command``: what is running it, for the file's ``history`` (``dataset.provenance``).
    """
    phys = physical_parameters(config)
    params, y0, settings, time_unit = system_arrays(config, phys)
    # compiled here, not first in integrate_ranges: before the progress clock
    compile_kernels_for(client)
    progress = Progress(params.shape[0], desc=config.name, enabled=show_progress)
    try:
        results, y_final = integrate_chunks(
            params, y0, settings, threads, chunk_size, progress, client
        )
    finally:
        progress.close()
    return build_dataset(config, phys, results, y_final, time_unit, command)


def time_compute(config, threads=None, chunk_size=None, client=None):
    """Wall time (s) to compute ``config`` in memory, kernels compiled beforehand.

    For benchmarks: compare thread counts, or threads against a Dask ``client``.
    """

    compile_kernels_for(client)
    start = time.perf_counter()
    compute(config, threads, chunk_size, show_progress=False, client=client)
    return time.perf_counter() - start


def _dask_threads(client):
    from .distributed import worker_threads

    return worker_threads(client)


def _backend(scheduler, dask_local):
    """A Dask client context for ``scheduler``/``dask_local``, or ``None`` for numba threads."""
    if scheduler is None and dask_local is None:
        return nullcontext(None)
    from .distributed import connect

    return connect(scheduler, dask_local)


def run_sweep(config, out=None, threads=None, chunk_size=None, show_progress=True, resume=False,
              scheduler=None, dask_local=None, shard=None, stop=None):  # fmt: skip
    """Run ``config``, saving each chunk as a part, and write the NetCDF result.

    Parameters
    ----------
    config : Config
    out : path, optional
        NetCDF output (default: the config's ``output``); parts go to
        ``<out without .nc>.parts/``.
    threads : int, optional
        numba threads (default: all); not used with Dask.
    chunk_size : int, optional
        Systems per chunk (default: :func:`default_chunk_size`; with ``shard``,
        one that depends on the grid size only, so all shards agree).
    resume : bool
        Reuse the rows of valid parts of this config instead of recomputing them.
    scheduler : str, optional
        Address of a running Dask scheduler to run the chunks on.
    dask_local : int, optional
        Start a Dask LocalCluster of this many worker processes.
    shard : (i, n_shards), optional
        Compute only chunks ``k`` with ``k % n_shards == i`` and keep them as
        parts (no NetCDF); combine with ``merge_parts`` or a later full run.
    stop : StopRequest, optional
        Checked between chunks; when set, raise :class:`Interrupted`.

    Raises ``ConfigError`` for an output that cannot be written, ``RunError``
    when the disk or the cluster fails and ``Interrupted`` after a stop; in
    every case an earlier result file is left as it was.
    """
    start_time = time.perf_counter()
    path = Path(out or config.output)
    check_writable(path, config.source, "output" if out is None else "--out")
    with _output_lock(path, shared=bool(shard)):
        phys = physical_parameters(config)
        params, y0, settings, time_unit = system_arrays(config, phys)
        n = params.shape[0]
        chash = parts.config_hash(config)
        parts_dir = parts.parts_dir_for(path)
        results = np.empty((n, N_RESULTS))
        y_final = np.empty_like(y0)
        stop = stop if stop is not None else StopRequest()
        saved = 0

        def save(a, b):
            nonlocal saved
            try:
                parts.write_part(parts_dir, config, chash, a, b, n, results[a:b], y_final[a:b])
            except OSError as exc:
                raise RunError(
                    f"cannot write a part to {parts_dir}: {exc.strerror or exc}; the parts "
                    "written so far are kept, rerun with --resume once this is fixed"
                ) from None
            saved += b - a

        with _backend(scheduler, dask_local) as client:
            _make_folder(parts_dir)
            chunk_size = chunk_size or _default_chunk_size(n, threads, client, shard)
            owned = chunk_ranges(n, chunk_size, shard or (0, 1))
            have = _reuse_parts(parts_dir, chash, owned, results, y_final, resume)
            todo = missing_ranges(owned, have)
            total, left = _rows(owned), _rows(todo)
            where = "numba threads" if client is None else f"Dask ({_dask_threads(client)} threads)"
            log.info(
                "%s: computing %d runs in %d chunks on %s", config.name, left, len(todo), where
            )
            # compiled here, not first in integrate_ranges: before the progress clock
            compile_kernels_for(client)
            progress = Progress(total, config.name, enabled=show_progress, initial=total - left)
            try:
                integrate_ranges(params, y0, settings, todo, results, y_final, threads, client,
                                 progress, save, stop)  # fmt: skip
            except KeyboardInterrupt:
                stop.signum = stop.signum or signal.SIGINT
            finally:
                progress.close()
        if saved < left:
            raise Interrupted(
                stop.signum,
                f"interrupted by {signal.Signals(stop.signum).name}: {total - left + saved} of "
                f"{total} runs are saved in {parts_dir}; rerun with --resume to continue",
            )
        elapsed = time.perf_counter() - start_time
        if shard:
            return SweepResult(None, parts_dir, elapsed, saved, total - left)
        ds = build_dataset(config, phys, results, y_final, time_unit)
        _write_result(ds, path, f"{parts_dir} (use --resume)")
        parts.remove_parts(parts_dir)
        return SweepResult(ds, path, time.perf_counter() - start_time, saved, total - left)


@contextmanager
def _output_lock(path, shared=False):
    """Hold the output's lock (``parts.output_lock``) for a run; another run holding it
    is a :class:`RunError` naming that process."""
    try:
        with parts.output_lock(path, shared):
            yield
    except parts.OutputBusy as exc:
        raise RunError(str(exc)) from None


def _rows(ranges):
    return sum(b - a for a, b in ranges)


def _default_chunk_size(n, threads, client, shard):
    """Chunk size for this run: per backend, or (shards) from the grid size alone."""
    if shard:
        return default_chunk_size(n)
    if client is not None:
        return default_chunk_size(n, dask_threads=max(1, _dask_threads(client)))
    return default_chunk_size(n, accelerate.thread_count(threads))


def _make_folder(parts_dir):
    try:
        parts_dir.mkdir(exist_ok=True)
    except OSError as exc:
        raise RunError(
            f"cannot create the parts folder {parts_dir}: {exc.strerror or exc}"
        ) from None


def _reuse_parts(parts_dir, chash, owned, results, y_final, resume):
    """Fill rows from the valid parts of this config (if ``resume``); return the row mask.

    Unusable parts are reported and removed, so their rows are recomputed.
    """
    n = len(results)
    have = np.zeros(n, bool)
    groups = parts.scan(parts_dir)
    others = sum(len(v) for h, v in groups.items() if h != chash)
    if others:
        log.info("ignoring %d parts of another config in %s", others, parts_dir)
    mine = groups.get(chash, [])
    if not resume:
        if mine:
            log.info("not reusing %d parts of this sweep in %s (--resume reuses them)",
                     len(mine), parts_dir)  # fmt: skip
        return have
    wanted = np.zeros(n, bool)
    for a, b in owned:
        wanted[a:b] = True
    used, bad = parts.fill_from_parts(mine, results, y_final, have, wanted)
    for path, reason in bad:
        log.warning("unusable part, its runs will be recomputed: %s", reason)
        path.unlink(missing_ok=True)
    log.info("resuming from %s: reusing %d runs from %d parts", parts_dir,
             int(have.sum()), len(used))  # fmt: skip
    return have


def _write_result(ds, path, kept):
    """Write the NetCDF atomically; on failure say what is kept (``kept``) and how to go on."""
    try:
        write_netcdf(ds, path)
    except (OSError, RuntimeError) as exc:
        raise RunError(
            f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}; the finished "
            f"chunks stay in {kept}, rerun once this is fixed"
        ) from None


def merge_parts(paths, out):
    """Assemble the NetCDF result ``out`` from part files or folders of parts.

    Uses the one config whose valid parts cover its whole grid (parts of
    other configs are ignored; corrupt parts are reported and never used).
    That config's parts are removed once ``out`` is written, and so are
    temporary files of writers that were killed (:func:`parts.stale_temp_files`),
    then folders left empty. Raises ``ConfigError`` for paths that are not parts and
    ``RunError`` naming the missing rows when no config is complete. Returns
    the Dataset.
    """
    check_writable(out, "merge", "--out")
    with _output_lock(out):
        return _merge_locked(paths, out)


def _merge_locked(paths, out):
    """The body of :func:`merge_parts`, holding the output's lock."""
    files = parts.part_files(paths)
    for f in files:
        if not f.exists():
            raise ConfigError("merge", [f"{f}: no such file or folder"])
        if parts.PART_NAME.match(f.name) is None or not f.is_file():
            raise ConfigError(
                "merge", [f"{f} is not a part file (<hash>_<start>-<stop>_of_<n>.npz)"]
            )
    groups = parts.group(files)
    if not groups:
        raise ConfigError("merge", [f"no part files in {', '.join(map(str, paths))}"])
    problems = []
    for chash, entries in groups.items():
        config = _part_config(entries)
        if config is None or parts.config_hash(config) != chash:
            problems.append(f"parts {chash}: no readable part of this rsf-sweep version")
            continue
        phys = physical_parameters(config)
        params, y0, settings, time_unit = system_arrays(config, phys)
        n = params.shape[0]
        results = np.empty((n, N_RESULTS))
        y_final = np.empty_like(y0)
        have = np.zeros(n, bool)
        used, bad = parts.fill_from_parts(entries, results, y_final, have, np.ones(n, bool))
        problems.extend(f"corrupt part, not merged: {reason}" for _, reason in bad)
        gaps = missing_ranges([(0, n)], have)
        if gaps:
            rows = ", ".join(f"{a}:{b}" for a, b in gaps[:5]) + (" ..." if len(gaps) > 5 else "")
            problems.append(
                f"parts {chash} ({config.name}): rows {rows} missing ({n - int(have.sum())} of "
                f"{n} runs); rerun the shards that own them with --resume"
            )
            continue
        for problem in problems:
            log.warning("%s", problem)
        ds = build_dataset(config, phys, results, y_final, time_unit, "merge")
        _write_result(ds, out, "the parts")
        for f in used:
            f.unlink()
        for folder in {Path(p) for p in paths if Path(p).is_dir()}:
            for f in parts.stale_temp_files(folder):
                f.unlink(missing_ok=True)
            if not any(folder.iterdir()):
                folder.rmdir()
        return ds
    raise RunError("cannot merge: " + "; ".join(problems))


def _part_config(entries):
    """The Config stored in the first readable part of ``entries`` (or ``None``)."""
    for *_, path in entries:
        try:
            part = parts.read_part(path)
            return parse_config(part.config_text, part.config_source)
        except (parts.PartError, ConfigError):
            continue
    return None
