"""Maps of a sweep result over its sweep axes: the phase diagram (:func:`plot_result`:
regimes beside the amplitude and growth rate) and any one variable
(:func:`plot_variable`); along one axis, the values against it coloured by regime.
The Kc line (K/Kc = 1) is drawn dashed on each. Runaway runs have no bounded
attractor: no amplitude of theirs is drawn (:data:`ATTRACTOR_MEASURES`), they get the
runaway colour instead. A refined result (``sweep/refine/lattice.py``,
:func:`plot_refined`) is drawn as its cells at their level, coloured by the attractor
(periodic cycles by their number of events, :data:`CYCLE_COLOURS`) or regime of their
runs, with the boundaries between those colours (``sweep.boundaries``) on top and its
quasi-periodic, chaotic and unresolved runs marked."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..results.checks import check_result
from ..variables import REGIMES
from .common import (
    ATTRACTOR_COLOURS,
    REGIME_CODES,
    REGIME_COLOURS,
    TYPE_BOX,
    _as_grid,
    _check_caption,
    _edges,
    _figure_and_axes,
    _log_spaced,
    _refined,
    _squeeze,
    _suptitle,
    axis_label,
    bounded,
    colormap,
    describe,
    initial_text,
    kc_label,
    kind_text,
    kinds_legend_text,
    new_figure,
    regime_legend,
    regime_names,
    scale_text,
    stiffness_ratio,
)

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Continuous measures shown beside the regimes in a phase diagram.
MEASURES = ("lnv_amplitude", "growth_rate")
#: Measures of the attractor, which a runaway run does not have: not drawn for those runs.
ATTRACTOR_MEASURES = (
    "lnv_amplitude",
    "lnv_max",
    "lnv_min",
    "v_max",
    "v_min",
    "period",
    "friction_drop",
    "slip_per_event",
)
#: Colour of periodic cycles by their number of events (1, 2, 3 or more) in a refined map;
#: the other attractors keep theirs (Okabe–Ito palette, colour-blind safe).
CYCLE_COLOURS = {1: "#009E73", 2: "#F0E442", 3: "#56B4E9"}
#: Markers over a refined map for the attractors whose cells are too small to see.
RARE_MARKERS = {"quasi_periodic": "o", "chaotic": "*", "unresolved": "X", "unbounded": "^"}
#: Colour of the line K/Kc = 1 over a refined map (on top of the black boundaries).
KC_COLOUR = "#B2182B"
#: Legend entry of the runs without an amplitude (runaway).
RUNAWAY_TEXT = "runaway: no amplitude (no bounded attractor)"


def plot_result(ds: xarray.Dataset, caption: str = "", ax: Axes | None = None) -> Figure:
    """Phase diagram of a sweep result.

    Two or more sweep axes: regimes as a categorical map over the first two
    (first axis along x), beside maps of :data:`MEASURES`; one axis: the
    measures against it, points coloured by regime, with the linear growth
    rate. The analytic critical stiffness (where K/Kc = 1) is drawn over every
    panel. Further axes are taken at their first value (named in the title).
    A refined result (runs along ``point``) is drawn by :func:`plot_refined`: its
    cells at their level with the boundaries between labels on top.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep result (:func:`sweep.run`, or a file opened with xarray).
    caption : str, optional
        An extra line of the figure's title.
    ax : matplotlib.axes.Axes, optional
        Draw only the regime panel there (one axis: the first measure coloured by
        regime), with no figure title (default: a new figure with every panel).

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or the figure of ``ax``.

    Raises
    ------
    ValueError
        No sweep axis has more than one value.
    """
    check_result(ds)
    _check_caption(caption)
    if _refined(ds):
        return plot_refined(ds, caption, ax)
    ds, fixed_axes = _squeeze(ds, keep=2)
    if ds["regime"].ndim not in (1, 2):
        raise ValueError("a phase diagram needs a sweep axis with more than one value")
    if ax is not None:
        if ds["regime"].ndim == 2:
            counts = _regime_map(ax, ds)
            _grid_axes(ax, ds)
            ax.set_ylabel(axis_label(ds[ds["regime"].dims[1]]))
            present = [name for name in REGIMES if counts.get(name)]
            regime_legend(ax, present, counts, fontsize=8)
        else:
            _measure_line(ax, ds, MEASURES[0])
        return ax.figure
    if ds["regime"].ndim == 2:
        fig = _phase_map(ds)
    else:
        fig = _phase_line(ds)
    note = "; ".join(filter(None, [fixed_axes and f"at {fixed_axes}", initial_text(ds)]))
    title = f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}"
    _suptitle(fig, [title, note, scale_text(ds), caption])
    return fig


def _kc_handle(ds):
    from matplotlib.lines import Line2D

    return Line2D([], [], color="k", ls="--", lw=1.5, label=kc_label(ds))


def _runaway_handle():
    from matplotlib.patches import Patch

    return Patch(color=REGIME_COLOURS["runaway"], label=RUNAWAY_TEXT)


def _phase_map(ds):
    xdim, ydim = ds["regime"].dims
    fig = new_figure(figsize=(14.5, 4.8))
    axes = fig.subplots(1, 1 + len(MEASURES), sharey=True)
    counts = _regime_map(axes[0], ds)
    masked = [_measure_map(ax, ds, ds[m]) for ax, m in zip(axes[1:], MEASURES, strict=True)]
    for ax in axes:
        _grid_axes(ax, ds)
    axes[0].set_ylabel(axis_label(ds[ydim]))
    present = [name for name in REGIMES if counts.get(name)]
    below = {"loc": "upper left", "bbox_to_anchor": (0, -0.15), "fontsize": 8, "frameon": False}
    regime_legend(axes[0], present, counts, ncol=2, **below)
    handles = [_kc_handle(ds), *([_runaway_handle()] if any(masked) else [])]
    axes[1].legend(handles=handles, **below)
    return fig


def _grid_axes(ax, ds):
    """Labels and scales of a map over a result's two sweep axes, and the line K/Kc = 1."""
    xdim, ydim = ds["regime"].dims
    x, y = ds[xdim].values, ds[ydim].values
    ratio = stiffness_ratio(ds).transpose(ydim, xdim).values
    if np.any(np.isfinite(ratio)) and min(ratio.shape) > 1:
        ax.contour(x, y, ratio, levels=[1.0], colors="k", linewidths=1.5, linestyles="--")
    ax.set_xlabel(axis_label(ds[xdim]))
    ax.set_xscale("log" if _log_spaced(x) else "linear")
    ax.set_yscale("log" if _log_spaced(y) else "linear")


