"""Shared test helpers: small configs from dicts, the kernels on one grid, and an
independent SciPy reference written from the physics brief (not from the kernels).
"""

import copy
import math
import re
import select
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml
from hypothesis import settings
from scipy.integrate import solve_ivp

from sweep.config import load_config, parse_config
from sweep.engine import chunks, grid, runner
from sweep.engine.dispatch import integrate_grid
from sweep.io.netcdf import write_netcdf
from sweep.kernels import layout
from sweep.model.physics import log_form_rhs

# Hypothesis tests have no per-example deadline (its default is 200 ms): an example may
# be the first call of a numba kernel variant, which compiles it (about 30 s cold), and
# the test machines share their cores. What they test is a property, not a speed.
settings.register_profile("rsf-sweep", deadline=None)
settings.load_profile("rsf-sweep")

#: Seconds any wait on another process (a subprocess, a Dask cluster, a Jupyter kernel)
#: may take: generous (cold numba compiles on two busy cores), and finite, so that a hang
#: fails the test instead of blocking the run for ever.
SUBPROCESS_TIMEOUT = 600

#: The seed paper's friction coefficients (physics brief, section 1).
PAPER_A, PAPER_B = 0.03, 0.08
#: Critical stiffness per normal load Kc/W = (B − A)/D0 for D0 = 1 µm, in µm⁻¹.
KC_W = PAPER_B - PAPER_A


def kc_w(model_name, eta_w=0.0, m_w=0.0, V=0.1, D0=1.0):
    """The brief's critical stiffness Kc/W (µm⁻¹) for the paper's A and B, η/W (s/µm),
    m/W (s²/µm), V (µm/s) and D0 (µm), from its closed forms (sections 3–4)::

        radiation damping   Kc = (W(B − A) − ηV)/D0
        inertia             Kc = (W(B − A)/D0)(1 + m V²/(W A D0))
    """
    if model_name == "quasi-dynamic":
        return ((PAPER_B - PAPER_A) - eta_w * V) / D0
    if model_name == "inertial":
        return (PAPER_B - PAPER_A) / D0 * (1.0 + m_w * V**2 / (PAPER_A * D0))
    return (PAPER_B - PAPER_A) / D0


#: A one-block quasi-static config like configs/quick.yaml (D0 = 1 µm, V = 0.1 µm/s,
#: so the time unit D0/V is 10 s), with the model's default method as users get it
#: (DOP853; RODAS4 for the inertial model); tests override only what they need, and name
#: the method where they are about one.
BASE_CONFIG = {
    "name": "test",
    "blocks": 1,
    "model": "quasi-static",
    "state_law": "aging",
    "parameters": {"A": PAPER_A, "B": PAPER_B, "mu0": 0.4, "V": 0.1, "Phi0": 1.0, "D0": 1.0},
    "sweep": {"K_W": [0.04, 0.06]},
    "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.01},
    "integrator": {"rtol": 1.0e-8, "atol": 1.0e-10, "t_end": 2000.0},
    "classification": {"v_cap_over_V": 1.0e6},
    "output": "results/test.nc",
}


def merge(base, overrides):
    """``base`` updated by ``overrides`` recursively: nested dicts merge, other values
    replace, and ``None`` removes the key."""
    out = copy.deepcopy(base)
    for key, value in overrides.items():
        if value is None:
            out.pop(key, None)
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def config_dict(overrides=None, **sections):
    """:data:`BASE_CONFIG` with ``overrides`` (a dict) and keyword sections merged in."""
    return merge(merge(BASE_CONFIG, overrides or {}), sections)


def make_config(overrides=None, source="<test>", **sections):
    """A validated :class:`sweep.config.Config` built through ``parse_config``."""
    return parse_config(yaml.safe_dump(config_dict(overrides, **sections)), source)


def write_config(path, overrides=None, **sections):
    """Write a config (YAML) to ``path`` and return the path."""
    path.write_text(yaml.safe_dump(config_dict(overrides, **sections)))
    return path


def run_grid(config):
    """Integrate every system of ``config`` → ``(results, y_final)`` (kernel units, D0/V)."""
    g = grid.build_grid(config)
    return chunks.integrate_in_memory(g.params, g.y0, g.settings)


