"""RK4: the classical Runge–Kutta method of order 4 with a fixed step (the paper's
integrator), read between its steps with the cubic Hermite interpolant."""

from ...accelerate import jit_inline
from ..equations import rhs
from ..step import MEASURED
from ..tangent import explicit_tableau, explicit_tangent_step

NAME = "RK4"
ADAPTIVE = False  # the fixed step P_DT
EXPONENT = 0.0  # no controller
#: Rows of ``k``: the stages k2, k3, k4.
STAGE_ROWS = 3
MATRIX = False
DENSE_ROWS, DENSE_STAGES = 0, 0  # the cubic Hermite interpolant
#: Measured: the proved bound (``step.PROVED``, r5 = 0) holds for the cubic Hermite
#: interpolant too, but moves numbers (RODAS4's: the inertial configs' friction drops by
#: up to 1.3e-7) for no time measurable (``docs/internals.md``).
EXCURSION = MEASURED
TANGENT_ROWS = 4
TANGENT_CAP = False  # a fixed step: nothing to cap
#: The tableau in the tangent's form (``tangent.explicit_tableau``).
TANGENT_A, TANGENT_B = explicit_tableau([[0.5], [0.0, 0.5], [0.0, 0.0, 1.0]],
                                        [1 / 6, 1 / 3, 1 / 3, 1 / 6])  # fmt: skip


@jit_inline
def step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew, rtol, atol):
    """One classical RK4 step of size h from (y, f = rhs(y)) into ``ynew`` and its slope
    ``fnew``; the stages k2, k3, k4 go to rows 0-2 of ``k``. Returns 0 (no error
    control).

    The stages are a loop around one call of the right-hand side, so that numba
    inlines it once (each inlined copy costs compile time, see accelerate.py)."""
    n = y.size
    for s in range(3):  # y + h/2 f, y + h/2 k2, y + h k3
        if s == 0:
            for j in range(n):
                ytmp[j] = y[j] + 0.5 * h * f[j]
        else:
            c = 0.5 * h if s == 1 else h
            for j in range(n):
                ytmp[j] = y[j] + c * k[s - 1, j]
        rhs(ytmp, p, model, law, coupling, het, nb, ev, k[s])
    for j in range(n):
        ynew[j] = y[j] + h / 6.0 * (f[j] + 2.0 * k[0, j] + 2.0 * k[1, j] + k[2, j])
    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
    return 0.0


@jit_inline
def dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
    """None: the cubic Hermite interpolant needs no coefficient beyond the step's ends."""


@jit_inline
def tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
                 coupling, het):  # fmt: skip
    """The tangent carried over the step just taken (``tangent.explicit_tangent_step``)."""
    return explicit_tangent_step(TANGENT_A, TANGENT_B, y, f, h, k, delta, work, dk, blocks, p,
                                 nb, ev, model, law, coupling, het)  # fmt: skip
