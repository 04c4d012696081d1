"""The cycle classifier: statistics of each oscillation cycle and the return-map verdict.

An *event* is a maximum of ℓ_0 (ln v/V of block 0); a *cycle* of the classifier
runs from one event to the next. Each run keeps running statistics over the
current cycle and the last ``HISTORY`` completed ones, so memory does not depend
on run length. After every event the cycle-to-cycle sequence of each observable
(extremes of every block's ℓ, the interval, the in-phase amplitude) is
extrapolated: the run has settled on a simple cycle when every observable is
within ``accuracy`` of its limit, on a cycle of n events when every residue class
of the sequence mod n is (:func:`multi_event_verdict`; n the smallest number of
events after which the state at the event repeats), and onto steady sliding when the
amplitudes extrapolate to zero.
"""

import math

import numpy as np

from ..accelerate import jit, jit_forceinline, jit_inline
from .layout import B_A, B_B, DOP853, N_PARAMS, STEADY, STICK_SLIP
from .steppers import dense_excursion, dense_extremum, dense_mix, dense_tail, dense_value

# A decaying oscillation is called steady only once it is this small (peak-to-peak
# ln v/V of every block), i.e. in the linear regime where decay is geometric: see
# steady_verdict.
LINEAR_AMPLITUDE = 0.1
# Cycle values that change by less than NOISE_FACTOR * (atol + rtol |x|), ten times
# the integrator's local error tolerance, from one cycle to the next count as
# converged to round-off (their ratio of differences would be noise).
NOISE_FACTOR = 10.0
#: An extremum of ℓ_i counts as a turning point (an event, a block's maximum) only
#: when it stands this many times the local error tolerance atol + rtol |ℓ_i| out of
#: the last counted turn (:func:`count_turn`). Once an oscillation has decayed below
#: the tolerance, the step size controller takes steps as long as its period and
#: sustains wiggles of 10–40 × atol (DOPRI5 and DOP853, K/Kc 1.0–1.2: make bench).
TURN_FACTOR = 100.0
#: Terms of a sequence the extrapolation uses (:func:`aitken_limit`): a verdict needs
#: this many completed cycles, per residue class for a cycle of several events.
TERMS = 4
#: Longest cycle recognised, in events.
MAX_CYCLE_EVENTS = 32
#: Completed cycles kept per observable: TERMS for each residue class of the longest.
HISTORY = TERMS * MAX_CYCLE_EVENTS
#: A sequence that does not contract geometrically (Aitken's ratio test fails: noise,
#: or a faint modulation) is settled to within its spread when it stays within
#: ``accuracy`` over all its kept cycles, at least this many (per residue class), and
#: turns at least twice: a slow monotone drift (an oscillation growing away from an
#: unstable fixed point at 1e-5 of Kc) never counts (test_classification.py).
STEADY_TERMS = 16
#: Cycles of several events are looked for only while the simple cycle's convergence
#: exceeds this many times ``accuracy`` (close to a simple cycle, it settles first;
#: what it costs runs that settle is measured by make bench: "settling").
SEARCH_FACTOR = 100.0


# --- rows of a cycle's per-block statistics (win in the grid kernel) -------
W_LMAX, W_LMIN, W_MUMAX, W_MUMIN = range(4)  # extremes of ℓ_i and of friction A ℓ_i + B ψ_i
W_T_PEAK = 4  # time of block i's last maximum of ℓ_i in the cycle (D0/V)
N_WINDOW = 5
#: The rows of ``win`` kept for each completed cycle (``past``: W_LMAX … W_MUMIN).
N_PAST = 4
# --- rows of every block's turning-point state (``turns``, see count_turn) ----
T_HIGH = 0  # highest ℓ_i since its last counted minimum (or the start)
T_LOW = 1  # lowest ℓ_i since its last counted maximum (or the start)
T_LAST = 2  # the last counted turn: +1 a maximum, −1 a minimum, 0 none yet
N_TURNS = 3
# --- columns of the scalars kept for each completed cycle (``past_cs``) ------
(
    X_SYNC,  # max |ℓ_i − ℓ_0| in the cycle
    X_SLIP_SUM,  # Σ fractions of slipping blocks of the slip events ended in the cycle
    X_SLIP_EVENTS,  # number of those events
) = range(3)
N_PAST_CS = 3

