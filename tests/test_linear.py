"""Linear theory of unequal blocks (sweep/model/linear.py) against the analytic normal modes
of identical blocks, closed forms for uncoupled blocks, and finite differences of
the kernels' right-hand side; the kernels' analytic Jacobian with every coupling
and per-block parameters against finite differences."""

import numpy as np
import pytest

from sweep.kernels import equations, layout
from sweep.model import linear, physics

A, B = 0.03, 0.08
MODEL_CODES = {
    "quasi-static": layout.QUASI_STATIC,
    "quasi-dynamic": layout.QUASI_DYNAMIC,
    "inertial": layout.INERTIAL,
}
COUPLING_CODES = {"chain": layout.CHAIN, "ring": layout.RING, "all": layout.ALL}
ETA_HAT, MASS_HAT = 0.01, 0.1
CASES = [(m, c, n) for m in MODEL_CODES for c in COUPLING_CODES for n in (3, 8)]


def extras(model_name):
    return {"eta_hat": ETA_HAT if model_name == "quasi-dynamic" else 0.0,
            "mass_hat": MASS_HAT if model_name == "inertial" else 0.0}  # fmt: skip


@pytest.mark.parametrize("coupling", ["chain", "ring", "all"])
@pytest.mark.parametrize("n_blocks", [3, 4, 7])
def test_laplacian_spectrum_is_the_analytic_one(coupling, n_blocks):
    """The Laplacian matrix built from the springs has the closed-form spectrum the
    analytic modes use (chain 2 − 2cos(πk/N), ring 2 − 2cos(2πk/N), all: N)."""
    lam = np.linalg.eigvalsh(linear.laplacian(n_blocks, coupling))
    expected = np.sort(physics.laplacian_eigenvalues(n_blocks, coupling))
    np.testing.assert_allclose(lam, expected, atol=1e-12)  # round-off of eigvalsh


@pytest.mark.parametrize("model_name, coupling, nb", CASES)
def test_identical_blocks_give_the_analytic_modes(model_name, coupling, nb):
    """The Jacobian's eigenvalues for identical blocks are the analytic modes' (physics.py)."""
    kappa1, kappa2 = 0.045, 0.02
    ex = extras(model_name)
    jac = linear.steady_jacobian(
        model_name, np.full(nb, A), np.full(nb, B), np.full(nb, kappa1), np.ones(nb),
        kappa2, linear.laplacian(nb, coupling), **ex,
    )  # fmt: skip
    got = rounded_sort(np.linalg.eigvals(jac))
    want = rounded_sort(
        physics.eigenvalues(model_name, nb, A, B, kappa1, kappa2, coupling=coupling, **ex).ravel()
    )
    np.testing.assert_allclose(got, want, atol=1e-9)  # eigvals round-off on O(1–10) entries


def rounded_sort(lam):
    """Eigenvalues in a fixed order despite round-off in repeated ones (to 1e-7)."""
    return lam[np.lexsort((np.round(lam.imag, 7), np.round(lam.real, 7)))]


@pytest.mark.parametrize("model_name", list(MODEL_CODES))
@pytest.mark.parametrize("coupling", ["chain", "all"])
def test_critical_stiffness_of_identical_blocks_is_analytic(model_name, coupling):
    """Bisection on the Jacobian finds κc = B − A (− η̂, × (1 + M̂/A)) for every coupling."""
    nb = 4
    ex = extras(model_name)
    one = np.ones((1, nb))
    growth, kc, omega = linear.unequal_theory(
        model_name, coupling, A * one, B * one, one, one, np.array([0.02]),
        np.array([ex["eta_hat"]]), np.array([ex["mass_hat"]]), np.array([0.04]),
    )  # fmt: skip
    want = physics.critical_kappa(model_name, A, B, **ex)
    assert kc[0] == pytest.approx(want, rel=1e-10)  # bisection to round-off
    assert omega[0] == pytest.approx(
        physics.onset_angular_frequency(model_name, A, B, **ex), rel=1e-6
    )  # Im λ at a κ within round-off of κc
    assert growth[0] == pytest.approx(
        physics.linear_growth_rate(model_name, nb, A, B, 0.04, 0.02, coupling=coupling, **ex),
        rel=1e-9,
    )


