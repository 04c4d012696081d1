"""Checks of the SciPy kick reference (``kick_reference``) against theory only.

The Jacobian at steady sliding and its eigenvalues are written here by hand from
``shared/physics.md`` §3, J = [[(B − κ)/A, B/A], [−1, −1]] for both state laws.
"""

import numpy as np
import pytest
from kick_reference import kick_outcome, kick_run, rhs_and_jacobian
from scipy.linalg import expm

A, B = 0.03, 0.08


def steady_jacobian(K_over_Kc):
    """physics.md §3: the Jacobian at ℓ = ψ = 0 (rows ℓ, ψ; per D0/V)."""
    kappa = K_over_Kc * (B - A)
    return np.array([[(B - kappa) / A, B / A], [-1.0, -1.0]])


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_jacobian_at_steady_sliding_is_the_linear_theory(law):
    _, jac = rhs_and_jacobian(law, A, B, 1.3 * (B - A))
    np.testing.assert_allclose(jac(0.0, np.zeros(2)), steady_jacobian(1.3), rtol=1e-14)


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_jacobian_matches_central_differences_of_the_rhs(law):
    rhs, jac = rhs_and_jacobian(law, A, B, 1.1 * (B - A))
    y, h = np.array([0.7, -1.3]), 1e-6
    columns = [(rhs(0.0, y + h * e) - rhs(0.0, y - h * e)) / (2 * h) for e in np.eye(2)]
    np.testing.assert_allclose(jac(0.0, y), np.array(columns).T, rtol=1e-7)


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_tiny_kick_below_kc_leaves(law):
    """Linear instability: below Kc any kick grows and runs away (physics.md §4)."""
    leaves, peak = kick_outcome(law, A, B, 0.9, 1.001, t_end=2000.0)
    assert leaves and peak == pytest.approx(np.log(1e6))


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_tiny_kick_above_kc_returns_with_the_linear_peak(law):
    """K/Kc 1.5, kick 1.001: it returns; its peak is ℓ0 max_t [exp(J t)]_ℓℓ (linear theory)."""
    lnv0 = np.log(1.001)
    lam, vec = np.linalg.eig(steady_jacobian(1.5))
    times = np.linspace(0.0, 3.0, 300001)
    response = (vec[0, :] * np.linalg.inv(vec)[:, 0] * np.exp(np.outer(times, lam))).sum(1)
    linear_peak = lnv0 * response.real.max()
    assert response[1000].real == pytest.approx(expm(steady_jacobian(1.5) * times[1000])[0, 0])
    leaves, peak = kick_outcome(law, A, B, 1.5, 1.001)
    assert not leaves
    assert peak == pytest.approx(linear_peak, rel=2e-3)
    assert peak == pytest.approx(lnv0, rel=0.05)


@pytest.mark.parametrize("law", ["aging", "slip"])
@pytest.mark.parametrize("K_over_Kc", [1.1, 1.5])
def test_small_kick_decays_at_the_linear_rate(law, K_over_Kc):
    """Successive maxima of ℓ after a kick of 1 + 1e-4 shrink at Re λ of physics.md §3."""
    rate = np.linalg.eigvals(steady_jacobian(K_over_Kc)).real.max()
    sol = kick_run(law, A, B, K_over_Kc, 1.0 + 1e-4, t_end=40.0)
    t_max, lnv_max = sol.t_events[1], sol.y_events[1][:, 0]
    measured = np.log(lnv_max[2] / lnv_max[1]) / (t_max[2] - t_max[1])
    assert measured == pytest.approx(rate, rel=0.01)


def test_a_maximum_just_above_the_cap_leaves():
    """Leaving is ℓ reaching ln(cap): a peak 1e-6 above ln(cap) leaves, 1e-6 below returns,
    even where the peak rises and falls within one solver step."""
    _, peak = kick_outcome("aging", A, B, 1.05, 40.0, cap=1e12)
    assert kick_outcome("aging", A, B, 1.05, 40.0, cap=np.exp(peak - 1e-6)) == (
        True,
        pytest.approx(peak - 1e-6),
    )
    leaves, below = kick_outcome("aging", A, B, 1.05, 40.0, cap=np.exp(peak + 1e-6))
    assert not leaves and below == pytest.approx(peak, abs=1e-8)
