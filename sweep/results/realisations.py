"""Statistics over realisations of the disorder: the mean, spread and count of each output
over the seeds of a sweep axis ``spread_seed`` (``sweep/model/heterogeneity.py``).

Each seed is one draw of the blocks' pattern ξ, so an output at one point of the other
axes is a sample of its distribution over the disorder. :func:`over_realisations`
reduces that sample, NaN-aware (a b-value that is NaN at some seeds counts only where it
is finite), to three variables per output, named and marked by the CF ``cell_methods``
convention (CF-1.11, section 7.3 and appendix E, methods ``mean`` and
``standard_deviation``): ``<name>_mean``, ``<name>_std`` (the sample standard deviation,
divisor count − 1; CF does not fix the divisor, the ``comment`` attribute says which) and
``<name>_count`` (finite values; CF has no counting method, so it carries no
``cell_methods``). The standard error of the mean is ``<name>_std / sqrt(<name>_count)``.
"""

import numpy as np
import xarray as xr

from ..model.heterogeneity import SEED_AXIS


def over_realisations(ds: xr.Dataset, dim: str = SEED_AXIS) -> xr.Dataset:
    """The mean, sample standard deviation and count of finite values of every numeric
    output over the realisations along ``dim``.

    Each numeric data variable with the dimension ``dim`` (floats; integer counts such
    as ``cycle_events`` too, as floats, with their ``_FillValue`` missing) gives
    ``<name>_mean``, ``<name>_std`` (divisor count − 1; NaN below two finite values) and
    ``<name>_count`` (int32), over its finite values only: NaN and ±inf count as missing,
    and the mean is NaN where none is finite. Labels (variables with ``flag_values``,
    e.g. ``regime`` and ``attractor``; booleans and text) have no mean: they are left
    out and named in the attribute ``realisations_skipped`` (the share of realisations
    in each label is ``(ds.regime == code).mean(dim)``). Variables without ``dim`` are
    left out too. An integer's special values other than its fill are numbers here
    (``cycle_events`` is 0 where a run is not periodic): mask such runs first, e.g.
    ``over_realisations(ds.where(ds.cycle_events > 0))``.

    Parameters
    ----------
    ds : xarray.Dataset
        A result with the dimension ``dim``, e.g. a sweep with the axis ``spread_seed``.
    dim : str, default spread_seed
        The dimension of the realisations.

    Returns
    -------
    xarray.Dataset
        The three variables per output over the other dimensions, with their units,
        ``long_name``, ``cell_methods`` and ``comment``; the coordinates of ``ds``
        without ``dim``; the attributes of ``ds`` and ``realisations_dim``,
        ``realisations`` (the length of ``dim``) and ``realisations_skipped``.

    Raises
    ------
    TypeError
        ``ds`` is not a Dataset.
    ValueError
        ``ds`` has no dimension ``dim``.
    """
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be an xarray Dataset, got {type(ds).__name__}")
    if dim not in ds.dims:
        raise ValueError(
            f"ds has no dimension {dim!r} (its dimensions: {', '.join(map(str, ds.dims))}); "
            f"sweep the seeds with the axis {SEED_AXIS}"
        )
    out = {}
    skipped = []
    for name, da in ds.data_vars.items():
        if dim not in da.dims:
            continue
        if "flag_values" in da.attrs or da.dtype.kind not in "iuf":
            skipped.append(str(name))
            continue
        out |= _statistics(name, da, dim)
    coords = {name: c for name, c in ds.coords.items() if dim not in c.dims}
    attrs = {
        **ds.attrs,
        "realisations_dim": dim,
        "realisations": np.int32(ds.sizes[dim]),
        "realisations_skipped": ", ".join(skipped),
    }
    return xr.Dataset(out, coords=coords, attrs=attrs)


def _statistics(name, da, dim):
    """``{name_mean, name_std, name_count}`` of one variable ``da`` over ``dim``."""
    values = da.astype(float)
    fill = da.attrs.get("_FillValue", da.encoding.get("_FillValue"))
    if da.dtype.kind in "iu" and fill is not None:
        values = values.where(da != fill)
    finite = np.isfinite(values)
    count = finite.sum(dim)
    zeroed = values.where(finite, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (zeroed.sum(dim) / count).where(count > 0)
        squares = ((values - mean) ** 2).where(finite, 0.0).sum(dim)
        std = np.sqrt(squares / (count - 1)).where(count > 1)
    units = da.attrs.get("units", "1")
    what = da.attrs.get("long_name", str(name))
    finite_only = f"over the finite values along {dim} (NaN where none)"
    return {
        f"{name}_mean": mean.assign_attrs(
            units=units,
            long_name=f"mean of {what} over realisations",
            cell_methods=f"{dim}: mean",
            comment=f"arithmetic mean {finite_only}",
        ),
        f"{name}_std": std.assign_attrs(
            units=units,
            long_name=f"standard deviation of {what} over realisations",
            cell_methods=f"{dim}: standard_deviation",
            comment=f"sample standard deviation (divisor count - 1) {finite_only}; NaN "
            "below two finite values",
        ),
        f"{name}_count": count.astype(np.int32).assign_attrs(
            units="1",
            long_name=f"realisations with a finite {what}",
            comment=f"number of finite values of {name} along {dim}",
        ),
    }
