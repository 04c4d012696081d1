"""The Rice–Ruina spring–block model: parameters, scaling and linear stability.

Plain numpy, no numba: this module is the readable statement of the physics that
the kernels integrate (``sweep/kernels/``) and that the tests check against.

Dimensionless log form (physics brief, section 2)::

    ℓ = ln(v/V)        ψ = ln(VΦ/D0)        τ = t V/D0
    κ = K D0/W         η̂ = η V/W            M̂ = m V²/(W D0)

    aging law:  ψ' = e^(−ψ) − e^ℓ          slip law:  ψ' = −e^ℓ (ℓ + ψ)
    quasi-static:   ℓ' = [κ(1 − e^ℓ) − B ψ'] / A
    quasi-dynamic:  ℓ' = [κ(1 − e^ℓ) − B ψ'] / (A + η̂ e^ℓ)
    inertial:       ℓ' = z e^(−ℓ) / M̂,   z' = κ(1 − e^ℓ) − B ψ' − A ℓ'

with z = (m/W) dv/dt = σ − Aℓ − Bψ the inertial force per unit normal load and
σ = (K/W)(Vt − x) − μ_ss the spring force in excess of steady friction. The
inertial state is z, not σ: in stick phases force balance holds to within
z ~ M̂ e^ℓ ℓ', far below the round-off of σ − Aℓ − Bψ, so ℓ' computed from σ
would be noise times e^(−ℓ)/M̂; z keeps full relative precision there. The
quasi-static model is the limit z → 0.
Block i feels κ2 (e^ℓj − e^ℓi) from each block j it is coupled to: its neighbours
in an open chain (the default) or a ring, or every other block (coupling ``all``).
"""

from dataclasses import dataclass

import numpy as np

from ..codes import MODELS, STATE_LAWS  # noqa: F401 (the models and laws, named here)


@dataclass(frozen=True)
class ParameterInfo:
    """A physical model parameter: unit, description and allowed interval."""

    units: str
    long_name: str
    low: float  # lower bound
    low_open: bool  # True: low itself is not allowed


#: Every physical parameter a config may set or sweep, in the units used throughout.
PARAMETERS = {
    "A": ParameterInfo("1", "direct-effect coefficient A", 0.0, True),
    "B": ParameterInfo("1", "evolution-effect coefficient B", 0.0, False),
    "mu0": ParameterInfo("1", "reference friction coefficient mu0", -np.inf, False),
    "V": ParameterInfo("um s-1", "load-point velocity V", 0.0, True),
    "V0": ParameterInfo("um s-1", "reference velocity V0", 0.0, True),
    "Phi0": ParameterInfo("s", "reference state Phi0", 0.0, True),
    "D0": ParameterInfo("um", "characteristic slip distance D0", 0.0, True),
    "K_W": ParameterInfo("um-1", "driving-spring stiffness per normal load K/W", 0.0, True),
    "k2_W": ParameterInfo("um-1", "coupling-spring stiffness per normal load k2/W", 0.0, False),
    "eta_W": ParameterInfo("s um-1", "radiation damping per normal load eta/W", 0.0, False),
    "m_W": ParameterInfo("s2 um-1", "block mass per normal load m/W", 0.0, False),
}

#: The start as a swept dimension (``sweep:`` axes; ``sweep/engine/grid.py``): the initial
#: ln(v/V) and ln(Φ/Φss) of the blocks in ``initial.kicked_blocks`` (default: every block),
#: e.g. a velocity jump from steady sliding on a log axis for the critical kick
#: (``sweep/results/kicks.py``). Not model parameters: the dynamics do not depend on them.
INITIAL_AXES = {
    "initial_v_over_V": ParameterInfo(
        "1", "initial slip velocity / load-point velocity", 0.0, True
    ),
    "initial_phi_over_phi_ss": ParameterInfo(
        "1", "initial state / its steady value Phi/Phi_ss", 0.0, True
    ),
}


