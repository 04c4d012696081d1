"""The critical kick by bisection: at every point of a config's other axes, in rounds.

The config sweeps one start axis (``physics.INITIAL_AXES``, e.g. ``initial_v_over_V``
on a log axis): its values are the first scan and its ends the range searched. Round 0
runs the config's grid and brackets the critical kick at every point
(``results/kicks.py``: the largest kick that returns below the smallest that leaves);
each later round runs the geometric mean of every bracket still wider than ``rtol``
(relative) and keeps the half where the outcome changes, all open points in one batch of
the engine's kernels; a last round runs the probes that tell a sharp threshold from one
set by the cap (``results/kicks.py``), 10 % below each critical kick. A bracket of
relative width r0 takes ⌈log2(ln(1 + r0) / ln(1 + rtol))⌉ rounds: 7 from a factor √10 to
1 %, and the probes one more.

After every round the Dataset so far is written to ``out`` (a temporary file, then a
rename) with ``kick_complete`` 0; a later call with the same config and the same file
goes on from its brackets (a smaller ``rtol`` narrows them further), so an interrupted
search loses at most one round. Each run is the run a uniform sweep makes at that point:
the outcome does not depend on the rounds, threads or chunks.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
import yaml

from ..config import Config, config_mapping, load_config
from ..errors import InputError
from ..io import files
from ..io.netcdf import write_netcdf
from ..kernels import layout
from ..model.physics import INITIAL_AXES
from ..progress import Progress
from ..results import kicks
from .backends import LocalThreads
from .chunks import integrate_in_memory
from .grid import build_grid
from .uniform import compute as compute_grid

#: Default relative width of the brackets (1 %).
DEFAULT_RTOL = 0.01


def bisect_critical_kick(
    config: str | os.PathLike | Mapping[str, Any] | Config,
    rtol: float = DEFAULT_RTOL,
    out: str | os.PathLike | None = None,
    threads: int | None = None,
    progress: bool = True,
) -> xr.Dataset:
    """Bisect the critical kick at every point of ``config``'s other axes.

    Parameters
    ----------
    config : str, os.PathLike, Mapping or Config
        A config sweeping one start axis (its values: the first scan; its ends: the range
        searched), no initial-condition ensemble.
    rtol : float
        Relative width of the brackets to reach, in (0, 1).
    out : str or os.PathLike, optional
        A NetCDF file written after every round and resumed from (None: nothing written).
    threads : int, optional
        Threads (default: all cores).
    progress : bool
        Show progress per round.

    Returns
    -------
    xarray.Dataset
        As :func:`sweep.results.kicks.critical_kick`, with ``kick_runs`` the runs made at
        each point, attributes ``kick_rtol_target``, ``kick_rounds``, ``kick_complete``.
    """
    config = load_config(config)
    axis = _kick_axis(config)
    if not 0.0 < rtol < 1.0:
        raise InputError(config.source, [f"rtol must be in (0, 1), got {rtol!r}"])
    path = None if out is None else Path(out)
    if path is not None:
        files.check_writable(path, config.source, "--out")
    key = yaml.safe_dump(config_mapping(config), sort_keys=True)
    backend = LocalThreads(threads)
    ds = _resumed(path, key, config.source)
    if ds is None:
        grid_ds = compute_grid(config, threads=threads, show_progress=progress, command="kick")
        ds = kicks.critical_kick(grid_ds, axis)
        ds.attrs.update(kick_rounds=np.int32(0), kick_config=key)
    others = [a for a in config.axes if a.name != axis]
    dims = tuple(a.name for a in others)
    shape = tuple(len(a.values) for a in others)
    brackets = _brackets(ds)
    runs = ds["kick_runs"].values.ravel().copy()
    values = _point_values(ds, dims)
    rounds = int(ds.attrs["kick_rounds"])
    while True:
        ds = _dataset(ds, axis, brackets, runs, shape, dims, rtol, rounds, key)
        todo = kicks.open_brackets(brackets, rtol)
        probes = kicks.stale_probes(brackets) if not todo.size else todo[:0]
        ds.attrs["kick_complete"] = np.int32(todo.size + probes.size == 0)
        if path is not None:
            write_netcdf(ds, path)
        if not todo.size and not probes.size:
            return ds
        rounds += 1
        desc = f"{config.name} round {rounds}" + ("" if todo.size else " (probes)")
        if todo.size:
            at = np.sqrt(brackets["low"][todo] * brackets["high"][todo])
        else:
            todo, at = probes, kicks.PROBE * brackets["high"][probes]
        points = {name: v[todo] for name, v in values.items()}
        points[axis] = at
        regime, peak = _outcomes(config, points, backend, progress, desc)
        if probes.size:
            kicks.set_probes(brackets, at, regime, peak, todo)
        else:
            kicks.bisect_brackets(brackets, at, regime, peak, todo)
        runs[todo] += 1


def _kick_axis(config):
    """The one start axis a config sweeps (else an InputError naming what is allowed)."""
    swept = [a.name for a in config.axes if a.name in INITIAL_AXES]
    problems = []
    if len(swept) != 1:
        problems.append(
            f"a critical-kick search sweeps exactly one start axis of {', '.join(INITIAL_AXES)} "
            f"(sweep: {', '.join(swept) or 'none of them'})"
        )
    if config.initial.ensemble:
        problems.append("a critical-kick search takes no initial.ensemble (set it to 0)")
    scan = [a for a in config.axes if a.name in swept[:1]]
    if scan and len(scan[0].values) < 2:
        problems.append(f"sweep.{scan[0].name} needs at least two values (the range searched)")
    if problems:
        raise InputError(config.source, problems)
    return swept[0]


def _resumed(path, key, source):
    """The Dataset of an earlier search of the same config at ``path``, or None."""
    if path is None or not path.exists():
        return None
    with xr.open_dataset(path) as stored:
        ds = stored.load()
    missing = [name for name in BRACKET_VARIABLES.values() if name not in ds]
    if missing and ds.attrs.get("kick_config") == key:
        raise InputError(
            path,
            [
                f"a critical-kick search without {', '.join(missing)} (an older version's): "
                "remove it or give another --out"
            ],
        )
    if ds.attrs.get("kick_config") != key:
        raise InputError(
            path,
            [
                f"holds no critical-kick search of {source} (another config or another "
                "kind of file); remove it or give another --out"
            ],
        )
    return ds


#: The bracket arrays (``results/kicks.py``) and the variables that hold them.
BRACKET_VARIABLES = {
    "low": "critical_kick_low",
    "high": "critical_kick",
    "peak_low": "lnv_peak_below",
    "peak_high": "lnv_peak_above",
    "regime_high": "regime_above",
    "status": "critical_kick_status",
    "probe": "kick_probe",
    "peak_probe": "lnv_peak_probe",
}


def _brackets(ds):
    """The flat bracket arrays of a critical-kick Dataset (``results/kicks.py``)."""
    out = {k: ds[v].values.ravel().copy() for k, v in BRACKET_VARIABLES.items()}
    out["regime_high"] = np.where(
        np.isnan(out["regime_high"].astype(float)), -1, out["regime_high"]
    )
    out["regime_high"] = out["regime_high"].astype(np.int8)
    out["status"] = out["status"].astype(np.int8)
    return out


def _point_values(ds, dims):
    """Values of the other axes at every flat point (C order): name → 1-D array."""
    mesh = np.meshgrid(*(ds[d].values for d in dims), indexing="ij")
    return {d: m.ravel() for d, m in zip(dims, mesh, strict=True)}


def _outcomes(config, points, backend, progress, desc):
    """Regime codes (as :func:`~sweep.results.kicks.outcomes` reads them) and lnv_peak of
    runs at ``points`` (axis name → values)."""
    grid = build_grid(config, points)
    backend.compile(grid.params, grid.settings)
    bar = Progress(grid.n, desc=desc, enabled=progress)
    try:
        results, _ = integrate_in_memory(
            grid.params, grid.y0, grid.settings, progress=bar, backend=backend
        )
    finally:
        bar.close()
    peak = results[:, layout.R_LNV_MAX_RUN]
    lnv_cap = np.log(config.classification.v_cap_over_V)
    return kicks.outcomes(results[:, layout.R_REGIME].astype(np.int8), peak, lnv_cap), peak


def _dataset(template, axis, brackets, runs, shape, dims, rtol, rounds, key):
    """The critical-kick Dataset of the brackets so far, with the search's attributes."""
    searched = (template.attrs["kick_min"], template.attrs["kick_max"])
    ds = kicks.kick_dataset(template, axis, searched, brackets, runs, shape, dims)
    ds.attrs.update(
        kick_rtol_target=float(rtol),
        kick_rounds=np.int32(rounds),
        kick_config=key,
    )
    return ds
