"""Which compiled kernel a run calls, and compiling it once, before the work starts.

``kernels.integrate.grid_kernel`` builds one serial grid kernel per variant (model, state law,
method, coupling, equal or unequal blocks); the kernels' arrays say which variant a
run is. The backends, the Dask tasks and traces all integrate through
:func:`integrate_grid`.
"""

import logging
import threading

import numpy as np

from .kernels import layout

log = logging.getLogger(__name__)


def grid_kernel(params, settings):
    """The serial grid kernel (``kernels.integrate.grid_kernel``) of the variant that the kernels'
    arrays describe: model, state law, method and coupling from ``settings``, and
    whether blocks differ from the width of ``params``."""
    from .kernels.integrate import grid_kernel as build  # numba: on first use

    codes = (layout.S_MODEL, layout.S_LAW, layout.S_METHOD, layout.S_COUPLING)
    heterogeneous = params.shape[1] > layout.N_PARAMS
    return build(*(int(settings[c]) for c in codes), heterogeneous)


def integrate_grid(params, y0, settings, results, y_final, rec_dt=0.0, rec_t=None, rec_y=None):
    """Integrate every row of the kernels' arrays in this thread, one after another.

    ``results``/``y_final`` are filled in place. A trace passes one row and
    recording buffers ``rec_t`` (m,) and ``rec_y`` (m, n_vars) for the state every
    ``rec_dt`` (D0/V); see ``kernels.integrate.integrate_system``.
    """
    if rec_t is None:
        rec_t, rec_y = np.empty(0), np.empty((0, y0.shape[1]))
    grid_kernel(params, settings)(params, y0, settings, results, y_final, rec_dt, rec_t, rec_y)


def load_kernel(params, settings):
    """Compile (or load from numba's cache) the grid kernel of this run's variant, in
    this process: before any chunk runs, on Dask workers, or to warm the cache before
    job arrays.

    It is compiled by a call on zero systems, not with ``kernel.compile(signature)``:
    numba files the two under different cache keys, and a process that had only
    called the kernel would leave Dask workers nothing to load (they then compile,
    and write the cache at once: numba#4807). Says "compiling kernels (first run
    only)" when this takes longer than a second (a cold cache; loading a warm one
    takes about a second). Only the variant the run uses is compiled.
    """
    notice = threading.Timer(1.0, log.info, ("compiling kernels (first run only) ...",))
    notice.start()
    try:
        integrate_grid(
            np.empty((0, params.shape[1])), np.empty((0, 2)), np.ascontiguousarray(settings),
            np.empty((0, layout.result_width(settings))), np.empty((0, 2)),
        )  # fmt: skip
    finally:
        notice.cancel()