def interval_text(name):
    """The allowed interval of parameter ``name``, e.g. ``(0, inf)``."""
    info = PARAMETERS[name]
    low = "-inf" if np.isinf(info.low) else f"{info.low:g}"
    return f"{'(' if info.low_open else '['}{low}, inf)"


def time_unit(D0, V):
    """The model's time unit D0/V in seconds (D0 in µm, V in µm/s)."""
    return np.asarray(D0, float) / np.asarray(V, float)


def dimensionless(A, B, D0, V, K_W, k2_W=0.0, eta_W=0.0, m_W=0.0):
    """Physical parameters → the dimensionless groups the dynamics depend on.

    Returns a dict with ``A``, ``B``, ``kappa1`` = K D0/W, ``kappa2`` = k2 D0/W,
    ``eta_hat`` = η V/W, ``mass_hat`` = m V²/(W D0) and ``time_unit`` = D0/V (s).
    """
    D0 = np.asarray(D0, float)
    V = np.asarray(V, float)
    return {
        "A": np.asarray(A, float),
        "B": np.asarray(B, float),
        "kappa1": np.asarray(K_W, float) * D0,
        "kappa2": np.asarray(k2_W, float) * D0,
        "eta_hat": np.asarray(eta_W, float) * V,
        "mass_hat": np.asarray(m_W, float) * V**2 / D0,
        "time_unit": D0 / V,
    }


def steady_friction(mu0, A, B, V, V0):
    """Steady-state friction coefficient at slip rate V: μ0 + (A − B) ln(V/V0)."""
    return mu0 + (np.asarray(A) - np.asarray(B)) * np.log(np.asarray(V) / np.asarray(V0))


def mode_jacobian(model, A, B, kappa, eta_hat=0.0, mass_hat=0.0):
    """Jacobian at steady sliding of one normal mode with stiffness ``kappa``.

    Rows/columns are (ℓ, ψ) for the quasi-static and quasi-dynamic models and
    (ℓ, ψ, z) for the inertial model; time in units of D0/V. Both state laws
    linearise to ψ' = −ℓ − ψ, so the law does not enter. Arrays broadcast;
    the matrix axes come last.
    """
    A, B, kappa, eta_hat, mass_hat = np.broadcast_arrays(
        *(np.asarray(x, float) for x in (A, B, kappa, eta_hat, mass_hat))
    )
    one = np.ones_like(A)
    if model == "quasi-static":
        rows = [[(B - kappa) / A, B / A], [-one, -one]]
    elif model == "quasi-dynamic":
        rows = [[(B - kappa) / (A + eta_hat), B / (A + eta_hat)], [-one, -one]]
    elif model == "inertial":
        zero = np.zeros_like(A)
        rows = [
            [zero, zero, one / mass_hat],
            [-one, -one, zero],
            [B - kappa, B, -A / mass_hat],
        ]
    else:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def laplacian_eigenvalues(n_blocks, coupling="chain"):
    """Eigenvalues λ_L of the coupling graph's Laplacian, k = 0 … N−1 (λ_0 = 0).

    chain: 2 − 2 cos(π k/N); ring: 2 − 2 cos(2π k/N); all (every pair): N for k ≥ 1.
    """
    k = np.arange(n_blocks)
    if coupling == "chain":
        return 2.0 - 2.0 * np.cos(np.pi * k / n_blocks)
    if coupling == "ring":
        return 2.0 - 2.0 * np.cos(2.0 * np.pi * k / n_blocks)
    if coupling == "all":
        return np.where(k == 0, 0.0, float(n_blocks))
    raise ValueError(f"coupling must be chain, ring or all, got {coupling!r}")


def mode_stiffnesses(n_blocks, kappa1, kappa2, coupling="chain"):
    """Stiffness of each normal mode of identical blocks: κ1 + κ2 λ_L.

    λ_L: :func:`laplacian_eigenvalues`; k = 0 is the in-phase mode (κ1), and for
    two blocks k = 1 is the anti-phase mode (κ1 + 2κ2). Returns a list of N arrays.
    """
    lam = laplacian_eigenvalues(n_blocks, coupling)
    return [np.asarray(kappa1, float) + np.asarray(kappa2, float) * lk for lk in lam]


