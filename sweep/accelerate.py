"""Numba policy: the one place where decorator arguments are decided.

Decisions (each tested in ``tests/test_accelerate.py``; the measurements behind them
are in the engineering notes of the documentation, ``docs/internals.md``):

* ``nogil=True`` everywhere, so Dask worker threads can run kernels side by side.
* The grid kernels and the helpers they call are cached on disk by default
  (``jit``, :class:`SourceKeyedCache`): users rerun the CLI many times and a warm
  cache saves the compile time, and a variant not compiled before (another model,
  law, method or coupling) loads the helpers it shares with those that were and
  compiles in 6–7 s instead of 13.5 (``docs/internals.md``). numba checks an entry
  against its own file only and a compiled function holds the code of everything it
  calls, so the key also covers every kernel source and this file: an edit anywhere
  compiles afresh (tested). numba's cache is not safe to write from several processes
  at once (numba#4807, #10128), so loading and saving hold a lock on the cache folder;
  a command that needs several variants (``make figures``, ``sweep.compile_kernels``
  of several configs) compiles them side by side in other processes
  (``dispatch.load_kernels``), and the runner compiles before any worker starts.
  ``SWEEP_NUMBA_CACHE=0`` turns caching off (e.g. on a shared, read-only install).
  Inlined helpers (``jit_inline``) are not cached: they are compiled into callers.
* ``fastmath=False``: runaway detection must see NaN and inf (``nnan``/``ninf``
  would let LLVM assume they never occur).
* ``error_model="numpy"``: a division by zero gives inf/NaN (a classified
  outcome), not a Python exception raised from inside a kernel running on a
  worker thread.
* ``no_cfunc_wrapper=True``: no kernel is passed as a first-class function, and the
  C wrapper numba builds for that by default cost 0.5 s of a cold compile.
* The helpers compiled on their own have no CPython wrapper either
  (``no_cpython_wrapper=True``): only the grid kernels are called from Python, and a
  wrapper cost about 50 ms of CPU per helper (``docs/internals.md``). A call of a
  helper from Python (tests, notebooks) goes through a small jitted shim that has one,
  built on the first such call (:class:`HelperDispatcher`); numba itself would jump
  through the missing wrapper.
* One grid kernel per variant (model, state law, method, coupling, equal or unequal
  blocks, with or without the tangent for λ1, and the state size of systems with at
  most ``dispatch.STACK_STATE_MAX`` values, whose scratch is then on the stack, where
  LLVM keeps it in registers: 1.1–1.4× per step, tested bit for bit against the
  kernel for any size; numba's heap arrays it cannot): ``kernels.integrate.grid_kernel``
  closes over the codes and holds the loop itself, so numba prunes the other variants'
  branches before it inlines any helper and a run compiles only its own (tested); the
  kernel with the tangent is compiled only when a run needs λ1
  (``dispatch.integrate_grid``), the catalogue of slip events only where runs keep one
  (a tenth of the default config's cold compile, ``docs/internals.md``). The loop is
  not an inlined function of its own: numba copies an inlined body once per basic
  block together with its whole scope (numba#8989), which was 10 s of a 27 s cold
  compile. Specialising with ``numba.literally`` arguments instead compiled each
  combination as slowly as the whole kernel and made every call through the dispatcher
  slow.
* The right-hand side, the explicit steps (DOP853's too: 4 % per step, no measurable
  compile time) and the dense-output helpers are inlined into the integration loop at
  numba-IR level (``inline="always"``): left to LLVM, they stay calls passing a dozen
  arrays each. Every inlined copy costs compile time, so the Runge–Kutta stages are a
  loop around one call of the right-hand side.
* The classifier's per-step update (``update_cycle``) is inlined by LLVM instead
  (``jit_forceinline``: numba's ``forceinline``, LLVM's ``alwaysinline``): compiled on
  its own, cached and shared by every variant, it no longer has its body
  and scope copied into the kernel by numba's inliner, and it runs as fast per step
  (measured with DOPRI5, DOP853 and RODAS4, heap and stack scratch). DOP853's step
  inlined that way was 2-3 % slower per step and compiled no faster, so it is not.
* Helpers are specialised on the variant's codes and on no other constant
  (:class:`VariantDispatcher`): numba compiles a copy of a function for every constant
  argument it is called with (``history_value`` eight times in one kernel).
  Together with the above, a cold compile of the default config takes 13.5 s instead
  of 16 and a further variant 6 s instead of 8 (``docs/internals.md``).
* The grid kernel's loop calls small inlined helpers, each written without
  a loop or a non-inlined call behind a branch (``runaway_index``, ``update_cycle``,
  ``classify_step``). Where an inlined body has one, numba's reference-count pruning
  fails and every array argument is increfed and decrefed on every step (numba#2350);
  the same holds for a call inside a helper's loop over blocks, even behind a rare
  branch, which is why the dense-output functions that ``update_cycle`` calls are
  inlined too. Rare work (a crossing of the cap, recording, DOP853's interpolant, the
  blocks' state at an event, the end of a slip event) is a plain call in the loop's
  own branch, which costs nothing per step. (``classify_step`` made the last two
  calls itself once: three increfs and decrefs every step, 2-3 % of a two-block step.)
* Thin wrappers with one caller are inlined at numba-IR level too, where that caller
  runs them outside the per-step path: the loop's work at an event (``new_event``), at
  ``tau_end`` (``at_tau_end``), before and after a run (``lyapunov_plan``,
  ``finish_run``), and a verdict's parts (``cycle_verdict`` and four more in
  ``classify/sequences.py``). numba compiles a helper as its own LLVM module and links
  into it, optimises and turns into machine code again everything it calls, so a
  wrapper compiled on its own cost about as much again as the helpers below it; its
  inlined copy is small (``docs/internals.md``). Inlined into the grid kernel, the
  tangent's branches of ``lyapunov_plan`` and ``at_tau_end`` are pruned with the
  kernel's own, so a kernel without the tangent no longer compiles its start.
* Threads have one owner, and numba's own thread pool is not used: on one machine
  ``backends.LocalThreads`` runs the serial grid kernel (``nogil``) on Python threads
  that take small batches of systems as they come free; under Dask each task calls
  the same kernel and Dask owns the threads. A ``prange`` kernel compiled more slowly
  and split its loop into equal contiguous blocks, which needed a shuffle of the rows
  to share the costly runs near Kc between threads.
"""

