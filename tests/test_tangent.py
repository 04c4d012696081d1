"""The largest Lyapunov exponent (``sweep/kernels/tangent.py``): the tangent step is the
derivative of the run's own step map, in slips and in inertial sticks; λ1 is the linear
growth rate at a stable fixed point and zero on a limit cycle; carrying the tangent
changes nothing else.
(λ1 against independent SciPy estimates on chaotic runs, quasi-static and inertial:
``test_attractors.py``.)"""

import numpy as np
import pytest
from conftest import KC_W, PAPER_A, PAPER_B, kc_w, make_config, run_grid

from sweep.codes import METHODS as CODE_TABLE
from sweep.codes import code
from sweep.engine import dispatch
from sweep.engine.floquet import floquet_pass
from sweep.engine.grid import build_grid
from sweep.engine.runner import compute
from sweep.kernels import equations, layout, tangent
from sweep.kernels.methods import MODULES
from sweep.variables import ATTRACTORS


@pytest.fixture(autouse=True)
def fresh_dispatch(monkeypatch):
    """Each test starts with no variant switched to its kernel with the tangent
    (``dispatch.tangent_first``), whatever tests ran before it in this process."""
    monkeypatch.setattr(dispatch, "_TANGENT_FIRST", {})


CODES = {"quasi-static": layout.QUASI_STATIC, "quasi-dynamic": layout.QUASI_DYNAMIC,
         "inertial": layout.INERTIAL}  # fmt: skip
METHODS = {name: code(CODE_TABLE, name) for name in CODE_TABLE}


def take_step(method, y, h, p, model, nb):
    """One step of ``method`` from ``y`` (the kernels' own step): its end, and the slope
    at y, the stages and (RODAS4) the LU factors it leaves."""
    n = y.size
    module = MODULES[method]
    ev, f, ytmp, ynew, fnew = np.empty(nb), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    k, lu, perm = np.empty((module.STAGE_ROWS, n)), np.empty((n, n)), np.empty(n, np.int64)
    codes = (model, layout.AGING, layout.CHAIN, False)
    equations.rhs(y, p, *codes, nb, ev, f)
    module.step(y, f, h, p, *codes, nb, ev, k, lu, perm, ytmp, ynew, fnew, 1e-8, 1e-10)
    return ynew, (f, k, lu, perm)


def step_jacobian(method, y, h, p, model, nb, steps):
    """The derivative of the step map by central differences, column j with step
    ``steps[j]`` (error ~ steps² × third derivatives, plus rounding ~ 1e-16/steps)."""
    columns = []
    for j, size in enumerate(steps):
        e = np.zeros(y.size)
        e[j] = size
        up, down = take_step(method, y + e, h, p, model, nb)[0], take_step(method, y - e, h, p,
                                                                          model, nb)[0]  # fmt: skip
        columns.append((up - down) / (2 * size))
    return np.array(columns).T


def pair_params(kappa1, kappa2, mass):
    p = np.zeros(layout.N_PARAMS)
    p[layout.P_A], p[layout.P_B], p[layout.P_KAPPA1], p[layout.P_KAPPA2] = (
        PAPER_A, PAPER_B, kappa1, kappa2)  # fmt: skip
    p[layout.P_MASS] = mass
    return p


#: A slip of two coupled blocks (ℓ, ψ[, z]), and a deep stick of two inertial blocks
#: (v = e^−25 V, z ~ 1e−12: ℓ' = z e^(−ℓ)/M̂ ~ 1e10 per unit of z), with the steps taken
#: there and the column steps of the reference differences (z's scaled to its range).
TANGENT_STATES = {
    "slip": ([1.2, -0.4, -0.8, 0.3], [0.02, -0.01], 0.05, (0.04, 0.02, 0.5), 1e-5, 1e-5),
    "stick": ([-25.0, -24.0, 2.0, 1.5], [3e-12, -2e-12], 2.0, (0.006, 0.004, 1.25), 1e-6, 1e-9),
}


