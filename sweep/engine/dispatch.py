"""Which compiled kernel a run calls, and compiling it once, before the work starts.

``kernels.integrate.grid_kernel`` builds one serial grid kernel per variant (model, state law,
method, coupling, equal or unequal blocks, tangent, catalogue, state size); the kernels'
arrays say which variant a run is. The backends, the Dask tasks and traces all integrate
through :func:`integrate_grid`.
"""

import json
import logging
import os
import subprocess
import sys
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..kernels import layout
from .floquet import floquet_pass

log = logging.getLogger(__name__)


_BUILD = threading.Lock()

#: Largest state (values per system) whose kernel is compiled for its size, with its
#: scratch on the stack (``kernels/stack.py``): one to three blocks, or two inertial.
#: Each size is a variant of its own; larger systems share one kernel.
STACK_STATE_MAX = 6


def grid_kernel(params, settings, tangent=None):
    """The serial grid kernel (``kernels.integrate.grid_kernel``) of the variant that the
    kernels' arrays describe: model, state law, method and coupling from ``settings``,
    whether blocks differ from the width of ``params``, and whether it carries the
    tangent for λ1 (``tangent``; default: where every run asks for λ1 from its start,
    ``lyapunov: always``)."""
    from ..kernels.integrate import grid_kernel as build  # numba: on first use

    with _BUILD:  # one dispatcher per variant, also when threads ask at once
        return build(*variant(params, settings, tangent))


def variant(params, settings, tangent=None):
    """The arguments of ``kernels.integrate.grid_kernel`` for these arrays: model, law,
    method and coupling codes, unequal blocks, with the tangent (see :func:`grid_kernel`),
    with a catalogue of slip events (``S_CATALOGUE`` > 0: only such runs compile it) and
    the state size the kernel is compiled for (0: any; ``STACK_STATE_MAX``)."""
    if tangent is None:
        tangent = int(settings[layout.S_LYAPUNOV]) == layout.LYAP_ALWAYS
    codes = (layout.S_MODEL, layout.S_LAW, layout.S_METHOD, layout.S_COUPLING)
    heterogeneous = params.shape[1] > layout.N_PARAMS
    model = int(settings[layout.S_MODEL])
    n_state = layout.values_per_block(model) * int(settings[layout.S_NBLOCKS])
    n_fixed = n_state if n_state <= STACK_STATE_MAX else 0
    catalogue = int(settings[layout.S_CATALOGUE]) > 0
    return (*(int(settings[c]) for c in codes), heterogeneous, bool(tangent), catalogue, n_fixed)


def may_need_tangent(settings):
    """Whether a run with ``settings`` may hand runs to the kernel with the tangent: λ1
    of runs unsettled at t_end (``lyapunov: unsettled``) with early exit on."""
    return (
        int(settings[layout.S_LYAPUNOV]) == layout.LYAP_UNSETTLED
        and settings[layout.S_EARLY_EXIT] > 0.5
    )


def integrate_grid(params, y0, settings, results, y_final, rec_dt=0.0, rec_t=None, rec_y=None):
    """Integrate every row of the kernels' arrays in this thread, one after another.

    ``results``/``y_final`` are filled in place. A trace passes one row and
    recording buffers ``rec_t`` (m,) and ``rec_y`` (m, n_vars) for the state every
    ``rec_dt`` (D0/V); see ``kernels.integrate.grid_kernel``. Runs still
    unsettled at t_end that ask for λ1 there are redone by the kernel that carries
    the tangent, compiled the first time one needs it: a config whose runs all
    settle never compiles it. Once one has, later calls of the variant use that
    kernel for every run (:func:`tangent_first`). Then the Floquet multipliers of the
    periodic runs (``floquet.floquet_pass``; its kernel, too, compiled on first need).
    """
    if rec_t is None:
        rec_t, rec_y = np.empty(0), np.empty((0, y0.shape[1]))
    args = (settings, results, y_final, rec_dt, rec_t, rec_y)
    kernel = grid_kernel(params, settings)
    with_tangent = _TANGENT_FIRST.get(kernel)
    if with_tangent is not None:
        with_tangent(params, y0, *args)
    else:
        kernel(params, y0, *args)
        redo = np.flatnonzero(results[:, layout.R_REGIME] == layout.TANGENT_NEEDED)
        if redo.size:
            with_tangent = ready_kernel(params, settings, tangent=True)
            sub_results, sub_final = results[redo], y_final[redo]
            with_tangent(params[redo], y0[redo], settings, sub_results, sub_final, *args[3:])
            results[redo] = sub_results
            y_final[redo] = sub_final
            _TANGENT_FIRST[kernel] = with_tangent
    floquet_pass(params, settings, results, y_final)


