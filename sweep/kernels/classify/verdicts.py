"""The verdicts at the end of a run: its regime and what it settled on (its attractor),
from the last cycle's verdict, the history of its cycles and λ1."""

import numpy as np

from ...accelerate import jit, jit_forceinline
from ..layout import (
    CHAOTIC,
    FIXED_POINT,
    PERIODIC,
    QUASI_PERIODIC,
    RUNAWAY,
    STEADY,
    STICK_SLIP,
    UNBOUNDED,
    UNDECIDED,
    UNRESOLVED,
)
from .sequences import (
    LINEAR_AMPLITUDE,
    SEARCH_FACTOR,
    envelope_turns,
    simple_cycle_within_spread,
    span_ptp,
)
from .state import C_CONV, C_EVENTS, C_N_CYCLES, C_VERDICT, HISTORY, verdict_held

#: λ1 counts as positive (chaos) only beyond this many standard errors …
LYAP_SIGMAS = 3.0
#: … and when the tangent grew by more than e^LYAP_MIN_GROWTH over the fit (λ1 × span):
#: a bounded oscillation of log |δ| on a cycle or torus (a few units) is not growth.
LYAP_MIN_GROWTH = 10.0


@jit
def max_abs(y):
    """Largest |y_j|."""
    big = 0.0
    for j in range(y.size):
        big = max(big, abs(y[j]))
    return big


@jit
def collapse_regime(y, nb, t):
    """``(regime, tau_runaway)`` of a run whose step size collapsed below 1e-300 D0/V at
    ``t``.

    With any finite slope a small enough step passes the error test, so the slope
    overflows. With a block slipping faster than the load point this is the
    finite-time blow-up of v (runaway at ``t``); otherwise the solver failed
    (undecided, NaN). Steps below the resolution of t are legitimate: an inertial block
    arresting after a fast slip lands on ℓ ~ −30 within ~1e-20 D0/V
    (test_models.py::test_inertial_arrest_is_resolved).
    """
    regime = UNDECIDED
    for i in range(nb):
        if y[i] > 0.0:
            regime = RUNAWAY
    return regime, (t if regime == RUNAWAY else np.nan)


@jit_forceinline
def settled_early(new_peak, cs, n_confirm, y, lin_growth, steady_amp):
    """The regime a run settled on after a step (−1: none yet): at an event
    (``new_peak``), the last cycle's verdict once it has held for ``n_confirm`` whole
    cycles; steady once the state has decayed below ``steady_amp`` onto a linearly
    stable steady state (``lin_growth`` < 0)."""
    if new_peak and verdict_held(cs, n_confirm):
        return int(cs[C_VERDICT])
    if lin_growth < 0.0 and max_abs(y) < steady_amp:
        return STEADY
    return -1


@jit
def attractor_verdict(lam, lam_err, span, conv, accuracy, ptp, turns):
    """What an unsettled run at its end time is, from λ1 (``lam`` ± ``lam_err`` over
    ``span``, V/D0 and D0/V), if it oscillates beyond the linear regime (``ptp``, the
    peak-to-peak ℓ of its kept cycles, at least ``LINEAR_AMPLITUDE``: a run resting on
    an unstable fixed point, an uncoupled block started exactly on it, has λ1 > 0 but
    no oscillation) within a bounded envelope (one that turns at least twice over the
    kept cycles, ``turns``: :func:`cycles.envelope_turns`; a spiral growing towards a
    runaway just below Kc has a small λ1 and no recurrence, and is no attractor):
    CHAOTIC where λ1 is positive beyond its error and the growth is real (``LYAP_*``);
    QUASI_PERIODIC where λ1 is consistent with zero and the event sequence is not
    closing in on any cycle of up to ``MAX_CYCLE_EVENTS`` events (its best
    convergence ``conv`` is not within ``SEARCH_FACTOR`` × ``accuracy``); else
    UNRESOLVED (a drifting envelope; λ1 negative: still contracting onto a cycle or
    steady sliding; or no estimate)."""
    if not (lam == lam and lam_err == lam_err and ptp >= LINEAR_AMPLITUDE and turns >= 2):
        return UNRESOLVED
    if lam > LYAP_SIGMAS * lam_err and lam * span > LYAP_MIN_GROWTH:
        return CHAOTIC
    zero = abs(lam) <= LYAP_SIGMAS * lam_err or abs(lam) * span <= LYAP_MIN_GROWTH
    if zero and not (conv <= SEARCH_FACTOR * accuracy):
        return QUASI_PERIODIC
    return UNRESOLVED


@jit
def final_regime(
    regime,
    t,
    tau_stop,
    y,
    cs,
    hist,
    limits,
    nb,
    steady_amp,
    lin_growth,
    accuracy,
    rtol,
    atol,
    lam,
    lam_err,
    span,
):
    """``(regime, attractor)`` of a run at its end.

    A regime settled in the loop stands (stick-slip there is a cycle: PERIODIC).
    Otherwise: undecided when the step budget ran out; else the last cycle's verdict
    (a cycle of n events once it has held for n events: each residue class confirmed);
    steady when it decayed onto a linearly stable steady state, or when its last cycle
    is within the linear regime (peak-to-peak ℓ below ``LINEAR_AMPLITUDE``) and λ1 is
    negative beyond its error (a slow decay, e.g. 0.2 % above Kc); a simple cycle known
    to within ``accuracy`` by the spread of its last cycles
    (:func:`simple_cycle_within_spread`); else bounded motion that is chaotic or
    quasi-periodic by λ1 is stick-slip (:func:`attractor_verdict`), and anything
    else undecided.
    """
    if regime < 0:
        if t < tau_stop:  # step budget exhausted
            return UNDECIDED, UNRESOLVED
        if verdict_held(cs, 1):
            regime = int(cs[C_VERDICT])
        elif max_abs(y) < steady_amp and lin_growth < 0.0:
            regime = STEADY
        elif (
            lin_growth < 0.0
            and lam < -LYAP_SIGMAS * lam_err
            and (span_ptp(hist, int(cs[C_N_CYCLES]), nb, 1) < LINEAR_AMPLITUDE)
        ):
            regime = STEADY  # a small oscillation contracting at a stable fixed point's rate
        else:
            n_cycles = int(cs[C_N_CYCLES])
            conv = simple_cycle_within_spread(hist, n_cycles, nb, accuracy, rtol, atol, limits)
            if conv <= accuracy:
                cs[C_CONV] = conv
                cs[C_EVENTS] = 1
                return STICK_SLIP, PERIODIC
            kept = min(n_cycles, HISTORY)
            ptp = span_ptp(hist, n_cycles, nb, kept)
            turns = envelope_turns(hist, n_cycles, nb, kept)
            kind = attractor_verdict(lam, lam_err, span, cs[C_CONV], accuracy, ptp, turns)
            if kind == UNRESOLVED:
                return UNDECIDED, UNRESOLVED
            return STICK_SLIP, kind
    if regime == STEADY:
        return regime, FIXED_POINT
    if regime == STICK_SLIP:
        return regime, PERIODIC
    if regime == RUNAWAY:
        return regime, UNBOUNDED
    return regime, UNRESOLVED
