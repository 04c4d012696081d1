"""What every figure shares: the colour tables, figures made without pyplot, colour
maps, labels with units, title lines (parameters, start, caption), grid-cell edges,
and :func:`save_figure` with its formats and default resolution.

One table, :data:`REGIME_COLOURS`, colours each regime in every figure;
:data:`ATTRACTOR_COLOURS` each attractor kind. Every caption states the model's
dimensionless number and the largest v_max/V of its bounded runs (:func:`scale_text`), and
names the critical stiffness for what it is (:func:`kc_label`).
"""

from __future__ import annotations

import os
import re
import textwrap
from typing import TYPE_CHECKING

import numpy as np

from ..model.heterogeneity import PER_BLOCK
from ..model.physics import PARAMETERS
from ..results.dataset import parameter_values
from ..variables import REGIMES

if TYPE_CHECKING:
    from pathlib import Path

    from matplotlib.figure import Figure

#: Colour of each regime in every figure (Okabe–Ito palette, colour-blind safe).
REGIME_COLOURS = {
    "steady": "#0072B2",
    "stick_slip": "#009E73",
    "runaway": "#D55E00",
    "undecided": "#999999",
}
#: Colour of each attractor kind in an orbit diagram (Okabe–Ito palette, colour-blind safe).
ATTRACTOR_COLOURS = {
    "fixed_point": "#0072B2",
    "periodic": "#009E73",
    "quasi_periodic": "#E69F00",
    "chaotic": "#CC79A7",
    "unresolved": "#999999",
    "unbounded": "#D55E00",
}
#: Code of each regime in a result's ``regime`` variable.
REGIME_CODES = {name: code for code, name in enumerate(REGIMES)}
#: Default resolution of saved raster figures (dots per inch; ``--dpi`` changes it).
DPI = 150
#: File types :func:`save_figure` writes, by suffix.
FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
#: Parameters shown in figure titles, in this order (mu0, V0, Phi0 do not change the dynamics).
TITLE_PARAMETERS = ("A", "B", "D0", "V", "K_W", "k2_W", "eta_W", "m_W")
SYMBOLS = {"D0": "D0", "K_W": "K/W", "k2_W": "k2/W", "eta_W": "η/W", "m_W": "m/W"}
#: Most blocks whose per-block parameters a title lists.
LISTED_BLOCKS = 4
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
    """``"A = 0.03, B = 0.08, D0 = 1, 0.6 µm"`` from a mapping of parameter name → value
    (a number, or one number per block)."""
    parts = []
    for name in TITLE_PARAMETERS:
        if name in values:
            units = unit_text(PARAMETERS[name].units)
            numbers = ", ".join(f"{float(v):g}" for v in np.atleast_1d(values[name]))
            parts.append(f"{SYMBOLS.get(name, name)} = {numbers}{' ' + units if units else ''}")
    return ", ".join(parts)


def fixed_block_values(ds):
    """Per-block parameters that differ between the blocks but are the same in every run
    (e.g. ``D0: [1.0, 0.6]`` in a config): name → one value per block; none for more than
    :data:`LISTED_BLOCKS` blocks (a title cannot list them)."""
    out = {}
    if ds.sizes.get("block", 0) > LISTED_BLOCKS:
        return out
    for name in PER_BLOCK:
        if f"{name}_block" not in ds:
            continue
        var = ds[f"{name}_block"]
        rows = var.transpose(..., "block").values.reshape(-1, var.sizes["block"])
        if np.all(rows == rows[:1]) and np.ptp(rows[0]) > 0:
            out[name] = rows[0]
    return out


def unequal_blocks(ds):
    """Whether the blocks of some run of a result differ (a ``*_block`` variable varies
    along ``block``): their Kc is then the Jacobian's, not a closed form."""
    return any(
        f"{name}_block" in ds and bool((np.ptp(ds[f"{name}_block"].values, axis=-1) > 0).any())
        for name in PER_BLOCK
    )


