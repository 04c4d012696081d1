"""Orchestration of a refinement: level after level, each run as any sweep's chunks are.

The plan of a level (``sweep/refine/lattice.py``) needs every run of the level before, so levels
run one after another; within a level the points are a sweep of their own: cut into
chunks, integrated on threads or as Dask tasks (``sweep/engine/backends.py``), each finished
chunk saved at once as a part (``sweep/io/parts.py``). A level's parts are named by its
*level key*, a hash of the config's hash (``sweep.io.parts.config_hash``: everything that
changes the numbers), the level and the kernels' arrays of its points, so they are only
ever used for those very runs. The plan is a function of the runs, which do not depend
on how they were run, so a resumed, sharded or Dask run plans the same points as any
other and writes the same file.

* ``resume``: a level's parts written before are read back instead of run again.
* ``shard=(i, n)``: shard i runs its chunks of each level (those of a sweep of the
  level's points), then waits for the other shards' parts of the level in the shared
  parts folder, plans the next level as they all do, and so on; at the end the parts
  stay for ``merge`` (:func:`merge`, through ``runner.merge_parts``). All shards
  must run at the same time (they meet between levels).
"""

import hashlib
import logging
import signal
import time
from pathlib import Path

import numpy as np

from ..errors import Interrupted, RunError
from ..io import files, parts
from ..io.netcdf import write_result
from ..kernels.layout import result_width
from ..progress import Progress
from ..refine.dataset import build_point_dataset
from ..refine.lattice import Refinement, point_labels
from ..results.dataset import derived_fields
from .backends import DaskTasks, LocalThreads, open_backend
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
from .grid import build_grid
from .run_control import StopRequest, SweepResult

log = logging.getLogger(__name__)

#: Seconds between looks into the parts folder while a shard waits for the others.
POLL = 1.0


def level_key(chash, level, grid):
    """16 hex digits naming the parts of one level: the config hash ``chash``, the level
    and the kernels' arrays of its points (``grid``)."""
    digest = hashlib.sha256(f"{chash} refine level {level}".encode())
    digest.update(np.ascontiguousarray(grid.params).tobytes())
    digest.update(np.ascontiguousarray(grid.y0).tobytes())
    return digest.hexdigest()[:16]


def refine_levels(config, run_level, timings=None):
    """Run the refinement of ``config``: level by level, ``run_level(level, index, grid)``
    returns ``(results, y_final)`` of the level's points ``index`` (their
    :class:`~sweep.engine.grid.Grid`: ``grid``). Returns ``(refinement, grid, results,
    y_final)`` over all points, in order. ``timings`` (a dict) gets the seconds spent
    planning and labelling (``planning``) and running (``integration``)."""
    timings = {} if timings is None else timings
    clock = time.perf_counter()
    refinement = Refinement(config)
    results, finals = [], []
    index = refinement.planned[0]
    while index is not None:
        grid = build_grid(config, refinement.lattice.values(index))
        start = time.perf_counter()
        res, yf = run_level(refinement.level, index, grid)
        timings["integration"] = timings.get("integration", 0.0) + time.perf_counter() - start
        results.append(res)
        finals.append(yf)
        refinement.add(index, point_labels(config, derived_fields(grid, res, yf)))
        log.info("%s: level %d: %d runs", config.name, refinement.level, grid.n)
        index = refinement.plan()
    grid = build_grid(config, refinement.lattice.values(refinement.index))
    total = time.perf_counter() - clock
    timings["planning"] = total - timings.get("integration", 0.0)
    return refinement, grid, np.concatenate(results), np.concatenate(finals)


def _desc(config, level):
    return f"{config.name} level {level}/{config.refine.levels}"


def compute(config, threads=None, chunk_size=None, show_progress=True, client=None, command="run"):
    """Run the refinement of ``config`` in memory and return its Dataset (nothing written);
    arguments as for :func:`sweep.engine.runner.compute`. Progress is shown per level."""
    backend = LocalThreads(threads) if client is None else DaskTasks(client)
    first = build_grid(config)
    backend.compile(first.params, first.settings)

    def run_level(level, index, grid):
        progress = Progress(grid.n, desc=_desc(config, level), enabled=show_progress)
        try:
            return integrate_in_memory(
                grid.params,
                grid.y0,
                grid.settings,
                chunk_size=chunk_size,
                progress=progress,
                backend=backend,
            )
        finally:
            progress.close()

    refinement, grid, results, y_final = refine_levels(config, run_level)
    return build_point_dataset(config, refinement, grid, results, y_final, command)


