"""Issue 36 §3: a cycle of several events is reported with its minimal period.

The engine's ``period`` and ``cycle_events`` against the first return of the whole
state in an independent SciPy run (``nblock_reference.event_states`` and
``first_return``; the systems from ``nblock_reference.Chain`` and
``attractor_reference.Blocks``, written from the physics brief, not from ``sweep``):
the smallest number d of maxima of ℓ_0 after which every ℓ_i and ψ_i (and the
inertial force) is back, and the time that takes.

The cases, each wrong before the fix (b68918e):

- eight unequal quasi-static blocks in a ring (the issue's case): a cycle of 2
  events, 7.1733 s, reported as 4 events, 14.347 s;
- three unequal quasi-static blocks in a chain: a cycle of 3 events reported as
  quasi_periodic, and one of 2 settled only late (quasi_periodic with
  configs/heterogeneous.yaml's t_end = 3000, max_t_end = 6000);
- two unequal inertial blocks (configs/route_to_chaos.yaml at K/W = 0.004925
  µm⁻¹): a cycle of 2 events, reported as 4.

Each was wrong for one reason: the classifier's rows for the other blocks'
extremes over a cycle are read at the end of the step holding the event
(``classify.state.event_state_row``), so they change with the step grid and differ from one
passage of the same state to the next (the ring's block 2: −0.8506 and −0.8780, where
its highest ℓ between the events is −1.2221). The cycle's events and its period are
now told by the rows that are functions of the state at the event.

The engine runs with the shipped configs' integrator (DOP853 or RODAS4, rtol 1e-8,
atol 1e-10) and default classification (accuracy 1e-3): its period is checked to
that relative accuracy, its event maxima to that absolute accuracy (their scale,
min(1, peak-to-peak ℓ/2), is 1 here).
"""

import numpy as np
import pytest
from attractor_reference import Blocks
from conftest import PAPER_A, PAPER_B, config_dict
from nblock_reference import Chain, event_states, first_return, start_state

import sweep
from sweep.variables import ATTRACTORS

#: The engine's classification accuracy (default), relative for the period and
#: absolute for ln v/V at the events.
ACCURACY = 1e-3
#: The SciPy reference call for the quasi-static runs (DOP853 needs no Jacobian) and
#: for the inertial one (stiff stick phases: LSODA with the hand-written Jacobian).
DOP853 = {"method": "DOP853", "rtol": 1e-10, "atol": 1e-12}
LSODA = {"method": "LSODA", "rtol": 1e-10, "atol": 1e-12}

#: The issue's ring: D0 = 1 ± 20 % per block (numpy.random.default_rng(0).uniform(0.8,
#: 1.2, 8), to 6 decimals), V = 1 µm/s, so the time unit is the mean D0 / V in s.
RING_D0 = [1.054785, 0.907915, 0.816389, 0.806611, 1.125308, 1.165102, 1.042654, 1.091799]
RING_K_W, RING_K2_W = 0.0455, 0.02
#: Three blocks with D0 = 1 + 0.2 ξ, ξ the first spread pattern of
#: configs/heterogeneous.yaml (seed 3): a cycle of 2 events at K/W = 0.0455 µm⁻¹ and of
#: 3 at 0.044 µm⁻¹; V = 0.1 µm/s.
CHAIN_D0 = [0.991621, 0.863896, 1.093831]
CHAIN_K2_W = 0.02


def engine(blocks, coupling, d0, k_w, k2_w, v=0.1, t_end=3000.0, **sections):
    """The engine on quasi-static unequal blocks (aging law, paper A and B) over K/W
    ``k_w``, started from v = V, Φ = 1.01 Φss; DOP853 as in the shipped configs."""
    cfg = config_dict(
        {
            "blocks": blocks,
            "coupling": coupling,
            "parameters": {"V": v, "D0": d0, "k2_W": k2_w},
            "sweep": {"K_W": list(k_w)},
            "integrator": {"method": "dop853", "t_end": t_end},
            "classification": {"events": 8},
        },
        **sections,
    )
    return sweep.run(cfg, progress=False)


def check_cycle(point, times, states, tol, time_unit):
    """The engine's ``point`` is the SciPy cycle whose events are ``times``, ``states``
    (D0_ref/V; ``time_unit`` s per D0_ref/V): periodic with the first return's d
    events (the state d' < d events back far beyond ``tol``), its period, and its d
    event maxima of ℓ_0."""
    d, period, gaps = first_return(times, states, tol)
    assert d is not None and min(gaps, default=np.inf) > 1e3 * tol, (d, gaps)
    assert ATTRACTORS[int(point.attractor)] == "periodic"
    assert int(point.cycle_events) == d
    np.testing.assert_allclose(float(point.period), period * time_unit, rtol=ACCURACY)
    peaks = point.event_lnv_peak.values[-d:]
    np.testing.assert_allclose(np.sort(peaks), np.sort(states[-d:, 0]), atol=ACCURACY)
    assert np.isnan(point.event_lnv_peak.values[:-d]).all()  # the settled cycle's only


