"""Figures of sweep results and traces: phase diagrams, bifurcation diagrams, time series.

All drawing lives here; the numbers come from result Datasets (``sweep/dataset.py``)
and trace Datasets (``sweep/trace.py``). Every ``plot_*`` function returns a
matplotlib Figure (drawn in a notebook, saved with :func:`save_figure`); those with
one panel draw on a given ``ax=`` instead. Figures are made without pyplot, so
nothing here selects a backend or keeps figures open; matplotlib is imported
lazily, so importing the package stays light.

One table, :data:`REGIME_COLOURS`, colours each regime in every figure.
"""

from __future__ import annotations

import os
import re
import textwrap
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

from .dataset import parameter_values
from .physics import PARAMETERS
from .result_check import check_result, check_trace
from .variables import REGIMES

if TYPE_CHECKING:
    from pathlib import Path

    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Colour of each regime in every figure (Okabe–Ito palette, colour-blind safe).
REGIME_COLOURS = {
    "steady": "#0072B2",
    "stick_slip": "#009E73",
    "runaway": "#D55E00",
    "undecided": "#999999",
}
#: Line colour and width of blocks 1, 2, … in time series (colours kept apart from the
#: regimes'). Later blocks are wider and drawn underneath, so blocks moving in
#: synchrony show as a dark line with a coloured halo.
BLOCK_STYLES = (("#222222", 0.9), ("#CC79A7", 2.6), ("#8C6BB1", 4.2), ("#BBBBBB", 5.8))
#: Default resolution of saved raster figures (dots per inch; ``--dpi`` changes it).
DPI = 150
#: File types :func:`save_figure` writes, by suffix.
FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
#: Parameters shown in figure titles, in this order (mu0, V0, Phi0 do not change the dynamics).
TITLE_PARAMETERS = ("A", "B", "D0", "V", "K_W", "k2_W", "eta_W", "m_W")
SYMBOLS = {"D0": "D0", "K_W": "K/W", "k2_W": "k2/W", "eta_W": "η/W", "m_W": "m/W"}
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def new_figure(**kwargs):
    """A matplotlib Figure with constrained layout, made without pyplot (so no
    backend is selected and nothing is kept open)."""
    from matplotlib.figure import Figure

    return Figure(layout="constrained", **kwargs)


def colormap(name):
    """The registered matplotlib colormap ``name``."""
    import matplotlib

    return matplotlib.colormaps[name]


def power_text(x):
    """A number for a label: ``1e6`` → ``"10⁶"``; other numbers as ``:g``."""
    exponent = np.log10(x) if x > 0 else np.nan
    if np.isfinite(exponent) and exponent == round(exponent):
        return "10" + str(int(exponent)).translate(_SUPERSCRIPT)
    return f"{x:g}"


def unit_text(units):
    """CF-style units → display text: ``"um-1"`` → ``"µm⁻¹"``, ``"1"`` → ``""``."""
    if units in ("", "1"):
        return ""
    words = []
    for word in units.split():
        base, power = re.fullmatch(r"([A-Za-z]+)(-?\d*)", word).groups()
        words.append(base.replace("um", "µm") + power.translate(_SUPERSCRIPT))
    return " ".join(words)


def axis_label(var):
    """Axis label of a coordinate or variable: its long name and units in brackets."""
    units = unit_text(var.attrs.get("units", "1"))
    name = var.attrs.get("long_name", var.name)
    return f"{name} [{units}]" if units else name


def parameter_text(values):
    """``"A = 0.03, B = 0.08, D0 = 1 µm"`` from a mapping of parameter name → value."""
    parts = []
    for name in TITLE_PARAMETERS:
        if name in values:
            units = unit_text(PARAMETERS[name].units)
            parts.append(
                f"{SYMBOLS.get(name, name)} = {float(values[name]):g}{' ' + units if units else ''}"
            )
    return ", ".join(parts)


def describe(ds):
    """Title line of a result or trace: blocks, model, state law and fixed parameters."""
    blocks = int(ds.attrs["blocks"])
    kind = "one block" if blocks == 1 else f"{blocks} blocks"
    fixed = parameter_text(parameter_values(ds))
    return f"{kind}, {ds.attrs['model']}, {ds.attrs['state_law']} law: {fixed}"