def test_uncoupled_unequal_blocks_go_unstable_with_the_weakest():
    """κ2 = 0: each block on its own, block i unstable below κ_i = r_i (B_i − A_i) / f_i
    (its own Kc/W = (B_i − A_i)/D0_i); the system's κc is the largest of them."""
    a = np.array([[0.03, 0.025, 0.035]])
    b = np.array([[0.08, 0.07, 0.09]])
    rate = np.array([[1.0, 1.0 / 1.3, 1.0 / 0.8]])
    ratio = np.array([[1.0, 1.2, 0.9]])
    kappa = np.array([0.05])
    _, kc, _ = linear.unequal_theory(
        "quasi-static", "chain", a, b, ratio, rate, np.zeros(1), np.zeros(1),
        np.zeros(1), kappa,
    )  # fmt: skip
    assert kc[0] == pytest.approx((rate * (b - a) / ratio).max(), rel=1e-10)


def het_row(nb, coupling, rng, kappa2=0.03):
    """A kernel parameter row with per-block columns (random unequal blocks)."""
    p = np.zeros(layout.N_PARAMS + layout.N_BLOCK_PARAMS * nb)
    p[layout.P_KAPPA2] = kappa2
    p[layout.P_ETA], p[layout.P_MASS] = ETA_HAT, MASS_HAT
    blocks = {
        layout.B_A: rng.uniform(0.02, 0.04, nb),
        layout.B_B: rng.uniform(0.06, 0.1, nb),
        layout.B_KAPPA1: rng.uniform(0.03, 0.06, nb),
        layout.B_RATE: rng.uniform(0.6, 1.5, nb),
    }
    for k, v in blocks.items():
        p[layout.N_PARAMS + k * nb : layout.N_PARAMS + (k + 1) * nb] = v
    return p, blocks


def kernel_rhs(y, p, model_name, law, nb, coupling):
    out = np.empty_like(y)
    law_code = layout.AGING if law == "aging" else layout.SLIP
    equations.rhs(
        y, p, MODEL_CODES[model_name], law_code, COUPLING_CODES[coupling], True, nb, np.empty(nb),
        out,
    )  # fmt: skip
    return out


def fd_jacobian(y, p, model_name, law, nb, coupling, h=1e-6):
    """Central differences of the kernels' rhs (error ~h² ≈ 1e-12 × third derivatives)."""
    n = y.size
    jac = np.empty((n, n))
    for j in range(n):
        dy = np.zeros(n)
        dy[j] = h
        jac[:, j] = (kernel_rhs(y + dy, p, model_name, law, nb, coupling)
                     - kernel_rhs(y - dy, p, model_name, law, nb, coupling)) / (2 * h)  # fmt: skip
    return jac


@pytest.mark.parametrize("model_name, coupling, nb", CASES)
def test_steady_jacobian_linearises_the_kernels(model_name, coupling, nb):
    """linear.steady_jacobian (written from the linearised equations) equals finite
    differences of equations.rhs at steady sliding, for unequal blocks."""
    p, blk = het_row(nb, coupling, np.random.default_rng(nb))
    n_vars = 3 * nb if model_name == "inertial" else 2 * nb
    fd = fd_jacobian(np.zeros(n_vars), p, model_name, "aging", nb, coupling)
    ex = extras(model_name)
    jac = linear.steady_jacobian(
        model_name, blk[layout.B_A], blk[layout.B_B], blk[layout.B_KAPPA1],
        blk[layout.B_RATE], p[layout.P_KAPPA2], linear.laplacian(nb, coupling), **ex,
    )  # fmt: skip
    np.testing.assert_allclose(jac, fd, atol=1e-6 * np.abs(fd).max())  # FD error ~1e-9


@pytest.mark.parametrize("law", ["aging", "slip"])
@pytest.mark.parametrize("model_name, coupling, nb", CASES)
def test_kernel_jacobian_with_couplings_and_unequal_blocks(model_name, coupling, nb, law):
    """The analytic Jacobian of the Rosenbrock stepper matches finite differences of the
    rhs away from steady sliding, for every coupling with per-block parameters."""
    rng = np.random.default_rng(100 + nb)
    p, _ = het_row(nb, coupling, rng)
    n_vars = 3 * nb if model_name == "inertial" else 2 * nb
    y = rng.uniform(-0.5, 0.5, n_vars)
    f = kernel_rhs(y, p, model_name, law, nb, coupling)
    jac = np.empty((n_vars, n_vars))
    law_code = layout.AGING if law == "aging" else layout.SLIP
    equations.jacobian(
        y, f, p, MODEL_CODES[model_name], law_code, COUPLING_CODES[coupling], True, nb,
        np.empty(nb), jac,
    )  # fmt: skip
    fd = fd_jacobian(y, p, model_name, law, nb, coupling)
    np.testing.assert_allclose(jac, fd, atol=1e-6 * np.abs(fd).max())  # FD error ~1e-9


