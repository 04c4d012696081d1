"""The numba policy of ``sweep/accelerate.py``: nogil, cache (with its off switch),
no fastmath, numpy error model."""

import json
import os
import shutil
from pathlib import Path

import numba
import numpy as np
import pytest
from conftest import python_stdout

from sweep import accelerate
from sweep.config import load_config, with_changes
from sweep.engine.runner import compute
from sweep.kernels import control, equations, integrate, layout, linalg, record, step, tangent
from sweep.kernels.classify import cycle, extrema, result, sequences, state, verdicts
from sweep.kernels.methods import MODULES as METHOD_MODULES

#: The modules of the kernel package that hold jitted functions.
CLASSIFY = (state, sequences, extrema, cycle, verdicts, result)
MODULES = (equations, step, control, linalg, tangent, *METHOD_MODULES, *CLASSIFY, record, integrate)
#: The plain-Python functions of the kernels: the one that builds the grid kernel of a
#: variant, the one that puts an explicit method's tableau in the tangent's form when its
#: module is imported, the one that builds RODAS4's steps from a way of solving, and an
#: implicit method's matrix columns (read when a grid kernel is built).
PLAIN = ("grid_kernel", "explicit_tableau", "rosenbrock", "matrix_columns")


def kernel_functions():
    """Every jitted function defined in the kernel modules, found by inspecting them:
    "module.name" (the module's last name) → dispatcher."""
    return {
        f"{module.__name__.rsplit('.', 1)[-1]}.{name}": obj
        for module in MODULES
        for name, obj in vars(module).items()
        if callable(obj) and getattr(obj, "__module__", None) == module.__name__
        and name not in PLAIN and not isinstance(obj, type)
    }  # fmt: skip


KERNELS = sorted(kernel_functions())
#: Helpers of the grid kernels' loop, one per integrator and the classifier's: the
#: discovery must find at least these (a guard against discovering nothing).
ENTRY_POINTS = {"extrema.update_cycle", "rk4.step", "dopri5.step", "dop853.step", "rodas4.step"}
#: Model, law, method, coupling codes and unequal blocks of one variant (quasi-static,
#: aging, DOPRI5, chain, equal blocks).
ROOT = Path(__file__).resolve().parents[1]
VARIANT = (layout.QUASI_STATIC, layout.AGING, layout.DOPRI5, layout.CHAIN, False, False)
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
    assert options["no_cfunc_wrapper"] is True  # no first-class use: not worth compiling
    # one owner of the threads: the backends' (local or Dask), never numba's pool
    assert options.get("parallel", False) is False


@NO_JIT
@pytest.mark.parametrize("name", KERNELS)
def test_kernel_options(name):
    """Every function of the kernel package is compiled with the policy (numba's own
    record); the helpers compiled on their own without a CPython wrapper (accelerate.py:
    no kernel calls them from Python), the inlined ones (compiled on their own only for
    a call from Python) with it."""
    dispatcher = kernel_functions()[name]
    assert_policy(dispatcher)
    inlined = dispatcher.targetoptions.get("inline") == "always"
    assert dispatcher.targetoptions.get("no_cpython_wrapper", False) is not inlined
    assert isinstance(dispatcher, accelerate.HelperDispatcher) is not inlined


@NO_JIT
def test_a_helper_without_cpython_wrapper_is_called_from_python_through_a_shim():
    """accelerate.HelperDispatcher: a call from Python goes through a jitted shim (numba
    would jump through the missing wrapper: a segmentation fault), which gives the plain
    function's result and is built once."""
    assert sequences.aitken_limit(1.0, 0.5, 0.25, 0.125, 1e-12) == (
        sequences.aitken_limit.py_func(1.0, 0.5, 0.25, 0.125, 1e-12))  # fmt: skip
    shim = sequences.aitken_limit._python_entry
    assert shim.targetoptions.get("no_cpython_wrapper", False) is False
    assert sequences.aitken_limit(x0=1.0, x1=0.5, x2=0.25, x3=0.125, noise=0.0)[1] == 0.0
    assert sequences.aitken_limit._python_entry is shim


@NO_JIT
def test_grid_kernels_follow_the_policy_one_per_variant():
    """The factory's grid kernels: the policy, one dispatcher per variant (built once)."""
    kernel = integrate.grid_kernel(*VARIANT)
    assert_policy(kernel)
    assert kernel.targetoptions.get("no_cpython_wrapper", False) is False  # Python calls it
    assert integrate.grid_kernel(*VARIANT) is kernel
    other = integrate.grid_kernel(layout.QUASI_DYNAMIC, *VARIANT[1:])
    assert other is not kernel


@NO_JIT
@pytest.mark.parametrize(
    "name",
    [
        "equations.rhs",
        "rk4.step",
        "dopri5.step",
        "dop853.step",
        "dopri5.dense",
        "step.dense_tail",
        "step.dense_value",
        "state.cycle_arrays",
    ],
)
def test_rhs_and_explicit_steps_are_inlined(name):
    """accelerate.py: the right-hand side and the explicit steps are inlined at numba-IR
    level (a third of the time per step)."""
    assert kernel_functions()[name].targetoptions.get("inline") == "always"


