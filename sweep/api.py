"""The Python API for notebooks and scripts: ``import sweep; ds = sweep.run("quick")``.

Thin functions over the same pieces the CLI uses; nothing here writes a file.
``sweep.load_config`` and ``sweep.with_changes`` come from ``sweep/config/``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from .config import Config, load_config, with_changes
from .errors import InputError

if TYPE_CHECKING:
    import xarray


def run(
    config: str | os.PathLike | Mapping[str, Any] | Config,
    *,
    threads: int | None = None,
    client: Any = None,
    progress: bool = True,
    refine: int | Mapping[str, Any] | bool | None = None,
) -> xarray.Dataset:
    """Run a sweep and return its result; nothing is written.

    Parameters
    ----------
    config : str, os.PathLike, Mapping or Config
        A YAML file, the name of a packaged example (:func:`sweep.examples.names`),
        a mapping as the YAML would read, or a :class:`~sweep.Config`
        (e.g. from :func:`~sweep.with_changes`).
    threads : int, optional
        Threads on this machine (default: all cores); not with ``client``.
    client : distributed.Client, Cluster or str, optional
        Run the chunks as tasks on this Dask client, on a new client of this
        cluster (e.g. a ``LocalCluster``), or on the scheduler at this address
        (``"tcp://host:8786"``). A given Client is left open.
    progress : bool, default True
        Show progress: a widget bar in a notebook (with ipywidgets), a bar on a
        terminal, plain lines in pipes and logs.
    refine : int, Mapping or bool, optional
        Refine the sweep where its labels change (the config's ``refine`` section,
        ``sweep/refine/lattice.py``): a number of levels, a mapping like the section (e.g.
        ``{"levels": 8, "max_runs": 20000}``, merged into the config's), True for the
        config's section or the defaults, False for the grid only. Default: as the
        config says.

    Returns
    -------
    xarray.Dataset
        The result, as ``python -m sweep run`` writes it (dimensions named after
        the sweep axes, fixed parameters as scalar coordinates, CF attributes);
        its ``history`` says it was made by ``sweep.run()`` and from which config
        (``<mapping>`` for a mapping). Save it with :func:`sweep.write_netcdf`
        (atomic) or ``ds.to_netcdf``. A refined sweep's runs lie along one dimension,
        ``point`` (:func:`sweep.to_grid` puts them on a grid, :func:`sweep.boundaries`
        gives the boundaries between labels).

    Raises
    ------
    ConfigError
        The config is not valid (every problem listed, each naming its key).
    InputError
        ``threads`` is not an integer in [1, cores], is given with ``client``,
        ``client`` is none of a Client, a Cluster or an address, or ``refine`` is none
        of a number, a mapping or a bool.
    RunError
        Dask is not installed, or the cluster cannot be reached.
    """
    from contextlib import nullcontext

    from .engine.runner import compute

    config = with_refine(load_config(config), refine)
    if client is not None and threads is not None:
        raise InputError(config.source, ["threads is for local threads; Dask workers own theirs"])
    _check_threads(config.source, threads)
    if client is None:
        backend = nullcontext(None)
    else:
        from .engine.distributed import connect

        backend = connect(client)
    with backend as dask_client:
        return compute(
            config, threads, show_progress=progress, client=dask_client, command="sweep.run"
        )


def with_refine(config, refine):
    """``config`` with its ``refine`` section set by ``refine`` (see :func:`run`): levels
    (an int), a mapping merged into the section, True (the section, or the defaults),
    False (none) or None (unchanged). Validated like a file (``ConfigError``)."""
    if refine is None or (refine is True and config.refine is not None):
        return config
    if refine is False:
        changes = {"refine": None}
    elif refine is True:
        changes = {"refine": {}}
    elif isinstance(refine, int):
        changes = {"refine": {"levels": refine}}
    elif isinstance(refine, Mapping):
        changes = {"refine": dict(refine)}
    else:
        problem = (
            f"refine must be a number of levels, a mapping like the config's refine "
            f"section, or a bool; got {refine!r}"
        )
        raise InputError(config.source, [problem])
    return with_changes(config, changes)


def compile_kernels(
    *configs: str | os.PathLike | Mapping[str, Any] | Config, processes: int | None = None
) -> None:
    """Compile the kernels that ``configs`` may use, or load them from numba's cache.

    Each config's variant is compiled into this process, and the one with the
    tangent for λ1 where unsettled runs ask for it (``classification.lyapunov``).
    Run it once before job-array tasks or workers on other nodes start, so that
    they only read numba's on-disk cache (``python -m sweep compile`` does the same).

    Parameters
    ----------
    *configs : str, os.PathLike, Mapping or Config
        Configs, each as :func:`run` takes them.
    processes : int, optional
        Several variants are compiled side by side in up to this many fresh
        processes (default: one per core), then loaded here.

    Returns
    -------
    None
        The kernels are compiled and cached; nothing is returned.

    Raises
    ------
    ConfigError
        A config is not valid.
    InputError
        ``processes`` is not a positive integer.
    """
    from .engine.dispatch import kernel_jobs, load_kernels
    from .engine.grid import build_grid

    configs = [load_config(config) for config in configs]
    positive = (
        isinstance(processes, (int, np.integer))
        and not isinstance(processes, bool)
        and processes >= 1
    )
    if not (processes is None or positive):
        source = configs[0].source if configs else "compile_kernels"
        raise InputError(source, [f"processes must be a positive integer, got {processes!r}"])
    grids = [build_grid(config) for config in configs]
    load_kernels(
        [job for g in grids for job in kernel_jobs(g.params, g.settings, every=True)], processes
    )


def _check_threads(source, threads):
    """Raise :class:`~sweep.errors.InputError` unless ``threads`` is None or in [1, cores]."""
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    ok = threads is None or (isinstance(threads, (int, np.integer)) and 1 <= threads <= top)
    if not ok or isinstance(threads, bool):
        raise InputError(source, [f"threads must be an integer in [1, {top}], got {threads!r}"])
