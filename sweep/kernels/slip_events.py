"""The catalogue of slip events of a run, written as the run goes.

A block slips while its ℓ_i = ln(v_i/V) is above the threshold (``S_CATALOGUE_LNV``: ln of
``catalogue.slip_v_over_V``): from its rise through it to its fall, both located on the
step's interpolant (``step.dense_crossing``); an episode is seen where the block is above
the threshold at the end of a step (a rise and fall inside one step is not). An event is a
connected rupture, the convention of spring-block chains (Carlson & Langer 1989; Kawamura
et al. 2012, Rev. Mod. Phys. 84, 839): the blocks whose episodes overlap in time and are
adjacent along the chain (ring: along the ring), from the first block's rise to the last
one's fall. A block that rises while a neighbour slips joins the neighbour's event, one
that rises with no neighbour slipping begins a new one, and two events that a rising block
joins merge: the one that began first keeps its identity (start time and first block, the
rupture's hypocentre), the other's blocks and slip join it. Two ruptures apart along the
chain at the same time are two events. All-to-all coupling has no space: every pair of
blocks is adjacent, so there an event is the window while any block slips.

Each block's slip ∫ v_i/V dτ (in D0) counts in an event only during its episodes in it,
integrated from the interpolant by Gauss–Legendre quadrature (four nodes per step, exact
for polynomials of degree 7), so it is part of the solution, not reconstructed afterwards;
the event's slip is their sum. An event still going when the run ends is not kept.

A run's catalogue is a block of its results row (``layout.catalogue_start``): the number
of events that began after ``S_CATALOGUE_AFTER`` × tau_end, then the first
``S_CATALOGUE`` of them to end, ``N_EVENT_FIELDS`` columns each (``E_*``), NaN where none.
"""

import math

import numpy as np

from ..accelerate import jit, jit_inline
from .layout import (
    ALL,
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
    RING,
    S_CATALOGUE,
    S_CATALOGUE_AFTER,
    S_CATALOGUE_LNV,
    S_EVENTS,
)
from .step import dense_crossing, dense_extremum, dense_tail, dense_value

# The catalogue's running state (``catalogue_arrays``): the number of blocks slipping,
# the time before which no event is kept (D0/V), the events a run keeps, the column of
# its count in the results row, the threshold of ℓ and the next event's serial number.
K_ACTIVE, K_AFTER, K_CAPACITY, K_START, K_LNV, K_SERIAL = range(6)

# Rows of the work array, per block: the slot of the event it slips in (−1: none), this
# step's crossing (θ, +1 rise / −1 fall) and the θ from which its slip in this step
# counts; per slot of an event going on:
# whether it is in use, its serial, start (D0/V), first block, blocks slipping in it,
# slip (D0) and largest ℓ. An event's blocks are a slot's row of the membership array.
B_SLOT, B_THETA, B_KIND, B_FROM = range(4)
C_USED, C_SERIAL, C_T_START, C_FIRST, C_SLIPPING, C_SLIP, C_PEAK = range(4, 11)
N_WORK_ROWS = 11

# Gauss–Legendre nodes and weights on [0, 1], four points.
_GL_X = np.array([0.06943184420297371, 0.33000947820757187, 0.6699905217924281, 0.9305681557970263])
_GL_W = np.array([0.17392742256872692, 0.3260725774312731, 0.3260725774312731, 0.17392742256872692])


@jit
def catalogue_arrays(out, settings, nb, tau_end):
    """The running state (``K_*``) and the scratch ``(work, member)`` (``B_*``/``C_*``
    rows of ``nb`` columns; ``member[c, i]``: block i belongs to the event in slot c) of a
    run of ``settings`` (``S_*``) up to ``tau_end``; its catalogue in its results row
    ``out`` is cleared (count 0, NaN)."""
    capacity, start = int(settings[S_CATALOGUE]), N_RESULTS + 2 * int(settings[S_EVENTS])
    state = np.zeros(6)
    state[K_AFTER] = settings[S_CATALOGUE_AFTER] * tau_end
    state[K_LNV] = settings[S_CATALOGUE_LNV]
    state[K_CAPACITY], state[K_START] = capacity, start
    if capacity > 0:
        out[start] = 0.0
        out[start + 1 : start + 1 + capacity * N_EVENT_FIELDS] = np.nan
    work = np.zeros((N_WORK_ROWS, nb))
    work[B_SLOT, :] = -1.0
    return state, (work, np.zeros((nb, nb), np.uint8))


