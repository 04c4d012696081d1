"""The Dataset of a refined sweep: the runs of every level along one ``point`` dimension.

A refinement (``sweep/refine/lattice.py``) runs points on lattices of different levels, so its
result is not a grid: every run is a *point* with the swept parameters as coordinates
on it (``K_W(point)``, ...), its ``level`` (0: the config's grid) and its integer
index on the finest lattice (``K_W_index(point)``, ...). Data variables are those of a
grid result with ``point`` in place of the sweep axes, from the same table
(``sweep/variables.py``) and constructor (``dataset.data_variables``); the file is a CF
discrete sampling geometry of feature type ``point`` (``featureType = "point"``), and
the run counts of each level are file attributes (``refine_runs``). Plain xarray opens
it; :func:`to_grid` puts it on the regular grid of any level, where every grid tool and
figure works.
"""

import dataclasses

import numpy as np
import xarray as xr

from ..config import parse_stored_config
from ..errors import ConfigError, InputError
from ..results.dataset import (
    data_variables,
    derived_fields,
    parameter_attrs,
    parameter_coords,
    provenance,
)
from .lattice import STOPPED, Lattice, axis_values

#: The dimension of the runs of a refinement.
POINT = "point"
#: Largest grid :func:`to_grid` builds (points): a finer level of a large sweep would
#: fill memory with copies of the same runs.
MAX_GRID_POINTS = 50_000_000


def index_name(axis):
    """Name of the coordinate holding the finest-lattice index along ``axis``."""
    return f"{axis}_index"


def build_point_dataset(config, refinement, grid, results, y_final, command="run"):
    """The result Dataset of a refinement from the kernels' outputs of all its points.

    ``refinement``: the finished :class:`~sweep.refine.lattice.Refinement`; ``grid``, ``results``,
    ``y_final``: the :class:`~sweep.engine.grid.Grid` of its points in order (level by level,
    each in C order) and their runs. ``command`` as for ``dataset.provenance``.
    """
    index = refinement.index
    lattice = refinement.lattice
    data_vars = data_variables(
        config, derived_fields(grid, results, y_final), shape=(len(index),), dims=(POINT,)
    )
    coords = {
        name: coord for name, coord in parameter_coords(config).items() if name not in lattice.names
    }
    values = lattice.values(index)
    for i, name in enumerate(lattice.names):
        coords[name] = (POINT, values[name], parameter_attrs(name))
        coords[index_name(name)] = (
            POINT,
            index[:, i],
            {"long_name": f"index of {name} on the lattice of level refine_levels", "units": "1"},
        )
    coords["level"] = (
        POINT,
        lattice.point_levels(index),
        {"long_name": "refinement level of the point (0: the grid of the config)", "units": "1"},
    )
    per_level = np.array([len(p) for p in refinement.planned], np.int32)
    attrs = provenance(config, command)
    attrs.update(
        featureType="point",
        refine_levels=np.int32(lattice.levels),
        refine_outputs=" ".join(config.refine.outputs),
        refine_rtol=config.refine.rtol,
        refine_points=per_level,
        refine_runs=per_level * np.int32(config.members),
        refine_stopped=STOPPED[refinement.stopped],
    )
    if config.refine.max_runs is not None:
        attrs["refine_max_runs"] = np.int32(config.refine.max_runs)
    ds = xr.Dataset(data_vars, coords=coords, attrs=attrs)
    for name in ds.coords:
        ds[name].encoding["_FillValue"] = None  # CF: coordinates hold no missing values
    return ds


def is_refined(ds):
    """Whether ``ds`` is a refined result (runs along ``point``, ``featureType`` point)."""
    return POINT in ds["regime"].dims and ds.attrs.get("featureType") == "point"


def refined_config(ds, source="result"):
    """The validated config stored in a refined result (``config_text``); raises
    :class:`~sweep.errors.InputError` naming ``source`` for any other Dataset."""
    if "regime" not in ds or not is_refined(ds) or "config_text" not in ds.attrs:
        raise InputError(source, ["not a refined result (runs along point, featureType point)"])
    try:
        config = parse_stored_config(
            ds.attrs["config_text"], f"{source} (config_text)", ds.attrs.get("integrator_method")
        )
    except ConfigError as exc:
        raise ConfigError(source, [f"stored config_text: {p}" for p in exc.problems]) from None
    if config.refine is None:
        raise InputError(source, ["its stored config has no refine section"])
    return dataclasses.replace(config, source=ds.attrs.get("config_path", str(source)))


def lattice_index(ds, lattice):
    """Indices (n, d) of a refined result's points on the finest lattice."""
    missing = [index_name(name) for name in lattice.names if index_name(name) not in ds]
    if missing:
        raise ValueError(f"not a complete refined result: no {', '.join(missing)}")
    return np.stack([ds[index_name(name)].values for name in lattice.names], axis=-1).astype(
        np.int64
    )


