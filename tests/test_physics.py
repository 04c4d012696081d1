"""The model's linear theory (sweep/model/physics.py) against the physics brief's closed forms,
and the kernels' right-hand side against that theory (fixed point, Jacobian)."""

import numpy as np
import pytest
from conftest import PAPER_A, PAPER_B
from scipy.optimize import brentq

from sweep.kernels import equations, layout
from sweep.model import physics

A, B = PAPER_A, PAPER_B
MODEL_CODES = {
    "quasi-static": layout.QUASI_STATIC,
    "quasi-dynamic": layout.QUASI_DYNAMIC,
    "inertial": layout.INERTIAL,
}
LAW_CODES = {"aging": layout.AGING, "slip": layout.SLIP}
# Off-critical parameters with every term of the right-hand side switched on:
# κ1 = 0.045 (below κc = 0.05), κ2 = 0.02, η̂ = 0.01, M̂ = 0.1.
KAPPA1, KAPPA2, ETA_HAT, MASS_HAT = 0.045, 0.02, 0.01, 0.1
# the compiled kernel and its pure-Python original (the same function when NUMBA_DISABLE_JIT=1)
RHS_KERNELS = {"jit": equations.rhs, "python": getattr(equations.rhs, "py_func", equations.rhs)}


def param_row(kappa1=KAPPA1, kappa2=KAPPA2, eta_hat=ETA_HAT, mass_hat=MASS_HAT):
    p = np.zeros(layout.N_PARAMS)
    p[layout.P_A], p[layout.P_B] = A, B
    p[layout.P_KAPPA1], p[layout.P_KAPPA2] = kappa1, kappa2
    p[layout.P_ETA], p[layout.P_MASS] = eta_hat, mass_hat
    return p


def n_vars(model_name, nb):
    return 3 * nb if model_name == "inertial" else 2 * nb


def kernel_rhs(rhs, y, p, model_name, law, nb):
    dydt = np.full(y.size, np.nan)
    rhs(y, p, MODEL_CODES[model_name], LAW_CODES[law], layout.CHAIN, False, nb, np.empty(nb), dydt)
    return dydt


def fd_jacobian(rhs, p, model_name, law, nb, h=1e-6):
    """Central finite-difference Jacobian of the kernel's rhs at steady sliding (y = 0)."""
    n = n_vars(model_name, nb)
    jac = np.empty((n, n))
    for j in range(n):
        dy = np.zeros(n)
        dy[j] = h
        up = kernel_rhs(rhs, dy, p, model_name, law, nb)
        down = kernel_rhs(rhs, -dy, p, model_name, law, nb)
        jac[:, j] = (up - down) / (2 * h)
    return jac


def sorted_eigs(values):
    return np.sort_complex(np.asarray(values).ravel())


# Central differences with h = 1e-6: truncation ~h²|f'''| ~ 1e-12 times the entries'
# scale, rounding ~1e-16/h = 1e-10; entries are at most ~1/M̂ = 10. Hence 1e-7.
FD_TOL = 1e-7


@pytest.mark.parametrize("kind", sorted(RHS_KERNELS))
@pytest.mark.parametrize("nb", [1, 2, 3])
@pytest.mark.parametrize("law", sorted(LAW_CODES))
@pytest.mark.parametrize("model_name", physics.MODELS)
def test_steady_sliding_is_a_fixed_point(model_name, law, nb, kind):
    """ℓ = ψ = 0 (and σ = 0) is steady sliding: every derivative vanishes exactly."""
    y = np.zeros(n_vars(model_name, nb))
    dydt = kernel_rhs(RHS_KERNELS[kind], y, param_row(), model_name, law, nb)
    assert np.array_equal(dydt, np.zeros_like(y))


@pytest.mark.parametrize("kind", sorted(RHS_KERNELS))
@pytest.mark.parametrize("law", sorted(LAW_CODES))
@pytest.mark.parametrize("model_name", physics.MODELS)
def test_one_block_jacobian_is_mode_jacobian(model_name, law, kind):
    jac = fd_jacobian(RHS_KERNELS[kind], param_row(), model_name, law, 1)
    expected = physics.mode_jacobian(model_name, A, B, KAPPA1, ETA_HAT, MASS_HAT)
    np.testing.assert_allclose(jac, expected, rtol=FD_TOL, atol=FD_TOL)


