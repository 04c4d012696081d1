"""The grid kernel: the integration loop of every system, one after another.

``grid_kernel`` builds one serial kernel per variant (model, state law, method,
coupling, equal or unequal blocks); its loop steps each system, folds every step
into the cycle classifier (and, where asked, the tangent for λ1) and writes its
statistics with the helpers here.
"""

import functools
import math

import numpy as np

from ..accelerate import jit, jit_inline
from .cycles import (
    C_CONV,
    C_EVENTS,
    C_GROWTH,
    C_IN_EVENT,
    C_LAST_ORDER,
    C_LAST_PHASE,
    C_LNV_MAX_RUN,
    C_N_CYCLES,
    C_N_PEAKS,
    C_PEAK_VALUE,
    C_PERIOD,
    C_SLIP_EVENTS,
    C_SLIP_SUM,
    C_SLIPPING,
    C_T_PEAK,
    C_VERDICT,
    C_WIN_MBAR_MAX,
    C_WIN_MBAR_MIN,
    C_WIN_SYNC,
    HISTORY,
    LINEAR_AMPLITUDE,
    SEARCH_FACTOR,
    W_LMAX,
    W_LMIN,
    W_MUMAX,
    W_MUMIN,
    X_SLIP_EVENTS,
    X_SLIP_SUM,
    X_SYNC,
    close_cycle,
    cycle_arrays,
    dense_needed,
    end_slip_event,
    envelope_turns,
    event_section,
    history_value,
    mean_extremum_matters,
    simple_cycle_within_spread,
    span_ptp,
    start_cycle,
    update_cycle,
    verdict_held,
)
from .equations import rhs
from .layout import (
    CHAOTIC,
    DOP853,
    DOPRI5,
    FIXED_POINT,
    LYAP_ALWAYS,
    LYAP_UNSETTLED,
    N_RESULTS,
    NO_RUNAWAY,
    NOT_FINITE,
    P_A,
    P_B,
    P_DT,
    P_LIN_GROWTH,
    P_MAX_STEP,
    P_TAU_END,
    P_TAU_MAX,
    PERIODIC,
    QUASI_PERIODIC,
    R_ATTRACTOR,
    R_CONVERGENCE,
    R_CYCLE_EVENTS,
    R_FRICTION_DROP,
    R_GROWTH,
    R_LNV_MAX,
    R_LNV_MAX_RUN,
    R_LNV_MIN,
    R_LYAPUNOV,
    R_LYAPUNOV_ERROR,
    R_N_PEAKS,
    R_N_RECORDED,
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
    RK4,
    ROSENBROCK,
    RUNAWAY,
    S_ACCURACY,
    S_ATOL,
    S_CONFIRM_CYCLES,
    S_EARLY_EXIT,
    S_EVENTS,
    S_LNV_CAP,
    S_LYAPUNOV,
    S_MAX_STEPS,
    S_NBLOCKS,
    S_RTOL,
    S_SLIP_LNV,
    S_STEADY_AMP,
    STEADY,
    STICK_SLIP,
    TANGENT_NEEDED,
    UNBOUNDED,
    UNDECIDED,
    UNRESOLVED,
    values_per_block,
)
from .stack import stack_matrix, stack_vector
from .steppers import (
    ROS_STAGE_ROWS,
    STAGE_ROWS,
    STAGE_ROWS_DOP853,
    dense_crossing,
    dense_dop853,
    dense_extremum,
    dense_tail,
    dense_value,
    next_step_size,
    rosenbrock_scratch,
    step_dop853,
    step_dopri5,
    step_rk4,
    step_rosenbrock,
    step_scratch,
)
from .tangent import (
    L_ON,
    L_RATE,
    LYAP_BLOCKS,
    TANGENT_STAGE_ROWS,
    TANGENT_STAGE_ROWS_DOP853,
    TANGENT_TURN,
    TANGENT_WORK_ROWS,
    lyapunov_add,
    lyapunov_estimate,
    lyapunov_start,
    tangent_arrays,
    tangent_step,
)