@jit_inline
def any_above(ynew, nb, slip_lnv):
    """Whether some block's ℓ_i is above ``slip_lnv`` after the step."""
    above = False
    for i in range(nb):
        above = above or ynew[i] > slip_lnv
    return above


@jit
def catalogue_reads(state, ynew, nb):
    """Whether :func:`catalogue_step` reads the interpolant of this step: some block
    slips, or is above the threshold after it."""
    return state[K_ACTIVE] > 0.0 or any_above(ynew, nb, state[K_LNV])


@jit
def _fold_block(s, h, i, th0, th1, work, c):
    """Add block ``i``'s slip over the fraction [th0, th1] of step ``s`` to the event in
    slot ``c`` and keep its largest ℓ there."""
    y0, y1, d0, d1 = s.y[i], s.ynew[i], s.f[i], s.fnew[i]
    r = dense_tail(s, i)
    acc = 0.0
    for q in range(4):
        acc += _GL_W[q] * math.exp(dense_value(y0, y1, d0, d1, h, r, th0 + (th1 - th0) * _GL_X[q]))
    work[C_SLIP, c] += acc * (th1 - th0) * h
    top = max(dense_value(y0, y1, d0, d1, h, r, th0), dense_value(y0, y1, d0, d1, h, r, th1))
    if d0 > 0.0 and d1 <= 0.0:  # a maximum inside the step
        theta = dense_extremum(y0, y1, d0, d1, h, r)
        if th0 <= theta <= th1:
            top = max(top, dense_value(y0, y1, d0, d1, h, r, theta))
    work[C_PEAK, c] = max(work[C_PEAK, c], top)


@jit
def _crossings(s, h, nb, slip_lnv, work):
    """Mark each block's crossing of the threshold in step ``s`` (``B_KIND``, ``B_THETA``):
    a rise of a block not slipping that is above it after the step (θ = 0 if above it
    already), a fall of a slipping one below it after the step. Returns their number."""
    n = 0
    for i in range(nb):
        work[B_KIND, i] = 0.0
        slipping = work[B_SLOT, i] >= 0.0
        y0, y1 = s.y[i], s.ynew[i]
        if not slipping and y1 > slip_lnv:
            work[B_KIND, i] = 1.0
            work[B_THETA, i] = (
                0.0
                if y0 > slip_lnv
                else dense_crossing(y0, y1, s.f[i], s.fnew[i], h, dense_tail(s, i), slip_lnv)
            )
        elif slipping and y1 <= slip_lnv:
            r = dense_tail(s, i)
            work[B_KIND, i] = -1.0
            work[B_THETA, i] = dense_crossing(
                -y0, -y1, -s.f[i], -s.fnew[i], h, (-r[0], -r[1], -r[2], -r[3]), -slip_lnv
            )
        if work[B_KIND, i] != 0.0:
            n += 1
    return n


@jit
def _next_crossing(nb, work):
    """The block of the earliest crossing not handled yet (a rise first at equal θ)."""
    best = -1
    for i in range(nb):
        kind = work[B_KIND, i]
        if kind != 0.0 and (
            best < 0
            or work[B_THETA, i] < work[B_THETA, best]
            or (work[B_THETA, i] == work[B_THETA, best] and kind > work[B_KIND, best])
        ):
            best = i
    return best


@jit
def _merge(a, b, nb, work, member):
    """Merge the events in slots ``a`` and ``b``; the one that began first keeps its
    identity. Returns the slot kept."""
    tb, ta = work[C_T_START, b], work[C_T_START, a]
    if tb < ta or (tb == ta and work[C_SERIAL, b] < work[C_SERIAL, a]):
        a, b = b, a
    work[C_SLIP, a] += work[C_SLIP, b]
    work[C_PEAK, a] = max(work[C_PEAK, a], work[C_PEAK, b])
    work[C_SLIPPING, a] += work[C_SLIPPING, b]
    for i in range(nb):
        if work[B_SLOT, i] == b:
            work[B_SLOT, i] = a
        member[a, i] |= member[b, i]
        member[b, i] = 0
    work[C_USED, b] = 0.0
    return a