@NO_JIT
def test_the_classifier_update_is_inlined_by_llvm():
    """accelerate.py: the classifier's per-step update is compiled on its own (cached,
    not copied into the kernel by numba's inliner) and inlined by LLVM."""
    options = extrema.update_cycle.targetoptions
    assert options["forceinline"] is True
    assert options.get("inline", "never") == "never"


@NO_JIT
@pytest.mark.parametrize("name", ["dop853.dense", "extrema.dense_needed"])
def test_dop853_parts_are_plain_calls(name):
    """accelerate.py: DOP853's interpolant and the test for where it is read are plain
    calls, typed only in DOP853's kernels, so no other kernel compiles them."""
    options = kernel_functions()[name].targetoptions
    assert options.get("inline", "never") == "never"
    assert options["forceinline"] is False


# Imports the kernels (compiles nothing) and reports each function's numba cache and
# whether it is inlined.
CACHE_PROBE = """
import json
from sweep.kernels import control, equations, integrate, linalg, record, step, tangent
from sweep.kernels.classify import cycle, extrema, result, sequences, state, verdicts
from sweep.kernels.methods import MODULES
report = {f"{module.__name__.rsplit('.', 1)[-1]}.{name}":
          [type(obj._cache).__name__, obj.targetoptions.get("inline") == "always"]
          for module in (equations, step, control, linalg, tangent, *MODULES, state, sequences,
                         extrema, cycle, verdicts, result, record, integrate)
          for name, obj in vars(module).items()
          if getattr(obj, "__module__", None) == module.__name__
          and name not in ("grid_kernel", "explicit_tableau", "rosenbrock", "matrix_columns")
          and callable(obj) and not isinstance(obj, type)}
report["grid_kernel()"] = [type(integrate.grid_kernel(0, 0, 0, 0, False, False)._cache).__name__,
                           False]
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("value, cache", [(None, "SourceKeyedCache"), ("0", "NullCache"),
                                          ("1", "SourceKeyedCache")])  # fmt: skip
def test_cache_switch(value, cache):
    """The grid kernels and the helpers they call are cached by default (variable
    unset), none of them with SWEEP_NUMBA_CACHE=0; inlined helpers never are (they are
    compiled into their callers)."""
    env = {k: v for k, v in os.environ.items() if k != "SWEEP_NUMBA_CACHE"}
    env["NUMBA_DISABLE_JIT"] = "0"
    if value is not None:
        env["SWEEP_NUMBA_CACHE"] = value
    report = json.loads(python_stdout(CACHE_PROBE, env=env))
    assert sorted(report) == sorted([*KERNELS, "grid_kernel()"])
    inlined = {name for name, (_, inline) in report.items() if inline}
    assert inlined and len(inlined) < len(report)
    for name, (kind, inline) in report.items():
        assert kind == ("NullCache" if inline else cache), name


def test_nan_and_inf_survive_compiled_code():
    """With fastmath off and the numpy error model, a zero A gives inf and a NaN state
    gives NaN in the compiled rhs, where fastmath's nnan/ninf could fold them away."""
    p = np.zeros(layout.N_PARAMS)
    p[layout.P_B], p[layout.P_KAPPA1] = 0.08, 0.05  # A = 0
    dydt = np.zeros(2)
    codes = layout.QUASI_STATIC, layout.AGING, layout.CHAIN, False
    equations.rhs(np.array([0.1, 0.0]), p, *codes, 1, np.empty(1), dydt)
    assert np.isinf(dydt[0])
    p[layout.P_A] = 0.03
    equations.rhs(np.array([np.nan, 0.0]), p, *codes, 1, np.empty(1), dydt)
    assert np.isnan(dydt).all()


def test_thread_count():
    # None: every core numba sees (the CLI's default); a number is taken as it is
    assert accelerate.thread_count(None) == numba.config.NUMBA_NUM_THREADS
    assert accelerate.thread_count(3) == 3


@NO_JIT
def test_one_cache_decision_in_this_process():
    """The grid kernels follow the one decision (whatever the environment says)."""
    kernel = integrate.grid_kernel(*VARIANT)
    expected = "SourceKeyedCache" if accelerate.CACHE else "NullCache"
    assert type(kernel._cache).__name__ == expected