def test_quasi_static_jacobian_closed_form():
    """The brief's J = [[(B − κ)/A, B/A], [−1, −1]], trace (B − A − κ)/A, det κ/A."""
    jac = physics.mode_jacobian("quasi-static", A, B, KAPPA1)
    np.testing.assert_allclose(jac, [[(B - KAPPA1) / A, B / A], [-1.0, -1.0]], rtol=1e-15)
    assert np.trace(jac) == pytest.approx((B - A - KAPPA1) / A, rel=1e-14)
    assert np.linalg.det(jac) == pytest.approx(KAPPA1 / A, rel=1e-12)


def one_block_eigs(model_name, kappa):
    """Eigenvalues of the one-block Jacobian with stiffness κ (numpy on mode_jacobian)."""
    return np.linalg.eigvals(physics.mode_jacobian(model_name, A, B, kappa, ETA_HAT, MASS_HAT))


@pytest.mark.parametrize("law", sorted(LAW_CODES))
@pytest.mark.parametrize("model_name", physics.MODELS)
def test_two_block_eigenvalues_are_in_phase_and_anti_phase_modes(model_name, law):
    """Two blocks: the in-phase pair is the one-block pair (κ1), the anti-phase pair the
    one-block pair with κ1 + 2κ2 (physics brief, section 3 and erratum 3)."""
    jac = fd_jacobian(equations.rhs, param_row(), model_name, law, 2)
    lam = physics.eigenvalues(model_name, 2, A, B, KAPPA1, KAPPA2, ETA_HAT, MASS_HAT)
    np.testing.assert_allclose(
        sorted_eigs(np.linalg.eigvals(jac)), sorted_eigs(lam), rtol=1e-6, atol=1e-6
    )
    in_phase = one_block_eigs(model_name, KAPPA1)
    anti_phase = one_block_eigs(model_name, KAPPA1 + 2 * KAPPA2)
    np.testing.assert_allclose(sorted_eigs(lam[0]), sorted_eigs(in_phase), rtol=1e-12)
    np.testing.assert_allclose(sorted_eigs(lam[1]), sorted_eigs(anti_phase), rtol=1e-12)


@pytest.mark.parametrize("model_name", physics.MODELS)
def test_three_block_chain_eigenvalues(model_name):
    """Open chain of three: mode stiffnesses κ1 + κ2 λ_L with λ_L = 0, 1, 3."""
    jac = fd_jacobian(equations.rhs, param_row(), model_name, "aging", 3)
    expected = np.concatenate(
        [one_block_eigs(model_name, KAPPA1 + KAPPA2 * lam) for lam in (0, 1, 3)]
    )
    # eigenvalues of a finite-difference matrix: error ~ FD_TOL × condition, ≲ 1e-6 here
    np.testing.assert_allclose(
        sorted_eigs(np.linalg.eigvals(jac)), sorted_eigs(expected), rtol=1e-6, atol=1e-6
    )


def test_quasi_static_eigenvalues_closed_form():
    """λ = tr/2 ± sqrt(tr²/4 − det) with tr = (B − A − κ)/A, det = κ/A; Re λ = (B − A − κ)/(2A)
    while the pair is complex (here for κ within ±20 % of κc)."""
    kappa = np.linspace(0.04, 0.06, 11)
    tr, det = (B - A - kappa) / A, kappa / A
    root = np.sqrt((tr**2 / 4 - det).astype(complex))
    expected = np.stack([tr / 2 + root, tr / 2 - root], axis=-1)
    lam = physics.eigenvalues("quasi-static", 1, A, B, kappa)[:, 0, :]
    np.testing.assert_allclose(np.sort_complex(lam), np.sort_complex(expected), rtol=1e-12)
    growth = physics.linear_growth_rate("quasi-static", 1, A, B, kappa)
    np.testing.assert_allclose(growth, (B - A - kappa) / (2 * A), rtol=1e-12, atol=1e-15)


def bisect_kappa_c(model_name, n_blocks=1, kappa2=0.0, eta_hat=0.0, mass_hat=0.0):
    """κ where max Re λ crosses zero, by root bracketing on linear_growth_rate."""

    def growth(kappa):
        return float(
            physics.linear_growth_rate(model_name, n_blocks, A, B, kappa, kappa2, eta_hat, mass_hat)
        )

    return brentq(growth, 1e-4, 100.0, xtol=1e-14, rtol=1e-13)


# The brief's closed forms (sections 3–4), written out here, not taken from the model.
CRITICAL_CASES = (
    [("quasi-static", 0.0, 0.0, B - A)]
    + [("quasi-dynamic", eta, 0.0, B - A - eta) for eta in (0.001, 0.01, 0.03)]
    + [("inertial", 0.0, m, (B - A) * (1 + m / A)) for m in np.geomspace(1e-3, 1.0, 7)]
)


