"""An independent reference for Floquet multipliers, plain numpy + SciPy.

Written from the physics brief (``shared/physics.md`` §2, §4, §5d), not from ``sweep``:

- one radiation-damped block (state ℓ, ψ; time in D0/V; η̂ = ηV/W)::

      ψ' = e^(−ψ) − e^ℓ (aging)   or   −e^ℓ (ℓ + ψ) (slip)
      ℓ' = [κ (1 − e^ℓ) − B ψ'] / (A + η̂ e^ℓ)

  whose non-trivial multiplier is exp(∮ tr J dt) (Liouville), tr J written out by hand
  (and checked against central differences of the right-hand side in the tests);
- any system's multipliers as the eigenvalues of the derivative of its Poincaré return map
  to a section ℓ_0 = level (crossed upwards), by forward differences of SciPy runs started
  on the section.
"""

import numpy as np
from scipy.integrate import solve_ivp

#: The SciPy call of the references (the issue's: Radau, rtol ≤ 1e-11).
RADAU = {"method": "Radau", "rtol": 1e-11, "atol": 1e-13}


class DampedBlock:
    """One quasi-dynamic block: A, B, κ = K D0/W, η̂ = ηV/W, state law "aging" or "slip"."""

    def __init__(self, A, B, kappa, eta_hat, law):
        self.A, self.B, self.kappa, self.eta, self.law = A, B, kappa, eta_hat, law

    def dpsi(self, lnv, psi):
        v = np.exp(lnv)
        return np.exp(-psi) - v if self.law == "aging" else -v * (lnv + psi)

    def rhs(self, t, y):
        lnv, psi = y[0], y[1]
        v = np.exp(lnv)
        dpsi = self.dpsi(lnv, psi)
        return np.array([(self.kappa * (1 - v) - self.B * dpsi) / (self.A + self.eta * v), dpsi])

    def trace(self, y):
        """tr J = ∂ℓ'/∂ℓ + ∂ψ'/∂ψ at ``y`` (per D0/V), by hand."""
        lnv, psi = y[0], y[1]
        v = np.exp(lnv)
        dpsi = self.dpsi(lnv, psi)
        if self.law == "aging":
            dpsi_dl, dpsi_dpsi = -v, -np.exp(-psi)
        else:
            dpsi_dl, dpsi_dpsi = -v * (lnv + psi + 1), -v
        den = self.A + self.eta * v
        num = self.kappa * (1 - v) - self.B * dpsi
        dl_dl = (-self.kappa * v - self.B * dpsi_dl) / den - num * self.eta * v / den**2
        return dl_dl + dpsi_dpsi


def settle(rhs, y0, t_settle, call=RADAU):
    """The state after ``t_settle`` (D0/V) from ``y0``."""
    sol = solve_ivp(rhs, (0.0, t_settle), y0, **call)
    return sol.y[:, -1]


def upward_crossing(level, index=0):
    """A solve_ivp event: y[index] rising through ``level``."""

    def event(t, y):
        return y[index] - level

    event.direction = 1.0
    return event


def on_section(rhs, y, level, t_max, call=RADAU, index=0):
    """The first point after ``y`` where y[index] rises through ``level``."""
    sol = solve_ivp(rhs, (0.0, t_max), y, events=upward_crossing(level, index), **call)
    return sol.y_events[0][0]


def return_map(rhs, y, level, returns, t_max, call=RADAU, index=0):
    """``(point, time)``: the ``returns``-th later upward crossing of y[index] = level from
    ``y`` on the section, and the time it took (D0/V)."""
    event = upward_crossing(level, index)
    sol = solve_ivp(rhs, (0.0, t_max), y, events=event, **call)
    times = sol.t_events[0]
    points = sol.y_events[0]
    later = np.flatnonzero(times > 1e-9)
    if later.size < returns:
        raise RuntimeError(f"{later.size} returns in {t_max} D0/V, {returns} asked")
    k = later[returns - 1]
    return points[k], times[k]


def liouville_multiplier(block, y, level, t_max, call=RADAU):
    """``(μ, T)``: exp(∮ tr J dt) over one return of ``block`` (a :class:`DampedBlock`) to
    ℓ = ``level`` from ``y`` on that section, and the period T (D0/V)."""

    def augmented(t, x):
        return np.append(block.rhs(t, x[:2]), block.trace(x[:2]))

    event = upward_crossing(level)
    sol = solve_ivp(augmented, (0.0, t_max), np.append(y, 0.0), events=event, **call)
    later = np.flatnonzero(sol.t_events[0] > 1e-9)
    k = later[0]
    return float(np.exp(sol.y_events[0][k][2])), float(sol.t_events[0][k])


def poincare_multipliers(rhs, y, level, returns, t_max, eps=1e-6, call=RADAU, index=0):
    """Eigenvalues of the derivative of the return map (the ``returns``-th upward crossing of
    y[index] = ``level``) at ``y`` on that section, by forward differences of step ``eps``
    in every other coordinate (truncation O(eps), 1e-6 of the multipliers; round-off
    rtol/eps, 1e-5 at rtol 1e-11): the non-trivial Floquet multipliers."""
    free = [j for j in range(y.size) if j != index]
    base = return_map(rhs, y, level, returns, t_max, call, index)[0][free]
    jac = np.empty((len(free), len(free)))
    for c, j in enumerate(free):
        start = y.copy()
        start[j] += eps
        jac[:, c] = (
            return_map(rhs, start, level, returns, t_max, call, index)[0][free] - base
        ) / eps
    return np.linalg.eigvals(jac)
