"""The largest Lyapunov exponent λ1: a tangent vector carried beside the state.

Benettin et al. (1980). A tangent vector δ follows the linearised dynamics; after
every step it is renormalised to length 1 and the logarithm of its growth is added
to S(t). λ1 is the slope of S(t) (V/D0).

The tangent's step is the exact derivative of the run's own step map along δ, formed
analytically from the step's stages (internal differentiation): for the explicit
methods the Runge–Kutta scheme applied to the variational equations δ' = J(y) δ, with
J at each stage's argument (``equations.rhs_jvp``); for RODAS4 the same stages solved
with the step's own LU factors, plus the change of its matrix J(y) along δ
(``equations.rhs_curvature``). A difference of two steps from y and y + εδ, used
before, cannot do this: in an inertial stick phase ℓ' = z e^(−ℓ)/M̂ changes by ~1e10
per unit of z, so any ε that round-off allows takes the perturbed step far outside the
linear range, and λ1 of inertial chaos came out 2–4× too large and moved with ε and
rtol (test_tangent.py, test_attractors.py). One tangent step costs about one step of
the method (``make bench``). While the tangent is carried, DOPRI5's and DOP853's steps
are capped so that they resolve it (``TANGENT_TURN``); before it starts, a run with
λ1 follows the trajectory of the same run without it, number for number.

The slope is fitted by least squares over blocks of equal length: the first block
is a transient (δ aligning with the most unstable direction) and is left out;
λ1 is the fit over the others, its error the standard error of the blocks' own
slopes. The least-squares fit, unlike the end-to-end ratio, averages out the
oscillation of log |δ| within a cycle (its error falls as 1/T², not 1/T).
"""

import itertools
import math

import numpy as np
from numba import literally

from ..accelerate import jit, jit_inline
from .equations import rhs_jvp

#: Blocks a Lyapunov window is cut into; the first is the transient.
LYAP_BLOCKS = 8
#: While the tangent is carried, a DOPRI5 or DOP853 step turns δ by at most about this
#: many radians: h ≤ TANGENT_TURN / |J δ|. The step size controller watches the state's
#: error only, and a state decayed onto a fixed point below atol takes steps longer
#: than the period of its linear modes, over which the tangent is not resolved (λ1 of a
#: stable fixed point came out ~0 instead of its growth rate: test_tangent.py). RODAS4
#: keeps its max_step instead: |J δ| includes the stiff decay it needs not resolve.
TANGENT_TURN = 0.5


def explicit_tableau(a_rows, b):
    """Butcher tableau (A, b) of an explicit method in the form of
    :func:`explicit_tangent_step`, stage 0 = f(y): row s of A holds the coefficients of
    stages 0 … s − 1 in stage s's argument y + h Σ a_sr K_r (``a_rows``, from row 1)."""
    b = np.asarray(b, float)
    a = np.zeros((b.size, b.size))
    for s, row in enumerate(a_rows, start=1):
        a[s, : len(row)] = row
    return a, b


# --- entries of the accumulator ``ly`` ----------------------------------------
_l = itertools.count()
L_ON = next(_l)  # 1 while the tangent is carried
L_T0 = next(_l)  # start of the window (D0/V)
L_BLOCK = next(_l)  # length of a block (D0/V)
L_LOG = next(_l)  # S: accumulated log growth of the tangent
L_BLOCK_START = next(_l)  # start of the current block (D0/V)
L_BLOCKS = next(_l)  # blocks completed (the transient first)
L_MEAN = next(_l)  # mean of the completed blocks' slopes (transient left out)
L_M2 = next(_l)  # their sum of squared deviations (Welford)
L_W = next(_l)  # fit over the window after the transient: Σ w, Σ w t, Σ w S, Σ w t², Σ w t S
L_WT = next(_l)
L_WS = next(_l)
L_WTT = next(_l)
L_WTS = next(_l)
L_BW = next(_l)  # the same sums over the current block
L_BWT = next(_l)
L_BWS = next(_l)
L_BWTT = next(_l)
L_BWTS = next(_l)
L_T_LAST = next(_l)  # time of the last sample (D0/V)
L_RATE = next(_l)  # |J δ| at the start of the last tangent step (V/D0; 0: none yet)
N_LYAP = next(_l)
#: Rows of the tangent's ``work`` scratch (see :func:`tangent_arrays`).
TANGENT_WORK_ROWS = 4


