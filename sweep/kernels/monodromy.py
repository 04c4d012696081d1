"""The monodromy matrix of a periodic run: every direction of the tangent over one period.

From a point y0 of a settled cycle (the run's final state) the state is carried around
the cycle once with n tangent vectors beside it, the columns of the identity, each by the
method's own ``tangent_step``: the exact derivative of the step taken (``tangent.py``).
Each column is renormalised after every step and its log growth kept apart, so the
matrix may span hundreds of decades. The period ends where the trajectory returns to the
hyperplane through y0 normal to the flow f(y0), from its negative side, within
``RETURN_WINDOW`` of the run's period (a cycle of n events passes near y0 at fractions
k/n of its period too, ≤ 31/32 for the classifier's largest n): the step that crosses it
is retaken to end on it (its fraction of the step read from the interpolant), so the
matrix is the derivative of the time-T map at the measured return time T and asks no
more of the classifier's period than to tell which crossing is the return. Its eigenvalues are the
Floquet multipliers (``engine/floquet.py``). One such pass costs about n + 1 periods of
the run.

The section is placed in the slow phase of the cycle: the state is first carried (without
the tangent) from the run's final state past the next minimum of ℓ_0, the stick of block 0
(at most one period). Started in a fast slip phase, where the flow is ~1e4 per D0/V in a
quasi-static ring, a gap to the cycle at the step's accuracy makes the matrix of a point
off the cycle (trivial multiplier 0.4 from 1, measured). The return maps of any two
sections transverse to a cycle are conjugate: they have the same multipliers.
"""

import functools
import math

import numpy as np

from ..accelerate import jit, jit_variant
from .control import next_step_size
from .equations import rhs
from .integrate import heap_scratch
from .layout import P_DT, P_MAX_STEP, S_ATOL, S_MAX_STEPS, S_NBLOCKS, S_RTOL
from .methods import MODULES
from .step import dense_value
from .tangent import TANGENT_TURN, tangent_arrays

#: The return is the first crossing of the section within this fraction of the run's
#: period from it: the classifier's period of a cycle still converging can be off by
#: ~1e-4 of itself (measured: one inertial pair near a period doubling, |μ| = 0.95).
RETURN_WINDOW = 0.02

# --- outcome of a pass (``info[:, M_STATUS]``) -----------------------------
M_OK, M_NO_RETURN, M_FAILED = 0, 1, 2
# --- columns of ``info`` ------------------------------------------------------
M_RETURN_TIME, M_STEPS, M_STATUS = 0, 1, 2
N_INFO = 3


