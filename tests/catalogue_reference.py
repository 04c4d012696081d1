"""An independent slip-event catalogue: SciPy integrates a chain of blocks with each
block's slip as a state variable, and the events are cut from its dense output.

Written from the physics brief (log form, ``shared/physics.md``) and the catalogue's
definition (``sweep/kernels/slip_events.py`` docstring), not from the engine: an event
lasts while some block's v/V exceeds the threshold; it begins where the first block
rises through it and ends where the last one falls through it; a block slipped in it
if its v exceeded the threshold; the event's slip is the sum of those blocks' slip
s_i(t_end) − s_i(t_start), s_i' = v_i/V (in D0). Time in D0/V.

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


def catalogue(model, sol, threshold_lnv, after=0.0):
    """The events of a run ``sol`` of ``model`` (:class:`ChainModel`) that began at or
    after ``after``: a list of dicts with ``start``, ``end`` (D0/V), ``first``,
    ``blocks`` (how many slipped), ``slip`` (summed, D0) and ``lnv_peak``."""
    n, t = model.n, sol.t
    lnv = sol.y[:n]
    crossings = []  # (time, block, rising)
    for i in range(n):
        above = lnv[i] > threshold_lnv
        for k in np.flatnonzero(above[1:] != above[:-1]):
            f = lambda s, i=i: sol.sol(s)[i] - threshold_lnv  # noqa: E731
            crossings.append((brentq(f, t[k], t[k + 1], xtol=1e-14, rtol=1e-15), i, not above[k]))
    crossings.sort()
    events, up, current = [], set(), None
    for time, block, rising in crossings:
        if rising:
            if not up:
                current = {"start": time, "first": block, "slipped": set()}
            up.add(block)
            current["slipped"].add(block)
        else:
            up.discard(block)
            if not up and current is not None:
                current["end"] = time
                events.append(current)
                current = None
    out = []
    for e in events:
        if e["start"] < after:
            continue
        s0, s1 = sol.sol(e["start"])[-n:], sol.sol(e["end"])[-n:]
        blocks = sorted(e["slipped"])
        peak = _peak(sol, n, e["start"], e["end"], t)
        out.append({"start": e["start"], "end": e["end"], "first": e["first"],
                    "blocks": len(blocks), "slip": float((s1 - s0)[blocks].sum()),
                    "lnv_peak": peak})  # fmt: skip
    return out


def _peak(sol, n, start, end, t):
    """The largest ℓ_i of any block over [start, end]: sampled on the solver's steps
    (nine points each), then refined by bounded Brent on the dense output around each
    block's three largest sampled local maxima."""
    inside = t[(t > start) & (t < end)]
    grid = np.concatenate([[start], inside, [end]])
    fine = np.unique(np.linspace(grid[:-1], grid[1:], 9, axis=1))
    values = sol.sol(fine)[:n]
    peak = float(values.max())
    for block, row in enumerate(values):
        humps = np.flatnonzero((row[1:-1] >= row[:-2]) & (row[1:-1] >= row[2:])) + 1
        for k in humps[np.argsort(row[humps])[-3:]]:
            best = minimize_scalar(lambda s, b=block: -sol.sol(s)[b], bounds=fine[[k - 1, k + 1]],
                                   method="bounded", options={"xatol": 1e-12})  # fmt: skip
            peak = max(peak, -float(best.fun))
    return peak