@jit
def max_abs(y):
    """Largest |y_j|."""
    big = 0.0
    for j in range(y.size):
        big = max(big, abs(y[j]))
    return big


@jit
def collapse_regime(y, nb):
    """Regime of a run whose step size collapsed below 1e-300 D0/V.

    With any finite slope a small enough step passes the error test, so the slope
    overflows. With a block slipping faster than the load point this is the
    finite-time blow-up of v (runaway); otherwise the solver failed (undecided).
    Steps below the resolution of t are legitimate: an inertial block arresting
    after a fast slip lands on ℓ ~ −30 within ~1e-20 D0/V
    (test_models.py::test_inertial_arrest_is_resolved).
    """
    regime = UNDECIDED
    for i in range(nb):
        if y[i] > 0.0:
            regime = RUNAWAY
    return regime


@jit_inline
def runaway_index(ynew, fnew, nb, lnv_cap):
    """Whether the state after a step ran away: NOT_FINITE when a state or slope is
    not finite, else the first block whose ℓ_i exceeds ``lnv_cap``, else NO_RUNAWAY."""
    out = NO_RUNAWAY
    for i in range(nb):
        if ynew[i] > lnv_cap and out < 0:
            out = i
    for j in range(ynew.size):  # no branch around these loops: accelerate.py
        if not (math.isfinite(ynew[j]) and math.isfinite(fnew[j])):
            out = NOT_FINITE
    return out


@jit
def record_step(method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, rec_dt, rec_t, rec_y, n_rec):
    """Record the state at the multiples of ``rec_dt`` inside the step (dense output)
    while the buffers have room (the last slot is kept for the end). Returns the count."""
    rec_cap = rec_t.size
    while n_rec < rec_cap - 1 and n_rec * rec_dt <= t + h and rec_dt > 0.0:
        theta = (n_rec * rec_dt - t) / h
        rec_t[n_rec] = n_rec * rec_dt
        for j in range(y.size):
            r = dense_tail(method, j, h, f, k3, k4, k5, k6, fnew, dense)
            rec_y[n_rec, j] = dense_value(y[j], ynew[j], f[j], fnew[j], h, r, theta)
        n_rec += 1
    return n_rec


@jit
def record_start(y, rec_t, rec_y):
    """Record the initial state when there are buffers; returns the count."""
    if rec_t.size == 0:
        return 0
    rec_t[0] = 0.0
    for j in range(y.size):
        rec_y[0, j] = y[j]
    return 1


@jit
def record_end(t, y, rec_t, rec_y, n_rec):
    """Record the final state when the buffers have room; returns the count."""
    if 0 < n_rec < rec_t.size and rec_t[n_rec - 1] < t:
        rec_t[n_rec] = t
        for j in range(y.size):
            rec_y[n_rec, j] = y[j]
        n_rec += 1
    return n_rec


@jit
def cap_crossing(method, i, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, nb, lnv_cap, win, cs):
    """End a run whose block ``i`` crossed ``lnv_cap`` in the step from ``t`` to
    ``t + h``: keep the step (``y`` becomes ``ynew``, the extremes include it) and
    return the time of the crossing (D0/V, interpolated)."""
    r = dense_tail(method, i, h, f, k3, k4, k5, k6, fnew, dense)
    theta = dense_crossing(y[i], ynew[i], f[i], fnew[i], h, r, lnv_cap)
    tau = t + (0.0 if y[i] > lnv_cap else theta) * h
    for j in range(nb):
        win[W_LMAX, j] = max(win[W_LMAX, j], ynew[j])
    cs[C_LNV_MAX_RUN] = max(cs[C_LNV_MAX_RUN], lnv_cap)
    for j in range(y.size):
        y[j] = ynew[j]
    return tau