def initial_text(ds):
    """The initial perturbation of a result or trace, e.g. ``"start Φ/Φss = 1.01, v/V = 1"``."""
    phi = np.atleast_1d(ds.attrs["initial_phi_over_phi_ss"])
    v = np.atleast_1d(ds.attrs["initial_v_over_V"])
    return (
        f"start Φ/Φss = {', '.join(f'{x:g}' for x in phi)}; v/V = {', '.join(f'{x:g}' for x in v)}"
    )


def regime_names(ds):
    """Regime name of every code in a result's ``regime`` flag attributes."""
    attrs = ds["regime"].attrs
    return dict(
        zip((int(c) for c in attrs["flag_values"]), attrs["flag_meanings"].split(), strict=True)
    )


def regime_legend(ax, regimes, counts=None, **kwargs):
    """A legend of coloured patches naming each regime (with run counts if given)."""
    from matplotlib.patches import Patch

    handles = [
        Patch(
            color=REGIME_COLOURS[name],
            label=name.replace("_", "-") + (f" ({counts[name]})" if counts else ""),
        )
        for name in regimes
    ]
    return ax.legend(handles=handles, **kwargs)


def _squeeze(ds, keep=None):
    """Take sweep axes of length one, and any beyond the first ``keep`` longer ones,
    at their first value; return the Dataset and a note naming those values."""
    longer = [d for d in ds["regime"].dims if ds.sizes[d] > 1]
    taken = [d for d in ds["regime"].dims if d not in longer[:keep]]
    values = {d: ds[d].values[0] for d in taken}
    return ds.isel({d: 0 for d in taken}), parameter_text(values)


def stiffness_ratio(ds):
    """K/Kc, NaN where Kc ≤ 0 (steady sliding is then stable at every stiffness)."""
    return ds["K_over_Kc"].where(ds["critical_K_W"] > 0)


def _check_caption(caption):
    """Raise TypeError unless ``caption`` (an extra title line) is a string."""
    if not isinstance(caption, str):
        raise TypeError(f"caption must be a string, got {type(caption).__name__}")


def _suptitle(fig, lines):
    """Figure title from non-empty ``lines``, each wrapped to the figure's width."""
    width = int(12 * fig.get_figwidth())  # characters of 10-point text per line (100 dpi)
    fig.suptitle("\n".join(textwrap.fill(line, width) for line in lines if line), fontsize=10)


def _log_spaced(values):
    """Whether grid values are evenly spaced in log but not linearly (a log-scale axis)."""
    v = np.asarray(values, float)
    if v.size < 3 or np.any(v <= 0):
        return False
    return np.allclose(np.diff(np.log(v)), np.log(v[1] / v[0])) and not np.allclose(
        np.diff(v), v[1] - v[0]
    )


def _edges(values):
    """Cell edges around grid values (geometric midpoints on a log-spaced axis)."""
    v = np.asarray(values, float)
    log = _log_spaced(v)
    w = np.log(v) if log else v
    mid = 0.5 * (w[1:] + w[:-1])
    e = np.concatenate([[2 * w[0] - mid[0]], mid, [2 * w[-1] - mid[-1]]])
    return np.exp(e) if log else e


def critical_crossings(x, ratio):
    """Values of x where K/Kc crosses 1 (linear interpolation between grid points)."""
    d = np.asarray(ratio, float) - 1.0
    out = [x[i] for i in np.flatnonzero(d == 0.0)]
    for i in np.flatnonzero(d[:-1] * d[1:] < 0):
        out.append(x[i] - d[i] * (x[i + 1] - x[i]) / (d[i + 1] - d[i]))
    return out


