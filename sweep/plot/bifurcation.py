"""Diagrams against one sweep axis: the bifurcation diagram (:func:`plot_bifurcation`:
the attractor's amplitude against K/Kc, one curve per model) and the orbit diagram
(:func:`plot_orbit_diagram`: the last events' maxima of ln v, coloured by attractor,
above the largest Lyapunov exponent)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

from ..results.checks import check_result
from ..results.dataset import parameter_values
from ..variables import REGIMES
from .common import (
    ATTRACTOR_COLOURS,
    REGIME_COLOURS,
    TYPE_BOX,
    _as_grid,
    _check_caption,
    _log_spaced,
    _squeeze,
    _suptitle,
    axis_label,
    describe,
    initial_text,
    kind_text,
    kinds_legend_text,
    new_figure,
    parameter_text,
    regime_legend,
    regime_names,
    scale_text,
)

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Marker of each model in a bifurcation diagram (lines in black; colours are regimes).
MODEL_MARKERS = {"quasi-static": "o", "quasi-dynamic": "s", "inertial": "D"}
#: Colour of the lines at the boundaries between neighbouring points, typed.
TYPE_COLOUR = "#666666"
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
        raise ValueError(
            "a bifurcation diagram needs a sweep axis with more than one value; "
            "this result is one run"
        )
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
    sliding, whatever transient they showed); runaway runs have no bounded attractor,
    so no amplitude: they are marked as triangles in a strip above each panel, off its
    axis; marker colours are the regimes. Between neighbouring points of a curve whose
    labels differ a dotted line marks the boundary, its type written low in panel (a)
    (``refine.boundary_types.boundary_types_1d``). The title states each model's dimensionless
    number and the largest v_max/V of the bounded runs (``plot.common.scale_text``).

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
    curves = [c for ds in datasets for c in bifurcation_curves(ds) if c[1]["regime"].size]
    if not curves:
        raise ValueError("no point with an analytic Kc > 0 (no instability to show)")
    runaway_code = REGIMES.index("runaway")
    any_runaway = any((c["regime"].values == runaway_code).any() for _, c in curves)
    fig = new_figure(figsize=(12, 5.4 if any_runaway else 5))
    if any_runaway:  # a strip above each panel for the runs without an amplitude
        (strip_a, strip_v), (ax_a, ax_v) = fig.subplots(
            2, 2, sharex="col", height_ratios=(0.08, 1), gridspec_kw={"hspace": 0.0}
        )
        strips = {ax_a: strip_a, ax_v: strip_v}
    else:
        ax_a, ax_v = fig.subplots(1, 2)
        strips = {}
    model_handles = []
    seen = set()
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
            if ax in strips:
                strips[ax].scatter(
                    x[~bounded],
                    np.full((~bounded).sum(), 0.5),
                    marker="^",
                    s=30,
                    color=REGIME_COLOURS["runaway"],
                    edgecolors="k",
                    linewidths=0.4,
                )
        seen.update(regime)
        model_handles.append(
            Line2D([], [], color="k", ls=style, marker=marker, mfc="white", label=label)
        )
    low = max(c["K_over_Kc"].min() for _, c in curves)
    high = min(c["K_over_Kc"].max() for _, c in curves)
    pad = 0.02 * (high - low) if high > low else 0.05
    for ax in (ax_a, ax_v, *strips.values()):
        ax.axvline(1.0, color="k", ls="--", lw=1.2)
        if high > low:  # the K/Kc range every curve covers
            ax.set_xlim(float(low) - pad, float(high) + pad)
    for ax in (ax_a, ax_v):
        ax.set_xlabel("K/Kc (each model's own analytic Kc)")
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
    for ax, title in ((ax_a, "(a) amplitude of ln v"), (ax_v, "(b) largest and smallest velocity")):
        top_axes = strips.get(ax, ax)
        top_axes.set_title(title)
    if "runaway" in seen and len(seen) == 1:  # no bounded point: no data for the log range
        ax_v.set_ylim(0.1, 10.0)
    for strip in strips.values():
        strip.set_ylim(0, 1)
        strip.set_yticks([0.5], ["runaway"], fontsize=8)
        strip.tick_params(axis="x", labelbottom=False)
    runaway = Line2D(
        [],
        [],
        ls="",
        marker="^",
        color=REGIME_COLOURS["runaway"],
        mec="k",
        label="runaway: no bounded attractor, no amplitude (strip above)",
    )
    handles = [*model_handles, runaway] if "runaway" in seen else model_handles
    kinds = _draw_types((ax_a, ax_v), curves)
    if kinds:
        line = "a boundary between neighbouring points, its type low in (a)"
        handles.append(Line2D([], [], color=TYPE_COLOUR, ls=":", label=line))
        handles += [Line2D([], [], ls="", label=text) for text in kinds_legend_text(kinds)]
    ax_a.legend(handles=handles, loc="upper right", fontsize=8)
    regime_legend(
        ax_v,
        [n for n in REGIMES if n in seen and n != "runaway"],
        loc="upper right",
        fontsize=8,
        title="marker colour: regime",
        title_fontsize=8,
    )
    title = f"Bifurcation at K = Kc: {describe_common(datasets)}"
    left, right = ax_a.get_xlim()
    shown = [
        c.isel({c["K_over_Kc"].dims[0]: (c["K_over_Kc"] >= left) & (c["K_over_Kc"] <= right)})
        for _, c in curves
    ]
    _suptitle(fig, [title, scale_text(datasets, shown), caption])
    return fig


def _draw_types(axes, curves):
    """The boundaries between neighbouring points of each curve
    (``refine.boundary_types.boundary_types_1d``) as vertical dotted lines on ``axes`` at
    the middle of their K/Kc, their type's short text low in the first, beside the line
    (left for the first curve, right for the second, and the next pair higher up, so that
    curves whose boundaries share a K/Kc do not write over each other); returns the types
    drawn."""
    from ..refine.boundary_types import boundary_types_1d

    kinds = []
    for k, (_, curve) in enumerate(curves):
        dims = curve["regime"].dims
        if len(dims) != 1 or curve.sizes[dims[0]] < 2:  # an ensemble, or one point
            continue
        line = curve.sortby(dims[0])
        ratio = line["K_over_Kc"].values
        for crossing in boundary_types_1d(line, dims[0]):
            x = float(ratio[crossing.index] + ratio[crossing.index + 1]) / 2
            for ax in axes:
                ax.axvline(x, color=TYPE_COLOUR, ls=":", lw=1.0, zorder=1)
            axes[0].text(
                x,
                0.05 + 0.35 * (k // 2),
                kind_text(crossing.kind),
                transform=axes[0].get_xaxis_transform(),
                fontsize=7,
                rotation=90,
                ha=("right", "left")[k % 2],
                va="bottom",
                zorder=6,
                bbox=TYPE_BOX,
            )
            kinds.append(crossing.kind)
    return kinds


def describe_common(datasets):
    """Blocks, state law and the parameters shared by every dataset, for a title."""
    ds = datasets[0]
    blocks = int(ds.attrs["blocks"])
    kind = "one block" if blocks == 1 else f"{blocks} blocks"
    values = [parameter_values(d) for d in datasets]
    shared = {k: v for k, v in values[0].items() if all(other.get(k) == v for other in values)}
    return f"{kind}, {ds.attrs['state_law']} law, {parameter_text(shared)}"


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
    kinds = dict(
        zip(
            (int(c) for c in ds["attractor"].attrs["flag_values"]),
            ds["attractor"].attrs["flag_meanings"].split(),
            strict=True,
        )
    )
    peaks = ds["event_lnv_peak"].values
    for code, kind in kinds.items():
        rows = ds["attractor"].values == code
        if not rows.any():
            continue
        xs, ys = np.repeat(x[rows], peaks.shape[1]), peaks[rows].ravel()
        kept = np.isfinite(ys)  # NaN: fewer events than kept, or before the settled cycle
        ax.scatter(
            xs[kept],
            ys[kept],
            s=4,
            lw=0,
            color=ATTRACTOR_COLOURS[kind],
            label=f"{kind.replace('_', '-')} ({int(rows.sum())})",
        )
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
        title = f"{ds.attrs.get('sweep_name', '')}: {describe(ds)}"
        _suptitle(fig, [title, note, scale_text(ds), caption])
    return fig
