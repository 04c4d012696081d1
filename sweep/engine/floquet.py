"""Floquet multipliers of the periodic runs of a chunk, after its grid kernel.

The kernel ``kernels.monodromy`` carries every direction of the exact tangent once around
the cycle from each periodic run's final state; here the matrix's eigenvalues are sorted
into the trivial multiplier (along the flow, 1 on an exact cycle: the one nearest 1, its
distance from 1 the check of the matrix's accuracy) and the non-trivial ones,
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

#: Newton steps that put a run's final state on its cycle before the matrix is kept, and the
#: gap |y(T) − y0| / (1 + |y0|) below which none is taken (:func:`floquet_pass`).
NEWTON_STEPS = 3
CLOSURE = 1e-9
#: A first pass whose trivial multiplier is within this of 1 is kept without Newton
#: steps (one radiation-damped block: 2e-5 from 1 gave multipliers within 5e-5 of SciPy's).
TRIVIAL_TARGET = 1e-6
#: A trivial multiplier farther than this from 1 marks the matrix ``inaccurate``: its
#: modulus and argument are not given (measured elsewhere: 1e-9 to 1e-5).
TRIVIAL_TOLERANCE = 1e-2

_COLUMNS = slice(layout.R_FLOQUET_MODULUS, layout.R_FLOQUET_STATUS + 1)
_BUILD = threading.Lock()


def floquet_pass(params, settings, results, y_final):
    """Write the ``R_FLOQUET_*`` columns of every run of a chunk (kernels' arrays, rows of
    ``results`` and ``y_final`` filled by the grid kernel): the multipliers of the runs
    labelled periodic where ``settings[S_FLOQUET]`` asks, NaN and ``not_computed`` else.

    The run's final state lies on its cycle only to the classifier's accuracy (~1e-3), and
    in the stiff phases of a cycle the flow, and with it the matrix, changes fast off it
    (a quasi-static ring: a trivial multiplier 0.2-1 from 1). Where the first pass's trivial
    multiplier is farther than ``TRIVIAL_TARGET`` from 1, the start is put on the cycle by
    Newton's method for a periodic orbit (shooting with the matrix itself):
    (M − I) Δ + f δT = y0 − y(T), f · Δ = 0, up to ``NEWTON_STEPS`` times until it is
    within it or the gap |y(T) − y0| is below ``CLOSURE`` (1 + |y0|); the pass whose
    trivial multiplier is nearest 1 is kept."""
    results[:, _COLUMNS] = np.nan
    results[:, layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, "not_computed")
    rows = floquet_rows(settings, results, y_final.shape[1])
    if not rows.size:
        return
    from ..kernels.monodromy import M_OK, M_RETURN_TIME, M_STATUS

    kernel = monodromy_kernel(params, settings)
    starts = np.array(y_final[rows])
    periods = np.array(results[rows, layout.R_PERIOD])
    best = [None] * rows.size
    todo = np.arange(rows.size)
    for attempt in range(NEWTON_STEPS + 1):
        passes = _monodromy(
            kernel, params[rows[todo]], starts, todo, periods[todo], settings, attempt == 0
        )
        closer = []
        for r, (columns, log_scale, flow, end, info) in zip(todo, passes, strict=True):
            found = multipliers(columns, log_scale) if info[M_STATUS] == M_OK else None
            trivial = found[2] if found else np.inf
            if best[r] is None or trivial < best[r][0]:
                best[r] = (trivial, found, info)
            gap = np.linalg.norm(end - starts[r])
            closed = gap <= CLOSURE * (1.0 + np.linalg.norm(starts[r]))
            if trivial <= TRIVIAL_TARGET or closed or not np.isfinite(gap):
                continue
            step = _newton_step(columns, log_scale, flow, end - starts[r])
            if step is not None and attempt < NEWTON_STEPS:
                starts[r] += step
                periods[r] = info[M_RETURN_TIME]
                closer.append(r)
        todo = np.array(closer, int)
        if not todo.size:
            break
    for r, row in enumerate(rows):
        trivial, found, info = best[r]
        out = results[row]
        if found is None:
            why = "no_return" if info[M_STATUS] == 1 else "failed"
            out[layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, why)
            continue
        modulus, argument, trivial, resolved = found
        out[layout.R_FLOQUET_TRIVIAL] = trivial
        out[layout.R_RETURN_TIME] = info[M_RETURN_TIME]
        if trivial > TRIVIAL_TOLERANCE:
            out[layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, "inaccurate")
            continue
        out[layout.R_FLOQUET_MODULUS] = modulus
        out[layout.R_FLOQUET_ARGUMENT] = argument
        status = "ok" if resolved else "at_resolution"
        out[layout.R_FLOQUET_STATUS] = code(FLOQUET_STATUSES, status)


def _monodromy(kernel, params, starts, todo, periods, settings, advance):
    """One pass of the kernel over the rows ``todo`` of ``starts`` (updated in place where
    ``advance`` moves them to the section): per row (columns, log_scale, flow, y(T), info)."""
    m, n = todo.size, starts.shape[1]
    columns, log_scale = np.empty((m, n, n)), np.empty((m, n))
    flows, ends, info = np.empty((m, n)), np.empty((m, n)), np.empty((m, 3))
    section = np.ascontiguousarray(starts[todo])
    kernel(
        np.ascontiguousarray(params),
        section,
        np.ascontiguousarray(periods),
        np.ascontiguousarray(settings),
        advance,
        columns,
        log_scale,
        flows,
        ends,
        info,
    )
    starts[todo] = section
    return list(zip(columns, log_scale, flows, ends, info, strict=True))


def _newton_step(columns, log_scale, flow, gap):
    """The change Δ of the start that closes the orbit to first order: (M − I) Δ + f δT =
    −gap, f · Δ = 0; None where M overflows or the bordered matrix is singular."""
    n = flow.size
    with np.errstate(over="ignore"):
        matrix = columns.T * np.exp(log_scale)
    if not np.all(np.isfinite(matrix)):
        return None
    bordered = np.zeros((n + 1, n + 1))
    bordered[:n, :n] = matrix - np.eye(n)
    bordered[:n, n] = flow
    bordered[n, :n] = flow
    try:
        solution = np.linalg.solve(bordered, np.append(-gap, 0.0))
    except np.linalg.LinAlgError:
        return None
    return solution[:n] if np.all(np.isfinite(solution)) else None


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


def multipliers(columns, log_scale):
    """``(modulus, argument, trivial_error, resolved)`` of one monodromy matrix M, given as
    unit ``columns`` (n, n; row j is column j of M) with log scales ``log_scale`` (n,): the
    largest modulus of the non-trivial multipliers and its argument (rad), |μ − 1| of the
    trivial one, and whether that modulus lies above the eigenvalues' round-off n ε ‖M‖
    (else it is replaced by that floor).

    The trivial multiplier is the one nearest 1. Its eigenvector lies along the flow f(y0),
    but in an inertial stick (ln v/V ≈ −25) f is known far less well than M (ℓ' = z e^(−ℓ)/M̂
    moves by 1e10 per unit of z), and the eigenvector most nearly along it was a wrong one
    (measured: the pair of configs/route_to_chaos.yaml at K/W = 0.00465 µm⁻¹). Where a
    non-trivial multiplier is as near 1, the two are within their distance of each other,
    so the modulus given is 1 to that accuracy either way."""
    top = float(np.max(log_scale))
    scaled = columns.T * np.exp(log_scale - top)  # M / e^top, column by column
    values = np.linalg.eigvals(scaled) * np.exp(top)
    trivial = int(np.argmin(np.abs(values - 1.0)))
    others = np.delete(values, trivial)
    error = float(abs(values[trivial] - 1.0))
    if others.size == 0:
        return np.nan, np.nan, error, True
    floor = scaled.shape[0] * np.finfo(float).eps * np.linalg.norm(scaled, 2) * np.exp(top)
    largest = others[np.argmax(np.abs(others))]
    resolved = abs(largest) > floor
    argument = float(np.angle(largest)) if resolved else np.nan
    return float(max(abs(largest), floor)), argument, error, resolved
