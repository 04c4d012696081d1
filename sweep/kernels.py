"""Numba kernels: right-hand side, steppers and the per-system integration loop.

Only jitted loops live here; the equations are documented in ``sweep/physics.py``.
Everything a kernel needs is passed as an argument (numba's cache freezes
globals, so the module-level integers below are true constants: column indices
and codes shared with the Python side).

State of one system with ``nb`` blocks: ``y[i] = ℓ_i`` (ln v/V), ``y[nb+i] = ψ_i``
(ln VΦ/D0) and, for the inertial model, ``y[2nb+i] = z_i`` (inertial force
m dv/dt per unit normal load). Time τ is in units of D0/V.

Each run keeps only running statistics over the current oscillation cycle (from
one maximum of ℓ_0 to the next) and over the last completed one, so memory does
not depend on run length. Extrema are located inside a step with the cubic
interpolant of the step (DOPRI5's dense output; cubic Hermite for RK4 and RODAS4).
"""

import functools
import math

import numpy as np

from .accelerate import jit, jit_inline

# --- codes shared with the Python side --------------------------------------
QUASI_STATIC, QUASI_DYNAMIC, INERTIAL = 0, 1, 2
AGING, SLIP = 0, 1
DOPRI5, RK4, ROSENBROCK = 0, 1, 2
STEADY, STICK_SLIP, RUNAWAY, UNDECIDED = 0, 1, 2, 3
CHAIN, RING, ALL = 0, 1, 2  # coupling springs: neighbours of a chain, of a ring, every pair
# A decaying oscillation is called steady only once it is this small (peak-to-peak
# ln v/V of every block), i.e. in the linear regime where decay is geometric: see
# steady_verdict.
LINEAR_AMPLITUDE = 0.1
# Cycle values that change by less than NOISE_FACTOR * (atol + rtol |x|), ten times
# the integrator's local error tolerance, from one cycle to the next count as
# converged to round-off (their ratio of differences would be noise).
NOISE_FACTOR = 10.0
# Cycles of history kept per observable (the extrapolation uses the last four).
HISTORY = 4

# --- columns of the per-system parameter array (all dimensionless) ----------
(
    P_A,  # direct effect
    P_B,  # evolution effect
    P_KAPPA1,  # driving stiffness K D0/W
    P_KAPPA2,  # coupling stiffness k2 D0/W
    P_ETA,  # radiation damping ηV/W
    P_MASS,  # mass mV²/(W D0)
    P_TAU_END,  # end time (D0/V)
    P_DT,  # fixed step of rk4 (D0/V)
    P_MAX_STEP,  # largest adaptive step (D0/V)
    P_TAU_MAX,  # unsettled runs continue up to this time (D0/V), ≥ P_TAU_END
    P_LIN_GROWTH,  # max Re λ of the linearisation at steady sliding (V/D0)
) = range(11)
N_PARAMS = 11
# Rows whose blocks differ have N_BLOCK_PARAMS × nb more columns after N_PARAMS:
# column N_PARAMS + k nb + i holds quantity k of block i (B_* below). Without them
# (p.size == N_PARAMS) every block takes P_A, P_B, P_KAPPA1 and rate factor 1.
(
    B_A,  # direct effect of block i
    B_B,  # evolution effect of block i
    B_KAPPA1,  # driving stiffness K_i D0/W (D0: the reference D0)
    B_RATE,  # state-rate factor D0/D0_i
) = range(4)
N_BLOCK_PARAMS = 4

# --- entries of the settings array, shared by all systems of a sweep --------
(
    S_MODEL,  # QUASI_STATIC | QUASI_DYNAMIC | INERTIAL
    S_LAW,  # AGING | SLIP
    S_METHOD,  # DOPRI5 | RK4 | ROSENBROCK
    S_NBLOCKS,  # number of blocks
    S_RTOL,  # relative tolerance of the adaptive methods
    S_ATOL,  # absolute tolerance of the adaptive methods
    S_MAX_STEPS,  # step budget per run (accepted + rejected)
    S_LNV_CAP,  # runaway when any ln(v/V) exceeds this
    S_STEADY_AMP,  # steady when every |state variable| falls below this
    S_ACCURACY,  # relative accuracy of the extrapolated limit that settles a run
    S_CONFIRM_CYCLES,  # consecutive cycles a verdict must hold to settle a run early
    S_EARLY_EXIT,  # 1: stop as soon as the regime is settled
    S_SLIP_LNV,  # a block slips (slip events, R_SLIP_PARTICIPATION) while ℓ_i exceeds this
    S_COUPLING,  # CHAIN | RING | ALL
) = range(14)
N_SETTINGS = 14

# --- columns of the per-system statistics array -----------------------------
(
    R_REGIME,  # STEADY | STICK_SLIP | RUNAWAY | UNDECIDED
    R_TAU_FINAL,  # time the run stopped (D0/V)
    R_N_STEPS,  # accepted steps
    R_N_REJECTED,  # rejected steps
    R_LNV_MAX,  # max ln(v/V) over blocks, final window
    R_LNV_MIN,  # min ln(v/V) over blocks, final window
    R_PERIOD,  # last peak-to-peak time of ℓ_0 (D0/V)
    R_GROWTH,  # envelope growth rate from the last two cycles (V/D0)
    R_FRICTION_DROP,  # max over blocks of max − min friction in the final window
    R_TAU_RUNAWAY,  # time ℓ crossed the cap or went non-finite (D0/V)
    R_SYNC_ERROR,  # max |ℓ_i − ℓ_0| over blocks, final window
    R_PHASE_LAG,  # (t peak of ℓ_last − t peak of ℓ_0) / period, in [−0.5, 0.5)
    R_N_PEAKS,  # maxima of ℓ_0 seen
    R_LNV_MAX_RUN,  # max ln(v/V) over the whole run
    R_N_RECORDED,  # points written to the recording buffers
    R_CONVERGENCE,  # estimated relative distance of the last cycle to its limit
    R_SYNC_ORDER,  # Kuramoto order parameter of the blocks' phases, final window
    R_SLIP_PARTICIPATION,  # mean fraction of blocks slipping per slip event, final window
) = range(18)
N_RESULTS = 18

