"""Steppers (RK4, DOPRI5, DOP853, RODAS4) and the dense output that locates extrema
inside a step.

Extrema are located inside a step with the interpolant of the step: DOPRI5's
continuous extension of order 4, DOP853's of order 7, cubic Hermite for RK4 and
RODAS4. All are one nested polynomial in θ (:func:`dense_value`) whose first four
coefficients come from the step's ends and slopes and the rest from its stages
(:func:`dense_tail`).
"""

import math

import numpy as np

from ..accelerate import jit, jit_inline
from . import tableau_dop853
from .equations import jacobian, rhs
from .layout import DOP853, DOPRI5, RK4, ROSENBROCK

# Dormand–Prince 5(4) tableau (Hairer, Nørsett & Wanner, Table II.5.2).
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

# RODAS4 (Hairer & Wanner, Solving ODEs II, section VI.4; rodas.f, METH = 1),
# autonomous form: row s of _RODAS_A gives stage s + 1's argument y + Σ a_sj k_j,
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


@jit
def lu_factor(a, perm):
    """In-place LU factorisation of ``a`` with partial pivoting; ``perm[i]`` is the
    original index of the i-th pivot row.

    A zero pivot is not trapped: it yields non-finite values, which the caller's
    error estimate turns into a rejected step.
    """
    n = a.shape[0]
    for k in range(n):
        perm[k] = k
    for k in range(n):
        pk = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[pk, k]):
                pk = i
        if pk != k:
            tmp_row = perm[k]
            perm[k] = perm[pk]
            perm[pk] = tmp_row
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[pk, j]
                a[pk, j] = tmp
        for i in range(k + 1, n):
            a[i, k] /= a[k, k]
            if a[i, k] != 0.0:  # coupling Jacobians are sparse: skip rows with nothing to do
                for j in range(k + 1, n):
                    a[i, j] -= a[i, k] * a[k, j]


@jit
def lu_solve(a, perm, b, x):
    """Solve ``a x = b`` into ``x`` (≠ ``b``) from the factors of :func:`lu_factor`."""
    n = a.shape[0]
    for i in range(n):
        acc = b[perm[i]]
        for j in range(i):
            if a[i, j] != 0.0:
                acc -= a[i, j] * x[j]
        x[i] = acc
    for ii in range(n):
        i = n - 1 - ii
        acc = x[i]
        for j in range(i + 1, n):
            if a[i, j] != 0.0:
                acc -= a[i, j] * x[j]
        x[i] = acc / a[i, i]


@jit_inline
def step_rk4(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew):
    """One classical RK4 step of size h from (y, f = rhs(y)) into ``ynew``; the stages
    k2, k3, k4 go to rows 0-2 of ``k``.

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


@jit_inline
def step_dopri5(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew, fnew, rtol, atol):
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


# DOP853 (Hairer, Nørsett & Wanner I, section II.10; tableau_dop853.py).
_A8 = tableau_dop853.A
_B8 = tableau_dop853.B
_E8_5 = tableau_dop853.E5
_E8_3 = tableau_dop853.E3
_D8 = tableau_dop853.D
_S8 = tableau_dop853.N_STAGES  # 12: K_0 = f, K_1 … K_11, then K_12 = f(y_new)
_S8_DENSE = tableau_dop853.N_STAGES_DENSE  # 16: … K_13 … K_15 for the interpolant


@jit_inline
def step_dop853(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew, fnew, rtol, atol):
    """One DOP853 step (order 8); returns its error norm, DOP853's blend of the 5th- and
    3rd-order estimates, ‖e5‖² / √(‖e5‖² + 0.01 ‖e3‖²), scaled as for DOPRI5.

    ``f`` = rhs(y) on entry; the stages K_1 … K_11 go to rows 0-10 of ``k`` (15, n),
    rows 12-14 are left for the dense output's (:func:`dense_dop853`); on return
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
    err5 = 0.0
    err3 = 0.0
    for j in range(n):
        e5 = _E8_5[0] * f[j] + _E8_5[_S8] * fnew[j]
        e3 = _E8_3[0] * f[j] + _E8_3[_S8] * fnew[j]
        for r in range(1, _S8):
            e5 += _E8_5[r] * k[r - 1, j]
            e3 += _E8_3[r] * k[r - 1, j]
        scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    if not (err5 < math.inf and err3 < math.inf):
        # The sums square the estimates before h scales them: with slopes beyond ~1e150
        # (a blow-up past a cap of 1e300) they overflow at any h, the blend read
        # err5 / √inf = 0 and accepted steps that no longer advanced t, until the step
        # budget ran out (undecided; test_kernels.py::test_huge_cap_still_classifies_runaway).
        # Then the same norm with h inside the squares, as only here: elsewhere the
        # numbers stay bit for bit those of DOP853's form.
        err5 = 0.0
        err3 = 0.0
        for j in range(n):
            e5 = _E8_5[0] * f[j] + _E8_5[_S8] * fnew[j]
            e3 = _E8_3[0] * f[j] + _E8_3[_S8] * fnew[j]
            for r in range(1, _S8):
                e5 += _E8_5[r] * k[r - 1, j]
                e3 += _E8_3[r] * k[r - 1, j]
            scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
            err5 += (h * e5 / scale) ** 2
            err3 += (h * e3 / scale) ** 2
        return err5 / math.sqrt((err5 + 0.01 * err3) * n)
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * n)