def _regime_map(ax, ds):
    """Regimes of a 2-D result as a categorical map on ``ax``; returns the run count
    of each regime."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    xdim, ydim = ds["regime"].dims
    names = regime_names(ds)
    codes = sorted(names)
    regime = ds["regime"].transpose(ydim, xdim).values
    cmap = ListedColormap([REGIME_COLOURS[names[c]] for c in codes])
    norm = BoundaryNorm(np.arange(len(codes) + 1) - 0.5, len(codes))
    ax.pcolormesh(_edges(ds[xdim].values), _edges(ds[ydim].values), regime, cmap=cmap, norm=norm)
    ax.set_title("regime")
    return {names[c]: int(np.count_nonzero(regime == c)) for c in codes}


def _measure_map(ax, ds, var):
    """One continuous variable of a 2-D result as a colour map on ``ax``: diverging
    about 0 if it changes sign, else logarithmic when it spans more than a decade;
    grey where it was not measured (NaN). The colour bar names its units. A measure of
    the attractor (:data:`ATTRACTOR_MEASURES`) is not drawn for runaway runs: their cells
    get the runaway colour. Returns whether any cell did."""
    from matplotlib.colors import ListedColormap, LogNorm, Normalize, TwoSlopeNorm

    xdim, ydim = ds["regime"].dims
    var = var.transpose(ydim, xdim)
    values = var.values.astype(float)
    runaway = np.zeros(values.shape, bool)
    if var.name in ATTRACTOR_MEASURES:
        runaway = (ds["regime"] == REGIME_CODES["runaway"]).transpose(ydim, xdim).values
        values[runaway] = np.nan
    finite = values[np.isfinite(values)]
    if finite.size == 0 or finite.min() < 0 < finite.max():
        top = np.abs(finite).max() if finite.size and finite.any() else 1.0
        norm, cmap = TwoSlopeNorm(0.0, -top, top), colormap("RdBu_r")
    elif finite.min() > 0 and finite.max() > 10 * finite.min():
        norm, cmap = LogNorm(finite.min(), finite.max()), colormap("viridis")
    else:
        norm, cmap = Normalize(finite.min(), finite.max()), colormap("viridis")
    cmap = cmap.with_extremes(bad="#DDDDDD")
    xe, ye = _edges(ds[xdim].values), _edges(ds[ydim].values)
    mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(values), cmap=cmap, norm=norm)
    if runaway.any():
        colour = ListedColormap([REGIME_COLOURS["runaway"]])
        ax.pcolormesh(xe, ye, np.ma.masked_where(~runaway, np.zeros(values.shape)), cmap=colour)
    grey = "\n(grey: not measured)" if np.count_nonzero(~runaway) > finite.size else ""
    ax.figure.colorbar(mesh, ax=ax, label=axis_label(var) + grey)
    ax.set_title(var.attrs.get("long_name", var.name))
    return bool(runaway.any())


def _phase_line(ds):
    fig = new_figure(figsize=(7.5, 6.4))
    axes = fig.subplots(len(MEASURES), 1, sharex=True)
    for i, (ax, measure) in enumerate(zip(axes, MEASURES, strict=True)):
        _measure_line(ax, ds, measure, legend=i == 0)
        if i < len(axes) - 1:
            ax.set_xlabel("")
    axes[-1].legend(handles=[*axes[-1].get_lines()[:1], _kc_handle(ds)], loc="best", fontsize=8)
    return fig


def _measure_line(ax, ds, measure, legend=True):
    """One variable of a 1-D result against its sweep axis on ``ax``, points coloured by
    regime (growth rate with the linear theory), the Kc line dashed. A measure of the
    attractor (:data:`ATTRACTOR_MEASURES`) is not drawn for runaway runs: they are marked
    above the axes instead."""
    (xdim,) = ds["regime"].dims
    x = ds[xdim].values
    names = regime_names(ds)
    regime = ds["regime"].values
    counts = {name: int(np.count_nonzero(regime == code)) for code, name in names.items()}
    values = ds[measure].values.astype(float)
    runaway = np.zeros(values.shape, bool)
    if measure in ATTRACTOR_MEASURES:
        runaway = ~bounded(ds).values
        values[runaway] = np.nan
        ax.scatter(
            x[runaway],
            np.full(runaway.sum(), 1.04),
            marker="^",
            s=18,
            color=REGIME_COLOURS["runaway"],
            transform=ax.get_xaxis_transform(),
            clip_on=False,
            zorder=3,
        )
    if measure == "growth_rate":
        ax.plot(
            x,
            ds["linear_growth_rate"].values,
            color="k",
            lw=1.2,
            label="linear theory: max Re λ",
        )
        ax.axhline(0.0, color="#BBBBBB", lw=0.8)
    else:
        ax.plot(x, values, color="#BBBBBB", lw=1, zorder=1)
    for code, name in names.items():
        sel = (regime == code) & ~runaway
        ax.scatter(x[sel], values[sel], color=REGIME_COLOURS[name], s=18, zorder=3)
    finite = values[np.isfinite(values)]
    if finite.size and finite.min() > 0 and finite.max() > 100 * finite.min():
        ax.set_yscale("log")
    for xc in critical_crossings(x, stiffness_ratio(ds).values):
        ax.axvline(xc, color="k", ls="--", lw=1.5)
    ax.set_ylabel(axis_label(ds[measure]))
    ax.set_xlabel(axis_label(ds[xdim]))
    ax.set_xscale("log" if _log_spaced(x) else "linear")
    if legend:
        present = [name for name in REGIMES if counts.get(name)]
        regime_legend(ax, present, counts, loc="best", fontsize=8)


def critical_crossings(x, ratio):
    """Values of x where K/Kc crosses 1 (linear interpolation between grid points)."""
    d = np.asarray(ratio, float) - 1.0
    out = [x[i] for i in np.flatnonzero(d == 0.0)]
    for i in np.flatnonzero(d[:-1] * d[1:] < 0):
        out.append(x[i] - d[i] * (x[i + 1] - x[i]) / (d[i + 1] - d[i]))
    return out


def plottable(ds):
    """Names of the variables of a result that :func:`plot_variable` can map: numeric,
    over the sweep axes (per-block ones too)."""
    dims = set(ds["regime"].dims)
    return [
        name
        for name, var in ds.data_vars.items()
        if dims <= set(var.dims) and set(var.dims) <= dims | {"block"} and var.dtype.kind in "iuf"
    ]


def plot_variable(ds: xarray.Dataset, name: str, ax: Axes | None = None, block: int = 0) -> Figure:
    """Any variable of a sweep result over its sweep axes.

    Two or more sweep axes: a colour map over the first two (``regime`` as
    categories, others with a colour bar naming the units); one axis: the
    variable against it, points coloured by regime. Further axes are taken at
    their first value, per-block variables at ``block``; both are named in the
    title. The analytic Kc (K/Kc = 1) is drawn dashed. A refined result is drawn on
    a grid (``refined_dataset.as_grid``).

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep result.
    name : str
        The variable, e.g. ``"period"`` (s) or ``"v_max"`` (µm s⁻¹): any numeric
        data variable of the result (``sweep.plot.plottable(ds)`` lists them).
    ax : matplotlib.axes.Axes, optional
        Draw there (default: a new figure).
    block : int, default 0
        Block index for per-block variables.

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or the figure of ``ax``.

    Raises
    ------
    ValueError
        ``name`` is not a variable of the result (the message lists the valid
        names), ``block`` is not one of its blocks, or no sweep axis has more than one
        value.
    """
    check_result(ds)
    ds = _as_grid(ds)
    valid = plottable(ds)
    if name not in valid:
        raise ValueError(f"no variable {name!r} to plot; valid names: {', '.join(valid)}")
    ds, fixed_axes = _squeeze(ds, keep=2)
    notes = [f"at {fixed_axes}"] if fixed_axes else []
    if "block" in ds[name].dims:
        n_blocks = ds.sizes["block"]
        if (
            isinstance(block, bool)
            or not isinstance(block, (int, np.integer))
            or not (0 <= block < n_blocks)
        ):
            raise ValueError(f"block must be an integer in [0, {n_blocks - 1}], got {block!r}")
        ds = ds.assign({name: ds[name].isel(block=int(block))})
        notes.append(f"block {block}")
    ndim = ds["regime"].ndim
    if ndim == 0:
        raise ValueError("a map needs a sweep axis with more than one value")
    fig, ax = _figure_and_axes(ax, (7.5, 5.0) if ndim == 2 else (7.5, 4.2))
    if ndim == 2:
        if name == "regime":
            counts = _regime_map(ax, ds)
            present = [n for n in REGIMES if counts.get(n)]
            regime_legend(ax, present, counts, loc="best", fontsize=8)
        else:
            _measure_map(ax, ds, ds[name])
        _grid_axes(ax, ds)
        ax.set_ylabel(axis_label(ds[ds["regime"].dims[1]]))
    elif name == "regime":
        _measure_line(ax, ds.assign(regime_code=ds["regime"].astype(float)), "regime_code")
        ax.set_ylabel("regime")
        ax.set_yticks(list(regime_names(ds)), list(regime_names(ds).values()))
    else:
        _measure_line(ax, ds, name)
    title = ds[name].attrs.get("long_name", name)
    ax.set_title(f"{title} ({'; '.join(notes)})" if notes else title, fontsize=10)
    return fig


def plot_refined(ds, caption="", ax=None):
    """A refined result (``sweep/refine/lattice.py``); returns the Figure.

    Over two refined axes: left, the cells at their level, each coloured by the attractor
    of its runs, periodic ones by their number of events (1, 2, 3 or more; with an
    ensemble the regime of most members; a cell whose corners differ, by quarters: each
    its corner's), the quasi-periodic, chaotic, unresolved and unbounded runs marked too
    (:data:`RARE_MARKERS`: their cells are often too small to see), with the boundaries
    between those colours on top (``sweep.boundaries``: solid where the attractor
    changes, dashed where only the number of events does; each pair of labels' longest
    polyline of a type with that type's short text at its middle,
    :data:`~sweep.plot.common.KIND_TEXT`) and the Kc line (K/Kc = 1,
    :func:`~sweep.plot.common.kc_label`); right, the level of every cell. Over one refined axis:
    the measures of :func:`plot_result` at every run, the boundaries' cells shaded, their
    types written at the top.
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
    if split == 1:
        found = boundaries(ds)
        fig = plot_result(along_axis(ds), "; ".join(filter(None, [stopped, caption])), ax)
        for a in fig.axes:
            for b in found:
                x, width = b.vertices[0, 0], b.resolution[0, 0]
                a.axvspan(x - width / 2, x + width / 2, color="k", alpha=0.15, lw=0)
        if found:
            _label_points(fig.axes[0], found)
        return fig
    classes, outputs = _colour_classes(ds)
    found = boundaries(classes, outputs, types_from=ds)  # typed by the runs' own events
    if ax is None:
        fig = new_figure(figsize=(14.5, 6.2))
        panels = fig.subplots(1, 2, sharex=True, sharey=True)
    else:
        fig, panels = ax.figure, (ax, None)
    counts = _refined_cells(panels[0], ds, lattice, "kind")
    if panels[1] is not None:
        _refined_cells(panels[1], ds, lattice, "level")
    _draw_boundaries(panels[0], found)  # the levels' panel shows where they are by its cells
    for a in filter(None, panels):
        kc_drawn = _refined_axes(a, ds, lattice)
    _label_boundaries(panels[0], found)
    rare = _rare_markers(panels[0], ds, lattice)
    below = {"loc": "upper left", "bbox_to_anchor": (0, -0.12), "fontsize": 8, "frameon": False}
    _kind_legend(panels[0], counts, rare, ncol=2, **below)
    if panels[1] is not None:
        kinds = [b.kind for b in found]
        panels[1].legend(handles=_boundary_handles(ds, outputs, kc_drawn, kinds), **below)
        runs = ", ".join(str(int(r)) for r in ds.attrs["refine_runs"])
        lines = [
            f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}",
            f"{stopped}: {runs} runs per level; {initial_text(ds)}",
            scale_text(ds),
            caption,
        ]
        _suptitle(fig, lines)
    return fig


