"""An independent reference for N quasi-static blocks (aging law), plain numpy + SciPy.

Written from the physics brief (``shared/physics.md``, sections 2–3), not from
``sweep``: the engine's N-block results are checked against it.

Log form, per block i (A_i, B_i, D0_i, K_i), time τ = t V/D0_ref (D0_ref in µm sets
the time unit only), κ_i = K_i D0_ref/W, κ2 = k2 D0_ref/W, ψ_i = ln(VΦ_i/D0_i)::

    ψ_i' = r_i (e^(−ψ_i) − e^(ℓ_i)),                r_i = D0_ref/D0_i
    ℓ_i' = [κ_i (1 − e^(ℓ_i)) − κ2 Σ_j L_ij e^(ℓ_j) − B_i ψ_i'] / A_i

(the friction equation μ0 + B_i ln Φ_i/Φ0 + A_i ln v_i/V0 = spring forces / W,
differentiated in time; μ0 and V0 drop out), L the graph Laplacian of the coupling
springs. Steady sliding ℓ = ψ = 0 is a fixed point for any heterogeneity. Its
Jacobian (written out by hand below) has rows/columns (ℓ_1…ℓ_N, ψ_1…ψ_N)::

    ∂ℓ'/∂ℓ = [diag(B r − κ) − κ2 L] / A     ∂ℓ'/∂ψ = diag(B r / A)
    ∂ψ'/∂ℓ = −diag(r)                       ∂ψ'/∂ψ = −diag(r)

Closed form used by the tests: with equal A, B, D0 but any K_i, eliminating ψ
(ψ = −ℓ/(s + 1)) leaves [s(A − B/(s + 1)) I + M] ℓ = 0 with M = diag(κ) + κ2 L
symmetric, so every eigenvalue μ of M is a one-block mode of stiffness μ and steady
sliding is stable iff min eig(M) > B − A.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

COUPLINGS = ("chain", "ring", "all")
#: The runaway cap of the engine's default classification: v = 1e6 V.
LN_CAP = math.log(1e6)
#: The SciPy call of every reference run (method, tolerances), named where quoted.
RUN_CALL = {"method": "DOP853", "rtol": 1e-10, "atol": 1e-12}
#: A faster call for runs to a cycle or a runaway: cycle amplitudes as with ``RUN_CALL``
#: and rtol 1e-12 to 1e-6 (checked once, 2000 D0/V of the three-block chain at 0.99 Kc).
FAST_CALL = {"rtol": 1e-8, "atol": 1e-10}


def laplacian(n_blocks, coupling="chain"):
    """Graph Laplacian (N x N) of the coupling springs: open chain, ring, or every pair."""
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")
    adj = np.zeros((n_blocks, n_blocks))
    if coupling == "all":
        adj[:] = 1.0
        np.fill_diagonal(adj, 0.0)
    else:
        i = np.arange(n_blocks - 1)
        adj[i, i + 1] = adj[i + 1, i] = 1.0
        if coupling == "ring" and n_blocks >= 3:
            adj[0, -1] = adj[-1, 0] = 1.0
    return np.diag(adj.sum(axis=1)) - adj


class Chain:
    """N quasi-static blocks (aging law) with per-block A, B, D0 (µm), K/W (µm⁻¹), a
    common k2/W (µm⁻¹) on each coupling spring and a coupling topology; the time unit
    is ``D0_ref``/V (``D0_ref`` in µm, default 1)."""

    def __init__(self, A, B, D0, K_W, k2_W=0.0, coupling="chain", n_blocks=None, D0_ref=1.0):
        lengths = {np.size(x) for x in (A, B, D0, K_W)} - {1}
        n = n_blocks or (lengths.pop() if lengths else 1)
        self.n = n
        self.A, self.B, self.D0, self.K_W = (
            np.broadcast_to(np.asarray(x, float), (n,)).copy() for x in (A, B, D0, K_W)
        )
        self.k2_W, self.coupling, self.D0_ref = float(k2_W), coupling, float(D0_ref)
        self.L = laplacian(n, coupling)
        self.rate = D0_ref / self.D0
        self.kappa = self.K_W * D0_ref
        self.kappa2 = self.k2_W * D0_ref

    def with_K(self, K_W):
        """The same blocks with driving stiffness ``K_W`` (µm⁻¹, scalar or per block)."""
        return Chain(self.A, self.B, self.D0, K_W, self.k2_W, self.coupling, self.n, self.D0_ref)

    def rhs(self, t, y):
        """(ℓ', ψ') per D0_ref/V for state ``y = (ℓ_1…ℓ_N, ψ_1…ψ_N)``."""
        lnv, psi = y[: self.n], y[self.n :]
        v = np.exp(lnv)
        dpsi = self.rate * (np.exp(-psi) - v)
        dlnv = (self.kappa * (1.0 - v) - self.kappa2 * (self.L @ v) - self.B * dpsi) / self.A
        return np.concatenate([dlnv, dpsi])

    def jacobian(self):
        """Jacobian of :meth:`rhs` at steady sliding (ℓ = ψ = 0), by hand; units V/D0_ref."""
        a, br = self.A[:, None], np.diag(self.B * self.rate)
        top = np.hstack([(br - np.diag(self.kappa) - self.kappa2 * self.L) / a, br / a])
        bottom = np.hstack([-np.diag(self.rate), -np.diag(self.rate)])
        return np.vstack([top, bottom])

    def growth_rate(self):
        """Largest real part of the steady-state eigenvalues (V/D0_ref); > 0 unstable."""
        return float(np.linalg.eigvals(self.jacobian()).real.max())

    def critical_K_W(self, factors=1.0, low=1e-6, high=10.0, rtol=1e-12):
        """Critical K/W (µm⁻¹): the K below which steady sliding of these blocks with
        driving stiffnesses K_i = K ``factors``_i is unstable, by bisection on the sign of
        :meth:`growth_rate` to ``rtol``. Assumes one crossing in [low, high] (asserted
        at the ends)."""
        factors = np.broadcast_to(np.asarray(factors, float), (self.n,))
        unstable = [self.with_K(k * factors).growth_rate() > 0 for k in (low, high)]
        assert unstable == [True, False], (low, high)
        while high - low > rtol * high:
            mid = 0.5 * (low + high)
            if self.with_K(mid * factors).growth_rate() > 0:
                low = mid
            else:
                high = mid
        return 0.5 * (low + high)


def fd_jacobian(fun, y, h=1e-7):
    """Central finite-difference Jacobian of ``fun(t, y)`` at ``y``."""
    y = np.asarray(y, float)
    cols = []
    for k in range(y.size):
        d = np.zeros(y.size)
        d[k] = h
        cols.append((fun(0.0, y + d) - fun(0.0, y - d)) / (2 * h))
    return np.array(cols).T


def start_state(n, v_over_V=1.0, phi_over_phi_ss=1.01):
    """Initial (ℓ, ψ) from v/V and Φ/Φss per block (scalars or lists)."""
    lnv = np.log(np.broadcast_to(np.asarray(v_over_V, float), (n,)))
    psi = np.log(np.broadcast_to(np.asarray(phi_over_phi_ss, float), (n,)))
    return np.concatenate([lnv, psi])


def run(chain, y0, t_end, **call):
    """Integrate ``chain`` from ``y0`` to ``t_end`` (D0_ref/V) with dense output,
    stopping where any ℓ_i reaches ln(1e6): ``solve_ivp(**RUN_CALL)`` unless ``call``
    overrides it.

    Returns ``(sol, t_runaway)``, ``t_runaway`` None if the cap was not reached.
    """

    def cap(t, y):
        return y[: chain.n].max() - LN_CAP

    cap.terminal, cap.direction = True, 1
    sol = solve_ivp(chain.rhs, (0.0, t_end), y0, events=cap, dense_output=True,
                    **(RUN_CALL | call))  # fmt: skip
    assert sol.status in (0, 1), sol.message
    return sol, (float(sol.t_events[0][0]) if sol.t_events[0].size else None)


def window_amplitudes(chain, sol, t_from, dt=0.002):
    """From ``t_from`` to the end of ``sol`` (dense output sampled every ``dt``, D0_ref/V):
    max |ψ_i| (= max |ln Φ_i/Φss|) and the range of ℓ (max − min over blocks and time)."""
    y = sol.sol(np.arange(t_from, sol.t[-1], dt))
    lnv, psi = y[: chain.n], y[chain.n :]
    return float(np.abs(psi).max()), float(lnv.max() - lnv.min())


def _maxima(t, x):
    """Times of the local maxima of samples ``x(t)``, refined by a parabola through
    each sampled maximum and its neighbours."""
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    a, b, c = x[i - 1], x[i], x[i + 1]
    return t[i] + 0.5 * (t[1] - t[0]) * (a - c) / (a - 2 * b + c)


def cycle_features(chain, sol, t_from, dt=0.002, slip_v_over_V=2.0):
    """Features of a converged cycle from ``t_from`` to the end of ``sol`` (dense output
    sampled every ``dt``, D0_ref/V), as the engine defines them (``sweep/variables.py``):
    ``lnv_max``/``lnv_min`` over all blocks; ``period`` between maxima of ℓ_0 (D0_ref/V);
    ``sync_order`` R = |mean_i exp(iθ_i)|, θ_i = 2π (block i's last maximum − block 0's
    last maximum)/period; ``slip_participation``, the mean over slip events (while any
    v_i > ``slip_v_over_V`` V) of the fraction of blocks slipping in the event;
    ``psi_amplitude`` max |ψ_i|."""
    t = np.arange(t_from, sol.t[-1], dt)
    y = sol.sol(t)
    lnv, psi = y[: chain.n], y[chain.n :]
    peaks0 = _maxima(t, lnv[0])
    period = float(np.mean(np.diff(peaks0[1:])))
    theta = [2 * np.pi * (_maxima(t, x)[-1] - peaks0[-1]) / period for x in lnv]
    slipping = lnv > np.log(slip_v_over_V)
    any_slip = slipping.any(axis=0).astype(int)
    starts = np.flatnonzero(np.diff(any_slip) == 1) + 1
    ends = np.flatnonzero(np.diff(any_slip) == -1) + 1
    ends = ends[ends > starts[0]]
    events = [slipping[:, s:e].any(axis=1).mean() for s, e in zip(starts, ends, strict=False)]
    return {
        "lnv_max": float(lnv.max()),
        "lnv_min": float(lnv.min()),
        "period": period,
        "sync_order": float(abs(np.mean(np.exp(1j * np.array(theta))))),
        "slip_participation": float(np.mean(events)),
        "psi_amplitude": float(np.abs(psi).max()),
    }


def event_states(rhs, y0, t_end, jac=None, **call):
    """Times (D0_ref/V) and full states at the maxima of ℓ_0 (the events of a cycle of
    several events: ℓ_0' crossing zero downwards) from ``y0`` to ``t_end``, for any
    system ``rhs(t, y)`` whose first component is ℓ_0 (a :class:`Chain`'s, or an
    ``attractor_reference.Blocks``'s with its ``jac``): ``solve_ivp(**RUN_CALL)``
    unless ``call`` overrides it. Returns ``(times, states)``, one row per event."""

    def falling(t, y):
        return rhs(t, y)[0]

    falling.direction = -1
    extra = {} if jac is None else {"jac": jac}
    sol = solve_ivp(rhs, (0.0, t_end), y0, events=falling, **(RUN_CALL | call), **extra)
    assert sol.status == 0, sol.message
    return sol.t_events[0], sol.y_events[0]


def first_return(times, states, tol, longest=32):
    """The minimal period of a cycle from its events (:func:`event_states`): the
    smallest d ≤ ``longest`` at which the whole state at the last event is within
    ``tol`` (max norm) of the state d events before. Returns ``(d, period, gaps)``:
    the time between those events (D0_ref/V) and the state's distance at every
    d' < d (each should stand clear of ``tol``); ``(None, None, gaps)`` when none
    returns."""
    gaps = []
    for d in range(1, min(longest, len(times) - 1) + 1):
        gap = float(np.abs(states[-1] - states[-1 - d]).max())
        if gap <= tol:
            return d, float(times[-1] - times[-1 - d]), gaps
        gaps.append(gap)
    return None, None, gaps
