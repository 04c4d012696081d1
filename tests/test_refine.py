"""The refinement plan (sweep/refine/lattice.py) on labels made up here, without a run.

A refinement must split exactly the cells whose corners differ, place its points where
a finer uniform grid has them (bit for bit), keep its budget, and be read back from its
points alone. The labels below are functions of the parameters (a straight line, a
circle, a sphere), so where the boundary lies is known exactly.
"""

import math

import numpy as np
import pytest
from conftest import make_config
from hypothesis import given
from hypothesis import strategies as st

from sweep.config import range_values
from sweep.refine.lattice import Labels, Lattice, Refinement, cell_tree, differs, point_labels


def refine_config(sweep, levels=4, **refine):
    """A one-block config over ``sweep`` with a refine section (nothing is run here)."""
    fixed = {name: None for name in sweep if name != "K_W"}  # swept, so not fixed
    return make_config(sweep=sweep, parameters=fixed, refine={"levels": levels, **refine})


def made_up(refinement, label):
    """:class:`Labels` of the points of the level planned last, ``label(values)`` → int."""
    index = refinement.planned[-1]
    codes = np.asarray(label(refinement.lattice.values(index)), np.int64)
    return Labels((("regime", True, codes[:, None]),), 0.05)


def refine_fully(refinement, label):
    """Plan and 'run' every level with the made-up ``label``; returns the refinement."""
    index = refinement.planned[0]
    while index is not None:
        refinement.add(index, made_up(refinement, label))
        index = refinement.plan()
    return refinement


def mixed(refinement, cells, level):
    """Whether the made-up label (one exact output) differs among each cell's corners,
    read directly from the labels of the runs."""
    corners = refinement.lattice.corners(cells, level)
    rows = refinement.rows(corners.reshape(-1, cells.shape[1])).reshape(corners.shape[:2])
    assert (rows >= 0).all()
    codes = refinement.labels.outputs[0][2][rows, 0]
    return np.any(codes != codes[:, :1], axis=1)


def unsplit_mixed_cells(refinement):
    """(level, cells) of the cells that were not split although their corners differ."""
    out = []
    for level, (cells, split) in enumerate(cell_tree(refinement.lattice, refinement.index)):
        leaves = cells[~split]
        out.append((level, leaves[mixed(refinement, leaves, level)]))
    return out


# --- values: a refined point has the value of a finer range's point, bit for bit ----------


@pytest.mark.slow
@given(
    start=st.floats(1e-3, 10.0),
    width=st.floats(1e-3, 10.0),
    num=st.integers(2, 40),
    level=st.integers(0, 12),
    scale=st.sampled_from(["linear", "log"]),
)
def test_refined_values_are_those_of_a_finer_range(start, width, num, level, scale):
    """Point k·2^L of (num − 1)·2^L intervals is point k of num − 1 bit for bit, and the
    points of level L are every point of the range of (num − 1)·2^L + 1 values that the
    config parser makes (configs write ranges as start, stop, num)."""
    stop = start + width
    config = refine_config({"K_W": {"start": start, "stop": stop, "num": num, "scale": scale}},
                           levels=12)  # fmt: skip
    lattice = Lattice(config)
    base = lattice.values(lattice.grid_points())["K_W"]
    assert base.tobytes() == np.array(config.axes[0].values).tobytes()
    fine_num = (num - 1) * 2**level + 1
    finer = make_config(sweep={"K_W": {"start": start, "stop": stop, "num": fine_num,
                                       "scale": scale}})  # fmt: skip
    index = np.arange(fine_num, dtype=np.int64)[:, None] << (12 - level)
    refined = lattice.values(index)["K_W"]
    assert refined.tobytes() == np.array(finer.axes[0].values).tobytes()


def test_a_log_axis_refines_in_log():
    """The new point between two values of a log range is their geometric mean."""
    config = refine_config({"K_W": {"start": 0.01, "stop": 1.0, "num": 3, "scale": "log"}}, 1)
    values = Lattice(config).values(np.array([[1]]), level=1)["K_W"]
    assert values[0] == pytest.approx(math.sqrt(0.01 * 0.1), rel=1e-14)


def test_a_list_axis_refines_between_its_neighbours():
    config = refine_config({"K_W": [0.04, 0.05, 0.08]}, 2)
    values = Lattice(config).values(np.arange(9)[:, None], level=2)["K_W"]
    np.testing.assert_allclose(
        values, [0.04, 0.0425, 0.045, 0.0475, 0.05, 0.0575, 0.065, 0.0725, 0.08], rtol=1e-15
    )
    assert values[[0, 4, 8]].tolist() == [0.04, 0.05, 0.08]  # the listed values exactly


