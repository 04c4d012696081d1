"""An independent reference for attractors beyond the simple cycle, plain numpy + SciPy.

Written from the physics brief (``shared/physics.md``, sections 2, 4 and 5b), not
from ``sweep``: the engine's event maxima, cycle periods and Lyapunov exponents are
checked against it.

N blocks in an open chain or a ring (aging law), per-block A_i, B_i, D0_i, K_i; time
τ = t V/D0_ref (D0_ref in µm sets the time unit only); κ_i = K_i D0_ref/W,
κ2 = k2 D0_ref/W, r_i = D0_ref/D0_i, M̂ = m V²/(W D0_ref), ψ_i = ln(VΦ_i/D0_i)::

    ψ_i' = r_i (e^(−ψ_i) − e^(ℓ_i))
    load_i = κ_i (1 − e^(ℓ_i)) − κ2 Σ_j L_ij e^(ℓ_j)      (rate of the spring force per W)
    quasi-static:  ℓ_i' = (load_i − B_i ψ_i') / A_i
    inertial:      ℓ_i' = z_i e^(−ℓ_i) / M̂,   z_i' = load_i − A_i ℓ_i' − B_i ψ_i'

z_i = m v̇_i / W is the spring force per W in excess of the friction (m ẍ_i =
W(σ_i − A_i ℓ_i − B_i ψ_i) with σ_i the spring force in excess of steady friction):
carried as a state itself, since σ_i − A_i ℓ_i − B_i ψ_i cancels to round-off in a deep
stick (ln v/V ≈ −30), where e^(−ℓ) multiplies it by 1e13. A start in force balance has
z_i = 0.

Largest Lyapunov exponent (Benettin et al. 1980): the variational equations
δ' = J(y) δ, with the Jacobian written out by hand, integrated beside the state;
λ1 = the growth rate of log |δ| after a transient. The 0-1 test for chaos (Gottwald & Melbourne
2009, the correlation method) on a series of event maxima: K ≈ 1 chaotic, ≈ 0 regular.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

#: The SciPy call of the reference runs (the brief's: LSODA, rtol 1e-10).
RUN_CALL = {"method": "LSODA", "rtol": 1e-10, "atol": 1e-12}


class Blocks:
    """``n_blocks`` blocks in an open chain (``ring``: closed); ``model`` "quasi-static" or
    "inertial"; A, B, D0 (µm), K/W (µm⁻¹) scalars or per block; k2/W (µm⁻¹); m/W (s²/µm);
    V (µm/s); time unit D0_ref/V with D0_ref the mean D0 (the engine's reference D0)."""

    def __init__(self, model, A, B, D0, K_W, k2_W=0.0, m_W=0.0, V=1.0, n_blocks=None, ring=False):
        sizes = {np.size(x) for x in (A, B, D0, K_W)} - {1}
        self.n = n_blocks or (sizes.pop() if sizes else 1)
        self.A, self.B, self.D0, self.K_W = (
            np.broadcast_to(np.asarray(x, float), (self.n,)).copy() for x in (A, B, D0, K_W)
        )
        self.model = model
        self.D0_ref = float(np.mean(self.D0))
        self.rate = self.D0_ref / self.D0
        self.kappa = self.K_W * self.D0_ref
        self.kappa2 = k2_W * self.D0_ref
        self.mass = m_W * V**2 / self.D0_ref
        lap = np.zeros((self.n, self.n))
        for i in range(self.n - 1):
            lap[i, i] += 1
            lap[i + 1, i + 1] += 1
            lap[i, i + 1] = lap[i + 1, i] = -1
        if ring and self.n > 2:
            lap[0, 0] += 1
            lap[-1, -1] += 1
            lap[0, -1] = lap[-1, 0] = -1
        self.L = lap

    def rhs(self, t, y):
        """Time derivative per D0_ref/V of ``y = (ℓ…, ψ…[, σ…])``."""
        n = self.n
        lnv, psi = y[:n], y[n : 2 * n]
        v = np.exp(lnv)
        dpsi = self.rate * (np.exp(-psi) - v)
        load = self.kappa * (1.0 - v) - self.kappa2 * (self.L @ v)
        if self.model == "quasi-static":
            return np.concatenate([(load - self.B * dpsi) / self.A, dpsi])
        dlnv = y[2 * n :] / (self.mass * v)
        return np.concatenate([dlnv, dpsi, load - self.A * dlnv - self.B * dpsi])

    def start(self, v_over_V=1.0, phi_over_phi_ss=1.0):
        """Initial state from v/V and Φ/Φss per block; inertial blocks in force balance."""
        lnv = np.log(np.broadcast_to(np.asarray(v_over_V, float), (self.n,)))
        psi = np.log(np.broadcast_to(np.asarray(phi_over_phi_ss, float), (self.n,)))
        parts = [lnv, psi]
        if self.model == "inertial":
            parts.append(np.zeros(self.n))
        return np.concatenate(parts)

    def jacobian(self, t, y):
        """∂(:meth:`rhs`)/∂y at ``y``, by hand (checked against finite differences in
        ``tests/test_attractors.py``)."""
        n = self.n
        lnv, psi = y[:n], y[n : 2 * n]
        v, e_psi = np.exp(lnv), np.exp(-psi)
        dload = -np.diag(self.kappa * v) - self.kappa2 * self.L * v[None, :]  # ∂load_i/∂ℓ_j
        dpsi_dl, dpsi_dp = np.diag(-self.rate * v), np.diag(-self.rate * e_psi)
        if self.model == "quasi-static":
            a = self.A[:, None]
            top = np.hstack(
                [(dload - self.B[:, None] * dpsi_dl) / a, -self.B[:, None] * dpsi_dp / a]
            )
            return np.vstack([top, np.hstack([dpsi_dl, dpsi_dp])])
        em = np.exp(-lnv) / self.mass
        zero = np.zeros((n, n))
        dl = np.hstack([np.diag(-y[2 * n :] * em), zero, np.diag(em)])  # ℓ' = z e^(−ℓ)/M̂
        dp = np.hstack([dpsi_dl, dpsi_dp, zero])
        b = self.B[:, None]
        dz = np.hstack([dload, zero, zero]) - self.A[:, None] * dl - b * dp
        return np.vstack([dl, dp, dz])


def event_maxima(blocks, y0, t_end, t_from=0.0, call=RUN_CALL):
    """Times and values of the maxima of ℓ_0 in (t_from, t_end] (D0_ref/V): SciPy events
    where ℓ_0' crosses zero downwards. Returns ``(times, values, final state)``."""

    def falling(t, y):
        return blocks.rhs(t, y)[0]

    falling.direction = -1
    implicit = call.get("method") in ("LSODA", "Radau", "BDF")
    extra = {"jac": blocks.jacobian} if implicit else {}
    sol = solve_ivp(blocks.rhs, (0.0, t_end), y0, events=falling, **call, **extra)
    assert sol.status == 0, sol.message
    t, y = sol.t_events[0], sol.y_events[0]
    keep = t > t_from
    return t[keep], y[keep, 0], sol.y[:, -1]


def lyapunov_fit(blocks, y0, t_end, dt=0.05, renorm=50.0, call=RUN_CALL):
    """λ1 (per D0_ref/V) over one run from ``y0`` to ``t_end`` as the engine defines its
    estimate with ``lyapunov: always``: the least-squares slope of S(t), the log growth
    of a tangent started at t = 0 along (1, 1 + 1/n, …) normalised, over t_end/8 …
    t_end (the first eighth a transient). S is sampled every ``dt`` from the
    variational equations δ' = J(y) δ integrated with the state in one system, δ
    renormalised to length 1 every ``renorm``. Implicit methods approximate the
    system's Jacobian by differences themselves: it steers their Newton iterations only,
    not the accuracy (a hand-made one with the cross term ∂(J δ)/∂y by differences was
    ten times slower: 3000 D0/V of inertial chaos in over 15 min instead of 65 s)."""
    n = y0.size

    def fun(t, z):
        y, d = z[:n], z[n:]
        return np.concatenate([blocks.rhs(t, y), blocks.jacobian(t, y) @ d])

    d = 1.0 + np.arange(n) / n
    z = np.concatenate([y0, d / np.linalg.norm(d)])
    times, logs, t, base = [], [], 0.0, 0.0
    while t < t_end - 1e-9:
        step = min(renorm, t_end - t)
        grid = np.arange(1, round(step / dt) + 1) * dt + t
        sol = solve_ivp(fun, (t, t + step), z, t_eval=grid, **call)
        assert sol.status == 0, sol.message
        times.append(sol.t)
        logs.append(base + np.log(np.linalg.norm(sol.y[n:], axis=0)))
        z = sol.y[:, -1]
        norm = float(np.linalg.norm(z[n:]))
        z[n:] /= norm
        base += math.log(norm)
        t += step
    times, logs = np.concatenate(times), np.concatenate(logs)
    keep = times >= t_end / 8
    return float(np.polyfit(times[keep], logs[keep], 1)[0])


def zero_one_test(series, n_c=100, seed=0):
    """Median over ``n_c`` random frequencies c ∈ (π/5, 4π/5) of the correlation K_c
    between the mean square displacement of the translation variables and time
    (Gottwald & Melbourne 2009, with their oscillatory term subtracted): ≈ 1 for a
    chaotic series, ≈ 0 for a regular one."""
    phi = np.asarray(series, float)
    phi = phi - phi.mean()
    n = phi.size
    n_cut = n // 10
    j = np.arange(1, n + 1)
    ns = np.arange(1, n_cut + 1)
    rng = np.random.default_rng(seed)
    ks = []
    for c in rng.uniform(math.pi / 5, 4 * math.pi / 5, n_c):
        p = np.cumsum(phi * np.cos(j * c))
        q = np.cumsum(phi * np.sin(j * c))
        m = np.array([np.mean((p[k:] - p[:-k]) ** 2 + (q[k:] - q[:-k]) ** 2) for k in ns])
        d = m - phi.var() * (1 - np.cos(ns * c)) / (1 - np.cos(c))
        ks.append(np.corrcoef(ns, d)[0, 1])
    return float(np.median(ks))
