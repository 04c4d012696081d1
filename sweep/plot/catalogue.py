"""Figures of a run's slip-event catalogue: its events in space and time beside its
size–frequency plot (:func:`plot_catalogue`), and maps of the catalogue's statistics
over a sweep's two axes on even, categorical cells (:func:`catalogue_map`): a
statistic that does not apply (its status not ``ok``) is left blank with the reason
written in its cell, and no b-value is drawn or printed where the Gutenberg–Richter
law was rejected. :func:`catalogue_caption` states every fixed setting a catalogue
depends on."""

from __future__ import annotations

import re
import textwrap
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..model.physics import PARAMETERS
from ..results.checks import check_result
from ..results.gutenberg_richter import N_BOOTSTRAP
from ..results.realisations import over_realisations
from .common import (
    TITLE_PARAMETERS,
    _suptitle,
    axis_label,
    colormap,
    describe,
    new_figure,
    parameter_text,
    unit_text,
)

if TYPE_CHECKING:
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: The status variable that says whether each statistic applies.
STATUS_OF = {
    "b_value": "b_value_status",
    "b_value_error": "b_value_status",
    "b_value_truncated": "b_value_truncated_status",
    "b_value_truncated_error": "b_value_truncated_status",
    "recurrence_mean": "recurrence_status",
    "recurrence_cv": "recurrence_status",
}


def catalogue_run(ds, point=None):
    """The one run of a result with a catalogue at ``point``: a mapping of sweep axes
    (and ``member``) to values, the nearest value taken on each axis; axes not named
    are taken at their first value. Returns the run's Dataset (no sweep dimension)."""
    if "slip_event_start" not in ds:
        raise ValueError("this result has no slip-event catalogue (config key catalogue.capacity)")
    if point is not None and not isinstance(point, Mapping):
        raise TypeError(f"point must be a mapping of sweep axes to values, got {point!r}")
    point = dict(point or {})
    bad = [
        k
        for k, v in point.items()
        if not (isinstance(v, (int, float, np.number)) and np.isfinite(v))
    ]
    if bad:
        raise ValueError(f"point: {', '.join(map(str, bad))} must be finite numbers")
    unknown = set(point) - set(ds["slip_event_start"].dims[:-1])
    if unknown:
        axes = ", ".join(ds["slip_event_start"].dims[:-1]) or "none"
        raise ValueError(f"point names {', '.join(sorted(unknown))}: not a sweep axis ({axes})")
    run = ds.sel({k: v for k, v in point.items() if k != "member"}, method="nearest")
    if "member" in point:
        run = run.isel(member=int(point["member"]))
    extra = [d for d in run["slip_event_start"].dims if d != "slip_event"]
    return run.isel(dict.fromkeys(extra, 0))


def plot_catalogue(
    ds: xarray.Dataset,
    point: Mapping[str, float] | None = None,
    fig: Figure | None = None,
    *,
    caption: bool = True,
) -> Figure:
    """One run's slip events: block against time, each event a bar over the blocks it
    spanned from its start to its end, coloured by its magnitude, its first block
    marked; beside it the size–frequency plot (events with magnitude ≥ m) with the
    Gutenberg–Richter line of the run's b-value above m_c and its truncated fit, each
    only where it holds (else the reason); the title states every fixed setting
    (:func:`catalogue_caption`).

    Parameters
    ----------
    ds : xarray.Dataset
        A result with a catalogue (config key ``catalogue.capacity``).
    point : Mapping, optional
        The run: sweep axis → value (the nearest is taken; ``member`` → index);
        axes not named at their first value.
    fig : matplotlib.figure.Figure or SubFigure, optional
        Draw there (default: a new figure).
    caption : bool, default True
        Title the figure with :func:`catalogue_caption` above the run's line (False:
        the run's line only, for a figure whose own title carries the caption).

    Returns
    -------
    matplotlib.figure.Figure
        The new figure, or ``fig``.

    Raises
    ------
    ValueError
        The result has no catalogue, or ``point`` names something that is not a sweep
        axis.
    """
    check_result(ds)
    if fig is not None and not hasattr(fig, "subplots"):
        raise TypeError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
    run = catalogue_run(ds, point)
    count = min(int(run["slip_event_count"]), run.sizes["slip_event"])
    ev = run.isel(slip_event=slice(0, count))
    fig = new_figure(figsize=(11, 4.6)) if fig is None else fig
    space, sizes = fig.subplots(1, 2, width_ratios=(2.2, 1))
    _space_time(fig, space, ev, int(ds.attrs["blocks"]))
    _size_frequency(sizes, ev, run)
    axes = {k: float(run[k]) for k in ds["slip_event_start"].dims[:-1] if k in run.coords}
    spreads = [f"{k} = {v:g}" for k, v in axes.items() if k.startswith("spread_")]
    where = ", ".join(
        t
        for t in (parameter_text({k: v for k, v in axes.items() if k in PARAMETERS}), *spreads)
        if t
    )
    kept = f"{count} of {int(run['slip_event_count'])} events kept"
    lines = catalogue_caption(ds) if caption else []
    _suptitle(fig, [*lines, f"run shown: {where}; {kept}" if where else kept])
    return fig


