"""Hopf criticality (sweep/model/hopf.py) against independent computations.

- l1 against Kuznetsov's formula evaluated here: the log-form right-hand side written
  in SymPy, its Jacobian and second and third derivative tensors by SymPy at steady
  sliding, κc from the closed forms of the physics brief (one block) or by brentq on the
  SymPy Jacobian's spectrum (two unequal blocks), eigenvectors by numpy.
- The signs theory gives: zero for the quasi-static aging law (Ranjith & Rice 1999: a
  family of closed orbits at Kc) and, by the Liénard form below, for the quasi-static
  slip law; negative with radiation damping, where the cycle's amplitude grows as the
  square root of the distance to Kc.
- The normal form's amplitude against a SciPy limit cycle at K/Kc = 0.999.
- The statuses where l1 is not defined, and the outputs of a result.
"""

import numpy as np
import pytest
import sympy as sp
from conftest import PAPER_A, PAPER_B, make_config
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from sweep.codes import HOPF_CRITICALITIES
from sweep.engine.grid import build_grid
from sweep.kernels import layout
from sweep.model import hopf, linear, physics
from sweep.results.dataset import build_dataset

A, B = PAPER_A, PAPER_B
ETA_HAT, MASS_HAT = 0.01, 0.1


def status(name):
    return HOPF_CRITICALITIES.index(name)


def sympy_rhs(model, law, A, B, kappa1, rate, kappa2, eta_hat, mass_hat):
    """The log form of an open chain (physics brief §2 and §4), symbols and expressions."""
    nb = len(A)
    lnv = sp.symbols(f"l0:{nb}")
    psi = sp.symbols(f"s0:{nb}")
    z = sp.symbols(f"z0:{nb}")
    v = [sp.exp(x) for x in lnv]
    f_lnv, f_psi, f_z = [], [], []
    for i in range(nb):
        if law == "aging":
            dpsi = rate[i] * (sp.exp(-psi[i]) - v[i])
        else:
            dpsi = -rate[i] * v[i] * (lnv[i] + psi[i])
        neighbours = [j for j in (i - 1, i + 1) if 0 <= j < nb]
        load = kappa1[i] * (1 - v[i]) + kappa2 * sum(v[j] - v[i] for j in neighbours)
        if model == "quasi-static":
            f_lnv.append((load - B[i] * dpsi) / A[i])
        elif model == "quasi-dynamic":
            f_lnv.append((load - B[i] * dpsi) / (A[i] + eta_hat * v[i]))
        else:
            f_lnv.append(z[i] * sp.exp(-lnv[i]) / mass_hat)
            f_z.append(load - B[i] * dpsi - A[i] * f_lnv[-1])
        f_psi.append(dpsi)
    state = list(lnv) + list(psi) + (list(z) if model == "inertial" else [])
    return state, f_lnv + f_psi + f_z


def tensors(state, f):
    """Jacobian, second and third derivatives of ``f`` at 0, as float arrays."""
    zero = dict.fromkeys(state, 0)
    jac = sp.Matrix(f).jacobian(state)
    second = sp.derive_by_array(jac, state)  # [k, i, j] = ∂²f_i/∂x_j∂x_k
    third = sp.derive_by_array(second, state)
    as_array = lambda t: np.array(sp.Array(t).subs(zero).tolist(), dtype=float)  # noqa: E731
    return as_array(jac), as_array(second), as_array(third)


def kuznetsov_l1(jac, second, third):
    """Kuznetsov's l1 with ⟨q, q⟩ = ⟨p, q⟩ = 1, written out independently of hopf.py."""
    lam, vec = np.linalg.eig(jac)
    c = np.argmax(np.where(lam.imag > 0, lam.real, -np.inf))
    omega = lam[c].imag
    q = vec[:, c] / np.linalg.norm(vec[:, c])
    lam_t, vec_t = np.linalg.eig(jac.T)
    p = vec_t[:, np.argmin(np.abs(lam_t + 1j * omega))]
    p = p / np.conj(np.conj(p) @ q)
    bil = lambda u, w: np.einsum("kij,j,k->i", second, u, w)  # noqa: E731
    tri = lambda u, w, x: np.einsum("lkij,j,k,l->i", third, u, w, x)  # noqa: E731
    n = jac.shape[0]
    a_inv = np.linalg.solve(jac, bil(q, q.conj()))
    res = np.linalg.solve(2j * omega * np.eye(n) - jac, bil(q, q))
    terms = (
        np.conj(p) @ tri(q, q, q.conj()),
        -2 * np.conj(p) @ bil(q, a_inv),
        np.conj(p) @ bil(q.conj(), res),
    )
    return sum(terms).real / (2 * omega), sum(abs(t) for t in terms) / (2 * omega)


