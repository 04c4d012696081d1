"""RODAS4's structured solve (``methods/rodas4_structured.py``, ``rosenbrock-structured``):
its factors solve the same systems as the dense LU of I/(γh) − J, and whole runs, with
and without the tangent for λ1, agree with ``rosenbrock`` within their tolerance."""

import numpy as np
import pytest
from conftest import config_dict

import sweep
from sweep.codes import ATTRACTORS
from sweep.config.schema import STRUCTURED_FROM
from sweep.kernels import equations, layout
from sweep.kernels.methods import rodas4
from sweep.kernels.methods import rodas4_structured as structured

MODELS = {"quasi-static": layout.QUASI_STATIC, "quasi-dynamic": layout.QUASI_DYNAMIC,
          "inertial": layout.INERTIAL}  # fmt: skip
COUPLINGS = {"chain": layout.CHAIN, "ring": layout.RING, "all": layout.ALL}
LAWS = {"aging": layout.AGING, "slip": layout.SLIP}
#: Steps (D0/V) from stiff (1/(γh) dominates) to long (J dominates).
STEPS = (1e-3, 0.1, 10.0)


def parameter_row(nb, het, rng):
    """A kernel parameter row (``layout.P_*``) with η̂ and M̂ set, per-block columns
    (A, B, κ1, rate factor drawn around the paper's) where ``het``."""
    p = np.zeros(layout.N_PARAMS + (layout.N_BLOCK_PARAMS * nb if het else 0))
    p[[layout.P_A, layout.P_B, layout.P_KAPPA1, layout.P_KAPPA2]] = 0.03, 0.08, 0.04, 0.05
    p[layout.P_ETA], p[layout.P_MASS] = 0.01, 1e-3
    ranges = {layout.B_A: (0.02, 0.04), layout.B_B: (0.06, 0.1),
              layout.B_KAPPA1: (0.03, 0.06), layout.B_RATE: (0.6, 1.5)}  # fmt: skip
    for k, (lo, hi) in ranges.items() if het else ():
        p[layout.N_PARAMS + k * nb : layout.N_PARAMS + (k + 1) * nb] = rng.uniform(lo, hi, nb)
    return p


@pytest.mark.slow
@pytest.mark.parametrize("het", [False, True], ids=["equal", "unequal"])
@pytest.mark.parametrize("nb", [1, 2, 3, 5, 16])
@pytest.mark.parametrize("coupling", list(COUPLINGS))
@pytest.mark.parametrize("law", list(LAWS))
@pytest.mark.parametrize("model_name", list(MODELS))
def test_structured_solve_is_the_dense_solve(model_name, law, coupling, nb, het):
    """The band (or block-diagonal and rank-one) factors solve (I/(γh) − J) x = b as the
    dense LU does, to round-off, at random states far from steady sliding, for stiff to
    long steps. (Rings of 1-2 blocks, which configs refuse, are checked as well: the
    neighbours add up in both.)"""
    rng = np.random.default_rng(nb + 7 * het)
    model, n = MODELS[model_name], (3 if model_name == "inertial" else 2) * nb
    codes = (model, LAWS[law], COUPLINGS[coupling], het, nb)
    p = parameter_row(nb, het, rng)
    width = structured.matrix_columns(model, COUPLINGS[coupling])
    for _ in range(2):
        y, f, ev = rng.normal(0.0, 0.8, n), np.empty(n), np.empty(nb)
        equations.rhs(y, p, *codes, ev, f)
        for h in STEPS:
            diag = 1.0 / (0.25 * h)
            dense, d_perm = np.empty((n, n)), np.empty(n, np.int64)
            band, b_perm = np.full((n, width), np.nan), np.empty(n, np.int64)
            rodas4.dense_factorise(y, f, diag, p, *codes, ev, dense, d_perm)
            structured.structured_factorise(y, f, diag, p, *codes, ev, band, b_perm)
            for b in (rng.normal(size=n), f):
                want, got = np.empty(n), np.empty(n)
                rodas4.dense_solve(dense, d_perm, b, want, nb, model, COUPLINGS[coupling])
                structured.structured_solve(band, b_perm, b.copy(), got, nb, model,
                                            COUPLINGS[coupling])  # fmt: skip
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.abs(want).max())


@pytest.mark.parametrize("nb", [1, 2])
@pytest.mark.parametrize("model_name", list(MODELS))
def test_dense_jacobian_of_small_rings(model_name, nb):
    """The dense Jacobian of a ring of one or two blocks (both neighbours the same
    block) is the derivative of the right-hand side (central differences)."""
    rng = np.random.default_rng(3)
    model, n = MODELS[model_name], (3 if model_name == "inertial" else 2) * nb
    codes = (model, layout.AGING, layout.RING, True, nb)
    p, y = parameter_row(nb, True, rng), rng.normal(0.0, 0.5, n)
    f, jac, ev = np.empty(n), np.empty((n, n)), np.empty(nb)
    equations.rhs(y, p, *codes, ev, f)
    equations.jacobian(y, f, p, *codes, ev, jac)
    fd = np.empty((n, n))
    for j in range(n):
        up, down, step = np.empty(n), np.empty(n), np.eye(n)[j] * 1e-6
        equations.rhs(y + step, p, *codes, ev, up)
        equations.rhs(y - step, p, *codes, ev, down)
        fd[:, j] = (up - down) / 2e-6
    np.testing.assert_allclose(jac, fd, atol=1e-6 * np.abs(fd).max())


