"""Orchestration: config → grid → kernels in chunks → parts → Dataset → NetCDF.

Knows about chunks, threads and Dask, never about friction. Every system is
integrated independently and deterministically, so results do not depend on
the chunk size, the number of threads or workers, sharding or resumption.

A sweep of ``n`` systems (rows of the C-ordered grid) is cut into chunks of
``chunk_size`` rows. Chunks run on threads of this process (batches of a
chunk's systems) or as Dask tasks (``sweep/engine/backends.py``). Each
finished chunk is saved at once as a part file (``sweep/io/parts.py``); with
``resume=True`` the rows already saved are read back instead of recomputed.
The NetCDF is written once every row is known, and the parts are removed only
after that. ``shard=(i, n_shards)`` computes only the chunks ``k`` with
``k % n_shards == i`` and leaves them as parts, for job arrays. An output
ending in ``.zarr`` is a Zarr store instead (``sweep/io/zarr.py``): created
full size up front, each chunk written into it as it finishes, no parts.
The chunks, parts and atomic write it shares with refinements are ``sweep/engine/chunks.py``.
"""

from __future__ import annotations

import logging
import math
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from ..config import Config, parse_config
from ..errors import (
    ConfigError,
    InputError,
    Interrupted,  # noqa: F401 (what run_sweep raises when it is stopped)
    PartError,
    RunError,
)
from ..io import parts as store
from ..io import zarr as zarr_store
from ..kernels.layout import result_width
from ..progress import Progress
from ..results.dataset import build_dataset
from .backends import DaskTasks, LocalThreads, Resources, open_backend
from .chunks import (
    PartStore,
    StopRequest,
    SweepResult,
    check_saved,
    chunk_ranges,
    chunk_size_for,
    count_rows,
    default_chunk_size,  # noqa: F401 (public here: run_sweep's default chunk size)
    fill_from_parts,
    integrate_in_memory,
    make_parts_folder,
    missing_ranges,
    ranges_mask,
    remove_merged,
    rows_missing,
    run_saving,
    write_result,
)
from .grid import build_grid, settings_array, state_size

log = logging.getLogger(__name__)


def compute(config, threads=None, chunk_size=None, show_progress=True, client=None,
            command="run"):  # fmt: skip
    """Run every system of ``config`` and return the result Dataset (nothing written).

    ``threads``: local threads (default: all cores), or ``client``: an open Dask client.
    ``command``: what is running it, for the file's ``history`` (``dataset.provenance``).
    """
    if config.refine is not None:
        from .refined import compute_refined

        return compute_refined(config, threads, chunk_size, show_progress, client, command)
    grid = build_grid(config)
    backend = LocalThreads(threads) if client is None else DaskTasks(client)
    # compiled here, not first in integrate_in_memory: before the progress clock
    backend.compile(grid.params, grid.settings)
    progress = Progress(grid.n, desc=config.name, enabled=show_progress)
    try:
        results, y_final = integrate_in_memory(
            grid.params, grid.y0, grid.settings, chunk_size=chunk_size, progress=progress,
            backend=backend,
        )  # fmt: skip
    finally:
        progress.close()
    return build_dataset(grid, results, y_final, command)


