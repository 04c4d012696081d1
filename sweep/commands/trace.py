"""Single-system traces: the full time series of one grid point of a config.

A trace pins every sweep axis of a config to one value (``--at K_W=0.046``),
integrates that one system with the same kernel as a sweep
(``dispatch.integrate_grid``, recording the state on a fine uniform time grid)
and keeps a decimated time series: in each of ``points`` time bins the first
sample and the samples where some block's ln(v/V) is largest and smallest, so
slip peaks and stick troughs survive decimation, plus the final state. The
result is an xarray Dataset with dimensions ``time`` and ``block``.

A trace always runs to the end time (early exit is off, so a settled or
decayed run is followed to the end), except that a runaway ends it, exactly
as in a sweep.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..config import Config, ConfigError, with_changes
from ..engine.dispatch import integrate_grid
from ..engine.grid import build_grid
from ..errors import InputError
from ..kernels import layout
from ..model import physics
from ..model.heterogeneity import SEED_AXIS, SPREAD_AXES, SPREAD_PREFIX
from ..model.physics import INITIAL_AXES, PARAMETERS
from ..results.dataset import (
    derived_fields,
    parameter_attrs,
    parameter_coords,
    provenance,
    without_coordinate_fill,
)
from ..variables import REGIMES, variables_for

#: Fine samples recorded per output point before decimation.
OVERSAMPLE = 50

#: The time series of a trace: name → (units, long_name).
TRACE_VARIABLES = {
    "velocity": ("um s-1", "slip velocity"),
    "lnv": ("1", "ln(v/V)"),
    "ln_state": ("1", "ln(Phi/Phi_ss)"),
    "friction": ("1", "friction coefficient mu0 + A ln(v/V0) + B ln(Phi/Phi0)"),
}


def pin_config(config: Config, at: Mapping[str, float], t_end: float | None = None) -> Config:
    """The one-system config of ``config`` at the parameter values ``at``.

    Early exit is switched off, so that a trace follows the run to its end time.

    Parameters
    ----------
    config : Config
        A sweep's config (:func:`sweep.load_config`).
    at : Mapping of str to float
        Parameter name → value, in physical units (e.g. ``{"K_W": 0.046}``, µm⁻¹).
        Every sweep axis must be given; a fixed parameter given here is overridden.
    t_end : float, optional
        A new end time, in the config's ``t_unit`` (default: the config's).

    Returns
    -------
    Config
        A config of one grid point, for :func:`compute_trace`.

    Raises
    ------
    InputError
        Listing every problem of ``at`` and ``t_end`` (an unknown parameter, a
        sweep axis without a value, a value out of range).
    """
    text = " ".join(f"--at {name}={value:g}" for name, value in at.items())
    source = f"{config.source} {text}".strip()
    known = (*PARAMETERS, *INITIAL_AXES, *SPREAD_AXES, SEED_AXIS)
    problems = [
        f"--at {name}: unknown parameter; known: {', '.join(known)}"
        for name in at
        if name not in known
    ]
    for axis in config.axes:
        if axis.name not in at:
            units = parameter_attrs(axis.name)["units"]
            problems.append(
                f"sweep axis {axis.name} needs a value: add --at {axis.name}=VALUE "
                f"(the sweep spans {min(axis.values):g} to {max(axis.values):g} {units})"
            )
    if problems:
        raise InputError(source, problems)
    swept = [axis.name for axis in config.axes]
    fixed = {k: float(v) for k, v in at.items() if k not in swept}
    changes = {
        "sweep": {name: [_pinned(name, at[name])] for name in swept},
        "parameters": {k: v for k, v in fixed.items() if k in PARAMETERS},
        "classification": {"early_exit": False},
    }
    spread_sizes = {k[len(SPREAD_PREFIX) :]: v for k, v in fixed.items() if k in SPREAD_AXES}
    if SEED_AXIS in fixed:
        spread_sizes["seed"] = _pinned(SEED_AXIS, fixed[SEED_AXIS])
    if spread_sizes:
        changes["spread"] = spread_sizes
    if t_end is not None:
        changes["integrator"] = {"t_end": float(t_end)}
        changes["classification"]["max_t_end"] = None  # no continuation without early exit
    # errors name the --at values; the result's provenance names the config file
    try:
        pinned = with_changes(config, changes, source)
    except ConfigError as exc:  # the values given, not the config, are at fault
        raise InputError(exc.source, exc.problems) from None
    return dataclasses.replace(pinned, source=config.source)


def _pinned(name, value):
    """A value given with ``--at``: a seed of ``spread_seed`` as an integer where it is
    one (the config's check names any other), other values as floats."""
    value = float(value)
    return int(value) if name == SEED_AXIS and value.is_integer() else value


def decimate(lnv, points):
    """Indices of samples to keep from a fine time series of ln(v/V) (time × block).

    The series is cut into ``points`` bins of equal sample count; each keeps
    its first sample and, for every block, its samples of largest and smallest
    ln(v/V). The last sample is always kept. Returns sorted unique indices.
    """
    n = lnv.shape[0]
    if n <= points:
        return np.arange(n)
    width = math.ceil(n / points)
    bins = math.ceil(n / width)
    padded = np.full((bins * width, lnv.shape[1]), np.nan)
    padded[:n] = lnv
    blocks = padded.reshape(bins, width, lnv.shape[1])
    start = np.arange(bins)[:, None] * width
    high = np.where(np.isnan(blocks), -np.inf, blocks).argmax(axis=1) + start
    low = np.where(np.isnan(blocks), np.inf, blocks).argmin(axis=1) + start
    keep = np.concatenate([start[:, 0], high.ravel(), low.ravel(), [n - 1]])
    return np.unique(keep[keep < n])


def compute_trace(config: Config, points: int = 4000) -> xr.Dataset:
    """Integrate the single system of a pinned config and keep its time series.

    Parameters
    ----------
    config : Config
        A config of one grid point (:func:`pin_config`).
    points : int, default 4000
        Number of time bins of the decimated series (each keeps up to
        1 + 2 × blocks samples, so every slip peak and stick trough survives).

    Returns
    -------
    xarray.Dataset
        The trace: ``velocity`` (µm/s), ``lnv``, ``ln_state`` and ``friction`` over
        (``block``, ``time`` in s); every model parameter a scalar coordinate; the
        run's regime, ``t_runaway`` and the other statistics of the sweep's schema
        as attributes. :func:`sweep.plot_trace` draws it.

    Raises
    ------
    ValueError
        The config has more than one grid point.
    """
    if math.prod(config.shape) != 1:
        raise ValueError(
            f"a trace integrates one system; this config has {config.shape} grid points"
        )
    grid = build_grid(config)
    params, y0, settings, time_unit = grid.params, grid.y0, grid.settings, grid.time_unit
    fine = points * OVERSAMPLE
    rec_t = np.empty(fine + 1)
    rec_y = np.empty((fine + 1, y0.shape[1]))
    result = np.empty((1, layout.result_width(settings)))
    y_final = np.empty_like(y0)
    rec_dt = params[0, layout.P_TAU_END] / (fine - 1)
    integrate_grid(params[:1], y0[:1], settings, result, y_final, rec_dt, rec_t, rec_y)
    n = int(result[0, layout.R_N_RECORDED])
    nb = config.blocks
    keep = decimate(rec_y[:n, :nb], points)
    lnv = rec_y[keep, :nb]
    psi = rec_y[keep, nb : 2 * nb]
    first = {name: values[0] for name, values in grid.physical.items()}
    mu_ss = physics.steady_friction(first["mu0"], first["A"], first["B"], first["V"], first["V0"])
    with np.errstate(over="ignore"):
        series = {
            "velocity": first["V"] * np.exp(lnv),
            "lnv": lnv,
            "ln_state": psi,
            "friction": mu_ss + first["A"] * lnv + first["B"] * psi,
        }
    data_vars = {  # block before time: CF wants other dimensions left of T
        name: (
            ("block", "time"),
            values.T,
            dict(zip(("units", "long_name"), TRACE_VARIABLES[name], strict=True)),
        )
        for name, values in series.items()
    }
    time_attrs = {"units": "s", "long_name": "time since the start", "standard_name": "time",
                  "axis": "T"}  # fmt: skip
    coords = {"time": ("time", rec_t[keep] * time_unit[0], time_attrs)}
    coords.update(parameter_coords(config))
    for axis in config.axes:  # each pinned to one value: a scalar coordinate
        coords[axis.name] = ((), axis.values[0], parameter_attrs(axis.name))
    ds = xr.Dataset(data_vars, coords=coords, attrs=trace_attributes(grid, result, y_final))
    return without_coordinate_fill(ds)


def trace_attributes(grid, result, y_final):
    """Provenance of a trace plus its pinned parameters and run statistics (with units)."""
    config, time_unit = grid.config, grid.time_unit
    attrs = provenance(config, "trace")
    attrs["title"] = f"Rice-Ruina spring-block trace: {config.name}"
    attrs["time_sampling"] = (
        f"decimated from a uniform grid: per bin the first sample and each block's "
        f"largest and smallest ln(v/V) ({OVERSAMPLE} fine samples per output point), "
        "plus the final state"
    )
    attrs["t_end"] = float(grid.params[0, layout.P_TAU_END] * time_unit[0])
    attrs["t_end_units"] = "s"
    fields = derived_fields(grid, result, y_final)
    for var in variables_for(config.blocks, config.model, config.features):
        if var.per_block or var.per_regime or var.per_event:
            continue
        value = fields[var.name][0]
        if var.name == "regime":
            attrs["regime"] = REGIMES[int(value)]
            continue
        attrs[var.name] = value.item()
        attrs[f"{var.name}_units"] = var.units
    return attrs
