"""An independent slip-event catalogue: SciPy integrates a chain of blocks with each
block's slip as a state variable, and the events are cut from its dense output.

Written from the physics brief (log form, ``shared/physics.md``) and the catalogue's
definition (``sweep/kernels/slip_events.py`` docstring), not from the engine: a block
slips while its v/V exceeds the threshold (an episode, from its rise through it to its
fall); an event is a connected cluster of episodes, those of neighbouring blocks that
overlap in time (cut here by union–find over every pair, not as the engine does it, in
time order); it begins at its first rise and ends at its last fall, and its slip is the
sum of its episodes' slip s_i(fall) − s_i(rise), s_i' = v_i/V (in D0). Time in D0/V.

Models: quasi-dynamic (ℓ_i' = [load − B ψ_i'] / (A + η̂ e^ℓ_i)) and inertial
(ℓ_i' = z_i e^(−ℓ_i)/M̂, z_i' = load − B ψ_i' − A ℓ_i'), aging law, identical A, B and
per-block D0 through the state rate r_i = D0/D0_i; load_i = κ1 (1 − e^ℓ_i) + κ2 Σ_j
(e^ℓ_j − e^ℓ_i) over the neighbours of an open chain.
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar
from scipy.sparse import csc_matrix


class ChainModel:
    """An open chain of ``n`` blocks (module docstring); ``rate``: D0/D0_i per block."""

    def __init__(self, n, model, A, B, kappa1, kappa2, eta=0.0, mass=0.0, rate=1.0):
        self.n, self.model = n, model
        self.A, self.B, self.k1, self.k2, self.eta, self.mass = A, B, kappa1, kappa2, eta, mass
        self.rate = np.broadcast_to(np.asarray(rate, float), (n,)).copy()
        self.vpb = 3 if model == "inertial" else 2  # state per block, before the slips

    def rhs(self, t, y):
        """(ℓ, ψ[, z], s)' for y = (ℓ_1…ℓ_n, ψ_1…ψ_n[, z_1…z_n], s_1…s_n)."""
        n = self.n
        lnv, psi = y[:n], y[n : 2 * n]
        v = np.exp(lnv)
        dpsi = self.rate * (np.exp(-psi) - v)
        coupling = np.zeros(n)
        coupling[1:] += v[:-1] - v[1:]
        coupling[:-1] += v[1:] - v[:-1]
        drive = self.k1 * (1.0 - v) + self.k2 * coupling - self.B * dpsi
        if self.model == "inertial":
            z = y[2 * n : 3 * n]
            dlnv = z * np.exp(-lnv) / self.mass
            return np.concatenate([dlnv, dpsi, drive - self.A * dlnv, v])
        dlnv = drive / (self.A + self.eta * v)
        return np.concatenate([dlnv, dpsi, v])

    def jac(self, t, y):
        """The Jacobian of :meth:`rhs`, derived by hand, as a sparse matrix (Radau and
        BDF then factorise it with a sparse LU: its pattern is a chain's band)."""
        n, m = self.n, self.vpb
        lnv, psi = y[:n], y[n : 2 * n]
        v, ep = np.exp(lnv), np.exp(-psi)
        i = np.arange(n)
        deg = np.full(n, 2.0)
        deg[[0, -1]] = 1.0 if n > 1 else 0.0
        jac = np.zeros(((m + 1) * n, (m + 1) * n))
        jac[n + i, i] = -self.rate * v  # ψ'
        jac[n + i, n + i] = -self.rate * ep
        d_drive = np.zeros((n, (m + 1) * n))  # the drive's derivatives
        d_drive[i, i] = -(self.k1 + self.k2 * deg) * v + self.B * self.rate * v
        d_drive[i[1:], i[:-1]] = self.k2 * v[:-1]
        d_drive[i[:-1], i[1:]] = self.k2 * v[1:]
        d_drive[i, n + i] = self.B * self.rate * ep
        dlnv = self.rhs(t, y)[:n]
        if self.model == "inertial":
            em = np.exp(-lnv) / self.mass
            d_lnv = np.zeros_like(d_drive)
            d_lnv[i, i] = -dlnv
            d_lnv[i, 2 * n + i] = em
            jac[:n] = d_lnv
            jac[2 * n : 3 * n] = d_drive - self.A * d_lnv
        else:
            den = self.A + self.eta * v
            jac[:n] = d_drive / den[:, None]
            jac[i, i] -= dlnv * self.eta * v / den
        jac[m * n + i, i] = v  # s' = v
        return csc_matrix(jac)

    def run(self, y0, t_end, method="Radau", rtol=1e-10, atol=1e-12):
        """Integrate from the state ``y0`` (without slips) to ``t_end`` with dense output."""
        y = np.concatenate([y0, np.zeros(self.n)])
        extra = {"jac": self.jac} if method in ("Radau", "BDF") else {}
        if method == "LSODA":
            extra = {"jac": lambda t, y: self.jac(t, y).toarray()}
        sol = solve_ivp(self.rhs, (0.0, t_end), y, method=method, rtol=rtol, atol=atol,
                        dense_output=True, **extra)  # fmt: skip
        assert sol.success, sol.message
        return sol


