"""The catalogue of slip events of a run, written as the run goes.

An event lasts while any block slips: it begins where the first block's ℓ_i rises
through the threshold (``S_CATALOGUE_LNV``: ln of ``catalogue.slip_v_over_V``) and ends
where the last one's falls through it, both located on the step's interpolant
(``step.dense_crossing``); like the classifier's slip events, it is seen where some
block is above the threshold at the end of a step. A block slipped in it if its ℓ_i
exceeded the threshold at a step's end or at a maximum of its interpolant. Each block's
slip ∫ v_i/V dτ (in D0) is integrated over the event from the interpolant by
Gauss–Legendre quadrature (four nodes per step, exact for polynomials of degree 7), so
it is part of the solution, not reconstructed afterwards; the event's slip is the sum
over the blocks that slipped. An event still going when the run ends is not kept.

A run's catalogue is a block of its results row (``layout.catalogue_start``): the
number of events that began after ``S_CATALOGUE_AFTER`` × tau_end, then the first
``S_CATALOGUE`` of them, ``N_EVENT_FIELDS`` columns each (``E_*``), NaN where none.
"""

import math

import numpy as np

from ..accelerate import jit, jit_inline
from .layout import (
    ALL,
    CHAIN,
    E_BLOCK_HI,
    E_BLOCK_LO,
    E_EXTENT,
    E_FIRST_BLOCK,
    E_LNV_PEAK,
    E_N_BLOCKS,
    E_SLIP,
    E_T_END,
    E_T_START,
    N_EVENT_FIELDS,
    N_RESULTS,
    S_CATALOGUE,
    S_CATALOGUE_AFTER,
    S_CATALOGUE_LNV,
    S_EVENTS,
)
from .step import dense_crossing, dense_extremum, dense_tail, dense_value

# The catalogue's running state (``catalogue_arrays``): whether an event is going on,
# when it began, its first block, its largest ℓ so far, the time before which none is
# kept (D0/V), the events a run keeps, the column of its count in the results row and
# the threshold of ℓ above which a block slips.
K_ACTIVE, K_T_START, K_FIRST, K_PEAK, K_AFTER, K_CAPACITY, K_START, K_LNV = range(8)

# Gauss–Legendre nodes and weights on [0, 1], four points.
_GL_X = np.array([0.06943184420297371, 0.33000947820757187, 0.6699905217924281, 0.9305681557970263])
_GL_W = np.array([0.17392742256872692, 0.3260725774312731, 0.3260725774312731, 0.17392742256872692])


@jit
def catalogue_arrays(out, settings, nb, tau_end):
    """The running state (``K_*``) and per-block scratch (row 0: slip since the event
    began, D0; row 1: 1 where the block slipped) of a run of ``settings`` (``S_*``) up to
    ``tau_end``; its catalogue in its results row ``out`` is cleared (count 0, NaN)."""
    capacity, start = int(settings[S_CATALOGUE]), N_RESULTS + 2 * int(settings[S_EVENTS])
    state = np.zeros(8)
    state[K_AFTER] = settings[S_CATALOGUE_AFTER] * tau_end
    state[K_LNV] = settings[S_CATALOGUE_LNV]
    state[K_CAPACITY], state[K_START] = capacity, start
    if capacity > 0:
        out[start] = 0.0
        out[start + 1 : start + 1 + capacity * N_EVENT_FIELDS] = np.nan
    return state, np.zeros((2, nb))


@jit_inline
def any_above(ynew, nb, slip_lnv):
    """Whether some block's ℓ_i is above ``slip_lnv`` after the step."""
    above = False
    for i in range(nb):
        above = above or ynew[i] > slip_lnv
    return above


@jit
def catalogue_reads(state, ynew, nb):
    """Whether :func:`catalogue_step` reads the interpolant of this step: an event is
    going on, or some block is above the threshold after it."""
    return state[K_ACTIVE] > 0.0 or any_above(ynew, nb, state[K_LNV])


@jit
def _falling(s, i, h, level):
    """Fraction of step ``s`` where ℓ_i falls through ``level`` (y_i > level ≥ ynew_i)."""
    r = dense_tail(s, i)
    return dense_crossing(
        -s.y[i], -s.ynew[i], -s.f[i], -s.fnew[i], h, (-r[0], -r[1], -r[2], -r[3]), -level
    )


@jit
def _edge(s, h, nb, slip_lnv, starting):
    """``(theta, block)``: where in step ``s`` the event begins (``starting``: the earliest
    rise through the threshold of a block above it after the step; 0 for one above it
    already) or ends (the latest fall of a block above it before the step)."""
    y, ynew = s.y, s.ynew
    theta, block = (1.0, -1) if starting else (0.0, -1)
    for i in range(nb):
        if starting and ynew[i] > slip_lnv:
            th = (
                0.0
                if y[i] > slip_lnv
                else dense_crossing(y[i], ynew[i], s.f[i], s.fnew[i], h, dense_tail(s, i), slip_lnv)
            )
            if block < 0 or th < theta:
                theta, block = th, i
        elif not starting and y[i] > slip_lnv:
            th = _falling(s, i, h, slip_lnv)
            if th > theta:
                theta, block = th, i
    return theta, block


