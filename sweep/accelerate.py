"""Numba policy: the one place where decorator arguments are decided.

Decisions (each tested in ``tests/test_accelerate.py``; the measurements behind them
are in the changelog of the documentation, ``docs/changelog.md``):

* ``nogil=True`` everywhere, so Dask worker threads can run kernels side by side.
* The grid kernels are cached on disk by default (``jit_kernel``): users rerun the CLI
  many times and a warm cache saves the compile time. Writing the cache from several
  processes at once can crash (numba#4807), so the runner compiles in the parent
  process before any worker starts, and ``SWEEP_NUMBA_CACHE=0`` turns caching off
  (e.g. on a shared, read-only install). Each variant's kernel has cache files of its
  own, so a command that needs several (``make figures``, ``sweep.compile_kernels`` of
  several configs) compiles them side by side in other processes that never write the
  same file (``dispatch.load_kernels``). The helpers the kernels call are not cached
  (``jit``): a cached grid kernel holds their compiled code, and numba checks a cache
  entry against its own file only, so a helper cached beside it could be stale after
  an edit to a file it calls. The grid kernel's cache key covers every kernel source
  instead (``kernels.integrate.grid_kernel``).
* ``fastmath=False``: runaway detection must see NaN and inf (``nnan``/``ninf``
  would let LLVM assume they never occur).
* ``error_model="numpy"``: a division by zero gives inf/NaN (a classified
  outcome), not a Python exception raised from inside a kernel running on a
  worker thread.
* ``no_cfunc_wrapper=True``: no kernel is passed as a first-class function, and the
  C wrapper numba builds for that by default cost 0.5 s of a cold compile. The
  CPython wrappers stay: tests and notebooks call the helpers from Python.
* One grid kernel per variant (model, state law, method, coupling, equal or unequal
  blocks, with or without the tangent for λ1): ``kernels.integrate.grid_kernel``
  closes over the codes and holds the loop itself, so numba prunes the other variants'
  branches before it inlines any helper and a run compiles only its own (tested); the
  kernel with the tangent is compiled only when a run needs λ1
  (``dispatch.integrate_grid``). The loop is not an inlined function of its own: numba
  copies an inlined body once per basic block together with its whole scope
  (numba#8989), which was 10 s of a 27 s cold compile. Specialising with
  ``numba.literally`` arguments instead compiled each combination as slowly as the
  whole kernel and made every call through the dispatcher slow.
* The right-hand side, the explicit steps (DOP853's too: 4 % per step, no measurable
  compile time) and the dense-output helpers are inlined into the integration loop at
  numba-IR level (``inline="always"``): left to LLVM, they stay calls passing a dozen
  arrays each. Every inlined copy costs compile time, so the Runge–Kutta stages are a
  loop around one call of the right-hand side.
* The grid kernel's loop calls small inlined helpers, each written without
  a loop or a non-inlined call behind a branch (``runaway_index``, ``update_cycle``).
  Where an inlined body has one, numba's reference-count pruning fails and every
  array argument is increfed and decrefed on every step; the same holds for a call
  inside a helper's loop over blocks, even behind a rare branch, which is why the
  dense-output functions that ``update_cycle`` calls are inlined too. Rare work (a
  crossing of the cap, recording, DOP853's interpolant) is a plain call in the
  loop's own branch, which costs nothing per step.
* Threads have one owner, and numba's own thread pool is not used: on one machine
  ``backends.LocalThreads`` runs the serial grid kernel (``nogil``) on Python threads
  that take small batches of systems as they come free; under Dask each task calls
  the same kernel and Dask owns the threads. A ``prange`` kernel compiled more slowly
  and split its loop into equal contiguous blocks, which needed a shuffle of the rows
  to share the costly runs near Kc between threads.
"""

import os

import numba

#: Whether compiled kernels are cached on disk (``SWEEP_NUMBA_CACHE=0`` disables).
CACHE = os.environ.get("SWEEP_NUMBA_CACHE", "1") != "0"

_COMMON = {"nogil": True, "fastmath": False, "error_model": "numpy", "no_cfunc_wrapper": True}


def jit_kernel(func):
    """Compile an entry point (a grid kernel) with the project's numba policy, cached
    on disk unless ``SWEEP_NUMBA_CACHE=0``."""
    return numba.njit(cache=CACHE, **_COMMON)(func)


def jit(func):
    """Compile a helper of the kernels with the project's numba policy (not cached:
    the kernel that calls it is)."""
    return numba.njit(cache=False, **_COMMON)(func)


def jit_inline(func):
    """Compile a small hot helper that numba inlines into every caller (not cached)."""
    return numba.njit(inline="always", cache=False, **_COMMON)(func)


def thread_count(n_threads):
    """Threads a run asks for: ``n_threads``, or when None all cores numba sees
    (``NUMBA_NUM_THREADS`` overrides, as for numba itself)."""
    return numba.config.NUMBA_NUM_THREADS if n_threads is None else int(n_threads)
