"""Basin fractions of an initial-condition ensemble (``results/basins.py``) as a figure.

Over one sweep axis, the fraction of the starts reaching an attractor against the axis
with its 95 % Wilson interval as a band (and the fraction unresolved); over two, a map of
the fraction beside a map of the interval's width. The caption states every fixed
parameter, the model's dimensionless number, K/Kc, the law, the ensemble's amplitude and
its members.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .common import (
    _edges,
    _figure_and_axes,
    _log_spaced,
    _suptitle,
    axis_label,
    colormap,
    describe,
    dimensionless_text,
    initial_text,
    new_figure,
)

if TYPE_CHECKING:
    import xarray
    from matplotlib.figure import Figure


def plot_basin_fractions(
    ds_basins: xarray.Dataset, attractor: str = "cycle_1ev", caption: str = ""
) -> Figure:
    """The fraction of an ensemble's starts reaching ``attractor`` over the sweep.

    Parameters
    ----------
    ds_basins : xarray.Dataset
        From :func:`~sweep.results.basins.basin_fractions`, over one or two sweep axes
        (axes of length one are taken).
    attractor : str, default cycle_1ev
        A value of its ``attractor`` coordinate, e.g. ``steady`` or ``cycle_1ev``.
    caption : str, optional
        A line under the title.

    Returns
    -------
    matplotlib.figure.Figure
        One panel over one axis (the fraction with its Wilson band, the unresolved
        fraction dashed); two panels over two (the fraction, the interval's width).

    Raises
    ------
    ValueError
        ``attractor`` is not in ``ds_basins``, or it has more than two sweep axes.
    """
    names = [str(a) for a in ds_basins["attractor"].values]
    if attractor not in names:
        raise ValueError(
            f"attractor {attractor!r} is not in this result; its attractors: {', '.join(names)}"
        )
    one = ds_basins.sel(attractor=attractor)
    axes = [d for d in one["basin_fraction"].dims if one.sizes[d] > 1]
    one = one.isel({d: 0 for d in one["basin_fraction"].dims if d not in axes})
    if len(axes) > 2:
        raise ValueError(f"plot_basin_fractions draws one or two sweep axes, not {axes}")
    if len(axes) == 2:
        fig = _maps(one, axes)
    else:
        fig, ax = _figure_and_axes(None, (7.5, 4.6))
        _line(ax, one, axes[0] if axes else one["basin_fraction"].dims[0], attractor)
    _suptitle(fig, [f"fraction of the starts reaching {attractor}", *_caption(ds_basins), caption])
    return fig


def _line(ax, one, axis, attractor):
    """The fraction against ``axis`` with its Wilson band and the unresolved fraction."""
    line = one.sortby(axis)
    x = line[axis].values
    ax.fill_between(
        x,
        line["basin_fraction_low"].values,
        line["basin_fraction_high"].values,
        color="#009E73",
        alpha=0.25,
        lw=0,
        label="95 % Wilson interval",
    )
    ax.plot(x, line["basin_fraction"].values, "o-", color="#009E73", ms=4, label=attractor)
    ax.plot(x, line["unresolved_fraction"].values, "s--", color="#999999", ms=3, label="unresolved")
    if axis == "K_W" and "critical_K_W" in line:
        ax.axvline(float(line["critical_K_W"].max()), color="0.3", lw=0.8, ls=":", label=_kc(line))
    if _log_spaced(x):
        ax.set_xscale("log")
    ax.set_xlabel(axis_label(line[axis]))
    ax.set_ylabel("fraction of the starts")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=8, loc="best")


def _kc(ds):
    """Legend text of the line K = Kc, with the Hopf bifurcation's kind there if known."""
    if "hopf_criticality" not in ds:
        return "Kc"
    kinds = ds["hopf_criticality"].attrs["flag_meanings"].split()
    return f"Kc ({kinds[int(ds['hopf_criticality'].max())]} Hopf)"


def _maps(one, axes):
    """Two panels over ``axes``: the fraction and the width of its Wilson interval."""
    fig = new_figure(figsize=(11.0, 4.6))
    left, right = fig.subplots(1, 2)
    y_axis, x_axis = axes
    grid = one.transpose(y_axis, x_axis)
    x, y = _edges(grid[x_axis].values), _edges(grid[y_axis].values)
    width = grid["basin_fraction_high"] - grid["basin_fraction_low"]
    for ax, values, label, cmap in (
        (left, grid["basin_fraction"], "fraction of the starts", "viridis"),
        (right, width, "width of the 95 % Wilson interval", "magma"),
    ):
        mesh = ax.pcolormesh(x, y, values.values, cmap=colormap(cmap), vmin=0.0, vmax=1.0)
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set_xlabel(axis_label(grid[x_axis]))
        ax.set_ylabel(axis_label(grid[y_axis]))
        if _log_spaced(grid[x_axis].values):
            ax.set_xscale("log")
        if _log_spaced(grid[y_axis].values):
            ax.set_yscale("log")
    return fig


def _caption(ds):
    """Caption lines: the model and fixed parameters, the dimensionless numbers, K/Kc,
    the ensemble."""
    ratio = ds["K_over_Kc"].values if "K_over_Kc" in ds else np.array([np.nan])
    ratio = np.unique(np.round(np.asarray(ratio, float).ravel(), 6))
    ratio_text = (
        ", ".join(f"{r:.4g}" for r in ratio)
        if ratio.size <= 4
        else f"{ratio[0]:.4g} to {ratio[-1]:.4g}"
    )
    ensemble = (
        f"{int(ds['members'].max())} members per point, offsets uniform in "
        f"±{float(ds.attrs.get('initial_amplitude', np.nan)):g} of ln(v/V) and ln(Φ/Φss) "
        f"(seed {ds.attrs.get('initial_seed', '?')}) about the {initial_text(ds)}"
    )
    return [describe(ds), f"{dimensionless_text(ds)}; K/Kc = {ratio_text}", ensemble]
