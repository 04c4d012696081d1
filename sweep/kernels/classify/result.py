"""A run's statistics into its row of the results array (``layout.R_*`` columns, then
the event columns): the final window, the period and growth, the verdicts and λ1."""

import math

import numpy as np

from ...accelerate import jit, jit_inline
from ..layout import (
    CHAOTIC,
    LYAP_UNSETTLED,
    N_RESULTS,
    PERIODIC,
    QUASI_PERIODIC,
    R_ATTRACTOR,
    R_CONVERGENCE,
    R_CYCLE_EVENTS,
    R_FRICTION_DROP,
    R_GROWTH,
    R_LINEAR_VERDICT,
    R_LNV_MAX,
    R_LNV_MAX_RUN,
    R_LNV_MIN,
    R_LYAPUNOV,
    R_LYAPUNOV_ERROR,
    R_N_PEAKS,
    R_N_REJECTED,
    R_N_STEPS,
    R_PERIOD,
    R_PHASE_LAG,
    R_REGIME,
    R_SLIP_PARTICIPATION,
    R_SYNC_ERROR,
    R_SYNC_ORDER,
    R_TAU_FINAL,
    R_TAU_RUNAWAY,
    RUNAWAY,
    STEADY,
    TANGENT_NEEDED,
    UNBOUNDED,
)
from ..tangent import lyapunov_estimate
from .state import (
    C_CONV,
    C_EVENTS,
    C_GROWTH,
    C_LAST_ORDER,
    C_LAST_PHASE,
    C_LINEAR,
    C_LNV_MAX_RUN,
    C_N_CYCLES,
    C_N_PEAKS,
    C_PERIOD,
    C_SLIP_EVENTS,
    C_SLIP_SUM,
    C_VERDICT,
    C_WIN_SYNC,
    HISTORY,
    W_LMAX,
    W_LMIN,
    W_MUMAX,
    W_MUMIN,
    X_SLIP_EVENTS,
    X_SLIP_SUM,
    X_SYNC,
    history_value,
    verdict_held,
)
from .verdicts import final_regime


@jit
def window_cycles(attractor, cs, use_last):
    """Completed cycles the reported extremes span: the n events of a periodic run's
    cycle, every kept cycle of chaotic or quasi-periodic motion, else the last one
    (0: the cycle in progress, where no cycle was completed or the run ran away)."""
    if not use_last:
        return 0
    if attractor == PERIODIC:
        return int(cs[C_EVENTS])
    if attractor == CHAOTIC or attractor == QUASI_PERIODIC:
        return min(int(cs[C_N_CYCLES]), HISTORY)
    return 1


@jit
def write_events(result, hist, nb, n_cycles, n_events, cycle):
    """The last ``n_events`` events' maxima of ℓ_0 and intervals (D0/V) into the columns
    after the ``R_*`` ones, oldest first, NaN where the run had fewer; of a periodic run
    (``cycle`` > 0 events per cycle) only its settled cycle's, the earlier ones being a
    transient an orbit diagram must not show. A ``result`` row narrower than
    ``layout.result_width`` gets none (numba checks no bounds)."""
    if result.size < N_RESULTS + 2 * n_events:
        return
    kept = min(n_cycles, cycle) if cycle > 0 else n_cycles
    for e in range(n_events):
        back = n_events - 1 - e
        peak = np.nan
        interval = np.nan
        if back < kept:
            peak = history_value(hist, 0, n_cycles, back)
            interval = history_value(hist, 2 * nb, n_cycles, back)
        result[N_RESULTS + e] = peak
        result[N_RESULTS + n_events + e] = interval