def run_recorded(config, rec_dt, index=0):
    """Integrate system ``index`` of ``config`` recording the state every ``rec_dt`` (D0/V).

    Returns ``(result, rec_t, rec_y)`` trimmed to the recorded points.
    """
    g = grid.build_grid(config)
    params, y0, settings = g.params, g.y0, g.settings
    n_rec = int(params[index, layout.P_TAU_END] / rec_dt) + 3
    rec_t = np.zeros(n_rec)
    rec_y = np.zeros((n_rec, y0.shape[1]))
    result = np.zeros((1, layout.result_width(settings)))
    y_final = np.zeros((1, y0.shape[1]))
    row = slice(index, index + 1)
    integrate_grid(params[row], y0[row], settings, result, y_final, rec_dt, rec_t, rec_y)
    n = int(result[0, layout.R_N_RECORDED])
    return result[0], rec_t[:n], rec_y[:n]


#: The anti-phase start of two blocks: block 0 1 % above steady sliding, block 1 1 % below.
ANTI = {"v_over_V": [1.01, 0.99], "phi_over_phi_ss": [1.01, 0.99]}


@pytest.fixture(scope="session")
def anti_phase_cycle():
    """``(row, ds)``: the kernel's result row (``layout.R_*`` columns) and the result
    Dataset of one run that three test modules check (test_classification,
    test_nblock_findings, test_readme), computed once per test process: two quasi-static
    blocks in a chain, k2/W = 0.001 µm⁻¹, K/Kc = 0.99, the :data:`ANTI` start, t_end =
    max_t_end = 8000 D0/V. SciPy has them settle on a bounded out-of-phase cycle
    (physics brief §4)."""
    from sweep.results.dataset import build_dataset

    config = make_config(
        {"blocks": 2, "coupling": "chain", "parameters": {"k2_W": 0.001}},
        sweep={"K_W": [0.99 * KC_W]}, initial=ANTI, integrator={"t_end": 8000.0},
        classification={"max_t_end": 8000.0},
    )  # fmt: skip
    g = grid.build_grid(config)
    results, y_final = chunks.integrate_in_memory(g.params, g.y0, g.settings)
    return results[0], build_dataset(g, results, y_final).isel(K_W=0)


def scipy_runaway_time(kappa_over_kc, lnv0, psi0, v_cap_over_V=1e6, t_max=3000.0):
    """Time (D0/V) at which one quasi-static block (paper A, B) first reaches the cap.

    Reference call: ``solve_ivp(log_form_rhs, method="DOP853", rtol=1e-10,
    atol=1e-12)`` with a terminal event at ℓ = ln(v_cap/V).
    """
    kappa = kappa_over_kc * (PAPER_B - PAPER_A)

    def cap(t, y, *args):
        return y[0] - math.log(v_cap_over_V)

    cap.terminal = True
    cap.direction = 1
    sol = solve_ivp(
        log_form_rhs, (0.0, t_max), [lnv0, psi0], method="DOP853", rtol=1e-10, atol=1e-12,
        args=(PAPER_A, PAPER_B, kappa), events=cap,
    )  # fmt: skip
    assert sol.status == 1, "the reference run did not reach the cap"
    return float(sol.t_events[0][0])


def assert_transition_at(k_w, regime, kc):
    """Steady exactly above Kc, not steady below: the sweep's transition lies in
    the grid step that contains Kc (so within one grid step of it)."""
    k_w, regime = np.asarray(k_w), np.asarray(regime)
    below = k_w < kc
    assert np.all(regime[~below] == layout.STEADY), (kc, regime)
    assert np.all(regime[below] != layout.STEADY), (kc, regime)
    assert below.any() and (~below).any()


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """Run the test inside a fresh temporary directory."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "configs" / "quick.yaml"


#: File attributes that say when and by which command (run, merge) a result was made:
#: the only difference between results of one config made in different ways.
PROVENANCE_ATTRS = ("created", "history")


def without_provenance(ds):
    """``ds`` without the file attributes :data:`PROVENANCE_ATTRS`."""
    out = ds.copy()
    out.attrs = {k: v for k, v in ds.attrs.items() if k not in PROVENANCE_ATTRS}
    return out


def assert_same_file(path, reference):
    """Two NetCDF result files hold the same data: every variable and coordinate bit for
    bit as stored (no CF decoding), each with the same attributes, dtype, shape and
    storage (compression, chunks), and the same file attributes except
    :data:`PROVENANCE_ATTRS`."""
    with (
        xr.open_dataset(path, decode_cf=False) as got,
        xr.open_dataset(reference, decode_cf=False) as want,
    ):
        xr.testing.assert_identical(without_provenance(got.load()), without_provenance(want))
        assert set(want.attrs) - set(PROVENANCE_ATTRS) == set(got.attrs) - set(PROVENANCE_ATTRS)
        for name, var in want.variables.items():
            a, b = got[name].values, var.values
            assert (a.dtype, a.shape, a.tobytes()) == (b.dtype, b.shape, b.tobytes()), name
            storage = [{k: v for k, v in x.encoding.items() if k != "source"}
                       for x in (got[name].variable, var)]  # fmt: skip
            assert storage[0] == storage[1], name


def reference_file(config, path):
    """The plainest run of ``config`` (one thread, one system per chunk) written to ``path``."""
    ds = runner.compute(config, threads=1, chunk_size=1, show_progress=False)
    return write_netcdf(ds, path)


@pytest.fixture(scope="module")
def quick():
    """The validated ``configs/quick.yaml``."""
    return load_config(QUICK)


@pytest.fixture(scope="module")
def quick_reference_file(quick, tmp_path_factory):
    """:func:`reference_file` of ``configs/quick.yaml``."""
    return reference_file(quick, tmp_path_factory.mktemp("reference") / "quick.nc")


#: A process that starts writing one part (rows 0:2 of configs/quick.yaml) into a
#: folder and never finishes: with mode "killed" it SIGKILLs itself in the middle of
#: the write, with "stuck" it waits there until the test kills it, and "elsewhere" is
#: "killed" on a machine that calls itself elsewhere.example.org (a shard on another
#: node of a shared file system).
PART_WRITER = r"""
import os, signal, socket, sys, time
import numpy as np
mode, directory, config_path = sys.argv[1:]
if mode == "elsewhere":
    socket.gethostname = lambda: "elsewhere.example.org"