def test_range_values_is_the_parser_formula():
    """config.range_values makes the values the parser gives (one formula)."""
    config = make_config(sweep={"K_W": {"start": 0.03, "stop": 0.07, "num": 64}})
    assert (
        np.array(config.axes[0].values).tobytes()
        == range_values("linear", 0.03, 0.07, np.arange(64), 63).tobytes()
    )


# --- planning ---------------------------------------------------------------------------


def test_one_axis_is_bisection():
    """Over one axis, each level splits the one cell holding the transition: one new
    point per level, and after L levels the transition lies in a cell 2^-L of a step."""
    kc = 0.05123
    refinement = refine_fully(
        Refinement(refine_config({"K_W": {"start": 0.04, "stop": 0.06, "num": 9}}, levels=10)),
        lambda v: v["K_W"] > kc,
    )
    assert [len(p) for p in refinement.planned] == [9] + [1] * 10
    assert refinement.stopped == "levels"
    ((level, cells),) = [(lv, c) for lv, c in unsplit_mixed_cells(refinement) if len(c)]
    lattice = refinement.lattice
    low, high = (lattice.values(cells + d)["K_W"][0] for d in (0, lattice.step(level)))
    assert level == 10 and low < kc < high
    assert high - low == pytest.approx(0.0025 / 2**10)


def circle(v):
    """A disc about (K_W, B) = (0.05 µm⁻¹, 0.08), radius 0.01 in both, and a half plane."""
    inside = (v["K_W"] - 0.05) ** 2 + (v["B"] - 0.08) ** 2 < 0.01**2
    return inside + 2 * (v["K_W"] > 0.063)


TWO_AXES = {"K_W": {"start": 0.03, "stop": 0.07, "num": 17}, "B": [0.06, 0.07, 0.08, 0.09, 0.1]}


def test_two_axes_every_mixed_cell_ends_at_the_finest_level():
    """Every cell whose corners differ is split down to the finest level; the cells left
    there hold the boundary (a corner on each side of it), and no other cell was split."""
    refinement = refine_fully(Refinement(refine_config(TWO_AXES, levels=5)), circle)
    for level, cells in unsplit_mixed_cells(refinement):
        assert level == 5 or len(cells) == 0, (level, len(cells))
    tree = cell_tree(refinement.lattice, refinement.index)
    for level, (cells, split) in enumerate(tree[:-1]):
        assert np.array_equal(split, mixed(refinement, cells, level)), level


def test_the_tree_read_back_is_the_planned_one():
    """cell_tree finds, from the points alone, the cells the plan split, level by level."""
    refinement = Refinement(refine_config(TWO_AXES, levels=4))
    planned_cells = []
    index = refinement.planned[0]
    while index is not None:
        planned_cells.append(refinement.cells)
        refinement.add(index, made_up(refinement, circle))
        index = refinement.plan()
    tree = cell_tree(refinement.lattice, refinement.index)
    for level, cells in enumerate(planned_cells):
        assert np.array_equal(tree[level][0], cells), level
    assert refinement.lattice.point_levels(refinement.index).tolist() == sum(
        ([level] * len(p) for level, p in enumerate(refinement.planned)), []
    )


def test_three_axes():
    """Any number of axes: a sphere over three is found down to the finest level, and a
    point of level L lies on its lattice."""
    config = make_config(
        {"model": "quasi-dynamic"},
        sweep={"K_W": {"start": 0.03, "stop": 0.07, "num": 5}, "A": [0.02, 0.03, 0.04],
               "eta_W": {"start": 0.0, "stop": 0.2, "num": 3}},
        parameters={"A": None},
        refine={"levels": 3},
    )  # fmt: skip

    def sphere(v):
        return ((v["K_W"] - 0.05) / 0.02) ** 2 + ((v["A"] - 0.03) / 0.01) ** 2 + (
            (v["eta_W"] - 0.1) / 0.1
        ) ** 2 < 0.5

    refinement = refine_fully(Refinement(config), sphere)
    assert refinement.stopped == "levels" and len(refinement.planned) == 4
    for level, cells in unsplit_mixed_cells(refinement):
        assert level == 3 or len(cells) == 0
    levels = refinement.lattice.point_levels(refinement.index)
    for level in range(4):
        on = refinement.index[levels == level] % refinement.lattice.step(level)
        assert not on.any()


