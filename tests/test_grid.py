"""From a config to the grid of systems, and what a whole sweep finds: the transition
where the physics brief puts it, independent of chunking, threads and kernel."""

import math
import threading
import time

import numpy as np
import pytest
from conftest import KC_W, PAPER_A, PAPER_B, assert_transition_at, make_config
from hypothesis import given, settings
from hypothesis import strategies as st

from sweep.engine import backends, grid, runner
from sweep.engine.backends import LocalThreads
from sweep.engine.dispatch import integrate_grid
from sweep.kernels import layout

A, B = PAPER_A, PAPER_B

# --- the grid --------------------------------------------------------------------------


def test_grid_is_c_ordered_product_of_axes():
    config = make_config(
        blocks=2,
        parameters={"D0": 2.0},
        sweep={"K_W": [0.01, 0.02, 0.03], "k2_W": [0.0, 0.5]},
        initial={"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
    )
    phys = grid.physical_parameters(config)
    assert config.shape == (3, 2)
    # the last axis varies fastest
    np.testing.assert_array_equal(phys["K_W"], [0.01, 0.01, 0.02, 0.02, 0.03, 0.03])
    np.testing.assert_array_equal(phys["k2_W"], [0.0, 0.5] * 3)
    np.testing.assert_array_equal(phys["D0"], np.full(6, 2.0))
    np.testing.assert_array_equal(phys["V0"], phys["D0"] / phys["Phi0"])  # V0 = D0/Φ0
    np.testing.assert_array_equal(phys["eta_W"], np.zeros(6))  # unset: zero
    g = grid.build_grid(config)
    np.testing.assert_array_equal(g.physical["K_W"], phys["K_W"])
    params, y0, settings, time_unit = g.params, g.y0, g.settings, g.time_unit
    np.testing.assert_allclose(params[:, layout.P_KAPPA1], phys["K_W"] * 2.0, rtol=1e-15)
    np.testing.assert_allclose(params[:, layout.P_KAPPA2], phys["k2_W"] * 2.0, rtol=1e-15)
    np.testing.assert_allclose(time_unit, 2.0 / 0.1)  # D0/V in s
    assert y0.shape == (6, 4)
    np.testing.assert_allclose(y0[0], [0.0, 0.0, math.log(1.01), 0.0], rtol=1e-15)
    assert settings[layout.S_NBLOCKS] == 2
    assert settings[layout.S_LNV_CAP] == pytest.approx(math.log(1e6))


def test_times_in_seconds_are_converted_per_system():
    """t_unit: s → end time in D0/V of each system; step sizes are always in D0/V."""
    config = make_config(
        sweep={"K_W": None, "D0": [1.0, 2.0]},
        parameters={"K_W": 0.05, "D0": None},
        integrator={"t_unit": "s", "t_end": 100.0, "dt": 0.5, "max_step": 2.0},
    )
    params = grid.build_grid(config).params
    tau_unit = np.array([10.0, 20.0])  # D0/V in s
    np.testing.assert_allclose(params[:, layout.P_TAU_END], 100.0 / tau_unit)
    np.testing.assert_array_equal(params[:, layout.P_DT], 0.5)
    np.testing.assert_array_equal(params[:, layout.P_MAX_STEP], 2.0)


def test_inertial_start_is_in_force_balance():
    """The inertial force z = (m/W) dv/dt starts at 0: zero acceleration at t = 0."""
    config = make_config(
        model="inertial",
        parameters={"m_W": 0.5},
        initial={"v_over_V": 1.2, "phi_over_phi_ss": 1.01},
    )
    y0 = grid.build_grid(config).y0
    np.testing.assert_allclose(y0[:, 0], math.log(1.2), rtol=1e-15)
    np.testing.assert_allclose(y0[:, 1], math.log(1.01), rtol=1e-15)
    np.testing.assert_array_equal(y0[:, 2], 0.0)


# --- the transition a sweep finds ---------------------------------------------------------


@pytest.mark.parametrize("D0", [1.0, 0.1])
def test_one_block_sweep_finds_kc(D0):
    """Kc/W = (B − A)/D0 (0.05 µm⁻¹ at D0 = 1 µm, 0.5 µm⁻¹ at D0 = 0.1 µm, erratum 1):
    a sweep through ``runner.compute`` is steady at every grid point above it and at
    none below, so the transition lies in the grid step holding Kc. The grid straddles
    Kc without hitting it (K = Kc itself is the degenerate closed-orbit case)."""
    kc_w = (B - A) / D0
    k_w = kc_w * np.linspace(0.855, 1.155, 21)  # step 1.5 % of Kc
    config = make_config(
        parameters={"D0": D0},
        sweep={"K_W": k_w.tolist()},
        integrator={"t_end": 3000.0},
    )
    ds = runner.compute(config, show_progress=False)
    assert_transition_at(k_w, ds["regime"].values, kc_w)


def test_two_block_sweep_finds_kc_for_every_coupling():
    """Two blocks: the transition stays at K/W = (B − A)/D0 for k2/W = 0, 0.05, 0.5 µm⁻¹."""
    k_w = KC_W * np.linspace(0.855, 1.155, 21)
    config = make_config(
        blocks=2,
        sweep={"K_W": k_w.tolist(), "k2_W": [0.0, 0.05, 0.5]},
        initial={"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
        integrator={"t_end": 3000.0},
    )
    ds = runner.compute(config, show_progress=False)
    for j in range(3):
        assert_transition_at(k_w, ds["regime"].values[:, j], KC_W)


# --- results do not depend on how the grid is cut or who runs it -------------------------

#: Every regime and plenty of NaN in 22 short runs: one block from 0.3 Kc (fast
#: runaway) to 1.3 Kc (steady); K = Kc exactly (D0 = 1 µm) keeps its closed orbit
#: (stick-slip) and K/Kc = 0.99 (D0 = 0.99 µm) has not run away by t_end (undecided).
#: Every regime on one small grid: radiation damping η/W = 0.1 s/µm gives stick-slip
#: below its Kc, η = 0 is the quasi-static model (runaway), runs near Kc stay
#: undecided within the short end time (no continuation: max_t_end = t_end).
MIXED = {
    "model": "quasi-dynamic",
    "sweep": {"K_W": (KC_W * np.linspace(0.3, 1.3, 11)).tolist(), "eta_W": [0.0, 0.1]},
    "integrator": {"t_end": 300.0},
    "classification": {"max_t_end": 300.0},
}


def same(ds_a, ds_b):
    """Bitwise equality of every data variable, NaN positions included."""
    for name in ds_a.data_vars:
        a, b = ds_a[name].values, ds_b[name].values
        assert a.dtype == b.dtype
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    return True


@pytest.fixture(scope="module")
def mixed_reference():
    return runner.compute(make_config(MIXED), threads=1, chunk_size=1, show_progress=False)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("chunk_size", [1, 7, None])
def test_results_do_not_depend_on_threads_or_chunks(mixed_reference, threads, chunk_size):
    chunk = chunk_size or mixed_reference["regime"].size  # None: the whole grid at once
    ds = runner.compute(make_config(MIXED), threads=threads, chunk_size=chunk, show_progress=False)
    regimes = set(np.unique(mixed_reference["regime"].values))
    assert regimes == {layout.STEADY, layout.STICK_SLIP, layout.RUNAWAY, layout.UNDECIDED}
    assert np.isnan(mixed_reference["period"].values).any()
    assert same(ds, mixed_reference)


@settings(max_examples=10)  # each example a whole sweep (no deadline: conftest.py)
@given(chunk_size=st.integers(1, 30), threads=st.sampled_from([1, 2]))
def test_results_do_not_depend_on_chunking_property(mixed_reference, chunk_size, threads):
    ds = runner.compute(
        make_config(MIXED), threads=threads, chunk_size=chunk_size, show_progress=False
    )
    assert same(ds, mixed_reference)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_local_threads_give_the_serial_kernels_numbers(threads):
    """Batches handed out to threads (sweep.engine.backends.LocalThreads) give every row the
    numbers of one serial kernel call over the whole grid, whatever the chunks."""
    g = grid.build_grid(make_config(MIXED))
    n = g.params.shape[0]
    results = np.full((n, layout.result_width(g.settings)), -1.0)
    y_final = np.full_like(g.y0, -1.0)
    integrate_grid(g.params, g.y0, g.settings, results, y_final)
    ranges = [(0, 3), (3, n)]
    chunks = list(LocalThreads(threads).run(g.params, g.y0, g.settings, ranges))
    assert [(a, b) for a, b, _, _ in chunks] == ranges
    for a, b, res, yf in chunks:
        assert np.array_equal(res, results[a:b], equal_nan=True)
        assert np.array_equal(yf, y_final[a:b], equal_nan=True)


#: Seconds a held batch waits for the event that releases it: only a broken scheduler
#: waits that long (the test then fails instead of hanging).
HOLD_TIMEOUT = 60.0


class RecordingKernel:
    """Stands in for ``integrate_grid`` in ``sweep.engine.backends``: writes each row's index
    into its results and logs ``("start" | "end", first row)`` of every batch in the
    order they happen. ``hold(first)`` is called at the start of each batch (it may
    wait); ``fail`` raises on the batch that starts at that row."""

    def __init__(self, hold=None, fail=None):
        self.hold, self.fail, self.log = hold, fail, []
        self.lock = threading.Lock()

    def __call__(self, params, y0, settings, results, y_final):
        first = int(params[0, 0])
        with self.lock:
            self.log.append(("start", first))
        if first == self.fail:
            raise FloatingPointError("kernel failed")
        if self.hold is not None:
            self.hold(first)
        results[:] = params[:, :1]
        y_final[:] = 0.0
        with self.lock:
            self.log.append(("end", first))

    def ended(self, rows):
        """How many batches that start in ``rows`` have ended."""
        with self.lock:
            return sum(event == "end" and first in rows for event, first in self.log)


def rows(n):
    """Kernel arrays whose column 0 is the row index."""
    params = np.zeros((n, layout.N_PARAMS))
    params[:, 0] = np.arange(n)
    return params, np.zeros((n, 2)), np.zeros(layout.N_SETTINGS)


def wait_for(condition):
    """Wait until ``condition()`` holds; fail after :data:`HOLD_TIMEOUT` s."""
    for _ in range(int(HOLD_TIMEOUT / 0.001)):
        if condition():
            return
        time.sleep(0.001)
    pytest.fail(f"waited {HOLD_TIMEOUT} s in vain")


def test_threads_go_on_to_the_next_range_while_a_range_finishes(monkeypatch):
    """No barrier at the end of a range: the first batch of range 0 runs until the other
    thread has done every batch of range 1 (8 batches of 4 rows); ranges still come
    back in order, with every row's own results."""
    kernel = RecordingKernel()
    kernel.hold = lambda first: first == 0 and wait_for(lambda: kernel.ended(range(32, 64)) == 8)
    monkeypatch.setattr(backends, "integrate_grid", kernel)
    params, y0, settings = rows(64)
    ranges = [(0, 32), (32, 64)]
    chunks = list(LocalThreads(2).run(params, y0, settings, ranges))
    assert [(a, b) for a, b, _, _ in chunks] == ranges
    for a, b, res, _ in chunks:
        np.testing.assert_array_equal(res[:, 0], np.arange(a, b))
    assert kernel.log.index(("end", 0)) > kernel.log.index(("end", 60))


def test_a_failing_batch_is_raised_by_the_generator(monkeypatch):
    monkeypatch.setattr(backends, "integrate_grid", RecordingKernel(fail=40))
    params, y0, settings = rows(64)
    with pytest.raises(FloatingPointError, match="kernel failed"):
        list(LocalThreads(2).run(params, y0, settings, [(0, 32), (32, 64)]))


def test_closing_the_generator_abandons_the_batches_not_started(monkeypatch):
    """A stop after the first range (8 batches of 1 row, then batches of 8): its first
    batch is held until the other thread has done 3 batches of range 1, the batches
    after those until the generator stops. The running batches finish, no later one
    starts."""
    kernel = RecordingKernel()

    def stopping():  # the generator's own stop event, set when it is closed
        return chunks.gi_frame.f_locals["abandon"].is_set()

    def hold(first):
        if first == 0:
            wait_for(lambda: kernel.ended(range(8, 4000)) == 3)
        elif first >= 32:
            wait_for(stopping)

    kernel.hold = hold
    monkeypatch.setattr(backends, "integrate_grid", kernel)
    params, y0, settings = rows(4000)
    chunks = LocalThreads(2).run(params, y0, settings, [(0, 8), (8, 4000)])
    a, b, _, _ = next(chunks)
    chunks.close()
    assert (a, b) == (0, 8)
    started = [first for event, first in kernel.log if event == "start"]
    ended = [first for event, first in kernel.log if event == "end"]
    assert sorted(started) == sorted(ended)  # none still running
    # one thread held at row 32, the other at 40 unless it saw the stop first
    assert set(started) - {40} == {*range(8), 8, 16, 24, 32}