#: λ1 counts as positive (chaos) only beyond this many standard errors …
LYAP_SIGMAS = 3.0
#: … and when the tangent grew by more than e^LYAP_MIN_GROWTH over the fit (λ1 × span):
#: a bounded oscillation of log |δ| on a cycle or torus (a few units) is not growth.
LYAP_MIN_GROWTH = 10.0


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
    regime, t, tau_stop, y, cs, hist, limits, nb, steady_amp, lin_growth, accuracy, rtol, atol,
    lam, lam_err, span,
):  # fmt: skip
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
    result, regime, attractor, t, n_steps, n_rejected, tau_runaway, nb, win, past, past_cs, hist,
    cs, lam, lam_err, n_events,
):  # fmt: skip
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
    write_events(result, hist, nb, n_cycles, n_events, events)


@jit_inline
def read_settings(settings):
    """The settings array (``S_*``) as typed values: blocks, rtol, atol, step budget,
    ln of the velocity cap, steady amplitude, accuracy, cycles to confirm (≥ 1),
    early exit (bool), ln of the slip threshold, when λ1 is computed (``LYAP_*``) and
    the number of events reported."""
    nb = int(settings[S_NBLOCKS])
    rtol = settings[S_RTOL]
    atol = settings[S_ATOL]
    max_steps = settings[S_MAX_STEPS]
    lnv_cap = settings[S_LNV_CAP]
    steady_amp = settings[S_STEADY_AMP]
    accuracy = settings[S_ACCURACY]
    n_confirm = max(1, int(settings[S_CONFIRM_CYCLES]))
    early_exit = settings[S_EARLY_EXIT] > 0.5
    slip_lnv = settings[S_SLIP_LNV]
    lyap = int(settings[S_LYAPUNOV])
    n_events = int(settings[S_EVENTS])
    return (
        nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit, slip_lnv,
        lyap, n_events,
    )  # fmt: skip


