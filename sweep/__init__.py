"""rsf-sweep: JIT-compiled parameter sweeps of the Rice–Ruina spring-block model.

Importing the package compiles nothing; kernels compile on first use::

    import sweep

    ds = sweep.run("quick")                      # a packaged example, a path or a mapping
    cfg = sweep.with_changes("quick", {"integrator": {"t_end": 5000}})
    ds2 = sweep.run(cfg, threads=2)
    sweep.plot_variable(ds, "period")            # a matplotlib Figure

Kernels: :func:`compile_kernels` (warm numba's cache before job arrays);
configs: :func:`load_config`, :func:`with_changes`, :func:`examples.names`;
figures: :func:`plot_result`, :func:`plot_variable`, :func:`plot_bifurcation`,
:func:`plot_orbit_diagram`, :func:`plot_trace`, :func:`plot_catalogue`, :func:`plot_floquet`,
:func:`plot_critical_kick`, :func:`plot_basin_fractions`, :func:`plot_threshold_sensitivity`
(``sweep/plot/``, one module per family); slip-event
statistics: :func:`catalogue_statistics`, against the slip threshold:
:func:`threshold_sensitivity`;
statistics over realisations of the disorder (seeds): :func:`over_realisations`;
traces: :func:`compute_trace`; the critical kick of a sweep over the start:
:func:`critical_kick`, by bisection: :func:`bisect_critical_kick`; the attractors an
ensemble's starts reach: :func:`basin_fractions`, :func:`members_needed`; refined results:
:func:`to_grid`, :func:`boundaries`;
files: :func:`read_result`, :func:`write_netcdf`; runs with parts, shards and Dask:
:func:`run_sweep`, :func:`merge_parts`, :class:`Resources`; extending and auditing a
result: :func:`extend_result`, :func:`extend_file`, :func:`audit_result`.
"""

from . import examples
from ._version import __version__ as __version__
from .api import compile_kernels, run
from .config import Config, load_config, parse_config, with_changes
from .errors import ConfigError, InputError, RunError, SweepError

_LAZY = {
    "plot_result": "plot",
    "plot_variable": "plot",
    "plot_bifurcation": "plot",
    "plot_orbit_diagram": "plot",
    "plot_trace": "plot",
    "save_figure": "plot",
    "plot_catalogue": "plot",
    "plot_floquet": "plot",
    "plot_critical_kick": "plot",
    "critical_kick": "results.kicks",
    "basin_fractions": "results.basins",
    "members_needed": "results.basins",
    "plot_basin_fractions": "plot",
    "bisect_critical_kick": "engine.kicks",
    "plot_threshold_sensitivity": "plot",
    "threshold_sensitivity": "commands.sensitivity",
    "catalogue_statistics": "results.catalogue_statistics",
    "over_realisations": "results.realisations",
    "to_grid": "refine.dataset",
    "boundaries": "refine.boundaries",
    "read_result": "io.netcdf",
    "write_netcdf": "io.netcdf",
    "run_sweep": "engine.runner",
    "merge_parts": "engine.runner",
    "Resources": "engine.backends",
    "compute_trace": "commands.trace",
    "pin_config": "commands.trace",
    "extend_result": "commands.extend",
    "extend_file": "commands.extend",
    "audit_result": "commands.audit",
}


def __getattr__(name):
    """Names imported on first use, so ``import sweep`` loads neither numba nor matplotlib."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'sweep' has no attribute {name!r}")


__all__ = [
    "audit_result",
    "basin_fractions",
    "bisect_critical_kick",
    "compile_kernels",
    "critical_kick",
    "compute_trace",
    "extend_file",
    "extend_result",
    "merge_parts",
    "pin_config",
    "read_result",
    "Resources",
    "run_sweep",
    "write_netcdf",
    "Config",
    "catalogue_statistics",
    "ConfigError",
    "InputError",
    "RunError",
    "examples",
    "load_config",
    "members_needed",
    "over_realisations",
    "parse_config",
    "plot_basin_fractions",
    "plot_bifurcation",
    "plot_catalogue",
    "plot_critical_kick",
    "plot_floquet",
    "plot_orbit_diagram",
    "plot_result",
    "plot_threshold_sensitivity",
    "plot_trace",
    "plot_variable",
    "run",
    "save_figure",
    "SweepError",
    "boundaries",
    "to_grid",
    "threshold_sensitivity",
    "with_changes",
]