@jit
def dense_dop853(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense):
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


@jit
def step_rosenbrock(
    y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew, rtol, atol
):
    """One linearly implicit RODAS4 step (order 4, embedded order 3, L-stable).

    Solves (I/(γh) − J) k_s = f(y + Σ a_sj k_j) + Σ c_sj k_j / h for six stages
    with the analytic Jacobian J at y; the stiff decay of the inertial force
    towards force balance in stick phases (rate A e^(−ℓ)/M̂) costs nothing.
    ``f`` = rhs(y) on entry; ``k`` is (6, n) scratch, ``mat`` (n, n), ``perm`` (n).
    On return ``ynew`` holds the solution and ``fnew`` = rhs(ynew); returns the
    scaled RMS error estimate (acceptable when ≤ 1, non-finite on overflow).
    """
    n = y.size
    jacobian(y, f, p, model, law, coupling, het, nb, ev, mat)
    diag = 1.0 / (_RODAS_GAMMA * h)
    for i in range(n):
        for j in range(n):
            mat[i, j] = -mat[i, j]
        mat[i, i] += diag
    lu_factor(mat, perm)
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
        lu_solve(mat, perm, fnew, k[s])
    err2 = 0.0
    for j in range(n):
        ynew[j] = ytmp[j] + k[5, j]
        scale = atol + rtol * max(abs(y[j]), abs(ynew[j]))
        err2 += (k[5, j] / scale) ** 2
    rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
    return math.sqrt(err2 / n)


# Dormand–Prince continuous extension of order 4 (Hairer, Nørsett & Wanner, dense
# output of DOPRI5, section II.6): the fifth coefficient of the interpolant.
_D1, _D3, _D4 = -12715105075 / 11282082432, 87487479700 / 32700410799, -10690763975 / 1880347072
_D5, _D6, _D7 = 701980252875 / 199316789632, -1453857185 / 822651844, 69997945 / 29380423


@jit_inline
def dense_tail(method, j, h, f, k3, k4, k5, k6, fnew, dense):
    """Coefficients r5 … r8 of the interpolant of component ``j`` over a step of size h
    (:func:`dense_value`): DOPRI5's r5 (stages k1 = ``f``, k3 … k6, k7 = ``fnew``),
    DOP853's four from ``dense`` (filled by :func:`dense_dop853`), none for RK4 and
    RODAS4 (cubic Hermite)."""
    if method == DOP853:
        return (dense[0, j], dense[1, j], dense[2, j], dense[3, j])
    if method != DOPRI5:
        return (0.0, 0.0, 0.0, 0.0)
    r5 = h * (_D1 * f[j] + _D3 * k3[j] + _D4 * k4[j] + _D5 * k5[j] + _D6 * k6[j] + _D7 * fnew[j])
    return (r5, 0.0, 0.0, 0.0)


