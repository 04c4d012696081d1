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
* Kernels are specialised at compile time for the model, state law and method a
  sweep uses: the grid kernels and ``integrate_system`` take their codes as
  ``numba.literally`` arguments, so each combination is its own compiled (and
  cached) version in which LLVM folds the branches on the codes away. numba still
  types every branch, so a combination compiles in about the same time whatever
  its method (15-16 s for ``integrate_system``, measured); only the combinations a
  sweep uses are compiled. Callers reach the compiled version through its entry
  point (``runner.compile_grid_kernel``): through the dispatcher each call would
  first try the codes as plain integers (14 ms per call).
* The right-hand side, the explicit steps and the dense-output coefficient are
  inlined into the integration loop at numba-IR level (``inline="always"``): left
  to LLVM, they stay calls passing a dozen arrays each. Measured on the
  specialised kernels (``make bench``, idle machine): RK4 189 vs 288 ns per step,
  DOPRI5 318 vs 396 ns per step. The cost is about 10 s more of first compile,
  which the cache pays once.
* Threads have one owner: on one machine ``prange`` in the parallel grid kernel;
  under Dask each task calls the serial grid kernel and Dask owns the threads.
"""

import os

import numba

#: Whether compiled kernels are cached on disk (``SWEEP_NUMBA_CACHE=0`` disables).
CACHE = os.environ.get("SWEEP_NUMBA_CACHE", "1") != "0"

_COMMON = {"nogil": True, "cache": CACHE, "fastmath": False, "error_model": "numpy"}

prange = numba.prange
literally = numba.literally


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