# One small run of quick.yaml with DOPRI5 (and another MODEL) in a fresh process: its
# step count, whether numba's cache served the grid kernel and the end of a cycle
# (``close_cycle``, a helper in another file), and how many signatures the process holds (compiled
# or loaded) of parts that only other variants use, and of two helpers that could be
# specialised on constants they should not be.
CACHED_RUN = """
import json, sweep
from numba.core import types
from sweep.engine.dispatch import grid_kernel
from sweep.engine.grid import build_grid
from sweep.kernels import tangent
from sweep.kernels.classify import extrema, state
from sweep.kernels.classify.cycle import close_cycle
from sweep.kernels.slip_events import catalogue_step
from sweep.kernels.methods import dop853, rodas4
# floquet: never: the pruning asked of the grid kernel, without the Floquet pass's kernel
# (which carries the tangent, so compiles its step, where periodic runs ask for it)
config = sweep.with_changes(sweep.load_config(CONFIG), {"integrator": {"method": "dopri5"},
                                                       "classification": {"floquet": "never"}})
if MODEL:
    config = sweep.with_changes(config, {"model": MODEL, "parameters": {"eta_W": 0.1}})
ds = sweep.run(config, progress=False)
g = build_grid(config)
report = {"n_steps": ds["n_steps"].values.tolist()}
for name, f in (("kernel", grid_kernel(g.params, g.settings)), ("helper", close_cycle)):
    report[name] = [sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
others = {"dop853.dense": dop853.dense, "rodas4.step": rodas4.step,
          "rodas4.tangent_step": rodas4.tangent_step,
          "explicit_tangent_step": tangent.explicit_tangent_step,
          "lyapunov_start": tangent.lyapunov_start,
          "history_value": state.history_value, "catalogue_step": catalogue_step}
report["signatures"] = {name: len(f.signatures) for name, f in others.items()}
report["literal"] = {
    name: sorted({str(a) for s in f.signatures for a in s if isinstance(a, types.Literal)})
    for name, f in {"history_value": state.history_value,
                    "update_cycle": extrema.update_cycle}.items()}
print(json.dumps(report))
"""


def cached_run(tmp_path, model=None):
    """CACHED_RUN of quick.yaml (with ``model``) with the copy of the package and the
    numba cache in ``tmp_path``: its report."""
    env = dict(os.environ, PYTHONPATH=str(tmp_path), NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               SWEEP_NUMBA_CACHE="1", NUMBA_DISABLE_JIT="0")  # fmt: skip
    config = str(ROOT / "configs" / "quick.yaml")
    code = f"CONFIG = {config!r}\nMODEL = {model!r}\n{CACHED_RUN}"
    return json.loads(python_stdout(code, env=env, cwd=tmp_path).splitlines()[-1])


def copy_package(tmp_path):
    shutil.copytree(
        ROOT / "sweep", tmp_path / "sweep", ignore=shutil.ignore_patterns("__pycache__")
    )


@NO_JIT  # the last step compares with a compiled run in this process
@pytest.mark.slow
def test_one_copy_of_the_package_compiles_prunes_caches_and_recompiles(tmp_path):
    """A copy of the package and its own numba cache, run by fresh processes in turn
    (each step needs the one before: one test, so that the cold compiles are not repeated
    per test).

    1. Pruning. The codes are constants of the grid kernel's closure, and numba prunes the
       other variants' branches before it inlines and types the helpers: a DOPRI5 kernel
       without the tangent compiles neither DOP853's interpolant nor RODAS4's step, nor a
       tangent step or the tangent's start, nor, for runs without a catalogue of slip
       events, the catalogue (each costs seconds of a cold start). Helpers are specialised on the
       codes they are passed and on no other constant: ``history_value``, called with
       constant and variable arguments, compiles once; ``update_cycle``, which takes the
       step record and no code, is shared by every method.
    2. The next process loads the kernel from the cache.
    3. A variant not compiled before (quasi-dynamic after quasi-static) compiles its
       kernel but loads the classifier from the cache, and gives the numbers of this
       test process's own run (its kernels compiled elsewhere, from the same sources).
    4. numba checks a cache entry against its own file only; the key of every cached
       function also covers every kernel source (``accelerate.source_digest``). With the
       step-size controller (``control.next_step_size``, inlined from another file)
       edited, the next run must compile the kernel and the cached helpers afresh and
       take other steps, not load stale code.
    """
    copy_package(tmp_path)
    first = cached_run(tmp_path)
    assert first["signatures"] == {
        "dop853.dense": 0, "rodas4.step": 0, "rodas4.tangent_step": 0,
        "explicit_tangent_step": 0, "lyapunov_start": 0, "history_value": 1,
        "catalogue_step": 0,
    }  # fmt: skip
    assert first["literal"] == {"history_value": [], "update_cycle": []}
    assert (first["kernel"], first["helper"]) == ([0, 1], [0, 1])

    again = cached_run(tmp_path)
    assert again["kernel"] == [1, 0]
    assert again["n_steps"] == first["n_steps"]

    further = cached_run(tmp_path, model="quasi-dynamic")
    assert (further["kernel"], further["helper"]) == ([0, 1], [1, 0])
    config = with_changes(load_config(ROOT / "configs" / "quick.yaml"), {
        "integrator": {"method": "dopri5"}, "model": "quasi-dynamic",
        "parameters": {"eta_W": 0.1}})  # fmt: skip
    assert compute(config, show_progress=False)["n_steps"].values.tolist() == further["n_steps"]

    helper = tmp_path / "sweep" / "kernels" / "control.py"
    text = helper.read_text()
    assert text.count("0.9 * max(err, 1e-10)") == 1
    helper.write_text(text.replace("0.9 * max(err, 1e-10)", "0.7 * max(err, 1e-10)"))
    edited = cached_run(tmp_path)
    assert (edited["kernel"], edited["helper"]) == ([0, 1], [0, 1])
    assert edited["n_steps"] != first["n_steps"]
