"""DOP853: Dormand and Prince's explicit Runge–Kutta pair of order 8(5,3) with its
continuous extension of order 7 (Hairer, Nørsett & Wanner I, section II.10; the
coefficients in ``tableau_dop853.py``). Adaptive, first same as last; the default
method."""

import math

import numpy as np

from ...accelerate import jit, jit_inline
from ..equations import rhs
from ..step import MEASURED
from ..tangent import explicit_tangent_step
from . import tableau_dop853

NAME = "DOP853"
ADAPTIVE = True
EXPONENT = -0.125  # the blended error estimate, of order 7
#: Rows of ``k``: the stages K_1 … K_11, then K_13 … K_15 of the interpolant (row 11
#: unused: K_12 is ``fnew``).
STAGE_ROWS = 15
MATRIX = False
#: The interpolant's coefficients r5 … r8 cost three more stages (K_13 … K_15): the loop
#: computes them only where they are read (``classify.extrema.dense_needed``).
DENSE_ROWS, DENSE_STAGES = 4, 3
#: Measured (``step.EXCURSION_FACTOR``): its r6 … r8 would cost the three stages to bound.
EXCURSION = MEASURED
TANGENT_ROWS = tableau_dop853.N_STAGES
TANGENT_CAP = True

_A8 = tableau_dop853.A
_B8 = tableau_dop853.B
_E8_5 = tableau_dop853.E5
_E8_3 = tableau_dop853.E3
_D8 = tableau_dop853.D
_S8 = tableau_dop853.N_STAGES  # 12: K_0 = f, K_1 … K_11, then K_12 = f(y_new)
_S8_DENSE = tableau_dop853.N_STAGES_DENSE  # 16: … K_13 … K_15 for the interpolant
#: The tableau in the tangent's form (``tangent.explicit_tableau``): the step's stages.
TANGENT_A = np.ascontiguousarray(_A8[:_S8, :_S8])
TANGENT_B = np.ascontiguousarray(_B8)


@jit_inline
def error_sums(y, ynew, f, fnew, k, factor, rtol, atol):
    """The sums of the squared 5th- and 3rd-order error estimates of a step, each
    times ``factor`` (1, or h where the plain sums overflow) over its tolerance."""
    err5 = 0.0
    err3 = 0.0
    for j in range(y.size):
        e5 = _E8_5[0] * f[j] + _E8_5[_S8] * fnew[j]
        e3 = _E8_3[0] * f[j] + _E8_3[_S8] * fnew[j]
        for r in range(1, _S8):
            e5 += _E8_5[r] * k[r - 1, j]
            e3 += _E8_3[r] * k[r - 1, j]
        scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
        err5 += (factor * e5 / scale) ** 2
        err3 += (factor * e3 / scale) ** 2
    return err5, err3


@jit_inline
def step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew, rtol, atol):
    """One DOP853 step (order 8); returns its error norm, DOP853's blend of the 5th- and
    3rd-order estimates, ‖e5‖² / √(‖e5‖² + 0.01 ‖e3‖²), scaled as for DOPRI5.

    ``f`` = rhs(y) on entry; the stages K_1 … K_11 go to rows 0-10 of ``k`` (15, n),
    rows 12-14 are left for the dense output's (:func:`dense`); on return
    ``ynew`` holds the 8th-order solution and ``fnew`` = rhs(ynew). The stages are a
    loop around one call of the right-hand side (one inlined copy).
    """
    n = y.size
    for s in range(1, _S8):
        for j in range(n):
            acc = _A8[s, 0] * f[j]
            for r in range(1, s):
                acc += _A8[s, r] * k[r - 1, j]
            ytmp[j] = y[j] + h * acc
        rhs(ytmp, p, model, law, coupling, het, nb, ev, k[s - 1])
    for j in range(n):
        acc = _B8[0] * f[j]
        for r in range(1, _S8):
            acc += _B8[r] * k[r - 1, j]
        ynew[j] = y[j] + h * acc
    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
    err5, err3 = error_sums(y, ynew, f, fnew, k, 1.0, rtol, atol)
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    if not (err5 < math.inf and err3 < math.inf):
        # The sums square the estimates before h scales them: with slopes beyond ~1e150
        # (a blow-up past a cap of 1e300) they overflow at any h, the blend read
        # err5 / √inf = 0 and accepted steps that no longer advanced t, until the step
        # budget ran out (undecided; test_kernels.py::test_huge_cap_still_classifies_runaway).
        # Then the same norm with h inside the squares, as only here: elsewhere the
        # numbers stay bit for bit those of DOP853's form.
        err5, err3 = error_sums(y, ynew, f, fnew, k, h, rtol, atol)
        return err5 / math.sqrt((err5 + 0.01 * err3) * n)
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * n)


@jit
def dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
    """DOP853's interpolant of the step just taken (order 7): its three extra stages
    K_13 … K_15 into rows 12-14 of ``k``, then rows 3-6 of the interpolant's
    coefficients, h Σ D K, into rows 0-3 of ``dense`` (4, n) (:func:`dense_tail`)."""
    n = y.size
    for s in range(_S8 + 1, _S8_DENSE):
        for j in range(n):
            acc = _A8[s, 0] * f[j] + _A8[s, _S8] * fnew[j]
            for r in range(1, s):
                if r != _S8:
                    acc += _A8[s, r] * k[r - 1, j]
            ytmp[j] = y[j] + h * acc
        rhs(ytmp, p, model, law, coupling, het, nb, ev, k[s - 1])
    for c in range(4):
        for j in range(n):
            acc = _D8[c, 0] * f[j] + _D8[c, _S8] * fnew[j]
            for r in range(1, _S8_DENSE):
                if r != _S8:
                    acc += _D8[c, r] * k[r - 1, j]
            dense[c, j] = h * acc


@jit_inline
def tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
                 coupling, het):  # fmt: skip
    """The tangent carried over the step just taken (``tangent.explicit_tangent_step``)."""
    return explicit_tangent_step(TANGENT_A, TANGENT_B, y, f, h, k, delta, work, dk, blocks, p,
                                 nb, ev, model, law, coupling, het)  # fmt: skip
