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

JITTED = [
    "rhs", "step_rk4", "step_dopri5", "dense_value", "dense_extremum",
    "dense_crossing", "aitken_limit", "cycle_verdict", "integrate_system",
    "integrate_grid_serial", "integrate_grid_parallel",
]  # fmt: skip


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="NUMBA_DISABLE_JIT=1: no dispatchers")
@pytest.mark.parametrize("name", JITTED)
def test_kernel_options(name):
    dispatcher = getattr(kernels, name)
    options = dispatcher.targetoptions
    assert options["nogil"] is True  # Dask threads run kernels side by side
    assert options["fastmath"] is False  # runaway detection must see NaN and inf
    assert options["error_model"] == "numpy"  # x/0 → inf, not an exception
    assert options.get("parallel", False) == (name == "integrate_grid_parallel")
    # numba keeps the cache choice on the dispatcher, not in targetoptions
    cached = type(dispatcher._cache).__name__ == "FunctionCache"
    assert cached == accelerate.CACHE


def test_cache_on_by_default():
    assert accelerate.CACHE == (os.environ.get("SWEEP_NUMBA_CACHE", "1") != "0")


# Imports the kernels (compiles nothing) and reports the cache decision.
CACHE_PROBE = """
import json
from sweep import accelerate, kernels
print(json.dumps({"CACHE": accelerate.CACHE,
                  "caches": sorted({type(getattr(kernels, n)._cache).__name__
                                    for n in ("rhs", "integrate_system",
                                              "integrate_grid_parallel")})}))
"""


@pytest.mark.parametrize("value, cached", [("0", False), ("1", True)])
def test_cache_switch(value, cached):
    env = {**os.environ, "SWEEP_NUMBA_CACHE": value, "NUMBA_DISABLE_JIT": "0"}
    proc = subprocess.run(
        [sys.executable, "-c", CACHE_PROBE], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["CACHE"] is cached
    assert report["caches"] == (["FunctionCache"] if cached else ["NullCache"])


def test_nan_and_inf_survive_compiled_code():
    """With fastmath off and the numpy error model, a zero A gives inf and a NaN state
    gives NaN in the compiled rhs, where fastmath's nnan/ninf could fold them away."""
    p = np.zeros(kernels.N_PARAMS)
    p[kernels.P_B], p[kernels.P_KAPPA1] = 0.08, 0.05  # A = 0
    dydt = np.zeros(2)
    kernels.rhs(np.array([0.1, 0.0]), p, kernels.QUASI_STATIC, kernels.AGING, 1, np.empty(1), dydt)
    assert np.isinf(dydt[0])
    p[kernels.P_A] = 0.03
    kernels.rhs(
        np.array([np.nan, 0.0]), p, kernels.QUASI_STATIC, kernels.AGING, 1, np.empty(1), dydt
    )
    assert np.isnan(dydt).all()


def test_set_threads():
    top = numba.config.NUMBA_NUM_THREADS
    try:
        assert accelerate.set_threads(1) == 1 and numba.get_num_threads() == 1
        # None: every core (the CLI's default), not whatever an earlier run set
        assert accelerate.set_threads(None) == top and numba.get_num_threads() == top
    finally:
        numba.set_num_threads(top)
