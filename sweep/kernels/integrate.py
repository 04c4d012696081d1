"""The grid kernel: the integration loop of every system, one after another.

``grid_kernel`` builds one serial kernel per variant (model, state law, method,
coupling, equal or unequal blocks, with or without the tangent, with or without the
catalogue of slip events, state size). It runs every row of ``params`` (``P_*``) from
its row of ``y0`` into ``results`` (``R_*``) and ``y_final``; a trace passes recording
buffers. Its loop steps each system with the method's module (``methods``), hands each
accepted step as a step record (``step.Step``) to the classifier (``classify``), the
tangent for λ1 and the recorder (and the catalogue, compiled only into the kernels of
runs that keep one), and has the classifier write the run's statistics.

Built and compiled on first use, one per variant. The codes are constants of the
closure, and the method's module is picked when the kernel is built, so numba prunes
the other variants' branches before it inlines the helpers and compiles no other
method. The loop is written here, not in an inlined function of its own: numba copies
an inlined body once per basic block with its whole scope, which took 10 of a 27 s
compile. Cached on disk like the helpers it calls (``accelerate.SourceKeyedCache``:
keyed on every kernel source, safe to share between processes); each variant's
function is named after its codes, so its cache files are its own.
"""

import functools
import math

import numpy as np

from ..accelerate import jit, jit_inline, jit_variant
from .classify.cycle import new_event
from .classify.extrema import (
    cap_crossing,
    classify_step,
    dense_needed,
    end_slip_event,
    event_section,
)
from .classify.result import finish_run
from .classify.state import C_VERDICT, cycle_arrays, verdict_held
from .classify.verdicts import collapse_regime, settled_early
from .control import next_step_size
from .equations import rhs
from .layout import (
    LYAP_ALWAYS,
    LYAP_UNSETTLED,
    NO_RUNAWAY,
    NOT_FINITE,
    P_A,
    P_B,
    P_DT,
    P_LIN_GROWTH,
    P_MAX_STEP,
    P_TAU_END,
    P_TAU_MAX,
    R_N_RECORDED,
    RUNAWAY,
    S_ACCURACY,
    S_ATOL,
    S_CATALOGUE,
    S_CONFIRM_CYCLES,
    S_EARLY_EXIT,
    S_EVENTS,
    S_LINEAR_VERDICTS,
    S_LNV_CAP,
    S_LYAPUNOV,
    S_MAX_STEPS,
    S_NBLOCKS,
    S_RTOL,
    S_SLIP_LNV,
    S_STEADY_AMP,
    values_per_block,
)
from .methods import MODULES
from .record import record_end, record_start, record_step
from .slip_events import K_CAPACITY, catalogue_arrays, catalogue_reads, catalogue_step
from .stack import stack_matrix, stack_vector
from .step import DENSE_ROWS, Step
from .tangent import (
    L_ON,
    LYAP_BLOCKS,
    TANGENT_WORK_ROWS,
    lyapunov_add,
    lyapunov_start,
    tangent_arrays,
    turn_step,
)


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
def heap_scratch(n, k_rows, mat_cols):
    """Scratch of a step for a state of ``n`` values on the heap: f, ynew, fnew, ytmp, the
    stages as the rows of one array (``k_rows`` of n), the matrix and pivots of an
    implicit method (n rows of ``mat_cols`` columns, 0: n, and n pivots; none for
    ``mat_cols`` < 0) and the interpolant's coefficients (``step.DENSE_ROWS`` of n,
    zero)."""
    mat_n = n if mat_cols >= 0 else 0
    mat_c = (mat_cols if mat_cols > 0 else n) if mat_cols >= 0 else 0
    return (
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty((k_rows, n)),
        np.empty((mat_n, mat_c)),
        np.empty(mat_n, np.int64),
        np.zeros((DENSE_ROWS, n)),
    )


