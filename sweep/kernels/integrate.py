"""The integration loop of one system and the grid kernel around it.

``grid_kernel`` builds one serial kernel per variant (model, state law, method,
coupling, equal or unequal blocks); ``integrate_system`` steps one system,
folds every step into the cycle classifier and writes its statistics.
"""

import functools
import math

import numpy as np

from ..accelerate import jit, jit_inline, jit_kernel
from . import source_digest
from .cycles import (
    C_CONV,
    C_GROWTH,
    C_IN_EVENT,
    C_LAST_ORDER,
    C_LAST_PARTICIPATION,
    C_LAST_PHASE,
    C_LAST_SYNC,
    C_LNV_MAX_RUN,
    C_N_AGREE,
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
    W_LMAX,
    W_LMIN,
    W_MUMAX,
    W_MUMIN,
    close_cycle,
    cycle_arrays,
    end_slip_event,
    start_cycle,
    update_cycle,
)
from .equations import rhs
from .layout import (
    DOPRI5,
    NO_RUNAWAY,
    NOT_FINITE,
    P_A,
    P_B,
    P_DT,
    P_LIN_GROWTH,
    P_MAX_STEP,
    P_TAU_END,
    P_TAU_MAX,
    R_CONVERGENCE,
    R_FRICTION_DROP,
    R_GROWTH,
    R_LNV_MAX,
    R_LNV_MAX_RUN,
    R_LNV_MIN,
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
    S_LNV_CAP,
    S_MAX_STEPS,
    S_NBLOCKS,
    S_RTOL,
    S_SLIP_LNV,
    S_STEADY_AMP,
    STEADY,
    UNDECIDED,
)
from .steppers import (
    dense_crossing,
    dense_extremum,
    dense_r5,
    dense_value,
    next_step_size,
    rosenbrock_scratch,
    step_dopri5,
    step_rk4,
    step_rosenbrock,
    step_scratch,
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
def record_step(method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, rec_dt, rec_t, rec_y, n_rec):
    """Record the state at the multiples of ``rec_dt`` inside the step (dense output)
    while the buffers have room (the last slot is kept for the end). Returns the count."""
    rec_cap = rec_t.size
    while n_rec < rec_cap - 1 and n_rec * rec_dt <= t + h and rec_dt > 0.0:
        theta = (n_rec * rec_dt - t) / h
        rec_t[n_rec] = n_rec * rec_dt
        for j in range(y.size):
            r5 = dense_r5(method, j, h, f, k3, k4, k5, k6, fnew)
            rec_y[n_rec, j] = dense_value(y[j], ynew[j], f[j], fnew[j], h, r5, theta)
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
def cap_crossing(method, i, t, h, y, ynew, f, fnew, k3, k4, k5, k6, nb, lnv_cap, win, cs):
    """End a run whose block ``i`` crossed ``lnv_cap`` in the step from ``t`` to
    ``t + h``: keep the step (``y`` becomes ``ynew``, the extremes include it) and
    return the time of the crossing (D0/V, interpolated)."""
    r5 = dense_r5(method, i, h, f, k3, k4, k5, k6, fnew)
    theta = dense_crossing(y[i], ynew[i], f[i], fnew[i], h, r5, lnv_cap)
    tau = t + (0.0 if y[i] > lnv_cap else theta) * h
    for j in range(nb):
        win[W_LMAX, j] = max(win[W_LMAX, j], ynew[j])
    cs[C_LNV_MAX_RUN] = max(cs[C_LNV_MAX_RUN], lnv_cap)
    for j in range(y.size):
        y[j] = ynew[j]
    return tau


@jit
def final_regime(regime, t, tau_stop, y, cs, steady_amp, lin_growth):
    """The regime of a run that ended without a settled verdict (``regime`` < 0):
    undecided when the step budget ran out, else the last cycle's verdict, steady
    when it decayed onto a linearly stable steady state, else undecided."""
    if regime >= 0:
        return regime
    if t < tau_stop:  # step budget exhausted
        return UNDECIDED
    if cs[C_VERDICT] >= 0:
        return int(cs[C_VERDICT])
    if max_abs(y) < steady_amp and lin_growth < 0.0:
        return STEADY
    return UNDECIDED


@jit
def write_result(result, regime, t, n_steps, n_rejected, tau_runaway, nb, win, last, cs):
    """The run's statistics into ``result`` (``R_*`` columns).

    The final window is the last completed cycle, except for runaway runs and
    runs that never completed one, which report the cycle in progress.
    """
    use_last = cs[C_N_PEAKS] >= 2 and regime != RUNAWAY
    window = last if use_last else win
    lmax = -np.inf
    lmin = np.inf
    fdrop = 0.0
    for i in range(nb):
        lmax = max(lmax, window[W_LMAX, i])
        lmin = min(lmin, window[W_LMIN, i])
        fdrop = max(fdrop, window[W_MUMAX, i] - window[W_MUMIN, i])
    sync = cs[C_LAST_SYNC] if use_last else cs[C_WIN_SYNC]
    result[R_REGIME] = regime
    result[R_TAU_FINAL] = t
    result[R_N_STEPS] = n_steps
    result[R_N_REJECTED] = n_rejected
    result[R_LNV_MAX] = lmax
    result[R_LNV_MIN] = lmin
    result[R_PERIOD] = cs[C_PERIOD]
    result[R_GROWTH] = cs[C_GROWTH]
    result[R_FRICTION_DROP] = fdrop
    result[R_TAU_RUNAWAY] = tau_runaway
    result[R_SYNC_ERROR] = sync if nb > 1 else np.nan
    result[R_PHASE_LAG] = cs[C_LAST_PHASE]
    result[R_N_PEAKS] = cs[C_N_PEAKS]
    result[R_LNV_MAX_RUN] = cs[C_LNV_MAX_RUN]
    steady_or_runaway = regime == STEADY or regime == RUNAWAY
    result[R_CONVERGENCE] = np.nan if steady_or_runaway else cs[C_CONV]
    events = cs[C_SLIP_EVENTS]
    result[R_SYNC_ORDER] = cs[C_LAST_ORDER] if use_last else np.nan
    if use_last:
        result[R_SLIP_PARTICIPATION] = cs[C_LAST_PARTICIPATION]
    else:
        result[R_SLIP_PARTICIPATION] = cs[C_SLIP_SUM] / events if events > 0 else np.nan


@jit_inline
def read_settings(settings):
    """The settings array (``S_*``) as typed values: blocks, rtol, atol, step budget,
    ln of the velocity cap, steady amplitude, accuracy, cycles to confirm (≥ 1),
    early exit (bool) and ln of the slip threshold."""
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
    return nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit, slip_lnv


@jit_inline
def integrate_system(
    p, y0, settings, result, y_final, rec_dt, rec_t, rec_y, model, law, method, coupling, het
):
    """Integrate one system (parameters ``p``: ``P_*``) from ``y0``; its statistics go
    to ``result`` (``R_*``), its final state to ``y_final``. Traces: the state every
    ``rec_dt`` (D0/V, interpolated) and at the end goes to ``rec_t``/``rec_y`` while
    they have room (sweeps pass empty buffers); the count is ``result[R_N_RECORDED]``.

    ``model``, ``law``, ``method``, ``coupling`` and ``het`` (per-block columns in
    ``p``) are the kernel's variant: constants of :func:`grid_kernel`, whose inlined
    copy of this function keeps only that variant's branches.
    """
    nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit, slip_lnv = (
        read_settings(settings)
    )
    A = p[P_A]
    B = p[P_B]
    tau_end = p[P_TAU_END]
    # unsettled runs go on past tau_end only with early exit (else: fixed-length runs)
    tau_max = max(p[P_TAU_MAX], tau_end) if early_exit else tau_end
    lin_growth = p[P_LIN_GROWTH]
    max_step = p[P_MAX_STEP]

    n = y0.size
    y = y0.copy()
    f, ynew, fnew, ytmp, k = step_scratch(n)
    k3, k4, k5, k6 = k[1], k[2], k[3], k[4]  # the stages dense output needs
    ev = np.empty(nb)
    k_ros, mat, perm = rosenbrock_scratch(method, n)
    win, last, hist, cs, slipped = cycle_arrays(y, p, nb, A, B)

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
            if cs[C_VERDICT] >= 0:
                regime = int(cs[C_VERDICT])
                break
        if n_steps + n_rejected >= max_steps:
            break
        h = min(h, tau_stop - t)
        err = 0.0  # RK4: every step is accepted
        if method == DOPRI5:
            err = step_dopri5(
                y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew, fnew, rtol, atol
            )
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
                tau_runaway = cap_crossing(
                    method, crossed, t, h, y, ynew, f, fnew, k3, k4, k5, k6, nb, lnv_cap, win, cs
                )
                t += h
            break

        new_peak, theta_peak = update_cycle(
            method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, p, nb, A, B, win, cs, slipped,
            slip_lnv,
        )  # fmt: skip
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
                for i in range(nb):
                    r5 += dense_r5(method, i, h, f, k3, k4, k5, k6, fnew) / nb
                theta = dense_extremum(m0, m1, dm0, dm1, h, r5)
                val = dense_value(m0, m1, dm0, dm1, h, r5, theta)
                cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], val)
                cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], val)
            cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], m1)
            cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], m1)
        if n_rec > 0:
            n_rec = record_step(
                method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, rec_dt, rec_t, rec_y, n_rec
            )
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
                    t_new_peak, nb, win, last, hist, cs, accuracy, steady_amp, lin_growth, rtol,
                    atol,
                )  # fmt: skip
            cs[C_T_PEAK] = t_new_peak
            # the new cycle starts at this peak
            start_cycle(y, p, nb, A, B, win, cs)
            win[W_LMAX, 0] = max(win[W_LMAX, 0], cs[C_PEAK_VALUE])
            if early_exit and cs[C_VERDICT] >= 0 and cs[C_N_AGREE] >= n_confirm:
                regime = int(cs[C_VERDICT])
                break

        # decayed onto a linearly stable steady state
        if early_exit and lin_growth < 0.0 and max_abs(y) < steady_amp:
            regime = STEADY
            break

    regime = final_regime(regime, t, tau_stop, y, cs, steady_amp, lin_growth)
    write_result(result, regime, t, n_steps, n_rejected, tau_runaway, nb, win, last, cs)
    y_final[:] = y
    result[R_N_RECORDED] = record_end(t, y, rec_t, rec_y, n_rec)