@jit
def _fold_step(s, h, nb, slip_lnv, th0, th1, state, blocks):
    """Add each block's slip over the fraction [th0, th1] of step ``s`` to ``blocks[0]``,
    mark the blocks above the threshold (``blocks[1]``) and keep the largest ℓ."""
    y, ynew, f, fnew = s.y, s.ynew, s.f, s.fnew
    span = (th1 - th0) * h
    peak = state[K_PEAK]
    for i in range(nb):
        r = dense_tail(s, i)
        acc = 0.0
        for q in range(4):
            acc += _GL_W[q] * math.exp(
                dense_value(y[i], ynew[i], f[i], fnew[i], h, r, th0 + (th1 - th0) * _GL_X[q])
            )
        blocks[0, i] += acc * span
        top = max(
            dense_value(y[i], ynew[i], f[i], fnew[i], h, r, th0),
            dense_value(y[i], ynew[i], f[i], fnew[i], h, r, th1),
        )
        if f[i] > 0.0 and fnew[i] <= 0.0:  # a maximum inside the step
            theta = dense_extremum(y[i], ynew[i], f[i], fnew[i], h, r)
            if th0 <= theta <= th1:
                top = max(top, dense_value(y[i], ynew[i], f[i], fnew[i], h, r, theta))
        peak = max(peak, top)
        if top > slip_lnv:
            blocks[1, i] = 1.0
    state[K_PEAK] = peak


@jit
def _extent(blocks, nb, coupling, lo, hi, count):
    """Blocks spanned by those that slipped: from the lowest to the highest along a
    chain, the shortest arc holding them on a ring (``nb`` less the longest run of
    blocks that did not slip), their number where every pair is coupled."""
    if coupling == CHAIN:
        return hi - lo + 1
    if coupling == ALL:
        return count
    gap = 0
    run = 0
    for k in range(2 * nb):  # twice round: a run of still blocks may wrap
        if blocks[1, k % nb] > 0.0:
            run = 0
        else:
            run = min(run + 1, nb)
            gap = max(gap, run)
    return nb - gap


@jit
def _close(t_end, state, blocks, nb, coupling, out):
    """Count the event that ended at ``t_end`` and keep it if it began after the
    transient and the catalogue has room."""
    if state[K_T_START] < state[K_AFTER]:
        return
    start, capacity = int(state[K_START]), int(state[K_CAPACITY])
    k = int(out[start])
    out[start] = k + 1.0
    if k >= capacity:
        return
    count, lo, hi, slip = 0, nb, -1, 0.0
    for i in range(nb):
        if blocks[1, i] > 0.0:
            count += 1
            lo, hi = min(lo, i), max(hi, i)
            slip += blocks[0, i]
    e = out[start + 1 + k * N_EVENT_FIELDS : start + 1 + (k + 1) * N_EVENT_FIELDS]
    e[E_T_START], e[E_T_END], e[E_FIRST_BLOCK] = state[K_T_START], t_end, state[K_FIRST]
    e[E_N_BLOCKS], e[E_BLOCK_LO], e[E_BLOCK_HI] = count, lo, hi
    e[E_EXTENT] = _extent(blocks, nb, coupling, lo, hi, count)
    e[E_SLIP], e[E_LNV_PEAK] = slip, state[K_PEAK]


@jit
def catalogue_step(s, t, h, nb, coupling, state, blocks, out):
    """Fold the accepted step ``s`` (``step.Step``) from ``t`` to ``t + h`` into the
    catalogue in the results row ``out`` (module docstring): an event may begin, go on
    or end in it."""
    slip_lnv = state[K_LNV]
    above = any_above(s.ynew, nb, slip_lnv)
    if state[K_ACTIVE] == 0.0 and not above:  # catalogue_reads: nothing to read
        return
    th0, th1 = 0.0, 1.0
    if state[K_ACTIVE] == 0.0:
        th0, first = _edge(s, h, nb, slip_lnv, True)
        state[K_ACTIVE], state[K_T_START], state[K_FIRST] = 1.0, t + th0 * h, first
        state[K_PEAK] = -np.inf
        blocks[:, :] = 0.0
    elif not above:
        th1 = _edge(s, h, nb, slip_lnv, False)[0]
    _fold_step(s, h, nb, slip_lnv, th0, th1, state, blocks)
    if not above:
        state[K_ACTIVE] = 0.0
        _close(t + th1 * h, state, blocks, nb, coupling, out)