# --- entries of the scalar cycle state ``cs`` of the grid kernel -----------
(
    C_N_PEAKS,  # maxima of ℓ_0 seen
    C_T_PEAK,  # time of the last maximum of ℓ_0 (D0/V)
    C_PEAK_VALUE,  # value of the latest maximum of ℓ_0
    C_PERIOD,  # last peak-to-peak time of ℓ_0 (D0/V)
    C_AMP_PREV,  # peak-to-trough amplitude of ℓ_0 in the last completed cycle
    C_GROWTH,  # envelope growth rate over the last two cycles (V/D0)
    C_N_CYCLES,  # completed cycles
    C_N_AGREE,  # consecutive cycles with the same verdict
    C_VERDICT,  # the last cycle's verdict (−1: none yet)
    C_CONV,  # the last cycle's estimated relative distance to its limit
    C_EVENTS,  # events per cycle of the last verdict (1: a simple cycle)
    C_WIN_SYNC,  # max |ℓ_i − ℓ_0| in the current cycle
    C_WIN_MBAR_MAX,  # max of mean ℓ_i in the current cycle
    C_WIN_MBAR_MIN,  # min of mean ℓ_i in the current cycle
    C_WIN_T_PEAK_LAST,  # time of the last block's maximum of ℓ in the current cycle
    C_LAST_PHASE,  # phase lag of the last block in the last completed cycle
    C_LNV_MAX_RUN,  # max ℓ_i over the whole run
    C_LAST_ORDER,  # Kuramoto order parameter of the last completed cycle
    C_SLIPPING,  # 1 while some block slips (ℓ_i > S_SLIP_LNV) after the current step
    C_IN_EVENT,  # 1 while a slip event lasts
    C_SLIP_SUM,  # Σ fractions of slipping blocks of the events ended in the current cycle
    C_SLIP_EVENTS,  # number of those events
) = range(22)
N_CYCLE_STATE = 22


@jit
def aitken_limit(x0, x1, x2, x3, noise):
    """Limit of a sequence that converges geometrically, from its last four terms.

    Returns ``(limit, error)``: Aitken's Δ² extrapolation from the last three terms
    and its error estimate, the change from the extrapolation one term earlier.
    ``error`` is inf where the differences do not contract (|ratio| ≥ 1);
    differences within ``noise`` count as converged (limit ``x3``).
    """
    d1 = x1 - x0
    d2 = x2 - x1
    d3 = x3 - x2
    if abs(d3) <= noise and abs(d2) <= noise:
        return x3, abs(d2) + abs(d3)
    if d1 == 0.0 or d2 == 0.0:
        return x3, np.inf
    q = d3 / d2
    q_prev = d2 / d1
    if not (abs(q) < 1.0 and abs(q_prev) < 1.0):
        return x3, np.inf
    limit = x3 + d3 * q / (1.0 - q)
    limit_prev = x2 + d2 * q_prev / (1.0 - q_prev)
    return limit, abs(limit - limit_prev)


@jit
def history_value(hist, k, n_cycles, back):
    """Observable ``k`` of the cycle ``back`` cycles before the last one."""
    return hist[k, (n_cycles - 1 - back) % HISTORY]


@jit
def last_four(hist, k, n_cycles):
    """Observable ``k`` over the last four cycles, oldest first."""
    return (
        history_value(hist, k, n_cycles, 3),
        history_value(hist, k, n_cycles, 2),
        history_value(hist, k, n_cycles, 1),
        history_value(hist, k, n_cycles, 0),
    )


@jit
def last_four_ptp(hist, nb, i, n_cycles):
    """Peak-to-peak ℓ_i (rows i and nb + i of ``hist``) over the last four cycles."""
    a0, a1, a2, a3 = last_four(hist, i, n_cycles)
    b0, b1, b2, b3 = last_four(hist, nb + i, n_cycles)
    return a0 - b0, a1 - b1, a2 - b2, a3 - b3


@jit
def decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
    """Whether amplitudes x0 > x1 > x2 > x3 head for zero: already below
    ``steady_amp``, or decreasing with an extrapolated limit of zero to within
    ``accuracy`` × x3."""
    if x3 < steady_amp:
        return True
    if not (x0 > x1 > x2 > x3):
        return False
    limit, error = aitken_limit(x0, x1, x2, x3, noise)
    return abs(limit) + error <= accuracy * x3


@jit
def steady_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, atol):
    """Whether the last four cycles show the decay onto steady sliding.

    Only where steady sliding is linearly stable (``lin_growth`` < 0): an unstable
    fixed point is never the attractor, whatever a transient does (two weakly
    coupled blocks whose anti-phase mode decays first while the in-phase mode grows,
    test_classification.py). Every block's oscillation must be small (peak-to-peak
    ℓ below ``LINEAR_AMPLITUDE``) and extrapolate to zero; with several blocks so
    must the in-phase coordinate mean(ℓ_i) (row 2 nb + 1), so a slowly decaying
    in-phase mode hidden behind a faster anti-phase one is seen.
    """
    if not (lin_growth < 0.0) or n_cycles < TERMS:
        return False
    noise = NOISE_FACTOR * atol
    for i in range(nb):
        x0, x1, x2, x3 = last_four_ptp(hist, nb, i, n_cycles)
        if not (x3 < LINEAR_AMPLITUDE):
            return False
        if not decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
            return False
    if nb > 1:
        x0, x1, x2, x3 = last_four(hist, 2 * nb + 1, n_cycles)
        if not decays_to_zero(x0, x1, x2, x3, accuracy, steady_amp, noise):
            return False
    return True