#: One block of each model: (model, η̂, M̂); inertia light enough to turn the aging law
#: subcritical (M̂ = 1e-3) and heavy enough to make it supercritical (0.1).
ONE_BLOCK = [("quasi-static", 0.0, 0.0), ("quasi-dynamic", ETA_HAT, 0.0),
             ("inertial", 0.0, MASS_HAT), ("inertial", 0.0, 1e-3)]  # fmt: skip
LAWS = ["aging", "slip"]


def one_block_kc(model, eta_hat, mass_hat):
    """κc of one block: B − A, B − A − η̂, (B − A)(1 + M̂/A) (physics brief §3–4)."""
    return {
        "quasi-static": B - A,
        "quasi-dynamic": B - A - eta_hat,
        "inertial": (B - A) * (1 + mass_hat / A),
    }[model]


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize(("model", "eta_hat", "mass_hat"), ONE_BLOCK)
def test_one_block_l1_is_kuznetsovs_formula_by_sympy(model, eta_hat, mass_hat, law):
    kc = one_block_kc(model, eta_hat, mass_hat)
    state, f = sympy_rhs(model, law, [A], [B], [kc], [1.0], 0.0, eta_hat, mass_hat)
    want, scale = kuznetsov_l1(*tensors(state, f))
    got = hopf.one_block(model, law, A, B, eta_hat, mass_hat)
    assert got.l1 == pytest.approx(want, rel=1e-6, abs=1e-12 * scale)
    omega = np.sqrt(kc / (A + eta_hat)) if model == "quasi-dynamic" else np.sqrt((B - A) / A)
    assert got.omega == pytest.approx(omega, rel=1e-12)


@pytest.mark.parametrize(
    ("model", "law", "d0"),
    [("quasi-static", "aging", [1.0, 1.3]), ("quasi-dynamic", "slip", [1.0, 0.6]),
     ("inertial", "aging", [0.8, 1.0])],
)  # fmt: skip
def test_two_unequal_blocks_l1_is_kuznetsovs_formula_by_sympy(model, law, d0):
    """Two blocks of unequal D0 in a chain (κ2 = 0.02): κc by brentq on the SymPy
    Jacobian's largest real part, then Kuznetsov's formula; the engine's κc and l1."""
    eta = ETA_HAT if model == "quasi-dynamic" else 0.0
    mass = MASS_HAT if model == "inertial" else 0.0
    rate = [1.0 / d for d in d0]  # reference D0 = 1
    kappa = sp.Symbol("kappa")
    state, f = sympy_rhs(model, law, [A, A], [B, B], [kappa, kappa], rate, 0.02, eta, mass)
    jac_of = sp.lambdify(kappa, sp.Matrix(f).jacobian(state).subs(dict.fromkeys(state, 0)))
    kc = brentq(lambda k: np.linalg.eigvals(np.array(jac_of(k), float)).real.max(), 1e-3, 10.0,
                xtol=1e-15, rtol=1e-15)  # fmt: skip
    state, f = sympy_rhs(model, law, [A, A], [B, B], [kc, kc], rate, 0.02, eta, mass)
    want, scale = kuznetsov_l1(*tensors(state, f))
    key = (A, A, B, B, 1.0, 1.0, *rate, 0.02, eta, mass)
    assert linear._critical(model, "chain", 2, key)[0] == pytest.approx(kc, rel=1e-10)
    got = hopf.unequal_blocks(model, law, "chain", 2, key)
    assert abs(want) > 1e-6 * scale  # heterogeneity unfolds even the quasi-static aging law
    assert got.l1 == pytest.approx(want, rel=1e-6)
    assert got.status == status("supercritical" if want < 0 else "subcritical")


@pytest.mark.parametrize(
    ("model", "eta_hat", "mass_hat", "law", "expected"),
    [("quasi-static", 0.0, 0.0, "aging", "degenerate"),
     ("quasi-static", 0.0, 0.0, "slip", "degenerate"),
     ("quasi-dynamic", ETA_HAT, 0.0, "aging", "supercritical"),
     ("quasi-dynamic", ETA_HAT, 0.0, "slip", "supercritical"),
     ("inertial", 0.0, MASS_HAT, "aging", "supercritical"),
     ("inertial", 0.0, MASS_HAT, "slip", "supercritical"),
     ("inertial", 0.0, 1e-3, "aging", "subcritical"),
     ("inertial", 0.0, 1e-3, "slip", "supercritical")],
)  # fmt: skip
def test_signs_of_one_block(model, eta_hat, mass_hat, law, expected):
    """Quasi-static aging law: Ranjith & Rice's family of closed orbits at Kc, l1 = 0.
    Quasi-static slip law, in slip as time (dt' = e^ℓ dt): ℓ'' − (a1 g'(ℓ) + b2) ℓ' − D g(ℓ)
    = 0 with g = e^(−ℓ) − 1, a Liénard equation whose l1 ∝ f''(0) − f'(0) h''(0)/h'(0) =
    a1 − a1 = 0 (f = −a1 g' − b2, h = −D g): zero too (f = c (h' − h'(0)), so ∫f is a
    function of ∫h: a centre), and Gu et al.'s (1984) conditional stability is a finite
    threshold, not a small unstable cycle. Radiation damping: negative (the amplitude grows as
    the square root of the distance to Kc, checked below). Inertia: the sign of the SymPy
    computation above (the aging law turns subcritical for light blocks)."""
    assert hopf.one_block(model, law, A, B, eta_hat, mass_hat).status == status(expected)