# Outcomes of a step's runaway test besides the index of the block that crossed
# the cap (runaway_index).
NO_RUNAWAY, NOT_FINITE = -1, -2

# --- rows of a cycle's per-block statistics (win, last in integrate_system) --
W_LMAX, W_LMIN, W_MUMAX, W_MUMIN = range(4)  # extremes of ℓ_i and of friction A ℓ_i + B ψ_i
W_T_PEAK = 4  # time of block i's last maximum of ℓ_i in the cycle (D0/V)
N_WINDOW = 5

# --- entries of the scalar cycle state ``cs`` of integrate_system ------------
(
    C_N_PEAKS,  # maxima of ℓ_0 seen
    C_T_PEAK,  # time of the last maximum of ℓ_0 (D0/V)
    C_PEAK_VALUE,  # value of the latest maximum of ℓ_0
    C_PERIOD,  # last peak-to-peak time of ℓ_0 (D0/V)
    C_AMP_PREV,  # peak-to-trough amplitude of ℓ_0 in the last completed cycle
    C_GROWTH,  # envelope growth rate over the last two cycles (V/D0)
    C_N_CYCLES,  # completed cycles
    C_N_AGREE,  # consecutive cycles with the same verdict
    C_VERDICT,  # the last cycle's verdict (−1: none yet)
    C_CONV,  # the last cycle's estimated relative distance to its limit
    C_WIN_SYNC,  # max |ℓ_i − ℓ_0| in the current cycle
    C_WIN_MBAR_MAX,  # max of mean ℓ_i in the current cycle
    C_WIN_MBAR_MIN,  # min of mean ℓ_i in the current cycle
    C_WIN_T_PEAK_LAST,  # time of the last block's maximum of ℓ in the current cycle
    C_LAST_SYNC,  # max |ℓ_i − ℓ_0| in the last completed cycle
    C_LAST_PHASE,  # phase lag of the last block in the last completed cycle
    C_LNV_MAX_RUN,  # max ℓ_i over the whole run
    C_LAST_ORDER,  # Kuramoto order parameter of the last completed cycle
    C_LAST_PARTICIPATION,  # mean fraction of blocks per slip event, last completed cycle
    C_SLIPPING,  # 1 while some block slips (ℓ_i > S_SLIP_LNV) after the current step
    C_IN_EVENT,  # 1 while a slip event lasts
    C_SLIP_SUM,  # Σ fractions of slipping blocks of the events ended in the current cycle
    C_SLIP_EVENTS,  # number of those events
) = range(23)
N_CYCLE_STATE = 23

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


@jit_inline
def rhs(y, p, model, law, coupling, het, nb, ev, dydt):
    """Time derivative (per D0/V) of the log-form state ``y`` into ``dydt``.

    ``p`` is one row of the parameter array, with per-block columns where blocks
    differ (``het`` true); ``ev`` is scratch for e^ℓ (length nb).
    """
    A = p[P_A]
    B = p[P_B]
    kappa1 = p[P_KAPPA1]
    kappa2 = p[P_KAPPA2]
    total = 0.0  # Σ e^ℓ_j: every pair coupled
    for i in range(nb):
        ev[i] = np.exp(y[i])
        if coupling == ALL:
            total += ev[i]
    for i in range(nb):
        lnv = y[i]
        psi = y[nb + i]
        e = ev[i]
        if law == AGING:
            dpsi = np.exp(-psi) - e
        else:
            dpsi = -e * (lnv + psi)
        if het:
            A = p[N_PARAMS + B_A * nb + i]
            B = p[N_PARAMS + B_B * nb + i]
            kappa1 = p[N_PARAMS + B_KAPPA1 * nb + i]
            dpsi *= p[N_PARAMS + B_RATE * nb + i]
        load = kappa1 * (1.0 - e)
        if coupling == CHAIN:
            if i > 0:
                load += kappa2 * (ev[i - 1] - e)
            if i < nb - 1:
                load += kappa2 * (ev[i + 1] - e)
        elif coupling == RING:
            load += kappa2 * (ev[i - 1 if i > 0 else nb - 1] - e)
            load += kappa2 * (ev[i + 1 if i < nb - 1 else 0] - e)
        else:
            load += kappa2 * (total - nb * e)
        if model == QUASI_STATIC:
            dlnv = (load - B * dpsi) / A
        elif model == QUASI_DYNAMIC:
            dlnv = (load - B * dpsi) / (A + p[P_ETA] * e)
        else:
            dlnv = y[2 * nb + i] * np.exp(-lnv) / p[P_MASS]
            dydt[2 * nb + i] = load - B * dpsi - A * dlnv
        dydt[i] = dlnv
        dydt[nb + i] = dpsi


