"""Time series of one trace (``sweep/commands/trace.py``): the slip velocity of every block
against time (:func:`plot_trace`; :func:`draw_trace` draws it on an axes of a larger
figure)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..results.checks import check_trace
from ..results.dataset import parameter_values
from .common import (
    REGIME_COLOURS,
    _figure_and_axes,
    axis_label,
    describe,
    initial_text,
    power_text,
)

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Line colour and width of blocks 1, 2, … in time series (colours kept apart from the
#: regimes'). Later blocks are wider and drawn underneath, so blocks moving in
#: synchrony show as a dark line with a coloured halo.
BLOCK_STYLES = (("#222222", 0.9), ("#CC79A7", 2.6), ("#8C6BB1", 4.2), ("#BBBBBB", 5.8))


def trace_summary(ds):
    """One line on how a trace ended: regime, and runaway time or period."""
    regime = ds.attrs["regime"]
    if regime == "runaway":
        cap = ds.attrs["classification_v_cap_over_V"]
        return f"runaway at t = {ds.attrs['t_runaway']:.4g} s (v > {power_text(cap)} V)"
    if regime == "stick_slip":
        return f"stick-slip, period {ds.attrs['period']:.3g} s"
    return regime.replace("_", "-")


def draw_trace(ax, ds, legend=True):
    """Block velocities of a trace against time on ``ax``.

    Log scale where the velocities span more than a decade; the load-point
    velocity V dotted; a runaway time marked by a vertical line; a label in
    the regime's colour says how the run ended.
    """
    t = ds["time"].values
    V = parameter_values(ds)["V"]
    lnv = ds["lnv"].values
    for b in range(ds.sizes["block"]):
        colour, width = BLOCK_STYLES[b % len(BLOCK_STYLES)]
        ax.plot(
            t,
            ds["velocity"].isel(block=b).values,
            color=colour,
            lw=width,
            zorder=3 - b / 10,
            label=f"block {b + 1}",
        )
    if np.nanmax(lnv) - np.nanmin(lnv) > np.log(10.0):
        ax.set_yscale("log")
    ax.axhline(V, color="#888888", ls=":", lw=1.0, label="load point V")
    regime = ds.attrs["regime"]
    if regime == "runaway":
        ax.axvline(ds.attrs["t_runaway"], color=REGIME_COLOURS["runaway"], lw=1.5)
    ax.text(
        0.02,
        0.95,
        trace_summary(ds),
        transform=ax.transAxes,
        va="top",
        fontsize=8.5,
        color="white",
        bbox={"boxstyle": "round", "facecolor": REGIME_COLOURS[regime], "lw": 0},
    )
    ax.set_xlim(0.0, t[-1])  # where the run ended (a runaway ends it early)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(axis_label(ds["velocity"]))
    if legend:
        ax.legend(loc="lower right", fontsize=8, framealpha=0.8)


def plot_trace(ds: xarray.Dataset, ax: Axes | None = None) -> Figure:
    """Slip velocity of every block against time, of one trace.

    The time axis ends where the run ended; the title names the parameters, K/Kc
    and the start.

    Parameters
    ----------
    ds : xarray.Dataset
        A trace: :func:`sweep.commands.trace.compute_trace`, or a file written by
        ``python -m sweep trace``.
    ax : matplotlib.axes.Axes, optional
        Draw there (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or the figure of ``ax``.

    Raises
    ------
    TypeError
        ``ds`` is not a Dataset.
    ValueError
        ``ds`` is not a trace, or lacks what its run wrote (a file edited since).
    """
    check_trace(ds)
    fig, ax = _figure_and_axes(ax, (8, 4.2))
    draw_trace(ax, ds)
    ratio = f"K/Kc = {ds.attrs['K_over_Kc']:.3g}"
    ax.set_title(f"{describe(ds)}\n{ratio}; {initial_text(ds)}", fontsize=9.5)
    return fig