def run(
    config,
    out=None,
    *,
    resources=None,
    chunk_size=None,
    resume=False,
    shard=None,
    show_progress=True,
    stop=None,
):
    """Run the refinement of ``config`` level by level, saving each chunk as a part, and
    write the NetCDF result; arguments, errors and result as for
    :func:`sweep.engine.runner.run_sweep` (whose refined configs come here). A ``.zarr`` output
    is refused: the points of a refinement are not known before it runs.
    ``SweepResult.timings``: seconds spent running, planning and writing."""
    start_time = time.perf_counter()
    path = Path(out or config.output)
    key = "output" if out is None else "--out"
    files.check_writable(path, config.source, key, ".nc")
    timings = {}
    counts = {"computed": 0, "reused": 0}
    with files.output_lock(path, shared=bool(shard)):
        stop = stop if stop is not None else StopRequest()
        folder = parts.parts_dir_for(path)
        chash = parts.config_hash(config)
        with open_backend(resources) as backend:
            first = build_grid(config)
            backend.compile(first.params, first.settings)

            def run_level(level, index, grid):
                return _run_level(
                    config,
                    level,
                    grid,
                    folder,
                    level_key(chash, level, grid),
                    backend,
                    chunk_size,
                    resume,
                    shard,
                    show_progress,
                    stop,
                    counts,
                )

            refinement, grid, results, y_final = refine_levels(config, run_level, timings)
        if shard:
            return SweepResult(
                None,
                folder,
                time.perf_counter() - start_time,
                counts["computed"],
                counts["reused"],
                timings,
            )
        clock = time.perf_counter()
        ds = build_point_dataset(config, refinement, grid, results, y_final)
        write_result(ds, path, f"{folder} (use --resume)")
        parts.remove_parts(folder)
        timings["file"] = time.perf_counter() - clock
        log.info(
            "%s: %.1f s running, %.2f s planning and labelling, %.2f s writing the file",
            config.name,
            timings["integration"],
            timings["planning"],
            timings["file"],
        )
        return SweepResult(
            ds,
            path,
            time.perf_counter() - start_time,
            counts["computed"],
            counts["reused"],
            timings,
        )


def _run_level(
    config,
    level,
    grid,
    folder,
    key,
    backend,
    chunk_size,
    resume,
    shard,
    show_progress,
    stop,
    counts,
):
    """The runs of one level: read back (``resume``), run the rest of this shard's chunks
    saving each as a part, and with a shard wait for the other shards' parts."""
    if level and stop:  # (within a level, run_chunks checks after each chunk)
        raise Interrupted(
            stop.signum,
            f"interrupted by {signal.Signals(stop.signum).name} "
            f"before level {level}; rerun with --resume to continue",
        )
    shape = (grid.n, result_width(grid.settings), grid.y0.shape[1])
    run = parts.PartStore(folder, config, shape, key)
    run.make_folder()
    size = chunk_size or chunk_size_for(grid.n, backend, shard)
    owned = chunk_ranges(grid.n, size, shard or (0, 1))
    have = np.zeros(grid.n, bool)
    if resume:
        run.fill(have, ranges_mask(grid.n, owned))
        log.info("%s: level %d: reusing %d runs from parts", config.name, level, int(have.sum()))
    todo = missing_ranges(owned, have)
    total, left = count_rows(owned), count_rows(todo)
    progress = Progress(total, _desc(config, level), enabled=show_progress, initial=total - left)
    run_saving(backend, grid, todo, run, progress, stop)
    counts["computed"] += run.saved
    counts["reused"] += total - left
    check_saved(run, total, left, stop, f"level {level}: ")
    have |= ranges_mask(grid.n, owned)
    if shard and not have.all():
        _await_shards(config, level, folder, key, run, have, shard, stop)
    return run.results, run.y_final


def _await_shards(config, level, folder, key, run, have, shard, stop):
    """Wait until every run of the level is in the parts folder (the other shards write
    them), reading them as they come; a stop request ends the wait."""
    i, n = shard
    log.info(
        "%s: shard %d/%d: level %d: waiting for the other shards' runs (%d of %d here)",
        config.name,
        i,
        n,
        level,
        int(have.sum()),
        have.size,
    )
    while True:
        run.fill(have, ~have)
        if have.all():
            return
        if stop:
            raise Interrupted(
                stop.signum,
                f"interrupted by {signal.Signals(stop.signum).name} while shard {i}/{n} waited "
                f"for the other shards' runs of level {level} ({int(have.sum())} of "
                f"{have.size} in {folder}); rerun with --resume to continue",
            )
        time.sleep(POLL)


def merge(config, groups, paths, out):
    """Assemble the result of the refinement of ``config`` from its parts (``groups``:
    part entries by hash, ``sweep.io.parts.group``), level by level, write it to ``out``
    and remove the parts used (``sweep.io.parts.remove_merged``). Raises ``RunError`` naming the
    level and rows that no part holds. Returns the Dataset."""
    chash = parts.config_hash(config)
    used_parts = []

    def run_level(level, index, grid):
        key = level_key(chash, level, grid)
        shape = (grid.n, result_width(grid.settings), grid.y0.shape[1])
        run = parts.PartStore(parts.parts_dir_for(out), config, shape, key)
        have = np.zeros(grid.n, bool)
        used, bad = run.fill(have, np.ones(grid.n, bool), groups.get(key, []), merging=True)
        for _, reason in bad:
            log.warning("corrupt part, not merged: %s", reason)
        gaps = missing_ranges([(0, grid.n)], have)
        if gaps:
            raise RunError(
                f"cannot merge: parts of {config.name}: level {level}: rows {rows_missing(gaps)} "
                "missing "
                f"({grid.n - int(have.sum())} of {grid.n} runs); rerun the shards with --resume"
            )
        used_parts.extend(used)
        return run.results, run.y_final

    refinement, grid, results, y_final = refine_levels(config, run_level)
    ds = build_point_dataset(config, refinement, grid, results, y_final, "merge")
    write_result(ds, out, "the parts")
    parts.remove_merged(used_parts, paths)
    return ds
