"""
Write, reopen and map a result
==============================

A result is an :class:`xarray.Dataset`. Written to NetCDF, it opens with plain xarray
(nothing from this package needed), with units and long names on every variable and
the fixed parameters as scalar coordinates. Any variable maps over the sweep axes.
"""

import tempfile
from pathlib import Path

import xarray as xr

import sweep
from sweep import write_netcdf

config = sweep.with_changes(
    "oneblock",
    {"sweep": {"K_W": {"start": 0.035, "stop": 0.06, "num": 6}}, "integrator": {"t_end": 500}},
)
ds = sweep.run(config, progress=False)

out = Path(tempfile.mkdtemp())
path = write_netcdf(ds, out / "oneblock.nc")
with xr.open_dataset(path) as result:
    print(f"A = {float(result['A'])} ({result['A'].attrs['long_name']})")
    print("t_final in", result["t_final"].attrs["units"])

# %%
# The time each run stopped: early exit ends settled runs long before the end time.
fig = sweep.plot_variable(ds, "t_final")
fig
