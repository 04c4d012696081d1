"""The numba policy of ``sweep/accelerate.py``: nogil, cache (with its off switch),
no fastmath, numpy error model."""

import json
import os
import subprocess
import sys

import numba
import numpy as np
import pytest

from sweep import accelerate, kernels

#: The one plain-Python function of sweep.kernels: it builds the grid kernel of a variant.
FACTORY = "grid_kernel"


def kernel_functions():
    """Every jitted function defined in ``sweep.kernels``, found by inspecting the module."""
    return {
        name: obj
        for name, obj in vars(kernels).items()
        if callable(obj)
        and getattr(obj, "__module__", None) == kernels.__name__
        and name != FACTORY
    }


KERNELS = sorted(kernel_functions())
#: Helpers the grid kernels inline, one per integrator: the discovery must find at
#: least these (a guard against discovering nothing).
ENTRY_POINTS = {"integrate_system", "step_rk4", "step_dopri5", "step_rosenbrock"}
#: Model, law, method, coupling codes and unequal blocks of one variant (quasi-static,
#: aging, DOPRI5, chain, equal blocks).
VARIANT = (kernels.QUASI_STATIC, kernels.AGING, kernels.DOPRI5, kernels.CHAIN, False)
NO_JIT = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="NUMBA_DISABLE_JIT=1: no dispatchers")


def test_discovery_finds_the_entry_points():
    assert ENTRY_POINTS <= set(KERNELS)


def assert_policy(dispatcher):
    assert isinstance(dispatcher, numba.core.registry.CPUDispatcher)  # compiled, nopython
    options = dispatcher.targetoptions
    assert options["nopython"] is True
    assert options["nogil"] is True  # Dask threads run kernels side by side
    assert options["fastmath"] is False  # runaway detection must see NaN and inf
    assert options["error_model"] == "numpy"  # x/0 → inf, not an exception
    # one owner of the threads: the backends' (local or Dask), never numba's pool
    assert options.get("parallel", False) is False


@NO_JIT
@pytest.mark.parametrize("name", KERNELS)
def test_kernel_options(name):
    """Every function in sweep.kernels is compiled with the policy (numba's own record)."""
    assert_policy(getattr(kernels, name))


@NO_JIT
def test_grid_kernels_follow_the_policy_one_per_variant():
    """The factory's grid kernels: the policy, one dispatcher per variant (built once),
    and the per-system loop inlined into them."""
    kernel = kernels.grid_kernel(*VARIANT)
    assert_policy(kernel)
    assert kernels.grid_kernel(*VARIANT) is kernel
    other = kernels.grid_kernel(kernels.QUASI_DYNAMIC, *VARIANT[1:])
    assert other is not kernel
    assert kernels.integrate_system.targetoptions.get("inline") == "always"


@NO_JIT
@pytest.mark.parametrize("name", ["rhs", "step_rk4", "step_dopri5", "dense_r5", "cycle_arrays"])
def test_rhs_and_explicit_steps_are_inlined(name):
    """accelerate.py: the right-hand side and the explicit steps are inlined at numba-IR
    level (a third of the time per step)."""
    assert getattr(kernels, name).targetoptions.get("inline") == "always"


# Imports the kernels (compiles nothing) and reports each kernel's numba cache.
CACHE_PROBE = """
import json
from sweep import kernels
report = {name: type(obj._cache).__name__ for name, obj in vars(kernels).items()
          if getattr(obj, "__module__", None) == "sweep.kernels" and name != "grid_kernel"}
report["grid_kernel()"] = type(kernels.grid_kernel(0, 0, 0, 0, False)._cache).__name__
print(json.dumps(report))
"""


@pytest.mark.parametrize("value, cache", [(None, "FunctionCache"), ("0", "NullCache"),
                                          ("1", "FunctionCache")])  # fmt: skip
def test_cache_switch(value, cache):
    """On by default (variable unset), off with SWEEP_NUMBA_CACHE=0, for every kernel."""
    env = {k: v for k, v in os.environ.items() if k != "SWEEP_NUMBA_CACHE"}
    env["NUMBA_DISABLE_JIT"] = "0"
    if value is not None:
        env["SWEEP_NUMBA_CACHE"] = value
    proc = subprocess.run(
        [sys.executable, "-c", CACHE_PROBE], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert sorted(report) == sorted([*KERNELS, "grid_kernel()"])
    assert set(report.values()) == {cache}


@NO_JIT
def test_one_cache_decision_in_this_process():
    """Here too every kernel follows the one decision (whatever the environment says)."""
    assert len({type(getattr(kernels, name)._cache) for name in KERNELS}) == 1


def test_nan_and_inf_survive_compiled_code():
    """With fastmath off and the numpy error model, a zero A gives inf and a NaN state
    gives NaN in the compiled rhs, where fastmath's nnan/ninf could fold them away."""
    p = np.zeros(kernels.N_PARAMS)
    p[kernels.P_B], p[kernels.P_KAPPA1] = 0.08, 0.05  # A = 0
    dydt = np.zeros(2)
    codes = kernels.QUASI_STATIC, kernels.AGING, kernels.CHAIN, False
    kernels.rhs(np.array([0.1, 0.0]), p, *codes, 1, np.empty(1), dydt)
    assert np.isinf(dydt[0])
    p[kernels.P_A] = 0.03
    kernels.rhs(np.array([np.nan, 0.0]), p, *codes, 1, np.empty(1), dydt)
    assert np.isnan(dydt).all()


def test_thread_count():
    # None: every core numba sees (the CLI's default); a number is taken as it is
    assert accelerate.thread_count(None) == numba.config.NUMBA_NUM_THREADS
    assert accelerate.thread_count(3) == 3
