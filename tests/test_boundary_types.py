"""The type of each boundary (sweep/refine/boundary_types.py, sweep.boundaries).

The rules are checked on made-up results whose outputs come from theory: the growth rate
of one quasi-static block from the Jacobian of its equations written out by hand (a Hopf
boundary where it changes sign), and the multipliers of maps whose bifurcations are
textbook ones: the logistic map x → r x (1 − x), whose fixed point has multiplier 2 − r
(period doubling at r = 3, the 2-cycle's 4 + 2r − r² doubling again at r = 1 + √6) and
whose 3-cycle is born in a fold at r = 1 + √8; and the delayed logistic map
x' = r x (1 − y), y' = x, whose fixed point has the complex pair |μ|² = r − 1 (a torus at
r = 2). A map's fixed point is a cycle's section: its multipliers are the cycle's.
Then engine runs: route_to_chaos's simple cycle doubling, a damped block's Hopf and a
quasi-static block's runaway across Kc.
"""

import numpy as np
import pytest
import xarray as xr
from conftest import ROOT, make_config
from test_phase_boundaries import made_up_dataset
from test_refine import made_up, refine_config

from sweep.codes import FLOQUET_STATUSES
from sweep.config import load_config, with_changes
from sweep.engine import runner
from sweep.plot.bifurcation import plot_bifurcation
from sweep.plot.common import KIND_TEXT, kind_text
from sweep.plot.maps import plot_result
from sweep.refine.boundaries import boundaries
from sweep.refine.boundary_types import (
    KINDS,
    NEAR_UNIT,
    boundary_types_1d,
    classify,
    run_table,
)
from sweep.refine.lattice import Refinement
from sweep.variables import ATTRACTORS, REGIMES

A, B = 0.03, 0.08  # the paper's A and B; D0 = 1 µm, V = 0.1 µm/s


def qs_growth_rate(kappa, b=B, a=A, v=0.1, d0=1.0):
    """Largest real part (s⁻¹) of the eigenvalues of one quasi-static aging-law block at
    steady sliding, from its Jacobian written out by hand: with x = ln(v/V),
    y = ln(Vθ/D0), κ = K D0/W, in time D0/V: x' = ((b − κ) x + b y)/a, y' = −x − y."""
    jac = np.array([[(b - kappa) / a, b / a], [-1.0, -1.0]])
    return np.linalg.eigvals(jac).real.max() * v / d0


def flags(table):
    """CF flag attributes of a code table."""
    return {"flag_values": np.arange(len(table), dtype=np.int8), "flag_meanings": " ".join(table)}


def line_result(
    x, regime, attractor, events, modulus=None, argument=None, growth=None, trivial_error=1e-6
):
    """A made-up 1-D result along axis ``r`` with what the rules read (the multipliers'
    accuracy ``trivial_error``)."""
    n = len(x)
    periodic = np.array([a == "periodic" for a in attractor])
    data = {
        "regime": ("r", np.array([REGIMES.index(r) for r in regime], np.int8), flags(REGIMES)),
        "attractor": (
            "r",
            np.array([ATTRACTORS.index(a) for a in attractor], np.int8),
            flags(ATTRACTORS),
        ),
        "cycle_events": ("r", np.asarray(events, np.int32)),
        "linear_growth_rate": ("r", np.full(n, np.nan) if growth is None else growth),
    }
    if modulus is not None:
        status = np.where(periodic, FLOQUET_STATUSES.index("ok"), 0).astype(np.int8)
        data["floquet_modulus"] = ("r", np.where(periodic, modulus, np.nan))
        data["floquet_argument"] = ("r", np.where(periodic, argument, np.nan))
        data["floquet_status"] = ("r", status, flags(FLOQUET_STATUSES))
        data["floquet_trivial_error"] = ("r", np.where(periodic, trivial_error, np.nan))
    return xr.Dataset(data, coords={"r": x})


def logistic_cycle_multiplier(r, period):
    """The multiplier of the stable cycle of ``period`` of the logistic map at ``r``: the
    product of r (1 − 2x) around the cycle, found by iterating from x = 0.5."""
    x = 0.5
    for _ in range(20000):
        x = r * x * (1 - x)
    mu = 1.0
    for _ in range(period):
        mu *= r * (1 - 2 * x)
        x = r * x * (1 - x)
    return mu