@jit
def tangent_arrays(stage_rows, n, nb):
    """Scratch of the tangent for a state of ``n`` values, ``nb`` blocks: δ (n,); the rows
    of ``work`` (``TANGENT_WORK_ROWS``, n): a stage's argument, its direction, and two
    rows for RODAS4's right-hand side and curvature; the stages' derivatives
    (``stage_rows``: the method's ``TANGENT_ROWS``, of n); per-block scratch (3, nb); the
    accumulator ``ly`` (``L_*``)."""
    return (
        np.empty(n),
        np.empty((TANGENT_WORK_ROWS, n)),
        np.empty((stage_rows, n)),
        np.empty((3, nb)),
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


@jit_inline
def turn_step(ly):
    """The longest step while the tangent is carried (D0/V): ``TANGENT_TURN`` / |J δ| at
    the last step (``ly[L_RATE]``), unbounded before one is known."""
    return TANGENT_TURN / ly[L_RATE] if ly[L_RATE] > 0.0 else math.inf


@jit
def explicit_tangent_step(
    a, b, y, f, h, k, delta, work, dk, blocks, p, nb, ev, model, law, coupling, het
):
    """Carry δ (unit length) over the accepted step of size ``h`` from ``y`` (slope
    ``f``) of an explicit method with tableau ``a``, ``b`` (:func:`explicit_tableau`;
    its stages K_1 … in the rows of ``k``) and renormalise it; returns the logarithm of
    its growth and |J δ| at ``y`` (V/D0).

    K_s = f(Y_s), Y_s = y + h Σ a_sr K_r, y1 = y + h Σ b_s K_s: along δ, dK_s = J(Y_s)
    (δ + h Σ a_sr dK_r), the derivative of the step (module docstring). ``work``,
    ``dk`` and ``blocks`` are the scratch of :func:`tangent_arrays`. Compiled per variant
    (``literally``): its codes are constants of the grid kernel.
    """
    literally(model)
    literally(law)
    literally(coupling)
    literally(het)
    n = y.size
    arg, direction = work[0], work[1]
    rate = 0.0
    stages = b.size
    for s in range(stages):
        for j in range(n):
            ya = 0.0
            da = 0.0
            for r in range(s):
                if a[s, r] != 0.0:
                    ya += a[s, r] * (f[j] if r == 0 else k[r - 1, j])
                    da += a[s, r] * dk[r, j]
            arg[j] = y[j] + h * ya
            direction[j] = delta[j] + h * da
        rhs_jvp(arg, direction, p, model, law, coupling, het, nb, ev, blocks[0], dk[s])
        if s == 0:
            for j in range(n):
                rate += dk[0, j] ** 2
    for j in range(n):
        acc_j = 0.0
        for r in range(stages):
            acc_j += b[r] * dk[r, j]
        delta[j] += h * acc_j
    return renormalise(delta), math.sqrt(rate)


@jit_inline
def renormalise(delta):
    """Scale the tangent ``delta`` to length 1; returns the logarithm of its length before."""
    n = delta.size
    norm = 0.0
    for j in range(n):
        norm += delta[j] ** 2
    norm = math.sqrt(norm)
    for j in range(n):
        delta[j] /= norm
    return math.log(norm)


@jit
def ls_slope(w, wt, ws, wtt, wts):
    """Least-squares slope of S against t from the weighted sums Σw, Σwt, ΣwS, Σwt², ΣwtS."""
    return (w * wts - wt * ws) / (w * wtt - wt * wt)


@jit
def lyapunov_add(ly, t, h, growth, rate):
    """Add the step of size ``h`` ending at ``t`` (D0/V) with log growth ``growth`` of
    the tangent: S and the least-squares sums of the current block and, after the
    transient block, of the window; a block that has ended adds its slope to the
    blocks' statistics. ``rate``: |J δ| at the step's start (V/D0), kept in ``L_RATE``."""
    ly[L_RATE] = rate
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