def _space_time(fig, ax, ev, blocks):
    """Each event a bar from its start to its end over its lowest to highest block."""
    from matplotlib.colors import Normalize

    start = ev["slip_event_start"].values
    end = start + ev["slip_event_duration"].values
    lo = ev["slip_event_block_low"].values
    hi = ev["slip_event_block_high"].values
    mag = ev["slip_event_magnitude"].values
    finite = mag[np.isfinite(mag)]
    norm = Normalize(*(np.percentile(finite, [1, 100]) if finite.size else (0, 1)))
    cmap = colormap("viridis")
    for s, e, a, b, m in zip(start, end, lo, hi, mag, strict=True):
        ax.add_patch(_bar(s, e, a, b, cmap(norm(m))))
    ax.scatter(
        start,
        ev["slip_event_first_block"].values,
        s=6,
        c="k",
        marker=".",
        lw=0,
        label="first block",
    )
    if start.size:
        ax.set_xlim(start.min(), end.max())
    ax.set_ylim(-0.5, blocks - 0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("block")
    ax.legend(loc="upper right", fontsize=8)
    from matplotlib.cm import ScalarMappable

    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="magnitude (2/3) log10(slip/D0)")


def _bar(start, end, lo, hi, colour):
    """A rectangle from ``start`` to ``end`` over blocks ``lo`` to ``hi``."""
    from matplotlib.patches import Rectangle

    return Rectangle((start, lo - 0.45), max(end - start, 0.0), hi - lo + 0.9, color=colour, lw=0)


