"""Phase boundaries of a refined result, as polylines in parameter space.

A refinement (``sweep/refine/lattice.py``) leaves unsplit cells whose corners differ in label
only where it stopped: at its finest level, or where ``max_runs`` cut it. The boundary
between two labels crosses each such cell; how far it is known is the cell's size.
Over two axes each cell is cut as in marching squares: a crossing at the middle of
every edge whose ends differ, joined across the cell (to its centre where three or
more labels meet; a saddle of two labels cuts off the corners of the label with the
lower code). Segments of one pair of labels are chained into polylines. Over one axis
a boundary is a point, the middle of its cell.

A label is a point's values of the refine outputs that are compared exactly (by
default regime, attractor and cycle_events: "stick_slip, periodic, 2 events"; with an
ensemble the regime fractions). Each boundary carries its type, the bifurcation that the
runs at its cells' corners name (``boundary_types.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .boundary_types import classify, combine, run_table
from .dataset import lattice_index, refined_config
from .lattice import Lattice, axis_values, cell_tree, point_labels

#: Attractors that a regime implies (not repeated in a label).
IMPLIED = {"steady": "fixed_point", "runaway": "unbounded", "undecided": "unresolved"}


@dataclass(frozen=True)
class Boundary:
    """One polyline of the boundary between two labels.

    ``between``: the labels on its two sides (text, lower code first); ``axes``: the
    names of the vertices' columns; ``vertices`` (n, d): points in parameter space, in
    the axes' units; ``resolution`` (max(n - 1, 1), d): the size along each axis of the
    cell each segment crosses (over one axis: the cell holding the point), within which
    the boundary is known; ``level`` (same rows): those cells' levels; ``kind``: the
    bifurcation the runs at those cells' corners name (``hopf``, ``runaway``,
    ``period_doubling``, ``fold_of_cycles``, ``torus`` or ``undetermined``; rules in
    ``sweep/refine/boundary_types.py``) and ``evidence``: why, in words.
    """

    between: tuple
    axes: tuple
    vertices: np.ndarray
    resolution: np.ndarray
    level: np.ndarray
    kind: str = "undetermined"
    evidence: str = ""


def point_label_codes(ds, config, outputs=None):
    """Label code of every point of a refined result and the text of each code.

    ``outputs``: the outputs whose values make a label (default: the refine outputs
    compared exactly, else regime), compared as refinement compares them
    (``refine.point_labels``). Returns ``(codes (n,), texts)``.
    """
    import dataclasses

    names = list(outputs or [o for o in config.refine.outputs if _exact(ds, o)] or ["regime"])
    members = config.members
    fields = {"regime": ds["regime"].values.ravel()}
    for name in names:
        if name != "regime_fraction":
            data = ds[name].values
            if "member" in ds.dims and "member" not in ds[name].dims:  # one value per point
                data = np.repeat(data, members, axis=0)
            fields[name] = data.reshape(len(fields["regime"]), -1)
    refine = dataclasses.replace(config.refine, outputs=tuple(names))
    labels = point_labels(dataclasses.replace(config, refine=refine), fields)
    columns = np.concatenate([data.astype(float) for _, _, data in labels.outputs], axis=1)
    unique, codes = np.unique(columns, axis=0, return_inverse=True)
    return codes.ravel(), [_label_text(ds, labels, row) for row in unique]


def _exact(ds, name):
    """Whether refinement compares output ``name`` exactly (see ``refine.point_labels``)."""
    return name == "regime_fraction" or ds[name].dtype.kind in "iu"


def _label_text(ds, labels, row):
    """Text of one label: its values of the outputs of ``labels``, laid out in ``row``."""
    parts, at = [], 0
    regime = None
    for name, _, data in labels.outputs:
        width = data.shape[1]
        values = row[at : at + width]
        at += width
        if name == "regime_fraction":
            regimes = ds["regime"].attrs["flag_meanings"].split()
            shares = zip(regimes, values, strict=True)
            parts.append(" ".join(f"{r} {v:.2g}" for r, v in shares if v))
        elif "flag_meanings" in ds[name].attrs and width == 1:
            meaning = ds[name].attrs["flag_meanings"].split()[int(values[0])]
            if name == "regime":
                regime = meaning
            if IMPLIED.get(regime) != meaning:
                parts.append(meaning)
        elif name == "cycle_events" and width == 1:
            if values[0] > 0:
                parts.append(f"{int(values[0])} event" + ("s" if values[0] != 1 else ""))
        else:
            parts.append(f"{name} " + " ".join(f"{v:g}" for v in values))
    return ", ".join(parts) or "-"


def boundaries(
    ds: xr.Dataset, outputs: Sequence[str] | None = None, *, types_from: xr.Dataset | None = None
) -> list[Boundary]:
    """The boundaries between the labels of a refined result.

    Parameters
    ----------
    ds : xarray.Dataset
        A refined result (a ``refine`` section; runs along ``point``) refined over one
        or two axes.
    outputs : sequence of str, optional
        The outputs whose values make a label (default: the refine outputs compared
        exactly, e.g. regime, attractor and cycle_events).
    types_from : xarray.Dataset, optional
        The result whose runs' outputs type the boundaries (default ``ds``): the same
        runs in the same order, e.g. ``ds`` before its labels were coarsened for a map.

    Returns
    -------
    list of Boundary
        One record per polyline (``between``, ``axes``, ``vertices``, ``resolution``,
        ``level``, ``kind``, ``evidence``; see :class:`~sweep.refine.boundaries.Boundary`),
        sorted by the labels they separate, then by their first vertex.

    Raises
    ------
    InputError
        ``ds`` is not a refined result.
    ValueError
        ``ds`` is refined over more than two axes (its boundaries are surfaces), or
        ``outputs`` is not a list of its variables.
    """
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be a refined result Dataset, got {type(ds).__name__}")
    config = refined_config(ds)
    lattice = Lattice(config)
    axes = [i for i, s in enumerate(lattice.split) if s]
    if len(axes) > 2:
        raise ValueError(
            f"boundaries are lines over two axes; this result is refined over {len(axes)} "
            "(take a slice with to_grid, or refine fewer axes)"
        )
    if outputs is not None and (
        isinstance(outputs, str) or not all(isinstance(o, str) for o in outputs)
    ):
        raise ValueError(f"outputs must be a list of variable names, got {outputs!r}")
    # the variables the labels read (regime_fraction is made from regime)
    read = ["regime", *(o for o in (outputs or config.refine.outputs) if o != "regime_fraction")]
    absent = [o for o in dict.fromkeys(read) if o not in ds]
    if absent:
        raise ValueError(f"outputs: no variable {', '.join(absent)} in this result")
    index = lattice_index(ds, lattice)
    codes, texts = point_label_codes(ds, config, outputs)
    keys = lattice.keys(index)
    order = np.argsort(keys)
    found = []
    for level, (cells, split) in enumerate(cell_tree(lattice, index)):
        leaves = cells[~split]
        if len(leaves) == 0:
            continue
        corners = lattice.keys(lattice.corners(leaves, level))
        at = np.minimum(np.searchsorted(keys[order], corners), len(keys) - 1)
        if not (keys[order][at] == corners).all():
            raise ValueError(
                "this refined result lacks the runs at some cells' corners (a "
                "subset of its points?): a refined result is read whole"
            )
        rows = order[at]
        labels = codes[rows]  # (n, 2^d)
        mixed = np.any(labels != labels[:, :1], axis=1)
        found.append((level, leaves[mixed], labels[mixed], rows[mixed]))
    cut = _cut_cells_1d if len(axes) == 1 else _cut_cells_2d
    if types_from is not None and types_from.sizes.get("point") != ds.sizes.get("point"):
        raise ValueError("types_from must hold the same runs as ds")
    table = run_table(ds if types_from is None else types_from)
    segments, verdicts = {}, {}
    for level, leaves, labels, rows in found:
        for cell, corner_labels, corner_rows in zip(leaves, labels, rows, strict=True):
            for pair, ends in cut(lattice, axes, cell, corner_labels, level):
                segments.setdefault(pair, []).append((ends, cell, level))
                key = (pair, tuple(cell), level)
                if key not in verdicts:
                    sides = [corner_rows[corner_labels == code] for code in pair]
                    verdicts[key] = classify(table, *sides)
    out = []
    names = tuple(lattice.names[i] for i in axes)
    for pair, segs in segments.items():
        between = (texts[pair[0]], texts[pair[1]])
        for chain in _chains(segs):
            cells = {(pair, tuple(c), lv): None for _, c, lv in chain}
            kind = combine([verdicts[key] for key in cells])
            out.append(_boundary(lattice, axes, names, between, chain, kind))
    out.sort(key=lambda b: (b.between, tuple(b.vertices[0])))
    return out


def _cut_cells_1d(lattice, axes, cell, labels, level):
    """The boundary point of a cell of one axis: ``(pair, [(half-index point,)])``."""
    step = lattice.step(level)
    mid = 2 * cell[axes[0]] + step
    pair = tuple(sorted((int(labels[0]), int(labels[1]))))
    yield pair, ((mid,),)


#: Corners of a 2-D cell in the order of ``Lattice.corners`` (x slow, y fast), as (x, y)
#: offsets, and its edges as corner pairs: bottom, right, top, left.
_CORNERS = ((0, 0), (0, 1), (1, 0), (1, 1))
_EDGES = ((0, 2), (2, 3), (1, 3), (0, 1))


def _cut_cells_2d(lattice, axes, cell, labels, level):
    """Marching-squares segments of one cell: ``(pair, ((x0, y0), (x1, y1)))`` in
    half-index units (twice the finest index)."""
    step = lattice.step(level)
    x0, y0 = 2 * cell[axes[0]], 2 * cell[axes[1]]

    def mid(edge):
        a, b = (_CORNERS[c] for c in _EDGES[edge])
        return (x0 + step * (a[0] + b[0]), y0 + step * (a[1] + b[1]))

    centre = (x0 + step, y0 + step)
    by_pair = {}
    for e, (a, b) in enumerate(_EDGES):
        la, lb = int(labels[a]), int(labels[b])
        if la != lb:
            by_pair.setdefault(tuple(sorted((la, lb))), []).append(e)
    for pair, edges in by_pair.items():
        if len(edges) == 1:
            yield pair, (mid(edges[0]), centre)
        elif len(edges) == 2:
            yield pair, (mid(edges[0]), mid(edges[1]))
        else:  # a saddle: cut off the two corners of the lower label
            low = [c for c in range(4) if int(labels[c]) == pair[0]]
            for c in low:
                around = [e for e in edges if c in _EDGES[e]]
                yield pair, (mid(around[0]), mid(around[1]))


def _chains(segments):
    """Segments ``(ends, cell, level)`` joined where they share an end: lists of them in
    order along each polyline, each with its direction (``ends`` may be flipped)."""
    if len(segments[0][0]) == 1:  # points of a 1-D boundary
        return [[s] for s in segments]
    at = {}
    for k, (ends, _, _) in enumerate(segments):
        for end in ends:
            at.setdefault(end, []).append(k)
    used = np.zeros(len(segments), bool)
    starts = [k for k, (ends, _, _) in enumerate(segments) if any(len(at[e]) == 1 for e in ends)]
    chains = []
    for first in starts + list(range(len(segments))):
        if used[first]:
            continue
        ends, cell, level = segments[first]
        if len(at[ends[1]]) == 1 and len(at[ends[0]]) != 1:
            ends = ends[::-1]
        chain = [(ends, cell, level)]
        used[first] = True
        tail = ends[1]
        while True:
            nxt = next((k for k in at[tail] if not used[k]), None)
            if nxt is None:
                break
            e, c, lv = segments[nxt]
            e = e if e[0] == tail else e[::-1]
            chain.append((e, c, lv))
            used[nxt] = True
            tail = e[1]
        chains.append(chain)
    return chains


def _boundary(lattice, axes, names, between, chain, kind):
    """A :class:`Boundary` from a chain of segments in half-index units and its
    ``(kind, evidence)``."""
    first = chain[0][0]
    points = [first[0], *(ends[-1] for ends, _, _ in chain)] if len(first) > 1 else [first[0]]
    half = np.array(points, np.int64).reshape(len(points), len(axes))
    vertices = np.stack(
        [axis_values(lattice.axes[i], half[:, k], lattice.levels + 1) for k, i in enumerate(axes)],
        axis=-1,
    )
    cells = np.array([c for _, c, _ in chain], np.int64)
    levels = np.array([lv for _, _, lv in chain], np.int8)
    steps = np.array([lattice.step(lv) for lv in levels], np.int64)
    size = [
        axis_values(lattice.axes[i], cells[:, i] + steps, lattice.levels)
        - axis_values(lattice.axes[i], cells[:, i], lattice.levels)
        for i in axes
    ]
    return Boundary(between, names, vertices, np.abs(np.stack(size, axis=-1)), levels, *kind)