def run_sweep(
    config: Config,
    out: str | Path | None = None,
    *,
    resources: Resources | None = None,
    chunk_size: int | None = None,
    resume: bool = False,
    shard: tuple[int, int] | None = None,
    show_progress: bool = True,
    stop: StopRequest | None = None,
) -> SweepResult:
    """Run ``config``, saving each chunk as a part, and write the NetCDF result.

    What ``python -m sweep run`` does: chunks run on threads or Dask, each kept as
    a part file as it finishes, so an interrupted sweep resumes where it stopped.
    A config with a ``refine`` section runs level by level
    (``sweep/engine/refined.py``), its runs along one dimension, ``point``.

    Parameters
    ----------
    config : Config
        The sweep (:func:`sweep.load_config`).
    out : str or pathlib.Path, optional
        NetCDF output (default: the config's ``output``); parts go to
        ``<out without .nc>.parts/``. A ``.zarr`` path is a Zarr store filled
        chunk by chunk (its chunks are the runner's; ``shard`` is refused).
    resources : sweep.engine.backends.Resources, optional
        Where the chunks run: ``threads`` on this machine (default: all cores), or Dask (a
        ``scheduler`` address or ``dask_local`` worker processes).
    chunk_size : int, optional
        Systems per chunk (default: :func:`default_chunk_size`; with ``shard``,
        one that depends on the grid size only, so all shards agree).
    resume : bool, default False
        Reuse the rows of valid parts of this config instead of recomputing them.
    shard : (int, int), optional
        Compute only chunks ``k`` with ``k % n_shards == i`` and keep them as
        parts (no NetCDF), ``i`` of ``n_shards``; combine with ``merge_parts`` or a
        later full run.
    show_progress : bool, default True
        Show progress (:class:`~sweep.progress.Progress`: a bar in a notebook or on a
        terminal, plain lines in pipes and logs).
    stop : StopRequest, optional
        Checked between chunks; when set, raise :class:`~sweep.errors.Interrupted`.

    Returns
    -------
    SweepResult
        ``dataset`` (the result; None for a shard), ``path`` (the file written, or
        a shard's parts folder), ``elapsed`` (wall time, s), ``computed`` and
        ``reused`` (runs integrated now and read back from parts); for a refinement
        also ``timings`` (wall time, s, by activity).

    Raises
    ------
    InputError
        The output cannot be written, or ``shard`` (or a ``refine`` section) is
        given with a Zarr output.
    RunError
        The disk or the cluster failed, or another process holds the output's
        lock; after a stop, its subclass ``Interrupted``. In every case an earlier
        result file is left as it was, and the parts written so far are kept.
    """
    if config.refine is not None:
        from .refined import run_refined

        return run_refined(config, out, resources=resources, chunk_size=chunk_size,
                           resume=resume, shard=shard, show_progress=show_progress,
                           stop=stop)  # fmt: skip
    start_time = time.perf_counter()
    path = Path(out or config.output)
    key = "output" if out is None else "--out"
    store.check_writable(path, config.source, key, (".nc", store.ZARR_SUFFIX))
    to_zarr = path.suffix == store.ZARR_SUFFIX
    if to_zarr:
        store.require_zarr(config.source, key)
        if shard:
            raise InputError(
                config.source,
                [f"--shard keeps parts for merge, which writes NetCDF: give {key} a .nc path"],
            )
    with store.output_lock(path, shared=bool(shard)):
        grid = build_grid(config)
        stop = stop if stop is not None else StopRequest()
        with open_backend(resources) as backend:
            chunk_size = chunk_size or chunk_size_for(grid.n, backend, shard)
            if to_zarr:
                run = _ZarrStore(zarr_store.ZarrResult(path, grid, chunk_size, resume), grid)
                owned = run.store.ranges
                todo = [(a, b) for a, b in owned if not run.store.have[a:b].all()]
            else:
                run = PartStore(store.parts_dir_for(path), config, grid.n, grid.y0.shape[1])
                make_parts_folder(run.folder)
                owned = chunk_ranges(grid.n, chunk_size, shard or (0, 1))
                have = _reuse_parts(run, owned, resume)
                todo = missing_ranges(owned, have)
            total, left = count_rows(owned), count_rows(todo)
            log.info("%s: computing %d runs in %d chunks on %s", config.name, left, len(todo),
                     backend)  # fmt: skip
            # compiled here, not first in run_chunks: before the progress clock
            backend.compile(grid.params, grid.settings)
            progress = Progress(total, config.name, enabled=show_progress, initial=total - left)
            run_saving(backend, grid, todo, run, progress, stop)
        check_saved(run, total, left, stop)
        if shard:
            elapsed = time.perf_counter() - start_time
            return SweepResult(None, run.folder, elapsed, run.saved, total - left)
        if to_zarr:
            ds = zarr_store.open_result(path)
            return SweepResult(ds, path, time.perf_counter() - start_time, run.saved, total - left)
        ds = build_dataset(grid, run.results, run.y_final)
        write_result(ds, path, f"{run.folder} (use --resume)")
        store.remove_parts(run.folder)
        return SweepResult(ds, path, time.perf_counter() - start_time, run.saved, total - left)


class _ZarrStore:
    """The result arrays of a run and the Zarr store each finished chunk is written to."""

    def __init__(self, zarr_result, grid):
        self.store = zarr_result
        self.folder = zarr_result.path
        self.results = np.empty((grid.n, result_width(grid.settings)))
        self.y_final = np.empty_like(grid.y0)

    @property
    def saved(self):
        return self.store.saved

    def save(self, a, b):
        """Write rows ``a:b`` into the store; a failure is a :class:`RunError`."""
        try:
            self.store.save(a, b, self.results[a:b], self.y_final[a:b])
        except OSError as exc:
            raise RunError(
                f"cannot write to {self.folder}: {exc.strerror or exc}; the chunks written so "
                "far are kept, rerun with --resume once this is fixed"
            ) from None