@jit_inline
def read_settings(settings):
    """The settings array (``S_*``) as typed values: blocks, rtol, atol, step budget,
    ln of the velocity cap, steady amplitude, accuracy, cycles to confirm (≥ 1),
    early exit (bool), ln of the slip threshold, when λ1 is computed (``LYAP_*``), the
    number of events reported and whether linear-regime verdicts are asked for (bool)."""
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
    linear = settings[S_LINEAR_VERDICTS] > 0.5
    return (
        nb,
        rtol,
        atol,
        max_steps,
        lnv_cap,
        steady_amp,
        accuracy,
        n_confirm,
        early_exit,
        slip_lnv,
        lyap,
        n_events,
        linear,
    )


@jit_inline
def system_scratch(y0_row, n, nb, n_fixed, nb_fixed, k_rows, mat_cols, dk_rows, tangent):
    """The scratch of one system's run: its state (from ``y0_row``), its slope, the state
    and slope after a step, a stage's argument, the blocks' scratch ``ev``, the stages
    (``k_rows`` of n), an implicit method's matrix (``mat_cols`` columns, 0: n) and
    pivots (none for ``mat_cols`` < 0), the interpolant's coefficients (zero), and the tangent's
    (``tangent.tangent_arrays``, empty without ``tangent``), after the number of blocks.
    On the stack for a kernel of fixed size ``n_fixed`` (``nb_fixed`` blocks;
    ``stack.py``, inlined into the kernel), else on the heap (``nb`` blocks)."""
    t_n = n if tangent and n_fixed == 0 else 0
    delta, work, dk, t_blocks, ly = tangent_arrays(dk_rows, t_n, nb if t_n else 0)
    if n_fixed > 0:
        nb = np.int64(nb_fixed)
        mat_n = n_fixed if mat_cols >= 0 else 0
        mat_c = (mat_cols if mat_cols > 0 else n_fixed) if mat_cols >= 0 else 0
        y, f, ynew, fnew, ytmp, ev = (
            stack_vector(n_fixed),
            stack_vector(n_fixed),
            stack_vector(n_fixed),
            stack_vector(n_fixed),
            stack_vector(n_fixed),
            stack_vector(nb_fixed),
        )
        k, mat, dense = (
            stack_matrix(k_rows, n_fixed),
            stack_matrix(mat_n, mat_c),
            stack_matrix(DENSE_ROWS, n_fixed),
        )
        perm = np.empty(mat_n, np.int64)
        dense[:, :] = 0.0
        for j in range(n):
            y[j] = y0_row[j]
        if tangent:
            delta, work = stack_vector(n_fixed), stack_matrix(TANGENT_WORK_ROWS, n_fixed)
            dk, t_blocks = stack_matrix(dk_rows, n_fixed), stack_matrix(3, nb_fixed)
    else:
        y = y0_row.copy()
        f, ynew, fnew, ytmp, k, mat, perm, dense = heap_scratch(n, k_rows, mat_cols)
        ev = np.empty(nb)
    return nb, y, f, ynew, fnew, ytmp, ev, k, mat, perm, dense, delta, work, dk, t_blocks, ly


@jit_inline
def read_params(p, early_exit):
    """A system's parameters the loop reads (``P_*``): A, B, tau_end, the time unsettled
    runs go on to (past tau_end only with early exit), the largest step and the linear
    growth rate at steady sliding."""
    tau_end = p[P_TAU_END]
    tau_max = max(p[P_TAU_MAX], tau_end) if early_exit else tau_end
    return p[P_A], p[P_B], tau_end, tau_max, p[P_MAX_STEP], p[P_LIN_GROWTH]


@jit_inline
def lyapunov_plan(lyap, tangent, ly, delta, tau_end, tau_max):
    """``(needs_tangent, tau_max, t_settle)`` of a run with λ1 asked for as ``lyap``
    (``LYAP_*``): over the whole run (LYAP_ALWAYS) the tangent starts at t = 0 and no run
    settles before ``tau_end``, and a kernel without the tangent takes no step (the one
    with it runs the run); else nothing changes yet."""
    if lyap != LYAP_ALWAYS:
        return False, tau_max, 0.0
    if tangent:
        lyapunov_start(ly, delta, 0.0, tau_end / LYAP_BLOCKS)
        return False, tau_max, tau_end
    return True, 0.0, tau_end