def _size_frequency(ax, ev, run):
    """Events with magnitude ≥ m against m; the run's Gutenberg–Richter fit where it
    holds (``b_value_status`` ok) and its truncated fit where that holds, else the
    reason in place of the fit."""
    mag = np.sort(ev["slip_event_magnitude"].values)
    mag = mag[np.isfinite(mag)]
    ax.step(mag, np.arange(mag.size, 0, -1), where="post", color="k", lw=1.2, label="events")
    mc = float(run["magnitude_completeness"])
    above = int((mag >= mc).sum()) if np.isfinite(mc) else 0
    notes = []
    for key, name, style in (("b_value", "GR", "--"), ("b_value_truncated", "truncated GR", ":")):
        b, err = float(run[key]), float(run[f"{key}_error"])
        if np.isfinite(b) and above:
            m_max = float(run["magnitude_max"])
            m = np.linspace(mc, m_max, 80)
            ax.plot(
                m,
                above * _survival(m, mc, b, m_max if key == "b_value_truncated" else None),
                style,
                color="#D55E00" if key == "b_value" else "#0072B2",
                lw=1.5,
                label=f"{name}: b = {b:.2f} ± {err:.2f} (m ≥ {mc:.2f})",
            )
        else:
            notes.append(textwrap.fill(f"no {name} fit: {_status_text(run, key)}", 36))
    if np.isfinite(mc):
        ax.axvline(mc, color="#999999", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("magnitude m = (2/3) log10(slip/D0)")
    ax.set_ylabel("events with magnitude ≥ m")
    ax.legend(loc="lower left", fontsize=7.5, title="\n".join(notes) or None, title_fontsize=7.5)


def _survival(m, mc, b, m_max=None):
    """Share of a Gutenberg–Richter law of ``b`` above ``mc`` at or above ``m``
    (truncated at ``m_max`` if given; Page 1968)."""
    beta = b * np.log(10.0)
    if m_max is None:
        return np.exp(-beta * (m - mc))
    if abs(beta * (m_max - mc)) < 1e-9:
        return (m_max - m) / (m_max - mc)
    return np.expm1(-beta * (m_max - m)) * np.exp(-beta * (m - mc)) / np.expm1(-beta * (m_max - mc))


def _status_text(run, key):
    """Why ``key`` (a b-value) of a run is not given: its status, with the KS p-value."""
    status = run[f"{key}_status"]
    names = status.attrs["flag_meanings"].split()
    text = names[int(status)].replace("_", " ")
    p = float(run[f"{key}_ks_p"])
    n = int(run["magnitude_events"])
    return f"{text} (n = {n}" + (f", KS p = {p:.2g})" if np.isfinite(p) else ")")


def catalogue_map(ds: xarray.Dataset, name: str, ax: Axes, ylabel: bool = True) -> Axes:
    """A statistic of a result with a catalogue over its two sweep axes (the others at
    their first value), one equal cell per grid point whatever the axes' spacing, each
    value written in its cell; blank, with the reason, where the statistic does not
    apply (:data:`STATUS_OF`); the y axis labelled if ``ylabel``. With realisations of
    the disorder (axis ``spread_seed``) a cell is the mean over the seeds where the
    statistic applies, written with their standard deviation and how many seeds those
    are; blank with the commonest reason where it applies at none. Returns ``ax``."""
    from matplotlib.colors import Normalize

    var = ds[name]
    attrs = var.attrs
    seeds = "spread_seed" in var.dims
    dims = [d for d in var.dims if d in ds.coords and ds.sizes[d] > 1 and d != "spread_seed"][:2]
    if len(dims) != 2:
        raise ValueError(
            f"a catalogue map needs two sweep axes with more than one value, got {dims}"
        )
    keep = (*dims, "spread_seed") if seeds else tuple(dims)
    ydim, xdim = dims
    var = var.isel({d: 0 for d in var.dims if d not in keep}).transpose(*keep)
    status = None
    if name in STATUS_OF:
        sv = ds[STATUS_OF[name]]
        sv = sv.isel({d: 0 for d in sv.dims if d not in keep}).transpose(*keep)
        meanings = sv.attrs["flag_meanings"].split()
        status = sv.values.astype(int)
        var = var.where(sv == 0)
    if seeds:  # mean, spread and count over the seeds where the statistic applies
        over = over_realisations(var.to_dataset(name=name))
        values, spread, count = (over[f"{name}_{k}"].values for k in ("mean", "std", "count"))
        n_seeds = var.sizes["spread_seed"]
    else:
        values = var.values.astype(float)
        status = None if status is None else status[..., None]
    finite = values[np.isfinite(values)]
    norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0.0, 1.0))
    cmap = colormap("viridis").with_extremes(bad="white")
    mesh = ax.pcolormesh(
        np.ma.masked_invalid(values), cmap=cmap, norm=norm, edgecolor="#BBBBBB", lw=0.5
    )
    for (j, i), v in np.ndenumerate(values):
        if np.isfinite(v):
            text = f"{v:.2g}"
            if seeds:
                text += (f" ± {spread[j, i]:.1g}" if count[j, i] > 1 else "") + (
                    f"\n({count[j, i]}/{n_seeds} seeds)"
                )
            colour = "white" if norm(v) < 0.5 else "black"
            ax.text(i + 0.5, j + 0.5, text, ha="center", va="center", fontsize=7.5, color=colour)
        else:
            why = "not measured"
            if status is not None:
                why = meanings[np.bincount(status[j, i], minlength=len(meanings)).argmax()]
            grey = {"ha": "center", "va": "center", "fontsize": 6.5, "color": "#555555"}
            ax.text(i + 0.5, j + 0.5, why.replace("_", "\n"), **grey)
    ax.set_xticks(np.arange(ds.sizes[xdim]) + 0.5, [f"{x:g}" for x in ds[xdim].values])
    ax.set_yticks(np.arange(ds.sizes[ydim]) + 0.5, [f"{y:g}" for y in ds[ydim].values])
    ax.set_xlabel(axis_label(ds[xdim]))
    if ylabel:
        ax.set_ylabel(axis_label(ds[ydim]))
    if finite.size:
        ax.figure.colorbar(mesh, ax=ax, label=unit_text(attrs.get("units", "1")))
    blank = " (blank: does not apply)" if name in STATUS_OF else ""
    over = f", mean over {n_seeds} seeds" if seeds else ""
    ax.set_title(textwrap.fill(attrs.get("long_name", name) + over + blank, 32), fontsize=9)
    return ax


