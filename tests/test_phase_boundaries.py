"""Boundaries of refined results (sweep/refine/boundaries.py), and where theory puts them.

The physics brief's closed forms: steady sliding of two quasi-static blocks is lost at
Kc/W = (B − A)/D0 for every coupling k2 (section 3), of one radiation-damped block at
Kc = (W(B − A) − ηV)/D0 (section 4). A refinement must find the edge of the steady
region in the finest cell that holds Kc, at every k2.
"""

import dataclasses

import numpy as np
import pytest
import xarray as xr
from conftest import KC_W, ROOT, kc_w, make_config
from test_refine import TWO_AXES, circle, made_up, refine_config

from sweep.config import load_config, with_changes
from sweep.engine import runner
from sweep.model import physics
from sweep.refine.boundaries import boundaries
from sweep.refine.lattice import Refinement
from sweep.variables import ATTRACTORS, REGIMES


def steady_edges(ds):
    """The boundaries between steady sliding and any other regime."""
    found = boundaries(ds, outputs=["regime"])
    return [b for b in found if "steady" in b.between]


def assert_edge_brackets(edge, kc, axis=0):
    """Each segment of ``edge`` crosses a cell that holds ``kc`` along ``axis``: its
    vertices lie within half the cell's size of it (closed: Kc may be a cell's corner)."""
    half = edge.resolution[:, axis] / 2
    vertices = edge.vertices[:, axis]
    for x, h in zip(vertices, np.resize(half, len(vertices)), strict=True):
        assert abs(x - kc) <= h * (1 + 1e-12), (x, kc, h)