def kc_label(ds):
    """Legend text of the line K/Kc = 1 of a result: for identical blocks Kc is the
    analytic formula of the model; for unequal ones the stiffness where the Jacobian at
    steady sliding gets an eigenvalue with Re λ = 0 (the engine's ``critical_K_W``)."""
    if unequal_blocks(ds):
        return "Kc of the Jacobian at steady sliding (unequal blocks): K/Kc = 1"
    return "analytic Kc (K/Kc = 1)"


#: Short text of each boundary type (``sweep/refine/boundary_types.py``) on a figure.
KIND_TEXT = {
    "hopf": "Hopf",
    "runaway": "runaway",
    "period_doubling": "PD",
    "fold_of_cycles": "fold",
    "torus": "torus",
    "undetermined": "?",
}
#: Box behind the short text of a boundary's type on a figure.
TYPE_BOX = {"boxstyle": "round,pad=0.15", "fc": "white", "ec": "k", "lw": 0.4, "alpha": 0.85}
#: What each short text stands for, for a legend.
KIND_MEANING = {
    "hopf": "Hopf: the growth rate changes sign",
    "runaway": "runaway: runaway beyond",
    "period_doubling": "PD: period doubling, μ → −1",
    "fold_of_cycles": "fold: fold of cycles, μ → +1",
    "torus": "torus: a complex pair μ → the unit circle",
    "undetermined": "?: type undetermined",
}


def kind_text(kind):
    """Short text of a boundary type, e.g. ``"hopf (supercritical)"`` → ``"Hopf (super)"``."""
    base, _, rest = kind.partition(" ")
    return KIND_TEXT[base] + (" " + rest.replace("critical", "") if rest else "")


def kinds_legend_text(kinds):
    """Legend lines naming the short texts of the boundary ``kinds`` present, one each."""
    present = dict.fromkeys(k.partition(" ")[0] for k in kinds)
    return [f"boundary type {KIND_MEANING[k]}" for k in present]


def describe(ds):
    """Title line of a result or trace: blocks, model, state law and fixed parameters
    (per block where the blocks differ by config)."""
    blocks = int(ds.attrs["blocks"])
    kind = "one block" if blocks == 1 else f"{blocks} blocks"
    fixed = parameter_text(parameter_values(ds) | fixed_block_values(ds))
    return f"{kind}, {ds.attrs['model']}, {ds.attrs['state_law']} law: {fixed}"


def _parameter(ds, name):
    """Parameter ``name`` of a result: its sweep coordinate, or its one value (0 when the
    config does not set it)."""
    if name in ds.coords and ds[name].ndim:
        return ds[name]
    return parameter_values(ds).get(name, 0.0)


def _values_text(values):
    """The distinct values of an array for a caption: up to four listed, else the range."""
    v = np.unique(np.asarray(values, float).ravel())
    if v.size > 4:
        return f"{v[0]:.3g} to {v[-1]:.3g}"
    return ", ".join(f"{x:.3g}" for x in v)


def dimensionless_text(ds):
    """The dimensionless numbers of a result's model beyond the quasi-static one:
    ``"M̂ = mV²/(W·D0) = 0.01"`` (inertial), ``"η̂ = ηV/W = 0.001"`` (radiation damping);
    a quasi-static model has neither (``"M̂ = η̂ = 0"``)."""
    V, eta = _parameter(ds, "V"), _parameter(ds, "eta_W")
    parts = []
    if ds.attrs["model"] == "inertial":
        mass = _parameter(ds, "m_W") * V**2 / _parameter(ds, "D0")
        parts.append(f"M̂ = mV²/(W·D0) = {_values_text(mass)}")
    if ds.attrs["model"] == "quasi-dynamic" or np.any(np.asarray(eta) > 0):
        parts.append(f"η̂ = ηV/W = {_values_text(eta * V)}")
    return ", ".join(parts) or "M̂ = η̂ = 0"


def bounded(ds):
    """Boolean array over a result's runs: the run has a bounded attractor (not runaway,
    and its attractor, where classified, not unbounded)."""
    ok = ds["regime"] != REGIME_CODES["runaway"]
    if "attractor" in ds:
        names = ds["attractor"].attrs["flag_meanings"].split()
        ok = ok & (ds["attractor"] != names.index("unbounded"))
    return ok


