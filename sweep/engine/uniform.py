"""A uniform grid's sweep: config → grid → kernels in chunks → parts → Dataset → NetCDF.

Knows about chunks, threads and Dask, never about friction. A sweep of ``n`` systems
(rows of the C-ordered grid) is cut into chunks of ``chunk_size`` rows. Chunks run on
threads of this process (batches of a chunk's systems) or as Dask tasks
(``sweep/engine/backends.py``). Each finished chunk is saved at once as a part file
(``sweep/io/parts.py``); with ``resume=True`` the rows already saved are read back
instead of recomputed. The NetCDF is written once every row is known, and the parts are
removed only after that. ``shard=(i, n_shards)`` computes only the chunks ``k`` with
``k % n_shards == i`` and leaves them as parts, for job arrays. An output ending in
``.zarr`` is a Zarr store instead (``sweep/io/zarr.py``): created full size up front,
each chunk written into it as it finishes, no parts. Reached through
``sweep.engine.runner`` (``run_sweep``, ``compute``, ``merge_parts``).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

from ..config import Config
from ..errors import InputError, RunError
from ..io import files, parts
from ..io.netcdf import write_result
from ..io.zarr import ZarrResult, open_result
from ..kernels.layout import result_width
from ..progress import Progress
from ..results.dataset import build_dataset
from .backends import DaskTasks, LocalThreads, Resources, open_backend
from .chunks import (
    check_saved,
    chunk_ranges,
    chunk_size_for,
    count_rows,
    integrate_in_memory,
    missing_ranges,
    ranges_mask,
    rows_missing,
    run_saving,
)
from .grid import build_grid, settings_array, state_size
from .run_control import StopRequest, SweepResult

log = logging.getLogger(__name__)


def compute(config, threads=None, chunk_size=None, show_progress=True, client=None, command="run"):
    """Run every system of ``config``'s grid and return the result Dataset (nothing
    written); arguments as for :func:`sweep.engine.runner.compute`."""
    grid = build_grid(config)
    backend = LocalThreads(threads) if client is None else DaskTasks(client)
    # compiled here, not first in integrate_in_memory: before the progress clock
    backend.compile(grid.params, grid.settings)
    progress = Progress(grid.n, desc=config.name, enabled=show_progress)
    try:
        results, y_final = integrate_in_memory(
            grid.params,
            grid.y0,
            grid.settings,
            chunk_size=chunk_size,
            progress=progress,
            backend=backend,
        )
    finally:
        progress.close()
    return build_dataset(grid, results, y_final, command)


def run(
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
    """Run ``config``'s grid, saving each chunk as a part (or into a Zarr store), and
    write the NetCDF result; arguments, errors and result as for
    :func:`sweep.engine.runner.run_sweep`."""
    start_time = time.perf_counter()
    path = Path(out or config.output)
    key = "output" if out is None else "--out"
    files.check_writable(path, config.source, key, (".nc", files.ZARR_SUFFIX))
    to_zarr = path.suffix == files.ZARR_SUFFIX
    if to_zarr:
        files.require_zarr(config.source, key)
        if shard:
            raise InputError(
                config.source,
                [f"--shard keeps parts for merge, which writes NetCDF: give {key} a .nc path"],
            )
    with files.output_lock(path, shared=bool(shard)):
        grid = build_grid(config)
        stop = stop if stop is not None else StopRequest()
        with open_backend(resources) as backend:
            chunk_size = chunk_size or chunk_size_for(grid.n, backend, shard)
            shape = (grid.n, result_width(grid.settings), grid.y0.shape[1])
            if to_zarr:
                run = parts.ZarrSink(ZarrResult(path, grid, chunk_size, resume), shape)
                owned = run.store.ranges
                todo = [(a, b) for a, b in owned if not run.store.have[a:b].all()]
            else:
                run = parts.PartStore(parts.parts_dir_for(path), config, shape)
                run.make_folder()
                owned = chunk_ranges(grid.n, chunk_size, shard or (0, 1))
                have = run.reuse(ranges_mask(grid.n, owned), resume)
                todo = missing_ranges(owned, have)
            total, left = count_rows(owned), count_rows(todo)
            log.info(
                "%s: computing %d runs in %d chunks on %s", config.name, left, len(todo), backend
            )
            # compiled here, not first in run_chunks: before the progress clock
            backend.compile(grid.params, grid.settings)
            progress = Progress(total, config.name, enabled=show_progress, initial=total - left)
            run_saving(backend, grid, todo, run, progress, stop)
        check_saved(run, total, left, stop)
        if shard:
            elapsed = time.perf_counter() - start_time
            return SweepResult(None, run.folder, elapsed, run.saved, total - left)
        if to_zarr:
            ds = open_result(path)
            return SweepResult(ds, path, time.perf_counter() - start_time, run.saved, total - left)
        ds = build_dataset(grid, run.results, run.y_final)
        write_result(ds, path, f"{run.folder} (use --resume)")
        parts.remove_parts(run.folder)
        return SweepResult(ds, path, time.perf_counter() - start_time, run.saved, total - left)


def merge(configs, groups, paths, out):
    """Assemble the result of the one config whose parts cover its grid and write it to
    ``out`` (``configs``, ``groups``: the config stored in each hash's parts and their
    entries; :func:`sweep.engine.runner.merge_parts` holds the locks); remove the parts
    used. Raises ``RunError`` naming what is missing. Returns the Dataset."""
    problems = []
    for chash, entries in groups.items():
        config = configs[chash]
        if config is None or parts.config_hash(config) != chash:
            problems.append(f"parts {chash}: no readable part of this rsf-sweep version")
            continue
        n = math.prod(config.run_shape)
        shape = (n, result_width(settings_array(config)), state_size(config))
        run = parts.PartStore(parts.parts_dir_for(out), config, shape, chash)
        have = np.zeros(n, bool)
        used, bad = run.fill(have, np.ones(n, bool), entries, merging=True)
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
        ds = build_dataset(build_grid(config), run.results, run.y_final, "merge")
        write_result(ds, out, "the parts")
        parts.remove_merged(used, paths)
        return ds
    raise RunError("cannot merge: " + "; ".join(problems))