@pytest.mark.slow
@pytest.mark.parametrize(
    "model, method, state",  # every method, every model (each pair compiles its own tangent step)
    [("quasi-static", "dopri5", "slip"), ("quasi-static", "rk4", "slip"),
     ("inertial", "dopri5", "slip"), ("inertial", "rosenbrock", "slip"),
     ("quasi-dynamic", "dop853", "slip"), ("inertial", "rosenbrock", "stick"),
     ("quasi-static", "bs23", "slip")],
)  # fmt: skip
def test_tangent_step_is_the_derivative_of_the_step_map(model, method, state):
    """A method's ``tangent_step`` carries δ by the derivative of the method's step map, formed from
    the step's own stages: against central differences of the step map, column by
    column, to 1e-5 (the differences' own error: ~1e-8 in a slip, ~5e-7 in the stick,
    where the step crosses the inertial force's decay, rate A e^25/M̂ ~ 2e9, thousands of
    times). |J δ| (its step cap) against the analytic Jacobian."""
    nb, m, method = 2, CODES[model], METHODS[method]
    y_lp, z, h, (kappa1, kappa2, mass), step, z_step = TANGENT_STATES[state]
    y = np.array(y_lp + (z if model == "inertial" else []))
    p = pair_params(kappa1, kappa2, mass)
    n = y.size
    delta = np.linspace(1.0, 2.0, n)
    delta /= np.linalg.norm(delta)
    steps = [step] * 2 * nb + [z_step] * (n - 2 * nb)
    expected = step_jacobian(method, y, h, p, m, nb, steps) @ delta
    _, (f, k, lu, perm) = take_step(method, y, h, p, m, nb)
    d, work, dk, blocks, _ = tangent.tangent_arrays(MODULES[method].TANGENT_ROWS, n, nb)
    d[:] = delta
    growth, rate = MODULES[method].tangent_step(
        y, f, h, k, lu, perm, d, work, dk, blocks, p, nb, np.empty(nb),
        m, layout.AGING, layout.CHAIN, False,
    )  # fmt: skip
    np.testing.assert_allclose(np.exp(growth) * d, expected, rtol=1e-5,
                               atol=1e-5 * np.abs(expected).max())  # fmt: skip
    jac = np.empty((n, n))
    equations.jacobian(y, f, p, m, layout.AGING, layout.CHAIN, False, nb, np.empty(nb), jac)
    assert rate == pytest.approx(np.linalg.norm(jac @ delta), rel=1e-12)


STEADY_CASES = {
    "one block, K = 1.05 Kc": {"sweep": {"K_W": [1.05 * KC_W]}},
    "one block, K = 1.3 Kc": {"sweep": {"K_W": [1.3 * KC_W]}},
    "two blocks": {"blocks": 2, "parameters": {"k2_W": 0.01}, "sweep": {"K_W": [1.1 * KC_W]},
                   "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]}},
    "radiation damping": {"model": "quasi-dynamic", "parameters": {"eta_W": 0.01},
                          "sweep": {"K_W": [1.1 * kc_w("quasi-dynamic", eta_w=0.01)]}},
    "inertia": {"model": "inertial", "parameters": {"m_W": 1.0},
                "sweep": {"K_W": [1.1 * kc_w("inertial", m_w=1.0)]},
                "integrator": {"method": "rosenbrock"}},
}  # fmt: skip


def lyapunov_run(case, t_end=2000.0):
    """``case`` with λ1 over the whole run (``lyapunov: always``) to ``t_end`` D0/V."""
    sections = {k: v for k, v in case.items() if k not in ("blocks", "model")}
    base = {k: v for k, v in case.items() if k in ("blocks", "model")}
    sections["integrator"] = {**sections.get("integrator", {}), "t_end": t_end}
    sections["classification"] = {"lyapunov": "always"}
    return compute(make_config(base, **sections), show_progress=False).isel(K_W=0)


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.slow) if n == "two blocks" else n for n in STEADY_CASES
])  # fmt: skip
def test_lyapunov_exponent_of_steady_sliding_is_the_linear_growth_rate(name):
    """At a stable fixed point λ1 is the largest real part of the Jacobian's eigenvalues
    (the stored linear_growth_rate, from the physics' normal modes): within 1 %."""
    ds = lyapunov_run(STEADY_CASES[name])
    assert ATTRACTORS[int(ds["attractor"])] == "fixed_point"
    linear = float(ds["linear_growth_rate"])
    assert linear < 0
    np.testing.assert_allclose(float(ds["lyapunov_exponent"]), linear, rtol=0.01)
    assert float(ds["lyapunov_error"]) < 0.01 * abs(linear)