# --- the rules, on theory ---------------------------------------------------------------------


def test_a_refined_hopf_line_where_the_hand_growth_rate_changes_sign():
    """One quasi-static block over K/W × B, refined 5 levels with steady sliding where
    the hand Jacobian's growth rate is negative, a simple cycle where it is positive:
    one boundary, at Kc/W = (B − A)/D0 within its cells, typed hopf."""
    refinement = Refinement(
        refine_config(
            {"K_W": {"start": 0.03, "stop": 0.07, "num": 9}, "B": [0.06, 0.07, 0.08, 0.09]},
            levels=5,
        )
    )

    def rates(v):
        return np.array([qs_growth_rate(k, b) for k, b in zip(v["K_W"], v["B"], strict=True)])

    index = refinement.planned[0]
    while index is not None:
        refinement.add(index, made_up(refinement, lambda v: (rates(v) > 0).astype(int)))
        index = refinement.plan()
    ds = made_up_dataset(refinement)
    values = refinement.lattice.values(refinement.index)
    ds["linear_growth_rate"] = ("point", rates(values))
    (edge,) = boundaries(ds)
    assert edge.kind == "hopf", edge.evidence
    assert "eigenpair crosses" in edge.evidence
    b, k = edge.vertices.T  # the line K/W = B − A crosses each cell: slope 1
    assert np.all(np.abs(k - (b - A)) <= edge.resolution.sum(axis=1).max() / 2 * (1 + 1e-9))


def test_a_hopf_boundary_carries_the_criticality_its_runs_agree_on():
    """With hopf_criticality in the result (a flag variable): "hopf (supercritical)"
    where both sides say supercritical, plain hopf where they differ."""
    criticality = ("supercritical", "subcritical", "degenerate", "not_simple", "no_hopf")
    k = np.array([0.049, 0.051])
    growth = np.array([qs_growth_rate(x) for x in k])
    assert growth[0] > 0 > growth[1]
    ds = line_result(
        k,
        regime=["stick_slip", "steady"],
        attractor=["periodic", "fixed_point"],
        events=[1, 0],
        growth=growth,
    )
    for codes, kind in (([0, 0], "hopf (supercritical)"), ([0, 1], "hopf")):
        ds["hopf_criticality"] = ("r", np.array(codes, np.int8), flags(criticality))
        (crossing,) = boundary_types_1d(ds)
        assert crossing.kind == kind, crossing.evidence


def test_the_same_line_without_a_sign_change_is_a_fold_only_where_mu_is_near_plus_one():
    """Steady sliding beside a cycle with the growth rate negative on both sides (a
    bistable edge): a fold of cycles where the cycle's multiplier is real and above
    NEAR_UNIT, undetermined (with the reason) where it is not, or not computed."""
    x = np.array([0.0, 1.0])
    common = dict(
        regime=["stick_slip", "steady"],
        attractor=["periodic", "fixed_point"],
        events=[1, 0],
        growth=np.array([-0.01, -0.02]),
    )
    fold = line_result(x, modulus=[0.97, np.nan], argument=[0.0, np.nan], **common)
    (crossing,) = boundary_types_1d(fold)
    assert crossing.kind == "fold_of_cycles", crossing.evidence
    inside = line_result(x, modulus=[NEAR_UNIT / 2, np.nan], argument=[0.0, np.nan], **common)
    (crossing,) = boundary_types_1d(inside)
    assert crossing.kind == "undetermined" and "not near +1" in crossing.evidence
    (crossing,) = boundary_types_1d(line_result(x, **common))
    assert crossing.kind == "undetermined" and "no Floquet" in crossing.evidence