def test_identical_blocks_are_the_in_phase_mode():
    """N identical coupled blocks: l1 is the one block's / N (the in-phase eigenvectors
    are the one block's / √N); the general path (Jacobian of the chain) agrees."""
    one = hopf.one_block("quasi-dynamic", "slip", A, B, ETA_HAT, 0.0)
    for nb, coupling in ((3, "chain"), (5, "ring"), (4, "all")):
        key = (A,) * nb + (B,) * nb + (1.0,) * nb + (1.0,) * nb + (0.02, ETA_HAT, 0.0)
        general = hopf.unequal_blocks("quasi-dynamic", "slip", coupling, nb, key)
        same = hopf.identical_blocks("quasi-dynamic", "slip", nb, A, B, 0.02, ETA_HAT, 0.0)
        assert general.l1 == pytest.approx(one.l1 / nb, rel=1e-9)
        assert same.l1 == pytest.approx(one.l1 / nb, rel=1e-15)


def test_not_simple_and_no_hopf():
    """Uncoupled identical blocks: every block's pair on the axis at once; κc ≤ 0
    (η̂ ≥ B − A, or A ≥ B): no Hopf point."""
    key = (A, A, B, B, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
    assert hopf.unequal_blocks("quasi-static", "aging", "chain", 2, key).status == status(
        "not_simple"
    )
    assert hopf.identical_blocks("quasi-static", "aging", 2, A, B, 0.0, 0.0, 0.0).status == (
        status("not_simple")
    )
    for args in ((A, B, B - A, 0.0), (B, A, 0.0, 0.0)):
        got = hopf.one_block("quasi-dynamic", "aging", *args)
        assert got.status == status("no_hopf") and np.isnan(got.l1)


def settled_lnv_amplitude(kappa, eta_hat, law, start, t_end=6000.0, window=1000.0):
    """Peak-to-peak ln(v/V) of one quasi-dynamic block over the last ``window`` of a
    SciPy DOP853 run (rtol 1e-10), and over the window before it."""

    def rhs(t, y):
        lnv, psi = y
        v = np.exp(lnv)
        dpsi = np.exp(-psi) - v if law == "aging" else -v * (lnv + psi)
        return [(kappa * (1 - v) - B * dpsi) / (A + eta_hat * v), dpsi]

    sol = solve_ivp(rhs, (0, t_end), [start, 0.0], method="DOP853", rtol=1e-10, atol=1e-12,
                    dense_output=True)  # fmt: skip
    spans = []
    for end in (t_end, t_end - window):
        lnv = sol.sol(np.linspace(end - window, end, 200_001))[0]
        spans.append(lnv.max() - lnv.min())
    return spans


@pytest.mark.slow
@pytest.mark.parametrize("law", ["aging", "slip"])
def test_normal_form_amplitude_against_scipy(law):
    """One quasi-dynamic block (η̂ = 0.01) at K/Kc = 0.999: the settled cycle's
    peak-to-peak ln v within 5 % of 4 |z| |q_ℓ|, |z|² = −Re λ/(ω l1), started on it."""
    kc = B - A - ETA_HAT
    kappa = 0.999 * kc
    tr, det = (B - kappa) / (A + ETA_HAT) - 1, kappa / (A + ETA_HAT)  # mode Jacobian
    growth = tr / 2  # complex pair: Re λ = tr/2
    assert tr**2 < 4 * det
    one = hopf.one_block("quasi-dynamic", law, A, B, ETA_HAT, 0.0)
    predicted = hopf.predicted_lnv_amplitude(one.l1, one.omega, one.lnv_weight, growth)
    last, before = settled_lnv_amplitude(kappa, ETA_HAT, law, predicted / 2)
    assert last == pytest.approx(before, rel=1e-2)  # settled: drifts < 1 % per 1000 D0/V
    assert predicted == pytest.approx(last, rel=0.05)


def test_result_outputs():
    """A result's hopf_* outputs: identical blocks (a K_W axis across Kc) and unequal
    ones (a D0 list), the amplitude only past Kc; the flag table in the file."""
    cfg = make_config({"model": "quasi-dynamic", "blocks": 2, "parameters": {"eta_W": 0.1},
                       "sweep": {"K_W": [0.035, 0.039, 0.041], "k2_W": [0.0, 0.02]}},
                      integrator={"method": "rk4", "t_end": 5.0},
                      classification={"lyapunov": "never"})  # fmt: skip
    g = build_grid(cfg)
    ds = build_dataset(g, np.zeros((g.n, layout.result_width(g.settings))), np.zeros_like(g.y0))
    assert ds.hopf_criticality.attrs["flag_meanings"].split() == list(HOPF_CRITICALITIES)
    one = hopf.one_block("quasi-dynamic", "aging", A, B, 0.1 * float(ds.V), 0.0)
    coupled = ds.sel(k2_W=0.02)
    np.testing.assert_allclose(coupled.hopf_l1, one.l1 / 2, rtol=1e-15)
    assert (coupled.hopf_criticality == status("supercritical")).all()
    assert (ds.sel(k2_W=0.0).hopf_criticality == status("not_simple")).all()
    past = coupled.K_over_Kc < 1
    assert past.any() and not past.all()
    assert np.isfinite(coupled.hopf_lnv_amplitude.where(past, drop=True)).all()
    assert np.isnan(coupled.hopf_lnv_amplitude.where(~past, drop=True)).all()


@pytest.mark.slow
def test_subcritical_light_inertial_block_against_scipy():
    """One inertial block, aging law, M̂ = 1e-3 (l1 > 0): at K/Kc = 1.002, where steady
    sliding is stable, the normal form's unstable cycle separates a start at half its
    amplitude, which decays, from one at twice it, which leaves |ln(v/V)| < 3 (SciPy
    LSODA, rtol 1e-10)."""
    mass = 1e-3
    kappa = 1.002 * (B - A) * (1 + mass / A)
    one = hopf.one_block("inertial", "aging", A, B, 0.0, mass)
    assert one.status == status("subcritical")
    lam = np.linalg.eigvals(
        [[0, 0, 1 / mass], [-1, -1, 0], [B - kappa, B, -A / mass]]
    )  # mode Jacobian (ℓ, ψ, z)
    radius = np.sqrt(-lam.real.max() / (one.omega * one.l1))  # Re λ < 0 < l1
    swing = 2 * one.lnv_weight * radius  # ℓ's half peak-to-peak on the unstable cycle

    def rhs(t, y):
        lnv, psi, z = y
        v = np.exp(lnv)
        dpsi = np.exp(-psi) - v
        dlnv = z * np.exp(-lnv) / mass
        return [dlnv, dpsi, kappa * (1 - v) - B * dpsi - A * dlnv]

    def leaves(t, y):
        return abs(y[0]) - 3.0

    leaves.terminal = True
    for factor, escapes in ((0.5, False), (2.0, True)):
        sol = solve_ivp(rhs, (0, 1500), [factor * swing, 0, 0], method="LSODA", rtol=1e-10,
                        atol=1e-12, events=leaves)  # fmt: skip
        assert (sol.t_events[0].size > 0) == escapes
        if not escapes:
            late = np.abs(sol.y[0][sol.t > 1200]).max()
            assert late < 0.5 * factor * swing


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("eta_hat", [0.0, ETA_HAT])
def test_rhs_is_the_log_form(law, eta_hat):
    """hopf.rhs's value away from steady sliding: physics.log_form_rhs (an open chain of
    three blocks), and its first derivative is the SymPy Jacobian there too."""
    y = np.array([0.3, -0.2, 0.1, -0.4, 0.25, 0.05])
    model = "quasi-dynamic" if eta_hat else "quasi-static"
    one = np.ones(3)
    blocks = hopf.Blocks(model, law, A * one, B * one, 0.045 * one, one, 0.02,
                         linear.laplacian(3, "chain"), eta_hat)  # fmt: skip
    jet = hopf.rhs(blocks, hopf.Jet.seed(y, [np.eye(6)[2]]))
    want = physics.log_form_rhs(0.0, y, A, B, 0.045, 0.02, 3, law, eta_hat)
    np.testing.assert_allclose(jet.c[0].real, want, rtol=1e-14, atol=1e-15)
    state, f = sympy_rhs(model, law, [A] * 3, [B] * 3, [0.045] * 3, [1] * 3, 0.02, eta_hat, 0)
    column = sp.Matrix(f).diff(state[2]).subs(dict(zip(state, y.tolist(), strict=True)))
    np.testing.assert_allclose(jet.c[1].real, np.array(column, float).ravel(), rtol=1e-12)
