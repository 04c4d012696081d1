"""Linear stability of N coupled blocks, equal or not: growth rate and critical stiffness.

Plain numpy. In log form the steady state is ℓ_i = ψ_i = 0 (z_i = 0) for every
block, whatever their parameters: every block slides at V with its own steady state
Φ_i = D0_i/V, and the springs stretch to balance the friction. Linearised about it
(time in units of the reference D0/V, block i's state rate r_i = D0/D0_i, both state
laws give ψ_i' = −r_i (ℓ_i + ψ_i))::

    quasi-static / -dynamic:  (A_i + η̂) ℓ_i' = −κ1_i ℓ_i − κ2 Σ_j L_ij ℓ_j + B_i r_i (ℓ_i + ψ_i)
    inertial:                 ℓ_i' = z_i/M̂,
                              z_i' = −κ1_i ℓ_i − κ2 Σ_j L_ij ℓ_j + B_i r_i (ℓ_i + ψ_i) − A_i z_i/M̂

with L the coupling graph's Laplacian. Identical blocks keep the analytic normal
modes of ``sweep/model.py``; for unequal ones the eigenvalues of this Jacobian
give the growth rate, and the critical stiffness is where the largest real part
crosses zero as the common K_W varies with the per-block ratios K_i/K fixed.
"""

import numpy as np

from . import heterogeneity, model

#: Critical-stiffness search: κ is scanned downwards from the first stable value
#: ``hi`` in factors of 2^(1/2) over SCAN_POINTS points (down to hi 2^(−20), about
#: 1e−6 hi); the largest unstable point and the stable one above it are bisected
#: BISECTIONS times (a bracket ratio of √2 shrinks below double round-off).
SCAN_POINTS = 41
BISECTIONS = 60


def laplacian(n_blocks, coupling="chain"):
    """Graph Laplacian (n_blocks × n_blocks) of the coupling springs: chain, ring or all."""
    adj = np.zeros((n_blocks, n_blocks))
    if coupling == "all":
        adj[:] = 1.0
        np.fill_diagonal(adj, 0.0)
    else:
        i = np.arange(n_blocks - 1)
        adj[i, i + 1] = adj[i + 1, i] = 1.0
        if coupling == "ring":
            adj[0, -1] = adj[-1, 0] = 1.0
        elif coupling != "chain":
            raise ValueError(f"coupling must be chain, ring or all, got {coupling!r}")
    return np.diag(adj.sum(axis=1)) - adj


def steady_jacobian(model_name, A, B, kappa1, rate, kappa2, lap, eta_hat=0.0, mass_hat=0.0):
    """Jacobian at steady sliding of unequal blocks, time in units of the reference D0/V.

    ``A``, ``B``, ``kappa1`` (K_i D0/W), ``rate`` (D0/D0_i): arrays (..., nb);
    ``kappa2``, ``eta_hat``, ``mass_hat``: arrays (...); ``lap``: (nb, nb).
    Variables (ℓ_1…ℓ_N, ψ_1…ψ_N[, z_1…z_N]). Returns (..., 2nb or 3nb, same).
    """
    A, B, kappa1, rate = np.broadcast_arrays(*(np.asarray(x, float) for x in (A, B, kappa1, rate)))
    lead = A.shape[:-1]
    nb = A.shape[-1]
    kappa2, eta_hat, mass_hat = (
        np.broadcast_to(np.asarray(x, float), lead)[..., None, None]
        for x in (kappa2, eta_hat, mass_hat)
    )
    eye = np.eye(nb)
    br = B * rate
    # d(load − B_i ψ_i')/dℓ and /dψ
    drive_l = -(kappa1 - br)[..., :, None] * eye - kappa2 * lap
    drive_psi = br[..., :, None] * eye
    dpsi = -rate[..., :, None] * eye
    inertial = model_name == "inertial"
    n = (3 if inertial else 2) * nb
    jac = np.zeros((*lead, n, n))
    jac[..., nb : 2 * nb, :nb] = dpsi
    jac[..., nb : 2 * nb, nb : 2 * nb] = dpsi
    if inertial:
        jac[..., :nb, 2 * nb :] = eye / mass_hat
        jac[..., 2 * nb :, :nb] = drive_l
        jac[..., 2 * nb :, nb : 2 * nb] = drive_psi
        jac[..., 2 * nb :, 2 * nb :] = -A[..., :, None] * eye / mass_hat
    elif model_name in ("quasi-static", "quasi-dynamic"):
        denom = A if model_name == "quasi-static" else A + eta_hat[..., 0]
        jac[..., :nb, :nb] = drive_l / denom[..., :, None]
        jac[..., :nb, nb : 2 * nb] = drive_psi / denom[..., :, None]
    else:
        raise ValueError(f"model must be one of {model.MODELS}, got {model_name!r}")
    return jac


def _largest_eigenvalue(jac):
    """The eigenvalue with the largest real part of each matrix of ``jac`` (...)."""
    lam = np.linalg.eigvals(jac)
    return np.take_along_axis(lam, lam.real.argmax(axis=-1)[..., None], axis=-1)[..., 0]