@jit_inline
def at_tau_end(cs, lyap, tangent, ly, delta, t, tau_max):
    """``(regime, needs_tangent)`` of a run at ``tau_end``: the verdict that held over one
    whole cycle of events settles it; else, with λ1 asked for unsettled runs
    (LYAP_UNSETTLED), the tangent starts here, or a kernel without it stops the run for
    the one with it to redo (``needs_tangent``). Regime −1: not settled."""
    if verdict_held(cs, 1):
        return int(cs[C_VERDICT]), False
    if lyap == LYAP_UNSETTLED and tau_max > t:
        if not tangent:
            return -1, True
        lyapunov_start(ly, delta, t, (tau_max - t) / LYAP_BLOCKS)
    return -1, False


@functools.cache
def grid_kernel(model, law, method, coupling, het, tangent, catalogue=False, n_fixed=0):
    """The grid kernel ``integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t,
    rec_y)`` of a variant (bools ``het``, ``tangent``, ``catalogue``: whether runs keep a
    catalogue of slip events; ``n_fixed``: state size, 0: any)."""
    m = MODULES[method]  # the method: its step, interpolant, controller, scratch shapes
    adaptive, exponent, bound, k_rows, dk_rows = (
        m.ADAPTIVE,
        m.EXPONENT,
        m.EXCURSION,
        m.STAGE_ROWS,
        m.TANGENT_ROWS,
    )
    dense_rows, dense_stages, tangent_cap = m.DENSE_ROWS, m.DENSE_STAGES, m.TANGENT_CAP
    nb_fixed = n_fixed // values_per_block(model)
    mat_cols = m.matrix_columns(model, coupling) if m.MATRIX else -1  # 0: n × n; −1: none

    def integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y):
        if n_fixed > 0 and y0.shape[0] > 0 and y0.shape[1] != n_fixed:
            raise ValueError("the state size differs from the one this kernel is compiled for")
        if not catalogue and settings[S_CATALOGUE] > 0.0:
            raise ValueError("a catalogue asked of a kernel compiled without one")
        n = np.int64(n_fixed) if n_fixed > 0 else y0.shape[1]  # LLVM: a constant; numba: int64
        for s in range(params.shape[0]):  # settings read per system: 3 % faster per step
            (
                nb,
                rtol,
                atol,
                max_steps,
                lnv_cap,
                steady_amp,
                accuracy,
                n_confirm,
                early_exit,
                slip_lnv,
                lyap,
                n_events,
                linear,
            ) = read_settings(settings)
            p = params[s]
            A, B, tau_end, tau_max, max_step, lin_growth = read_params(p, early_exit)
            nb, y, f, ynew, fnew, ytmp, ev, k, mat, perm, dense, delta, work, dk, t_blocks, ly = (
                system_scratch(y0[s], n, nb, n_fixed, nb_fixed, k_rows, mat_cols, dk_rows, tangent)
            )
            step = Step(y, ynew, f, fnew, dense, bound)
            win, past, past_cs, hist, limits, section, cs, slipped, turns = cycle_arrays(
                y, p, nb, A, B
            )
            needs_tangent, tau_max, t_settle = lyapunov_plan(
                lyap, tangent, ly, delta, tau_end, tau_max
            )
            horizon = tau_max if linear and early_exit else 0.0  # linear verdicts: stop time
            n_rec = record_start(y, rec_t, rec_y)
            if catalogue:  # compiled only where runs keep a catalogue
                cat, cat_blocks = catalogue_arrays(results[s], settings, nb, tau_end)
            rhs(y, p, model, law, coupling, het, nb, ev, f)
            t, h = 0.0, min(1e-3, max_step, tau_end) if adaptive else p[P_DT]
            n_steps, n_rejected, regime, tau_runaway, tau_stop = 0, 0, -1, np.nan, tau_end
            while t < tau_max:  # tau_stop: tau_end, then (unsettled there, settling early) tau_max
                if t >= tau_stop:
                    tau_stop = tau_max
                    regime, needs_tangent = at_tau_end(cs, lyap, tangent, ly, delta, t, tau_max)
                    if regime >= 0 or needs_tangent:
                        break
                if n_steps + n_rejected >= max_steps:
                    break
                h = min(h, tau_stop - t, turn_step(ly) if tangent and tangent_cap else math.inf)
                err = m.step(
                    y,
                    f,
                    h,
                    p,
                    model,
                    law,
                    coupling,
                    het,
                    nb,
                    ev,
                    k,
                    mat,
                    perm,
                    ytmp,
                    ynew,
                    fnew,
                    rtol,
                    atol,
                )
                h_next = next_step_size(exponent, h, err, max_step) if adaptive else h
                if not (err <= 1.0):
                    n_rejected += 1
                    h = h_next
                    if h < 1e-300:
                        regime, tau_runaway = collapse_regime(y, nb, t)
                        break
                    continue
                n_steps += 1
                crossed = runaway_index(ynew, fnew, nb, lnv_cap)
                if crossed != NO_RUNAWAY:
                    regime, tau_runaway = RUNAWAY, t + h
                    if crossed < 0:  # not finite: the step is not kept
                        break
                    # a block passed the cap: the step is kept, its interpolant formed
                    # below (one call site of m.dense: each is a copy of the method's
                    # dense output, compiled again), and the run ends after it
                elif tangent and ly[L_ON] > 0.0:  # the log growth of δ and |J δ|
                    lyapunov_add(
                        ly,
                        t + h,
                        h,
                        *m.tangent_step(
                            y,
                            f,
                            h,
                            k,
                            mat,
                            perm,
                            delta,
                            work,
                            dk,
                            t_blocks,
                            p,
                            nb,
                            ev,
                            model,
                            law,
                            coupling,
                            het,
                        ),
                    )
                # the interpolant's coefficients; where they cost stages, only where read
                if dense_rows > 0 and (
                    crossed >= 0
                    or dense_stages == 0
                    or n_rec > 0
                    or dense_needed(step, h, p, nb, A, B, turns, rtol, atol)
                    or (catalogue and cat[K_CAPACITY] > 0.0 and catalogue_reads(cat, ynew, nb))
                ):
                    m.dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense)
                if crossed >= 0:
                    tau_runaway = cap_crossing(step, crossed, t, h, nb, lnv_cap, win, cs)
                    t += h
                    break
                new_peak, theta_peak, slip_ended = classify_step(
                    step, t, h, p, nb, A, B, win, cs, slipped, slip_lnv, turns, rtol, atol
                )
                if new_peak and nb > 1:  # rare calls made here: see classify_step
                    event_section(step, h, nb, theta_peak, section)
                if slip_ended:
                    end_slip_event(nb, slipped, cs)
                if n_rec > 0:
                    n_rec = record_step(step, t, h, rec_dt, rec_t, rec_y, n_rec)
                if catalogue and cat[K_CAPACITY] > 0.0:
                    catalogue_step(step, t, h, nb, coupling, cat, cat_blocks, results[s])
                t_new_peak, t, h = t + theta_peak * h, t + h, h_next
                for j in range(n):
                    y[j] = ynew[j]
                    f[j] = fnew[j]
                if new_peak:
                    new_event(
                        t_new_peak,
                        y,
                        p,
                        nb,
                        A,
                        B,
                        win,
                        past,
                        past_cs,
                        hist,
                        limits,
                        section,
                        cs,
                        accuracy,
                        steady_amp,
                        lin_growth,
                        rtol,
                        atol,
                        horizon,
                    )
                if early_exit and t >= t_settle:
                    regime = settled_early(new_peak, cs, n_confirm, y, lin_growth, steady_amp)
                    if regime >= 0:
                        break
            finish_run(
                results[s],
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
            )
            for j in range(n):  # not y_final[s] = y: numba compiles its error message
                y_final[s, j] = y[j]
            results[s, R_N_RECORDED] = record_end(t, y, rec_t, rec_y, n_rec)

    return jit_variant(
        integrate_grid, model, law, method, coupling, het, tangent, catalogue, n_fixed
    )
