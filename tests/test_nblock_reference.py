"""The independent N-block reference (``tests/nblock_reference.py``) against closed-form
results, and what it establishes about the paper's open question (issue 14).

Closed forms (physics brief, section 3, and the derivation in the reference's
docstring): identical blocks lose stability at K/W = (B − A)/D0 for every topology and
k2; uncoupled blocks at the largest one-block value; blocks differing only in K_i where
the smallest eigenvalue of diag(κ) + κ2 L reaches B − A, which for two blocks with
K_i = K(1 ± δ) gives K²(1 − δ²) + 2K(κ2 − c) + c² − 2cκ2 = 0 (c = B − A).
"""

import math

import numpy as np
import pytest
from conftest import PAPER_A, PAPER_B
from nblock_reference import COUPLINGS, FAST_CALL, Chain, fd_jacobian, laplacian, run, start_state
from nblock_reference import window_amplitudes as amplitudes

from sweep.model.physics import log_form_rhs

A, B = PAPER_A, PAPER_B
C = B - A


def random_chain(rng, n, coupling, **fixed):
    """Blocks with A, B, D0 (µm), K/W (µm⁻¹) drawn within ±30 % of the paper's values."""
    spread = {name: value * (1 + 0.3 * rng.uniform(-1, 1, n))
              for name, value in {"A": A, "B": B, "D0": 1.0, "K_W": 0.05}.items()}  # fmt: skip
    return Chain(**(spread | fixed), k2_W=0.02, coupling=coupling)


@pytest.mark.parametrize("coupling", COUPLINGS)
def test_jacobian_by_hand_is_the_finite_difference_one(coupling):
    """Central differences (h = 1e-7: truncation ~h² · 10, round-off ~1e-16/h) agree
    with the hand-written Jacobian to 1e-6; heterogeneous A, B, D0, K, D0_ref ≠ 1."""
    rng = np.random.default_rng(3)
    for n in (3, 5):
        chain = random_chain(rng, n, coupling)
        chain = Chain(chain.A, chain.B, chain.D0, chain.K_W, 0.02, coupling, D0_ref=0.7)
        y0 = np.zeros(2 * n)
        np.testing.assert_allclose(chain.rhs(0.0, y0), 0.0, atol=1e-15)  # steady sliding
        np.testing.assert_allclose(fd_jacobian(chain.rhs, y0), chain.jacobian(), atol=1e-6)


def test_identical_chain_is_the_package_log_form():
    """Identical blocks on an open chain: the same right-hand side as
    ``sweep.model.physics.log_form_rhs`` (the package's plain-numpy statement, written
    separately) at random states."""
    rng = np.random.default_rng(5)
    chain = Chain(A, B, 1.0, 0.045, k2_W=0.03, n_blocks=4)
    for _ in range(10):
        y = rng.normal(scale=1.5, size=8)
        np.testing.assert_allclose(chain.rhs(0.0, y), log_form_rhs(0.0, y, A, B, 0.045, 0.03, 4),
                                   rtol=1e-13, atol=1e-13)  # fmt: skip


@pytest.mark.parametrize("coupling, eigenvalues", [
    ("chain", lambda n: 2 - 2 * np.cos(np.pi * np.arange(n) / n)),
    ("ring", lambda n: 2 - 2 * np.cos(2 * np.pi * np.arange(n) / n)),
    ("all", lambda n: np.r_[0.0, np.full(n - 1, float(n))]),
])  # fmt: skip
def test_laplacian_spectrum(coupling, eigenvalues):
    for n in (3, 4, 7):
        lap = laplacian(n, coupling)
        np.testing.assert_allclose(lap.sum(axis=1), 0.0)
        np.testing.assert_allclose(np.linalg.eigvalsh(lap), np.sort(eigenvalues(n)), atol=1e-12)


@pytest.mark.parametrize("coupling", COUPLINGS)
def test_identical_blocks_modes_are_one_block_modes(coupling):
    """Identical blocks: the spectrum is the union over Laplacian eigenvalues λ_L of the
    one-block pair with κ = κ1 + κ2 λ_L, λ = [tr ± √(tr² − 4 det)]/2, tr = (B − A − κ)/A,
    det = κ/A (brief, section 3)."""
    n, kappa1, kappa2 = 5, 0.045, 0.02
    chain = Chain(A, B, 1.0, kappa1, kappa2, coupling, n_blocks=n)
    kappa = kappa1 + kappa2 * np.linalg.eigvalsh(laplacian(n, coupling))
    tr, det = (B - A - kappa) / A, kappa / A
    root = np.sqrt((tr**2 - 4 * det).astype(complex))
    want = np.r_[(tr + root) / 2, (tr - root) / 2]
    got = np.linalg.eigvals(chain.jacobian())

    def ordered(lam):  # degenerate modes (ring, all): order on rounded values
        return lam[np.lexsort((lam.imag.round(8), lam.real.round(8)))]

    # 1e-10: repeated eigenvalues (ring, all) can lose digits in general; observed 2e-15
    np.testing.assert_allclose(ordered(got), ordered(want), atol=1e-10)