@functools.cache
def grid_kernel(model, law, method, coupling, het, tangent, n_fixed=0):
    """The serial grid kernel of one variant: model, state law, method and coupling
    codes (int), whether blocks differ (``het``, bool), whether it carries the
    tangent for λ1 (``tangent``, bool) and the state size it is compiled for
    (``n_fixed``, values per system; 0: any).

    With a fixed size, the state, the stages and the other scratch of the step are
    arrays of that size on the stack (``stack.py``), which LLVM keeps in registers:
    1.1–1.4× faster per step for one and two blocks, the same numbers bit for bit
    (``docs/performance.md``). Otherwise they are numba arrays on the heap.

    ``integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y)``
    integrates every row one after another: the system with parameters ``params[s]``
    (``P_*``) from ``y0[s]``; its statistics go to ``results[s]`` (``R_*``), its final
    state to ``y_final[s]``. Traces pass one row and buffers for the state every
    ``rec_dt`` (D0/V, interpolated) and at the end, ``rec_t``/``rec_y``, written while
    they have room (sweeps pass empty buffers); the count is ``R_N_RECORDED``.

    The tangent for λ1 (``tangent.py``) is carried from ``tau_end`` on by runs not
    settled by then (``LYAP_UNSETTLED``), or over the whole run (``LYAP_ALWAYS``,
    which then settles no run before ``tau_end``). A kernel compiled without it stops
    such a run where the tangent would start and marks it ``TANGENT_NEEDED`` for the
    kernel with it to redo from the start: no step before the tangent starts depends
    on it, so the redone run is the same run, number for number, up to where the
    other kernel stopped it.

    Built and compiled on first use, one per variant. The codes are constants of the
    closure, so numba prunes the other variants' branches before it inlines the
    helpers: the other methods' steppers are never compiled. The loop is written
    here, not in an inlined function of its own: numba copies an inlined body once
    per basic block with its whole scope, which took 10 of a 27 s compile. The
    helpers are still prepared for inlining with every branch (their codes are
    arguments), which is why the Runge–Kutta stages are loops around one call of
    :func:`rhs`.

    Cached on disk like the helpers it calls (``accelerate.SourceKeyedCache``: keyed
    on every kernel source, safe to share between processes). Each variant's function
    is named after its codes, so its cache files are its own.
    """

    # the shapes of step_scratch, rosenbrock_scratch and tangent_arrays, for size n_fixed
    nb_fixed = n_fixed // values_per_block(model)
    k_rows = STAGE_ROWS_DOP853 if method == DOP853 else STAGE_ROWS
    dense_width = n_fixed if method == DOP853 else 0
    ros_rows, ros_n = (ROS_STAGE_ROWS, n_fixed) if method == ROSENBROCK else (0, 0)
    dk_rows = TANGENT_STAGE_ROWS_DOP853 if method == DOP853 else TANGENT_STAGE_ROWS

    def integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y):
        if n_fixed > 0 and y0.shape[0] > 0 and y0.shape[1] != n_fixed:
            raise ValueError("the state size differs from the one this kernel is compiled for")
        # a constant for LLVM, typed int64 for numba: helpers taking n or nb are compiled
        # once, not once per size
        n = np.int64(n_fixed) if n_fixed > 0 else y0.shape[1]
        for s in range(params.shape[0]):  # the settings are read per system: hoisted out
            # of this loop they made every step 3 % slower (make bench)
            (
                nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit,
                slip_lnv, lyap, n_events,
            ) = read_settings(settings)  # fmt: skip
            p = params[s]
            result = results[s]
            A = p[P_A]
            B = p[P_B]
            tau_end = p[P_TAU_END]
            # unsettled runs go on past tau_end only with early exit (else: fixed-length runs)
            tau_max = max(p[P_TAU_MAX], tau_end) if early_exit else tau_end
            lin_growth = p[P_LIN_GROWTH]
            max_step = p[P_MAX_STEP]

            if n_fixed > 0:  # a small system: scratch on the stack (kernels/stack.py)
                nb = np.int64(nb_fixed)
                y = stack_vector(n_fixed)
                f = stack_vector(n_fixed)
                ynew = stack_vector(n_fixed)
                fnew = stack_vector(n_fixed)
                ytmp = stack_vector(n_fixed)
                k = stack_matrix(k_rows, n_fixed)
                dense = stack_matrix(4, dense_width)
                dense[:, :] = 0.0
                ev = stack_vector(nb_fixed)
                for j in range(n):
                    y[j] = y0[s, j]
            else:
                y = y0[s].copy()
                f, ynew, fnew, ytmp, k, dense = step_scratch(method, n)
                ev = np.empty(nb)
            k3, k4, k5, k6 = k[1], k[2], k[3], k[4]  # the stages DOPRI5's dense output needs
            if n_fixed > 0:  # RODAS4's stages and matrix (empty for the other methods)
                k_ros = stack_matrix(ros_rows, n_fixed)
                mat = stack_matrix(ros_n, ros_n)
                perm = np.empty(ros_n, np.int64)
            else:
                k_ros, mat, perm = rosenbrock_scratch(method, n)
            win, past, past_cs, hist, limits, section, cs, slipped, turns = cycle_arrays(
                y, p, nb, A, B
            )
            # the tangent's scratch (empty without it) and its accumulator
            t_n = n if tangent and n_fixed == 0 else 0
            delta, work, dk, t_blocks, ly = tangent_arrays(method, t_n, nb if t_n else 0)
            if n_fixed > 0 and tangent:
                delta = stack_vector(n_fixed)
                work = stack_matrix(TANGENT_WORK_ROWS, n_fixed)
                dk = stack_matrix(dk_rows, n_fixed)
                t_blocks = stack_matrix(3, nb_fixed)
            needs_tangent = False
            if lyap == LYAP_ALWAYS:
                if tangent:
                    lyapunov_start(ly, delta, 0.0, tau_end / LYAP_BLOCKS)
                else:
                    needs_tangent = True
                    tau_max = 0.0  # no step: the kernel with the tangent runs it
            # no run is settled before tau_end while λ1 is measured over whole runs
            t_settle = tau_end if lyap == LYAP_ALWAYS else 0.0

            n_rec = record_start(y, rec_t, rec_y)

            rhs(y, p, model, law, coupling, het, nb, ev, f)
            t = 0.0
            h = p[P_DT] if method == RK4 else min(1e-3, max_step, tau_end)
            n_steps = 0
            n_rejected = 0
            regime = -1
            tau_runaway = np.nan
            # unsettled at tau_end: go on (settling early from then on) up to tau_max
            tau_stop = tau_end
            while t < tau_max:
                if t >= tau_stop:
                    tau_stop = tau_max
                    if verdict_held(cs, 1):  # a verdict that held over one whole cycle of events
                        regime = int(cs[C_VERDICT])
                        break
                    if lyap == LYAP_UNSETTLED and tau_max > t:
                        if not tangent:
                            needs_tangent = True
                            break
                        lyapunov_start(ly, delta, t, (tau_max - t) / LYAP_BLOCKS)
                if n_steps + n_rejected >= max_steps:
                    break
                h = min(h, tau_stop - t)
                if tangent:
                    if (method == DOPRI5 or method == DOP853) and ly[L_RATE] > 0.0:  # TANGENT_TURN
                        h = min(h, TANGENT_TURN / ly[L_RATE])
                err = 0.0  # RK4: every step is accepted
                if method == DOPRI5:
                    err = step_dopri5(
                        y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp,
                        ynew, fnew, rtol, atol,
                    )  # fmt: skip
                elif method == DOP853:
                    err = step_dop853(
                        y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp,
                        ynew, fnew, rtol, atol,
                    )  # fmt: skip
                elif method == ROSENBROCK:
                    err = step_rosenbrock(
                        y, f, h, p, model, law, coupling, het, nb, ev, k_ros, mat, perm, ytmp, ynew,
                        fnew, rtol, atol,
                    )  # fmt: skip
                else:
                    step_rk4(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew)
                    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
                h_next = next_step_size(method, h, err, max_step)
                if not (err <= 1.0):
                    n_rejected += 1
                    h = h_next
                    if h < 1e-300:
                        regime = collapse_regime(y, nb)
                        tau_runaway = t if regime == RUNAWAY else np.nan
                        break
                    continue
                n_steps += 1

                crossed = runaway_index(ynew, fnew, nb, lnv_cap)
                if crossed != NO_RUNAWAY:
                    regime = RUNAWAY
                    tau_runaway = t + h
                    if crossed >= 0:  # the step is kept: the run ends after it
                        if method == DOP853:
                            dense_dop853(
                                y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense
                            )
                        tau_runaway = cap_crossing(
                            method, crossed, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, nb,
                            lnv_cap, win, cs,
                        )  # fmt: skip
                        t += h
                    break

                if tangent:
                    if ly[L_ON] > 0.0:
                        growth, rate = tangent_step(
                            y, f, h, k, k_ros, mat, perm, delta, work, dk, t_blocks, p, nb, ev,
                            model, law, method, coupling, het,
                        )  # fmt: skip
                        ly[L_RATE] = rate
                        lyapunov_add(ly, t + h, h, growth)

                if method == DOP853:  # its interpolant costs three stages: only where it is read
                    if n_rec > 0 or dense_needed(
                        h, y, ynew, f, fnew, p, nb, A, B, turns, rtol, atol
                    ):
                        dense_dop853(
                            y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense
                        )
                new_peak, theta_peak = update_cycle(
                    method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, p, nb, A, B, win, cs,
                    slipped, slip_lnv, turns, rtol, atol,
                )  # fmt: skip
                if new_peak and nb > 1:
                    event_section(
                        method, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, nb, theta_peak, section
                    )
                if cs[C_SLIPPING] > 0.0:
                    cs[C_IN_EVENT] = 1.0
                elif cs[C_IN_EVENT] > 0.0:
                    end_slip_event(nb, slipped, cs)
                if nb > 1:  # extremes of the mean ℓ, written out here (see accelerate.py: an
                    # inlined helper with a branch around its loops refcounts every step)
                    m0 = 0.0
                    m1 = 0.0
                    dm0 = 0.0
                    dm1 = 0.0
                    for i in range(nb):
                        m0 += y[i] / nb
                        m1 += ynew[i] / nb
                        dm0 += f[i] / nb
                        dm1 += fnew[i] / nb
                    if (dm0 > 0.0) == (dm1 <= 0.0):
                        r5 = 0.0
                        r6 = 0.0
                        r7 = 0.0
                        r8 = 0.0
                        for i in range(nb):
                            r = dense_tail(method, i, h, f, k3, k4, k5, k6, fnew, dense)
                            r5 += r[0] / nb
                            r6 += r[1] / nb
                            r7 += r[2] / nb
                            r8 += r[3] / nb
                        if mean_extremum_matters(method, m0, m1, dm0, dm1, h, r5, rtol, atol):
                            theta = dense_extremum(m0, m1, dm0, dm1, h, (r5, r6, r7, r8))
                            val = dense_value(m0, m1, dm0, dm1, h, (r5, r6, r7, r8), theta)
                            cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], val)
                            cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], val)
                    cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], m1)
                    cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], m1)
                if n_rec > 0:
                    n_rec = record_step(
                        method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, rec_dt,
                        rec_t, rec_y, n_rec,
                    )  # fmt: skip
                t_new_peak = t + theta_peak * h
                t += h
                for j in range(n):
                    y[j] = ynew[j]
                    f[j] = fnew[j]
                h = h_next

                if new_peak:
                    cs[C_N_PEAKS] += 1
                    if cs[C_N_PEAKS] >= 2:
                        close_cycle(
                            t_new_peak, nb, win, past, past_cs, hist, limits, section, cs, accuracy,
                            steady_amp, lin_growth, rtol, atol,
                        )  # fmt: skip
                    cs[C_T_PEAK] = t_new_peak
                    # the new cycle starts at this peak
                    start_cycle(y, p, nb, A, B, win, cs)
                    win[W_LMAX, 0] = max(win[W_LMAX, 0], cs[C_PEAK_VALUE])
                    if early_exit and verdict_held(cs, n_confirm) and t >= t_settle:
                        regime = int(cs[C_VERDICT])
                        break

                # decayed onto a linearly stable steady state
                if early_exit and lin_growth < 0.0 and max_abs(y) < steady_amp and t >= t_settle:
                    regime = STEADY
                    break

            lam, lam_err, span = lyapunov_estimate(ly)
            by_cycles = regime >= 0 or cs[C_VERDICT] >= 0  # settled by the cycle classifier
            regime, attractor = final_regime(
                regime, t, tau_stop, y, cs, hist, limits, nb, steady_amp, lin_growth, accuracy,
                rtol, atol, lam, lam_err, span,
            )  # fmt: skip
            if attractor == UNBOUNDED or (by_cycles and lyap == LYAP_UNSETTLED):
                # λ1 of the part of the run before a runaway or before it settled: a transient's
                lam, lam_err = np.nan, np.nan
            write_result(
                result, regime, attractor, t, n_steps, n_rejected, tau_runaway, nb, win, past,
                past_cs, hist, cs, lam, lam_err, n_events,
            )  # fmt: skip
            for j in range(n):
                y_final[s, j] = y[j]
            result[R_N_RECORDED] = record_end(t, y, rec_t, rec_y, n_rec)
            if needs_tangent:
                result[R_REGIME] = TANGENT_NEEDED

    codes = "_".join(str(int(c)) for c in (model, law, method, coupling, het, tangent, n_fixed))
    integrate_grid.__qualname__ = f"{integrate_grid.__qualname__}_{codes}"
    return jit(integrate_grid)