def _colour_classes(ds):
    """``(ds, outputs)`` whose labels are the colours of a refined map's cells, for
    ``sweep.boundaries``: the attractor and, of periodic runs, the number of events cut
    at 3 (0 for the other attractors); with an ensemble ``ds`` and its own labels
    (``outputs`` None)."""
    if "regime_fraction" in ds or "cycle_events" not in ds:
        return ds, None
    periodic = ds["attractor"] == ds["attractor"].attrs["flag_meanings"].split().index("periodic")
    top = max(CYCLE_COLOURS)
    events = ds["cycle_events"].clip(1, top).where(periodic, 0).astype(ds["cycle_events"].dtype)
    return ds.assign(cycle_events=events), ("attractor", "cycle_events")


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
            antialiased=False,
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
            verts,
            array=colours,
            cmap=cmap,
            norm=norm,
            edgecolors="face",
            linewidths=0.2,
            antialiased=False,  # sharp cells, and a PNG a third smaller
        )
    )
    what = "regime of most members" if "regime_fraction" in ds else "attractor"
    between = "labels" if "regime_fraction" in ds else "colours"
    ax.set_title(f"{what}, by cell; boundaries between {between}")
    return {k: int(np.count_nonzero(kind == c)) for c, k in enumerate(kinds)}