CYCLE_CASES = {
    "radiation damping": {"model": "quasi-dynamic", "parameters": {"eta_W": 0.01},
                          "sweep": {"K_W": [0.9 * kc_w("quasi-dynamic", eta_w=0.01)]}},
    "inertia": {"model": "inertial", "parameters": {"m_W": 1.0},
                "sweep": {"K_W": [0.8 * kc_w("inertial", m_w=1.0)]},
                "integrator": {"method": "rosenbrock"}},
}  # fmt: skip


@pytest.mark.parametrize("name", CYCLE_CASES)
def test_lyapunov_exponent_of_a_limit_cycle_is_zero(name):
    """On a limit cycle λ1 = 0 (the direction along the flow neither grows nor decays):
    within its error, and far below the cycle's own rate 1/period."""
    ds = lyapunov_run(CYCLE_CASES[name], t_end=4000.0)
    assert (ATTRACTORS[int(ds["attractor"])], int(ds["cycle_events"])) == ("periodic", 1)
    lam, err = float(ds["lyapunov_exponent"]), float(ds["lyapunov_error"])
    assert abs(lam) <= 3 * err
    assert 3 * err < 1e-3 / float(ds["period"])


#: Results of the trajectory itself, whatever decides the label at the end: the final
#: time and state, the integrator's work, the maxima seen and the largest ln v.
TRAJECTORY = [layout.R_TAU_FINAL, layout.R_N_STEPS, layout.R_N_REJECTED, layout.R_N_PEAKS,
              layout.R_LNV_MAX_RUN, layout.R_TAU_RUNAWAY]  # fmt: skip


def test_the_tangent_changes_no_step_before_it_starts():
    """The state's steps before the tangent starts do not depend on it: the same runs
    (steady, cycle, runaway, and one unsettled at t_end that carries it from there)
    without λ1 and with it from t_end on give, bit for bit, the same numbers for every
    run settled by t_end, and (early exit off, so no run goes past t_end) for every
    run. Carried over whole runs, the tangent caps the steps (``TANGENT_TURN``): the
    labels stay, a steady run gets its λ1 and a runaway none."""
    ks = [1.1 * KC_W, 0.9 * KC_W, 1.0 * KC_W, 1.0002 * KC_W]
    base = {"sweep": {"K_W": ks}, "integrator": {"t_end": 400.0}}
    runs = {}
    for mode in ("never", "unsettled", "always"):
        for early in (True, False):
            config = make_config(base, classification={"lyapunov": mode, "early_exit": early})
            runs[mode, early] = run_grid(config)
    lam = [layout.R_LYAPUNOV, layout.R_LYAPUNOV_ERROR]
    for early in (True, False):
        (res_a, yf_a), (res_b, yf_b) = runs["never", early], runs["unsettled", early]
        by_t_end = res_a[:, layout.R_TAU_FINAL] < 400.0 if early else np.full(len(ks), True)
        assert by_t_end.sum() >= 3
        np.testing.assert_array_equal(yf_a[by_t_end], yf_b[by_t_end])
        np.testing.assert_array_equal(
            res_a[by_t_end][:, TRAJECTORY], res_b[by_t_end][:, TRAJECTORY]
        )
        settled = by_t_end & (res_a[:, layout.R_REGIME] != layout.UNDECIDED)
        other = np.setdiff1d(np.arange(res_a.shape[1]), lam)
        np.testing.assert_array_equal(res_a[settled][:, other], res_b[settled][:, other])
    assert np.isnan(runs["never", False][0][:, lam]).all()
    always = runs["always", False][0]
    np.testing.assert_array_equal(
        always[:3, layout.R_REGIME], runs["never", False][0][:3, layout.R_REGIME]
    )
    assert np.isfinite(always[0, layout.R_LYAPUNOV])  # steady: λ1 over the whole run
    assert always[1, layout.R_REGIME] == layout.RUNAWAY and np.isnan(always[1, lam]).all()