@pytest.mark.slow
def test_eight_unequal_blocks_in_a_ring_report_the_minimal_period():
    """The issue's ring (K/W = 0.0455, k2/W = 0.02 µm⁻¹): SciPy (DOP853, rtol 1e-10, to
    1000 mean-D0/V; 9 s) returns to the whole state after 2 events, 7.1639 D0_ref/V
    = 7.1733 s, to 1e-11 (one event back it is 3.9 away); the engine reported 4
    events and 14.347 s. Tolerance 1e-8 on the state: the run's own error, far above
    its 1e-11 return and far below 3.9."""
    ds = engine(8, "ring", RING_D0, [RING_K_W], RING_K2_W, v=1.0)
    chain = Chain(PAPER_A, PAPER_B, RING_D0, RING_K_W, RING_K2_W, "ring",
                  D0_ref=np.mean(RING_D0))  # fmt: skip
    times, states = event_states(chain.rhs, start_state(8, 1.0, 1.01), 1000.0, **DOP853)
    check_cycle(ds.isel(K_W=0), times, states, 1e-8, np.mean(RING_D0) / 1.0)


@pytest.mark.slow
@pytest.mark.parametrize(("k_w", "t_end"), [(0.0455, 3500.0), (0.044, 1500.0)])
def test_three_unequal_blocks_cycles_of_two_and_three_events(k_w, t_end):
    """Three blocks in a chain: SciPy (DOP853, rtol 1e-10, to ``t_end`` mean-D0/V; 8 and
    3 s) returns to the whole state after 2 events (18.783 D0_ref/V, to 2e-7: still
    approached, the engine settles at 3147) at K/W = 0.0455 µm⁻¹ and after 3 (18.611,
    to 5e-12) at 0.044; one event back the state is 1 and 8 away, two back (0.044) 2.
    Tolerance 1e-5 on the state. b68918e called 0.044 quasi_periodic (run to
    max_t_end, 50000) and settled 0.0455 only at 3447; with t_end = 3000, where the
    tangent for λ1 starts and changes the steps, and max_t_end = 6000 (as in
    configs/heterogeneous.yaml, whose members 0–2 at K/W = 0.0455, spread_D0 = 0.2 are
    this chain), it called 0.0455 quasi_periodic."""
    ds = engine(3, "chain", CHAIN_D0, [k_w], CHAIN_K2_W, t_end=5000.0)
    chain = Chain(PAPER_A, PAPER_B, CHAIN_D0, k_w, CHAIN_K2_W, D0_ref=np.mean(CHAIN_D0))
    times, states = event_states(chain.rhs, start_state(3, 1.0, 1.01), t_end, **DOP853)
    check_cycle(ds.isel(K_W=0), times, states, 1e-5, np.mean(CHAIN_D0) / 0.1)


@pytest.mark.slow
def test_two_unequal_inertial_blocks_report_the_minimal_period():
    """configs/route_to_chaos.yaml at K/W = 0.004925 µm⁻¹ (D0 = 1.0 / 0.6 µm, m/W = 1
    s²/µm, k2/W = 0.005 µm⁻¹, V = 1 µm/s, RODAS4): SciPy (LSODA, rtol 1e-10, to 6000
    mean-D0/V; 4 s) returns to the whole state (ℓ, ψ, inertial force) after 2 events,
    280.14 D0_ref/V = 224.11 s (one event back it is 1 away); the engine reported 4
    events, 448.22 s. Tolerance 1e-5 on the state (the cycle is approached slowly:
    7e-4 at 3200)."""
    cfg = config_dict(
        {
            "blocks": 2,
            "coupling": "chain",
            "model": "inertial",
            "parameters": {"V": 1.0, "D0": [1.0, 0.6], "m_W": 1.0, "k2_W": 0.005},
            "sweep": {"K_W": [0.004925]},
            "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
            "integrator": {"method": "rosenbrock", "t_end": 3000.0},
            "classification": {"events": 8},
        }
    )
    ds = sweep.run(cfg, progress=False)
    blocks = Blocks("inertial", PAPER_A, PAPER_B, [1.0, 0.6], 0.004925, 0.005, m_W=1.0)
    times, states = event_states(blocks.rhs, blocks.start(1.0, [1.01, 1.0]), 6000.0,
                                 jac=blocks.jacobian, **LSODA)  # fmt: skip
    check_cycle(ds.isel(K_W=0), times, states, 1e-5, 0.8 / 1.0)
