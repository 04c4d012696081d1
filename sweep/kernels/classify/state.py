"""The classifier's state: its arrays (the current cycle, the last ``HISTORY`` completed
ones, the turning points, the scalar cycle state), their rows and columns, and the
start of a cycle.

Each table of rows or columns is numbered in the order it is written, and its N_* count
is the number after its last entry."""

import itertools

import numpy as np

from ...accelerate import jit, jit_inline
from ..layout import B_A, B_B, N_PARAMS

#: Terms of a sequence the extrapolation uses (:func:`sequences.aitken_limit`): a verdict needs
#: this many completed cycles, per residue class for a cycle of several events.
TERMS = 4
#: Longest cycle recognised, in events.
MAX_CYCLE_EVENTS = 32
#: Completed cycles kept per observable: TERMS for each residue class of the longest.
HISTORY = TERMS * MAX_CYCLE_EVENTS

# --- rows of a cycle's per-block statistics (win in the grid kernel) -------
_w = itertools.count()
W_LMAX = next(_w)  # extremes of ℓ_i and of friction A ℓ_i + B ψ_i
W_LMIN = next(_w)
W_MUMAX = next(_w)
W_MUMIN = next(_w)
#: The rows of ``win`` kept for each completed cycle (``past``: W_LMAX … W_MUMIN).
N_PAST = W_MUMIN + 1
W_T_PEAK = next(_w)  # time of block i's last maximum of ℓ_i in the cycle (D0/V)
N_WINDOW = next(_w)
# --- rows of every block's turning-point state (``turns``, see count_turn) ----
_t = itertools.count()
T_HIGH = next(_t)  # highest ℓ_i since its last counted minimum (or the start)
T_LOW = next(_t)  # lowest ℓ_i since its last counted maximum (or the start)
T_LAST = next(_t)  # the last counted turn: +1 a maximum, −1 a minimum, 0 none yet
N_TURNS = next(_t)
# --- columns of the scalars kept for each completed cycle (``past_cs``) ------
_x = itertools.count()
X_SYNC = next(_x)  # max |ℓ_i − ℓ_0| in the cycle
X_SLIP_SUM = next(_x)  # Σ fractions of slipping blocks of the slip events ended in the cycle
X_SLIP_EVENTS = next(_x)  # number of those events
N_PAST_CS = next(_x)

# --- entries of the scalar cycle state ``cs`` of the grid kernel -----------
_c = itertools.count()
C_N_PEAKS = next(_c)  # maxima of ℓ_0 seen
C_T_PEAK = next(_c)  # time of the last maximum of ℓ_0 (D0/V)
C_PEAK_VALUE = next(_c)  # value of the latest maximum of ℓ_0
C_PERIOD = next(_c)  # last peak-to-peak time of ℓ_0 (D0/V)
C_AMP_PREV = next(_c)  # peak-to-trough amplitude of ℓ_0 in the last completed cycle
C_GROWTH = next(_c)  # envelope growth rate over the last two cycles (V/D0)
C_N_CYCLES = next(_c)  # completed cycles
C_N_AGREE = next(_c)  # consecutive cycles with the same verdict
C_VERDICT = next(_c)  # the last cycle's verdict (−1: none yet)
C_CONV = next(_c)  # the last cycle's estimated relative distance to its limit
C_EVENTS = next(_c)  # events per cycle of the last verdict (1: a simple cycle)
C_WIN_SYNC = next(_c)  # max |ℓ_i − ℓ_0| in the current cycle
C_WIN_MBAR_MAX = next(_c)  # max of mean ℓ_i in the current cycle
C_WIN_MBAR_MIN = next(_c)  # min of mean ℓ_i in the current cycle
C_WIN_T_PEAK_LAST = next(_c)  # time of the last block's maximum of ℓ in the current cycle
C_LAST_PHASE = next(_c)  # phase lag of the last block in the last completed cycle
C_LNV_MAX_RUN = next(_c)  # max ℓ_i over the whole run
C_LAST_ORDER = next(_c)  # Kuramoto order parameter of the last completed cycle
C_SLIPPING = next(_c)  # 1 while some block slips (ℓ_i > S_SLIP_LNV) after the current step
C_IN_EVENT = next(_c)  # 1 while a slip event lasts
C_SLIP_SUM = next(_c)  # Σ fractions of slipping blocks of the events ended in the current cycle
C_SLIP_EVENTS = next(_c)  # number of those events
C_LINEAR = next(_c)  # 1 if a verdict of the current run of agreeing ones is a linear-regime one
N_CYCLE_STATE = next(_c)


@jit
def history_value(hist, k, n_cycles, back):
    """Observable ``k`` of the cycle ``back`` cycles before the last one."""
    return hist[k, (n_cycles - 1 - back) % HISTORY]


@jit
def n_observables(nb):
    """Rows of ``hist``: max ℓ_i and min ℓ_i per block, the interval, the in-phase
    amplitude (unused for one block), then ℓ_i at the event of blocks 1 … nb − 1."""
    return 3 * nb + 1