def critical_scale(jac_at, n_systems):
    """Largest common stiffness κ > 0 at which the largest real part crosses zero.

    ``jac_at(kappa)``: the Jacobians (n_systems, n, n) at common stiffness κ
    (array (n_systems,)). Stable above the returned κ. Returns ``(kappa_c,
    omega)``, ω = |Im λ| of the critical eigenvalue (V/D0); NaN where no
    κ in the scanned range is unstable.
    """
    hi = np.ones(n_systems)
    for _ in range(60):  # the first stable stiffness from κ = 1 up
        unstable = _largest_eigenvalue(jac_at(hi)).real > 0.0
        if not unstable.any():
            break
        hi = np.where(unstable, 2.0 * hi, hi)
    scan = hi[:, None] * 2.0 ** (-0.5 * np.arange(SCAN_POINTS))[None, :]
    growth = np.stack(
        [_largest_eigenvalue(jac_at(scan[:, k])).real for k in range(SCAN_POINTS)], axis=1
    )
    first = np.argmax(growth > 0.0, axis=1)  # the largest unstable κ (scan goes down)
    found = (growth > 0.0).any(axis=1) & (first > 0)
    rows = np.arange(n_systems)
    lo = np.where(found, scan[rows, first], np.nan)  # unstable
    up = np.where(found, scan[rows, np.maximum(first - 1, 0)], np.nan)  # stable
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + up)
        grows = _largest_eigenvalue(jac_at(np.where(found, mid, 1.0))).real > 0.0
        lo = np.where(grows, mid, lo)
        up = np.where(grows, up, mid)
    kc = 0.5 * (lo + up)
    omega = np.abs(_largest_eigenvalue(jac_at(np.where(found, kc, 1.0))).imag)
    return kc, np.where(found, omega, np.nan)


def unequal_theory(model_name, coupling, A, B, kappa1, rate, kappa2, eta_hat, mass_hat, kappa):
    """Growth rate at κ and critical κ (with ω at onset) of unequal blocks.

    Per-block arrays (n, nb), the others (n,); ``kappa`` is the common κ = K D0/W
    (so κ1_i/κ are the per-block stiffness ratios). Repeated rows are computed once.
    Returns ``(growth_rate, kappa_c, omega)``, in units of V/D0 and 1.
    """
    nb = A.shape[1]
    lap = laplacian(nb, coupling)
    ratio = kappa1 / kappa[:, None]
    keys = np.column_stack([A, B, ratio, rate, kappa2, eta_hat, mass_hat])
    uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    uA, uB, uratio, urate = (uniq[:, k * nb : (k + 1) * nb] for k in range(4))
    uk2, ueta, umass = uniq[:, 4 * nb], uniq[:, 4 * nb + 1], uniq[:, 4 * nb + 2]

    def jac_at(scale):
        return steady_jacobian(
            model_name, uA, uB, uratio * scale[:, None], urate, uk2, lap, ueta, umass
        )

    kc, omega = critical_scale(jac_at, len(uniq))
    full = np.column_stack([keys, kappa])
    ufull, finverse = np.unique(full, axis=0, return_inverse=True)
    finverse = finverse.reshape(-1)
    growth = _largest_eigenvalue(
        steady_jacobian(
            model_name, *(ufull[:, k * nb : (k + 1) * nb] for k in (0, 1)),
            ufull[:, 2 * nb : 3 * nb] * ufull[:, -1:], ufull[:, 3 * nb : 4 * nb],
            ufull[:, 4 * nb], lap, ufull[:, 4 * nb + 1], ufull[:, 4 * nb + 2],
        )
    ).real  # fmt: skip
    return growth[finverse], kc[inverse], omega[inverse]


def theory(config, phys):
    """Linear theory at every system of a sweep (dimensionless, units of the reference D0/V).

    Returns a dict of arrays: ``growth_rate`` (max Re λ), ``kappa_c`` (critical
    common κ = Kc D0/W) and ``omega`` (|Im λ| at onset). Systems whose blocks are
    identical use the analytic modes of ``sweep/model.py``; the others the
    eigenvalues of :func:`steady_jacobian`.
    """
    dl = model.dimensionless(
        phys["A"], phys["B"], phys["D0"], phys["V"], phys["K_W"], phys["k2_W"],
        phys["eta_W"], phys["m_W"],
    )  # fmt: skip
    args = (config.model, dl["A"], dl["B"], dl["eta_hat"], dl["mass_hat"])
    growth = model.linear_growth_rate(
        config.model, config.blocks, dl["A"], dl["B"], dl["kappa1"], dl["kappa2"],
        dl["eta_hat"], dl["mass_hat"], config.coupling,
    )  # fmt: skip
    out = {
        "growth_rate": growth,
        "kappa_c": model.critical_kappa(*args),
        "omega": model.onset_angular_frequency(*args),
    }
    if not config.heterogeneous:
        return out
    values = heterogeneity.block_values(config, phys)
    rows = ~heterogeneity.identical_blocks(values)
    if rows.any():
        D0 = phys["D0"][rows, None]
        growth, kc, omega = unequal_theory(
            config.model, config.coupling, values["A"][rows], values["B"][rows],
            values["K_W"][rows] * D0, D0 / values["D0"][rows], dl["kappa2"][rows],
            dl["eta_hat"][rows], dl["mass_hat"][rows], dl["kappa1"][rows],
        )  # fmt: skip
        for name, value in (("growth_rate", growth), ("kappa_c", kc), ("omega", omega)):
            out[name] = np.array(out[name], float)
            out[name][rows] = value
    return out