@jit
def jacobian(y, f, p, model, law, coupling, het, nb, ev, jac):
    """Analytic Jacobian ∂(dy/dτ)/∂y of :func:`rhs` at ``y`` into ``jac`` (n × n).

    ``f`` = rhs(y) (its ℓ rows enter the quasi-dynamic and inertial entries);
    ``ev`` is scratch for e^ℓ (length nb).
    """
    A = p[P_A]
    B = p[P_B]
    kappa1 = p[P_KAPPA1]
    kappa2 = p[P_KAPPA2]
    jac[:, :] = 0.0
    for i in range(nb):
        ev[i] = np.exp(y[i])
    for i in range(nb):
        e = ev[i]
        if law == AGING:
            dpsi_dlnv = -e
            dpsi_dpsi = -np.exp(-y[nb + i])
        else:
            dpsi_dlnv = -e * (y[i] + y[nb + i] + 1.0)
            dpsi_dpsi = -e
        if het:
            A = p[N_PARAMS + B_A * nb + i]
            B = p[N_PARAMS + B_B * nb + i]
            kappa1 = p[N_PARAMS + B_KAPPA1 * nb + i]
            rate = p[N_PARAMS + B_RATE * nb + i]
            dpsi_dlnv *= rate
            dpsi_dpsi *= rate
        jac[nb + i, i] = dpsi_dlnv
        jac[nb + i, nb + i] = dpsi_dpsi
        # the driving term load − B ψ' of block i: its own ℓ, ψ and its coupled
        # neighbours' ℓ, into row ``row`` divided by ``denom``
        dload_self = -kappa1 * e
        if coupling == CHAIN:
            if i > 0:
                dload_self -= kappa2 * e
            if i < nb - 1:
                dload_self -= kappa2 * e
        elif coupling == RING:
            dload_self -= 2.0 * kappa2 * e
        else:
            dload_self -= (nb - 1) * kappa2 * e
        if model == INERTIAL:
            row = 2 * nb + i
            denom = 1.0
            em = np.exp(-y[i]) / p[P_MASS]
            jac[i, i] = -f[i]
            jac[i, row] = em
            jac[row, i] = A * f[i]
            jac[row, row] = -A * em
        else:
            row = i
            denom = A if model == QUASI_STATIC else A + p[P_ETA] * e
            if model == QUASI_DYNAMIC:
                jac[i, i] = -f[i] * p[P_ETA] * e / denom
        jac[row, i] += (dload_self - B * dpsi_dlnv) / denom
        jac[row, nb + i] = -B * dpsi_dpsi / denom
        if coupling == CHAIN:
            if i > 0:
                jac[row, i - 1] = kappa2 * ev[i - 1] / denom
            if i < nb - 1:
                jac[row, i + 1] = kappa2 * ev[i + 1] / denom
        elif coupling == RING:
            jac[row, i - 1 if i > 0 else nb - 1] = kappa2 * ev[i - 1 if i > 0 else nb - 1] / denom
            jac[row, i + 1 if i < nb - 1 else 0] = kappa2 * ev[i + 1 if i < nb - 1 else 0] / denom
        else:
            for j in range(nb):
                if j != i:
                    jac[row, j] = kappa2 * ev[j] / denom


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
def dense_r5(method, j, h, f, k3, k4, k5, k6, fnew):
    """Fifth coefficient of the interpolant of component ``j`` over a step of size h:
    DOPRI5's (stages k1 = ``f``, k3 … k6, k7 = ``fnew``), 0 for the other methods
    (cubic Hermite)."""
    if method != DOPRI5:
        return 0.0
    return h * (_D1 * f[j] + _D3 * k3[j] + _D4 * k4[j] + _D5 * k5[j] + _D6 * k6[j] + _D7 * fnew[j])


@jit_inline
def dense_value(y0, y1, d0, d1, h, r5, theta):
    """Interpolant at fraction ``theta`` of a step of size h from (y0, slope d0) to
    (y1, slope d1): DOPRI5's continuous extension (order 4) with its coefficient
    ``r5``, the cubic Hermite interpolant for ``r5`` = 0 (RK4, RODAS4).

    The extrema of a cycle are read from it: with the cubic Hermite interpolant over
    0.5 D0/V steps they scattered by ~1e-4 of the amplitude from cycle to cycle,
    too much to extrapolate the cycle-to-cycle sequence near Kc
    (test_classification.py); the dense output is as accurate as the steps.
    """
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    return y0 + theta * (r2 + (1.0 - theta) * (r3 + theta * (r4 + (1.0 - theta) * r5)))


@jit_inline
def dense_slope(y0, y1, d0, d1, h, r5, theta):
    """h × the time derivative of :func:`dense_value` at fraction ``theta``."""
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    u = 1.0 - theta
    return (
        r2
        + (u - theta) * r3
        + theta * (2.0 - 3.0 * theta) * r4
        + 2.0 * theta * u * (u - theta) * r5
    )


@jit_inline
def dense_extremum(y0, y1, d0, d1, h, r5):
    """Fraction θ ∈ [0, 1] of the step where the interpolant's slope vanishes, given
    slopes d0 and d1 of opposite sign (bisection, 50 halvings)."""
    lo = 0.0
    hi = 1.0
    rising = d0 > 0.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if (dense_slope(y0, y1, d0, d1, h, r5, mid) > 0.0) == rising:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@jit
def dense_crossing(y0, y1, d0, d1, h, r5, level):
    """Fraction θ of the step where the interpolant rises through ``level``
    (y0 < level ≤ y1; bisection, 50 halvings)."""
    lo = 0.0
    hi = 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if dense_value(y0, y1, d0, d1, h, r5, mid) < level:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@jit
def aitken_limit(x0, x1, x2, x3, noise):
    """Limit of a sequence that converges geometrically, from its last four terms.

    Returns ``(limit, error)``: Aitken's Δ² extrapolation from the last three terms
    and its error estimate, the change from the extrapolation one term earlier.
    ``error`` is inf where the differences do not contract (|ratio| ≥ 1);
    differences within ``noise`` count as converged (limit ``x3``).
    """
    d1 = x1 - x0
    d2 = x2 - x1
    d3 = x3 - x2
    if abs(d3) <= noise and abs(d2) <= noise:
        return x3, abs(d2) + abs(d3)
    if d1 == 0.0 or d2 == 0.0:
        return x3, np.inf
    q = d3 / d2
    q_prev = d2 / d1
    if not (abs(q) < 1.0 and abs(q_prev) < 1.0):
        return x3, np.inf
    limit = x3 + d3 * q / (1.0 - q)
    limit_prev = x2 + d2 * q_prev / (1.0 - q_prev)
    return limit, abs(limit - limit_prev)


@jit
def history_value(hist, k, n_cycles, back):
    """Observable ``k`` of the cycle ``back`` cycles before the last one."""
    return hist[k, (n_cycles - 1 - back) % HISTORY]