@jit_inline
def dense_mix(a, r, b, s):
    """The coefficients r5 … r8 of a r + b s (a linear combination of components)."""
    return (a * r[0] + b * s[0], a * r[1] + b * s[1], a * r[2] + b * s[2], a * r[3] + b * s[3])


@jit_inline
def dense_value(y0, y1, d0, d1, h, r, theta):
    """Interpolant at fraction ``theta`` of a step of size h from (y0, slope d0) to
    (y1, slope d1) with the coefficients ``r`` = (r5, r6, r7, r8) of
    :func:`dense_tail`: y0 + θ(r2 + θ'(r3 + θ(r4 + θ'(r5 + θ(r6 + θ'(r7 + θ r8)))))),
    θ' = 1 − θ, r2 … r4 from the ends. DOPRI5's continuous extension (order 4) has
    r5 only, DOP853's (order 7) all four, the cubic Hermite interpolant (RK4,
    RODAS4) none.

    The extrema of a cycle are read from it: with the cubic Hermite interpolant over
    0.5 D0/V steps they scattered by ~1e-4 of the amplitude from cycle to cycle,
    too much to extrapolate the cycle-to-cycle sequence near Kc
    (test_classification.py); the dense output is as accurate as the steps.
    """
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    r5, r6, r7, r8 = r
    u = 1.0 - theta
    return y0 + theta * (
        r2 + u * (r3 + theta * (r4 + u * (r5 + theta * (r6 + u * (r7 + theta * r8)))))
    )


#: How far the interpolant of a step may stray beyond the step's ends where a slope
#: changes sign, in units of the ends' difference plus h × their slopes, for the
#: methods whose bound :func:`dense_excursion` does not prove. Measured up to 8.4 for
#: DOP853 on the wiggles of a decayed oscillation, where its interpolant's higher terms
#: dominate (test_kernels.py).
EXCURSION_FACTOR = 10.0
_CUBE_SLOPE = 4.0 / 27.0  # max of θ(1 − θ)² over [0, 1]
_CUBE_CHORD = math.sqrt(3.0) / 18.0  # max of θ(1 − θ)|1 − 2θ| over [0, 1]


@jit_inline
def dense_excursion(method, y0, y1, d0, d1, h, r5):
    """A bound on how far the interpolant of a step of size h from (y0, slope d0) to
    (y1, slope d1) strays beyond its ends: where a slope changes sign, its extremum lies
    within this distance of them.

    DOPRI5's interpolant departs from the chord by θθ'(θ' h d0 − θ h d1 − (1 − 2θ)(y1 −
    y0) + θθ' r5) (:func:`dense_value`; ``r5`` its fifth coefficient), and over θ ∈
    [0, 1] θθ'² and θ²θ' ≤ 4/27, θθ'|1 − 2θ| ≤ √3/18, θ²θ'² ≤ 1/16: a proved bound. The
    other methods take ``EXCURSION_FACTOR`` × (|y1 − y0| + h (|d0| + |d1|)): DOP853's
    r6 … r8 cost three more stages, and the cubic Hermite interpolant of RK4 and RODAS4
    keeps the factor too (its proved bound, r5 = 0, would move the inertial configs'
    friction drops by up to 1.3e-7 for no measurable time: ``docs/performance.md``)."""
    if method == DOPRI5:
        return _CUBE_SLOPE * h * (abs(d0) + abs(d1)) + _CUBE_CHORD * abs(y1 - y0) + abs(r5) / 16.0
    return EXCURSION_FACTOR * (abs(y1 - y0) + h * (abs(d0) + abs(d1)))