def to_grid(ds: xr.Dataset, level: int = 0) -> xr.Dataset:
    """A refined result on the regular grid of ``level``: a Dataset like a grid sweep's.

    Every grid point takes the values of the run at it where there is one, else of the
    first run found by rounding it to the lattice of each level from ``level`` down to 0
    (per axis the nearer point, the lower at a tie): a run on the closed unsplit cell
    that holds it, at most half that cell's step away (a corner, or a point on its side
    run by a finer neighbour), so that where the cell's corners agree in the refine
    outputs the grid point has their values of them. The dimensions are the sweep axes
    at the level's values; the coordinate ``level`` gives the level of each value's run
    and ``exact`` whether it was run right there. At level 0 this is the grid of the
    config, run for run.

    Parameters
    ----------
    ds : xarray.Dataset
        A refined result (:func:`sweep.run` or ``python -m sweep run`` with a ``refine``
        section).
    level : int, default 0
        From 0 (the config's grid) to the result's ``refine_levels``.

    Returns
    -------
    xarray.Dataset
        The grid of ``level``: one dimension per sweep axis at that level's values,
        the data variables of the runs taken, and the coordinates ``level`` and
        ``exact``; the attributes of ``ds`` (without ``featureType``) and
        ``refine_grid_level``.

    Raises
    ------
    InputError
        ``ds`` is not a refined result (no runs along ``point`` with
        ``featureType`` point, or no stored config with a ``refine`` section).
    ValueError
        ``level`` is not an integer in [0, ``refine_levels``], or its grid would have
        more than :data:`MAX_GRID_POINTS` points.
    """
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be a refined result Dataset, got {type(ds).__name__}")
    config = refined_config(ds)
    lattice = Lattice(config)
    if not (isinstance(level, (int, np.integer)) and 0 <= level <= lattice.levels):
        raise ValueError(f"level must be an integer in [0, {lattice.levels}], got {level!r}")
    shape = tuple(int(e >> (lattice.levels - level)) + 1 for e in lattice.extent)
    if np.prod(shape, dtype=float) > MAX_GRID_POINTS:
        raise ValueError(
            f"the grid of level {level} has {np.prod(shape, dtype=float):.3g} points, more than "
            f"{MAX_GRID_POINTS:.3g}; take a coarser level"
        )
    grid = [np.arange(n, dtype=np.int64) << (lattice.levels - level) for n in shape]
    mesh = np.stack([m.ravel() for m in np.meshgrid(*grid, indexing="ij")], axis=-1)
    rows, exact = nearest_runs(lattice, lattice_index(ds, lattice), mesh, level)
    dims = lattice.names
    drop = [*dims, *(index_name(name) for name in dims)]
    out = ds.drop_vars(drop).isel({POINT: xr.DataArray(rows.reshape(shape), dims=dims)})
    out = out.assign_coords(
        {
            a.name: (a.name, axis_values(a, g, lattice.levels), parameter_attrs(a.name))
            for a, g in zip(config.axes, grid, strict=True)
        }
    )
    out.coords["exact"] = (dims, exact.reshape(shape), {"long_name": "run at this grid point"})
    out = out.transpose(*dims, ...)
    out.attrs = {k: v for k, v in ds.attrs.items() if k != "featureType"}
    out.attrs["refine_grid_level"] = np.int32(level)
    for name in out.coords:
        out[name].encoding["_FillValue"] = None
    return out


def nearest_runs(lattice, index, targets, level):
    """For lattice points ``targets`` (m, d) of ``level``: the row of ``index`` (n, d,
    the runs) whose value each takes (see :func:`to_grid`) and whether it is exact.

    Rounds each target to the nearest point of every level from ``level`` down to 0
    (per axis, the lower at a tie) and takes the first that was run; at level 0 every
    point was. Rounding to a level's lattice stays inside the unsplit cell holding the
    target, whose corners lie on it.
    """
    keys = lattice.keys(index)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    rows = np.full(len(targets), -1, np.int64)
    exact = np.zeros(len(targets), bool)
    for L in range(level, -1, -1):
        todo = np.flatnonzero(rows < 0)
        if todo.size == 0:
            break
        step = lattice.step(L)
        t = targets[todo]
        r = t % step
        q = t - r + step * (r > step // 2)
        k = lattice.keys(q)
        at = np.minimum(np.searchsorted(sorted_keys, k), len(sorted_keys) - 1)
        found = sorted_keys[at] == k
        rows[todo[found]] = order[at[found]]
        if L == level:
            exact[todo[found]] = True
    if not (rows >= 0).all():
        raise ValueError(
            "this refined result lacks runs of its level-0 grid (a subset of its "
            "points?): a refined result is read whole"
        )
    return rows, exact


#: Most grid points of the grid a figure puts a refined result on (:func:`as_grid`).
DISPLAY_POINTS = 250_000


def display_level(ds, max_points=DISPLAY_POINTS):
    """The finest level of a refined result whose grid has at most ``max_points`` points
    (at least 0)."""
    lattice = Lattice(refined_config(ds))
    level = 0
    while level < lattice.levels:
        shape = [int(e >> (lattice.levels - level - 1)) + 1 for e in lattice.extent]
        if np.prod(shape, dtype=float) > max_points:
            break
        level += 1
    return level


def along_axis(ds):
    """A refined result of one refined axis as a 1-D result along it: its runs sorted by
    that axis, which becomes their dimension (the other axes' one values scalar)."""
    config = refined_config(ds)
    lattice = Lattice(config)
    (axis,) = [name for name, s in zip(lattice.names, lattice.split, strict=True) if s]
    out = ds.sortby(axis).swap_dims({POINT: axis})
    out = out.drop_vars([index_name(name) for name in lattice.names])
    for a in config.axes:
        if a.name != axis:
            out = out.assign_coords({a.name: ((), a.values[0], parameter_attrs(a.name))})
    out.attrs = {k: v for k, v in ds.attrs.items() if k != "featureType"}
    return out


def as_grid(ds):
    """A refined result as a grid result for the grid figures: along its axis if one is
    refined (:func:`along_axis`), else :func:`to_grid` at :func:`display_level`."""
    lattice = Lattice(refined_config(ds))
    if lattice.split.sum() == 1:
        return along_axis(ds)
    return to_grid(ds, display_level(ds))
