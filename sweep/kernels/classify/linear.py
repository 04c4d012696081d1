"""Linear-regime verdicts: an oscillation small enough to be linear, whose envelope
grows or decays at the rate the linear theory gives (``P_LIN_GROWTH``), is labelled
by that rate without waiting for its limit.

Near a critical point the envelope changes by |κ − κc|/(2A) per D0/V, so the cycle
sequences converge (or reach the cap) only after ~10/rate D0/V: 10⁴–10⁵ D0/V at 10⁻⁴
of Kc. The rate itself is known after a few dozen cycles: the least-squares slope of
ln(peak-to-peak ℓ) against the events' times (:func:`envelope_rate`). Asked only where
``S_LINEAR_VERDICTS`` is set (refinement's runs, ``refine.full_runs: false``), by
:func:`cycle.close_cycle` when no other verdict holds. Two verdicts, each needing every
block's envelope (a block resting on steady sliding, below ``steady_amp``, is left out)
and, with several blocks, the in-phase amplitude to follow the linear rate λ within
``RATE_TOLERANCE`` (|slope − λ| + ``RATE_SIGMAS`` standard errors) over the last
``LINEAR_TERMS`` cycles, all of them below ``LINEAR_AMPLITUDE`` (the classifier's
linear regime):

* **steady** where λ < 0: a decay at a linearly stable steady state's rate, in the
  linear regime, where the nonlinear terms (measured: below the tolerance) only
  shrink as the amplitude does. The same evidence as the steady verdict by λ1 at
  ``max_t_end`` (``verdicts.final_regime``), known earlier.
* **undecided** where λ > 0 and the run cannot leave the linear regime before the
  time it would stop (``horizon``, ``max_t_end``): the peak-to-peak ℓ extrapolated at
  (1 + ε) λ (ε the measured relative deviation) stays below ``LINEAR_AMPLITUDE``, and
  the deviation, grown as the fourth power of the amplitude, stays below
  ``GROWTH_MARGIN``: the envelope still grows there at more than half the linear rate.
  (The leading nonlinear term of an oscillation's amplitude equation is cubic at a
  generic Hopf bifurcation, a deviation growing as the square of the amplitude, and
  quintic at a degenerate one, as the quasi-static model's at Kc: the fourth power.)
  Such a run reaches neither the cap (runaway) nor a cycle (its sequences do not
  converge while they grow), and in the linear regime no λ1 verdict applies
  (``attractor_verdict``): the full run would end ``undecided``, the label given here.
  A bounded cycle the run could reach before the horizon (weakly coupled or unequal
  blocks just below Kc, physics brief §4) bends its envelope already where it is
  measured: the test refuses it.
"""

import math

import numpy as np

from ...accelerate import jit
from ..layout import STEADY, UNDECIDED
from .sequences import LINEAR_AMPLITUDE, span_ptp
from .state import history_value

#: Cycles the envelope's rate is fitted over (the last ones).
LINEAR_TERMS = 16
#: Largest relative deviation of the fitted rate from the linear theory's, standard
#: errors included (two quasi-static blocks near Kc: below 1e-3 once the anti-phase
#: mode has decayed).
RATE_TOLERANCE = 0.01
#: Standard errors of the fitted slope added to its deviation.
RATE_SIGMAS = 3.0
#: Largest relative deviation of the growth rate, extrapolated to the horizon, that
#: still leaves the run growing: an undecided verdict needs ε F⁴ ≤ this (F: the
#: amplitude's growth factor up to the horizon).
GROWTH_MARGIN = 0.5


@jit
def series_amplitude(hist, s, nb, n_cycles, back):
    """The amplitude of series ``s`` in the cycle ``back`` cycles before the last: the
    peak-to-peak ℓ_s of block s < nb, else the peak-to-peak of the mean ℓ_i (in phase)."""
    if s < nb:
        return history_value(hist, s, n_cycles, back) - history_value(hist, nb + s, n_cycles, back)
    return history_value(hist, 2 * nb + 1, n_cycles, back)


@jit
def envelope_rate(hist, s, nb, n_cycles, m):
    """``(slope, standard error)`` of the least-squares fit of ln(amplitude) of series
    ``s`` (:func:`series_amplitude`) against the times of the events that close the
    last ``m`` cycles (V/D0); NaN where an amplitude is not positive."""
    t = 0.0
    st = 0.0
    sy = 0.0
    for back in range(m):
        a = series_amplitude(hist, s, nb, n_cycles, back)
        if not (a > 0.0):
            return np.nan, np.nan
        st += t
        sy += math.log(a)
        t -= history_value(hist, 2 * nb, n_cycles, back)
    t_mean = st / m
    y_mean = sy / m
    stt = 0.0
    sty = 0.0
    syy = 0.0
    t = 0.0
    for back in range(m):
        dt = t - t_mean
        dy = math.log(series_amplitude(hist, s, nb, n_cycles, back)) - y_mean
        stt += dt * dt
        sty += dt * dy
        syy += dy * dy
        t -= history_value(hist, 2 * nb, n_cycles, back)
    slope = sty / stt
    residual = max(syy - slope * sty, 0.0)
    return slope, math.sqrt(residual / (m - 2) / stt)


@jit
def linear_verdict(hist, n_cycles, nb, lin_growth, t, horizon, steady_amp):
    """STEADY, UNDECIDED or −1 (none) for a run at the event at ``t`` (D0/V) that would
    stop at ``horizon`` (D0/V; 0: no linear verdicts), from its last ``LINEAR_TERMS``
    cycles (module docstring). ``lin_growth``: the linear theory's rate (V/D0)."""
    if not (horizon > 0.0 and n_cycles >= LINEAR_TERMS and lin_growth != 0.0):
        return -1
    if not (abs(lin_growth) < np.inf):
        return -1
    m = LINEAR_TERMS
    big = span_ptp(hist, n_cycles, nb, m)
    if not (big < LINEAR_AMPLITUDE):
        return -1
    span = max(horizon - t, 0.0)
    if lin_growth > 0.0 and not (big * math.exp(lin_growth * span) < LINEAR_AMPLITUDE):
        return -1  # it would leave the linear regime even at the linear rate
    if not (series_amplitude(hist, 0, nb, n_cycles, 0) >= steady_amp):
        return -1
    worst = 0.0
    for s in range(nb + 1 if nb > 1 else 1):
        if s > 0:
            rest = True  # a block resting on steady sliding has no rate to give
            for back in range(m):
                if series_amplitude(hist, s, nb, n_cycles, back) >= steady_amp:
                    rest = False
            if rest:
                continue
        slope, error = envelope_rate(hist, s, nb, n_cycles, m)
        eps = (abs(slope - lin_growth) + RATE_SIGMAS * error) / abs(lin_growth)
        if not (eps <= RATE_TOLERANCE):
            return -1
        worst = max(worst, eps)
    if lin_growth < 0.0:
        return STEADY
    growth = math.exp(lin_growth * (1.0 + worst) * span)
    if big * growth < LINEAR_AMPLITUDE and worst * growth**4 <= GROWTH_MARGIN:
        return UNDECIDED
    return -1