@jit
def last_four(hist, k, n_cycles):
    """Observable ``k`` over the last four cycles, oldest first."""
    return (
        history_value(hist, k, n_cycles, 3),
        history_value(hist, k, n_cycles, 2),
        history_value(hist, k, n_cycles, 1),
        history_value(hist, k, n_cycles, 0),
    )


@jit
def last_four_ptp(hist, nb, i, n_cycles):
    """Peak-to-peak ℓ_i (rows i and nb + i of ``hist``) over the last four cycles."""
    a0, a1, a2, a3 = last_four(hist, i, n_cycles)
    b0, b1, b2, b3 = last_four(hist, nb + i, n_cycles)
    return a0 - b0, a1 - b1, a2 - b2, a3 - b3


@jit
def decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
    """Whether amplitudes x0 > x1 > x2 > x3 head for zero: already below
    ``steady_amp``, or decreasing with an extrapolated limit of zero to within
    ``accuracy`` × x3."""
    if x3 < steady_amp:
        return True
    if not (x0 > x1 > x2 > x3):
        return False
    limit, error = aitken_limit(x0, x1, x2, x3, noise)
    return abs(limit) + error <= accuracy * x3


@jit
def steady_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, atol):
    """Whether the last four cycles show the decay onto steady sliding.

    Only where steady sliding is linearly stable (``lin_growth`` < 0): an unstable
    fixed point is never the attractor, whatever a transient does (two weakly
    coupled blocks whose anti-phase mode decays first while the in-phase mode grows,
    test_classification.py). Every block's oscillation must be small (peak-to-peak
    ℓ below ``LINEAR_AMPLITUDE``) and extrapolate to zero; with several blocks so
    must the in-phase coordinate mean(ℓ_i) (row 2 nb + 1), so a slowly decaying
    in-phase mode hidden behind a faster anti-phase one is seen.
    """
    if not (lin_growth < 0.0) or n_cycles < HISTORY:
        return False
    noise = NOISE_FACTOR * atol
    for i in range(nb):
        x0, x1, x2, x3 = last_four_ptp(hist, nb, i, n_cycles)
        if not (x3 < LINEAR_AMPLITUDE):
            return False
        if not decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
            return False
    if nb > 1:
        x0, x1, x2, x3 = last_four(hist, 2 * nb + 1, n_cycles)
        if not decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
            return False
    return True


@jit
def cycle_convergence(hist, n_cycles, nb, rtol, atol):
    """Estimated relative distance of the last cycle to the limit cycle.

    The largest, over the cycle's observables, of the distance to the extrapolated
    limit plus that limit's error (:func:`aitken_limit`), relative to the
    observable's scale: for the extremes of every block's ℓ, min(1, peak-to-peak ℓ / 2)
    (so v_max and v_min are known to that relative accuracy, and the peak-to-peak
    too); for the period, the period; for the in-phase amplitude, the peak-to-peak
    ℓ. inf with fewer than four cycles or where an observable does not contract.
    """
    if n_cycles < HISTORY:
        return np.inf
    ptp = 0.0
    for i in range(nb):
        ptp = max(
            ptp, history_value(hist, i, n_cycles, 0) - history_value(hist, nb + i, n_cycles, 0)
        )
    worst = 0.0
    for k in range(2 * nb + 2):
        if k == 2 * nb + 1 and nb == 1:
            break
        x0, x1, x2, x3 = last_four(hist, k, n_cycles)
        noise = NOISE_FACTOR * (atol + rtol * abs(x3))
        limit, error = aitken_limit(x0, x1, x2, x3, noise)
        error += abs(limit - x3)
        if k < 2 * nb:
            scale = min(1.0, 0.5 * ptp)
        elif k == 2 * nb:
            scale = abs(x3)
        else:
            scale = ptp
        if not (error <= worst * scale):
            worst = error / scale if scale > 0.0 else np.inf
    return worst


@jit
def cycle_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, rtol, atol):
    """Regime settled by the last four cycles, or −1; and the cycle's convergence.

    Steady: :func:`steady_verdict`. Stick-slip: every cycle observable within
    ``accuracy`` (relative, see :func:`cycle_convergence`) of its extrapolated
    limit, so the reported features are those of the limit cycle to that accuracy.
    """
    if steady_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, atol):
        return STEADY, np.nan
    conv = cycle_convergence(hist, n_cycles, nb, rtol, atol)
    if conv <= accuracy:
        return STICK_SLIP, conv
    return -1, conv


@jit
def max_abs(y):
    """Largest |y_j|."""
    big = 0.0
    for j in range(y.size):
        big = max(big, abs(y[j]))
    return big


@jit_inline
def next_step_size(method, h, err, max_step):
    """The step after one of size ``h`` with error norm ``err`` (D0/V).

    RK4 keeps its fixed step. The adaptive methods use the standard controller
    0.9 err^(−1/(q+1)) (q: order of the error estimate), growing at most 5× and
    at most to ``max_step`` after an accepted step, shrinking at least 5× after a
    rejected one (and 5× when the error is not finite).
    """
    if method == RK4:
        return h
    expo = -0.25 if method == ROSENBROCK else -0.2
    if err <= 1.0:
        return min(max_step, h * min(5.0, 0.9 * max(err, 1e-10) ** expo))
    if math.isfinite(err):
        return h * max(0.2, 0.9 * err**expo)
    return h * 0.2


@jit
def collapse_regime(y, nb):
    """Regime of a run whose step size collapsed below 1e-300 D0/V.

    With any finite slope a small enough step passes the error test, so the slope
    overflows. With a block slipping faster than the load point this is the
    finite-time blow-up of v (runaway); otherwise the solver failed (undecided).
    Steps below the resolution of t are legitimate: an inertial block arresting
    after a fast slip lands on ℓ ~ −30 within ~1e-20 D0/V
    (test_models.py::test_inertial_arrest_is_resolved).
    """
    regime = UNDECIDED
    for i in range(nb):
        if y[i] > 0.0:
            regime = RUNAWAY
    return regime


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