@pytest.mark.slow
def test_two_blocks_lose_steady_sliding_at_the_one_block_kc_for_every_k2():
    """Two quasi-static blocks over K/W × k2/W refined 5 levels (K step / 32 = 2.5e-4
    µm⁻¹, Kc between points of every level): the steady region's edge runs from k2 = 0
    to 0.2 without a gap, every segment in a finest cell that holds Kc/W = (B − A)/D0.
    What lies beyond it may change along the edge (runaway; at weak coupling, k2/W ≈
    0.005 µm⁻¹, a bounded out-of-phase cycle below Kc, physics brief §4), so the edge
    may be several polylines, one per label on its other side."""
    config = make_config(
        {"blocks": 2, "parameters": {"k2_W": None}},
        sweep={"K_W": {"start": 0.0303, "stop": 0.0703, "num": 6}, "k2_W": [0.0, 0.1, 0.2]},
        initial={"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
        refine={"levels": 5},
    )
    ds = runner.compute(config, show_progress=False)
    edges = steady_edges(ds)
    assert edges
    spans = sorted((e.vertices[:, 1].min(), e.vertices[:, 1].max()) for e in edges)
    reach = spans[0][1]
    for lo, hi in spans[1:]:
        assert lo <= reach, spans  # no gap in k2 between the polylines
        reach = max(reach, hi)
    assert spans[0][0] == 0.0 and reach == 0.2
    for edge in edges:
        assert (edge.level == 5).all()
        assert_edge_brackets(edge, KC_W)
        np.testing.assert_allclose(edge.resolution[:, 0], 0.008 / 32, rtol=1e-12)


TWOBLOCK = ROOT / "configs" / "twoblock.yaml"


@pytest.mark.slow
@pytest.mark.parametrize("k2_w", load_config(TWOBLOCK).axes[1].values)
def test_twoblock_config_refined_8_levels_finds_kc(k2_w):
    """configs/twoblock.yaml refined 8 levels along K/W (its step / 256 = 2.5e-6 µm⁻¹) at
    each k2/W of its grid (1-D: the 2-D refinement samples the same K/W values, and
    every k2 between; test_two_blocks_... above checks those at 5 levels): the edge of
    the steady region is the finest cell holding the analytic Kc/W, which lies on the
    lattice of level 1 (a closed bracket)."""
    config = with_changes(load_config(TWOBLOCK), {"sweep": {"k2_W": [k2_w]},
                                                  "refine": {"levels": 8}})  # fmt: skip
    ds = runner.compute(config, threads=2, show_progress=False)
    (edge,) = steady_edges(ds)
    kc = float(physics.critical_kappa("quasi-static", 0.03, 0.08))  # D0 = 1 µm
    assert edge.level.tolist() == [8]
    assert edge.resolution[0, 0] == pytest.approx(0.04 / 63 / 256, rel=1e-12)
    assert_edge_brackets(edge, kc)


@pytest.mark.slow
def test_twoblock_refined_8_levels_in_two_dimensions_finds_kc_at_every_k2():
    """configs/twoblock.yaml's blocks over K/W ± 0.2 % about Kc/W (which lies on the
    lattice of level 1) × its k2/W axis, refined 8 levels over both (the default
    refinement: linear-regime verdicts, undecided corners splitting only against steady
    ones): one edge of the steady region, from k2 = 0 to 0.2 without a gap, every segment
    in a finest cell (K step / 256) that holds Kc, and the runs next to it stopped by
    linear-regime verdicts."""
    config = with_changes(load_config(TWOBLOCK), {
        "sweep": {"K_W": {"start": 0.0499, "stop": 0.0501, "num": 2}},
        "refine": {"levels": 8},
    })  # fmt: skip
    ds = runner.compute(config, threads=2, show_progress=False)
    (edge,) = steady_edges(ds)
    kc = float(physics.critical_kappa("quasi-static", 0.03, 0.08))
    assert edge.between == ("steady", "stick_slip")
    assert (edge.level == 8).all()
    np.testing.assert_allclose(edge.resolution[:, 0], 0.0002 / 256, rtol=1e-9)
    assert_edge_brackets(edge, kc)
    k2 = np.sort(edge.vertices[:, 1])
    assert k2[0] == 0.0 and k2[-1] == 0.2
    assert np.diff(k2).max() <= 0.2 / 15 / 256 * (1 + 1e-9)
    steady = ds.regime.values == REGIMES.index("steady")
    near = steady & (ds.level.values == 8)
    assert ds.linear_verdict.values[near].mean() > 0.99


def test_one_damped_block_loses_steady_sliding_at_the_linear_theory_kc():
    """One quasi-dynamic block, ηV/W = 0.01, K/W refined 8 levels (2e-5 µm⁻¹, 5e-4 of
    Kc): the edge of steady sliding lies in the finest cell holding
    Kc/W = ((B − A) − ηV/W)/D0 = 0.04 µm⁻¹, where the limit cycle is born."""
    config = make_config(
        {"model": "quasi-dynamic"},
        parameters={"eta_W": 0.1},
        sweep={"K_W": {"start": 0.0301, "stop": 0.0501, "num": 5}},
        refine={"levels": 8},
    )
    ds = runner.compute(config, show_progress=False)
    (edge,) = steady_edges(ds)
    assert edge.level.tolist() == [8]
    assert_edge_brackets(edge, kc_w("quasi-dynamic", eta_w=0.1, V=0.1))


# --- the polylines ------------------------------------------------------------------------------


def made_up_dataset(refinement):
    """A refined result of made-up labels: regime 0/1/2 as the labels, attractor the
    regime's, one event; what boundaries() reads, as a refinement writes it."""
    from sweep.refine.dataset import index_name

    config = refinement.config
    codes = refinement.labels.outputs[0][2][:, 0].astype(np.int8)
    regime_flags = {"flag_values": np.arange(4, dtype=np.int8), "flag_meanings": " ".join(REGIMES)}
    attractor_flags = {"flag_values": np.arange(6, dtype=np.int8),
                       "flag_meanings": " ".join(ATTRACTORS)}  # fmt: skip
    coords = {index_name(a.name): ("point", refinement.index[:, i])
              for i, a in enumerate(config.axes)}  # fmt: skip
    return xr.Dataset(
        {
            "regime": ("point", codes, regime_flags),
            "attractor": ("point", np.array([0, 1, 5], np.int8)[codes], attractor_flags),
            "cycle_events": ("point", (codes == 1).astype(np.int32)),
        },
        coords=coords,
        attrs={"featureType": "point", "config_text": config.text},
    )


def test_a_closed_boundary_is_one_closed_polyline_within_its_resolution():
    """A disc (made-up labels) refined 6 levels: its boundary is one closed polyline whose
    vertices lie within a finest cell of the circle; the straight boundary beside it
    is one open line."""
    refinement = Refinement(refine_config(TWO_AXES, levels=6))
    index = refinement.planned[0]
    while index is not None:
        refinement.add(index, made_up(refinement, circle))
        index = refinement.plan()
    found = boundaries(made_up_dataset(refinement))
    disc = [b for b in found if b.between == ("steady", "stick_slip, periodic, 1 event")]
    line = [b for b in found if "runaway" in b.between]
    assert len(disc) == 1 and len(line) == 1
    (disc,), (line,) = disc, line
    assert disc.axes == line.axes == ("B", "K_W")  # the config's order (YAML sorts keys)
    assert np.array_equal(disc.vertices[0], disc.vertices[-1])
    b, k = disc.vertices.T
    radius = np.hypot(k - 0.05, b - 0.08)
    cell = np.hypot(*disc.resolution[0])
    assert np.all(np.abs(radius - 0.01) <= cell), np.abs(radius - 0.01).max()
    assert np.allclose(line.vertices[:, 1], line.vertices[0, 1])
    assert abs(line.vertices[0, 1] - 0.063) <= line.resolution[0, 1] / 2
    assert line.vertices[:, 0].min() == 0.06 and line.vertices[:, 0].max() == 0.1


def test_three_refined_axes_have_no_lines(tmp_path):
    config = dataclasses.replace(
        make_config(
            {"model": "quasi-dynamic"},
            sweep={"K_W": [0.04, 0.05], "A": [0.02, 0.03], "eta_W": [0.0, 0.1]},
            parameters={"A": None},
            refine={"levels": 1},
        )
    )
    ds = runner.compute(config, show_progress=False)
    with pytest.raises(ValueError, match="refined over 3"):
        boundaries(ds)
