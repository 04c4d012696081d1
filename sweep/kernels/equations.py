"""Right-hand side of the log-form equations and its analytic Jacobian.

The equations are documented in ``sweep/model/physics.py`` (plain numpy); these are their
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
def block_parameters(p, nb, i):
    """Block ``i``'s own A, B, κ1 and state-rate factor D0/D0_i from a parameter row
    whose blocks differ (``layout``: the columns after N_PARAMS)."""
    return (
        p[N_PARAMS + B_A * nb + i],
        p[N_PARAMS + B_B * nb + i],
        p[N_PARAMS + B_KAPPA1 * nb + i],
        p[N_PARAMS + B_RATE * nb + i],
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
            A, B, kappa1, rate = block_parameters(p, nb, i)
            dpsi *= rate
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


@jit_inline
def block_jacobian(y, f, p, model, law, coupling, het, nb, ev, i):
    """Block ``i``'s entries of the Jacobian of :func:`rhs` (V/D0 per unit of state)
    but its coupling to other blocks, shared by :func:`jacobian` and the structured
    matrix of ``methods/rodas4_structured.py``: ``(psi_l, psi_psi, l_l, l_z, row_l,
    row_z, row_psi, denom)``.

    ψ_i' depends on ℓ_i (``psi_l``) and ψ_i (``psi_psi``). The driving term load − B ψ'
    enters the block's row ``row`` (z_i inertial, else ℓ_i) divided by ``denom``: that
    row's entries in ℓ_i (with κ2's own term), ψ_i and z_i are ``row_l``, ``row_psi``,
    ``row_z``; each coupled block j adds :func:`coupling_entry` in ℓ_j. Inertial only
    (else 0): ℓ_i''s entries in ℓ_i and z_i, ``l_l`` and ``l_z``. ``f`` = rhs(y) (its
    ℓ rows enter); ``ev`` holds e^ℓ (length nb).
    """
    A = p[P_A]
    B = p[P_B]
    kappa1 = p[P_KAPPA1]
    kappa2 = p[P_KAPPA2]
    e = ev[i]
    if law == AGING:
        dpsi_dlnv = -e
        dpsi_dpsi = -np.exp(-y[nb + i])
    else:
        dpsi_dlnv = -e * (y[i] + y[nb + i] + 1.0)
        dpsi_dpsi = -e
    if het:
        A, B, kappa1, rate = block_parameters(p, nb, i)
        dpsi_dlnv *= rate
        dpsi_dpsi *= rate
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
    l_l, l_z, row_z = 0.0, 0.0, 0.0
    if model == INERTIAL:
        denom = 1.0
        em = np.exp(-y[i]) / p[P_MASS]
        l_l, l_z, row_z = -f[i], em, -A * em
        row_l = A * f[i]
    else:
        denom = A if model == QUASI_STATIC else A + p[P_ETA] * e
        row_l = -f[i] * p[P_ETA] * e / denom if model == QUASI_DYNAMIC else 0.0
    row_l += (dload_self - B * dpsi_dlnv) / denom
    return dpsi_dlnv, dpsi_dpsi, l_l, l_z, row_l, row_z, -B * dpsi_dpsi / denom, denom


@jit_inline
def coupling_entry(p, ev, j, denom):
    """The Jacobian entry of a block's row (``block_jacobian``, divided by ``denom``) in
    the ℓ_j of a block j coupled to it (V/D0)."""
    return p[P_KAPPA2] * ev[j] / denom


@jit
def jacobian(y, f, p, model, law, coupling, het, nb, ev, jac):
    """Analytic Jacobian ∂(dy/dτ)/∂y of :func:`rhs` at ``y`` into ``jac`` (n × n, V/D0).

    ``f`` = rhs(y) (its ℓ rows enter the quasi-dynamic and inertial entries);
    ``ev`` is scratch for e^ℓ (length nb). A ring's neighbours add up: in a ring of two
    blocks both are the other block, in a ring of one the block itself.
    """
    jac[:, :] = 0.0
    for i in range(nb):
        ev[i] = np.exp(y[i])
    for i in range(nb):
        psi_l, psi_psi, l_l, l_z, row_l, row_z, row_psi, denom = block_jacobian(
            y, f, p, model, law, coupling, het, nb, ev, i
        )
        jac[nb + i, i] = psi_l
        jac[nb + i, nb + i] = psi_psi
        row = i
        if model == INERTIAL:
            row = 2 * nb + i
            jac[i, i] = l_l
            jac[i, row] = l_z
            jac[row, row] = row_z
        jac[row, i] = row_l
        jac[row, nb + i] = row_psi
        if coupling == CHAIN:
            if i > 0:
                jac[row, i - 1] += coupling_entry(p, ev, i - 1, denom)
            if i < nb - 1:
                jac[row, i + 1] += coupling_entry(p, ev, i + 1, denom)
        elif coupling == RING:
            left, right = i - 1 if i > 0 else nb - 1, i + 1 if i < nb - 1 else 0
            jac[row, left] += coupling_entry(p, ev, left, denom)
            jac[row, right] += coupling_entry(p, ev, right, denom)
        else:
            for j in range(nb):
                if j != i:
                    jac[row, j] = coupling_entry(p, ev, j, denom)


@jit_inline
def coupled_sum(coupling, nb, i, x, xi, total):
    """κ2's coupling term of block ``i`` over per-block values ``x`` (``xi`` = x[i]):
    Σ over its neighbours of x_j − x_i (chain, ring), or ``total`` − nb x_i with
    ``total`` = Σ_j x_j (every pair)."""
    if coupling == CHAIN:
        out = 0.0
        if i > 0:
            out += x[i - 1] - xi
        if i < nb - 1:
            out += x[i + 1] - xi
        return out
    if coupling == RING:
        return x[i - 1 if i > 0 else nb - 1] + x[i + 1 if i < nb - 1 else 0] - 2.0 * xi
    return total - nb * xi


@jit
def rhs_jvp(y, u, p, model, law, coupling, het, nb, ev, work, out):
    """J(y) u: the derivative of :func:`rhs` at ``y`` along ``u`` (V/D0 per unit of
    ``u``), into ``out``, without forming J.

    The tangent for λ1 is carried by it (``tangent.py``): a difference of two steps
    cannot resolve the inertial stick phases, where ℓ' = z e^(−ℓ)/M̂ changes by 1e10 per
    unit of z (test_tangent.py). ``ev`` and ``work`` are scratch of length nb.
    """
    A = p[P_A]
    B = p[P_B]
    kappa1 = p[P_KAPPA1]
    kappa2 = p[P_KAPPA2]
    total = 0.0  # Σ e^ℓ_j and Σ e^ℓ_j u_ℓj: every pair coupled
    dtotal = 0.0
    for i in range(nb):
        ev[i] = np.exp(y[i])
        work[i] = ev[i] * u[i]  # the change of e^ℓ_i along u
        total += ev[i]
        dtotal += work[i]
    for i in range(nb):
        lnv = y[i]
        psi = y[nb + i]
        e = ev[i]
        de = work[i]
        if law == AGING:
            ep = np.exp(-psi)
            dpsi = ep - e
            d_dpsi = -ep * u[nb + i] - de
        else:
            dpsi = -e * (lnv + psi)
            d_dpsi = -de * (lnv + psi) - e * (u[i] + u[nb + i])
        if het:
            A, B, kappa1, rate = block_parameters(p, nb, i)
            dpsi *= rate
            d_dpsi *= rate
        load = kappa1 * (1.0 - e) + kappa2 * coupled_sum(coupling, nb, i, ev, e, total)
        d_load = -kappa1 * de + kappa2 * coupled_sum(coupling, nb, i, work, de, dtotal)
        d_num = d_load - B * d_dpsi
        if model == QUASI_STATIC:
            d_lnv = d_num / A
        elif model == QUASI_DYNAMIC:
            den = A + p[P_ETA] * e
            d_lnv = (d_num - (load - B * dpsi) / den * p[P_ETA] * de) / den
        else:
            em = np.exp(-lnv) / p[P_MASS]
            d_lnv = (u[2 * nb + i] - y[2 * nb + i] * u[i]) * em
            out[2 * nb + i] = d_num - A * d_lnv
        out[i] = d_lnv
        out[nb + i] = d_dpsi


@jit
def rhs_curvature(y, u, w, p, model, law, coupling, het, nb, ev, work, out):
    """f''(y)[u, w]: the second derivative of :func:`rhs` at ``y`` along ``u`` and
    ``w`` (symmetric in them), into ``out``. RODAS4's tangent needs it: its matrix
    holds J(y), whose change along δ moves every stage (``tangent.py``).
    ``ev`` is scratch of length nb, ``work`` of (3, nb).
    """
    A = p[P_A]
    B = p[P_B]
    kappa1 = p[P_KAPPA1]
    kappa2 = p[P_KAPPA2]
    du_e, dw_e, d2_e = work[0], work[1], work[2]  # changes of e^ℓ_i along u, w, both
    tot_u = 0.0
    tot_w = 0.0
    tot_uw = 0.0
    for i in range(nb):
        ev[i] = np.exp(y[i])
        du_e[i] = ev[i] * u[i]
        dw_e[i] = ev[i] * w[i]
        d2_e[i] = ev[i] * u[i] * w[i]
        tot_u += du_e[i]
        tot_w += dw_e[i]
        tot_uw += d2_e[i]
    total = 0.0
    for i in range(nb):
        total += ev[i]
    for i in range(nb):
        lnv = y[i]
        psi = y[nb + i]
        e = ev[i]
        ul, up, wl, wp = u[i], u[nb + i], w[i], w[nb + i]
        if law == AGING:
            ep = np.exp(-psi)
            dpsi = ep - e
            du_dpsi = -ep * up - du_e[i]
            dw_dpsi = -ep * wp - dw_e[i]
            d2_dpsi = ep * up * wp - d2_e[i]
        else:
            s = lnv + psi
            dpsi = -e * s
            du_dpsi = -e * (ul * (s + 1.0) + up)
            dw_dpsi = -e * (wl * (s + 1.0) + wp)
            d2_dpsi = -e * (ul * wl * (s + 2.0) + wl * up + ul * wp)
        if het:
            A, B, kappa1, rate = block_parameters(p, nb, i)
            dpsi *= rate
            du_dpsi *= rate
            dw_dpsi *= rate
            d2_dpsi *= rate
        d2_load = -kappa1 * d2_e[i] + kappa2 * coupled_sum(coupling, nb, i, d2_e, d2_e[i], tot_uw)
        d2_num = d2_load - B * d2_dpsi
        if model == QUASI_STATIC:
            d2_lnv = d2_num / A
        elif model == QUASI_DYNAMIC:
            eta = p[P_ETA]
            den = A + eta * e
            lnv_rate = (
                kappa1 * (1.0 - e) + kappa2 * coupled_sum(coupling, nb, i, ev, e, total) - B * dpsi
            ) / den
            du_num = (
                -kappa1 * du_e[i]
                + kappa2 * coupled_sum(coupling, nb, i, du_e, du_e[i], tot_u)
                - B * du_dpsi
            )
            dw_num = (
                -kappa1 * dw_e[i]
                + kappa2 * coupled_sum(coupling, nb, i, dw_e, dw_e[i], tot_w)
                - B * dw_dpsi
            )
            du_lnv = (du_num - lnv_rate * eta * du_e[i]) / den
            dw_lnv = (dw_num - lnv_rate * eta * dw_e[i]) / den
            d2_lnv = (
                d2_num - du_lnv * eta * dw_e[i] - dw_lnv * eta * du_e[i] - lnv_rate * eta * d2_e[i]
            ) / den
        else:
            em = np.exp(-lnv) / p[P_MASS]
            uz, wz = u[2 * nb + i], w[2 * nb + i]
            d2_lnv = (y[2 * nb + i] * ul * wl - uz * wl - wz * ul) * em
            out[2 * nb + i] = d2_num - A * d2_lnv
        out[i] = d2_lnv
        out[nb + i] = d2_dpsi
