"""The return-map verdicts of a cycle's sequences: after every event the cycle-to-cycle
sequence of each observable (extremes of every block's ℓ, the interval, the in-phase
amplitude, the blocks' ℓ at the event) is extrapolated. The run has settled on a
simple cycle when every observable is within ``accuracy`` of its limit, on a cycle of
n events when every residue class of the sequence mod n is
(:func:`multi_event_verdict`; n the smallest number of events after which the state at
the event repeats), and onto steady sliding when the amplitudes extrapolate to zero."""

import numpy as np

from ...accelerate import jit, jit_inline
from ..layout import STEADY, STICK_SLIP
from .state import HISTORY, MAX_CYCLE_EVENTS, TERMS, event_state_row, history_value, n_observables

# A decaying oscillation is called steady only once it is this small (peak-to-peak
# ln v/V of every block), i.e. in the linear regime where decay is geometric: see
# steady_verdict.
LINEAR_AMPLITUDE = 0.1
# Cycle values that change by less than NOISE_FACTOR * (atol + rtol |x|), ten times
# the integrator's local error tolerance, from one cycle to the next count as
# converged to round-off (their ratio of differences would be noise).
NOISE_FACTOR = 10.0
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
def last_four(hist, k, n_cycles):
    """Observable ``k`` over the last four cycles, oldest first."""
    return (
        history_value(hist, k, n_cycles, 3),
        history_value(hist, k, n_cycles, 2),
        history_value(hist, k, n_cycles, 1),
        history_value(hist, k, n_cycles, 0),
    )


@jit_inline
def last_four_ptp(hist, nb, i, n_cycles):
    """Peak-to-peak ℓ_i (rows i and nb + i of ``hist``) over the last four cycles."""
    a0, a1, a2, a3 = last_four(hist, i, n_cycles)
    b0, b1, b2, b3 = last_four(hist, nb + i, n_cycles)
    return a0 - b0, a1 - b1, a2 - b2, a3 - b3


@jit_inline
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


@jit_inline
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
            a = max(
                a,
                history_value(hist, i, n_cycles, back)
                - history_value(hist, nb + i, n_cycles, back),
            )
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


@jit_inline
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


@jit_inline
def simple_cycle_within_spread(hist, n_cycles, nb, accuracy, rtol, atol, limits):
    """Convergence of a run to a simple cycle with the spread test of
    :func:`classes_convergence` (a cycle known to within ``accuracy`` whose
    cycle-to-cycle values wander at the noise floor or with a faint modulation,
    where the extrapolation's ratio test fails). Asked only of runs unsettled at
    their end, so no run that settles by extrapolation changes."""
    if n_cycles < STEADY_TERMS:
        return np.inf
    return classes_convergence(hist, n_cycles, nb, 1, accuracy, rtol, atol, limits, True)
