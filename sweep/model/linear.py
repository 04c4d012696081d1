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
modes of ``sweep/model/physics.py``; for unequal ones the eigenvalues of this Jacobian
give the growth rate, and the critical stiffness is where the largest real part
crosses zero as the common K_W varies with the per-block ratios K_i/K fixed.
"""

import functools

import numpy as np

from . import heterogeneity, physics

#: Critical-stiffness search: from an estimate, steps of this factor up to the first
#: stable κ and down to the first unstable one, then the Illinois variant of regula
#: falsi on the largest real part (superlinear; 10-15 Jacobian spectra instead of
#: ~60 for bisection, which matters at 64 blocks) to a bracket of RELATIVE_WIDTH.
BRACKET_FACTOR = 1.25
RELATIVE_WIDTH = 1e-14


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
        raise ValueError(f"model must be one of {physics.MODELS}, got {model_name!r}")
    return jac


def _largest_eigenvalue(jac):
    """The eigenvalue with the largest real part of each matrix of ``jac`` (...)."""
    lam = np.linalg.eigvals(jac)
    return np.take_along_axis(lam, lam.real.argmax(axis=-1)[..., None], axis=-1)[..., 0]


def critical_scale(growth, estimate):
    """Largest κ > 0 at which ``growth(κ)`` (the largest real part) crosses zero.

    Brackets the crossing by steps of :data:`BRACKET_FACTOR` from ``estimate`` (the
    first stable κ above, the first unstable one below it), then narrows the bracket
    by the Illinois method to :data:`RELATIVE_WIDTH`. NaN where no κ within a factor
    1e20 of the estimate is unstable (or none is stable).
    """
    hi, g_hi = estimate, growth(estimate)
    lo, g_lo = np.nan, np.nan
    for _ in range(210):  # 1.25^210 ≈ 1e20
        if g_hi < 0.0:
            break
        lo, g_lo = hi, g_hi
        hi *= BRACKET_FACTOR
        g_hi = growth(hi)
    else:
        return np.nan
    if not g_lo > 0.0:
        lo = hi
        for _ in range(210):
            lo /= BRACKET_FACTOR
            g_lo = growth(lo)
            if g_lo > 0.0:
                break
            hi, g_hi = lo, g_lo
        else:
            return np.nan
    side = 0
    for it in range(200):
        if hi - lo <= RELATIVE_WIDTH * hi:
            break
        c = hi - g_hi * (hi - lo) / (g_hi - g_lo)
        if it >= 100 or not lo < c < hi:  # safeguard: bisection
            c = 0.5 * (lo + hi)
        g_c = growth(c)
        if g_c > 0.0:
            lo, g_lo = c, g_c
            if side > 0:
                g_hi *= 0.5
            side = 1
        elif g_c < 0.0:
            hi, g_hi = c, g_c
            if side < 0:
                g_lo *= 0.5
            side = -1
        else:
            return c
    return 0.5 * (lo + hi)


@functools.lru_cache(maxsize=4096)
def _critical(model_name, coupling, nb, key):
    """(κc, ω at onset) of one set of unequal blocks; ``key``: the tuple (A_i…, B_i…,
    K_i/K…, D0/D0_i…, κ2, η̂, M̂). Cached: the grid and the Dataset ask for the same."""
    k = np.array(key)
    A, B, ratio, rate = (k[i * nb : (i + 1) * nb] for i in range(4))
    kappa2, eta_hat, mass_hat = k[4 * nb :]
    lap = laplacian(nb, coupling)

    def largest(kappa):
        return _largest_eigenvalue(
            steady_jacobian(model_name, A, B, ratio * kappa, rate, kappa2, lap, eta_hat, mass_hat)
        )

    # each block on its own, at its own rate: the mean of their critical κ
    own = physics.critical_kappa(model_name, A, B, eta_hat, mass_hat) * rate / ratio
    estimate = float(np.mean(own)) if np.mean(own) > 0.0 else 1.0
    kc = critical_scale(lambda kappa: largest(kappa).real, estimate)
    return kc, (abs(largest(kc).imag) if kc == kc else np.nan)


@functools.lru_cache(maxsize=65536)
def _growth(model_name, coupling, nb, key):
    """Largest real part at steady sliding for the key of :func:`_critical` + (κ,)."""
    k = np.array(key)
    A, B, ratio, rate = (k[i * nb : (i + 1) * nb] for i in range(4))
    kappa2, eta_hat, mass_hat, kappa = k[4 * nb :]
    jac = steady_jacobian(
        model_name, A, B, ratio * kappa, rate, kappa2, laplacian(nb, coupling), eta_hat, mass_hat
    )
    return float(_largest_eigenvalue(jac).real)


def unequal_theory(model_name, coupling, A, B, ratio, rate, kappa2, eta_hat, mass_hat, kappa):
    """Growth rate at κ and critical κ (with ω at onset) of unequal blocks.

    Per-block arrays (n, nb): ``A``, ``B``, ``ratio`` = K_i/K and ``rate`` = D0/D0_i;
    the others (n,); ``kappa`` is the common κ = K D0/W (block i's κ1_i = ratio_i κ).
    Each distinct parameter set is computed once (and cached). Returns
    ``(growth_rate, kappa_c, omega)``, in units of V/D0 and 1.
    """
    nb = A.shape[1]
    keys = np.column_stack([A, B, ratio, rate, kappa2, eta_hat, mass_hat])
    growth = np.empty(len(keys))
    kc = np.empty(len(keys))
    omega = np.empty(len(keys))
    for r, (key, kap) in enumerate(zip(map(tuple, keys.tolist()), kappa.tolist(), strict=True)):
        kc[r], omega[r] = _critical(model_name, coupling, nb, key)
        growth[r] = _growth(model_name, coupling, nb, key + (kap,))
    return growth, kc, omega


def theory(config, phys, dl, values):
    """Linear theory at every system of a sweep (dimensionless, units of the reference D0/V),
    from its physical parameters ``phys`` (``grid.physical_parameters``), their
    dimensionless ``dl`` (``physics.dimensionless``) and, where blocks differ by config,
    the blocks' ``values`` (``heterogeneity.block_values``).

    Returns a dict of arrays: ``growth_rate`` (max Re λ), ``kappa_c`` (critical
    common κ = Kc D0/W) and ``omega`` (|Im λ| at onset). Systems whose blocks are
    identical use the analytic modes of ``sweep/model/physics.py``; the others the
    eigenvalues of :func:`steady_jacobian`.
    """
    args = (config.model, dl["A"], dl["B"], dl["eta_hat"], dl["mass_hat"])
    growth = physics.linear_growth_rate(
        config.model,
        config.blocks,
        dl["A"],
        dl["B"],
        dl["kappa1"],
        dl["kappa2"],
        dl["eta_hat"],
        dl["mass_hat"],
        config.coupling,
    )
    out = {
        "growth_rate": growth,
        "kappa_c": physics.critical_kappa(*args),
        "omega": physics.onset_angular_frequency(*args),
    }
    if not config.heterogeneous:
        return out
    rows = ~heterogeneity.identical_blocks(values)
    if rows.any():
        factors = heterogeneity.block_factors(config, phys)
        growth, kc, omega = unequal_theory(
            config.model,
            config.coupling,
            values["A"][rows],
            values["B"][rows],
            factors["K_W"][rows],
            1.0 / factors["D0"][rows],
            dl["kappa2"][rows],
            dl["eta_hat"][rows],
            dl["mass_hat"][rows],
            dl["kappa1"][rows],
        )
        for name, value in (("growth_rate", growth), ("kappa_c", kc), ("omega", omega)):
            out[name] = np.array(out[name], float)
            out[name][rows] = value
    return out