@jit_inline
def block_friction(p, nb, i, A, B):
    """(A_i, B_i) of block i: its per-block columns, or the common ``A``, ``B``."""
    if p.size > N_PARAMS:
        return p[N_PARAMS + B_A * nb + i], p[N_PARAMS + B_B * nb + i]
    return A, B


@jit
def start_cycle(y, p, nb, A, B, win, cs):
    """Start a cycle's statistics at state ``y``: extremes of ℓ_i and of the friction
    A_i ℓ_i + B_i ψ_i, the synchronisation error and mean ℓ at their current values;
    no block maximum and no slip event ended yet."""
    sync = 0.0
    mbar = 0.0
    for i in range(nb):
        win[W_LMAX, i] = y[i]
        win[W_LMIN, i] = y[i]
        a_i, b_i = block_friction(p, nb, i, A, B)
        mu = a_i * y[i] + b_i * y[nb + i]
        win[W_MUMAX, i] = mu
        win[W_MUMIN, i] = mu
        win[W_T_PEAK, i] = np.nan
        sync = max(sync, abs(y[i] - y[0]))
        mbar += y[i] / nb
    cs[C_WIN_SYNC] = sync
    cs[C_WIN_MBAR_MAX] = mbar
    cs[C_WIN_MBAR_MIN] = mbar
    cs[C_WIN_T_PEAK_LAST] = np.nan
    cs[C_SLIP_SUM] = 0.0
    cs[C_SLIP_EVENTS] = 0.0


@jit_inline
def update_cycle(
    method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, p, nb, A, B, win, cs, slipped, slip_lnv
):
    """Fold the step from ``t`` to ``t + h`` into the current cycle's statistics.

    Extremes of every block's ℓ and friction are located inside the step with
    the dense output. Blocks with ℓ_i > ``slip_lnv`` after the step are marked in
    ``slipped`` (``cs[C_SLIPPING]``: whether any is). Returns ``(new_peak, theta)``:
    whether ℓ_0 had a maximum in the step (its value goes to ``cs[C_PEAK_VALUE]``)
    and where, as a fraction of the step.
    """
    new_peak = False
    theta_peak = 0.0
    lnv_max_run = cs[C_LNV_MAX_RUN]
    win_sync = cs[C_WIN_SYNC]
    slipping = 0.0
    for i in range(nb):
        rising = f[i] > 0.0
        falling_now = fnew[i] <= 0.0
        if rising == falling_now:  # slope changed sign: one extremum in the step
            r5 = dense_r5(method, i, h, f, k3, k4, k5, k6, fnew)
            theta = dense_extremum(y[i], ynew[i], f[i], fnew[i], h, r5)
            val = dense_value(y[i], ynew[i], f[i], fnew[i], h, r5, theta)
            win[W_LMAX, i] = max(win[W_LMAX, i], val)
            win[W_LMIN, i] = min(win[W_LMIN, i], val)
            lnv_max_run = max(lnv_max_run, val)
            if rising:
                win[W_T_PEAK, i] = t + theta * h
                if i == 0:
                    new_peak = True
                    theta_peak = theta
                    cs[C_PEAK_VALUE] = val
                elif i == nb - 1:
                    cs[C_WIN_T_PEAK_LAST] = t + theta * h
        win[W_LMAX, i] = max(win[W_LMAX, i], ynew[i])
        win[W_LMIN, i] = min(win[W_LMIN, i], ynew[i])
        lnv_max_run = max(lnv_max_run, ynew[i])
        if ynew[i] > slip_lnv:
            slipped[i] = 1.0
            slipping = 1.0
        # friction A_i ℓ_i + B_i ψ_i (relative to steady sliding), extremes interpolated
        a_i, b_i = block_friction(p, nb, i, A, B)
        mu0 = a_i * y[i] + b_i * y[nb + i]
        mu = a_i * ynew[i] + b_i * ynew[nb + i]
        dmu0 = a_i * f[i] + b_i * f[nb + i]
        dmu1 = a_i * fnew[i] + b_i * fnew[nb + i]
        if (dmu0 > 0.0) == (dmu1 <= 0.0):
            r5_mu = a_i * dense_r5(method, i, h, f, k3, k4, k5, k6, fnew) + b_i * dense_r5(
                method, nb + i, h, f, k3, k4, k5, k6, fnew
            )
            theta = dense_extremum(mu0, mu, dmu0, dmu1, h, r5_mu)
            val = dense_value(mu0, mu, dmu0, dmu1, h, r5_mu, theta)
            win[W_MUMAX, i] = max(win[W_MUMAX, i], val)
            win[W_MUMIN, i] = min(win[W_MUMIN, i], val)
        win[W_MUMAX, i] = max(win[W_MUMAX, i], mu)
        win[W_MUMIN, i] = min(win[W_MUMIN, i], mu)
        if i > 0:
            win_sync = max(win_sync, abs(ynew[i] - ynew[0]))
    cs[C_LNV_MAX_RUN] = lnv_max_run
    cs[C_WIN_SYNC] = win_sync
    cs[C_SLIPPING] = slipping
    return new_peak, theta_peak


@jit
def end_slip_event(nb, slipped, cs):
    """A slip event ended (no block slips any more): add the fraction of blocks that
    slipped during it to the current cycle's sum and clear the marks."""
    count = 0.0
    for i in range(nb):
        count += slipped[i]
        slipped[i] = 0.0
    cs[C_SLIP_SUM] += count / nb
    cs[C_SLIP_EVENTS] += 1.0
    cs[C_IN_EVENT] = 0.0


@jit
def kuramoto_order(t_peak_blocks, t_peak, period, nb):
    """Kuramoto order parameter R = |mean_i exp(iθ_i)| of the blocks' phases at the
    maximum of ℓ_0 at ``t_peak``: θ_i = 2π (last maximum of ℓ_i − t_peak) / period.
    NaN if a block had no maximum in the cycle."""
    re = 0.0
    im = 0.0
    for i in range(nb):
        theta = 2.0 * math.pi * (t_peak_blocks[i] - t_peak) / period
        re += math.cos(theta)
        im += math.sin(theta)
    return math.sqrt(re * re + im * im) / nb  # NaN from a block without a maximum