import contextlib
import fcntl
import functools
import hashlib
import inspect
import os
from pathlib import Path

import numba
from numba.core import types
from numba.core.caching import FunctionCache
from numba.core.registry import CPUDispatcher

#: Whether compiled kernels are cached on disk (``SWEEP_NUMBA_CACHE=0`` disables).
CACHE = os.environ.get("SWEEP_NUMBA_CACHE", "1") != "0"

_COMMON = {"nogil": True, "fastmath": False, "error_model": "numpy", "no_cfunc_wrapper": True}


#: The files outside ``sweep/kernels`` that compiled code depends on: this policy and
#: the code tables the kernels take as constants.
COMPILED_FROM = ("accelerate.py", "codes.py")


@functools.cache
def source_digest():
    """SHA-256 (hex) of the sources compiled code comes from: every file of
    ``sweep/kernels`` (its subpackages too) and :data:`COMPILED_FROM`, in path order."""
    here = Path(__file__).parent
    paths = [*(here / "kernels").rglob("*.py"), *(here / name for name in COMPILED_FROM)]
    digest = hashlib.sha256()
    for path in sorted(paths):
        digest.update(path.relative_to(here).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


class SourceKeyedCache(FunctionCache):
    """numba's on-disk cache of one function, keyed also on :func:`source_digest` and
    safe to share between processes.

    numba checks an entry against its own file only, and a compiled function holds
    the code of everything it calls: the digest in the key makes an edit to any kernel
    file compile afresh. numba numbers the data files of a function in its index, so
    two processes that save the same function at once can point one index at the
    other's data (numba#4807, #10128): loading and saving hold a lock on the cache
    folder (shared, exclusive), so processes that compile side by side
    (``dispatch.load_kernels``) or start on one install at once stay safe.
    """

    def _index_key(self, sig, codegen):
        return (*super()._index_key(sig, codegen), source_digest())

    @contextlib.contextmanager
    def _locked(self, mode):
        if not os.path.isdir(self._cache_path):  # nothing cached yet
            yield
            return
        try:
            lock = open(os.path.join(self._cache_path, "sweep-numba.lock"), "a")
        except OSError:  # a read-only cache: nothing is written to it
            yield
            return
        with lock:
            fcntl.flock(lock, mode)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def load_overload(self, sig, target_context):
        with self._locked(fcntl.LOCK_SH):
            return super().load_overload(sig, target_context)

    def save_overload(self, sig, data):
        self._impl.locator.ensure_cache_path()
        with self._locked(fcntl.LOCK_EX):
            super().save_overload(sig, data)


#: The parameters a helper is compiled for each constant value of, when a caller
#: passes a constant: the variant's codes, so each variant's helpers hold only its own
#: branches. Any other constant (a count, an index, a flag) is passed as a value of
#: its type, so the helper compiles once and every variant shares it.
VARIANT_CODES = frozenset({"model", "law", "method", "coupling", "het"})


class VariantDispatcher(CPUDispatcher):
    """numba's dispatcher, specialising a call from compiled code on the constants of
    :data:`VARIANT_CODES` only (numba would compile a copy for every constant
    argument: ``history_value`` eight times in one kernel). A helper that needs some
    other argument as a constant (``numba.literally``) must name it there."""

    def get_call_template(self, args, kws):
        pysig, args = self._compiler.fold_argument_types(args, kws)
        names = list(pysig.parameters)
        args = tuple(
            a if name in VARIANT_CODES else types.unliteral(a)
            for name, a in zip(names, args, strict=True)
        )
        return super().get_call_template(args, {})


class HelperDispatcher(VariantDispatcher):
    """:class:`VariantDispatcher` of a helper compiled without a CPython wrapper (numba's
    ``no_cpython_wrapper``): compiled code calls it directly, and a call from Python
    (tests, notebooks) goes through a small jitted shim that has one, built on the
    first such call (:func:`python_entry`). numba would jump through a null wrapper
    otherwise (a segmentation fault)."""

    def __call__(self, *args, **kws):
        entry = self.__dict__.get("_python_entry")
        if entry is None:
            entry = self._python_entry = python_entry(self)
        return entry(*args, **kws)


def python_entry(helper):
    """A jitted function of ``helper``'s parameters that returns ``helper(...)``, with a
    CPython wrapper: how Python calls a helper compiled without one. Not cached on
    disk (it has no source file); the helper it calls is."""
    names = ", ".join(inspect.signature(helper.py_func).parameters)
    namespace = {"helper": helper}
    exec(f"def call({names}):\n    return helper({names})\n", namespace)
    call = namespace["call"]
    call.__qualname__ = f"{helper.py_func.__qualname__}_from_python"
    return numba.njit(**_COMMON)(call)


def _compiled(func, kind=VariantDispatcher, **options):
    """``func`` compiled with the project's policy and ``options`` (a ``kind`` of
    :class:`VariantDispatcher`, cached by :class:`SourceKeyedCache` unless
    ``SWEEP_NUMBA_CACHE=0``); the plain function under ``NUMBA_DISABLE_JIT=1``."""
    if numba.config.DISABLE_JIT:
        return func
    dispatcher = kind(func, targetoptions={"nopython": True, **_COMMON, **options})
    if CACHE:
        dispatcher._cache = SourceKeyedCache(func)
    return dispatcher


def _helper(func, **options):
    """``func`` compiled as a helper of the kernels: no CPython wrapper
    (:class:`HelperDispatcher`)."""
    return _compiled(func, HelperDispatcher, no_cpython_wrapper=True, **options)


def jit(func):
    """Compile a helper of the kernels with the project's numba policy, cached on disk:
    a further variant loads the helpers it shares with one compiled before. Without a
    CPython wrapper (:class:`HelperDispatcher`). ``forceinline=False`` is explicit
    because numba otherwise passes the option on from the caller being compiled (a
    helper first called from ``update_cycle`` would be inlined everywhere)."""
    return _helper(func, forceinline=False)


def jit_variant(func, *codes):
    """Compile a grid kernel, a function built per variant, named after its ``codes``
    (``_c1_c2…`` appended): the disk cache keys on the name, so each variant's cache
    files are its own. Python calls it: it keeps its CPython wrapper."""
    func.__qualname__ += "".join(f"_{int(c)}" for c in codes)
    return _compiled(func, forceinline=False)


def jit_inline(func):
    """Compile a small hot helper that numba inlines into every caller (not cached:
    it is compiled into them, never on its own but for a call from Python)."""
    return numba.njit(inline="always", **_COMMON)(func)


def jit_forceinline(func):
    """Compile a large hot helper on its own (cached, shared by the variants with its
    codes) and have LLVM inline it into every caller: as fast as :func:`jit_inline`,
    without numba copying its body and scope into the caller. Without a CPython
    wrapper, as :func:`jit`."""
    return _helper(func, forceinline=True)


def thread_count(n_threads):
    """Threads a run asks for: ``n_threads``, or when None all cores numba sees
    (``NUMBA_NUM_THREADS`` overrides, as for numba itself)."""
    return numba.config.NUMBA_NUM_THREADS if n_threads is None else int(n_threads)