def inertial_blocks(coupling, method, blocks=4, **sections):
    """Inertial blocks (M̂ = 0.01), the first half started off the others: stick-slip at
    K/W = 0.06 µm⁻¹, steady at 0.08, to 300 D0/V (``method`` None: the default)."""
    phi = [1.01 if i < blocks // 2 else 1.0 for i in range(blocks)]
    return config_dict(
        {"blocks": blocks, "coupling": coupling, "model": "inertial",
         "parameters": {"k2_W": 0.02, "m_W": 1.0},
         "initial": {"v_over_V": 1.0, "phi_over_phi_ss": phi},
         "sweep": {"K_W": [0.06, 0.08]}, "integrator": {"method": method, "t_end": 300.0}},
        **sections,
    )  # fmt: skip


@pytest.mark.parametrize("coupling, blocks", [
    ("chain", 2),
    *(pytest.param(c, 4, marks=pytest.mark.slow) for c in ("chain", "ring", "all")),
])  # fmt: skip
def test_structured_runs_agree_with_dense_runs(coupling, blocks):
    """The same runs with either solve: the same labels, and numbers equal to 1e-6
    relative or 1e-9 absolute (the integration's rtol 1e-8, atol 1e-10: the solves
    differ in round-off only). Two blocks: the kernel with its scratch on the stack."""
    dense, band = (sweep.run(inertial_blocks(coupling, m, blocks), threads=1, progress=False)
                   for m in ("rosenbrock", "rosenbrock-structured"))  # fmt: skip
    assert_runs_agree(band, dense)


def assert_runs_agree(band, dense):
    """The structured and dense runs of one config: the same labels; numbers equal to
    1e-6 relative or 1e-9 absolute except in chaotic runs, whose last cycle the solves'
    different round-off moves (λ1 > 0); steps to 1e-3."""
    assert (dense.regime.values == [1, 0]).all()  # the case is what it says
    for name in ("regime", "attractor", "cycle_events"):
        np.testing.assert_array_equal(band[name], dense[name], err_msg=name)
    regular = dense.attractor.values != ATTRACTORS.index("chaotic")
    for name in ("lnv_max", "lnv_min", "period", "friction_drop", "lnv_final"):
        np.testing.assert_allclose(band[name].values[regular], dense[name].values[regular],
                                   rtol=1e-6, atol=1e-9, err_msg=name)  # fmt: skip
    np.testing.assert_allclose(band.n_steps, dense.n_steps, rtol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("coupling", list(COUPLINGS))
def test_default_at_the_crossing_agrees_with_dense(coupling):
    """At ``config.schema.STRUCTURED_FROM`` blocks, where an inertial config that names no method
    turns from ``rosenbrock`` to ``rosenbrock-structured``, the default's runs are the
    dense runs to the tolerance, with the same labels: the switch moves no label. (At
    the sizes of today the stick-slip runs are chaotic in the chain, quasi-periodic in
    the ring and periodic all-to-all; λ1 agrees to 3 %.)"""
    blocks = STRUCTURED_FROM[coupling]
    default = sweep.run(inertial_blocks(coupling, None, blocks), threads=1, progress=False)
    assert default.attrs["integrator_method"] == "rosenbrock-structured"
    dense = sweep.run(inertial_blocks(coupling, "rosenbrock", blocks), threads=1,
                      progress=False)  # fmt: skip
    assert_runs_agree(default, dense)
    np.testing.assert_allclose(default.lyapunov_exponent, dense.lyapunov_exponent, rtol=0.03)


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["chain", "all"])
def test_structured_tangent_agrees_with_dense_tangent(coupling):
    """λ1 over the whole run (``lyapunov: always``) with either solve: the tangent reuses
    the structured factors; the steady run's λ1 is its linear growth rate."""
    sections = {"classification": {"lyapunov": "always"}, "integrator": {"t_end": 150.0}}
    dense, band = (sweep.run(inertial_blocks(coupling, m, **sections), threads=1,
                             progress=False)
                   for m in ("rosenbrock", "rosenbrock-structured"))  # fmt: skip
    lam, want = band.lyapunov_exponent.values, dense.lyapunov_exponent.values
    assert np.isfinite(lam).all()
    np.testing.assert_allclose(lam, want, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(lam[1], band.linear_growth_rate[1], rtol=0.02)
