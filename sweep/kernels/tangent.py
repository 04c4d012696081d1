"""The largest Lyapunov exponent λ1: a tangent vector carried beside the state.

Benettin et al. (1980). A tangent vector δ follows the linearised dynamics; after
every step it is renormalised to length 1 and the logarithm of its growth is added
to S(t). λ1 is the slope of S(t) (V/D0).

The tangent's step is the derivative of the run's own step map (the stepper's own
scheme applied to the tangent): the same stepper, with the same step size, from
y and from y + εδ, differenced (ε = ``TANGENT_EPS`` × max(1, max |y|)). For the
explicit methods this is, to O(ε), the Runge–Kutta scheme applied to the
variational equations δ' = J(y) δ; for RODAS4 it includes the change of its
Jacobian along δ, which an analytic tangent would need second derivatives for.
One tangent step costs one more step of the method (``make bench``). While the
tangent is carried, DOPRI5's and DOP853's steps are capped so that they resolve it
(``TANGENT_TURN``); before it starts, a run with λ1 follows the trajectory of the same
run without it, number for number.

The slope is fitted by least squares over blocks of equal length: the first block
is a transient (δ aligning with the most unstable direction) and is left out;
λ1 is the fit over the others, its error the standard error of the blocks' own
slopes. The least-squares fit, unlike the end-to-end ratio, averages out the
oscillation of log |δ| within a cycle (its error falls as 1/T², not 1/T).
"""

import math

import numpy as np
from numba import literally

from ..accelerate import jit
from .equations import rhs
from .layout import DOP853, DOPRI5, ROSENBROCK
from .steppers import (
    ROS_STAGE_ROWS,
    STAGE_ROWS,
    STAGE_ROWS_DOP853,
    step_dop853,
    step_dopri5,
    step_rk4,
    step_rosenbrock,
)

#: Size of the difference that gives the tangent step, relative to max(1, max |y|):
#: about √(machine epsilon) / 10, so round-off (u |y| / ε ~ 1e-8) and the second-order
#: term (~ε) both stay far below the accuracy the tests ask of λ1 (1 %).
TANGENT_EPS = 1e-8
#: Blocks a Lyapunov window is cut into; the first is the transient.
LYAP_BLOCKS = 8
#: While the tangent is carried, a DOPRI5 or DOP853 step turns δ by at most about this
#: many radians: h ≤ TANGENT_TURN / |J δ|. The step size controller watches the state's
#: error only, and a state decayed onto a fixed point below atol takes steps longer
#: than the period of its linear modes, over which the tangent is not resolved (λ1 of a
#: stable fixed point came out ~0 instead of its growth rate: test_tangent.py). RODAS4
#: keeps its max_step instead: |J δ| includes the stiff decay it needs not resolve.
TANGENT_TURN = 0.5

# --- entries of the accumulator ``ly`` ----------------------------------------
(
    L_ON,  # 1 while the tangent is carried
    L_T0,  # start of the window (D0/V)
    L_BLOCK,  # length of a block (D0/V)
    L_LOG,  # S: accumulated log growth of the tangent
    L_BLOCK_START,  # start of the current block (D0/V)
    L_BLOCKS,  # blocks completed (the transient first)
    L_MEAN,  # mean of the completed blocks' slopes (transient left out)
    L_M2,  # their sum of squared deviations (Welford)
    L_W,  # fit over the window after the transient: Σ w, Σ w t, Σ w S, Σ w t², Σ w t S
    L_WT,
    L_WS,
    L_WTT,
    L_WTS,
    L_BW,  # the same sums over the current block
    L_BWT,
    L_BWS,
    L_BWTT,
    L_BWTS,
    L_T_LAST,  # time of the last sample (D0/V)
    L_RATE,  # |J δ| at the start of the last tangent step (V/D0; 0: none yet)
) = range(20)
N_LYAP = 20
#: Rows of the tangent's ``work`` scratch (see :func:`tangent_arrays`).
TANGENT_WORK_ROWS = 5


@jit
def tangent_arrays(method, n):
    """Scratch of the tangent: δ (n,); the rows of ``work`` (``TANGENT_WORK_ROWS``, n):
    y + εδ, its slope, a stage argument, the step's end and its slope; the explicit
    stages (``STAGE_ROWS`` or, for DOP853, ``STAGE_ROWS_DOP853`` rows of n); RODAS4's
    stages (``ROS_STAGE_ROWS``, n), matrix (n, n) and pivots (n,) (empty for the other
    methods); the accumulator ``ly`` (``L_*``)."""
    n_ros = n if method == ROSENBROCK else 0
    return (
        np.empty(n),
        np.empty((TANGENT_WORK_ROWS, n)),
        np.empty((STAGE_ROWS_DOP853 if method == DOP853 else STAGE_ROWS, n)),
        np.empty((ROS_STAGE_ROWS if n_ros else 0, n)),
        np.empty((n_ros, n_ros)),
        np.empty(n_ros, np.int64),
        np.zeros(N_LYAP),
    )


@jit
def lyapunov_start(ly, delta, t, block):
    """Start carrying the tangent at time ``t`` (D0/V), blocks of ``block`` D0/V: δ is a
    fixed generic unit vector (every component different, so no mode of identical
    blocks is left out by symmetry)."""
    n = delta.size
    norm = 0.0
    for j in range(n):
        delta[j] = 1.0 + j / n
        norm += delta[j] ** 2
    for j in range(n):
        delta[j] /= math.sqrt(norm)
    ly[:] = 0.0
    ly[L_ON] = 1.0
    ly[L_T0] = t
    ly[L_BLOCK] = block
    ly[L_BLOCK_START] = t
    ly[L_MEAN] = 0.0
    ly[L_T_LAST] = t