@jit
def _join(i, t, nb, coupling, state, work, member):
    """Block ``i`` rises through the threshold at ``t``: it joins the event of a slipping
    neighbour (merging two), or begins one."""
    c = -1
    for j in range(nb):
        if j == i or work[B_SLOT, j] < 0.0:
            continue
        d = abs(i - j)
        if coupling == ALL or d == 1 or (coupling == RING and d == nb - 1):
            slot = int(work[B_SLOT, j])
            c = slot if c < 0 or c == slot else _merge(c, slot, nb, work, member)
    if c < 0:
        c = 0
        while work[C_USED, c] > 0.0:
            c += 1
        work[C_USED, c], work[C_SERIAL, c] = 1.0, state[K_SERIAL]
        state[K_SERIAL] += 1.0
        work[C_T_START, c], work[C_FIRST, c] = t, i
        work[C_SLIPPING, c], work[C_SLIP, c], work[C_PEAK, c] = 0.0, 0.0, -np.inf
    work[B_SLOT, i] = c
    work[C_SLIPPING, c] += 1.0
    member[c, i] = 1
    state[K_ACTIVE] += 1.0


@jit
def _close(c, t_end, nb, coupling, state, work, member, out):
    """Count the event in slot ``c`` that ended at ``t_end``, keep it if it began after
    the transient and the catalogue has room, and free its slot."""
    work[C_USED, c] = 0.0
    count, lo, hi = 0, nb, -1
    for i in range(nb):
        if member[c, i]:
            count += 1
            lo, hi = min(lo, i), max(hi, i)
    if coupling == RING and 0 < count < nb:  # the arc's first block, going up the ring
        for i in range(nb):
            if member[c, i] and not member[c, (i - 1) % nb]:
                lo, hi = i, (i + count - 1) % nb
    member[c, :] = 0
    if work[C_T_START, c] < state[K_AFTER]:
        return
    start, capacity = int(state[K_START]), int(state[K_CAPACITY])
    k = int(out[start])
    out[start] = k + 1.0
    if k >= capacity:
        return
    e = out[start + 1 + k * N_EVENT_FIELDS : start + 1 + (k + 1) * N_EVENT_FIELDS]
    e[E_T_START], e[E_T_END], e[E_FIRST_BLOCK] = work[C_T_START, c], t_end, work[C_FIRST, c]
    e[E_N_BLOCKS], e[E_BLOCK_LO], e[E_BLOCK_HI] = count, lo, hi
    e[E_EXTENT] = count if coupling == ALL else (hi - lo) % nb + 1
    e[E_SLIP], e[E_LNV_PEAK] = work[C_SLIP, c], work[C_PEAK, c]


@jit
def catalogue_step(s, t, h, nb, coupling, state, scratch, out):
    """Fold the accepted step ``s`` (``step.Step``) from ``t`` to ``t + h`` into the
    catalogue in the results row ``out`` (module docstring): blocks rise and fall through
    the threshold in the order of their crossings, events begin, merge and end."""
    work, member = scratch
    if not catalogue_reads(state, s.ynew, nb):
        return
    for _ in range(_crossings(s, h, nb, state[K_LNV], work)):
        i = _next_crossing(nb, work)
        theta = work[B_THETA, i]
        if work[B_KIND, i] > 0.0:
            _join(i, t + theta * h, nb, coupling, state, work, member)
            work[B_FROM, i] = theta
        else:
            c = int(work[B_SLOT, i])
            _fold_block(s, h, i, work[B_FROM, i], theta, work, c)
            work[B_SLOT, i] = -1.0
            work[C_SLIPPING, c] -= 1.0
            state[K_ACTIVE] -= 1.0
            if work[C_SLIPPING, c] == 0.0:
                _close(c, t + theta * h, nb, coupling, state, work, member, out)
        work[B_KIND, i] = 0.0
    for i in range(nb):
        if work[B_SLOT, i] >= 0.0:
            _fold_block(s, h, i, work[B_FROM, i], 1.0, work, int(work[B_SLOT, i]))
        work[B_FROM, i] = 0.0