@jit_inline
def dense_slope(y0, y1, d0, d1, h, r, theta):
    """h × the time derivative of :func:`dense_value` at fraction ``theta``."""
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    r5, r6, r7, r8 = r
    u = 1.0 - theta
    # DOPRI5's terms first, DOP853's added: with r6 = r7 = r8 = 0 the same numbers
    return (
        r2
        + (u - theta) * r3
        + theta * (2.0 - 3.0 * theta) * r4
        + 2.0 * theta * u * (u - theta) * r5
        + theta * theta * u * (3.0 * u - 2.0 * theta) * r6
        + 3.0 * theta * theta * u * u * (u - theta) * r7
        + theta * theta * theta * u * u * (4.0 * u - 3.0 * theta) * r8
    )


@jit_inline
def dense_extremum(y0, y1, d0, d1, h, r):
    """Fraction θ ∈ [0, 1] of the step where the interpolant's slope vanishes, given
    slopes d0 and d1 of opposite sign: the Illinois variant of false position, which
    keeps the root bracketed and converges superlinearly (~8 slope evaluations where
    bisection to round-off took 50), until the bracket stops shrinking."""
    lo = 0.0
    hi = 1.0
    g_lo = h * d0
    g_hi = h * d1
    rising = d0 > 0.0
    kept = 0  # the end the last step kept (+1: hi, −1: lo); kept twice, its slope is halved
    theta = 0.5
    for _ in range(60):
        theta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        if not (lo < theta < hi):
            break
        g = dense_slope(y0, y1, d0, d1, h, r, theta)
        if g == 0.0:
            break
        if (g > 0.0) == rising:
            lo = theta
            g_lo = g
            if kept == 1:
                g_hi *= 0.5
            kept = 1
        else:
            hi = theta
            g_hi = g
            if kept == -1:
                g_lo *= 0.5
            kept = -1
    return min(max(theta, lo), hi)


@jit
def dense_crossing(y0, y1, d0, d1, h, r, level):
    """Fraction θ of the step where the interpolant rises through ``level``
    (y0 < level ≤ y1; bisection, 50 halvings)."""
    lo = 0.0
    hi = 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if dense_value(y0, y1, d0, d1, h, r, mid) < level:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@jit_inline
def next_step_size(method, h, err, max_step):
    """The step after one of size ``h`` with error norm ``err`` (D0/V).

    RK4 keeps its fixed step. The adaptive methods use the standard controller
    0.9 err^(−1/(q+1)) (q: order of the error estimate: 3 for RODAS4, 4 for
    DOPRI5, 7 for DOP853's blended estimate), growing at most 5× and
    at most to ``max_step`` after an accepted step, shrinking at least 5× after a
    rejected one (and 5× when the error is not finite).
    """
    if method == RK4:
        return h
    expo = -0.2
    if method == ROSENBROCK:
        expo = -0.25
    elif method == DOP853:
        expo = -0.125
    if err <= 1.0:
        return min(max_step, h * min(5.0, 0.9 * max(err, 1e-10) ** expo))
    if math.isfinite(err):
        return h * max(0.2, 0.9 * err**expo)
    return h * 0.2


#: Rows of the stage scratch ``k``: DOPRI5's k2 … k6, DOP853's K_1 … K_15 (row 11 unused).
STAGE_ROWS, STAGE_ROWS_DOP853 = 5, 15
#: Rows of RODAS4's stage scratch.
ROS_STAGE_ROWS = 6


@jit
def step_scratch(method, n):
    """Scratch of the explicit steps for a state of ``n`` values: f, ynew, fnew, ytmp,
    the stages as the rows of one array (``STAGE_ROWS`` or, for DOP853,
    ``STAGE_ROWS_DOP853``) and DOP853's interpolant coefficients (4, n; (4, 0) for
    the other methods)."""
    rows = STAGE_ROWS_DOP853 if method == DOP853 else STAGE_ROWS
    width = n if method == DOP853 else 0
    return (
        np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty((rows, n)),
        np.zeros((4, width)),
    )  # fmt: skip


@jit
def rosenbrock_scratch(method, n):
    """Scratch of the RODAS4 step (stages, matrix, pivots); empty for other methods."""
    if method == ROSENBROCK:
        return np.empty((ROS_STAGE_ROWS, n)), np.empty((n, n)), np.empty(n, np.int64)
    return np.empty((0, n)), np.empty((0, 0)), np.empty(0, np.int64)
