"""Floquet multipliers of the periodic runs of a chunk, after its grid kernel.

The kernel ``kernels.monodromy`` carries every direction of the exact tangent once around
the cycle from each periodic run's final state; here the matrix's eigenvalues are sorted
into the trivial multiplier (the one whose eigenvector lies along the flow, 1 on an exact
cycle: its distance from 1 is the check of the matrix's accuracy) and the non-trivial ones,
of which the largest modulus, its argument and the return time are written into the run's
``R_FLOQUET_*`` columns. Runs not labelled periodic, and all runs where
``classification.floquet`` does not ask, get NaN and ``not_computed``.

The matrix is formed column by column with each column's log scale apart; its eigenvalues
are accurate to about n ε ‖M‖ (a backward-stable eigensolver): a largest non-trivial
modulus below that floor is reported as the floor (``at_resolution``), an upper bound.
"""

import threading

import numpy as np

from ..codes import FLOQUET_STATUSES, code
from ..kernels import layout

#: ``classification.floquet: auto`` computes the multipliers of systems of at most this
#: many state values: the pass costs about (n + 1) periods of a run, a small share of runs
#: that take tens of periods to settle.
AUTO_STATE_MAX = 16

_COLUMNS = slice(layout.R_FLOQUET_MODULUS, layout.R_FLOQUET_STATUS + 1)
_BUILD = threading.Lock()


def floquet_pass(params, settings, results, y_final):
    """Write the ``R_FLOQUET_*`` columns of every run of a chunk (kernels' arrays, rows of
    ``results`` and ``y_final`` filled by the grid kernel): the multipliers of the runs
    labelled periodic where ``settings[S_FLOQUET]`` asks, NaN and ``not_computed`` else."""
    results[:, _COLUMNS] = np.nan
    results[:, layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, "not_computed")
    rows = floquet_rows(settings, results, y_final.shape[1])
    if not rows.size:
        return
    n = y_final.shape[1]
    columns = np.empty((rows.size, n, n))
    log_scale = np.empty((rows.size, n))
    flows = np.empty((rows.size, n))
    info = np.empty((rows.size, 3))
    kernel = monodromy_kernel(params, settings)
    kernel(
        np.ascontiguousarray(params[rows]),
        np.ascontiguousarray(y_final[rows]),
        np.ascontiguousarray(results[rows, layout.R_PERIOD]),
        np.ascontiguousarray(settings),
        columns,
        log_scale,
        flows,
        info,
    )
    from ..kernels.monodromy import M_OK, M_RETURN_TIME, M_STATUS

    for r, row in enumerate(rows):
        out = results[row]
        if info[r, M_STATUS] != M_OK:
            why = "no_return" if info[r, M_STATUS] == 1 else "failed"
            out[layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, why)
            continue
        modulus, argument, trivial, resolved = multipliers(columns[r], log_scale[r], flows[r])
        out[layout.R_FLOQUET_MODULUS] = modulus
        out[layout.R_FLOQUET_ARGUMENT] = argument
        out[layout.R_FLOQUET_TRIVIAL] = trivial
        out[layout.R_RETURN_TIME] = info[r, M_RETURN_TIME]
        status = "ok" if resolved else "at_resolution"
        out[layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, status)


def floquet_rows(settings, results, n_state):
    """Rows of a chunk whose multipliers ``settings[S_FLOQUET]`` asks for: runs labelled
    periodic with a period, of every size (``always``) or of at most ``AUTO_STATE_MAX``
    state values (``auto``)."""
    mode = int(settings[layout.S_FLOQUET])
    if mode == layout.FLOQUET_NEVER or (mode == layout.FLOQUET_AUTO and n_state > AUTO_STATE_MAX):
        return np.empty(0, int)
    period = results[:, layout.R_PERIOD]
    periodic = results[:, layout.R_ATTRACTOR] == layout.PERIODIC
    with np.errstate(invalid="ignore"):
        return np.flatnonzero(periodic & (period > 0.0) & np.isfinite(period))


def monodromy_kernel(params, settings):
    """The compiled ``kernels.monodromy`` kernel of this run's variant (model, law, method,
    coupling, equal or unequal blocks; ``dispatch.variant``)."""
    from ..kernels.monodromy import monodromy_kernel as build  # numba: on first use
    from .dispatch import variant

    with _BUILD:
        return build(*variant(params, settings)[:5])


def multipliers(columns, log_scale, flow):
    """``(modulus, argument, trivial_error, resolved)`` of one monodromy matrix M, given as
    unit ``columns`` (n, n; row j is column j of M) with log scales ``log_scale`` (n,), and
    the flow f(y0) (n,) at its start: the largest modulus of the non-trivial multipliers and
    its argument (rad), |μ − 1| of the trivial one (eigenvector most nearly along f(y0)),
    and whether that modulus lies above the eigenvalues' round-off n ε ‖M‖ (else it is
    replaced by that floor)."""
    top = float(np.max(log_scale))
    scaled = columns.T * np.exp(log_scale - top)  # M / e^top, column by column
    values, vectors = np.linalg.eig(scaled)
    along = np.abs(vectors.conj().T @ flow) / (np.linalg.norm(flow) or 1.0)
    trivial = int(np.argmax(along))
    others = np.delete(values, trivial)
    floor = scaled.shape[0] * np.finfo(float).eps * np.linalg.norm(scaled, 2)
    if others.size == 0:
        return np.nan, np.nan, abs(values[trivial] * np.exp(top) - 1.0), True
    largest = others[np.argmax(np.abs(others))]
    resolved = abs(largest) > floor
    log_modulus = np.log(max(abs(largest), floor)) + top
    argument = float(np.angle(largest)) if resolved else np.nan
    return (
        float(np.exp(log_modulus)),
        argument,
        float(abs(values[trivial] * np.exp(top) - 1.0)),
        resolved,
    )
