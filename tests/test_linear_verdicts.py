"""Linear-regime verdicts (sweep/kernels/classify/linear.py), refinement's shortcut: a run
whose small oscillation follows the linear theory's rate is labelled by it, and the
label is the one the full run (to max_t_end, λ1 from t_end on) gives.

The runs compared lie near Kc of two quasi-static blocks (configs/twoblock.yaml's model
and start), at couplings from the weak ones, where bounded cycles live just below Kc
and the anti-phase mode decays slowly (physics brief §4), to strong ones; a run both
ways costs a full run to max_t_end (~0.1 s each).
"""

import math

import numpy as np
import pytest
from conftest import KC_W, make_config, run_grid

from sweep.kernels import layout
from sweep.kernels.classify import linear, state
from sweep.kernels.classify.sequences import LINEAR_AMPLITUDE

A, B = 0.03, 0.08


def rate(kappa):
    """The linear growth rate (κc − κ)/(2A) near Kc (V/D0), physics brief §5."""
    return (B - A - kappa) / (2 * A)


def history(amplitudes, period=4.87, nb=1, rest=()):
    """A cycle history (as :func:`state.history_value` reads it) of a sinusoidal ℓ_i of
    peak-to-peak ``amplitudes[k]`` in cycle k (oldest first), every block alike except
    the blocks in ``rest`` (at rest), the in-phase amplitude the blocks' mean."""
    hist = np.zeros((state.n_observables(nb), state.HISTORY))
    for n, a in enumerate(amplitudes):
        slot = n % state.HISTORY
        moving = [i for i in range(nb) if i not in rest]
        for i in moving:
            hist[i, slot] = a / 2
            hist[nb + i, slot] = -a / 2
        hist[2 * nb, slot] = period
        hist[2 * nb + 1, slot] = a * len(moving) / nb
    return hist, len(amplitudes)


def envelope(lam, n=20, a0=0.03, period=4.87):
    return [a0 * math.exp(lam * period * k) for k in range(n)]


def verdict(hist, n, lam, t, horizon, nb=1):
    return linear.linear_verdict(hist, n, nb, lam, t, horizon, 1e-6)


def test_the_envelope_rate_is_the_slope_of_the_log_amplitude():
    lam = -3.3e-4
    hist, n = history(envelope(lam, n=40))
    slope, error = linear.envelope_rate(hist, 0, 1, n, linear.LINEAR_TERMS)
    assert slope == pytest.approx(lam, rel=1e-9)
    assert error < 1e-12


def test_a_decay_at_the_linear_rate_is_steady():
    lam = -4.2e-5
    hist, n = history(envelope(lam))
    assert verdict(hist, n, lam, 100.0, 30000.0) == layout.STEADY


def test_growth_at_the_linear_rate_is_undecided_only_if_it_stays_linear_to_the_horizon():
    """A growing envelope is undecided where, at the linear rate, it stays below the
    linear regime's amplitude up to the horizon; with a later horizon it would leave
    it (and might run away or find a cycle there): no verdict."""
    lam = 4.2e-5
    hist, n = history(envelope(lam))
    t = 100.0
    assert verdict(hist, n, lam, t, 20000.0) == layout.UNDECIDED
    beyond = t + math.log(LINEAR_AMPLITUDE / 0.03) / lam
    assert verdict(hist, n, lam, t, beyond) == -1
    assert verdict(hist, n, lam, t, 0.0) == -1  # horizon 0: no linear verdicts


def test_no_verdict_where_the_rate_is_not_the_linear_one():
    """An envelope 5 % off the linear rate, a bounded (constant) one, a beating one, or
    one beyond the linear regime is left to the other verdicts."""
    lam = 4.2e-5
    for amplitudes in (envelope(1.05 * lam), envelope(0.0), envelope(-lam),
                       [0.03 * (1 + 0.01 * math.sin(k)) for k in range(20)],
                       envelope(lam, a0=0.2)):  # fmt: skip
        hist, n = history(amplitudes)
        assert verdict(hist, n, lam, 100.0, 1000.0) == -1
        assert verdict(hist, n, -lam, 100.0, 1000.0) in (-1, layout.STEADY)
    hist, n = history(envelope(1.05 * lam))
    assert verdict(hist, n, -lam, 100.0, 1000.0) == -1


def test_too_few_cycles_give_no_verdict():
    lam = -4.2e-5
    hist, n = history(envelope(lam, n=linear.LINEAR_TERMS - 1))
    assert verdict(hist, n, lam, 100.0, 30000.0) == -1
    hist, n = history(envelope(lam, n=linear.LINEAR_TERMS))
    assert verdict(hist, n, lam, 100.0, 30000.0) == layout.STEADY


