"""The critical kick against a swept parameter (``results/kicks.py``).

One curve per critical-kick Dataset (e.g. one per state law or velocity cap), or per value
of a second axis: each found threshold as its bracket (a bar from the largest kick that
returned to the smallest that left) with a marker at its geometric mean, filled where the
threshold is sharp and open where the cap sets it; "none up to the largest kick tried" as
a triangle up at that kick, "the smallest kick tried already leaves" as a triangle down.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..codes import code
from ..results.kicks import KICK_STATUSES, THRESHOLD_KINDS
from .common import _figure_and_axes, _suptitle, axis_label, describe, dimensionless_text

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: The kick's symbol on the y axis, per start axis.
SYMBOLS = {"initial_v_over_V": "v0/V", "initial_phi_over_phi_ss": "Φ0/Φss"}
#: Factor between the "none up to the largest kick" markers of successive curves.
NONE_LIFT = 1.5
#: Most curves one figure draws (values of a second axis).
MAX_CURVES = 8
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000")


def plot_critical_kick(
    datasets: xarray.Dataset | list,
    labels: list | None = None,
    caption: str = "",
    ax: Axes | None = None,
) -> Figure:
    """The critical kick against the swept parameter (K/Kc where K/W is swept).

    Parameters
    ----------
    datasets : xarray.Dataset or list of them
        Critical-kick Datasets (:func:`sweep.critical_kick`,
        :func:`sweep.bisect_critical_kick`) over one axis, or over two (one curve per
        value of the second, at most :data:`MAX_CURVES`).
    labels : list of str, optional
        One per Dataset (default: its state law and velocity cap).
    caption : str, optional
        A line under the title.
    ax : matplotlib.axes.Axes, optional
        Draw there (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.ticker import FuncFormatter

    datasets = datasets if isinstance(datasets, (list, tuple)) else [datasets]
    if labels is not None and len(labels) != len(datasets):
        raise ValueError(f"labels: {len(labels)} given for {len(datasets)} datasets")
    fig, ax = _figure_and_axes(ax, (7.0, 4.8))
    curves = []
    for i, ds in enumerate(datasets):
        label = labels[i] if labels is not None else _default_label(ds, len(datasets))
        curves += _curves(ds, label)
    if len(curves) > MAX_CURVES:
        raise ValueError(f"{len(curves)} curves: at most {MAX_CURVES} (select fewer values)")
    for i, ((ds, label), colour) in enumerate(zip(curves, COLOURS, strict=False)):
        _draw(ax, ds, label, colour, NONE_LIFT**i)
    first = datasets[0]
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(_plain))
    if _few_decades(ax):  # minor ticks get numbers too
        ax.yaxis.set_minor_formatter(FuncFormatter(_plain))
    ax.set_ylabel(f"critical kick {SYMBOLS[first.attrs['kick_axis']]}")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    rtol = np.nanmax([float(d["critical_kick_rtol"].max()) for d in datasets])
    title = describe(first)
    if len({d.attrs["state_law"] for d in datasets}) > 1:  # the laws are in the legend
        title = title.replace(f", {first.attrs['state_law']} law", "")
    lines = [
        title,
        f"{dimensionless_text(first)}; start {_start_text(first)}; runaway past "
        f"{_caps_text(datasets)}; brackets to "
        f"{100 * rtol:.2g} % (bars); ● sharp (10 % below it the peak v stays 10× under the "
        "cap), ○ set by the cap, ■ to another attractor; ▲ none up to the largest kick tried "
        "(drawn at and above it)",
        caption,
    ]
    _suptitle(fig, lines)
    return fig


def _plain(y, _position):
    """A tick label: the number as ``:g`` (module level, so that the Figure pickles)."""
    return f"{y:g}"


def _few_decades(ax):
    """Whether the y range spans less than a decade."""
    low, high = ax.get_ylim()
    return high / low < 10.0