@jit
def cycle_convergence(hist, n_cycles, nb, rtol, atol):
    """Estimated relative distance of the last cycle to the limit cycle.

    The largest, over the cycle's observables, of the distance to the extrapolated
    limit plus that limit's error (:func:`aitken_limit`), relative to the
    observable's scale: for the extremes of every block's ℓ, min(1, peak-to-peak ℓ / 2)
    (so v_max and v_min are known to that relative accuracy, and the peak-to-peak
    too); for the period, the period; for the in-phase amplitude, the peak-to-peak
    ℓ. inf with fewer than four cycles or where an observable does not contract.
    """
    if n_cycles < TERMS:
        return np.inf
    ptp = 0.0
    for i in range(nb):
        ptp = max(
            ptp, history_value(hist, i, n_cycles, 0) - history_value(hist, nb + i, n_cycles, 0)
        )
    worst = 0.0
    for k in range(2 * nb + 2):
        if k == 2 * nb + 1 and nb == 1:
            break
        x0, x1, x2, x3 = last_four(hist, k, n_cycles)
        noise = NOISE_FACTOR * (atol + rtol * abs(x3))
        limit, error = aitken_limit(x0, x1, x2, x3, noise)
        error += abs(limit - x3)
        if k < 2 * nb:
            scale = min(1.0, 0.5 * ptp)
        elif k == 2 * nb:
            scale = abs(x3)
        else:
            scale = ptp
        if not (error <= worst * scale):
            worst = error / scale if scale > 0.0 else np.inf
    return worst


@jit
def cycle_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, rtol, atol):
    """Regime settled by the last four cycles, or −1; and the cycle's convergence.

    Steady: :func:`steady_verdict`. Stick-slip: every cycle observable within
    ``accuracy`` (relative, see :func:`cycle_convergence`) of its extrapolated
    limit, so the reported features are those of the limit cycle to that accuracy,
    and with several blocks the other blocks at the event repeating too
    (:func:`section_settled`).
    """
    if steady_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, atol):
        return STEADY, np.nan
    conv = cycle_convergence(hist, n_cycles, nb, rtol, atol)
    if conv <= accuracy:
        if not section_settled(hist, n_cycles, nb, accuracy, rtol, atol):
            return -1, np.inf
        return STICK_SLIP, conv
    return -1, conv


@jit
def span_ptp(hist, n_cycles, nb, n):
    """Peak-to-peak ℓ over the last ``n`` cycles: the largest over blocks of the
    highest maximum minus the lowest minimum of ℓ_i."""
    ptp = 0.0
    for i in range(nb):
        hi = -np.inf
        lo = np.inf
        for back in range(n):
            hi = max(hi, history_value(hist, i, n_cycles, back))
            lo = min(lo, history_value(hist, nb + i, n_cycles, back))
        ptp = max(ptp, hi - lo)
    return ptp


@jit
def envelope_turns(hist, n_cycles, nb, n):
    """How often the envelope of the last ``n`` cycles turns: the sign changes of the
    cycle-to-cycle differences of the peak-to-peak ℓ (the largest over blocks of
    max ℓ_i − min ℓ_i in a cycle). Bounded motion on a torus or a chaotic attractor
    comes back: its envelope turns again and again; a spiral growing away from an
    unstable fixed point (or decaying onto a stable one) has a monotone envelope,
    however slow (one block at 0.9999 Kc: test_classification.py)."""
    turns = 0
    d_prev = 0.0
    a_prev = 0.0
    for j in range(n):
        back = n - 1 - j
        a = 0.0
        for i in range(nb):
            a = max(a, history_value(hist, i, n_cycles, back)
                    - history_value(hist, nb + i, n_cycles, back))  # fmt: skip
        if j > 0:
            d = a - a_prev
            if d * d_prev < 0.0:
                turns += 1
            if d != 0.0:
                d_prev = d
        a_prev = a
    return turns


@jit
def recurrence(hist, n_cycles, nb, n, peak_scale):
    """How far the last cycle is from the one ``n`` cycles before it: the change of
    the event's ℓ_0 relative to ``peak_scale`` plus the relative change of the interval."""
    d_peak = history_value(hist, 0, n_cycles, 0) - history_value(hist, 0, n_cycles, n)
    interval = history_value(hist, 2 * nb, n_cycles, 0)
    d_interval = interval - history_value(hist, 2 * nb, n_cycles, n)
    return abs(d_peak) / peak_scale + abs(d_interval / interval)


@jit
def class_scale(k, nb, ptp, value):
    """Scale of observable ``k`` (as in :func:`cycle_convergence`): min(1, ptp/2) for
    the extremes of ℓ and the other blocks' ℓ at the event, the interval itself
    (``value``), ptp for the in-phase amplitude."""
    if k == 2 * nb:
        return abs(value)
    if k == 2 * nb + 1:
        return ptp
    return min(1.0, 0.5 * ptp)


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


@jit
def section_settled(hist, n_cycles, nb, accuracy, rtol, atol):
    """Whether the other blocks' ℓ at the event (rows 2 nb + 2 …, the return map's
    coordinates that the per-cycle extremes miss) repeat from cycle to cycle: each
    extrapolates within ``accuracy`` (scale min(1, ptp/2)) or its last four values lie
    within that. Two uncoupled blocks with unrelated periods have constant per-cycle
    extremes but a drifting phase: not a cycle."""
    scale = min(1.0, 0.5 * span_ptp(hist, n_cycles, nb, 1))
    for k in range(2 * nb + 2, n_observables(nb)):
        x0, x1, x2, x3 = last_four(hist, k, n_cycles)
        limit, error = aitken_limit(x0, x1, x2, x3, NOISE_FACTOR * (atol + rtol * abs(x3)))
        spread = max(x0, x1, x2, x3) - min(x0, x1, x2, x3)
        if not (min(error + abs(limit - x3), spread) <= accuracy * scale):
            return False
    return True