def test_every_block_must_follow_the_rate_but_a_block_at_rest_is_left_out():
    lam = -4.2e-5
    hist, n = history(envelope(lam), nb=2, rest=(1,))
    assert verdict(hist, n, lam, 100.0, 30000.0, nb=2) == layout.STEADY
    hist, n = history(envelope(lam), nb=2)
    hist[1, :n] = 0.015 * (1 + 0.01 * np.sin(np.arange(n)))  # block 1 beating
    assert verdict(hist, n, lam, 100.0, 30000.0, nb=2) == -1


# --- whole runs: the label of the full run, earlier ---------------------------------------

#: configs/twoblock.yaml's blocks, start and times (t_end 3000 D0/V, max_t_end 30000)
TWO_BLOCKS = {
    "blocks": 2,
    "parameters": {"k2_W": None},
    "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
    "integrator": {"t_end": 3000.0},
}
#: K/Kc − 1: the finest levels of configs/twoblock.yaml refined 8 levels lie within
#: ±5e-5 and ±1e-4 of Kc; 2e-4 leaves the linear regime before max_t_end (no verdict)
OFFSETS = [-2e-4, -5e-5, 5e-5, 1e-4]
#: k2/W (µm⁻¹): uncoupled (block 2 at rest), weak (the anti-phase mode decays at
#: κ2/A: beating for thousands of D0/V; bounded cycles below Kc at 0.0004–0.006 µm⁻¹,
#: further from it), and twoblock's grid step and 0.1
COUPLINGS = [0.0, 4e-4, 2e-3, 0.0133, 0.1]


@pytest.fixture(scope="module")
def both_ways():
    """Every (K, k2) run with linear verdicts (refinement's default) and as a grid runs
    it (refine.full_runs: true): ``(fast, full, t_end, max_t_end)``."""
    sweep = {"K_W": [KC_W * (1 + d) for d in OFFSETS], "k2_W": COUPLINGS}
    fast = make_config(TWO_BLOCKS, sweep=sweep, refine={"levels": 1})
    full = make_config(TWO_BLOCKS, sweep=sweep, refine={"levels": 1, "full_runs": True})
    (fast_res, _), (full_res, _) = run_grid(fast), run_grid(full)
    return fast_res, full_res, 3000.0, 30000.0


@pytest.mark.slow
def test_linear_verdicts_give_the_full_runs_labels(both_ways):
    fast, full, _, _ = both_ways
    for column in (layout.R_REGIME, layout.R_ATTRACTOR, layout.R_CYCLE_EVENTS):
        np.testing.assert_array_equal(fast[:, column], full[:, column])
    regimes = set(full[:, layout.R_REGIME].astype(int))
    assert regimes == {layout.STEADY, layout.UNDECIDED}


def test_linear_verdicts_end_the_runs_near_kc_early(both_ways):
    """Steady runs within 1e-4 of Kc and growing ones within 5e-5 stop long before the
    full run (which settles steady only after 7000–15000 D0/V, or goes on to max_t_end
    undecided) and say so (``R_LINEAR_VERDICT``), except the growing uncoupled one (block
    2 at rest leaves block 1 with twice the amplitude, which would leave the linear
    regime by max_t_end); runs at 2e-4 below Kc leave it and are the full runs."""
    fast, full, t_end, max_t_end = both_ways
    offsets = np.repeat(OFFSETS, len(COUPLINGS))
    k2 = np.tile(COUPLINGS, len(OFFSETS))
    t_fast, t_full = fast[:, layout.R_TAU_FINAL], full[:, layout.R_TAU_FINAL]
    strong = k2 > 0.0
    near = (np.abs(offsets) <= 5e-5) | (offsets > 0)
    assert (t_fast[strong & near] < 2000.0).all(), t_fast[strong & near]
    assert (t_full[strong & near] > 5000.0).all()
    assert (t_fast <= t_full).all()
    far = offsets == -2e-4  # leaves the linear regime before max_t_end: the full run
    assert (t_fast[far] == max_t_end).all()
    np.testing.assert_array_equal(fast[far], full[far])
    assert np.isnan(fast[near & strong, layout.R_LYAPUNOV]).all()
    stopped = t_fast < t_full
    assert (fast[:, layout.R_LINEAR_VERDICT] == stopped).all()
    assert (full[:, layout.R_LINEAR_VERDICT] == 0).all()
    assert stopped.sum() == 14  # all but the 5 far ones and the growing uncoupled one


def test_a_grid_sweep_has_no_linear_verdicts():
    config = make_config(TWO_BLOCKS, sweep={"K_W": [KC_W * (1 + 1e-4)], "k2_W": [0.1]},
                         integrator={"t_end": 300.0})  # fmt: skip
    from sweep.engine.grid import build_grid

    assert build_grid(config).settings[layout.S_LINEAR_VERDICTS] == 0.0
    refined = make_config(TWO_BLOCKS, sweep={"K_W": [0.04, 0.06], "k2_W": [0.1]},
                          refine={"levels": 1})  # fmt: skip
    assert build_grid(refined).settings[layout.S_LINEAR_VERDICTS] == 1.0