def _reuse_parts(run, owned, resume):
    """Fill ``run``'s rows ``owned`` from the valid parts of its config (if ``resume``);
    return the mask of rows filled. Unusable parts are reported and removed, so their
    rows are recomputed."""
    have = np.zeros(run.n, bool)
    groups = store.scan(run.folder)
    others = sum(len(v) for h, v in groups.items() if h != run.chash)
    if others:
        log.info("ignoring %d parts of another config in %s", others, run.folder)
    mine = groups.get(run.chash, [])
    if not resume:
        if mine:
            log.info("not reusing %d parts of this sweep in %s (--resume reuses them)",
                     len(mine), run.folder)  # fmt: skip
        return have
    used = fill_from_parts(mine, run, have, ranges_mask(run.n, owned))
    log.info("resuming from %s: reusing %d runs from %d parts", run.folder,
             int(have.sum()), len(used))  # fmt: skip
    return have


def merge_parts(paths, out):
    """Assemble the NetCDF result ``out`` from part files or folders of parts.

    Uses the one config whose valid parts cover its whole grid (parts of
    other configs are ignored; corrupt parts are reported and never used).
    That config's parts are removed once ``out`` is written, and so are
    temporary files of writers that were killed (:func:`store.stale_temp_files`),
    then folders left empty. Raises ``InputError`` for paths that are not parts and
    ``RunError`` naming the missing rows when no config is complete. Returns
    the Dataset.

    Holds the lock of ``out`` and of every output whose parts folder it reads
    (``x.parts`` → ``x.nc``), so a run or shard still working on those parts makes it
    refuse with ``OutputBusy`` instead of removing parts under it.
    """
    store.check_writable(out, "merge", "--out")
    folders = {Path(p) if Path(p).is_dir() else Path(p).parent for p in paths}
    owners = {store.owner_output(f) for f in folders} - {None}
    with ExitStack() as locks:
        for output in sorted({Path(out).resolve()} | {o.resolve() for o in owners}):
            locks.enter_context(store.output_lock(output))
        return _merge_locked(paths, out)


def _merge_locked(paths, out):
    """The body of :func:`merge_parts`, holding the output's lock."""
    files = store.part_files(paths)
    for f in files:
        if not f.exists():
            raise InputError("merge", [f"{f}: no such file or folder"])
        if store.PART_NAME.match(f.name) is None or not f.is_file():
            raise InputError(
                "merge", [f"{f} is not a part file (<hash>_<start>-<stop>_of_<n>.npz)"]
            )
    groups = store.group(files)
    if not groups:
        raise InputError("merge", [f"no part files in {', '.join(map(str, paths))}"])
    refined = next((c for c in map(_part_config, groups.values()) if c and c.refine), None)
    if refined is not None:  # the parts of a refinement's levels: replayed level by level
        from .refined import merge_refined

        return merge_refined(refined, groups, paths, out)
    problems = []
    for chash, entries in groups.items():
        config = _part_config(entries)
        if config is None or store.config_hash(config) != chash:
            problems.append(f"parts {chash}: no readable part of this rsf-sweep version")
            continue
        n = math.prod(config.run_shape)
        results = np.empty((n, result_width(settings_array(config))))
        y_final = np.empty((n, state_size(config)))
        have = np.zeros(n, bool)
        used, bad = store.fill_from_parts(entries, results, y_final, have, np.ones(n, bool))
        problems.extend(f"corrupt part, not merged: {reason}" for _, reason in bad)
        gaps = missing_ranges([(0, n)], have)
        if gaps:
            problems.append(
                f"parts {chash} ({config.name}): rows {rows_missing(gaps)} missing "
                f"({n - int(have.sum())} of "
                f"{n} runs); rerun the shards that own them with --resume"
            )
            continue
        for problem in problems:
            log.warning("%s", problem)
        ds = build_dataset(build_grid(config), results, y_final, "merge")
        write_result(ds, out, "the parts")
        remove_merged(used, paths)
        return ds
    raise RunError("cannot merge: " + "; ".join(problems))


def _part_config(entries):
    """The Config stored in the first readable part of ``entries`` (or ``None``)."""
    for *_, path in entries:
        try:
            part = store.read_part(path)
            return parse_config(part.config_text, part.config_source)
        except (PartError, ConfigError):
            continue
    return None