@pytest.mark.parametrize("model_name, eta_hat, mass_hat, expected", CRITICAL_CASES)
def test_critical_kappa(model_name, eta_hat, mass_hat, expected):
    """κc from the closed form = the zero crossing of max Re λ (bisection); the
    inertial case over M̂ from 1e-3 to 1 (three decades)."""
    kc = physics.critical_kappa(model_name, A, B, eta_hat, mass_hat)
    assert kc == pytest.approx(expected, rel=1e-14)
    # brentq converges to ~1e-13 relative; the growth rate is smooth and simple at κc
    assert bisect_kappa_c(model_name, 1, 0.0, eta_hat, mass_hat) == pytest.approx(kc, rel=1e-9)


@pytest.mark.parametrize("kappa2", [0.0, 0.05, 0.5])
def test_two_block_transition_does_not_depend_on_coupling(kappa2):
    """Coupling only stiffens the anti-phase mode: κc = B − A for every κ2 ≥ 0."""
    assert bisect_kappa_c("quasi-static", 2, kappa2) == pytest.approx(B - A, rel=1e-9)


def test_paper_critical_stiffness_and_physical_units():
    """Kc/W = (B − A)/D0: 0.05 µm⁻¹ for D0 = 1 µm and 0.5 µm⁻¹ for D0 = 0.1 µm (erratum 1);
    with mass, Kc = W(B − A)/D0 · (1 + m V²/(W A D0))."""
    for D0, kc_w in ((1.0, 0.05), (0.1, 0.5)):
        dl = physics.dimensionless(A, B, D0, 0.1, kc_w)
        assert physics.critical_kappa("quasi-static", A, B) == pytest.approx(
            dl["kappa1"], rel=1e-12
        )
    m_W, V, D0 = 2.0, 0.1, 1.0  # s² µm⁻¹, µm/s, µm
    dl = physics.dimensionless(A, B, D0, V, 0.05, m_W=m_W)
    assert dl["mass_hat"] == pytest.approx(m_W * V**2 / D0, rel=1e-15)
    kc_w = physics.critical_kappa("inertial", A, B, mass_hat=dl["mass_hat"]) / D0
    assert kc_w == pytest.approx((B - A) / D0 * (1 + m_W * V**2 / (A * D0)), rel=1e-14)


def test_dimensionless_groups():
    dl = physics.dimensionless(A, B, D0=2.0, V=0.5, K_W=0.03, k2_W=0.01, eta_W=0.2, m_W=3.0)
    assert dl["kappa1"] == pytest.approx(0.06)  # K D0/W
    assert dl["kappa2"] == pytest.approx(0.02)  # k2 D0/W
    assert dl["eta_hat"] == pytest.approx(0.1)  # η V/W
    assert dl["mass_hat"] == pytest.approx(3.0 * 0.25 / 2.0)  # m V²/(W D0)
    assert dl["time_unit"] == pytest.approx(4.0)  # D0/V in s


@pytest.mark.parametrize("model_name", ["quasi-static", "inertial"])
@pytest.mark.parametrize("mass_hat", [1e-3, 1e-2, 0.1, 1.0])
def test_onset_frequency_does_not_depend_on_mass(model_name, mass_hat):
    """ω at onset = sqrt((B − A)/A) V/D0, with or without mass (physics brief, section 4);
    the kernel's Jacobian at κc has the pair ±iω."""
    omega = np.sqrt((B - A) / A)
    assert physics.onset_angular_frequency(model_name, A, B, mass_hat=mass_hat) == pytest.approx(
        omega, rel=1e-12
    )
    kc = physics.critical_kappa(model_name, A, B, mass_hat=mass_hat)
    jac = fd_jacobian(equations.rhs, param_row(kc, 0.0, 0.0, mass_hat), model_name, "aging", 1)
    lam = np.linalg.eigvals(jac)
    pair = lam[np.argmax(np.abs(lam.imag))]
    # entries up to A/M̂ = 30: the finite-difference error scales with them
    assert abs(pair.real) < 1e-5
    assert abs(pair.imag) == pytest.approx(omega, rel=1e-6)


def test_paper_onset_period():
    """2π/ω = 4.87 D0/V for A = 0.03, B = 0.08 (physics brief, section 3)."""
    period = 2 * np.pi / physics.onset_angular_frequency("quasi-static", A, B)
    assert round(period, 2) == 4.87


def test_no_instability_without_weakening():
    """B ≤ A (velocity strengthening): κc ≤ 0, no onset frequency."""
    assert physics.critical_kappa("quasi-static", 0.03, 0.02) < 0
    assert np.isnan(physics.onset_angular_frequency("quasi-static", 0.03, 0.02))