def eigenvalues(
    model, n_blocks, A, B, kappa1, kappa2=0.0, eta_hat=0.0, mass_hat=0.0, coupling="chain"
):
    """Eigenvalues of the linearised system of identical blocks at steady sliding,
    units of V/D0.

    Returns a complex array with axes (..., mode, eigenvalue), the modes in the
    order of :func:`mode_stiffnesses` (in-phase first).
    """
    modes = [
        np.linalg.eigvals(mode_jacobian(model, A, B, k, eta_hat, mass_hat))
        for k in mode_stiffnesses(n_blocks, kappa1, kappa2, coupling)
    ]
    return np.stack(modes, axis=-2)


def linear_growth_rate(
    model, n_blocks, A, B, kappa1, kappa2=0.0, eta_hat=0.0, mass_hat=0.0, coupling="chain"
):
    """Largest real part of the eigenvalues (units of V/D0); > 0 means unstable."""
    lam = eigenvalues(model, n_blocks, A, B, kappa1, kappa2, eta_hat, mass_hat, coupling)
    return lam.real.max(axis=(-2, -1))


def critical_kappa(model, A, B, eta_hat=0.0, mass_hat=0.0):
    """Critical dimensionless stiffness κc = Kc D0/W of the in-phase mode.

    quasi-static: B − A; quasi-dynamic: B − A − η̂; inertial: (B − A)(1 + M̂/A)
    (physics brief, sections 3–4). Steady sliding is unstable for κ1 < κc.
    For any number of blocks the in-phase mode is the first to go unstable,
    because coupling springs only stiffen the other modes.
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    if model == "quasi-static":
        return B - A
    if model == "quasi-dynamic":
        return B - A - np.asarray(eta_hat, float)
    if model == "inertial":
        return (B - A) * (1.0 + np.asarray(mass_hat, float) / A)
    raise ValueError(f"model must be one of {MODELS}, got {model!r}")


def onset_angular_frequency(model, A, B, eta_hat=0.0, mass_hat=0.0):
    """Angular frequency (units of V/D0) of the oscillation born at κ = κc.

    Computed as Im λ of the in-phase mode at κc; NaN where κc ≤ 0 (no
    instability for any positive stiffness).
    """
    kc = critical_kappa(model, A, B, eta_hat, mass_hat)
    lam = np.linalg.eigvals(mode_jacobian(model, A, B, kc, eta_hat, mass_hat))
    omega = np.abs(lam.imag).max(axis=-1)
    return np.where(kc > 0, omega, np.nan)


def log_form_rhs(t, y, A, B, kappa1, kappa2=0.0, n_blocks=1, law="aging", eta_hat=0.0):
    """Right-hand side of the log form (physics brief, section 2), plain numpy.

    State ``y = (ℓ_1 … ℓ_N, ψ_1 … ψ_N)``, time in D0/V; an open chain with κ2 on
    each coupling spring; ``eta_hat`` > 0 adds radiation damping (quasi-dynamic).
    Written independently of ``sweep.kernels``: the reference the tests integrate with
    SciPy, and what the scalar right-hand side of the SciPy loops in
    ``benchmarks/bench.py`` is checked against (``tests/test_bench.py``).
    """
    lnv, psi = y[:n_blocks], y[n_blocks:]
    v = np.exp(lnv)
    if law == "aging":
        dpsi = np.exp(-psi) - v
    else:  # slip law: dΦ/dt = −(vΦ/D0) ln(vΦ/D0), i.e. ψ' = −e^ℓ (ℓ + ψ)
        dpsi = -v * (lnv + psi)
    coupling = np.zeros(n_blocks)
    coupling[1:] += v[:-1] - v[1:]
    coupling[:-1] += v[1:] - v[:-1]
    dlnv = (kappa1 * (1.0 - v) + kappa2 * coupling - B * dpsi) / (A + eta_hat * v)
    return np.concatenate([dlnv, dpsi])