@jit
def class_spread(hist, k, n_cycles, n, r, terms):
    """Largest minus smallest value of observable ``k`` over the last ``terms`` cycles
    of residue class ``r`` mod ``n``; inf unless the sequence turns (its differences
    change sign) at least twice."""
    hi = -np.inf
    lo = np.inf
    turns = 0
    x_prev = history_value(hist, k, n_cycles, r)
    d_prev = 0.0
    for j in range(terms):
        x = history_value(hist, k, n_cycles, r + j * n)
        hi = max(hi, x)
        lo = min(lo, x)
        d = x - x_prev
        if d * d_prev < 0.0:
            turns += 1
        if d != 0.0:
            d_prev = d
        x_prev = x
    return hi - lo if turns >= 2 else np.inf


@jit
def classes_convergence(hist, n_cycles, nb, n, bound, rtol, atol, limits, every_row):
    """Estimated relative distance of the last ``n`` cycles to a cycle of ``n`` events.

    :func:`cycle_convergence` applied to each residue class of the cycle sequence
    mod ``n`` (every ``n``-th cycle, the last four of each), scales from the
    peak-to-peak over the ``n`` cycles; the extrapolated limits go to
    ``limits[k, r]`` (observable k, class of the cycle r cycles before the last).
    Where the extrapolation fails or exceeds ``bound``, a class with at least
    ``STEADY_TERMS`` cycles kept counts as settled to within the spread of all of
    them if it turns (:func:`class_spread`, limit: its last value). Stops with inf as
    soon as one class exceeds ``bound``; without ``every_row``, only one of the rows
    that are functions of the state at the event (:func:`event_state_row`) does: a
    class of another row beyond ``bound`` gets limit NaN and is left out of the
    distance (its values depend on the step grid).
    """
    ptp = span_ptp(hist, n_cycles, nb, n)
    terms = min(n_cycles, HISTORY) // n
    worst = 0.0
    for k in range(n_observables(nb)):
        if k == 2 * nb + 1 and nb == 1:
            continue
        for r in range(n):
            x0 = history_value(hist, k, n_cycles, r + 3 * n)
            x1 = history_value(hist, k, n_cycles, r + 2 * n)
            x2 = history_value(hist, k, n_cycles, r + n)
            x3 = history_value(hist, k, n_cycles, r)
            noise = NOISE_FACTOR * (atol + rtol * abs(x3))
            limit, error = aitken_limit(x0, x1, x2, x3, noise)
            scale = class_scale(k, nb, ptp, x3)
            distance = (error + abs(limit - x3)) / scale if scale > 0.0 else np.inf
            if not (distance <= bound) and terms >= STEADY_TERMS and scale > 0.0:
                distance = class_spread(hist, k, n_cycles, n, r, terms) / scale
                limit = x3
            if not (distance <= bound):
                if every_row or event_state_row(k, nb):
                    return np.inf
                limits[k, r] = np.nan
                continue
            worst = max(worst, distance)
            limits[k, r] = limit
    return worst


@jit
def limits_repeat(limits, n, nb, ptp, tol, d, every_row):
    """Whether the classes' limits (:func:`classes_convergence`) repeat after ``d``
    events, within ``tol`` × each observable's scale (:func:`class_scale`): of every
    row, or only of the rows that are functions of the state at the event
    (:func:`event_state_row`). A NaN limit never repeats."""
    for k in range(n_observables(nb)):
        if k == 2 * nb + 1 and nb == 1:
            continue
        if not (every_row or event_state_row(k, nb)):
            continue
        for r in range(n):
            a = limits[k, r]
            b = limits[k, (r + d) % n]
            if not (abs(a - b) <= tol * class_scale(k, nb, ptp, a)):
                return False
    return True


@jit
def every_limit_known(limits, n, nb):
    """Whether every row's classes have a limit (none NaN: every row within the bound
    of :func:`classes_convergence`, as its ``every_row`` asks)."""
    for k in range(n_observables(nb)):
        if k == 2 * nb + 1 and nb == 1:
            continue
        for r in range(n):
            if limits[k, r] != limits[k, r]:
                return False
    return True


@jit
def limit_period(limits, n, nb, ptp, accuracy):
    """The smallest d dividing ``n`` after which the state at the event repeats: the
    limits of its rows (:func:`event_state_row`) within twice ``accuracy`` of each
    observable's scale (:func:`limits_repeat`). The cycle's true number of events."""
    for d in range(1, n):
        if n % d == 0 and limits_repeat(limits, n, nb, ptp, 2.0 * accuracy, d, False):
            return d
    return n