@jit
def record_step(method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, rec_dt, rec_t, rec_y, n_rec):
    """Record the state at the multiples of ``rec_dt`` inside the step (dense output)
    while the buffers have room (the last slot is kept for the end). Returns the count."""
    rec_cap = rec_t.size
    while n_rec < rec_cap - 1 and n_rec * rec_dt <= t + h and rec_dt > 0.0:
        theta = (n_rec * rec_dt - t) / h
        rec_t[n_rec] = n_rec * rec_dt
        for j in range(y.size):
            r5 = dense_r5(method, j, h, f, k3, k4, k5, k6, fnew)
            rec_y[n_rec, j] = dense_value(y[j], ynew[j], f[j], fnew[j], h, r5, theta)
        n_rec += 1
    return n_rec


@jit
def close_cycle(t_peak, nb, win, last, hist, cs, accuracy, steady_amp, lin_growth, rtol, atol):
    """End the cycle at the maximum of ℓ_0 at ``t_peak`` (D0/V).

    Adds the cycle to the history, judges it (:func:`cycle_verdict`) and keeps
    its statistics as the last completed cycle.
    """
    period = t_peak - cs[C_T_PEAK]
    cs[C_PERIOD] = period
    # growth of the peak-to-trough amplitude of ℓ_0, where it is above round-off
    # (a decayed run would report noise, not a rate)
    amp = cs[C_PEAK_VALUE] - win[W_LMIN, 0]
    growth = np.nan
    if cs[C_AMP_PREV] >= steady_amp and amp >= steady_amp:
        growth = math.log(amp / cs[C_AMP_PREV]) / period
    cs[C_GROWTH] = growth
    cs[C_AMP_PREV] = amp
    n_cycles = int(cs[C_N_CYCLES])
    slot = n_cycles % HISTORY
    for i in range(nb):
        hist[i, slot] = win[W_LMAX, i]
        hist[nb + i, slot] = win[W_LMIN, i]
    hist[0, slot] = cs[C_PEAK_VALUE]
    hist[2 * nb, slot] = period
    hist[2 * nb + 1, slot] = cs[C_WIN_MBAR_MAX] - cs[C_WIN_MBAR_MIN]
    n_cycles += 1
    cs[C_N_CYCLES] = n_cycles
    verdict, conv = cycle_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, rtol, atol)
    cs[C_CONV] = conv
    same = verdict >= 0 and verdict == int(cs[C_VERDICT])
    cs[C_N_AGREE] = cs[C_N_AGREE] + 1 if same else 1
    cs[C_VERDICT] = verdict
    for k in range(N_WINDOW):
        for i in range(nb):
            last[k, i] = win[k, i]
    cs[C_LAST_ORDER] = kuramoto_order(win[W_T_PEAK], t_peak, period, nb)
    events = cs[C_SLIP_EVENTS]
    cs[C_LAST_PARTICIPATION] = cs[C_SLIP_SUM] / events if events > 0 else np.nan
    cs[C_LAST_SYNC] = cs[C_WIN_SYNC]
    t_last = cs[C_WIN_T_PEAK_LAST]
    if nb > 1 and t_last == t_last:
        lag = (t_last - cs[C_T_PEAK]) / period
        cs[C_LAST_PHASE] = lag - math.floor(lag + 0.5)


@jit
def final_regime(regime, t, tau_stop, y, cs, steady_amp, lin_growth):
    """The regime of a run that ended without a settled verdict (``regime`` < 0):
    undecided when the step budget ran out, else the last cycle's verdict, steady
    when it decayed onto a linearly stable steady state, else undecided."""
    if regime >= 0:
        return regime
    if t < tau_stop:  # step budget exhausted
        return UNDECIDED
    if cs[C_VERDICT] >= 0:
        return int(cs[C_VERDICT])
    if max_abs(y) < steady_amp and lin_growth < 0.0:
        return STEADY
    return UNDECIDED


@jit
def write_result(result, regime, t, n_steps, n_rejected, tau_runaway, nb, win, last, cs):
    """The run's statistics into ``result`` (``R_*`` columns).

    The final window is the last completed cycle, except for runaway runs and
    runs that never completed one, which report the cycle in progress.
    """
    use_last = cs[C_N_PEAKS] >= 2 and regime != RUNAWAY
    window = last if use_last else win
    lmax = -np.inf
    lmin = np.inf
    fdrop = 0.0
    for i in range(nb):
        lmax = max(lmax, window[W_LMAX, i])
        lmin = min(lmin, window[W_LMIN, i])
        fdrop = max(fdrop, window[W_MUMAX, i] - window[W_MUMIN, i])
    sync = cs[C_LAST_SYNC] if use_last else cs[C_WIN_SYNC]
    result[R_REGIME] = regime
    result[R_TAU_FINAL] = t
    result[R_N_STEPS] = n_steps
    result[R_N_REJECTED] = n_rejected
    result[R_LNV_MAX] = lmax
    result[R_LNV_MIN] = lmin
    result[R_PERIOD] = cs[C_PERIOD]
    result[R_GROWTH] = cs[C_GROWTH]
    result[R_FRICTION_DROP] = fdrop
    result[R_TAU_RUNAWAY] = tau_runaway
    result[R_SYNC_ERROR] = sync if nb > 1 else np.nan
    result[R_PHASE_LAG] = cs[C_LAST_PHASE]
    result[R_N_PEAKS] = cs[C_N_PEAKS]
    result[R_LNV_MAX_RUN] = cs[C_LNV_MAX_RUN]
    steady_or_runaway = regime == STEADY or regime == RUNAWAY
    result[R_CONVERGENCE] = np.nan if steady_or_runaway else cs[C_CONV]
    events = cs[C_SLIP_EVENTS]
    result[R_SYNC_ORDER] = cs[C_LAST_ORDER] if use_last else np.nan
    if use_last:
        result[R_SLIP_PARTICIPATION] = cs[C_LAST_PARTICIPATION]
    else:
        result[R_SLIP_PARTICIPATION] = cs[C_SLIP_SUM] / events if events > 0 else np.nan