def kernel_jacobian(y, p, model_name, law, nb, coupling):
    """The kernels' analytic Jacobian (checked against finite differences above)."""
    jac = np.empty((y.size, y.size))
    law_code = layout.AGING if law == "aging" else layout.SLIP
    equations.jacobian(
        y, kernel_rhs(y, p, model_name, law, nb, coupling), p, MODEL_CODES[model_name],
        law_code, COUPLING_CODES[coupling], True, nb, np.empty(nb), jac,
    )  # fmt: skip
    return jac


@pytest.mark.parametrize("law", ["aging", "slip"])
@pytest.mark.parametrize("model_name, coupling, nb", CASES)
def test_directional_derivatives_of_the_rhs(model_name, coupling, nb, law):
    """equations.rhs_jvp (J u, which carries the tangent for λ1) equals the analytic
    Jacobian times u, and rhs_curvature (f''[u, w], RODAS4's tangent) equals central
    differences of the Jacobian along w applied to u, symmetric in u and w; at random
    states far from steady sliding, with per-block parameters and every coupling."""
    rng = np.random.default_rng(200 + nb)
    p, _ = het_row(nb, coupling, rng)
    n = 3 * nb if model_name == "inertial" else 2 * nb
    codes = (MODEL_CODES[model_name], layout.AGING if law == "aging" else layout.SLIP,
             COUPLING_CODES[coupling], True, nb, np.empty(nb))  # fmt: skip
    for _ in range(3):
        y, u, w = rng.normal(0.0, 0.8, n), rng.normal(size=n), rng.normal(size=n)
        jvp = np.empty(n)
        equations.rhs_jvp(y, u, p, *codes, np.empty(nb), jvp)
        want = kernel_jacobian(y, p, model_name, law, nb, coupling) @ u
        # the same products summed in another order: a few ulps of the largest term
        np.testing.assert_allclose(jvp, want, rtol=1e-12, atol=1e-13 * np.abs(want).max())
        step = 1e-6
        up = kernel_jacobian(y + step * w, p, model_name, law, nb, coupling)
        down = kernel_jacobian(y - step * w, p, model_name, law, nb, coupling)
        fd = (up - down) @ u / (2 * step)
        curv_uw, curv_wu = np.empty(n), np.empty(n)
        equations.rhs_curvature(y, u, w, p, *codes, np.empty((3, nb)), curv_uw)
        equations.rhs_curvature(y, w, u, p, *codes, np.empty((3, nb)), curv_wu)
        # central differences: truncation ~ step^2 (fourth derivatives) ~ 1e-12, rounding
        # ~ 1e-16 / step ~ 1e-10 relative to the largest entry
        np.testing.assert_allclose(curv_uw, fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max())
        np.testing.assert_allclose(curv_wu, curv_uw, rtol=1e-12, atol=1e-13 * np.abs(fd).max())


@pytest.mark.parametrize("coupling", ["chain", "ring", "all"])
def test_kernel_rhs_matches_a_laplacian_reference(coupling):
    """equations.rhs with per-block columns against the log form written with the
    Laplacian matrix: ℓ_i' = [κ1_i (1 − e^ℓi) − κ2 Σ_j L_ij e^ℓj − B_i r_i ψ̃_i'] / A_i."""
    nb = 5
    rng = np.random.default_rng(7)
    p, blk = het_row(nb, coupling, rng)
    y = rng.uniform(-1.0, 1.0, 2 * nb)
    v = np.exp(y[:nb])
    dpsi = blk[layout.B_RATE] * (np.exp(-y[nb:]) - v)
    load = blk[layout.B_KAPPA1] * (1 - v) - p[layout.P_KAPPA2] * linear.laplacian(nb, coupling) @ v
    want = np.concatenate([(load - blk[layout.B_B] * dpsi) / blk[layout.B_A], dpsi])
    got = kernel_rhs(y, p, "quasi-static", "aging", nb, coupling)
    np.testing.assert_allclose(got, want, rtol=1e-12)