def test_the_plan_does_not_depend_on_the_order_of_the_runs_within_a_level():
    """Labels arrive in the order of the planned points; the plan is a function of the
    labels, so two refinements told the same labels plan the same points."""
    one = refine_fully(Refinement(refine_config(TWO_AXES, levels=4)), circle)
    two = refine_fully(Refinement(refine_config(TWO_AXES, levels=4)), circle)
    for a, b in zip(one.planned, two.planned, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.slow
@given(budget=st.integers(85, 1200))
def test_max_runs_is_never_passed_and_a_larger_budget_runs_a_superset(budget):
    """The runs never pass max_runs; a cut level keeps whole cells in order and stops
    refinement; a larger budget runs every point a smaller one did."""
    config = refine_config(TWO_AXES, levels=5, max_runs=budget)
    cut = refine_fully(Refinement(config), circle)
    assert cut.runs <= budget
    larger = refine_fully(Refinement(refine_config(TWO_AXES, levels=5, max_runs=budget + 40)),
                          circle)  # fmt: skip
    keys = set(larger.lattice.keys(larger.index).tolist())
    assert set(cut.lattice.keys(cut.index).tolist()) <= keys
    free = refine_fully(Refinement(refine_config(TWO_AXES, levels=5)), circle)
    if free.runs <= budget:
        assert cut.runs == free.runs and cut.stopped == "levels"
    else:
        assert cut.stopped == "max_runs"


def test_a_cut_level_takes_the_first_listed_output_first():
    """Cells whose corners differ in an earlier output of refine.outputs come first when
    max_runs cuts a level."""
    config = refine_config({"K_W": {"start": 0.04, "stop": 0.06, "num": 9}}, levels=3,
                           max_runs=10, outputs=["regime", "period"])  # fmt: skip
    refinement = Refinement(config)
    index = refinement.planned[0]
    k = refinement.lattice.values(index)["K_W"]
    regime = (k > 0.0551).astype(np.int8)[:, None]  # changes in one cell only
    period = np.where(k < 0.0449, 2.0, 1.0)[:, None]  # changes (100 %) in another
    refinement.add(index, Labels((("regime", True, regime), ("period", False, period)), 0.05))
    (new,) = refinement.plan()
    assert 0.055 < refinement.lattice.values(new[None])["K_W"][0] < 0.0575
    assert refinement.stopped == "max_runs" and refinement.plan() is None


def test_converged_when_no_corners_differ():
    refinement = refine_fully(Refinement(refine_config(TWO_AXES, levels=5)), lambda v: 0 * v["K_W"])
    assert refinement.stopped == "converged" and len(refinement.planned) == 1


# --- labels -------------------------------------------------------------------------------


def test_continuous_outputs_split_beyond_rtol():
    """A continuous output splits a cell where its spread over the corners passes rtol
    times its largest magnitude; NaN against a number always does."""
    corners = np.array([[0, 1]])
    cases = (([1.0, 1.04], False), ([1.0, 1.06], True), ([np.nan, np.nan], False),
             ([np.nan, 1.0], True), ([np.inf, 1.0], True), ([0.0, 0.0], False))  # fmt: skip
    for values, split in cases:
        labels = Labels((("period", False, np.array(values)[:, None]),), 0.05)
        assert (differs(labels, corners)[0] == 0) == split, values


def test_ensemble_labels_compare_the_members_distribution():
    """With an ensemble, regime and regime_fraction compare how many members end in each
    regime, not which; a continuous output compares member by member."""
    config = make_config(sweep={"K_W": [0.04, 0.06]}, initial={"ensemble": 3},
                         refine={"outputs": ["regime_fraction", "regime", "lnv_max"]})  # fmt: skip
    fields = {
        "regime": np.array([0, 2, 0, 2, 0, 0], np.int8),  # points: (0, 2, 0) and (2, 0, 0)
        "lnv_max": np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0]),
    }
    labels = point_labels(config, fields)
    (_, _, fraction), (_, _, regime), (_, _, lnv) = labels.outputs
    assert np.array_equal(fraction[0], fraction[1]) and np.array_equal(regime[0], regime[1])
    assert np.array_equal(lnv[0], lnv[1])
    assert differs(labels, np.array([[0, 1]]))[0] == -1


# --- refine.split_undecided: false (the default): undecided corners do not split a cell -------

STEADY, UNDECIDED = 0, 3