@pytest.mark.parametrize("coupling", COUPLINGS)
@pytest.mark.parametrize("k2_W", [0.0, 0.001, 0.05, 1.0])
def test_identical_blocks_critical_stiffness(coupling, k2_W):
    """Kc/W = (B − A)/D0 for identical blocks whatever the topology and coupling."""
    for n, D0 in ((1, 1.0), (3, 1.0), (4, 0.1), (8, 2.5)):
        chain = Chain(A, B, D0, 0.05, k2_W, coupling, n_blocks=n)
        np.testing.assert_allclose(chain.critical_K_W(), C / D0, rtol=1e-10)


def test_uncoupled_blocks_fail_at_the_weakest():
    """k2 = 0: each block alone, stable iff K > (B_i − A_i)/D0_i for all i."""
    rng = np.random.default_rng(7)
    for n in (2, 3, 6):
        chain = random_chain(rng, n, "chain")
        chain = Chain(chain.A, chain.B, chain.D0, 1.0, k2_W=0.0)
        want = ((chain.B - chain.A) / chain.D0).max()
        np.testing.assert_allclose(chain.critical_K_W(), want, rtol=1e-10)


@pytest.mark.parametrize("delta", [0.05, 0.2, 0.5])
@pytest.mark.parametrize("k2_W", [0.0, 0.01, 0.1, 10.0])
def test_two_blocks_unequal_springs_closed_form(delta, k2_W):
    """K_i = K(1 ± δ), equal A, B, D0 = 1 µm: the module docstring's quadratic; its
    limits are c/(1 − δ) (uncoupled) and c (rigidly tied: the mean spring)."""
    c, k2 = C, k2_W
    disc = (k2 - c) ** 2 - (1 - delta**2) * (c**2 - 2 * c * k2)
    want = (c - k2 + math.sqrt(disc)) / (1 - delta**2)
    chain = Chain(A, B, 1.0, 1.0, k2_W, n_blocks=2)
    got = chain.critical_K_W(factors=[1 + delta, 1 - delta])
    np.testing.assert_allclose(got, want, rtol=1e-10)
    if k2_W == 0.0:
        np.testing.assert_allclose(got, c / (1 - delta), rtol=1e-10)
    if k2_W == 10.0:
        assert abs(got - c) < 1e-3


@pytest.mark.parametrize("coupling", COUPLINGS)
def test_unequal_springs_smallest_mode_stiffness(coupling):
    """Any K_i (equal A, B, D0): stable iff min eig(diag(κ) + κ2 L) > B − A, found here
    by bisection on that symmetric eigenvalue, not on the Jacobian."""
    rng = np.random.default_rng(11)
    factors = 1 + 0.4 * rng.uniform(-1, 1, 6)
    chain = Chain(A, B, 1.0, factors, k2_W=0.03, coupling=coupling)
    lap = laplacian(6, coupling)
    low, high = 0.0, 1.0
    while high - low > 1e-13:
        mid = 0.5 * (low + high)
        if np.linalg.eigvalsh(np.diag(mid * factors) + 0.03 * lap)[0] < C:
            low = mid
        else:
            high = mid
    np.testing.assert_allclose(chain.critical_K_W(factors), low, rtol=1e-10)


@pytest.mark.parametrize("ratio, tau", [(0.5, 8.71), (0.9, 61.28)])
def test_runaway_times_of_the_brief(ratio, tau):
    """One block from v = 1.05 V, Φ = Φss reaches 1e6 V at the brief's τ (section 4,
    DOP853 rtol 1e-10, printed to 4 digits); three identical blocks started in phase
    are that block."""
    one = Chain(A, B, 1.0, ratio * C)
    _, t1 = run(one, start_state(1, 1.05, 1.0), 200.0)
    three = Chain(A, B, 1.0, ratio * C, 0.02, n_blocks=3)
    _, t3 = run(three, start_state(3, 1.05, 1.0), 200.0)
    assert abs(t1 - tau) < 0.005 and abs(t3 - t1) < 1e-6 * t1, (t1, t3)


# --- finding 2 of issue 14, in SciPy alone ---------------------------------------------

#: The issue's three-block chain: D0 per block (µm), k2/W (µm⁻¹), paper A, B.
CHAIN_D0, CHAIN_K2 = [1.0, 1.3, 0.8], 0.02


def heterogeneous_chain(D0=CHAIN_D0):
    chain = Chain(A, B, D0, 0.05, CHAIN_K2)
    return chain, chain.critical_K_W()


def test_heterogeneous_chain_own_critical_stiffness():
    """The chain's own Kc is the Jacobian critical K/W of the unequal chain: 0.0470 µm⁻¹,
    between the one-block values (B − A)/D0_i (0.038–0.063) and below the value of
    identical blocks with the mean D0 (0.0484). Checked with the finite-difference
    Jacobian (not the hand-written one): unstable 0.1 % below, stable 0.1 % above."""
    chain, kc = heterogeneous_chain()
    assert C / 1.3 < kc < C / 0.8 and kc < C / np.mean(CHAIN_D0) - 1e-3
    for ratio, sign in ((0.999, 1), (1.001, -1)):
        jac = fd_jacobian(chain.with_K(ratio * kc).rhs, np.zeros(6))
        assert sign * np.linalg.eigvals(jac).real.max() > 0


