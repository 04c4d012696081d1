"""Maps of a refined result (``sweep/refine/lattice.py``, :func:`plot_refined`): its cells at
their level, coloured by the attractor (or regime) of their runs, with the boundaries
between labels (``sweep.boundaries``) on top."""

from __future__ import annotations

import numpy as np

from ..variables import REGIMES
from .common import (
    ATTRACTOR_COLOURS,
    REGIME_COLOURS,
    _suptitle,
    axis_label,
    colormap,
    describe,
    initial_text,
    new_figure,
    stiffness_ratio,
)
from .maps import plot_result


def plot_refined(ds, caption="", ax=None):
    """A refined result (``sweep/refine/lattice.py``); returns the Figure.

    Over two refined axes: left, the cells at their level, each coloured by the regime
    of its runs (a cell whose corners differ, by quarters: each its corner's), with the
    boundaries between labels on top (``sweep.boundaries``: solid where the regime
    changes, dashed where only the attractor or the number of events does) and the
    analytic Kc (K/Kc = 1) dashed; right, the level of every cell. Over one refined axis:
    the measures of :func:`plot_result` at every run, the boundaries' cells shaded.
    More axes: the grid of level 0 (:func:`plot_result`). With ``ax``: only the left
    panel, there. ``caption``: an extra title line.
    """
    from ..refine.boundaries import boundaries
    from ..refine.dataset import along_axis, refined_config, to_grid
    from ..refine.lattice import Lattice

    lattice = Lattice(refined_config(ds))
    split = int(lattice.split.sum())
    stopped = f"refined {len(ds.attrs['refine_runs']) - 1} levels, {ds['regime'].size} runs"
    if split > 2:
        return plot_result(to_grid(ds, 0), "; ".join(filter(None, [caption, stopped])), ax)
    found = boundaries(ds)
    if split == 1:
        fig = plot_result(along_axis(ds), "; ".join(filter(None, [stopped, caption])), ax)
        for a in fig.axes:
            for b in found:
                x, width = b.vertices[0, 0], b.resolution[0, 0]
                a.axvspan(x - width / 2, x + width / 2, color="k", alpha=0.15, lw=0)
        return fig
    if ax is None:
        fig = new_figure(figsize=(14.5, 5.6))
        panels = fig.subplots(1, 2, sharex=True, sharey=True)
    else:
        fig, panels = ax.figure, (ax, None)
    counts = _refined_cells(panels[0], ds, lattice, "kind")
    if panels[1] is not None:
        _refined_cells(panels[1], ds, lattice, "level")
    for a in filter(None, panels):
        _draw_boundaries(a, found)
        _refined_axes(a, ds, lattice)
    below = {"loc": "upper left", "bbox_to_anchor": (0, -0.12), "fontsize": 8, "frameon": False}
    _kind_legend(panels[0], counts, ncol=3, **below)
    if panels[1] is not None:
        panels[1].legend(handles=_boundary_handles(), **below)
        runs = ", ".join(str(int(r)) for r in ds.attrs["refine_runs"])
        lines = [
            f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}",
            f"{stopped}: {runs} runs per level; {initial_text(ds)}",
            caption,
        ]
        _suptitle(fig, lines)
    return fig