def catalogue_caption(ds: xarray.Dataset) -> list[str]:
    """Caption lines of a result with a catalogue: blocks, model, law, coupling and
    every fixed parameter; the spread (distribution, seed, size if fixed); the catalogue's
    threshold, transient, completeness and system-wide extent; the dimensionless mass
    M̂ = m V²/(W D0) (or damping η̂ = ηV/W) and the largest peak v/V of any block in
    any slip event of its runs."""
    from ..results.dataset import parameter_values

    a = ds.attrs
    fixed = parameter_values(ds)
    others = []  # the fixed parameters the dynamics do not depend on (TITLE_PARAMETERS)
    for name, value in fixed.items():
        if name not in TITLE_PARAMETERS:
            units = unit_text(PARAMETERS[name].units)
            others.append(f"{name} = {value:g}" + (f" {units}" if units else ""))
    coupling = f"; {a['coupling']}" if "coupling" in a else ""
    lines = [", ".join([describe(ds), *others]) + coupling]
    spread = []
    if "spread_distribution" in a:
        sizes = [
            f"{k[7:]} spread {a[k]:g}"
            for k in a
            if k.startswith("spread_") and k not in ("spread_distribution", "spread_seed")
        ]
        seeds = (
            f"seeds {', '.join(str(int(x)) for x in ds['spread_seed'].values)}"
            if "spread_seed" in ds.dims
            else f"seed {a['spread_seed']}"
        )
        spread = [f"spread {a['spread_distribution']} ({seeds})", *sizes]
    mc = a.get("catalogue_completeness")
    lines.append(
        ", ".join(
            [
                *spread,
                f"slip threshold v > {a['catalogue_slip_v_over_V']:g} V",
                f"transient {a['catalogue_after']:g} t_end",
                f"m_c = {mc:g}" if mc is not None else "m_c = each run's smallest magnitude",
                f"system-wide: extent ≥ {a.get('catalogue_system_wide_extent', 0.9):g} × blocks",
            ]
        )
    )
    regime = []
    d0 = fixed.get("D0")
    if "m_W" in fixed and "V" in fixed and d0:
        regime.append(f"M̂ = mV²/(W D0) = {fixed['m_W'] * fixed['V'] ** 2 / d0:.3g}")
    if "eta_W" in fixed and "V" in fixed:
        regime.append(f"η̂ = ηV/W = {fixed['eta_W'] * fixed['V']:.3g}")
    if "slip_event_v_peak" in ds and "V" in fixed:  # any block's, not block 0's v_max
        top = float(ds["slip_event_v_peak"].max()) / fixed["V"]
        regime.append(f"largest v_max/V of the runs' slip events = {top:.3g}")
    lines.append(", ".join(regime))
    return lines


