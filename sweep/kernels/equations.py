"""Right-hand side of the log-form equations and its analytic Jacobian.

The equations are documented in ``sweep/physics.py`` (plain numpy); these are their
jitted forms on one system's state ``y`` (``layout`` docstring) and parameter row ``p``.
"""

import numpy as np

from ..accelerate import jit, jit_inline
from .layout import (
    AGING,
    ALL,
    B_A,
    B_B,
    B_KAPPA1,
    B_RATE,
    CHAIN,
    INERTIAL,
    N_PARAMS,
    P_A,
    P_B,
    P_ETA,
    P_KAPPA1,
    P_KAPPA2,
    P_MASS,
    QUASI_DYNAMIC,
    QUASI_STATIC,
    RING,
)


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