@jit
def event_state_row(k, nb):
    """Whether row ``k`` of ``hist`` is a function of the state at the event, where the
    steps fall does not matter: ℓ_0 at the event (row 0, the interpolant's maximum),
    block 0's lowest ℓ between its maxima (row nb, a minimum inside the cycle), the
    interval (row 2 nb) and the other blocks' ℓ at the event (rows 2 nb + 2 …). The
    other blocks' extremes of ℓ over the cycle and the mean ℓ's peak-to-peak (rows
    1 … nb − 1, nb + 1 … 2 nb − 1, 2 nb + 1) are not: where one lies at an end of the
    cycle (a block still slowing at the event, or starting to slip), the cycle's window
    reads it at the end of the step holding the event, up to a step past it, so it
    changes with the step grid from one passage of the same state to the next (eight
    unequal blocks in a ring, a cycle of 2 events whose state repeats to 1e-11: block
    2's highest ℓ over the long cycle, −1.2221 at its closing event, read as −0.8506 and
    −0.8780; ``tests/test_cycle_periods.py``). A cycle of several events is told by
    these rows (:func:`multi_event_verdict`)."""
    return k == 0 or k == nb or k == 2 * nb or k >= 2 * nb + 2


@jit_inline
def block_friction(p, nb, i, A, B):
    """(A_i, B_i) of block i: its per-block columns, or the common ``A``, ``B``."""
    if p.size > N_PARAMS:
        return p[N_PARAMS + B_A * nb + i], p[N_PARAMS + B_B * nb + i]
    return A, B


@jit
def new_cycle_state(y, nb):
    """Scalar cycle state (``C_*`` entries) at the start of a run from ``y``."""
    cs = np.full(N_CYCLE_STATE, np.nan)
    cs[C_N_PEAKS] = 0.0
    cs[C_PEAK_VALUE] = 0.0
    cs[C_N_CYCLES] = 0.0
    cs[C_N_AGREE] = 0.0
    cs[C_VERDICT] = -1.0
    cs[C_CONV] = np.inf
    cs[C_EVENTS] = 1.0
    cs[C_SLIPPING] = 0.0
    cs[C_IN_EVENT] = 0.0
    cs[C_LINEAR] = 0.0
    lnv_max_run = -np.inf
    for i in range(nb):
        lnv_max_run = max(lnv_max_run, y[i])
    cs[C_LNV_MAX_RUN] = lnv_max_run
    return cs


@jit
def start_cycle(y, p, nb, A, B, win, cs):
    """Start a cycle's statistics at state ``y``: extremes of ℓ_i and of the friction
    A_i ℓ_i + B_i ψ_i, the synchronisation error and mean ℓ at their current values;
    no block maximum and no slip event ended yet."""
    sync = 0.0
    mbar = 0.0
    for i in range(nb):
        win[W_LMAX, i] = y[i]
        win[W_LMIN, i] = y[i]
        a_i, b_i = block_friction(p, nb, i, A, B)
        mu = a_i * y[i] + b_i * y[nb + i]
        win[W_MUMAX, i] = mu
        win[W_MUMIN, i] = mu
        win[W_T_PEAK, i] = np.nan
        sync = max(sync, abs(y[i] - y[0]))
        mbar += y[i] / nb
    cs[C_WIN_SYNC] = sync
    cs[C_WIN_MBAR_MAX] = mbar
    cs[C_WIN_MBAR_MIN] = mbar
    cs[C_WIN_T_PEAK_LAST] = np.nan
    cs[C_SLIP_SUM] = 0.0
    cs[C_SLIP_EVENTS] = 0.0


@jit
def verdict_held(cs, cycles):
    """Whether the last cycle's verdict has held for ``cycles`` whole cycles of its
    events: a cycle of n events needs n × ``cycles`` consecutive agreeing events, so
    each of its residue classes is confirmed by as many new terms."""
    return cs[C_VERDICT] >= 0 and cs[C_N_AGREE] >= cycles * cs[C_EVENTS]


@jit_inline
def cycle_arrays(y, p, nb, A, B):
    """The classifier's arrays at the start of a run, the first cycle started at ``y``:
    the current cycle (``win``, ``W_*`` rows per block); per completed cycle, the last
    ``HISTORY`` of them in a ring: the classifier's observables (``hist``: max ℓ_i, min
    ℓ_i, interval, peak-to-peak of mean(ℓ_i)), the reported extremes (``past``: slot,
    ``W_LMAX`` … ``W_MUMIN``, block) and scalars (``past_cs``: slot, ``X_*``); scratch
    of the search for cycles of several events (``limits``); every block's ℓ at the
    latest event (``section``); the cycle state ``cs`` (``C_*``); ``slipped`` (1: block
    i slipped during the current slip event); every block's turning points (``turns``,
    ``T_*`` rows: :func:`count_turn`)."""
    win = np.empty((N_WINDOW, nb))
    past = np.empty((HISTORY, N_PAST, nb))
    past_cs = np.empty((HISTORY, N_PAST_CS))
    hist = np.zeros((n_observables(nb), HISTORY))
    limits = np.empty((n_observables(nb), MAX_CYCLE_EVENTS))
    section = np.zeros(nb)
    cs = new_cycle_state(y, nb)
    start_cycle(y, p, nb, A, B, win, cs)
    slipped = np.zeros(nb)
    turns = np.zeros((N_TURNS, nb))
    for i in range(nb):
        turns[T_HIGH, i] = y[i]
        turns[T_LOW, i] = y[i]
    return win, past, past_cs, hist, limits, section, cs, slipped, turns
