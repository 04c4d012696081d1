"""The end of a cycle: at each event (a maximum of ℓ_0 that counts as a turn) the cycle
just completed goes into the history and is judged (``sequences``), and the next one
starts."""

import math

import numpy as np

from ...accelerate import jit, jit_inline
from ..layout import STICK_SLIP
from .linear import linear_verdict
from .sequences import SEARCH_FACTOR, cycle_verdict, multi_event_verdict
from .state import (
    C_AMP_PREV,
    C_CONV,
    C_EVENTS,
    C_GROWTH,
    C_LAST_ORDER,
    C_LAST_PHASE,
    C_LINEAR,
    C_N_AGREE,
    C_N_CYCLES,
    C_N_PEAKS,
    C_PEAK_VALUE,
    C_PERIOD,
    C_SLIP_EVENTS,
    C_SLIP_SUM,
    C_T_PEAK,
    C_VERDICT,
    C_WIN_MBAR_MAX,
    C_WIN_MBAR_MIN,
    C_WIN_SYNC,
    C_WIN_T_PEAK_LAST,
    HISTORY,
    N_PAST,
    W_LMAX,
    W_LMIN,
    W_T_PEAK,
    X_SLIP_EVENTS,
    X_SLIP_SUM,
    X_SYNC,
    start_cycle,
)


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
def close_cycle(
    t_peak,
    nb,
    win,
    past,
    past_cs,
    hist,
    limits,
    section,
    cs,
    accuracy,
    steady_amp,
    lin_growth,
    rtol,
    atol,
    horizon,
):
    """End the cycle at the maximum of ℓ_0 at ``t_peak`` (D0/V).

    Adds the cycle to the history (``hist``: the classifier's observables; ``past``,
    ``past_cs``: what a reported window spans; ``section``: the blocks' ℓ at the event)
    and judges it: :func:`cycle_verdict`, then, far from a simple cycle,
    :func:`multi_event_verdict` (``limits``: its scratch, (rows of ``hist``,
    MAX_CYCLE_EVENTS)); then, where neither settles it and ``horizon`` > 0 (the time
    the run would stop, D0/V), :func:`linear.linear_verdict`.
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
    linear = 0.0
    if verdict < 0 and horizon > 0.0:
        verdict = linear_verdict(hist, n_cycles, nb, lin_growth, t_peak, horizon, steady_amp)
        linear = 1.0 if verdict >= 0 else 0.0
    cs[C_CONV] = conv
    same = verdict >= 0 and verdict == int(cs[C_VERDICT]) and events == int(cs[C_EVENTS])
    cs[C_N_AGREE] = cs[C_N_AGREE] + 1 if same else 1
    cs[C_LINEAR] = max(cs[C_LINEAR], linear) if same else linear
    cs[C_VERDICT] = verdict
    cs[C_EVENTS] = events
    cs[C_LAST_ORDER] = kuramoto_order(win[W_T_PEAK], t_peak, period, nb)
    t_last = cs[C_WIN_T_PEAK_LAST]
    if nb > 1 and t_last == t_last:
        lag = (t_last - cs[C_T_PEAK]) / period
        cs[C_LAST_PHASE] = lag - math.floor(lag + 0.5)


@jit_inline
def new_event(
    t_peak,
    y,
    p,
    nb,
    A,
    B,
    win,
    past,
    past_cs,
    hist,
    limits,
    section,
    cs,
    accuracy,
    steady_amp,
    lin_growth,
    rtol,
    atol,
    horizon,
):
    """An event, the maximum of ℓ_0 at ``t_peak`` (D0/V), the state now ``y``: from the
    second on, close the cycle it ends (:func:`close_cycle`; ``horizon``: the time the
    run would stop for its linear verdicts, 0: none); start the next one there, its
    highest ℓ_0 the event's. Inlined into the grid kernel's branch at an event: a thin
    wrapper (accelerate.py)."""
    cs[C_N_PEAKS] += 1
    if cs[C_N_PEAKS] >= 2:
        close_cycle(
            t_peak,
            nb,
            win,
            past,
            past_cs,
            hist,
            limits,
            section,
            cs,
            accuracy,
            steady_amp,
            lin_growth,
            rtol,
            atol,
            horizon,
        )
    cs[C_T_PEAK] = t_peak
    start_cycle(y, p, nb, A, B, win, cs)
    win[W_LMAX, 0] = max(win[W_LMAX, 0], cs[C_PEAK_VALUE])
