"""Result files: a result Dataset written to NetCDF atomically, and a result file (NetCDF
or Zarr) read back and checked to be a complete sweep result."""

from pathlib import Path

import xarray as xr

from ..errors import InputError, RunError
from ..results.checks import RESULT_VARIABLES, missing_parts
from .files import ZARR_SUFFIX, replaced_atomically, require_zarr


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a result to a NetCDF file atomically (a temporary file, then a rename).

    Data variables are compressed (zlib, level 4); coordinates get no fill value
    (CF). A failed write leaves an earlier file at ``path`` as it was.

    Parameters
    ----------
    ds : xarray.Dataset
        A result (:func:`sweep.run`) or a trace (:func:`sweep.commands.trace.compute_trace`).
    path : str or pathlib.Path
        The file; missing folders are created.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    encoding = {name: {"zlib": True, "complevel": 4} for name in ds.data_vars}
    encoding.update({name: {"_FillValue": None} for name in ds.coords})  # CF: none on coordinates
    with replaced_atomically(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", encoding=encoding)
    return path


def read_result(path: str | Path, needs_config: bool = False) -> xr.Dataset:
    """Load a result file into memory and check that it is a complete sweep result.

    The file is closed again, so it can be replaced while the result is in use
    (``xarray.open_dataset`` alone keeps it open and reads lazily).

    Parameters
    ----------
    path : str or pathlib.Path
        A NetCDF result, or a ``.zarr`` store (needs zarr), which must be complete.
    needs_config : bool, default False
        The file must also hold the config that made it (``config_text``).

    Returns
    -------
    xarray.Dataset
        The result, in memory.

    Raises
    ------
    InputError
        Naming ``path``: it is missing or unreadable, not a sweep result, without
        ``config_text`` when ``needs_config`` asks for it, or has runs not yet
        computed (a Zarr store of a sweep in progress).
    """
    zarr = Path(path).suffix == ZARR_SUFFIX
    if zarr:
        require_zarr(path, "result")
    try:
        with xr.open_dataset(path, engine="zarr" if zarr else None, chunks=None) as ds:
            ds.load()
    except (OSError, ValueError) as exc:
        text = str(exc).strip() or type(exc).__name__
        why = "not a NetCDF file" if "IO backends" in text else text.splitlines()[0][:200]
        raise InputError(
            path,
            [
                f"cannot read result file: {why} (a result is the NetCDF "
                "file or Zarr store of rsf-sweep run)"
            ],
        ) from None
    missing = [v for v in RESULT_VARIABLES if v not in ds]
    if needs_config and "config_text" not in ds.attrs:
        missing.append("config_text attribute")
    if missing:
        raise InputError(path, [f"not a sweep result (no {', '.join(missing)})"])
    incomplete = missing_parts(ds)
    if incomplete:
        raise InputError(
            path,
            [
                f"not a complete sweep result: no {', '.join(incomplete)} (a "
                "file edited after the run, or from another version)"
            ],
        )
    pending = int((ds["regime"] < 0).sum())
    if pending:
        raise InputError(
            path,
            [
                f"{pending} of {ds['regime'].size} runs are not computed yet; finish the "
                "sweep first (python -m sweep run CONFIG --out PATH --resume)"
            ],
        )
    return ds


def write_result(ds, path, kept):
    """Write the NetCDF atomically; on failure say what is kept (``kept``) and how to go on."""
    try:
        write_netcdf(ds, path)
    except (OSError, RuntimeError) as exc:
        raise RunError(
            f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}; the finished "
            f"chunks stay in {kept}, rerun once this is fixed"
        ) from None