#: Continuous measures shown beside the regimes in a phase diagram.
MEASURES = ("lnv_amplitude", "growth_rate")


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
    _suptitle(fig, [f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}", note, caption])
    return fig


def _kc_handle():
    from matplotlib.lines import Line2D

    return Line2D([], [], color="k", ls="--", lw=1.5, label="analytic Kc (K/Kc = 1)")


def _phase_map(ds):
    xdim, ydim = ds["regime"].dims
    fig = new_figure(figsize=(14.5, 4.8))
    axes = fig.subplots(1, 1 + len(MEASURES), sharey=True)
    counts = _regime_map(axes[0], ds)
    for ax, measure in zip(axes[1:], MEASURES, strict=True):
        _measure_map(ax, ds, ds[measure])
    for ax in axes:
        _grid_axes(ax, ds)
    axes[0].set_ylabel(axis_label(ds[ydim]))
    present = [name for name in REGIMES if counts.get(name)]
    below = {"loc": "upper left", "bbox_to_anchor": (0, -0.15), "fontsize": 8, "frameon": False}
    regime_legend(axes[0], present, counts, ncol=2, **below)
    axes[1].legend(handles=[_kc_handle()], **below)
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
    grey where it was not measured (NaN). The colour bar names its units."""
    from matplotlib.colors import LogNorm, Normalize, TwoSlopeNorm

    xdim, ydim = ds["regime"].dims
    var = var.transpose(ydim, xdim)
    values = var.values.astype(float)
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
    grey = "\n(grey: not measured)" if finite.size < values.size else ""
    ax.figure.colorbar(mesh, ax=ax, label=axis_label(var) + grey)
    ax.set_title(var.attrs.get("long_name", var.name))


def _phase_line(ds):
    fig = new_figure(figsize=(7.5, 6.4))
    axes = fig.subplots(len(MEASURES), 1, sharex=True)
    for i, (ax, measure) in enumerate(zip(axes, MEASURES, strict=True)):
        _measure_line(ax, ds, measure, legend=i == 0)
        if i < len(axes) - 1:
            ax.set_xlabel("")
    axes[-1].legend(handles=[*axes[-1].get_lines()[:1], _kc_handle()], loc="best", fontsize=8)
    return fig


def _measure_line(ax, ds, measure, legend=True):
    """One variable of a 1-D result against its sweep axis on ``ax``, points coloured by
    regime (growth rate with the linear theory), the analytic Kc dashed."""
    (xdim,) = ds["regime"].dims
    x = ds[xdim].values
    names = regime_names(ds)
    regime = ds["regime"].values
    counts = {name: int(np.count_nonzero(regime == code)) for code, name in names.items()}
    values = ds[measure].values.astype(float)
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
        sel = regime == code
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


def plottable(ds):
    """Names of the variables of a result that :func:`plot_variable` can map: numeric,
    over the sweep axes (per-block ones too)."""
    dims = set(ds["regime"].dims)
    return [
        name
        for name, var in ds.data_vars.items()
        if dims <= set(var.dims) and set(var.dims) <= dims | {"block"} and var.dtype.kind in "iuf"
    ]


def _figure_and_axes(ax, figsize):
    """``(figure, ax)``: the given axes and its figure, or a new figure with one axes."""
    if ax is not None:
        if not hasattr(ax, "figure"):
            raise TypeError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
        return ax.figure, ax
    fig = new_figure(figsize=figsize)
    return fig, fig.subplots()


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
        data variable of the result (``sweep.plots.plottable(ds)`` lists them).
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


#: Marker of each model in a bifurcation diagram (lines in black; colours are regimes).
MODEL_MARKERS = {"quasi-static": "o", "quasi-dynamic": "s", "inertial": "D"}
#: Line style and marker area (pt²) of successive curves: later curves smaller, so
#: curves that coincide (e.g. all steady at zero amplitude) stay visible.
CURVE_STYLES = (("-", 46), ("--", 22), (":", 11), ("-.", 6))


def bifurcation_curves(ds):
    """The curves of a result for a bifurcation diagram: one per value of the
    sweep axes other than K/W (or the first axis). Yields ``(label, curve)``
    with ``curve`` a 1-D Dataset sorted by K/Kc, without points where Kc ≤ 0
    (no instability at any K); the label names the model, its damping
    η̂ = ηV/W where that is one number, and the other axes' values."""
    ds, _ = _squeeze(ds)
    dims = ds["regime"].dims
    if not dims:
        raise ValueError("a bifurcation diagram needs a sweep axis with more than one value; "
                         "this result is one run")  # fmt: skip
    xdim = "K_W" if "K_W" in dims else dims[0]
    others = [d for d in dims if d != xdim]
    for index in np.ndindex(*(ds.sizes[d] for d in others)):
        curve = ds.isel(dict(zip(others, index, strict=True)))
        label = ds.attrs["model"]
        eta, V = _scalar(curve, "eta_W"), _scalar(curve, "V")
        if label == "quasi-dynamic" and eta is not None and V is not None:
            label += f", η̂ = ηV/W = {eta * V:g}"
        rest = {d: curve[d].values for d in others if d not in ("eta_W", "V")}
        if rest:
            label += f" ({parameter_text(rest)})"
        unstable_somewhere = np.flatnonzero(curve["critical_K_W"].values > 0)
        yield label, curve.isel({xdim: unstable_somewhere}).sortby("K_over_Kc")


def _scalar(ds, name):
    """The single value of parameter ``name`` in a result, or None if it varies or is
    absent."""
    return parameter_values(ds).get(name)


def plot_bifurcation(
    datasets: xarray.Dataset | Iterable[xarray.Dataset], caption: str = ""
) -> Figure:
    """Bifurcation diagram of 1-D sweeps over K (or any axis).

    Amplitude of the attractor against K/Kc, one curve per model (and per value
    of any further sweep axis): (a) peak-to-peak ln v, (b) v_max/V and v_min/V.
    Steady runs are drawn at zero amplitude (v/V = 1: their attractor is steady
    sliding, whatever transient they showed); runaway runs as triangles at the
    top (no bounded attractor); marker colours are the regimes.

    Parameters
    ----------
    datasets : xarray.Dataset or iterable of xarray.Dataset
        Sweep results, e.g. of ``configs/bifurcation_qs.yaml`` and
        ``configs/bifurcation_qd.yaml``; each gives one curve per value of its
        axes other than K/W.
    caption : str, optional
        An extra line of the figure's title.

    Returns
    -------
    matplotlib.figure.Figure
        A new figure with the two panels.

    Raises
    ------
    ValueError
        No point of any result has an analytic Kc > 0 (no instability to show), or a
        result is a single run.
    """
    import xarray as xr
    from matplotlib.lines import Line2D

    datasets = [datasets] if isinstance(datasets, xr.Dataset) else list(datasets)
    for k, ds in enumerate(datasets):
        check_result(ds, f"datasets[{k}]")
    _check_caption(caption)
    fig = new_figure(figsize=(12, 5))
    ax_a, ax_v = fig.subplots(1, 2)
    model_handles = []
    seen = set()
    curves = [c for ds in datasets for c in bifurcation_curves(ds) if c[1]["regime"].size]
    if not curves:
        raise ValueError("no point with an analytic Kc > 0 (no instability to show)")
    for k, (label, curve) in enumerate(curves):
        marker = MODEL_MARKERS[curve.attrs["model"]]
        style, size = CURVE_STYLES[k % len(CURVE_STYLES)]
        x = curve["K_over_Kc"].values
        names = regime_names(curve)
        regime = np.array([names[int(c)] for c in curve["regime"].values])
        steady = regime == "steady"
        bounded = ~np.isin(regime, ("runaway",))
        amp = np.where(steady, 0.0, curve["lnv_amplitude"].values)
        vmax = np.where(steady, 0.0, curve["lnv_max"].values)
        vmin = np.where(steady, 0.0, curve["lnv_min"].values)
        for ax, ys in ((ax_a, (amp,)), (ax_v, (np.exp(vmax), np.exp(vmin)))):
            for y in ys:
                ax.plot(x[bounded], y[bounded], color="k", ls=style, lw=1.0, zorder=2)
                for name in REGIMES:
                    sel = (regime == name) & bounded
                    ax.scatter(
                        x[sel],
                        y[sel],
                        marker=marker,
                        s=size,
                        color=REGIME_COLOURS[name],
                        edgecolors="k",
                        linewidths=0.4,
                        zorder=3,
                    )
            ax.scatter(
                x[~bounded],
                np.full((~bounded).sum(), 0.97),
                marker="^",
                s=30,
                color=REGIME_COLOURS["runaway"],
                edgecolors="k",
                linewidths=0.4,
                transform=ax.get_xaxis_transform(),
                zorder=3,
                clip_on=False,
            )
        seen.update(regime)
        model_handles.append(
            Line2D([], [], color="k", ls=style, marker=marker, mfc="white", label=label)
        )
    low = max(c["K_over_Kc"].min() for _, c in curves)
    high = min(c["K_over_Kc"].max() for _, c in curves)
    pad = 0.02 * (high - low) if high > low else 0.05
    for ax in (ax_a, ax_v):
        ax.axvline(1.0, color="k", ls="--", lw=1.2)
        ax.set_xlabel("K/Kc (each model's own analytic Kc)")
        if high > low:  # the K/Kc range every curve covers
            ax.set_xlim(float(low) - pad, float(high) + pad)
    bounded_amplitudes = [
        c["lnv_amplitude"].values[
            [regime_names(c)[int(r)] != "runaway" for r in c["regime"].values]
        ]
        for _, c in curves
    ]
    top = max((float(np.nanmax(a)) for a in bounded_amplitudes if a.size), default=np.nan)
    top = top if np.isfinite(top) and top > 0 else 1.0  # e.g. every run ran away
    ax_a.set_ylim(-0.03 * top, 1.12 * top)
    ax_a.set_ylabel("attractor peak-to-peak ln(v/V)")
    ax_v.set_yscale("log")
    ax_v.set_ylabel("attractor v_max/V (above 1) and v_min/V (below 1)")
    ax_a.set_title("(a) amplitude of ln v")
    ax_v.set_title("(b) largest and smallest velocity")
    low_v, high_v = ax_v.get_ylim()
    if low_v <= 0:  # no bounded point at all: no data to set the log range
        low_v, high_v = 0.1, 10.0
    ax_v.set_ylim(low_v, high_v * 10.0)  # room for the runaway markers at the top
    runaway = Line2D(
        [],
        [],
        ls="",
        marker="^",
        color=REGIME_COLOURS["runaway"],
        mec="k",
        label="runaway (no bounded attractor)",
    )
    handles = [*model_handles, runaway] if "runaway" in seen else model_handles
    ax_a.legend(handles=handles, loc="upper right", bbox_to_anchor=(1, 0.9), fontsize=8)
    regime_legend(
        ax_v,
        [n for n in REGIMES if n in seen and n != "runaway"],
        loc="upper right",
        fontsize=8,
        title="marker colour: regime",
        title_fontsize=8,
    )
    title = f"Bifurcation at K = Kc: {describe_common(datasets)}"
    _suptitle(fig, [title, caption])
    return fig


def describe_common(datasets):
    """Blocks, state law and the parameters shared by every dataset, for a title."""
    ds = datasets[0]
    blocks = int(ds.attrs["blocks"])
    kind = "one block" if blocks == 1 else f"{blocks} blocks"
    values = [parameter_values(d) for d in datasets]
    shared = {k: v for k, v in values[0].items() if all(other.get(k) == v for other in values)}
    return f"{kind}, {ds.attrs['state_law']} law, {parameter_text(shared)}"


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


#: Colour of each attractor kind in an orbit diagram (Okabe–Ito palette, colour-blind safe).
ATTRACTOR_COLOURS = {
    "fixed_point": "#0072B2",
    "periodic": "#009E73",
    "quasi_periodic": "#E69F00",
    "chaotic": "#CC79A7",
    "unresolved": "#999999",
    "unbounded": "#D55E00",
}


def plot_orbit_diagram(
    ds: xarray.Dataset,
    axis: str | None = None,
    ax: Axes | None = None,
    caption: str = "",
    lnv_range: tuple[float, float] | None = None,
) -> Figure:
    """Orbit diagram: the last events' maxima of ln v (block 0) against a sweep axis.

    Each run's ``event_lnv_peak`` (a periodic run: its cycle's n events; chaotic and
    quasi-periodic runs: their last kept events) as points coloured by attractor,
    and below, the largest Lyapunov exponent with its error where it was computed.

    A refined result is drawn on a grid (``refined_dataset.as_grid``).

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep result with events (``classification.events`` > 0).
    axis : str, optional
        The sweep axis along x (default: the first with more than one value); the
        other axes are taken at their first value (named in the title).
    ax : matplotlib.axes.Axes, optional
        Draw only the orbit panel there (default: a new figure with both panels).
    caption : str, optional
        An extra line of the figure's title.
    lnv_range : (float, float), optional
        The range of ln(v/V) shown, e.g. only the slips, where the small bumps of a
        sticking block (ln v/V ≈ −25) would squash them (default: all).

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or the figure of ``ax``.

    Raises
    ------
    ValueError
        The result has no events (``classification.events: 0``), or ``axis`` is
        not one of its sweep axes.
    """
    check_result(ds)
    _check_caption(caption)
    ds = _as_grid(ds)
    if "event_lnv_peak" not in ds:
        raise ValueError("no event maxima in this result (its classification.events is 0)")
    dims = list(ds["regime"].dims)
    axis = axis or next((d for d in dims if ds.sizes[d] > 1), dims[0])
    if axis not in dims:
        raise ValueError(f"no sweep axis {axis!r}; the axes are {', '.join(dims)}")
    others = {d: 0 for d in dims if d != axis}
    fixed = parameter_text({d: ds[d].values[0] for d in others})
    ds = ds.isel(others)
    if ax is None:
        fig = new_figure(figsize=(9.0, 6.4))
        ax, ax_lam = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1.0))
    else:
        fig, ax_lam = ax.figure, None
    x = ds[axis].values
    kinds = dict(zip((int(c) for c in ds["attractor"].attrs["flag_values"]),
                     ds["attractor"].attrs["flag_meanings"].split(), strict=True))  # fmt: skip
    peaks = ds["event_lnv_peak"].values
    for code, kind in kinds.items():
        rows = ds["attractor"].values == code
        if not rows.any():
            continue
        xs, ys = np.repeat(x[rows], peaks.shape[1]), peaks[rows].ravel()
        kept = np.isfinite(ys)  # NaN: fewer events than kept, or before the settled cycle
        ax.scatter(xs[kept], ys[kept], s=4, lw=0, color=ATTRACTOR_COLOURS[kind],
                   label=f"{kind.replace('_', '-')} ({int(rows.sum())})")  # fmt: skip
    ax.set_ylabel(
        axis_label(ds["event_lnv_peak"]).replace("at each of the last events", "at events")
    )
    if lnv_range is not None:
        ax.set_ylim(*lnv_range)
    ax.legend(loc="best", fontsize=8, markerscale=3)
    ax.set_title("orbit diagram: maxima of ln v at the last events", fontsize=10)
    for a in (ax, ax_lam):
        if a is not None:
            a.set_xscale("log" if _log_spaced(x) else "linear")
    last = ax_lam or ax
    last.set_xlabel(axis_label(ds[axis]))
    if ax_lam is not None:
        lam, err = ds["lyapunov_exponent"].values, ds["lyapunov_error"].values
        colours = [ATTRACTOR_COLOURS[kinds[int(c)]] for c in ds["attractor"].values]
        ax_lam.axhline(0.0, color="#BBBBBB", lw=0.8)
        ax_lam.errorbar(x, lam, yerr=err, fmt="none", ecolor="#BBBBBB", lw=0.8)
        ax_lam.scatter(x, lam, s=10, c=colours)
        ax_lam.set_ylabel(axis_label(ds["lyapunov_exponent"]))
        ax.set_xlabel("")
        note = "; ".join(filter(None, [fixed and f"at {fixed}", initial_text(ds)]))
        _suptitle(fig, [f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}", note, caption])
    return fig


def plot_trace(ds: xarray.Dataset, ax: Axes | None = None) -> Figure:
    """Slip velocity of every block against time, of one trace.

    The time axis ends where the run ended; the title names the parameters, K/Kc
    and the start.

    Parameters
    ----------
    ds : xarray.Dataset
        A trace: :func:`sweep.trace.compute_trace`, or a file written by
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


def save_figure(fig: Figure, out: str | os.PathLike, dpi: float = DPI) -> Path:
    """Write a figure to a file atomically (a temporary file, then a rename).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, e.g. from :func:`plot_result`.
    out : str or os.PathLike
        The file; its suffix picks the format: ``.png``, ``.pdf`` or ``.svg``.
        Missing folders are created.
    dpi : float, default 150
        Resolution of a PNG, in dots per inch.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        The suffix is not ``.png``, ``.pdf`` or ``.svg``.
    """
    from pathlib import Path

    from .store import replaced_atomically

    out = Path(out)
    if out.suffix not in FORMATS:
        raise ValueError(f"{out}: figure files end in {', '.join(FORMATS)}")
    out.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format=FORMATS[out.suffix])
    return out


def _cell_positions(values):
    """Positions of grid values on a map axis: the values themselves where evenly spaced
    (linearly or in log), else their indices (the caller labels the ticks)."""
    v = np.asarray(values, float)
    even = v.size < 3 or np.allclose(np.diff(v), v[1] - v[0]) or _log_spaced(v)
    return (v, False) if even else (np.arange(v.size, dtype=float), True)


def _dominant_regime_map(ax, ds):
    """Regime of most ensemble members (``regime_fraction``) over a result's two sweep
    axes on ``ax``, hatched where the starts disagree. An unevenly spaced second axis is
    drawn by index, one row per value. Returns the y positions of its values."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import MaxNLocator

    fraction = ds["regime_fraction"]
    xdim, ydim = (d for d in fraction.dims if d != "regime_name")
    fraction = fraction.transpose(ydim, xdim, "regime_name").values
    dominant = fraction.argmax(axis=-1)
    cmap = ListedColormap([REGIME_COLOURS[name] for name in REGIMES])
    norm = BoundaryNorm(np.arange(len(REGIMES) + 1) - 0.5, len(REGIMES))
    y, by_index = _cell_positions(ds[ydim].values)
    xe, ye = _edges(ds[xdim].values), _edges(y)
    ax.pcolormesh(xe, ye, dominant, cmap=cmap, norm=norm)
    for i, j in zip(*np.nonzero(fraction.max(axis=-1) < 1.0), strict=True):
        ax.add_patch(
            Rectangle(
                (xe[j], ye[i]),
                xe[j + 1] - xe[j],
                ye[i + 1] - ye[i],
                fill=False,
                hatch="///",
                edgecolor="white",
                linewidth=0,
            )
        )
    if by_index:
        ax.set_yticks(y, [f"{v:g}" for v in ds[ydim].values])
    ax.xaxis.set_major_locator(MaxNLocator(5))
    ax.set_xlabel(axis_label(ds[xdim]))
    ax.set_ylabel(axis_label(ds[ydim]))
    return y


def _critical_line(ax, ds, y, **style):
    """``critical_K_W`` of a result over (K_W, second axis) at positions ``y`` on ``ax``."""
    kc = ds["critical_K_W"]
    ax.plot((kc.isel(K_W=0) if "K_W" in kc.dims else kc).values, y, **style)


def plot_nblock(sizes, spread, coupling, caption=""):
    """Many contact points (issue 14): where steady sliding is lost and what follows.

    ``sizes``: DataArray ``Kc_ratio`` (dims coupling, blocks, seed) of the critical
    stiffness of unequal blocks relative to identical blocks with their mean D0;
    ``spread``: an ensemble result over (K_W, spread_D0); ``coupling``: an ensemble
    result over (K_W, k2_W). Returns the Figure (three panels).
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig = new_figure(figsize=(16, 5.2))
    axes = fig.subplots(1, 3)
    ax = axes[0]
    for name, marker in zip(sizes["coupling"].values, "osD", strict=False):
        r = sizes.sel(coupling=name)
        n = r["blocks"].values
        ax.fill_between(n, r.min("seed"), r.max("seed"), alpha=0.2)
        ax.plot(n, r.mean("seed"), marker=marker, label=f"{name}: mean, min–max")
    ax.axhline(1.0, color="k", ls="--", lw=1.2, label="identical blocks (any N, coupling)")
    ax.set_xscale("log", base=2)
    ax.set_xticks(sizes["blocks"].values, [str(n) for n in sizes["blocks"].values])
    ax.set_xlabel("number of blocks N")
    ax.set_ylabel("Kc / Kc(identical blocks, mean D0)")
    ax.set_title(sizes.attrs.get("title", ""), fontsize=9)
    ax.legend(fontsize=8)

    handles = [Patch(color=REGIME_COLOURS[name], label=name.replace("_", "-")) for name in REGIMES]
    handles.append(Patch(facecolor="white", edgecolor="k", hatch="///", label="starts disagree"))
    kc_style = {"color": "k", "ls": "--", "lw": 1.5}
    rows = {}
    for ax, ds, title in ((axes[1], spread, "unequal D0"), (axes[2], coupling, "coupling")):
        rows[title] = _dominant_regime_map(ax, ds)
        _critical_line(ax, ds, rows[title], **kc_style)
        ax.set_title(
            f"{ds.attrs['blocks']} blocks, {ds.attrs['coupling'].split(',')[0]}: "
            f"{title}; regime of most of {ds.sizes['member']} starts",
            fontsize=9,
        )
    mean_d0 = spread["D0_block"].isel(K_W=0).mean("block").values
    values = parameter_values(spread)
    kc_mean = (values["B"] - values["A"]) / mean_d0
    axes[1].plot(kc_mean, rows["unequal D0"], color="#F0E442", ls=":", lw=2)
    handles += [
        Line2D([], [], label="Kc of the blocks (Jacobian)", **kc_style),
        Line2D([], [], color="#F0E442", ls=":", lw=2, label="identical blocks, mean D0"),
    ]
    axes[2].legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1))
    common = parameter_text({k: values[k] for k in ("A", "B", "D0", "V")})
    _suptitle(fig, [f"{spread.attrs['model']}, {spread.attrs['state_law']} law: {common}", caption])
    return fig


# --- refined results (sweep/refine.py): cells at their level, boundaries on top ---------


def _refined(ds):
    from .refined_dataset import is_refined

    return "regime" in ds and is_refined(ds)


def _as_grid(ds):
    """A refined result on a grid (``refined_dataset.as_grid``); any other as it is."""
    from .refined_dataset import as_grid

    return as_grid(ds) if _refined(ds) else ds


def plot_refined(ds, caption="", ax=None):
    """A refined result (``sweep/refine.py``); returns the Figure.

    Over two refined axes: left, the cells at their level, each coloured by the regime
    of its runs (a cell whose corners differ, by quarters: each its corner's), with the
    boundaries between labels on top (``sweep.boundaries``: solid where the regime
    changes, dashed where only the attractor or the number of events does) and the
    analytic Kc (K/Kc = 1) dashed; right, the level of every cell. Over one refined axis:
    the measures of :func:`plot_result` at every run, the boundaries' cells shaded.
    More axes: the grid of level 0 (:func:`plot_result`). With ``ax``: only the left
    panel, there. ``caption``: an extra title line.
    """
    from .phase_boundaries import boundaries
    from .refine import Lattice
    from .refined_dataset import along_axis, refined_config, to_grid

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
        lines = [f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}",
                 f"{stopped}: {runs} runs per level; {initial_text(ds)}", caption]  # fmt: skip
        _suptitle(fig, lines)
    return fig


def _refined_cells(ax, ds, lattice, what):
    """The unsplit cells of a refined result on ``ax`` as rectangles: coloured by the
    attractor of their corners' runs (``what="kind"``; with an ensemble by the regime of
    most members; a cell whose corners differ by quarters) or by their level
    (``"level"``). Returns ``{(colour, name): runs}`` of each kind."""
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import BoundaryNorm, ListedColormap

    from .refine import axis_values, cell_tree
    from .refined_dataset import lattice_index

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
        cells = PolyCollection(verts, array=colours, cmap=cmap, clim=(-0.5, lattice.levels + 0.5),
                               edgecolors="face", linewidths=0.2)  # fmt: skip
        ax.add_collection(cells)
        ax.figure.colorbar(cells, ax=ax, label="level of the cell (its size: grid step / 2^level)",
                           ticks=range(lattice.levels + 1))  # fmt: skip
        ax.set_title("cells at their level")
        return {}
    cmap = ListedColormap([colour for colour, _ in kinds])
    norm = BoundaryNorm(np.arange(len(kinds) + 1) - 0.5, len(kinds))
    ax.add_collection(PolyCollection(verts, array=colours, cmap=cmap, norm=norm,
                                     edgecolors="face", linewidths=0.2))  # fmt: skip
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

    handles = [Patch(color=colour, label=f"{name.replace('_', '-')} ({n})")
               for (colour, name), n in counts.items() if n]  # fmt: skip
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
    from .refined_dataset import to_grid

    x, y = (lattice.axes[i] for i in np.flatnonzero(lattice.split))
    coarse = to_grid(ds[["regime", "K_over_Kc", "critical_K_W"]], min(lattice.levels, 3))
    ratio = stiffness_ratio(coarse).transpose(y.name, x.name).values
    if np.any(np.isfinite(ratio)):
        ax.contour(coarse[x.name].values, coarse[y.name].values, ratio, levels=[1.0],
                   colors="k", linewidths=1.5, linestyles=":")  # fmt: skip
    for axis, set_lim, set_scale, set_label in (
        (x, ax.set_xlim, ax.set_xscale, ax.set_xlabel),
        (y, ax.set_ylim, ax.set_yscale, ax.set_ylabel),
    ):
        values = np.asarray(axis.values)
        set_lim(values.min(), values.max())
        set_scale("log" if axis.span and axis.span[0] == "log" else "linear")
        set_label(axis_label(ds[axis.name]))
