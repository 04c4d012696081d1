"""The entry to running a config: its uniform grid (``sweep/engine/uniform.py``) or, for
a config with a ``refine`` section, its refinement level by level
(``sweep/engine/refined.py``), chosen once by :func:`runner_for`.

Every system is integrated independently and deterministically, so results do not
depend on the chunk size, the number of threads or workers, sharding or resumption.
"""

from __future__ import annotations

from collections.abc import Iterable
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING

from ..config import Config, parse_config
from ..errors import InputError
from ..io import files, parts
from . import refined, uniform
from .backends import Resources
from .run_control import StopRequest, SweepResult

if TYPE_CHECKING:
    import xarray


def runner_for(config):
    """The module that runs ``config``: :mod:`~sweep.engine.refined` for a config with a
    ``refine`` section, else :mod:`~sweep.engine.uniform`. Both offer ``compute``,
    ``run`` and ``merge``."""
    return refined if config.refine is not None else uniform


def compute(config, threads=None, chunk_size=None, show_progress=True, client=None, command="run"):
    """Run every system of ``config`` and return the result Dataset (nothing written).

    ``threads``: local threads (default: all cores), or ``client``: an open Dask client.
    ``command``: what is running it, for the file's ``history`` (``dataset.provenance``).
    """
    return runner_for(config).compute(config, threads, chunk_size, show_progress, client, command)


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
        Systems per chunk (default: :func:`~sweep.engine.chunks.default_chunk_size`; with
        ``shard``, one that depends on the grid size only, so all shards agree).
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
    return runner_for(config).run(
        config,
        out,
        resources=resources,
        chunk_size=chunk_size,
        resume=resume,
        shard=shard,
        show_progress=show_progress,
        stop=stop,
    )


def merge_parts(paths: Iterable[str | Path], out: str | Path) -> xarray.Dataset:
    """Assemble the NetCDF result ``out`` from part files or folders of parts.

    Uses the one config whose valid parts cover its whole grid (parts of other configs
    are ignored; corrupt parts are reported and never used); the parts of a refinement
    are replayed level by level. That config's parts are removed once ``out`` is
    written, and so are temporary files of writers that were killed
    (:func:`~sweep.io.parts.stale_temp_files`), then folders left empty. Holds the lock
    of ``out`` and of every output whose parts folder it reads (``x.parts`` → ``x.nc``),
    so a run or shard still working on those parts makes it refuse instead of removing
    parts under it.

    Parameters
    ----------
    paths : iterable of str or pathlib.Path
        Part files, or folders of them (``<output>.parts``).
    out : str or pathlib.Path
        The NetCDF file to write.

    Returns
    -------
    xarray.Dataset
        The merged result.

    Raises
    ------
    InputError
        A path is not a part file, or there is none.
    RunError
        No config's parts cover its grid (naming the missing rows), or another process
        holds a lock (``OutputBusy``).
    """
    files.check_writable(out, "merge", "--out")
    folders = {Path(p) if Path(p).is_dir() else Path(p).parent for p in paths}
    owners = {parts.owner_output(f) for f in folders} - {None}
    with ExitStack() as locks:
        for output in sorted({Path(out).resolve()} | {o.resolve() for o in owners}):
            locks.enter_context(files.output_lock(output))
        groups = _part_groups(paths)
        configs = {h: parts.stored_config(entries, parse_config) for h, entries in groups.items()}
        refinement = next((c for c in configs.values() if c and c.refine), None)
        if refinement is not None:  # the parts of a refinement's levels
            return refined.merge(refinement, groups, paths, out)
        return uniform.merge(configs, groups, paths, out)


def _part_groups(paths):
    """The part files of ``paths`` by config hash; an ``InputError`` for a path that is
    not a part file, or when there is none."""
    found = parts.part_files(paths)
    for f in found:
        if not f.exists():
            raise InputError("merge", [f"{f}: no such file or folder"])
        if parts.PART_NAME.match(f.name) is None or not f.is_file():
            raise InputError(
                "merge", [f"{f} is not a part file (<hash>_<start>-<stop>_of_<n>.npz)"]
            )
    groups = parts.group(found)
    if not groups:
        raise InputError("merge", [f"no part files in {', '.join(map(str, paths))}"])
    return groups
