"""A tour of the Python API: sweep → open → plot → compare models.

    python examples/gallery.py [OUT_DIR] [--quick]

Runs a packaged example, saves and reopens the result with plain xarray, maps a
few variables, then compares the quasi-static model with radiation damping
(quasi-dynamic) on one K/W axis and combines the two along the damping. Figures
and files go to OUT_DIR (default ``gallery``). ``--quick`` uses small grids and
short runs (the test suite runs it so, tests/test_examples.py); each step runs as
in a notebook cell.
"""

import sys
from pathlib import Path

import xarray as xr

import sweep
from sweep import write_netcdf


def main(out_dir="gallery", quick=False):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    num = 7 if quick else 41
    short = {"integrator": {"t_end": 500}} if quick else {}

    # 1. Sweep: a packaged example, with a finer or coarser K/W axis
    config = sweep.with_changes(
        "oneblock", {"sweep": {"K_W": {"start": 0.04, "stop": 0.06, "num": num}}, **short}
    )
    ds = sweep.run(config, progress=False)
    print(ds["regime"].attrs["flag_meanings"], ds["regime"].values)

    # 2. Open: write the file and read it back with xarray alone
    path = write_netcdf(ds, out / "oneblock.nc")
    with xr.open_dataset(path) as result:
        print(f"A = {float(result['A'])} ({result['A'].attrs['long_name']})")

    # 3. Plot: the phase diagram and any variable, each a matplotlib Figure
    sweep.save_figure(sweep.plot_result(ds), out / "phase.png")
    sweep.save_figure(sweep.plot_variable(ds, "t_final"), out / "t_final.svg")

    # 4. Compare models: radiation damping turns the runaway into stick-slip cycles
    damped = sweep.with_changes(
        config,
        {"name": "damped", "model": "quasi-dynamic", "parameters": {"eta_W": 0.1}},
    )
    qd = sweep.run(damped, progress=False)
    sweep.save_figure(sweep.plot_bifurcation([ds, qd]), out / "bifurcation.pdf")
    sweep.save_figure(sweep.plot_variable(qd, "v_max"), out / "v_max.png")
    # fixed parameters are coordinates: results combine along them
    both = xr.concat(
        [ds.assign_coords(eta_W=0.0), qd], dim="eta_W", coords="minimal", compat="override"
    )
    print(both["regime"].sizes, "stick-slip runs:", int((both["regime"] == 1).sum()))
    return sorted(p.name for p in out.iterdir())


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--quick"]
    for name in main(*args[:1], quick="--quick" in sys.argv):
        print("wrote", name)
