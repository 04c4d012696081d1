"""Kernels compiled for one state size, with their scratch on the stack
(``kernels/stack.py``), against the kernels for any size: the same numbers, bit for
bit, for every method and model, one and two blocks."""

import numba
import numpy as np
import pytest
from conftest import make_config

from sweep import codes
from sweep.engine import dispatch, grid
from sweep.kernels import integrate, layout

NO_JIT = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="NUMBA_DISABLE_JIT=1: no stack")

#: (method, overrides): every method (``codes.METHODS``, checked below), one and two
#: blocks, the three models and both state laws; the K/W grids cross the transition,
#: so runs settle steady, stick-slip and run away.
CASES = {
    "dop853, two blocks": ("dop853", {"blocks": 2, "sweep": {"K_W": [0.03, 0.045, 0.055],
                                                             "k2_W": [0.01, 0.05]}}),
    "dopri5, one block": ("dopri5", {"sweep": {"K_W": [0.03, 0.045, 0.049, 0.06]}}),
    "rk4, quasi-dynamic": ("rk4", {"model": "quasi-dynamic", "parameters": {"eta_W": 0.1},
                                   "sweep": {"K_W": [0.02, 0.035, 0.05]}}),
    "bs23, one slip-law block": ("bs23", {"state_law": "slip",
                                          "sweep": {"K_W": [0.03, 0.045, 0.06]},
                                          "integrator": {"rtol": 1e-6, "atol": 1e-9}}),
    "rosenbrock, two inertial blocks": ("rosenbrock", {
        "blocks": 2, "model": "inertial", "parameters": {"m_W": 1.0},
        "sweep": {"K_W": [0.04, 0.08], "k2_W": [0.02]}}),
    "rosenbrock-structured, two inertial blocks": ("rosenbrock-structured", {
        "blocks": 2, "model": "inertial", "parameters": {"m_W": 1.0},
        "sweep": {"K_W": [0.04, 0.08], "k2_W": [0.02]}}),
    # the kernels with the tangent for λ1
    "dopri5 with the tangent": ("dopri5", {"sweep": {"K_W": [0.03, 0.045, 0.06]},
                                           "classification": {"lyapunov": "always"}}),
    "rosenbrock with the tangent": ("rosenbrock", {
        "blocks": 2, "model": "inertial", "parameters": {"m_W": 1.0},
        "sweep": {"K_W": [0.04, 0.08], "k2_W": [0.02]},
        "classification": {"lyapunov": "always"}}),
}  # fmt: skip


def run(kernel, g):
    results = np.full((g.params.shape[0], layout.result_width(g.settings)), -7.0)
    y_final = np.full_like(g.y0, -7.0)
    kernel(g.params, g.y0, g.settings, results, y_final, 0.0, np.empty(0), np.empty((0, 0)))
    return results, y_final


@pytest.mark.slow
@NO_JIT
@pytest.mark.parametrize("case", CASES)
def test_fixed_size_kernels_give_the_same_numbers(case):
    method, overrides = CASES[case]
    overrides = dict(overrides)
    integrator = {"method": method, "t_end": 600.0, **overrides.pop("integrator", {})}
    if method == "rk4":
        integrator["dt"] = 0.01
    config = make_config(overrides, integrator=integrator)
    g = grid.build_grid(config)
    codes = dispatch.variant(g.params, g.settings)
    *_, tangent, catalogue, size = codes
    assert size == g.y0.shape[1]  # small systems get the kernel for their size
    assert tangent == ("tangent" in case) and not catalogue
    fixed = run(integrate.grid_kernel(*codes), g)
    any_size = run(integrate.grid_kernel(*codes[:-1], 0), g)
    # the runs integrated, and settled differently across the transition
    assert (fixed[0][:, layout.R_N_STEPS] > 10).all()
    assert len(set(fixed[0][:, layout.R_REGIME])) >= 2
    if "tangent" in case:  # λ1 was measured
        assert np.isfinite(fixed[0][:, layout.R_LYAPUNOV]).any()
    np.testing.assert_array_equal(fixed[0], any_size[0])
    np.testing.assert_array_equal(fixed[1], any_size[1])


def test_every_method_is_a_case():
    assert {method for method, _ in CASES.values()} == set(codes.METHODS)


def test_only_small_systems_get_a_kernel_of_their_size():
    for blocks, model, size in ((1, "quasi-static", 2), (2, "inertial", 6),
                                (3, "quasi-static", 6), (4, "quasi-static", 0),
                                (3, "inertial", 0)):  # fmt: skip
        overrides = {"blocks": blocks, "model": model, "sweep": {"K_W": [0.05]}}
        if model == "inertial":
            overrides["parameters"] = {"m_W": 1.0}
        if blocks > 1:
            overrides["sweep"]["k2_W"] = [0.02]
        g = grid.build_grid(make_config(overrides))
        assert dispatch.variant(g.params, g.settings)[-1] == size, (blocks, model)
    assert dispatch.STACK_STATE_MAX == 6


@NO_JIT
def test_a_kernel_refuses_another_state_size():
    g = grid.build_grid(make_config({"sweep": {"K_W": [0.05]}}))
    variant = dispatch.variant(g.params, g.settings)
    kernel = integrate.grid_kernel(*variant[:-1], 4)  # compiled for two blocks
    with pytest.raises(ValueError, match="state size"):
        run(kernel, g)