def _boxes(lows, size, x, y):
    """Rows (x, y, size) of squares with lower corners ``lows`` (n, d) along axes x, y."""
    return np.stack([lows[:, x], lows[:, y], np.full(len(lows), size)], axis=-1)


def _cell_kinds(ds):
    """``(kinds, code per point)``: kinds are ``(colour, name)``; a point's code is its
    attractor, periodic ones split by their number of events (1, 2, 3 or more:
    :data:`CYCLE_COLOURS`), or with an ensemble the regime of most members (the colours
    agree: steady sliding and a fixed point are one blue, runaway and unbounded one red)."""
    if "regime_fraction" in ds:
        code = ds["regime_fraction"].transpose("point", "regime_name").values.argmax(axis=-1)
        return [(REGIME_COLOURS[name], name) for name in REGIMES], code
    attractor = ds["attractor"].values
    if "cycle_events" not in ds:
        names = ds["attractor"].attrs["flag_meanings"].split()
        return [(ATTRACTOR_COLOURS[name], name) for name in names], attractor
    classes, _ = _colour_classes(ds)
    events = classes["cycle_events"].values
    kinds, code = [], np.empty(attractor.shape, int)
    for c, name in enumerate(ds["attractor"].attrs["flag_meanings"].split()):
        if name != "periodic":
            code[attractor == c] = len(kinds)
            kinds.append((ATTRACTOR_COLOURS[name], name))
            continue
        for n, colour in CYCLE_COLOURS.items():
            code[(attractor == c) & (events == n)] = len(kinds)
            more = " or more" if n == max(CYCLE_COLOURS) else ""
            kinds.append((colour, f"periodic, {n}{more} event{'s' if n > 1 else ''} a cycle"))
    return kinds, code


