"""Refinement by label: which points each level runs (plain numpy; no runs, no files).

The sweep axes span a lattice. Level 0 is the config's grid; level L halves its steps L
times, along every axis with more than one value (an axis of one value stays put). A
point is named by its integer index on the finest lattice, level ``refine.levels``,
along every axis (index j on the lattice of level L is ``j 2^(levels - L)`` there), and
its values come from the axis's own rule (:meth:`Lattice.values`): a range axis places
point k of a level by the range's formula, so that it is bit for bit the value of a
finer range's point and a refined run is the run a uniform grid would make there.

A *cell* of level L is the box between 2^d neighbouring points of level L (d: the axes
that are split). Level by level (:class:`Refinement`):

1. the cells of the level are every cell of the grid at level 0, later the children of
   the cells split at the level before;
2. a cell is split where its corner runs differ in the refine outputs (:func:`differs`);
3. a split cell asks for every point of the next level in it (3^d, its corners known);
   the new points are those not run yet, in C order of their indices.

A cell's centre is a point of the next level that no other cell holds, so a cell was
split exactly when its centre was run: the tree is read back from the points alone
(:func:`cell_tree`). Every point that was run lies on the lattice of its level and of no
coarser one, so the level of a point is also read from its indices.

With ``refine.max_runs`` a level that would pass the budget keeps the split cells that
fit, in order: first those whose corners differ in an earlier output of
``refine.outputs``, then spread evenly over the rest (bit-reversed order of their index),
and refinement stops after it.
"""

from dataclasses import dataclass

import numpy as np

from ..codes import REGIMES, code
from ..config import range_values

#: Why a refinement stopped (the ``refine_stopped`` file attribute).
STOPPED = {
    "levels": "every level of refine.levels is done",
    "converged": "no cell left whose corners differ",
    "max_runs": "the next level would pass refine.max_runs",
}


class Lattice:
    """The sweep axes of ``config`` as a lattice of ``config.refine.levels`` levels.

    ``split``: whether each axis has more than one value (is refined); ``extent``: the
    largest index of each axis on the finest lattice.
    """

    def __init__(self, config):
        self.config = config
        self.axes = config.axes
        self.levels = config.refine.levels
        self.split = np.array([len(a.values) > 1 for a in self.axes])
        self.extent = np.array([(len(a.values) - 1) << self.levels for a in self.axes], np.int64)
        strides = np.cumprod(np.concatenate([[1], (self.extent + 1)[::-1][:-1]]))[::-1]
        self.strides = strides.astype(np.int64)

    @property
    def names(self):
        return tuple(a.name for a in self.axes)

    def step(self, level):
        """Index distance of neighbouring points of ``level`` on the finest lattice."""
        return 1 << (self.levels - level)

    def keys(self, index):
        """One int64 per point of ``index`` (..., d): its place in C order of the lattice."""
        return np.asarray(index, np.int64) @ self.strides

    def values(self, index, level=None):
        """Values of the points ``index`` (..., d) on the lattice of ``level`` (default: the
        finest), one array per axis: ``{name: array (...)}``, in the axes' units."""
        level = self.levels if level is None else level
        index = np.asarray(index, np.int64)
        return {a.name: axis_values(a, index[..., i], level) for i, a in enumerate(self.axes)}

    def grid_points(self):
        """Indices (n, d) of the points of level 0, the config's grid, in C order."""
        base = [np.arange(len(a.values), dtype=np.int64) * self.step(0) for a in self.axes]
        mesh = np.meshgrid(*base, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=-1)

    def grid_cells(self):
        """Lowest corners (n, d) of the cells of level 0, in C order."""
        base = [
            np.arange(max(len(a.values) - 1, 1), dtype=np.int64) * self.step(0) for a in self.axes
        ]
        mesh = np.meshgrid(*base, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=-1)

    def offsets(self, level, counts):
        """Offsets (m, d) of the points ``0 .. counts - 1`` steps of ``level`` along each
        split axis (0 along the others), in C order."""
        ranges = [
            np.arange(counts if s else 1, dtype=np.int64) * self.step(level) for s in self.split
        ]
        mesh = np.meshgrid(*ranges, indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=-1)

    def corners(self, cells, level):
        """Corners (n, 2^d, d) of the cells of ``level`` with lowest corners ``cells``."""
        return cells[:, None, :] + self.offsets(level, 2)[None]

    def children(self, cells, level):
        """Lowest corners of the 2^d children (level + 1) of ``cells``, cell by cell."""
        return self.corners(cells, level + 1).reshape(-1, cells.shape[1])

    def centres(self, cells, level):
        """Centres (points of level + 1) of the cells of ``level``."""
        return cells + np.where(self.split, self.step(level + 1), 0)

    def point_levels(self, index):
        """The level of each point (n, d): the coarsest lattice it lies on."""
        index = np.asarray(index, np.int64)
        level = np.zeros(len(index), np.int8)
        for L in range(self.levels, 0, -1):
            off = np.any(index % self.step(L - 1) != 0, axis=1)
            level[off & (level == 0)] = L
        return level