@jit
def write_result(
    result,
    regime,
    attractor,
    t,
    n_steps,
    n_rejected,
    tau_runaway,
    nb,
    win,
    past,
    past_cs,
    hist,
    cs,
    lam,
    lam_err,
    n_events,
):
    """The run's statistics into ``result`` (``R_*`` columns, then the event columns).

    The final window (extremes, friction drop, synchronisation, slip participation)
    spans :func:`window_cycles`; a periodic run's period is the sum of its cycle's
    intervals and its growth rate compares amplitudes one cycle apart.
    """
    use_last = cs[C_N_PEAKS] >= 2 and regime != RUNAWAY
    span = window_cycles(attractor, cs, use_last)
    n_cycles = int(cs[C_N_CYCLES])
    lmax = -np.inf
    lmin = np.inf
    fdrop = 0.0
    sync = 0.0
    slip_sum = 0.0
    slip_events = 0.0
    if span == 0:
        for i in range(nb):
            lmax = max(lmax, win[W_LMAX, i])
            lmin = min(lmin, win[W_LMIN, i])
            fdrop = max(fdrop, win[W_MUMAX, i] - win[W_MUMIN, i])
        sync = cs[C_WIN_SYNC]
        slip_sum = cs[C_SLIP_SUM]
        slip_events = cs[C_SLIP_EVENTS]
    for back in range(span):
        slot = (n_cycles - 1 - back) % HISTORY
        for i in range(nb):
            lmax = max(lmax, past[slot, W_LMAX, i])
            lmin = min(lmin, past[slot, W_LMIN, i])
            fdrop = max(fdrop, past[slot, W_MUMAX, i] - past[slot, W_MUMIN, i])
        sync = max(sync, past_cs[slot, X_SYNC])
        slip_sum += past_cs[slot, X_SLIP_SUM]
        slip_events += past_cs[slot, X_SLIP_EVENTS]
    period = cs[C_PERIOD]
    growth = cs[C_GROWTH]
    events = int(cs[C_EVENTS]) if attractor == PERIODIC else 0
    if events > 1:
        period = 0.0
        for back in range(events):
            period += history_value(hist, 2 * nb, n_cycles, back)
        amp = history_value(hist, 0, n_cycles, 0) - history_value(hist, nb, n_cycles, 0)
        amp_before = history_value(hist, 0, n_cycles, events) - history_value(
            hist, nb, n_cycles, events
        )
        growth = math.log(amp / amp_before) / period
    result[R_REGIME] = regime
    result[R_TAU_FINAL] = t
    result[R_N_STEPS] = n_steps
    result[R_N_REJECTED] = n_rejected
    result[R_LNV_MAX] = lmax
    result[R_LNV_MIN] = lmin
    result[R_PERIOD] = period
    result[R_GROWTH] = growth
    result[R_FRICTION_DROP] = fdrop
    result[R_TAU_RUNAWAY] = tau_runaway
    result[R_SYNC_ERROR] = sync if nb > 1 else np.nan
    result[R_PHASE_LAG] = cs[C_LAST_PHASE]
    result[R_N_PEAKS] = cs[C_N_PEAKS]
    result[R_LNV_MAX_RUN] = cs[C_LNV_MAX_RUN]
    steady_or_runaway = regime == STEADY or regime == RUNAWAY
    result[R_CONVERGENCE] = np.nan if steady_or_runaway else cs[C_CONV]
    result[R_SYNC_ORDER] = cs[C_LAST_ORDER] if use_last else np.nan
    result[R_SLIP_PARTICIPATION] = slip_sum / slip_events if slip_events > 0 else np.nan
    result[R_ATTRACTOR] = attractor
    result[R_CYCLE_EVENTS] = events
    result[R_LYAPUNOV] = lam
    result[R_LYAPUNOV_ERROR] = lam_err
    by_verdict = verdict_held(cs, 1) and regime == int(cs[C_VERDICT])
    result[R_LINEAR_VERDICT] = 1.0 if by_verdict and cs[C_LINEAR] > 0.0 else 0.0
    write_events(result, hist, nb, n_cycles, n_events, events)


@jit_inline
def finish_run(
    result,
    regime,
    t,
    tau_stop,
    y,
    n_steps,
    n_rejected,
    tau_runaway,
    nb,
    win,
    past,
    past_cs,
    hist,
    limits,
    cs,
    steady_amp,
    lin_growth,
    accuracy,
    rtol,
    atol,
    ly,
    lyap,
    n_events,
    needs_tangent,
):
    """The verdicts of a run stopped at ``t`` (:func:`verdicts.final_regime`; ``regime``
    the one settled in the loop, −1 if none) and its statistics into ``result``
    (:func:`write_result`), λ1 from the tangent's accumulator ``ly``. λ1 is not reported
    for a run that ran away, nor, with ``lyap`` = LYAP_UNSETTLED, for one the cycle
    classifier settled: it would be a transient's. A run the kernel with the tangent
    must redo (``needs_tangent``) is marked ``TANGENT_NEEDED``. Inlined into the grid
    kernel after the run: a thin wrapper (accelerate.py)."""
    lam, lam_err, span = lyapunov_estimate(ly)
    by_cycles = regime >= 0 or cs[C_VERDICT] >= 0  # settled by the cycle classifier
    regime, attractor = final_regime(
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
    )
    if attractor == UNBOUNDED or (by_cycles and lyap == LYAP_UNSETTLED):
        lam, lam_err = np.nan, np.nan
    write_result(
        result,
        regime,
        attractor,
        t,
        n_steps,
        n_rejected,
        tau_runaway,
        nb,
        win,
        past,
        past_cs,
        hist,
        cs,
        lam,
        lam_err,
        n_events,
    )
    if needs_tangent:
        result[R_REGIME] = TANGENT_NEEDED