def episodes(model, sol, threshold_lnv):
    """Each block's slip episodes: ``(block, rise, fall)`` with v_i above the threshold
    from ``rise`` to ``fall`` (D0/V; rise 0 for a block above it at the start, fall NaN
    for one still above it at the end), crossings by Brent on the dense output."""
    n, t = model.n, sol.t
    out = []
    for i in range(n):
        above = sol.y[i] > threshold_lnv
        f = lambda s, i=i: sol.sol(s)[i] - threshold_lnv  # noqa: E731
        times = [brentq(f, t[k], t[k + 1], xtol=1e-14, rtol=1e-15)
                 for k in np.flatnonzero(above[1:] != above[:-1])]  # fmt: skip
        if above[0]:
            times.insert(0, t[0])
        if above[-1]:
            times.append(np.nan)
        out += [(i, times[k], times[k + 1]) for k in range(0, len(times), 2)]
    return out


def catalogue(model, sol, threshold_lnv, after=0.0):
    """The events of a run ``sol`` of ``model`` (:class:`ChainModel`, an open chain) that
    began at or after ``after``, in the order they ended: connected clusters of episodes
    (:func:`episodes`), two episodes being connected when their blocks are neighbours and
    their times overlap (union–find over every pair). A list of dicts with ``start``,
    ``end`` (D0/V), ``first`` (the block that rose first), ``blocks`` (how many slipped),
    ``slip`` (Σ of each episode's s_i(fall) − s_i(rise), D0) and ``lnv_peak``."""
    eps = episodes(model, sol, threshold_lnv)
    parent = list(range(len(eps)))

    def root(k):
        while parent[k] != k:
            k = parent[k]
        return k

    for a, (i, r1, f1) in enumerate(eps):
        for b, (j, r2, f2) in enumerate(eps[:a]):
            ends_a, ends_b = (np.inf if np.isnan(f1) else f1), (np.inf if np.isnan(f2) else f2)
            if abs(i - j) == 1 and r1 <= ends_b and r2 <= ends_a:
                parent[root(a)] = root(b)
    clusters = {}
    for k in range(len(eps)):
        clusters.setdefault(root(k), []).append(eps[k])
    n, out = model.n, []
    for members in clusters.values():
        falls = [f for _, _, f in members]
        if np.isnan(falls).any():
            continue  # still going at the end of the run
        first, start = min(((r, i) for i, r, _ in members))[::-1]
        if start < after:
            continue
        slip = sum(sol.sol(f)[-n:][i] - sol.sol(r)[-n:][i] for i, r, f in members)
        peak = max(_peak(sol, i, r, f, sol.t) for i, r, f in members)
        out.append({"start": start, "end": max(falls), "first": first,
                    "blocks": len({i for i, _, _ in members}), "slip": float(slip),
                    "lnv_peak": peak})  # fmt: skip
    return sorted(out, key=lambda e: e["end"])


def _peak(sol, block, start, end, t):
    """The largest ℓ of ``block`` over [start, end]: sampled on the solver's steps (nine
    points each), then refined by bounded Brent on the dense output around its three
    largest sampled local maxima."""
    inside = t[(t > start) & (t < end)]
    grid = np.concatenate([[start], inside, [end]])
    fine = np.unique(np.linspace(grid[:-1], grid[1:], 9, axis=1))
    row = sol.sol(fine)[block]
    peak = float(row.max())
    humps = np.flatnonzero((row[1:-1] >= row[:-2]) & (row[1:-1] >= row[2:])) + 1
    for k in humps[np.argsort(row[humps])[-3:]]:
        best = minimize_scalar(lambda s: -sol.sol(s)[block], bounds=fine[[k - 1, k + 1]],
                               method="bounded", options={"xatol": 1e-12})  # fmt: skip
        peak = max(peak, -float(best.fun))
    return peak
