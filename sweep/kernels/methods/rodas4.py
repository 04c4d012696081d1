"""RODAS4: a linearly implicit Rosenbrock method of order 4 (embedded order 3,
L-stable; Hairer & Wanner, Solving ODEs II, section VI.4; rodas.f, METH = 1), for the
stiff inertial model (its default), read between its steps with the cubic Hermite
interpolant. Its tangent step is its own: the same stages solved with the step's LU
factors, plus the change of its matrix along the tangent."""

import math

import numpy as np
from numba import literally

from ...accelerate import jit, jit_inline
from ..equations import jacobian, rhs, rhs_curvature, rhs_jvp
from ..linalg import lu_factor, lu_solve
from ..step import MEASURED
from ..tangent import renormalise

NAME = "RODAS4"
ADAPTIVE = True
EXPONENT = -0.25  # error estimate of order 3
#: Rows of ``k``: the six stages (the last is the error estimate).
STAGE_ROWS = 6
MATRIX = True  # I/(γh) − J, factorised in place
DENSE_ROWS, DENSE_STAGES = 0, 0  # the cubic Hermite interpolant
#: Measured: the proved bound (``step.PROVED``, r5 = 0) would move the inertial configs'
#: friction drops by up to 1.3e-7 for no time measurable (``docs/internals.md``).
EXCURSION = MEASURED
TANGENT_ROWS = STAGE_ROWS
#: Not capped: |J δ| includes the stiff decay it need not resolve (``tangent.TANGENT_TURN``).
TANGENT_CAP = False

# Autonomous form: row s of _RODAS_A gives stage s + 1's argument y + Σ a_sj k_j,
# row s of _RODAS_C its coupling Σ c_sj k_j / h; the last row's stage is the error.
_RODAS_GAMMA = 0.25
_RODAS_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [1.544, 0.0, 0.0, 0.0, 0.0],
        [0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0],
        [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0],
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0.0],
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0],
    ]
)
_RODAS_C = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [-5.6688, 0.0, 0.0, 0.0, 0.0],
        [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0],
        [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0],
        [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0.0],
        [8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136,
         -6.058818238834054],
    ]
)  # fmt: skip