def _caps_text(datasets):
    """The velocity caps of the datasets, e.g. ``"v/V = 1e+06"``."""
    caps = dict.fromkeys(f"{float(d.attrs['classification_v_cap_over_V']):.0e}" for d in datasets)
    return "v/V = " + ", ".join(caps)


def _default_label(ds, n):
    cap = float(ds.attrs["classification_v_cap_over_V"])
    return f"{ds.attrs['state_law']} law, cap v/V = {cap:.0e}" if n > 1 else "critical kick"


def _start_text(ds):
    """The start apart from the kick, e.g. ``"Φ/Φss = 1"`` for a velocity kick."""
    if ds.attrs["kick_axis"] == "initial_v_over_V":
        phi = np.atleast_1d(ds.attrs["initial_phi_over_phi_ss"])
        return "Φ/Φss = " + ", ".join(f"{x:g}" for x in phi)
    v = np.atleast_1d(ds.attrs["initial_v_over_V"])
    return "v/V = " + ", ".join(f"{x:g}" for x in v)


def _curves(ds, label):
    """``[(1-D dataset, label)]``: the dataset, or one per value of its second axis."""
    dims = ds["critical_kick"].dims
    if len(dims) == 1:
        return [(ds, label)]
    if len(dims) != 2:
        raise ValueError(
            f"critical kick over {len(dims)} axes: plot_critical_kick draws one or two"
        )
    other = dims[1]
    return [
        (ds.isel({other: j}), f"{label}, {other} = {float(ds[other][j]):.3g}")
        for j in range(ds.sizes[other])
    ]


def _draw(ax, ds, label, colour, lift):
    """One curve: brackets, markers by kind, and the points without a threshold (those
    with none up to the largest kick drawn ``lift`` times above it, so that curves that
    share them stay apart)."""
    (dim,) = ds["critical_kick"].dims
    if dim == "K_W" and "K_over_Kc" in ds:
        x = ds["K_over_Kc"].values
        ax.set_xlabel("K/Kc (Kc of the linear theory)")
    else:
        x = ds[dim].values
        ax.set_xlabel(axis_label(ds[dim]))
    lo, hi = ds["critical_kick_low"].values, ds["critical_kick"].values
    status, kind = ds["critical_kick_status"].values, ds["kick_threshold"].values
    mid = np.sqrt(lo * hi)
    found = status == code(KICK_STATUSES, "found")
    ax.vlines(x[found], lo[found], hi[found], colors=colour, lw=2.0)
    ax.plot(x[found], mid[found], "-", color=colour, lw=0.8, alpha=0.6)
    sharp = found & (kind == code(THRESHOLD_KINDS, "sharp"))
    capped = found & (kind == code(THRESHOLD_KINDS, "cap_limited"))
    if sharp.any():
        ax.plot(x[sharp], mid[sharp], "o", color=colour, ms=5, label=f"{label}: sharp")
    basin = found & (kind == code(THRESHOLD_KINDS, "basin_boundary"))
    if basin.any():
        ax.plot(
            x[basin], mid[basin], "s", color=colour, ms=5, label=f"{label}: to another attractor"
        )
    if capped.any():
        ax.plot(
            x[capped],
            mid[capped],
            "o",
            mfc="white",
            mec=colour,
            ms=6,
            label=f"{label}: cap-limited",
        )
    none = status == code(KICK_STATUSES, "none_up_to_max")
    if none.any():
        top = np.full(none.sum(), ds.attrs["kick_max"] * lift)
        ax.plot(x[none], top, "^", color=colour, ms=7, label=f"{label}: none up to the max")
    unsure = status == code(KICK_STATUSES, "undecided")
    if unsure.any():
        middle = np.full(unsure.sum(), np.sqrt(ds.attrs["kick_min"] * ds.attrs["kick_max"]))
        ax.plot(x[unsure], middle, "x", color="#999999", ms=7, label=f"{label}: undecided")
    below = status == code(KICK_STATUSES, "below_min")
    if below.any():
        low = np.full(below.sum(), ds.attrs["kick_min"])
        ax.plot(x[below], low, "v", color=colour, ms=7, label=f"{label}: below the min")
