"""How stable each cycle is: the largest non-trivial Floquet multiplier of a sweep's runs.

Over one axis, |μ| of every periodic run against the axis, its marker saying whether μ
is real and positive (a fold of cycles where it reaches +1), real and negative (a period
doubling at −1) or one of a complex pair (a torus on the unit circle), with the types
of the boundaries between neighbouring points (``refine.boundary_types``); over two
axes, a map of |μ| (``plot_variable``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..refine.boundary_types import REAL_ANGLE
from .bifurcation import TYPE_COLOUR
from .common import TYPE_BOX, _figure_and_axes, axis_label, kind_text
from .maps import plot_variable

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Marker and label of each kind of largest multiplier.
KINDS = (
    ("real, positive (→ +1: fold)", "o", "tab:blue"),
    ("real, negative (→ −1: period doubling)", "v", "tab:red"),
    ("complex pair (→ |μ| = 1: torus)", "D", "tab:green"),
)


def multiplier_kind(argument):
    """0 real positive, 1 real negative, 2 complex (of :data:`KINDS`) for arguments
    (rad); −1 where NaN."""
    a = np.abs(np.asarray(argument, float))
    kind = np.where(a <= REAL_ANGLE, 0, np.where(a >= np.pi - REAL_ANGLE, 1, 2))
    return np.where(np.isfinite(a), kind, -1)


def plot_floquet(ds: xarray.Dataset, caption: str = "", ax: Axes | None = None) -> Figure:
    """The largest non-trivial Floquet multiplier's modulus of a sweep's periodic runs.

    Parameters
    ----------
    ds : xarray.Dataset
        A grid result with ``floquet_modulus`` and ``floquet_argument``.
    caption : str, optional
        A line under the title.
    ax : matplotlib.axes.Axes, optional
        Draw there (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or the figure of ``ax``.

    Raises
    ------
    ValueError
        The result has no Floquet multipliers (``classification.floquet: never`` or a
        result written before they existed).
    """
    if "floquet_modulus" not in ds:
        raise ValueError("this result has no floquet_modulus (classification.floquet: never?)")
    axes = [d for d in ds["regime"].dims if ds.sizes[d] > 1]
    if len(axes) >= 2:
        fig = plot_variable(ds, "floquet_modulus", ax=ax)
    else:
        fig = _modulus_line(ds, axes[0] if axes else ds["regime"].dims[0], ax)
    if caption:
        target = ax or fig.axes[0]
        target.set_title(f"{target.get_title()}\n{caption}", fontsize=9)
    return fig


def _modulus_line(ds, axis, ax):
    """|μ| against ``axis`` by kind of multiplier, with the boundaries' types."""
    from ..refine.boundary_types import boundary_types_1d

    fig, ax = _figure_and_axes(ax, (8.0, 4.2))
    line = ds.sortby(axis)
    x = line[axis].values
    modulus = line["floquet_modulus"].values
    kind = multiplier_kind(line["floquet_argument"].values)
    for k, (label, marker, colour) in enumerate(KINDS):
        shown = kind == k
        if shown.any():
            ax.plot(x[shown], modulus[shown], marker, color=colour, ms=4, ls="", label=label)
    ax.axhline(1.0, color="0.3", lw=0.8)
    for crossing in boundary_types_1d(line, axis):
        at = crossing.position
        ax.axvline(at, color=TYPE_COLOUR, ls=":", lw=1.0, zorder=1)
        ax.text(
            at,
            0.03,
            kind_text(crossing.kind),
            transform=ax.get_xaxis_transform(),
            fontsize=7,
            rotation=90,
            ha="right",
            va="bottom",
            bbox=TYPE_BOX,
        )
    ax.set_xlabel(axis_label(line[axis]))
    ax.set_ylabel("largest non-trivial |μ|")
    ax.set_ylim(0.0, 1.1)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("largest non-trivial Floquet multiplier of the periodic runs", fontsize=10)
    return fig