def rosenbrock(name, factorise, solve):
    """RODAS4's ``step`` and ``tangent_step`` for a matrix I/(γh) − J built and
    factorised by ``factorise(y, f, diag, p, model, law, coupling, het, nb, ev, mat,
    perm)`` (``diag`` = 1/(γh), V/D0) and solved by ``solve(mat, perm, b, x, nb, model,
    coupling)`` (x = (I/(γh) − J)⁻¹ b, ``x`` ≠ ``b``, ``b`` may be overwritten): one
    stage loop for every way of solving. Each function is named after ``name``
    (``accelerate``: the disk cache keys on the name)."""

    def step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew,
             rtol, atol):  # fmt: skip
        """One linearly implicit RODAS4 step (order 4, embedded order 3, L-stable).

        Solves (I/(γh) − J) k_s = f(y + Σ a_sj k_j) + Σ c_sj k_j / h for six stages
        with the analytic Jacobian J at y; the stiff decay of the inertial force
        towards force balance in stick phases (rate A e^(−ℓ)/M̂) costs nothing.
        ``f`` = rhs(y) on entry; ``k`` is (6, n) scratch, ``mat``/``perm`` the method's.
        On return ``ynew`` holds the solution and ``fnew`` = rhs(ynew); returns the
        scaled RMS error estimate (acceptable when ≤ 1, non-finite on overflow).
        """
        n = y.size
        factorise(y, f, 1.0 / (_RODAS_GAMMA * h), p, model, law, coupling, het, nb, ev, mat,
                  perm)  # fmt: skip
        for s in range(6):
            if s == 0:
                for j in range(n):
                    fnew[j] = f[j]
            else:
                for j in range(n):
                    acc = y[j]
                    for r in range(s):
                        acc += _RODAS_A[s, r] * k[r, j]
                    ytmp[j] = acc
                rhs(ytmp, p, model, law, coupling, het, nb, ev, fnew)
            for j in range(n):
                acc = 0.0
                for r in range(s):
                    acc += _RODAS_C[s, r] * k[r, j]
                fnew[j] += acc / h
            solve(mat, perm, fnew, k[s], nb, model, coupling)
        err2 = 0.0
        for j in range(n):
            ynew[j] = ytmp[j] + k[5, j]
            scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
            err2 += (k[5, j] / scale) ** 2
        rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
        return math.sqrt(err2 / n)

    def tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
                     coupling, het):  # fmt: skip
        """Carry δ (unit length) over the accepted step of size ``h`` from ``y`` (slope
        ``f``) and renormalise it; returns the logarithm of its growth and |J δ| at ``y``
        (V/D0). The step's stages ``k`` and the factors ``mat``/``perm`` of its matrix
        give the derivative of the step along δ; ``work``, ``dk`` and ``blocks`` are the
        scratch of ``tangent.tangent_arrays``. Compiled per variant (``literally``): its
        codes are constants of the grid kernel.

        (I/(γh) − J) k_s = f(Y_s) + Σ c_sr k_r / h, Y_s = y + Σ a_sr k_r, y1 = Y_5 + k_5:
        along δ, (I/(γh) − J) dk_s = J(Y_s) dY_s + Σ c_sr dk_r / h + f''(y)[δ, k_s].
        """
        literally(model)
        literally(law)
        literally(coupling)
        literally(het)
        n = y.size
        arg, direction, acc, curv = work[0], work[1], work[2], work[3]
        rate = 0.0
        for s in range(STAGE_ROWS):
            for j in range(n):
                ya = y[j]
                da = delta[j]
                for r in range(s):
                    ya += _RODAS_A[s, r] * k[r, j]
                    da += _RODAS_A[s, r] * dk[r, j]
                arg[j] = ya
                direction[j] = da
            rhs_jvp(arg, direction, p, model, law, coupling, het, nb, ev, blocks[0], acc)
            if s == 0:
                for j in range(n):
                    rate += acc[j] ** 2
            rhs_curvature(y, delta, k[s], p, model, law, coupling, het, nb, ev, blocks, curv)
            for j in range(n):
                c = 0.0
                for r in range(s):
                    c += _RODAS_C[s, r] * dk[r, j]
                acc[j] += c / h + curv[j]
            solve(mat, perm, acc, dk[s], nb, model, coupling)
        last = STAGE_ROWS - 1
        for j in range(n):
            delta[j] = direction[j] + dk[last, j]
        return renormalise(delta), math.sqrt(rate)

    step.__qualname__ = f"{name}_step"
    tangent_step.__qualname__ = f"{name}_tangent_step"
    return jit(step), jit(tangent_step)


@jit_inline
def dense_factorise(y, f, diag, p, model, law, coupling, het, nb, ev, mat, perm):
    """The dense matrix I/(γh) − J at ``y`` (``diag`` = 1/(γh), V/D0) into ``mat``
    (n × n), factorised in place (``linalg.lu_factor``, pivots ``perm``)."""
    n = y.size
    jacobian(y, f, p, model, law, coupling, het, nb, ev, mat)
    for i in range(n):
        for j in range(n):
            mat[i, j] = -mat[i, j]
        mat[i, i] += diag
    lu_factor(mat, perm)


@jit_inline
def dense_solve(mat, perm, b, x, nb, model, coupling):
    """x = (I/(γh) − J)⁻¹ b from the factors of :func:`dense_factorise`."""
    lu_solve(mat, perm, b, x)


def matrix_columns(model, coupling):
    """Columns of the method's matrix for ``model`` and ``coupling`` (codes): 0, n (the
    dense n × n matrix)."""
    return 0


step, tangent_step = rosenbrock("rodas4", dense_factorise, dense_solve)


@jit_inline
def dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
    """None: the cubic Hermite interpolant needs no coefficient beyond the step's ends."""
