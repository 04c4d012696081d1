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
  ``numba.literally`` arguments, so each combination compiles (and is cached) as
  its own version with the other models' and methods' branches pruned. A sweep
  compiles only its own combination (about 14 s cold, once), and the per-step
  branching on the codes is gone.
* No forced inlining: with the codes constant, LLVM inlines the right-hand side
  and the steps by itself. Forcing it at numba-IR level (``inline="always"``), which
  had made the unspecialised kernel 45 % faster, now changes nothing at run time
  (273–302 vs 279–286 ns per DOPRI5 step, ``make bench``) and costs 10 s of compile
  (24.5 vs 14.3 s for ``integrate_system``).
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