def test_undecided_corners_are_left_out_of_the_comparison_but_against_steady_ones():
    """Cells whose decided corners agree do not split (an undecided corner against one
    decided label other than steady, or every corner undecided); decided corners that
    differ still do, whatever the undecided ones say; continuous outputs alike; and an
    undecided corner against a steady one always splits (the steady region's edge)."""
    regime = np.array([2, UNDECIDED, 1, UNDECIDED, 2, STEADY])
    lnv = np.array([1.0, 9.0, 1.0, np.nan, 1.0, 1.0])
    labels = Labels((("regime", True, regime[:, None]), ("lnv_max", False, lnv[:, None])), 0.05,
                    regime == UNDECIDED, regime == STEADY)  # fmt: skip
    cells = [np.array(c) for c in ([0, 1], [1, 0], [1, 3], [0, 1, 2], [1, 2, 3], [0, 4],
                                   [1, 3, 4], [0, 2], [1, 5], [5, 3, 3])]  # fmt: skip
    first = [differs(labels, c[None])[0] for c in cells]
    assert first == [-1, -1, -1, 0, -1, -1, -1, 0, 0, 0]
    everything = Labels(labels.outputs, 0.05)  # split_undecided: true
    assert [differs(everything, c[None])[0] for c in cells] == [0, 0, 1, 0, 0, -1, 0, 0, 0, 0]


def test_point_labels_mark_undecided_and_steady_points_by_default():
    sweep = {"K_W": [0.04, 0.06, 0.05]}
    fields = {"regime": np.array([STEADY, UNDECIDED, 2], np.int8)}
    every = refine_config(sweep, outputs=["regime"], split_undecided=True)
    assert point_labels(every, fields).undecided is None
    labels = point_labels(refine_config(sweep, outputs=["regime"]), fields)
    assert labels.undecided.tolist() == [False, True, False]
    assert labels.steady.tolist() == [True, False, False]
    assert labels.take([2, 1]).undecided.tolist() == [False, True]
    assert labels.join(labels).steady.tolist() == [True, False, False] * 2
    members = make_config(sweep=sweep, initial={"ensemble": 2}, refine={})
    fields = {"regime": np.array([UNDECIDED, 0, UNDECIDED, UNDECIDED, 0, 0], np.int8)}
    labels = point_labels(members, fields)
    assert labels.undecided.tolist() == [False, True, False]
    assert labels.steady.tolist() == [False, False, True]


def band_refinement(split_undecided, levels=5):
    """A refinement over TWO_AXES of made-up regimes: steady right of a line, runaway left
    of it, and below B = 0.08 an undecided band between them (twoblock's runs just below
    Kc, where growth is too slow to reach the cap by max_t_end), 0.0011 µm⁻¹ wide."""

    def band(v):
        x = v["K_W"] - 0.05 - 0.1 * (v["B"] - 0.08)
        inside = np.where(v["B"] < 0.08, x > -0.0011, x > -1e-12)
        return np.where(x > 0, STEADY, np.where(inside, UNDECIDED, 2))

    refinement = Refinement(refine_config(TWO_AXES, levels=levels,
                                          split_undecided=split_undecided))  # fmt: skip
    index = refinement.planned[0]
    while index is not None:
        codes = np.asarray(band(refinement.lattice.values(index)))
        marked = () if split_undecided else (codes == UNDECIDED, codes == STEADY)
        refinement.add(index, Labels((("regime", True, codes[:, None]),), 0.05, *marked))
        index = refinement.plan()
    return refinement


def test_an_undecided_band_is_not_refined_but_the_steady_edge_is():
    """With split_undecided false the band's edge against runaway stops being split once
    the band spans a cell, the steady region's edge is refined to the finest level all
    along (against runaway above B = 0.08, against the band below), and every point run
    is one the refinement with split_undecided true runs too."""
    every, decided = band_refinement(True), band_refinement(False)
    assert set(decided.lattice.keys(decided.index)) < set(every.lattice.keys(every.index))
    assert decided.runs < 0.8 * every.runs

    def finest(refinement, label, where):
        regime = refinement.labels.outputs[0][2][:, 0]
        b = refinement.lattice.values(refinement.index)["B"]
        levels = refinement.lattice.point_levels(refinement.index)
        return levels[(regime == label) & where(b)].max()

    for b_range in (lambda b: b > 0.08, lambda b: b < 0.075):
        assert finest(decided, STEADY, b_range) == 5
    # the band's edge against runaway, away from B = 0.08: coarse unless split_undecided
    assert finest(decided, 2, lambda b: b < 0.075) < 5
    assert finest(every, 2, lambda b: b < 0.075) == 5
