"""BS23: the Bogacki–Shampine pair of order 3(2) (Bogacki & Shampine 1989; MATLAB's
``ode23``, SciPy's ``RK23``), explicit, adaptive, first same as last. Its natural
interpolant is the cubic Hermite one of the step's ends and slopes (order 3), so its
extrema need no coefficient beyond them. Cheap per step (three evaluations of the
right-hand side), for loose tolerances."""

import math

from ...accelerate import jit_inline
from ..equations import rhs
from ..step import PROVED
from ..tangent import explicit_tableau, explicit_tangent_step

NAME = "BS23"
ADAPTIVE = True
EXPONENT = -1.0 / 3.0  # error estimate of order 2
#: Rows of ``k``: the stages k2 and k3 (k4 is ``fnew``).
STAGE_ROWS = 2
MATRIX = False
DENSE_ROWS, DENSE_STAGES = 0, 0  # the cubic Hermite interpolant
#: Proved (``step.excursion``, r5 = 0): the cubic Hermite interpolant is its own.
EXCURSION = PROVED
TANGENT_ROWS = 3
TANGENT_CAP = True

_A21 = 1 / 2
_A32 = 3 / 4
_B1, _B2, _B3 = 2 / 9, 1 / 3, 4 / 9
# the error: the 3rd-order solution minus the embedded 2nd-order one, per h
_E1, _E2, _E3, _E4 = 5 / 72, -1 / 12, -1 / 9, 1 / 8
#: The tableau in the tangent's form (``tangent.explicit_tableau``).
TANGENT_A, TANGENT_B = explicit_tableau([[_A21], [0.0, _A32]], [_B1, _B2, _B3])


@jit_inline
def step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew, rtol, atol):
    """One Bogacki–Shampine step from (y, f = rhs(y)) into ``ynew`` (3rd order) and its
    slope ``fnew``; the stages k2, k3 go to rows 0-1 of ``k``. Returns the scaled RMS
    error estimate (acceptable when ≤ 1, non-finite on overflow). The stages are a loop
    around one call of the right-hand side (one inlined copy)."""
    n = y.size
    for s in range(2):  # y + h/2 f, y + 3h/4 k2
        for j in range(n):
            ytmp[j] = y[j] + h * (_A21 * f[j] if s == 0 else _A32 * k[0, j])
        rhs(ytmp, p, model, law, coupling, het, nb, ev, k[s])
    for j in range(n):
        ynew[j] = y[j] + h * (_B1 * f[j] + _B2 * k[0, j] + _B3 * k[1, j])
    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
    err2 = 0.0
    for j in range(n):
        e = h * (_E1 * f[j] + _E2 * k[0, j] + _E3 * k[1, j] + _E4 * fnew[j])
        scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
        err2 += (e / scale) ** 2
    return math.sqrt(err2 / n)


@jit_inline
def dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
    """None: the cubic Hermite interpolant needs no coefficient beyond the step's ends."""


@jit_inline
def tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
                 coupling, het):  # fmt: skip
    """The tangent carried over the step just taken (``tangent.explicit_tangent_step``)."""
    return explicit_tangent_step(TANGENT_A, TANGENT_B, y, f, h, k, delta, work, dk, blocks, p,
                                 nb, ev, model, law, coupling, het)  # fmt: skip