@jit
def step_scratch(n):
    """Scratch of the explicit steps for a state of ``n`` values: f, ynew, fnew, ytmp
    and the stages k2 … k6 as the rows of one (5, n) array."""
    return np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty((5, n))


@jit
def rosenbrock_scratch(method, n):
    """Scratch of the RODAS4 step (stages, matrix, pivots); empty for other methods."""
    if method == ROSENBROCK:
        return np.empty((6, n)), np.empty((n, n)), np.empty(n, np.int64)
    return np.empty((0, n)), np.empty((0, 0)), np.empty(0, np.int64)


@jit
def cap_crossing(method, i, t, h, y, ynew, f, fnew, k3, k4, k5, k6, nb, lnv_cap, win, cs):
    """End a run whose block ``i`` crossed ``lnv_cap`` in the step from ``t`` to
    ``t + h``: keep the step (``y`` becomes ``ynew``, the extremes include it) and
    return the time of the crossing (D0/V, interpolated)."""
    r5 = dense_r5(method, i, h, f, k3, k4, k5, k6, fnew)
    theta = dense_crossing(y[i], ynew[i], f[i], fnew[i], h, r5, lnv_cap)
    tau = t + (0.0 if y[i] > lnv_cap else theta) * h
    for j in range(nb):
        win[W_LMAX, j] = max(win[W_LMAX, j], ynew[j])
    cs[C_LNV_MAX_RUN] = max(cs[C_LNV_MAX_RUN], lnv_cap)
    for j in range(y.size):
        y[j] = ynew[j]
    return tau


@jit
def record_start(y, rec_t, rec_y):
    """Record the initial state when there are buffers; returns the count."""
    if rec_t.size == 0:
        return 0
    rec_t[0] = 0.0
    for j in range(y.size):
        rec_y[0, j] = y[j]
    return 1


@jit
def record_end(t, y, rec_t, rec_y, n_rec):
    """Record the final state when the buffers have room; returns the count."""
    if 0 < n_rec < rec_t.size and rec_t[n_rec - 1] < t:
        rec_t[n_rec] = t
        for j in range(y.size):
            rec_y[n_rec, j] = y[j]
        n_rec += 1
    return n_rec


@jit
def new_cycle_state(y, nb):
    """Scalar cycle state (``C_*`` entries) at the start of a run from ``y``."""
    cs = np.full(N_CYCLE_STATE, np.nan)
    cs[C_N_PEAKS] = 0.0
    cs[C_PEAK_VALUE] = 0.0
    cs[C_N_CYCLES] = 0.0
    cs[C_N_AGREE] = 0.0
    cs[C_VERDICT] = -1.0
    cs[C_CONV] = np.inf
    cs[C_SLIPPING] = 0.0
    cs[C_IN_EVENT] = 0.0
    lnv_max_run = -np.inf
    for i in range(nb):
        lnv_max_run = max(lnv_max_run, y[i])
    cs[C_LNV_MAX_RUN] = lnv_max_run
    return cs


@jit_inline
def cycle_arrays(y, p, nb, A, B):
    """The classifier's arrays at the start of a run, the first cycle started at ``y``:
    the current cycle (``win``) and the last completed one (``last``), ``W_*`` rows per
    block; per completed cycle (``hist``): max ℓ_i, min ℓ_i, period, peak-to-peak of
    mean(ℓ_i); the cycle state ``cs`` (``C_*``); ``slipped`` (1: block i slipped during
    the current slip event)."""
    win = np.empty((N_WINDOW, nb))
    last = np.full((N_WINDOW, nb), np.nan)
    hist = np.zeros((2 * nb + 2, HISTORY))
    cs = new_cycle_state(y, nb)
    start_cycle(y, p, nb, A, B, win, cs)
    slipped = np.zeros(nb)
    return win, last, hist, cs, slipped


@jit_inline
def read_settings(settings):
    """The settings array (``S_*``) as typed values: blocks, rtol, atol, step budget,
    ln of the velocity cap, steady amplitude, accuracy, cycles to confirm (≥ 1),
    early exit (bool) and ln of the slip threshold."""
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
    return nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit, slip_lnv