def _rare_markers(ax, ds, lattice):
    """Every run of a kind in :data:`RARE_MARKERS` marked at its point on ``ax``; returns
    the kinds marked."""
    if "regime_fraction" in ds:
        return []
    x, y = (lattice.axes[i].name for i in np.flatnonzero(lattice.split))
    names = ds["attractor"].attrs["flag_meanings"].split()
    attractor = ds["attractor"].values
    marked = []
    for name, marker in RARE_MARKERS.items():
        sel = attractor == names.index(name)
        if sel.any():
            ax.scatter(
                ds[x].values[sel],
                ds[y].values[sel],
                marker=marker,
                s=16,
                lw=0.6,
                color=ATTRACTOR_COLOURS[name],
                edgecolors="k",
                zorder=4,
            )
            marked.append(name)
    return marked


def _kind_legend(ax, counts, marked=(), **kwargs):
    """A legend of the kinds present (``_refined_cells``' counts of runs); the kinds in
    ``marked`` with their marker too."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = []
    for (colour, name), n in counts.items():
        if not n:
            continue
        label = f"{name.replace('_', '-')} ({n})"
        if name in marked:
            handles.append(
                Line2D(
                    [],
                    [],
                    ls="",
                    marker=RARE_MARKERS[name],
                    color=colour,
                    mec="k",
                    mew=0.6,
                    ms=7,
                    label=f"{label}, marked",
                )
            )
        else:
            handles.append(Patch(color=colour, label=label))
    return ax.legend(handles=handles, **kwargs)


def _draw_boundaries(ax, found):
    """Boundary polylines on ``ax``: solid black where the first output of the labels
    (the attractor, or with an ensemble the regime) changes, dashed where only the others
    do."""
    for b in found:
        first = [text.split(",")[0] for text in b.between]
        style = "-" if first[0] != first[1] else "--"
        ax.plot(b.vertices[:, 0], b.vertices[:, 1], color="k", ls=style, lw=0.9)


#: Places tried along a polyline for its type's text (fractions of its vertices), and the
#: least distance (fraction of the axes) between two such texts.
LABEL_PLACES = (0.5, 0.25, 0.75, 0.125, 0.875, 0.375, 0.625)
LABEL_SPACING = 0.08


def _label_boundaries(ax, found):
    """Each boundary type's short text (:data:`~sweep.plot.common.KIND_TEXT`) on the
    longest polyline of its pair of labels, at the first of :data:`LABEL_PLACES` at least
    :data:`LABEL_SPACING` from the texts already placed (longest polylines first; none
    where no place is: a crowded type is named in the legend only). Call after the axes'
    limits and scales are set."""
    longest = {}
    for b in found:
        key = (b.between, b.kind)
        if key not in longest or len(b.vertices) > len(longest[key].vertices):
            longest[key] = b
    to_axes = ax.transData + ax.transAxes.inverted()
    placed = []
    for b in sorted(longest.values(), key=lambda b: -len(b.vertices)):
        n = len(b.vertices)
        places = [b.vertices[min(int(f * n), n - 1)] for f in LABEL_PLACES]
        free = [
            point
            for point in places
            if all(np.hypot(*(to_axes.transform(point) - p)) >= LABEL_SPACING for p in placed)
        ]
        if not free:
            continue
        at = free[0]
        placed.append(to_axes.transform(at))
        ax.text(
            *at, kind_text(b.kind), fontsize=7, ha="center", va="center", zorder=6, bbox=TYPE_BOX
        )


def _label_points(ax, found):
    """The type of each boundary of one refined axis at its point, at the top of ``ax``."""
    transform = ax.get_xaxis_transform()
    for b in found:
        ax.text(
            b.vertices[0, 0],
            0.98,
            kind_text(b.kind),
            transform=transform,
            fontsize=7,
            rotation=90,
            ha="center",
            va="top",
            zorder=6,
            bbox=TYPE_BOX,
        )


def _boundary_handles(ds, outputs, kc_drawn, kinds=()):
    """Legend entries of the boundaries (``outputs`` of :func:`_colour_classes`), of their
    types' short texts (``kinds`` present) and of the Kc line if it is drawn."""
    from matplotlib.lines import Line2D

    if outputs:
        solid, dashed = "the attractor changes", "the number of events a cycle changes"
    else:
        solid, dashed = "the regime changes", "other labels change"
    handles = [
        Line2D([], [], color="k", lw=0.9, label=f"boundary (left): {solid}"),
        Line2D([], [], color="k", ls="--", lw=0.9, label=f"boundary (left): {dashed}"),
    ]
    handles += [Line2D([], [], ls="", label=text) for text in kinds_legend_text(kinds)]
    if kc_drawn:
        handles.append(Line2D([], [], color=KC_COLOUR, ls="-.", lw=1.8, label=kc_label(ds)))
    return handles


