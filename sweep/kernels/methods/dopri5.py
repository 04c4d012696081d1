"""DOPRI5: the Dormand–Prince pair of order 5(4) with its continuous extension of order
4 (Hairer, Nørsett & Wanner I, section II.5; Table II.5.2 and the dense output of
section II.6). Explicit, adaptive, first same as last."""

import math

import numpy as np

from ...accelerate import jit_inline
from ..equations import rhs
from ..step import PROVED
from ..tangent import explicit_tableau, explicit_tangent_step

NAME = "DOPRI5"
ADAPTIVE = True
EXPONENT = -0.2  # error estimate of order 4
#: Rows of ``k``: the stages k2 … k6.
STAGE_ROWS = 5
MATRIX = False
#: Its continuous extension's fifth coefficient r5, from the stages: no evaluation.
DENSE_ROWS, DENSE_STAGES = 1, 0
#: Proved (``step.excursion``): with the measured factor of DOP853 it spared none of its
#: wiggles; with the proved bound, 90–95 % (``docs/internals.md``).
EXCURSION = PROVED
TANGENT_ROWS = 6
TANGENT_CAP = True

_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
#: Row s: the coefficients of f, k2, … of stage s + 3's argument (stages 3 to 6; stage
#: 2's, _A21, is applied to h first, as h a21 f).
_DP_A = np.array([
    [_A31, _A32, 0.0, 0.0, 0.0],
    [_A41, _A42, _A43, 0.0, 0.0],
    [_A51, _A52, _A53, _A54, 0.0],
    [_A61, _A62, _A63, _A64, _A65],
])  # fmt: skip
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = (
    71 / 57600,
    -71 / 16695,
    71 / 1920,
    -17253 / 339200,
    22 / 525,
    -1 / 40,
)
# The continuous extension of order 4: the fifth coefficient of the interpolant.
_D1, _D3, _D4 = -12715105075 / 11282082432, 87487479700 / 32700410799, -10690763975 / 1880347072
_D5, _D6, _D7 = 701980252875 / 199316789632, -1453857185 / 822651844, 69997945 / 29380423
#: The tableau in the tangent's form (``tangent.explicit_tableau``).
TANGENT_A, TANGENT_B = explicit_tableau([[_A21], *[list(r) for r in _DP_A]],
                                        [_B1, 0.0, _B3, _B4, _B5, _B6])  # fmt: skip


@jit_inline
def step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew, rtol, atol):
    """One Dormand–Prince 5(4) step; returns the scaled RMS error estimate.

    ``f`` = rhs(y) on entry; the stages k2 … k6 go to rows 0-4 of ``k``; on return
    ``ynew`` holds the 5th-order solution and ``fnew`` = rhs(ynew) (first same as
    last). The step is acceptable when the returned error is ≤ 1; a non-finite error
    means the trial state overflowed. The stages are a loop around one call of the
    right-hand side (one inlined copy), summed term by term in the tableau's order.
    """
    n = y.size
    for s in range(5):
        for j in range(n):
            if s == 0:
                ytmp[j] = y[j] + h * _A21 * f[j]
            else:
                acc = _DP_A[s - 1, 0] * f[j]
                for r in range(s):
                    acc += _DP_A[s - 1, r + 1] * k[r, j]
                ytmp[j] = y[j] + h * acc
        rhs(ytmp, p, model, law, coupling, het, nb, ev, k[s])
    for j in range(n):
        ynew[j] = y[j] + h * (
            _B1 * f[j] + _B3 * k[1, j] + _B4 * k[2, j] + _B5 * k[3, j] + _B6 * k[4, j]
        )
    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
    err2 = 0.0
    for j in range(n):
        e = h * (
            _E1 * f[j] + _E3 * k[1, j] + _E4 * k[2, j] + _E5 * k[3, j] + _E6 * k[4, j]
            + _E7 * fnew[j]
        )  # fmt: skip
        scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
        err2 += (e / scale) ** 2
    return math.sqrt(err2 / n)


@jit_inline
def dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
    """The continuous extension's fifth coefficient r5 of every component into row 0 of
    ``dense``, from the step's stages k1 = ``f``, k3 … k6 (rows 1-4 of ``k``) and k7 =
    ``fnew``."""
    for j in range(y.size):
        dense[0, j] = h * (
            _D1 * f[j] + _D3 * k[1, j] + _D4 * k[2, j] + _D5 * k[3, j] + _D6 * k[4, j]
            + _D7 * fnew[j]
        )  # fmt: skip


@jit_inline
def tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
                 coupling, het):  # fmt: skip
    """The tangent carried over the step just taken (``tangent.explicit_tangent_step``)."""
    return explicit_tangent_step(TANGENT_A, TANGENT_B, y, f, h, k, delta, work, dk, blocks, p,
                                 nb, ev, model, law, coupling, het)  # fmt: skip