@jit_inline
def integrate_system(
    p, y0, settings, result, y_final, rec_dt, rec_t, rec_y, model, law, method, coupling, het
):
    """Integrate one system (parameters ``p``: ``P_*``) from ``y0``; its statistics go
    to ``result`` (``R_*``), its final state to ``y_final``. Traces: the state every
    ``rec_dt`` (D0/V, interpolated) and at the end goes to ``rec_t``/``rec_y`` while
    they have room (sweeps pass empty buffers); the count is ``result[R_N_RECORDED]``.

    ``model``, ``law``, ``method``, ``coupling`` and ``het`` (per-block columns in
    ``p``) are the kernel's variant: constants of :func:`grid_kernel`, whose inlined
    copy of this function keeps only that variant's branches.
    """
    nb, rtol, atol, max_steps, lnv_cap, steady_amp, accuracy, n_confirm, early_exit, slip_lnv = (
        read_settings(settings)
    )
    A = p[P_A]
    B = p[P_B]
    tau_end = p[P_TAU_END]
    # unsettled runs go on past tau_end only with early exit (else: fixed-length runs)
    tau_max = max(p[P_TAU_MAX], tau_end) if early_exit else tau_end
    lin_growth = p[P_LIN_GROWTH]
    max_step = p[P_MAX_STEP]

    n = y0.size
    y = y0.copy()
    f, ynew, fnew, ytmp, k = step_scratch(n)
    k3, k4, k5, k6 = k[1], k[2], k[3], k[4]  # the stages dense output needs
    ev = np.empty(nb)
    k_ros, mat, perm = rosenbrock_scratch(method, n)
    win, last, hist, cs, slipped = cycle_arrays(y, p, nb, A, B)

    n_rec = record_start(y, rec_t, rec_y)

    rhs(y, p, model, law, coupling, het, nb, ev, f)
    t = 0.0
    h = p[P_DT] if method == RK4 else min(1e-3, max_step, tau_end)
    n_steps = 0
    n_rejected = 0
    regime = -1
    tau_runaway = np.nan
    # unsettled at tau_end: go on (settling early from then on) up to tau_max
    tau_stop = tau_end
    while t < tau_max:
        if t >= tau_stop:
            tau_stop = tau_max
            if cs[C_VERDICT] >= 0:
                regime = int(cs[C_VERDICT])
                break
        if n_steps + n_rejected >= max_steps:
            break
        h = min(h, tau_stop - t)
        err = 0.0  # RK4: every step is accepted
        if method == DOPRI5:
            err = step_dopri5(
                y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew, fnew, rtol, atol
            )
        elif method == ROSENBROCK:
            err = step_rosenbrock(
                y, f, h, p, model, law, coupling, het, nb, ev, k_ros, mat, perm, ytmp, ynew,
                fnew, rtol, atol,
            )  # fmt: skip
        else:
            step_rk4(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, ynew)
            rhs(ynew, p, model, law, coupling, het, nb, ev, fnew)
        h_next = next_step_size(method, h, err, max_step)
        if not (err <= 1.0):
            n_rejected += 1
            h = h_next
            if h < 1e-300:
                regime = collapse_regime(y, nb)
                tau_runaway = t if regime == RUNAWAY else np.nan
                break
            continue
        n_steps += 1

        crossed = runaway_index(ynew, fnew, nb, lnv_cap)
        if crossed != NO_RUNAWAY:
            regime = RUNAWAY
            tau_runaway = t + h
            if crossed >= 0:  # the step is kept: the run ends after it
                tau_runaway = cap_crossing(
                    method, crossed, t, h, y, ynew, f, fnew, k3, k4, k5, k6, nb, lnv_cap, win, cs
                )
                t += h
            break

        new_peak, theta_peak = update_cycle(
            method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, p, nb, A, B, win, cs, slipped,
            slip_lnv,
        )  # fmt: skip
        if cs[C_SLIPPING] > 0.0:
            cs[C_IN_EVENT] = 1.0
        elif cs[C_IN_EVENT] > 0.0:
            end_slip_event(nb, slipped, cs)
        if nb > 1:  # extremes of the mean ℓ, written out here (see accelerate.py: an
            # inlined helper with a branch around its loops refcounts every step)
            m0 = 0.0
            m1 = 0.0
            dm0 = 0.0
            dm1 = 0.0
            for i in range(nb):
                m0 += y[i] / nb
                m1 += ynew[i] / nb
                dm0 += f[i] / nb
                dm1 += fnew[i] / nb
            if (dm0 > 0.0) == (dm1 <= 0.0):
                r5 = 0.0
                for i in range(nb):
                    r5 += dense_r5(method, i, h, f, k3, k4, k5, k6, fnew) / nb
                theta = dense_extremum(m0, m1, dm0, dm1, h, r5)
                val = dense_value(m0, m1, dm0, dm1, h, r5, theta)
                cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], val)
                cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], val)
            cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], m1)
            cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], m1)
        if n_rec > 0:
            n_rec = record_step(
                method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, rec_dt, rec_t, rec_y, n_rec
            )
        t_new_peak = t + theta_peak * h
        t += h
        for j in range(n):
            y[j] = ynew[j]
            f[j] = fnew[j]
        h = h_next

        if new_peak:
            cs[C_N_PEAKS] += 1
            if cs[C_N_PEAKS] >= 2:
                close_cycle(
                    t_new_peak, nb, win, last, hist, cs, accuracy, steady_amp, lin_growth, rtol,
                    atol,
                )  # fmt: skip
            cs[C_T_PEAK] = t_new_peak
            # the new cycle starts at this peak
            start_cycle(y, p, nb, A, B, win, cs)
            win[W_LMAX, 0] = max(win[W_LMAX, 0], cs[C_PEAK_VALUE])
            if early_exit and cs[C_VERDICT] >= 0 and cs[C_N_AGREE] >= n_confirm:
                regime = int(cs[C_VERDICT])
                break

        # decayed onto a linearly stable steady state
        if early_exit and lin_growth < 0.0 and max_abs(y) < steady_amp:
            regime = STEADY
            break

    regime = final_regime(regime, t, tau_stop, y, cs, steady_amp, lin_growth)
    write_result(result, regime, t, n_steps, n_rejected, tau_runaway, nb, win, last, cs)
    y_final[:] = y
    result[R_N_RECORDED] = record_end(t, y, rec_t, rec_y, n_rec)


@functools.cache
def grid_kernel(model, law, method, coupling, het):
    """The serial grid kernel of one variant: model, state law, method and coupling
    codes (int) and whether blocks differ (``het``, bool).

    Built and compiled on first use, one per variant: the codes are constants of
    the closure, so once the helpers are inlined numba prunes the other variants'
    branches before typing (the other methods' steppers are never compiled), and
    numba's cache keys each variant by their values. The helpers themselves are
    still prepared for inlining with every branch (their codes are arguments), which
    is why the Runge–Kutta stages are loops around one call of :func:`rhs`. Sweeps and
    traces call the same kernel: ``integrate_grid(params, y0, settings, results, y_final, rec_dt,
    rec_t, rec_y)`` integrates every row one after another; a trace passes one row
    and recording buffers, sweeps empty buffers (see :func:`integrate_system`).
    """

    def integrate_grid(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y):
        for s in range(params.shape[0]):
            integrate_system(
                params[s], y0[s], settings, results[s], y_final[s], rec_dt, rec_t, rec_y,
                model, law, method, coupling, het,
            )  # fmt: skip

    return jit(integrate_grid)