@pytest.mark.slow
@pytest.mark.parametrize("D0, ratio, t_end, printed", [
    (CHAIN_D0, 0.99, 1000.0, "0.79"),
    (CHAIN_D0, 0.97, 400.0, "1.22"),
    ([1.0, 0.5, 1.5, 0.7], 0.99, 1000.0, "1.94"),
    ([1.0, 0.5, 1.5, 0.7], 0.97, 400.0, "2.89"),
])  # fmt: skip
def test_unequal_chain_below_its_kc_is_bounded(D0, ratio, t_end, printed):
    """Below its own Kc the unequal chain (start v/V = 1, Φ/Φss = 1.01 on every block)
    settles on a bounded cycle: max |ln Φ/Φss| over the last 100 D0/V (converged by then
    to 1e-5: the 0.99 cycle is reached by τ ≈ 900, the 0.97 one by 200) as the brief
    prints it (section 4, LSODA rtol 1e-10, a separate computation). Values here:
    0.78617, 1.22126; four blocks 1.93960, 2.88587."""
    chain, kc = heterogeneous_chain(D0)
    sol, t_runaway = run(chain.with_K(ratio * kc), start_state(len(D0)), t_end, **FAST_CALL)
    assert t_runaway is None
    amplitude, _ = amplitudes(chain, sol, t_end - 100.0)
    assert abs(amplitude - float(printed)) <= 0.005, amplitude


def test_unequal_chain_above_its_kc_decays():
    """1 % above its Kc the same start decays at ~0.009 per D0/V (the slowest mode)."""
    chain, kc = heterogeneous_chain()
    sol, t_runaway = run(chain.with_K(1.01 * kc), start_state(3), 600.0, **FAST_CALL)
    early, _ = amplitudes(chain, sol, 100.0)
    late, _ = amplitudes(chain, sol, 500.0)
    assert t_runaway is None and late < 0.5 * early


@pytest.mark.slow
def test_bounded_cycle_does_not_depend_on_the_start():
    """Four starts v/V, Φ/Φss = 1 + 0.1 ξ (ξ ~ U(−1, 1), seed 0) at 0.97 Kc all reach the
    cycle of amplitude 1.2213 (1e-4: converged by τ = 300, sampled every 0.002)."""
    chain, kc = heterogeneous_chain()
    rng = np.random.default_rng(0)
    for _ in range(4):
        y0 = start_state(3, 1 + 0.1 * rng.uniform(-1, 1, 3), 1 + 0.1 * rng.uniform(-1, 1, 3))
        sol, t_runaway = run(chain.with_K(0.97 * kc), y0, 400.0, **FAST_CALL)
        assert t_runaway is None
        assert abs(amplitudes(chain, sol, 300.0)[0] - 1.2213) < 1e-4


@pytest.mark.slow
def test_identical_blocks_run_away_at_the_same_ratio():
    """Identical blocks with the mean D0 (1.033 µm) at 0.97 of their Kc = (B − A)/D0:
    in phase they are one block (runaway at τ = 258.6), and the four random starts of
    the test above run away too, by τ = 300 (observed 188–276 over six starts)."""
    D0 = np.mean(CHAIN_D0)
    chain = Chain(A, B, D0, 0.97 * C / D0, CHAIN_K2, n_blocks=3)
    _, t_runaway = run(chain, start_state(3), 1000.0, **FAST_CALL)
    assert t_runaway is not None and abs(t_runaway - 258.6) < 0.1
    rng = np.random.default_rng(0)
    for _ in range(4):
        y0 = start_state(3, 1 + 0.1 * rng.uniform(-1, 1, 3), 1 + 0.1 * rng.uniform(-1, 1, 3))
        _, t_runaway = run(chain, y0, 1000.0, **FAST_CALL)
        assert t_runaway is not None and t_runaway < 300.0


@pytest.mark.parametrize("coupling", ["chain", "ring"])
def test_long_chain_goes_unstable_on_a_stretch_of_small_d0(coupling):
    """The README's reason why the Kc of a long chain drifts up: 32 blocks, D0 spread 0.2
    (uniform, seeds 0–5), k2/W = 0.02 µm⁻¹. The critical mode's ℓ components (|v_i|²,
    normalised) sit on fewer than half of the blocks (participation ratio; observed
    6–13) whose weighted D0 is below the chain's mean (observed 0.91–1.01 vs 0.98–1.06)."""
    for seed in range(6):
        d0 = 1 + 0.2 * np.random.default_rng(seed).uniform(-1, 1, (4, 32))[2]
        chain = Chain(A, B, d0, 0.05, 0.02, coupling)
        lam, vec = np.linalg.eig(chain.with_K(chain.critical_K_W(rtol=1e-10)).jacobian())
        weight = np.abs(vec[:32, np.argmax(lam.real)]) ** 2
        weight /= weight.sum()
        assert 1 / (weight**2).sum() < 32 / 2
        assert (weight * d0).sum() < d0.mean()