def test_runs_that_need_the_tangent_are_redone_by_its_kernel_number_for_number():
    """The kernel without the tangent hands exactly the runs unsettled at t_end to the
    kernel with it (``TANGENT_NEEDED``), and what ``integrate_grid`` returns is, bit
    for bit, what the kernel with the tangent computes for every run from the start;
    after that, the variant's calls go straight to that kernel, with the same numbers.
    Asked for λ1 over whole runs, the kernel without it steps no run."""
    ks = [1.1 * KC_W, 0.9 * KC_W, 1.0 * KC_W, 1.0002 * KC_W]
    t_end = 20.0  # runaway, cycle and slow decay all unsettled by then; the runaway and
    # the slow decay still unsettled at max_t_end = 40, with λ1 over 20 … 40
    config = make_config({"sweep": {"K_W": ks}, "integrator": {"t_end": t_end},
                          "classification": {"max_t_end": 2 * t_end}})  # fmt: skip
    g = build_grid(config)

    def call(kernel, settings):
        """The kernel's run, then the Floquet pass that ``integrate_grid`` adds after it."""
        results = np.full((len(ks), layout.result_width(settings)), -7.0)
        y_final = np.empty_like(g.y0)
        kernel(g.params, g.y0, settings, results, y_final, 0.0, np.empty(0), np.empty((0, 0)))
        floquet_pass(g.params, settings, results, y_final)
        return results, y_final

    plain, _ = call(dispatch.grid_kernel(g.params, g.settings, tangent=False), g.settings)
    handed = plain[:, layout.R_REGIME] == layout.TANGENT_NEEDED
    direct = call(dispatch.grid_kernel(g.params, g.settings, tangent=True), g.settings)
    went_on = direct[0][:, layout.R_TAU_FINAL] > t_end
    assert went_on.sum() >= 3 and handed[went_on].all()
    np.testing.assert_array_equal(plain[~handed], direct[0][~handed])
    split = run_grid(config)
    np.testing.assert_array_equal(split[0], direct[0])
    np.testing.assert_array_equal(split[1], direct[1])
    # runs of this variant needed λ1: later calls go straight to the kernel with it
    assert dispatch.tangent_first(g.params, g.settings)
    again = run_grid(config)
    np.testing.assert_array_equal(again[0], direct[0])
    np.testing.assert_array_equal(again[1], direct[1])
    assert split[0][3, layout.R_REGIME] == layout.UNDECIDED
    assert np.isfinite(split[0][3, layout.R_LYAPUNOV])

    always = g.settings.copy()
    always[layout.S_LYAPUNOV] = layout.LYAP_ALWAYS
    results, _ = call(dispatch.grid_kernel(g.params, g.settings, tangent=False), always)
    assert (results[:, layout.R_REGIME] == layout.TANGENT_NEEDED).all()
    assert (results[:, layout.R_N_STEPS] == 0).all()


def test_lyapunov_estimate_needs_two_blocks_after_the_transient():
    """λ1 is the fit over the window after the first of its eight blocks; with fewer
    than two blocks after that there is no error estimate, hence NaN."""
    ly = np.zeros(tangent.N_LYAP)
    tangent.lyapunov_start(ly, np.empty(4), 0.0, 10.0)
    for k in range(1, 25):  # S(t) = 0.3 t sampled every 1: 2.4 blocks in all
        tangent.lyapunov_add(ly, float(k), 1.0, 0.3, 0.0)
    assert np.isnan(tangent.lyapunov_estimate(ly)[0])
    for k in range(25, 41):
        tangent.lyapunov_add(ly, float(k), 1.0, 0.3, 0.0)
    lam, err, span = tangent.lyapunov_estimate(ly)
    assert lam == pytest.approx(0.3) and err == pytest.approx(0.0, abs=1e-12)
    assert span == pytest.approx(30.0)


def test_grid_settings_carry_the_lyapunov_mode_and_event_count():
    config = make_config(classification={"lyapunov": "always", "events": 7})
    g = build_grid(config)
    assert g.settings[layout.S_LYAPUNOV] == layout.LYAP_ALWAYS
    assert layout.result_width(g.settings) == layout.N_RESULTS + 14