def test_the_logistic_map_doubles_at_three_and_again_and_folds_into_its_window():
    """Points of r with the logistic map's attractors and multipliers (the fixed point
    2 − r; the 2-cycle 4 + 2r − r²; the 4- and 3-cycles' by iteration): 1 → 2 events at
    r = 3 and 2 → 4 at 1 + √6 are period doublings; chaos → the 3-cycle at 1 + √8 is a
    fold."""
    pd1, pd2, fold = 3.0, 1 + np.sqrt(6), 1 + np.sqrt(8)
    r = np.array([pd1 - 0.05, pd1 + 0.05, pd2 - 0.01, pd2 + 0.01])
    mu = [2 - r[0], 2 - r[1], 4 + 2 * r[2] - r[2] ** 2, logistic_cycle_multiplier(r[3], 4)]
    assert mu[0] < -NEAR_UNIT and mu[2] < -NEAR_UNIT  # the theory, as the rules use it
    ds = line_result(
        r,
        regime=["stick_slip"] * 4,
        attractor=["periodic"] * 4,
        events=[1, 2, 2, 4],
        modulus=np.abs(mu),
        argument=np.angle(np.asarray(mu, complex)),
    )
    found = boundary_types_1d(ds)
    assert [(c.index, c.kind) for c in found] == [(0, "period_doubling"), (2, "period_doubling")]
    assert found[0].position == pytest.approx(pd1)
    assert found[1].between == ("stick_slip, periodic, 2 events", "stick_slip, periodic, 4 events")
    mu3 = logistic_cycle_multiplier(fold + 1e-4, 3)
    assert NEAR_UNIT < mu3 < 1
    ds = line_result(
        [fold - 1e-3, fold + 1e-4],
        regime=["stick_slip"] * 2,
        attractor=["chaotic", "periodic"],
        events=[0, 3],
        modulus=[np.nan, mu3],
        argument=[np.nan, 0.0],
    )
    (crossing,) = boundary_types_1d(ds)
    assert crossing.kind == "fold_of_cycles", crossing.evidence


def test_events_that_double_while_mu_is_not_near_minus_one_are_undetermined():
    """1 → 2 events but the single-event cycle's multiplier is +0.9: contradictory."""
    ds = line_result(
        [0.0, 1.0],
        regime=["stick_slip"] * 2,
        attractor=["periodic"] * 2,
        events=[1, 2],
        modulus=[0.9, 0.9],
        argument=[0.0, 0.0],
    )
    (crossing,) = boundary_types_1d(ds)
    assert crossing.kind == "undetermined" and "not near −1" in crossing.evidence


def test_a_neutral_or_unstable_cycle_names_no_bifurcation():
    """A cycle with |μ| = 1 within ten times its accuracy (a family of closed orbits: no
    fold however near +1) and one with |μ| = 1.06 (unstable, though labelled periodic):
    undetermined, saying which."""
    common = dict(regime=["stick_slip"] * 2, attractor=["periodic", "chaotic"], events=[1, 0])
    for modulus, argument, error, word in (
        (1 - 5e-7, 1e-7, 1e-7, "neutral"),
        (1.06, np.pi, 1e-4, "unstable"),
    ):
        ds = line_result(
            [0.0, 1.0],
            modulus=[modulus, np.nan],
            argument=[argument, np.nan],
            trivial_error=error,
            **common,
        )
        (crossing,) = boundary_types_1d(ds)
        assert crossing.kind == "undetermined" and word in crossing.evidence, crossing.evidence
    ds = line_result(
        [0.0, 1.0],
        modulus=[1 - 5e-7, np.nan],
        argument=[1e-7, np.nan],
        trivial_error=1e-8,
        **common,
    )
    assert boundary_types_1d(ds)[0].kind == "fold_of_cycles"  # 50 times its accuracy from 1


def test_the_delayed_logistic_map_loses_its_fixed_point_to_a_torus_at_two():
    """x' = r x (1 − y), y' = x: at the fixed point x = y = 1 − 1/r the Jacobian
    [[1, −(r − 1)], [1, 0]] has the pair |μ|² = r − 1; beyond r = 2 the orbit is
    quasi-periodic: a torus. Beside a chaotic run instead: undetermined."""
    r = 1.95
    mu = np.linalg.eigvals(np.array([[1.0, -(r - 1)], [1.0, 0.0]]))
    top = mu[np.argmax(np.angle(mu))]
    assert abs(top) == pytest.approx(np.sqrt(r - 1))
    for beyond, kind in (("quasi_periodic", "torus"), ("chaotic", "undetermined")):
        ds = line_result(
            [r, 2.05],
            regime=["stick_slip"] * 2,
            attractor=["periodic", beyond],
            events=[1, 0],
            modulus=[abs(top), np.nan],
            argument=[np.angle(top), np.nan],
        )
        (crossing,) = boundary_types_1d(ds)
        assert crossing.kind == kind, (beyond, crossing.evidence)