def axis_values(axis, index, level):
    """Values of an :class:`~sweep.config.Axis` at integer ``index`` (array) on the lattice
    of ``level``: a range axis by its formula over ``(num - 1) 2^level`` intervals; a list
    linearly between neighbouring values."""
    index = np.asarray(index, np.int64)
    n = len(axis.values)
    if n == 1:
        return np.full(index.shape, axis.values[0])
    if axis.span:
        scale, start, stop = axis.span
        return range_values(scale, start, stop, index, (n - 1) << level)
    values = np.asarray(axis.values, float)
    i = np.minimum(index >> level, n - 2)
    r = index - (i << level)
    return values[i] + (values[i + 1] - values[i]) * r.astype(float) / float(1 << level)


@dataclass(frozen=True)
class Labels:
    """What refinement compares at each point: per output, ``(name, exact, array (n, k))``:
    integer outputs and ``regime_fraction`` compared exactly, the others with ``rtol``.
    With ``refine.split_undecided: false``, ``undecided`` (n,): the points whose runs are
    all undecided, left out of the comparison except against ``steady`` (n,) ones, those
    whose runs are all steady (else both None)."""

    outputs: tuple
    rtol: float
    undecided: np.ndarray | None = None
    steady: np.ndarray | None = None

    def take(self, rows):
        """The labels of the points ``rows`` only."""
        outputs = tuple((n, e, a[rows]) for n, e, a in self.outputs)
        if self.undecided is None:
            return Labels(outputs, self.rtol)
        return Labels(outputs, self.rtol, self.undecided[rows], self.steady[rows])

    def join(self, other):
        """These points' labels followed by ``other``'s."""
        outputs = tuple(
            (n, e, np.concatenate([a, b]))
            for (n, e, a), (_, _, b) in zip(self.outputs, other.outputs, strict=True)
        )
        if self.undecided is None:
            return Labels(outputs, other.rtol)
        return Labels(
            outputs,
            other.rtol,
            np.concatenate([self.undecided, other.undecided]),
            np.concatenate([self.steady, other.steady]),
        )