def _refined_cells(ax, ds, lattice, what):
    """The unsplit cells of a refined result on ``ax`` as rectangles: coloured by the
    attractor of their corners' runs (``what="kind"``; with an ensemble by the regime of
    most members; a cell whose corners differ by quarters) or by their level
    (``"level"``). Returns ``{(colour, name): runs}`` of each kind."""
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import BoundaryNorm, ListedColormap

    from ..refine.dataset import lattice_index
    from ..refine.lattice import axis_values, cell_tree

    x, y = np.flatnonzero(lattice.split)
    index = lattice_index(ds, lattice)
    keys = lattice.keys(index)
    order = np.argsort(keys)
    kinds, kind = _cell_kinds(ds)
    boxes, colours = [], []  # boxes: (x, y, size) in half-index units (twice the index)
    for level, (cells, split) in enumerate(cell_tree(lattice, index)):
        leaves = cells[~split]
        step = lattice.step(level)
        if what == "level":
            boxes.append(_boxes(2 * leaves, 2 * step, x, y))
            colours.append(np.full(len(leaves), level))
            continue
        corners = lattice.corners(leaves, level)  # (m, 2^2, d)
        codes = kind[order[np.searchsorted(keys[order], lattice.keys(corners))]]
        same = np.all(codes == codes[:, :1], axis=1)
        boxes.append(_boxes(2 * leaves[same], 2 * step, x, y))
        colours.append(codes[same, 0])
        # a quarter per corner: from the corner towards the cell's centre
        quarters = (corners[~same] + leaves[~same][:, None, :]).reshape(-1, corners.shape[-1])
        boxes.append(_boxes(quarters, step, x, y))
        colours.append(codes[~same].ravel())
    x0, y0, size = np.concatenate(boxes).T
    colours = np.concatenate(colours)
    ax_x, ax_y = lattice.axes[x], lattice.axes[y]
    left, right = (axis_values(ax_x, v, lattice.levels + 1) for v in (x0, x0 + size))
    bottom, top = (axis_values(ax_y, v, lattice.levels + 1) for v in (y0, y0 + size))
    corners = ((left, bottom), (right, bottom), (right, top), (left, top))
    verts = np.stack([np.stack(c, axis=-1) for c in corners], axis=1)
    if what == "level":
        cmap = colormap("viridis").resampled(lattice.levels + 1)
        cells = PolyCollection(
            verts,
            array=colours,
            cmap=cmap,
            clim=(-0.5, lattice.levels + 0.5),
            edgecolors="face",
            linewidths=0.2,
        )
        ax.add_collection(cells)
        ax.figure.colorbar(
            cells,
            ax=ax,
            label="level of the cell (its size: grid step / 2^level)",
            ticks=range(lattice.levels + 1),
        )
        ax.set_title("cells at their level")
        return {}
    cmap = ListedColormap([colour for colour, _ in kinds])
    norm = BoundaryNorm(np.arange(len(kinds) + 1) - 0.5, len(kinds))
    ax.add_collection(
        PolyCollection(
            verts, array=colours, cmap=cmap, norm=norm, edgecolors="face", linewidths=0.2
        )
    )
    what = "regime of most members" if "regime_fraction" in ds else "attractor"
    ax.set_title(f"{what}, by cell; boundaries between labels")
    return {k: int(np.count_nonzero(kind == c)) for c, k in enumerate(kinds)}


def _boxes(lows, size, x, y):
    """Rows (x, y, size) of squares with lower corners ``lows`` (n, d) along axes x, y."""
    return np.stack([lows[:, x], lows[:, y], np.full(len(lows), size)], axis=-1)


def _cell_kinds(ds):
    """``(kinds, code per point)``: kinds are ``(colour, name)``; a point's code is its
    attractor, or with an ensemble the regime of most members (the colours agree:
    steady sliding and a fixed point are one blue, runaway and unbounded one red)."""
    if "regime_fraction" in ds:
        code = ds["regime_fraction"].transpose("point", "regime_name").values.argmax(axis=-1)
        return [(REGIME_COLOURS[name], name) for name in REGIMES], code
    names = ds["attractor"].attrs["flag_meanings"].split()
    return [(ATTRACTOR_COLOURS[name], name) for name in names], ds["attractor"].values


def _kind_legend(ax, counts, **kwargs):
    """A legend of the kinds present (``_refined_cells``' counts of runs)."""
    from matplotlib.patches import Patch

    handles = [
        Patch(color=colour, label=f"{name.replace('_', '-')} ({n})")
        for (colour, name), n in counts.items()
        if n
    ]
    return ax.legend(handles=handles, **kwargs)


def _draw_boundaries(ax, found):
    """Boundary polylines on ``ax``: solid black where the regime changes, dashed where
    only the attractor or the number of events does."""
    for b in found:
        regimes = [text.split(",")[0] for text in b.between]
        style = "-" if regimes[0] != regimes[1] else "--"
        ax.plot(b.vertices[:, 0], b.vertices[:, 1], color="k", ls=style, lw=0.9)


def _boundary_handles():
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], color="k", lw=0.9, label="boundary: the regime changes"),
        Line2D([], [], color="k", ls="--", lw=0.9, label="boundary: attractor or events change"),
        Line2D([], [], color="k", ls=":", lw=1.5, label="analytic Kc (K/Kc = 1)"),
    ]


def _refined_axes(ax, ds, lattice):
    """Limits, scales and labels of a map of a refined result, and the line K/Kc = 1."""
    from ..refine.dataset import to_grid

    x, y = (lattice.axes[i] for i in np.flatnonzero(lattice.split))
    coarse = to_grid(ds[["regime", "K_over_Kc", "critical_K_W"]], min(lattice.levels, 3))
    ratio = stiffness_ratio(coarse).transpose(y.name, x.name).values
    if np.any(np.isfinite(ratio)):
        ax.contour(
            coarse[x.name].values,
            coarse[y.name].values,
            ratio,
            levels=[1.0],
            colors="k",
            linewidths=1.5,
            linestyles=":",
        )
    for axis, set_lim, set_scale, set_label in (
        (x, ax.set_xlim, ax.set_xscale, ax.set_xlabel),
        (y, ax.set_ylim, ax.set_yscale, ax.set_ylabel),
    ):
        values = np.asarray(axis.values)
        set_lim(values.min(), values.max())
        set_scale("log" if axis.span and axis.span[0] == "log" else "linear")
        set_label(axis_label(ds[axis.name]))