#: Kernels without the tangent whose runs have needed it in this process, each with its
#: variant's compiled kernel with the tangent: later calls go straight to that one (the
#: same numbers, bit for bit, as a run redone; no run integrated twice).
_TANGENT_FIRST = {}


def tangent_first(params, settings):
    """Whether calls of this variant go straight to the kernel with the tangent (a run
    of it needed λ1 earlier in this process)."""
    return grid_kernel(params, settings) in _TANGENT_FIRST


def ready_kernel(params, settings, tangent=None):
    """:func:`grid_kernel`, compiled (or loaded from numba's cache) by a call on zero
    systems, not with ``kernel.compile(signature)``: numba files the two under
    different cache keys, and a process that had only called the kernel would leave
    Dask workers nothing to load (they then compile, and write the cache at once:
    numba#4807). Says "compiling kernels (first run only)" when this takes longer
    than a second: a compile (loading a warm cache takes well under a second, 0.7 s
    under load)."""
    kernel = grid_kernel(params, settings, tangent)
    notice = threading.Timer(1.0, log.info, ("compiling kernels (first run only) ...",))
    notice.start()
    try:
        with _COMPILE:
            kernel(
                np.empty((0, params.shape[1])),
                np.empty((0, 2)),
                np.ascontiguousarray(settings),
                np.empty((0, layout.result_width(settings))),
                np.empty((0, 2)),
                0.0,
                np.empty(0),
                np.empty((0, 2)),
            )
    finally:
        notice.cancel()
    return kernel


_COMPILE = threading.Lock()


def load_kernel(params, settings, every=False):
    """Compile (or load from numba's cache) the grid kernel of this run's variant, in
    this process, before any chunk runs, on Dask workers, or to warm the cache
    before job arrays. ``every``: also the kernel with the tangent where runs may
    need it (:func:`may_need_tangent`), so that processes which share a cache (Dask
    workers, job-array tasks) only read it; on threads in one process it is
    compiled when a run first needs it. Only the variants the run uses are compiled.
    """
    for job in kernel_jobs(params, settings, every):
        ready_kernel(*job)


def kernel_jobs(params, settings, every=False):
    """The (params, settings, tangent) jobs of :func:`ready_kernel` for one run's arrays:
    its variant, and with ``every`` also the kernel with the tangent where runs may
    need it (:func:`may_need_tangent`)."""
    jobs = [(params, settings, None)]
    if every and may_need_tangent(settings):
        jobs.append((params, settings, True))
    return jobs