def test_runaway_below_the_hand_kc_names_the_other_side():
    """A quasi-static block: runaway where the hand growth rate is positive, steady
    where it is negative; the boundary is runaway, beside steady."""
    k = np.array([0.046, 0.048, 0.052, 0.054])
    growth = np.array([qs_growth_rate(x) for x in k])
    runaway = growth > 0
    ds = line_result(
        k,
        regime=np.where(runaway, "runaway", "steady"),
        attractor=np.where(runaway, "unbounded", "fixed_point"),
        events=[0] * 4,
        growth=growth,
    )
    (crossing,) = boundary_types_1d(ds, "r")
    assert crossing.kind == "runaway" and crossing.evidence == "runaway beside steady"
    assert crossing.position == pytest.approx(0.05)
    assert crossing.between == ("runaway", "steady")


def test_an_ensemble_and_runs_that_differ_on_one_side_are_undetermined():
    assert classify(None, [0], [1])[0] == "undetermined"
    ds = line_result(
        [0.0, 1.0, 2.0],
        regime=["steady", "stick_slip", "stick_slip"],
        attractor=["fixed_point", "periodic", "chaotic"],
        events=[0, 1, 0],
        growth=np.array([-1.0, 1.0, 1.0]),
    )
    kind, evidence = classify(run_table(ds), [0], [1, 2])
    assert kind == "undetermined" and "differ" in evidence


def test_every_type_has_a_short_text_for_the_figures():
    assert set(KIND_TEXT) == set(KINDS)
    assert kind_text("hopf (supercritical)") == "Hopf (super)"


def figure_texts(fig):
    """Every text drawn on the axes of ``fig``."""
    return {t.get_text() for ax in fig.axes for t in ax.texts}


# --- engine runs ------------------------------------------------------------------------------


@pytest.mark.slow
def test_route_to_chaos_simple_cycle_doubles_with_mu_near_minus_one():
    """configs/route_to_chaos.yaml at a few K/W about 0.004125 µm⁻¹ (its t_end): the
    simple cycle above, two events a cycle below; the boundary between is a period
    doubling, the simple cycle's multiplier near −1."""
    config = with_changes(
        load_config(ROOT / "configs" / "route_to_chaos.yaml"),
        {
            "sweep": {"K_W": [0.0041, 0.00412, 0.00413, 0.00415]},
            "classification": {"events": 8},
        },
    )
    ds = runner.compute(config, threads=1, show_progress=False)
    crossings = boundary_types_1d(ds)
    doubling = [
        c
        for c in crossings
        if c.between == ("stick_slip, periodic, 2 events", "stick_slip, periodic, 1 event")
    ]
    assert len(doubling) == 1, crossings
    assert doubling[0].kind == "period_doubling", doubling[0].evidence
    fig = plot_bifurcation(ds)
    assert "PD" in figure_texts(fig)


@pytest.mark.slow
def test_a_damped_block_refined_across_kc_is_a_hopf_and_a_quasi_static_one_runs_away():
    """One block, K/W refined 4 levels about Kc: quasi-dynamic with ηV/W = 0.01 (Kc/W =
    0.04 µm⁻¹, configs/quasidynamic.yaml's η/W = 0.1 s/µm at V = 0.1 µm/s): hopf;
    quasi-static (Kc/W = 0.05 µm⁻¹): runaway beside steady sliding."""
    for model, eta_w, start, kind in (
        ("quasi-dynamic", 0.1, 0.0361, "hopf"),
        ("quasi-static", 0.0, 0.0451, "runaway"),
    ):
        config = make_config(
            {"model": model},
            parameters={"eta_W": eta_w} if eta_w else {},
            sweep={"K_W": {"start": start, "stop": start + 0.008, "num": 3}},
            refine={"levels": 4},
        )
        ds = runner.compute(config, threads=1, show_progress=False)
        found = boundaries(ds)
        edges = [b for b in found if "steady" in b.between]
        assert len(edges) == 1, [(b.between, b.kind) for b in found]
        assert edges[0].kind.startswith(kind), edges[0].evidence
        assert kind_text(edges[0].kind) in figure_texts(plot_result(ds))