#: Panels of :func:`plot_threshold_sensitivity`: variable, its interval's bounds (or None).
SENSITIVITY_PANELS = (
    ("slip_event_count", None),
    ("system_wide_fraction", None),
    ("recurrence_cv", ("recurrence_cv_low", "recurrence_cv_high")),
    ("b_value_ks_p", None),
)


#: Where a goodness-of-fit p-value of 0 (no synthetic sample as far as the data) is drawn.
P_FLOOR = 1.0 / N_BOOTSTRAP


def plot_threshold_sensitivity(ds: xarray.Dataset) -> Figure:
    """How a catalogue's statistics move with its slip threshold.

    One line per point of the result's other axes (their mean and range over
    ``spread_seed`` if it has one): the number of events, the system-wide fraction, the
    recurrence's CV (with its 95 % interval, where it applies) and the goodness-of-fit
    p-value of the Gutenberg–Richter law (the b-value is given only above the dotted
    0.1; p = 0 is drawn at :data:`P_FLOOR`). Statistics that do not apply are left out.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`sweep.threshold_sensitivity` (dimension ``slip_v_over_V``).

    Returns
    -------
    matplotlib.figure.Figure
        Four panels against the threshold, titled with every fixed setting.
    """
    fig = new_figure(figsize=(13, 4.8))
    axes = fig.subplots(1, len(SENSITIVITY_PANELS))
    thr = ds["slip_v_over_V"].values
    others = [d for d in ds["slip_event_count"].dims if d not in ("slip_v_over_V", "spread_seed")]
    stacked = ds.stack(point=others) if others else ds.expand_dims(point=[0])
    for k in range(stacked.sizes["point"]):
        run = stacked.isel(point=k)
        label = ", ".join(f"{d} = {float(run[d]):g}" for d in others)
        for ax, (name, bounds) in zip(axes, SENSITIVITY_PANELS, strict=True):
            values = run[name]
            if name in STATUS_OF:
                values = values.where(run[STATUS_OF[name]] == 0)
            if name == "b_value_ks_p":  # p = 0: no synthetic sample was as far
                values = values.clip(min=P_FLOOR)
            seeds = "spread_seed" in values.dims
            mid = values.mean("spread_seed") if seeds else values
            (line,) = ax.plot(thr, mid, "o-", label=label)
            if seeds:
                low, high = values.min("spread_seed"), values.max("spread_seed")
                ax.fill_between(thr, low, high, color=line.get_color(), alpha=0.2)
            elif bounds is not None:
                low, high = (run[b].where(run[STATUS_OF[name]] == 0) for b in bounds)
                ax.fill_between(thr, low, high, color=line.get_color(), alpha=0.2)
    for ax, (name, _) in zip(axes, SENSITIVITY_PANELS, strict=True):
        ax.set_xscale("log")
        ax.set_xticks(thr, [f"{t:g}" for t in thr])
        ax.minorticks_off()
        ax.set_xlabel(axis_label(ds["slip_v_over_V"]))
        ax.set_title(textwrap.fill(ds[name].attrs.get("long_name", name), 30), fontsize=9)
    axes[-1].set_yscale("log")
    axes[-1].set_ylim(P_FLOOR / 2, 1.5)
    axes[-1].axhline(0.1, color="grey", ls=":", lw=1)
    axes[-1].axhline(P_FLOOR, color="grey", lw=0.5)
    axes[-1].text(thr[0], P_FLOOR * 1.2, f"p < 1/{N_BOOTSTRAP} drawn here", fontsize=7)
    axes[0].legend(fontsize=8, loc="upper left")
    note = "shaded: range over the seeds" if "spread_seed" in ds.dims else "shaded: 95 % interval"
    lines = catalogue_caption(ds)  # the threshold is the x axis, not a fixed setting
    lines[1] = re.sub(r"slip threshold v > [^,]+ V(, )?", "", lines[1])
    lines[1] += f"; {note}; blank where a statistic does not apply"
    _suptitle(fig, lines)
    return fig
