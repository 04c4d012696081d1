"""The N-block figure (issue 14, :func:`plot_nblock`): the critical stiffness of unequal
blocks against their number, beside the regime of most ensemble members over
(K/W, spread of D0) and over (K/W, coupling), hatched where the starts disagree."""

from __future__ import annotations

import numpy as np

from ..results.dataset import parameter_values
from ..variables import REGIMES
from .common import (
    REGIME_COLOURS,
    _edges,
    _log_spaced,
    _suptitle,
    axis_label,
    new_figure,
    parameter_text,
    scale_text,
)


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
    title = f"{spread.attrs['model']}, {spread.attrs['state_law']} law: {common}"
    _suptitle(fig, [title, scale_text([spread, coupling]), caption])
    return fig


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


def _cell_positions(values):
    """Positions of grid values on a map axis: the values themselves where evenly spaced
    (linearly or in log), else their indices (the caller labels the ticks)."""
    v = np.asarray(values, float)
    even = v.size < 3 or np.allclose(np.diff(v), v[1] - v[0]) or _log_spaced(v)
    return (v, False) if even else (np.arange(v.size, dtype=float), True)


def _critical_line(ax, ds, y, **style):
    """``critical_K_W`` of a result over (K_W, second axis) at positions ``y`` on ``ax``."""
    kc = ds["critical_K_W"]
    ax.plot((kc.isel(K_W=0) if "K_W" in kc.dims else kc).values, y, **style)