def point_labels(config, fields):
    """The :class:`Labels` of runs from ``fields`` (flat per run, as
    ``dataset.derived_fields`` gives them; with an ensemble, members fastest).

    With an ensemble a per-member output of integer type is compared through its
    distribution over the members (sorted member by member), ``regime_fraction`` as the
    share of each regime; continuous ones member by member (every point starts its
    member m alike). With ``refine.split_undecided: false`` the points whose runs (every
    member's) are all undecided, and those whose runs are all steady, are marked.
    """
    from ..results.dataset import regime_fractions
    from ..variables import BY_NAME

    members = config.members
    n = len(fields["regime"]) // members
    outputs = []
    for name in config.refine.outputs:
        var = BY_NAME[name]
        if name == "regime_fraction":
            data, exact = regime_fractions(fields["regime"].reshape(n, members)), True
        else:
            data = np.asarray(fields[name]).reshape(n, members, -1).astype(var.dtype)
            exact = np.dtype(var.dtype).kind in "iu"
            if not var.per_member:
                data = data[:, :1]
            elif exact and members > 1:
                data = np.sort(data, axis=1)
        outputs.append((name, exact, data.reshape(n, -1)))
    if config.refine.split_undecided:
        return Labels(tuple(outputs), config.refine.rtol)
    regime = np.asarray(fields["regime"]).reshape(n, members)
    undecided = (regime == code(REGIMES, "undecided")).all(axis=1)
    steady = (regime == code(REGIMES, "steady")).all(axis=1)
    return Labels(tuple(outputs), config.refine.rtol, undecided, steady)


def differs(labels, corners):
    """For cells with corner rows ``corners`` (n, 2^d): the index in ``labels.outputs`` of
    the first output in which the corners differ, or -1 where they agree in all.

    Corners ``labels.undecided`` take the labels of the cell's first corner that is not
    (a cell whose corners are all undecided agrees), except where the cell also has a
    ``labels.steady`` corner: the edge of the steady region is always split (index 0).
    """
    edge = np.zeros(len(corners), bool)
    if labels.undecided is not None:
        left_out = labels.undecided[corners]
        edge = left_out.any(axis=1) & labels.steady[corners].any(axis=1)
        first_kept = np.argmax(~left_out, axis=1)
        kept = corners[np.arange(len(corners)), first_kept]
        corners = np.where(left_out, kept[:, None], corners)
    first = np.full(len(corners), -1)
    first[edge] = 0
    for k, (_, exact, data) in enumerate(labels.outputs):
        v = data[corners]  # (n, 2^d, m)
        if exact:
            change = np.any(v != v[:, :1], axis=(1, 2))
        else:
            change = _continuous_change(v, labels.rtol)
        first[(first < 0) & change] = k
    return first


def _continuous_change(v, rtol):
    """Cells (axis 0) whose corner values (axis 1) differ: beyond ``rtol`` times their
    largest magnitude, or in which corners are NaN or infinite."""
    finite = np.isfinite(v)
    code = np.where(finite, 0.0, np.where(np.isnan(v), 2.0, np.sign(v)))
    special = np.any(code != code[:, :1], axis=(1, 2))
    with np.errstate(invalid="ignore"):
        w = np.where(finite, v, 0.0)
        spread = w.max(axis=1) - w.min(axis=1)
        scale = np.abs(w).max(axis=1)
    return special | np.any(spread > rtol * scale, axis=1)