@functools.cache
def grid_kernel(model, law, method, coupling, het):
    """The serial grid kernel of one variant: model, state law, method and coupling
    codes (int) and whether blocks differ (``het``, bool).

    Built and compiled on first use, one per variant: the codes are constants of
    the closure, so once the helpers are inlined numba prunes the other variants'
    branches before typing (the other methods' steppers are never compiled), and
    numba's cache keys each variant by their values. The helpers themselves are
    still prepared for inlining with every branch (their codes are arguments), which
    is why the Runge–Kutta stages are loops around one call of :func:`rhs`. Sweeps and
    traces call the same kernel: ``integrate_grid(params, y0, settings, results, y_final, rec_dt,
    rec_t, rec_y)`` integrates every row one after another; a trace passes one row
    and recording buffers, sweeps empty buffers (see :func:`integrate_system`).

    Only these kernels are cached on disk (``accelerate.jit_kernel``), each with
    everything it calls compiled in. numba keys a cache entry on the closure's
    values and on this file's timestamp: the closure holds the digest of every
    kernel source, so an edit to any kernel file compiles the kernel afresh.
    """
    sources = source_digest()

    def integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y):
        _ = sources  # a closure value: part of numba's cache key (see above)
        for s in range(params.shape[0]):
            integrate_system(
                params[s], y0[s], settings, results[s], y_final[s], rec_dt, rec_t, rec_y,
                model, law, method, coupling, het,
            )  # fmt: skip

    return jit_kernel(integrate_grid)