@jit
def tangent_step(
    y, f, ynew, h, delta, work, stages, ros_k, ros_mat, ros_perm, p, nb, ev, rtol, atol,
    model, law, method, coupling, het,
):  # fmt: skip
    """Carry δ (unit length) over the step of size ``h`` from ``y`` (slope ``f``) to
    ``ynew`` and renormalise it; returns the logarithm of its growth and |J δ| at ``y``
    (the difference of the slopes, V/D0).

    The difference of the method's step from y + εδ and from y (see the module
    docstring); ``work`` (``TANGENT_WORK_ROWS``, n) and ``stages`` are scratch,
    ``ros_*`` RODAS4's.
    Compiled per variant (``literally``): its codes are constants of the grid kernel.
    """
    literally(model)
    literally(law)
    literally(method)
    literally(coupling)
    literally(het)
    n = y.size
    y2, f2, ytmp, ynew2, fnew2 = work[0], work[1], work[2], work[3], work[4]
    big = 1.0
    for j in range(n):
        big = max(big, abs(y[j]))
    eps = TANGENT_EPS * big
    for j in range(n):
        y2[j] = y[j] + eps * delta[j]
    rhs(y2, p, model, law, coupling, het, nb, ev, f2)
    rate = 0.0
    for j in range(n):
        rate += (f2[j] - f[j]) ** 2
    rate = math.sqrt(rate) / eps
    if method == DOPRI5:
        step_dopri5(
            y2, f2, h, p, model, law, coupling, het, nb, ev, stages, ytmp, ynew2, fnew2, rtol, atol
        )
    elif method == DOP853:
        step_dop853(
            y2, f2, h, p, model, law, coupling, het, nb, ev, stages, ytmp, ynew2, fnew2, rtol, atol
        )
    elif method == ROSENBROCK:
        step_rosenbrock(
            y2, f2, h, p, model, law, coupling, het, nb, ev, ros_k, ros_mat, ros_perm, ytmp, ynew2,
            fnew2, rtol, atol,
        )  # fmt: skip
    else:
        step_rk4(y2, f2, h, p, model, law, coupling, het, nb, ev, stages, ytmp, ynew2)
    norm = 0.0
    for j in range(n):
        delta[j] = (ynew2[j] - ynew[j]) / eps
        norm += delta[j] ** 2
    norm = math.sqrt(norm)
    for j in range(n):
        delta[j] /= norm
    return math.log(norm), rate


@jit
def ls_slope(w, wt, ws, wtt, wts):
    """Least-squares slope of S against t from the weighted sums Σw, Σwt, ΣwS, Σwt², ΣwtS."""
    return (w * wts - wt * ws) / (w * wtt - wt * wt)


@jit
def lyapunov_add(ly, t, h, growth):
    """Add the step of size ``h`` ending at ``t`` (D0/V) with log growth ``growth`` of
    the tangent: S and the least-squares sums of the current block and, after the
    transient block, of the window; a block that has ended adds its slope to the
    blocks' statistics."""
    while t - ly[L_BLOCK_START] >= ly[L_BLOCK]:
        if ly[L_BLOCKS] >= 1.0 and ly[L_BW] > 0.0:
            slope = ls_slope(ly[L_BW], ly[L_BWT], ly[L_BWS], ly[L_BWTT], ly[L_BWTS])
            count = ly[L_BLOCKS]  # slopes so far, this one included
            change = slope - ly[L_MEAN]
            ly[L_MEAN] += change / count
            ly[L_M2] += change * (slope - ly[L_MEAN])
        for k in range(L_BW, L_BWTS + 1):
            ly[k] = 0.0
        ly[L_BLOCK_START] += ly[L_BLOCK]
        ly[L_BLOCKS] += 1.0
    ly[L_LOG] += growth
    s = ly[L_LOG]
    u = t - ly[L_T0]  # times from the window's start: sums of moderate size
    ly[L_BW] += h
    ly[L_BWT] += h * u
    ly[L_BWS] += h * s
    ly[L_BWTT] += h * u * u
    ly[L_BWTS] += h * u * s
    if ly[L_BLOCKS] >= 1.0:
        ly[L_W] += h
        ly[L_WT] += h * u
        ly[L_WS] += h * s
        ly[L_WTT] += h * u * u
        ly[L_WTS] += h * u * s
    ly[L_T_LAST] = t


@jit
def lyapunov_estimate(ly):
    """``(λ1, error, span)`` from the accumulator (V/D0, V/D0, D0/V): the slope over the
    window after the transient block, the standard error of the completed blocks'
    slopes, and the time the fit spans. NaN unless two blocks after the transient
    have been completed."""
    slopes = ly[L_BLOCKS] - 1.0
    if ly[L_ON] == 0.0 or slopes < 2.0:
        return np.nan, np.nan, np.nan
    lam = ls_slope(ly[L_W], ly[L_WT], ly[L_WS], ly[L_WTT], ly[L_WTS])
    error = math.sqrt(ly[L_M2] / (slopes - 1.0) / slopes)
    span = ly[L_T_LAST] - (ly[L_T0] + ly[L_BLOCK])
    return lam, error, span