from sweep.io import parts as store
from sweep.config import load_config

def savez(f, **arrays):
    f.write(b"PK\x03\x04 the first bytes of a part")
    f.flush()
    print("writing", flush=True)
    if mode == "stuck":
        time.sleep(600)
    os.kill(os.getpid(), signal.SIGKILL)

np.savez = savez
config = load_config(config_path)
store.write_part(directory, config, store.config_hash(config), 0, 2, 9, np.zeros((2, 15)),
                 np.zeros((2, 2)))
"""


def python_stdout(code, *args, **run_options):
    """What ``python -c code *args`` prints on stdout, run in a fresh process (options
    such as ``env`` or ``cwd`` go to ``subprocess.run``); fails, showing its stderr,
    if it exits non-zero or runs longer than ``SUBPROCESS_TIMEOUT``."""
    proc = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=SUBPROCESS_TIMEOUT, **run_options)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def read_line(proc, timeout=SUBPROCESS_TIMEOUT):
    """The next line ``proc`` prints on its stdout (a text pipe); fails after ``timeout`` s."""
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    assert ready, f"pid {proc.pid} printed nothing within {timeout} s"
    return proc.stdout.readline()


def interrupted_part_writer(directory, mode):
    """Run :data:`PART_WRITER` on ``directory`` until it is inside the write.

    ``mode`` "killed" / "elsewhere": returns once the writer is dead; "stuck":
    returns the live process (the caller kills it).
    """
    proc = subprocess.Popen(
        [sys.executable, "-c", PART_WRITER, mode, str(directory), str(QUICK)],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert read_line(proc) == "writing\n"
    if mode == "stuck":
        return proc
    assert proc.wait(timeout=SUBPROCESS_TIMEOUT) == -signal.SIGKILL
    return proc


def readme_numbers(pattern):
    """The numbers the README states where ``pattern`` (a regex whose groups capture
    them) matches, as the printed strings; whitespace in the README counts as one space.
    Fails if the pattern is not found once exactly."""
    text = " ".join((ROOT / "README.md").read_text().split())
    found = re.findall(pattern, text)
    assert len(found) == 1, f"README: {pattern!r} matched {len(found)} times"
    return found[0] if isinstance(found[0], tuple) else (found[0],)


def assert_as_printed(value, printed):
    """``value`` agrees with the README's ``printed`` number to its last printed digit
    (within half a unit of it): the README may round, but not be wrong."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    assert abs(value - float(printed)) <= 0.5 * 10.0**-decimals, (value, printed)


# A process that takes an output's lock, says so, and holds it until killed (the
# fixture kills it after the test, however long the test takes).
LOCK_HOLDER = """
import sys, threading
from sweep.io import files
with files.output_lock(sys.argv[1], shared=sys.argv[2] == "shared"):
    print("locked", flush=True)
    threading.Event().wait()
"""


@pytest.fixture
def lock_holder(tmp_path):
    """Start a process holding the lock of ``out`` (exclusive or shared); kill it after."""
    import subprocess
    import sys

    procs = []

    def start(out, mode="exclusive"):
        proc = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(out), mode],
                                stdout=subprocess.PIPE, text=True)  # fmt: skip
        assert read_line(proc).strip() == "locked"
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        proc.kill()
        proc.wait(timeout=SUBPROCESS_TIMEOUT)
