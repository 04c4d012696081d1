"""Numba policy: the one place where decorator arguments are decided.

Decisions (each tested in ``tests/test_accelerate.py``):

* ``nogil=True`` everywhere, so Dask worker threads can run kernels side by side.
* ``cache=True`` by default: users rerun the CLI many times and a warm cache saves
  the compile time. Writing the cache from several processes at once can crash
  (numba#4807), so the runner compiles in the parent process before any worker
  starts, and ``SWEEP_NUMBA_CACHE=0`` turns caching off (e.g. on a shared,
  read-only install).
* ``fastmath=False``: runaway detection must see NaN and inf (``nnan``/``ninf``
  would let LLVM assume they never occur).
* ``error_model="numpy"``: a division by zero gives inf/NaN (a classified
  outcome), not a Python exception raised from inside a parallel loop.
* The right-hand side and the explicit steps are inlined into the integration
  loop at numba-IR level (``inline="always"``): left to LLVM's heuristics, they
  stayed calls passing a dozen arrays each, and the RK4 loop took 2.9x the time
  per step of the same arithmetic written plainly (``make bench``); inlined,
  1.46x, and DOPRI5 runs 45 % more steps/s. The cost is a longer first compile
  (about 12 → 20 s), which the cache pays once.
* Threads have one owner: on one machine ``prange`` in the parallel grid kernel;
  under Dask each task calls the serial grid kernel and Dask owns the threads.
"""

import os

import numba

#: Whether compiled kernels are cached on disk (``SWEEP_NUMBA_CACHE=0`` disables).
CACHE = os.environ.get("SWEEP_NUMBA_CACHE", "1") != "0"

_COMMON = {"nogil": True, "cache": CACHE, "fastmath": False, "error_model": "numpy"}

prange = numba.prange


def jit(func):
    """Compile a serial kernel with the project's numba policy."""
    return numba.njit(**_COMMON)(func)


def jit_inline(func):
    """Compile a small hot function that numba inlines into every caller."""
    return numba.njit(inline="always", **_COMMON)(func)


def parallel_jit(func):
    """Compile a kernel whose ``prange`` loop runs on numba's thread pool."""
    return numba.njit(parallel=True, **_COMMON)(func)


def thread_count(n_threads):
    """Threads a run asks for: ``n_threads``, or all available when None."""
    return numba.config.NUMBA_NUM_THREADS if n_threads is None else int(n_threads)


def set_threads(n_threads):
    """Set how many numba threads the parallel kernels use (None: all available)."""
    n = thread_count(n_threads)
    numba.set_num_threads(n)
    return n