def load_kernels(jobs, processes=None, here=True):
    """:func:`ready_kernel` for several variants: ``jobs`` are (params, settings,
    tangent) triples of the kernels' arrays (``tangent`` as for :func:`grid_kernel`).
    ``here=False``: only compile them into numba's cache, for other processes to load
    (nothing is loaded here unless another process failed).

    numba holds one lock over all compiling in a process, so the distinct variants
    this process has not compiled yet are compiled by up to ``processes`` fresh
    Python processes (default: one per core), which take them one at a time as they
    come free (:func:`compile_specs`): each takes a group of :func:`variant_groups`
    that no other has started and stays in it while it lasts, so the helpers
    specialised on a group's codes are compiled once; when no group is left to
    start, it helps with the variants left in the others. They write numba's cache,
    under its lock (``accelerate.SourceKeyedCache``); this process then loads them. With the cache
    off (``SWEEP_NUMBA_CACHE=0``), one variant to build or one process, they are
    compiled here one after another; if a process failed, what it left is compiled
    here (with a warning)."""
    from ..accelerate import CACHE, thread_count

    wanted = {}
    for params, settings, tangent in jobs:
        job = (params[:0], np.ascontiguousarray(settings), tangent)
        wanted.setdefault(variant(*job), job)
    todo = [job for job in wanted.values() if not grid_kernel(*job).signatures]
    processes = min(thread_count(processes), len(todo))
    elsewhere = CACHE and processes > 1
    if elsewhere:
        log.info("compiling (or loading) %d kernels in %d processes ...", len(todo), processes)
        groups = variant_groups(todo)
        with tempfile.TemporaryDirectory() as claims, ThreadPoolExecutor(processes) as pool:
            for failure in pool.map(_compile_elsewhere, [groups] * processes, [claims] * processes):
                if failure:
                    log.warning("compiling kernels in another process failed: %s", failure)
                    here = True
    if here or not elsewhere:
        for job in wanted.values():
            ready_kernel(*job)


def variant_groups(jobs):
    """``jobs`` of :func:`load_kernels` in groups of the variants that differ only in the
    tangent, the catalogue or the state size, largest first: the variants that call the
    same helpers specialised on their codes (model, law, method, coupling, equal blocks)."""
    groups = {}
    for job in jobs:
        groups.setdefault(variant(*job)[:5], []).append(job)
    return sorted(groups.values(), key=len, reverse=True)


def _compile_elsewhere(groups, claims):
    """Compile, in a fresh process, the kernels of the groups of (params, settings,
    tangent) jobs of :func:`load_kernels` that no other process has claimed
    (:func:`compile_specs`; claims are files in the folder ``claims``), writing numba's
    cache; returns None, or the end of its error output if it failed."""
    spec = compile_spec(groups, claims)
    env = dict(os.environ)
    package_root = str(Path(__file__).resolve().parents[1])  # this copy of sweep
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
    code = "import sys; from sweep.engine.dispatch import compile_specs; compile_specs(sys.argv[1])"
    proc = subprocess.run(
        [sys.executable, "-c", code, spec], env=env, capture_output=True, text=True
    )
    return None if proc.returncode == 0 else proc.stderr.strip()[-500:]


def compile_spec(groups, claims):
    """The JSON that :func:`compile_specs` reads: the groups of (params, settings, tangent)
    jobs (each job by its width, settings and tangent), the claims folder and this
    process (the one that waits for them)."""
    return json.dumps(
        {
            "claims": str(claims),
            "parent": os.getpid(),
            "groups": [
                [
                    {"width": params.shape[1], "settings": settings.tolist(), "tangent": tangent}
                    for params, settings, tangent in group
                ]
                for group in groups
            ],
        }
    )


def compile_specs(spec):
    """Compile in this process the kernels of the JSON ``spec`` (:func:`compile_spec`)
    that no other process has claimed: the other process's side of
    :func:`load_kernels`. First each group that no process has started (claim
    ``<group>``), its variants one at a time (claim ``<group>-<variant>``); then the
    variants still unclaimed in the groups that others started. A claim is a file
    created in the claims folder, by one process only (``O_EXCL``). A process whose
    parent has gone (killed: no one waits for its kernels) takes no further variant."""
    spec = json.loads(spec)
    groups, parent = spec["groups"], spec["parent"]

    def claim(name):
        if parent not in (os.getpid(), os.getppid()):
            return False
        try:
            os.close(os.open(os.path.join(spec["claims"], name), os.O_CREAT | os.O_EXCL))
        except FileExistsError:
            return False
        return True

    def take(g):
        for v, job in enumerate(groups[g]):
            if claim(f"{g}-{v}"):
                ready_kernel(np.empty((0, job["width"])), np.array(job["settings"]), job["tangent"])

    for g in range(len(groups)):  # a group of its own, when done with one, ...
        if claim(str(g)):
            take(g)
    for g in range(len(groups)):  # ... then what is left in the others'
        take(g)