def largest_peak(ds):
    """The largest v_max/V (in the final window) of a result's bounded runs; NaN if none."""
    lnv = ds["lnv_max"].where(bounded(ds)).values
    return float(np.exp(np.nanmax(lnv))) if np.isfinite(lnv).any() else np.nan


def scale_text(datasets, shown=None):
    """Caption line with each model's dimensionless number (:func:`dimensionless_text`)
    and the largest v_max/V of the bounded runs of ``datasets`` (a result or a list), or of
    ``shown`` (the parts of them a figure draws): slow slip while it is 10–10³, seismic
    far above (physics brief, section 5c)."""
    datasets = datasets if isinstance(datasets, (list, tuple)) else [datasets]
    numbers = {}
    for ds in datasets:
        numbers.setdefault(ds.attrs["model"], []).append(dimensionless_text(ds))
    if len(numbers) == 1:
        (texts,) = numbers.values()
        parts = list(dict.fromkeys(texts))
    else:
        parts = [f"{model}: {'; '.join(dict.fromkeys(t))}" for model, t in numbers.items()]
    peaks = [p for p in map(largest_peak, datasets if shown is None else shown) if np.isfinite(p)]
    peak = f"largest v_max/V of the bounded runs {max(peaks):.3g}" if peaks else "no bounded run"
    return "; ".join([*parts, peak])


def initial_text(ds):
    """The initial perturbation of a result or trace, e.g. ``"start Φ/Φss = 1.01, v/V = 1"``;
    a start that is a sweep axis (``initial_v_over_V``, ``initial_phi_over_phi_ss``) is
    named as swept, or by its value where a trace pins it."""

    def text(name):
        if name in ds.coords:  # a sweep axis: its value where pinned
            value = ds.coords[name]
            return f"{float(value):g}" if value.ndim == 0 else f"swept ({name})"
        return ", ".join(f"{x:g}" for x in np.atleast_1d(ds.attrs[name]))

    return f"start Φ/Φss = {text('initial_phi_over_phi_ss')}; v/V = {text('initial_v_over_V')}"


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
    inches = fig.get_figwidth() if hasattr(fig, "get_figwidth") else fig.figure.get_figwidth()
    width = int(12 * inches)  # characters of 10-point text per line (100 dpi; a subfigure:
    # its figure's width)
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


def _figure_and_axes(ax, figsize):
    """``(figure, ax)``: the given axes and its figure, or a new figure with one axes."""
    if ax is not None:
        if not hasattr(ax, "figure"):
            raise TypeError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
        return ax.figure, ax
    fig = new_figure(figsize=figsize)
    return fig, fig.subplots()


def _refined(ds):
    from ..refine.dataset import is_refined

    return "regime" in ds and is_refined(ds)


def _as_grid(ds):
    """A refined result on a grid (``refined_dataset.as_grid``); any other as it is."""
    from ..refine.dataset import as_grid

    return as_grid(ds) if _refined(ds) else ds


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

    from ..io.files import replaced_atomically

    out = Path(out)
    if out.suffix not in FORMATS:
        raise ValueError(f"{out}: figure files end in {', '.join(FORMATS)}")
    out.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(out) as tmp:
        if out.suffix == ".png":
            _save_png(fig, tmp, dpi)
        else:
            fig.savefig(tmp, dpi=dpi, format=FORMATS[out.suffix])
    return out


def _save_png(fig, path, dpi):
    """``fig`` as a PNG at ``dpi``: without its alpha channel where every pixel is opaque
    (a figure on its white background; lossless, and the file about a tenth smaller)."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=dpi, format="png")
    image = Image.open(buffer)
    if image.mode == "RGBA" and image.getchannel("A").getextrema() == (255, 255):
        image = image.convert("RGB")
    image.save(path, format="png", optimize=True, dpi=(dpi, dpi))
