"""Figures of a run's slip-event catalogue: its events in space and time beside its
size–frequency plot. Maps of the catalogue's statistics over a sweep are
:func:`sweep.plot_variable` (e.g. ``"b_value"``, ``"recurrence_cv"``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..results.checks import check_result
from .common import colormap, describe, new_figure, parameter_text

if TYPE_CHECKING:
    import xarray
    from matplotlib.figure import Figure


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
    ds: xarray.Dataset, point: Mapping[str, float] | None = None, fig: Figure | None = None
) -> Figure:
    """One run's slip events: block against time, each event a bar over the blocks it
    spanned from its start to its end, coloured by its magnitude, its first block
    marked; beside it the size–frequency plot (events with magnitude ≥ m) with the
    Gutenberg–Richter line of the run's b-value above m_c.

    Parameters
    ----------
    ds : xarray.Dataset
        A result with a catalogue (config key ``catalogue.capacity``).
    point : Mapping, optional
        The run: sweep axis → value (the nearest is taken; ``member`` → index);
        axes not named at their first value.
    fig : matplotlib.figure.Figure or SubFigure, optional
        Draw there (default: a new figure).

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
    where = parameter_text(
        {
            k: float(run[k])
            for k in ds["slip_event_start"].dims[:-1]
            if k in run.coords and k != "member"
        }
    )
    kept = f"{count} of {int(run['slip_event_count'])} events kept"
    fig.suptitle(f"{describe(ds)}\n{where}; {kept}", fontsize=9.5)
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
    """Events with magnitude ≥ m against m, and the run's Gutenberg–Richter fit."""
    mag = np.sort(ev["slip_event_magnitude"].values)
    mag = mag[np.isfinite(mag)]
    ax.step(mag, np.arange(mag.size, 0, -1), where="post", color="k", lw=1.2, label="events")
    b, err, mc = (float(run[k]) for k in ("b_value", "b_value_error", "magnitude_completeness"))
    if np.isfinite(b) and mag.size:
        above = int((mag >= mc).sum())
        m = np.linspace(mc, mag.max(), 50)
        ax.plot(
            m,
            above * 10 ** (-b * (m - mc)),
            "--",
            color="#D55E00",
            label=f"b = {b:.2f} ± {err:.2f} (m ≥ {mc:.2f})",
        )
        ax.axvline(mc, color="#999999", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("magnitude m")
    ax.set_ylabel("events with magnitude ≥ m")
    ax.legend(loc="lower left", fontsize=8)