@functools.cache
def monodromy_kernel(model, law, method, coupling, het):
    """The kernel ``monodromy_grid(params, y_start, periods, settings, advance, columns,
    log_scale, flows, y_end, info)`` of a variant (codes as for ``integrate.grid_kernel``).

    For each row s, from ``y_start[s]`` (with ``advance``, first carried without the
    tangent past the next minimum of ℓ_0, and ``y_start[s]`` replaced by that point)
    around the cycle of period about ``periods[s]`` (D0/V): the monodromy matrix M, with
    M[:, j] = columns[s, j] × exp(log_scale[s, j]) (``columns[s, j]`` of unit length),
    the flow f(y_start[s]) (``flows[s]``, per D0/V), the state on return (``y_end[s]``)
    and ``info[s]`` (``M_*``: return time in D0/V, accepted steps, outcome)."""
    m = MODULES[method]
    adaptive, exponent, k_rows, dk_rows = m.ADAPTIVE, m.EXPONENT, m.STAGE_ROWS, m.TANGENT_ROWS
    dense_rows, tangent_cap = m.DENSE_ROWS, m.TANGENT_CAP
    mat_cols = m.matrix_columns(model, coupling) if m.MATRIX else -1

    def monodromy_grid(
        params, y_start, periods, settings, advance, columns, log_scale, flows, y_end, info
    ):
        n = y_start.shape[1]
        nb = int(settings[S_NBLOCKS])
        rtol, atol, max_steps = settings[S_RTOL], settings[S_ATOL], settings[S_MAX_STEPS]
        for s in range(params.shape[0]):
            p = params[s]
            f, ynew, fnew, ytmp, k, mat, perm, dense = heap_scratch(n, k_rows, mat_cols)
            delta, work, dk, t_blocks, _ = tangent_arrays(dk_rows, n, nb)
            ev = np.empty(nb)
            y = y_start[s].copy()
            rhs(y, p, model, law, coupling, het, nb, ev, f)
            normal = flows[s]
            for j in range(n):
                normal[j] = f[j]
            cols = columns[s]
            cols[:, :] = 0.0
            for j in range(n):
                cols[j, j] = 1.0
                log_scale[s, j] = 0.0
            period = periods[s]
            t, g, rate = 0.0, 0.0, 0.0
            h = min(1e-3, p[P_MAX_STEP], period) if adaptive else p[P_DT]
            steps, status = 0, M_FAILED
            advancing = advance
            returned = False  # the step crossed the section: retaken to end on it
            g_new, h_next = 0.0, h
            while steps < max_steps or returned:
                if tangent_cap and rate > 0.0 and not returned:
                    h = min(h, TANGENT_TURN / rate)
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
                if not returned:  # (a retaken step is the step's end: no control)
                    h_next = next_step_size(exponent, h, err, p[P_MAX_STEP]) if adaptive else h
                    if not (err <= 1.0):
                        if h_next < 1e-300:
                            break
                        h = h_next
                        continue
                    steps += 1
                    if advancing:  # to the section: past the next minimum of ℓ_0
                        for j in range(n):
                            y[j] = ynew[j]
                        t += h
                        h = h_next
                        if f[0] < 0.0 <= fnew[0] or t > period:
                            advancing = False
                            t = 0.0
                            for j in range(n):
                                y_start[s, j] = y[j]
                                normal[j] = fnew[j]
                        for j in range(n):
                            f[j] = fnew[j]
                        continue
                    g_new = 0.0
                    for j in range(n):
                        g_new += normal[j] * (ynew[j] - y_start[s, j])
                    if not math.isfinite(g_new):
                        break
                    returned = t + h >= (1.0 - RETURN_WINDOW) * period and g < 0.0 <= g_new
                    if returned:  # retake the step, by the one call above, to end on the section
                        if dense_rows > 0:
                            m.dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense)
                        h *= section_fraction(y, ynew, f, fnew, dense, h, normal, y_start[s])
                        continue
                rate = 0.0
                for j in range(n):  # every column over the step just taken
                    for i in range(n):
                        delta[i] = cols[j, i]
                    growth, r = m.tangent_step(
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
                    )
                    for i in range(n):
                        cols[j, i] = delta[i]
                    log_scale[s, j] += growth
                    rate = max(rate, r)
                t += h
                for j in range(n):
                    y[j] = ynew[j]
                    f[j] = fnew[j]
                if returned:
                    status = M_OK
                    break
                if t > (1.0 + RETURN_WINDOW) * period:
                    status = M_NO_RETURN
                    break
                g, h = g_new, h_next
            for j in range(n):
                y_end[s, j] = y[j]
            info[s, M_RETURN_TIME] = t
            info[s, M_STEPS] = steps
            info[s, M_STATUS] = status

    return jit_variant(monodromy_grid, model, law, method, coupling, het)


@jit
def section_fraction(y, ynew, f, fnew, dense, h, normal, y0):
    """Fraction θ of the step (y → ynew, slopes f, fnew, size h, interpolant coefficients
    ``dense``) where normal · (y(θ) − y0) rises through 0 (bisection to round-off)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        g = 0.0
        for j in range(y.size):
            r = (dense[0, j], dense[1, j], dense[2, j], dense[3, j])
            g += normal[j] * (dense_value(y[j], ynew[j], f[j], fnew[j], h, r, mid) - y0[j])
        if g < 0.0:
            lo = mid
        else:
            hi = mid
    return hi