@jit
def multi_event_verdict(hist, n_cycles, nb, accuracy, rtol, atol, limits):
    """The cycle of n ≥ 2 events that the run has settled on: ``(n, convergence)``,
    or ``(0, the best convergence found)``; ``(1, convergence)`` for a simple cycle
    that the simple cycle's own test cannot settle.

    Candidates are the n up to :data:`MAX_CYCLE_EVENTS` (four cycles of each residue
    class kept) at which the last cycle comes closer to the one n cycles earlier
    than to any nearer one (:func:`recurrence`): a cycle of n events returns to
    itself after n cycles, not before. A candidate whose classes are all within
    ``accuracy`` (:func:`classes_convergence`) has as many events as it takes the
    state at the event to repeat (:func:`limit_period`: a cycle of 4 events whose
    limits repeat every 2 is a cycle of 2), judged on the rows that are functions of
    that state (:func:`event_state_row`); the other rows' limits, read off the step
    grid, may differ from class to class.

    The first candidate of more than one event settles the run when every row's
    classes are within ``accuracy``, or, where only the state's rows are, when the
    cycle is far from a simple one: some row's limits differ from class to class by
    more than ``SEARCH_FACTOR`` × ``accuracy`` of its scale (the search's own bound
    for "close to a simple cycle"). Closer than that, a simple cycle approached with
    slowly decaying, beating alternation (a Floquet multiplier near −1: route_to_chaos
    at K/W = 0.00415 µm⁻¹) can look converged in each class over its four terms; the
    rows that miss it are then needed. A simple cycle approached with alternating
    overshoots (the state's limits repeating every event) is left to the simple
    cycle's own test (so it settles as before), unless every row's classes are
    within ``accuracy`` and some row's limits differ from class to class: that row
    never converges from cycle to cycle, and the simple test never settles it.
    ``convergence`` and the best one found are as :func:`classes_convergence` of
    every row gives them (inf where some row is beyond ``accuracy``), except for a
    cycle settled by the state's rows alone (theirs).
    """
    longest = min(MAX_CYCLE_EVENTS, n_cycles // TERMS)
    best = np.inf
    if longest < 2:
        return 0, best
    peak_scale = max(min(1.0, 0.5 * span_ptp(hist, n_cycles, nb, 1)), 1e-300)
    closest = recurrence(hist, n_cycles, nb, 1, peak_scale)
    for n in range(2, longest + 1):
        distance = recurrence(hist, n_cycles, nb, n, peak_scale)
        if not (distance < closest):
            continue
        closest = distance
        conv = classes_convergence(hist, n_cycles, nb, n, accuracy, rtol, atol, limits, False)
        if not (conv <= accuracy):
            best = min(best, conv)
            continue
        ptp = span_ptp(hist, n_cycles, nb, n)
        events = limit_period(limits, n, nb, ptp, accuracy)
        known = every_limit_known(limits, n, nb)
        if events > 1:
            far = not limits_repeat(limits, n, nb, ptp, SEARCH_FACTOR * accuracy, 1, False)
            if known or far:
                return events, conv
        elif known and not limits_repeat(limits, n, nb, ptp, 2.0 * accuracy, 1, True):
            return 1, conv
        if known:
            best = min(best, conv)
    return 0, best


@jit
def simple_cycle_within_spread(hist, n_cycles, nb, accuracy, rtol, atol, limits):
    """Convergence of a run to a simple cycle with the spread test of
    :func:`classes_convergence` (a cycle known to within ``accuracy`` whose
    cycle-to-cycle values wander at the noise floor or with a faint modulation,
    where the extrapolation's ratio test fails). Asked only of runs unsettled at
    their end, so no run that settles by extrapolation changes."""
    if n_cycles < STEADY_TERMS:
        return np.inf
    return classes_convergence(hist, n_cycles, nb, 1, accuracy, rtol, atol, limits, True)


@jit_inline
def block_friction(p, nb, i, A, B):
    """(A_i, B_i) of block i: its per-block columns, or the common ``A``, ``B``."""
    if p.size > N_PARAMS:
        return p[N_PARAMS + B_A * nb + i], p[N_PARAMS + B_B * nb + i]
    return A, B


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
def count_turn(turns, i, val, is_max, noise):
    """Whether an extremum of ℓ_i of value ``val`` counts as a turning point: it must
    stand out of the local error scale ``noise`` (TURN_FACTOR × the tolerance at
    ``val``) against the last counted turn of the other kind, and turns alternate.

    A slope changes sign by round-off where an oscillation has decayed below the
    tolerance (the step size controller then takes steps longer than its period) or
    on the flat top of a slow extremum; such extrema move ``turns`` (``T_*`` rows)
    but are not counted, so neither events nor block maxima come from noise.
    """
    if is_max:
        if turns[T_LAST, i] <= 0.0 and val - turns[T_LOW, i] > noise:
            turns[T_HIGH, i] = val
            turns[T_LAST, i] = 1.0
            return True
    elif turns[T_LAST, i] >= 0.0 and turns[T_HIGH, i] - val > noise:
        turns[T_LOW, i] = val
        turns[T_LAST, i] = -1.0
        return True
    hold_extreme(turns, i, val, is_max)
    return False


@jit_inline
def hold_extreme(turns, i, val, is_max):
    """Fold an extremum of ℓ_i that is no turn, a maximum (``is_max``) or a minimum of
    value ``val``, into the highest or lowest ℓ_i since the last counted turn."""
    if is_max:
        turns[T_HIGH, i] = max(turns[T_HIGH, i], val)
    else:
        turns[T_LOW, i] = min(turns[T_LOW, i], val)


@jit_inline
def lnv_extremum_matters(i, span, y, ynew, f, turns, rtol, atol):
    """Whether the extremum of ℓ_i in a step where its slope changes sign must be
    located with the interpolant. It need not when its excursion bound ``span``
    (:func:`steppers.dense_excursion`) keeps it within the local error scale
    (``TURN_FACTOR`` × the tolerance) of the step's ends and, wherever it lies there,
    it could not count as a turn (:func:`count_turn`): the wiggles of an oscillation
    decayed below the tolerance, which otherwise cost root searches (and DOP853 three
    more stages) at almost every step (``docs/performance.md``)."""
    lo = min(y[i], ynew[i])
    hi = max(y[i], ynew[i])
    least = TURN_FACTOR * (atol + rtol * max(0.0, min(abs(lo), abs(hi)) - span))
    if span > least:
        return True
    if f[i] > 0.0:  # a maximum: could it stand out of the last counted minimum?
        return turns[T_LAST, i] <= 0.0 and hi + span - turns[T_LOW, i] > least
    return turns[T_LAST, i] >= 0.0 and turns[T_HIGH, i] - (lo - span) > least


@jit_inline
def extremum_matters(method, x0, x1, d0, d1, h, r5, tol):
    """Whether the extremum of a quantity in a step of size h where its slope changes
    sign (from ``x0``, slope ``d0`` to ``x1``, slope ``d1``; ``r5`` the fifth coefficient
    of its interpolant, read by DOPRI5) must be located: unless its excursion bound
    (:func:`steppers.dense_excursion`) is within ``TURN_FACTOR`` × its tolerance ``tol``.
    For a block's friction and the mean ℓ, whose extremes are kept but never counted
    as turns."""
    return dense_excursion(method, x0, x1, d0, d1, h, r5) > TURN_FACTOR * tol


@jit_inline
def mean_extremum_matters(method, m0, m1, dm0, dm1, h, r5, rtol, atol):
    """:func:`extremum_matters` for the mean ℓ of several blocks (from ``m0``, slope
    ``dm0`` to ``m1``, slope ``dm1``) at its tolerance atol + rtol |m1|: one test for the
    kernel, which locates the extremum, and :func:`dense_needed`, which must agree."""
    return extremum_matters(method, m0, m1, dm0, dm1, h, r5, atol + rtol * abs(m1))


@jit_inline
def friction_tolerance(a_i, b_i, lnv, psi, rtol, atol):
    """The tolerance of a block's friction A_i ℓ_i + B_i ψ_i at ℓ_i = ``lnv``, ψ_i = ``psi``."""
    return a_i * (atol + rtol * abs(lnv)) + b_i * (atol + rtol * abs(psi))


@jit_forceinline
def update_cycle(
    method, t, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, p, nb, A, B, win, cs, slipped,
    slip_lnv, turns, rtol, atol,
):  # fmt: skip
    """Fold the step from ``t`` to ``t + h`` into the current cycle's statistics.

    Extremes of every block's ℓ and friction are located inside the step with
    the dense output. Blocks with ℓ_i > ``slip_lnv`` after the step are marked in
    ``slipped`` (``cs[C_SLIPPING]``: whether any is). Returns ``(new_peak, theta)``:
    whether ℓ_0 had a maximum in the step that counts as a turn (:func:`count_turn`
    with tolerances ``rtol``, ``atol``; its value goes to ``cs[C_PEAK_VALUE]``) and
    where, as a fraction of the step.
    """
    new_peak = False
    theta_peak = 0.0
    lnv_max_run = cs[C_LNV_MAX_RUN]
    win_sync = cs[C_WIN_SYNC]
    slipping = 0.0
    for i in range(nb):
        rising = f[i] > 0.0
        falling_now = fnew[i] <= 0.0
        if rising == falling_now:  # slope changed sign: one extremum in the step
            r = dense_tail(method, i, h, f, k3, k4, k5, k6, fnew, dense)
            span = dense_excursion(method, y[i], ynew[i], f[i], fnew[i], h, r[0])
            if lnv_extremum_matters(i, span, y, ynew, f, turns, rtol, atol):
                theta = dense_extremum(y[i], ynew[i], f[i], fnew[i], h, r)
                val = dense_value(y[i], ynew[i], f[i], fnew[i], h, r, theta)
                win[W_LMAX, i] = max(win[W_LMAX, i], val)
                win[W_LMIN, i] = min(win[W_LMIN, i], val)
                lnv_max_run = max(lnv_max_run, val)
                noise = TURN_FACTOR * (atol + rtol * abs(val))
                if count_turn(turns, i, val, rising, noise) and rising:
                    win[W_T_PEAK, i] = t + theta * h
                    if i == 0:
                        new_peak = True
                        theta_peak = theta
                        cs[C_PEAK_VALUE] = val
                    elif i == nb - 1:
                        cs[C_WIN_T_PEAK_LAST] = t + theta * h
            else:  # below the error scale, no turn: the step's ends stand for it
                end = max(y[i], ynew[i]) if rising else min(y[i], ynew[i])
                hold_extreme(turns, i, end, rising)
        win[W_LMAX, i] = max(win[W_LMAX, i], ynew[i])
        win[W_LMIN, i] = min(win[W_LMIN, i], ynew[i])
        lnv_max_run = max(lnv_max_run, ynew[i])
        if ynew[i] > slip_lnv:
            slipped[i] = 1.0
            slipping = 1.0
        # friction A_i ℓ_i + B_i ψ_i (relative to steady sliding), extremes interpolated
        a_i, b_i = block_friction(p, nb, i, A, B)
        mu0 = a_i * y[i] + b_i * y[nb + i]
        mu = a_i * ynew[i] + b_i * ynew[nb + i]
        dmu0 = a_i * f[i] + b_i * f[nb + i]
        dmu1 = a_i * fnew[i] + b_i * fnew[nb + i]
        if (dmu0 > 0.0) == (dmu1 <= 0.0):
            r_mu = dense_mix(
                a_i, dense_tail(method, i, h, f, k3, k4, k5, k6, fnew, dense),
                b_i, dense_tail(method, nb + i, h, f, k3, k4, k5, k6, fnew, dense),
            )  # fmt: skip
            tol = friction_tolerance(a_i, b_i, ynew[i], ynew[nb + i], rtol, atol)
            if extremum_matters(method, mu0, mu, dmu0, dmu1, h, r_mu[0], tol):
                theta = dense_extremum(mu0, mu, dmu0, dmu1, h, r_mu)
                val = dense_value(mu0, mu, dmu0, dmu1, h, r_mu, theta)
                win[W_MUMAX, i] = max(win[W_MUMAX, i], val)
                win[W_MUMIN, i] = min(win[W_MUMIN, i], val)
        win[W_MUMAX, i] = max(win[W_MUMAX, i], mu)
        win[W_MUMIN, i] = min(win[W_MUMIN, i], mu)
        if i > 0:
            win_sync = max(win_sync, abs(ynew[i] - ynew[0]))
    cs[C_LNV_MAX_RUN] = lnv_max_run
    cs[C_WIN_SYNC] = win_sync
    cs[C_SLIPPING] = slipping
    return new_peak, theta_peak


@jit
def dense_needed(h, y, ynew, f, fnew, p, nb, A, B, turns, rtol, atol):
    """Whether :func:`update_cycle` or the mean ℓ's extremes read the interpolant of the
    step of size h from (``y``, slopes ``f``) to (``ynew``, ``fnew``): an extremum of
    some ℓ_i or friction μ_i in it must be located (the same tests, term by term), or
    (several blocks) the mean ℓ's slope changes sign. DOP853 computes its interpolant
    only then (three more stages)."""
    need = False
    m0 = 0.0  # the mean ℓ and its slope before and after the step
    m1 = 0.0
    dm0 = 0.0
    dm1 = 0.0
    for i in range(nb):
        if (f[i] > 0.0) == (fnew[i] <= 0.0):
            span = dense_excursion(DOP853, y[i], ynew[i], f[i], fnew[i], h, 0.0)
            if lnv_extremum_matters(i, span, y, ynew, f, turns, rtol, atol):
                need = True
        a_i, b_i = block_friction(p, nb, i, A, B)
        dmu0 = a_i * f[i] + b_i * f[nb + i]
        dmu1 = a_i * fnew[i] + b_i * fnew[nb + i]
        if (dmu0 > 0.0) == (dmu1 <= 0.0):
            mu0 = a_i * y[i] + b_i * y[nb + i]
            mu = a_i * ynew[i] + b_i * ynew[nb + i]
            tol = friction_tolerance(a_i, b_i, ynew[i], ynew[nb + i], rtol, atol)
            if extremum_matters(DOP853, mu0, mu, dmu0, dmu1, h, 0.0, tol):
                need = True
        m0 += y[i] / nb
        m1 += ynew[i] / nb
        dm0 += f[i] / nb
        dm1 += fnew[i] / nb
    if nb > 1 and (dm0 > 0.0) == (dm1 <= 0.0):
        if mean_extremum_matters(DOP853, m0, m1, dm0, dm1, h, 0.0, rtol, atol):
            need = True
    return need


@jit
def end_slip_event(nb, slipped, cs):
    """A slip event ended (no block slips any more): add the fraction of blocks that
    slipped during it to the current cycle's sum and clear the marks."""
    count = 0.0
    for i in range(nb):
        count += slipped[i]
        slipped[i] = 0.0
    cs[C_SLIP_SUM] += count / nb
    cs[C_SLIP_EVENTS] += 1.0
    cs[C_IN_EVENT] = 0.0


@jit
def kuramoto_order(t_peak_blocks, t_peak, period, nb):
    """Kuramoto order parameter R = |mean_i exp(iθ_i)| of the blocks' phases at the
    maximum of ℓ_0 at ``t_peak``: θ_i = 2π (last maximum of ℓ_i − t_peak) / period.
    NaN if a block had no maximum in the cycle."""
    re = 0.0
    im = 0.0
    for i in range(nb):
        theta = 2.0 * math.pi * (t_peak_blocks[i] - t_peak) / period
        re += math.cos(theta)
        im += math.sin(theta)
    return math.sqrt(re * re + im * im) / nb  # NaN from a block without a maximum


@jit
def event_section(method, h, y, ynew, f, fnew, k3, k4, k5, k6, dense, nb, theta, section):
    """Every block's ℓ at the event at fraction ``theta`` of the step (dense output)."""
    for i in range(nb):
        r = dense_tail(method, i, h, f, k3, k4, k5, k6, fnew, dense)
        section[i] = dense_value(y[i], ynew[i], f[i], fnew[i], h, r, theta)


@jit
def close_cycle(
    t_peak, nb, win, past, past_cs, hist, limits, section, cs, accuracy, steady_amp, lin_growth,
    rtol, atol,
):  # fmt: skip
    """End the cycle at the maximum of ℓ_0 at ``t_peak`` (D0/V).

    Adds the cycle to the history (``hist``: the classifier's observables; ``past``,
    ``past_cs``: what a reported window spans; ``section``: the blocks' ℓ at the event)
    and judges it: :func:`cycle_verdict`, then, far from a simple cycle,
    :func:`multi_event_verdict` (``limits``: its scratch, (rows of ``hist``,
    MAX_CYCLE_EVENTS)).
    """
    period = t_peak - cs[C_T_PEAK]
    cs[C_PERIOD] = period
    # growth of the peak-to-trough amplitude of ℓ_0, where it is above round-off
    # (a decayed run would report noise, not a rate)
    amp = cs[C_PEAK_VALUE] - win[W_LMIN, 0]
    growth = np.nan
    if cs[C_AMP_PREV] >= steady_amp and amp >= steady_amp:
        growth = math.log(amp / cs[C_AMP_PREV]) / period
    cs[C_GROWTH] = growth
    cs[C_AMP_PREV] = amp
    n_cycles = int(cs[C_N_CYCLES])
    slot = n_cycles % HISTORY
    for i in range(nb):
        hist[i, slot] = win[W_LMAX, i]
        hist[nb + i, slot] = win[W_LMIN, i]
    hist[0, slot] = cs[C_PEAK_VALUE]
    hist[2 * nb, slot] = period
    hist[2 * nb + 1, slot] = cs[C_WIN_MBAR_MAX] - cs[C_WIN_MBAR_MIN]
    for i in range(1, nb):
        hist[2 * nb + 1 + i, slot] = section[i]
    for k in range(N_PAST):
        for i in range(nb):
            past[slot, k, i] = win[k, i]
    past_cs[slot, X_SYNC] = cs[C_WIN_SYNC]
    past_cs[slot, X_SLIP_SUM] = cs[C_SLIP_SUM]
    past_cs[slot, X_SLIP_EVENTS] = cs[C_SLIP_EVENTS]
    n_cycles += 1
    cs[C_N_CYCLES] = n_cycles
    verdict, conv = cycle_verdict(hist, n_cycles, nb, accuracy, steady_amp, lin_growth, rtol, atol)
    events = 1
    if verdict < 0 and not (conv <= SEARCH_FACTOR * accuracy):
        events, conv_n = multi_event_verdict(hist, n_cycles, nb, accuracy, rtol, atol, limits)
        if events > 0:
            verdict = STICK_SLIP
            conv = conv_n
        else:
            events = 1
            conv = min(conv, conv_n)
    cs[C_CONV] = conv
    same = verdict >= 0 and verdict == int(cs[C_VERDICT]) and events == int(cs[C_EVENTS])
    cs[C_N_AGREE] = cs[C_N_AGREE] + 1 if same else 1
    cs[C_VERDICT] = verdict
    cs[C_EVENTS] = events
    cs[C_LAST_ORDER] = kuramoto_order(win[W_T_PEAK], t_peak, period, nb)
    t_last = cs[C_WIN_T_PEAK_LAST]
    if nb > 1 and t_last == t_last:
        lag = (t_last - cs[C_T_PEAK]) / period
        cs[C_LAST_PHASE] = lag - math.floor(lag + 0.5)


@jit
def verdict_held(cs, cycles):
    """Whether the last cycle's verdict has held for ``cycles`` whole cycles of its
    events: a cycle of n events needs n × ``cycles`` consecutive agreeing events, so
    each of its residue classes is confirmed by as many new terms."""
    return cs[C_VERDICT] >= 0 and cs[C_N_AGREE] >= cycles * cs[C_EVENTS]


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
    lnv_max_run = -np.inf
    for i in range(nb):
        lnv_max_run = max(lnv_max_run, y[i])
    cs[C_LNV_MAX_RUN] = lnv_max_run
    return cs


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