class Refinement:
    """The points of a refinement, level by level, and the plan of the next level.

    ``add(index, labels)`` records the finished runs of the points ``index`` (n, d) of the
    level planned last (first: :meth:`Lattice.grid_points`); :meth:`plan` then returns
    the indices of the next level's points, sorted in C order, or None when refinement is
    over (``stopped`` says why: a key of :data:`STOPPED`). ``runs`` counts runs so far
    (points times ensemble members); ``planned`` holds the points' indices per level.
    """

    def __init__(self, config):
        self.config = config
        self.lattice = Lattice(config)
        self.members = config.members
        self.max_runs = config.refine.max_runs
        self.planned = [self.lattice.grid_points()]
        self.cells = self.lattice.grid_cells()
        self.index = np.empty((0, len(config.axes)), np.int64)
        self.labels = None
        self.stopped = None
        self._keys = np.empty(0, np.int64)
        self._order = np.empty(0, np.int64)

    @property
    def level(self):
        """The level planned last (its points are ``planned[-1]``)."""
        return len(self.planned) - 1

    @property
    def runs(self):
        return sum(len(p) for p in self.planned) * self.members

    def add(self, index, labels):
        """Record the runs of ``index`` (the level planned last) and their ``labels``."""
        self.index = np.concatenate([self.index, index])
        self.labels = labels if self.labels is None else self.labels.join(labels)
        self._keys = self.lattice.keys(self.index)
        self._order = np.argsort(self._keys, kind="stable")

    def rows(self, index):
        """Rows (in order of :meth:`add`) of the points ``index``; -1 where not run."""
        keys = self.lattice.keys(index)
        sorted_keys = self._keys[self._order]
        at = np.searchsorted(sorted_keys, keys)
        at = np.minimum(at, len(sorted_keys) - 1)
        found = sorted_keys[at] == keys
        return np.where(found, self._order[at], -1)

    def plan(self):
        """Indices (n, d) of the next level's new points in C order, or None when done."""
        level = self.level
        lattice = self.lattice
        if self.stopped is not None:
            return None
        if level >= lattice.levels:
            self.stopped = "levels"
            return None
        corners = lattice.corners(self.cells, level)
        corners = self.rows(corners.reshape(-1, len(lattice.axes))).reshape(corners.shape[:2])
        assert (corners >= 0).all(), "a corner of a cell was not run"
        first = differs(self.labels, corners)
        split = np.flatnonzero(first >= 0)
        if split.size == 0:
            self.stopped = "converged"
            return None
        order = np.lexsort((bit_reversed_rank(split.size), first[split]))
        cells = self.cells[split[order]]
        points = (cells[:, None, :] + lattice.offsets(level + 1, 3)[None]).reshape(
            -1, cells.shape[1]
        )
        keys = lattice.keys(points)
        _, first_at = np.unique(keys, return_index=True)
        fresh = np.zeros(keys.size, bool)
        fresh[first_at] = True
        fresh &= self.rows(points) < 0
        new_per_cell = fresh.reshape(len(cells), -1).sum(axis=1)
        kept = len(cells)
        if self.max_runs is not None:
            room = (self.max_runs - self.runs) // self.members
            kept = int(np.searchsorted(np.cumsum(new_per_cell), room, side="right"))
            if kept < len(cells):
                self.stopped = "max_runs"
        per_cell = points.reshape(len(cells), -1, points.shape[1])
        new = _sorted(lattice, per_cell[:kept][fresh.reshape(len(cells), -1)[:kept]])
        if len(new) == 0:
            self.stopped = "max_runs"
            return None
        self.planned.append(new)
        self.cells = _sorted(lattice, lattice.children(cells[:kept], level))
        return new


def _sorted(lattice, index):
    """The points or cells ``index`` (n, d) in C order of the lattice."""
    return index[np.argsort(lattice.keys(index), kind="stable")]


def bit_reversed_rank(n):
    """For ``n`` items in order, a rank that spreads any prefix of them evenly: their
    position in van der Corput order (bit-reversed index)."""
    if n <= 1:
        return np.zeros(n, np.int64)
    bits = int(n - 1).bit_length()
    index = np.arange(n, dtype=np.int64)
    rev = np.zeros(n, np.int64)
    for b in range(bits):
        rev |= ((index >> b) & 1) << (bits - 1 - b)
    return rev


def cell_tree(lattice, index):
    """The cells of a refinement read back from its points ``index`` (n, d): a list over
    levels of ``(cells, split)``: the lowest corners (m, d) of the level's cells and
    whether each was split (its centre was run)."""
    keys = np.sort(lattice.keys(index))
    cells = lattice.grid_cells()
    tree = []
    for level in range(lattice.levels + 1):
        if level == lattice.levels or len(cells) == 0:
            tree.append((cells, np.zeros(len(cells), bool)))
            break
        split = np.isin(lattice.keys(lattice.centres(cells, level)), keys)
        tree.append((cells, split))
        cells = _sorted(lattice, lattice.children(cells[split], level))
    return tree