def _refined_axes(ax, ds, lattice):
    """Limits, scales and labels of a map of a refined result, and the line K/Kc = 1;
    returns whether that line crosses the map."""
    from ..refine.dataset import to_grid

    x, y = (lattice.axes[i] for i in np.flatnonzero(lattice.split))
    coarse = to_grid(ds[["regime", "K_over_Kc", "critical_K_W"]], min(lattice.levels, 3))
    ratio = stiffness_ratio(coarse).transpose(y.name, x.name).values
    crosses = bool(np.nanmin(ratio, initial=np.inf) < 1 < np.nanmax(ratio, initial=-np.inf))
    if crosses:
        ax.contour(
            coarse[x.name].values,
            coarse[y.name].values,
            ratio,
            levels=[1.0],
            colors=KC_COLOUR,
            linewidths=1.8,
            linestyles="-.",
            zorder=5,
        )
    for axis, set_lim, set_scale, set_label in (
        (x, ax.set_xlim, ax.set_xscale, ax.set_xlabel),
        (y, ax.set_ylim, ax.set_yscale, ax.set_ylabel),
    ):
        values = np.asarray(axis.values)
        set_lim(values.min(), values.max())
        set_scale("log" if axis.span and axis.span[0] == "log" else "linear")
        set_label(axis_label(ds[axis.name]))
    return crosses
