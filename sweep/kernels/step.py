"""The step record and the interpolant read from it.

A :class:`Step` holds the arrays of the step just taken: the state before and after,
the slopes there, and the coefficients r5 … r8 of the step's interpolant beyond the
cubic; its time t and size h go beside it. The loop builds one record per run (every
step reuses its arrays) and hands it to the classifier, the recorder and the runaway
test, which need no method: every method's interpolant is the one nested polynomial
of :func:`dense_value` (DOPRI5's continuous extension of order 4 has r5, DOP853's of
order 7 all four, the cubic Hermite interpolant of RK4 and RODAS4 none), and the
method says which bound its extrema obey (``bound``: :data:`PROVED` or
:data:`MEASURED`, :func:`excursion`).
"""

import math
from collections import namedtuple

from ..accelerate import jit, jit_inline

#: Rows of the interpolant's coefficients in ``Step.dense``: r5, r6, r7 and r8.
DENSE_ROWS = 4

#: The step just taken: ``y`` → ``ynew`` (state before and after), ``f``, ``fnew`` (their
#: slopes, per D0/V), ``dense`` (DENSE_ROWS, n): the interpolant's coefficients r5 … r8 of
#: each component (rows a method does not fill stay zero), ``bound``: the excursion bound
#: its interpolant obeys (:data:`PROVED` or :data:`MEASURED`).
Step = namedtuple("Step", ["y", "ynew", "f", "fnew", "dense", "bound"])


@jit_inline
def dense_tail(s, j):
    """Coefficients (r5, r6, r7, r8) of the interpolant of component ``j`` of step ``s``."""
    d = s.dense
    return (d[0, j], d[1, j], d[2, j], d[3, j])


@jit_inline
def dense_mix(a, r, b, s):
    """The coefficients r5 … r8 of a r + b s (a linear combination of components)."""
    return (a * r[0] + b * s[0], a * r[1] + b * s[1], a * r[2] + b * s[2], a * r[3] + b * s[3])


@jit_inline
def dense_value(y0, y1, d0, d1, h, r, theta):
    """Interpolant at fraction ``theta`` of a step of size h from (y0, slope d0) to
    (y1, slope d1) with the coefficients ``r`` = (r5, r6, r7, r8) of
    :func:`dense_tail`: y0 + θ(r2 + θ'(r3 + θ(r4 + θ'(r5 + θ(r6 + θ'(r7 + θ r8)))))),
    θ' = 1 − θ, r2 … r4 from the ends. DOPRI5's continuous extension (order 4) has
    r5 only, DOP853's (order 7) all four, the cubic Hermite interpolant (RK4,
    RODAS4) none.

    The extrema of a cycle are read from it: with the cubic Hermite interpolant over
    0.5 D0/V steps they scattered by ~1e-4 of the amplitude from cycle to cycle,
    too much to extrapolate the cycle-to-cycle sequence near Kc
    (test_classification.py); the dense output is as accurate as the steps.
    """
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    r5, r6, r7, r8 = r
    u = 1.0 - theta
    return y0 + theta * (
        r2 + u * (r3 + theta * (r4 + u * (r5 + theta * (r6 + u * (r7 + theta * r8)))))
    )


#: The excursion bounds of :func:`excursion`: proved for an interpolant with r6 = r7 =
#: r8 = 0, or measured.
PROVED, MEASURED = 0, 1
#: How far the interpolant of a step may stray beyond the step's ends where a slope
#: changes sign, in units of the ends' difference plus h × their slopes, for the
#: methods whose bound is :data:`MEASURED`. Measured up to 8.4 for DOP853 on the
#: wiggles of a decayed oscillation, where its interpolant's higher terms dominate
#: (test_kernels.py).
EXCURSION_FACTOR = 10.0
_CUBE_SLOPE = 4.0 / 27.0  # max of θ(1 − θ)² over [0, 1]
_CUBE_CHORD = math.sqrt(3.0) / 18.0  # max of θ(1 − θ)|1 − 2θ| over [0, 1]


@jit_inline
def excursion(bound, y0, y1, d0, d1, h, r5):
    """A bound on how far the interpolant of a step of size h from (y0, slope d0) to
    (y1, slope d1) strays beyond its ends: where a slope changes sign, its extremum lies
    within this distance of them.

    :data:`PROVED`: an interpolant with r6 = r7 = r8 = 0 departs from the chord by
    θθ'(θ' h d0 − θ h d1 − (1 − 2θ)(y1 − y0) + θθ' r5) (:func:`dense_value`; ``r5`` its
    fifth coefficient), and over θ ∈ [0, 1] θθ'² and θ²θ' ≤ 4/27, θθ'|1 − 2θ| ≤ √3/18,
    θ²θ'² ≤ 1/16. :data:`MEASURED`: ``EXCURSION_FACTOR`` × (|y1 − y0| + h (|d0| +
    |d1|)), which reads no coefficient (a method whose coefficients cost stages can
    test it before computing them)."""
    if bound == PROVED:
        return _CUBE_SLOPE * h * (abs(d0) + abs(d1)) + _CUBE_CHORD * abs(y1 - y0) + abs(r5) / 16.0
    return EXCURSION_FACTOR * (abs(y1 - y0) + h * (abs(d0) + abs(d1)))


@jit_inline
def dense_slope(y0, y1, d0, d1, h, r, theta):
    """h × the time derivative of :func:`dense_value` at fraction ``theta``."""
    r2 = y1 - y0
    r3 = h * d0 - r2
    r4 = r2 - h * d1 - r3
    r5, r6, r7, r8 = r
    u = 1.0 - theta
    # DOPRI5's terms first, DOP853's added: with r6 = r7 = r8 = 0 the same numbers
    return (
        r2
        + (u - theta) * r3
        + theta * (2.0 - 3.0 * theta) * r4
        + 2.0 * theta * u * (u - theta) * r5
        + theta * theta * u * (3.0 * u - 2.0 * theta) * r6
        + 3.0 * theta * theta * u * u * (u - theta) * r7
        + theta * theta * theta * u * u * (4.0 * u - 3.0 * theta) * r8
    )


@jit_inline
def dense_extremum(y0, y1, d0, d1, h, r):
    """Fraction θ ∈ [0, 1] of the step where the interpolant's slope vanishes, given
    slopes d0 and d1 of opposite sign: the Illinois variant of false position, which
    keeps the root bracketed and converges superlinearly (~8 slope evaluations where
    bisection to round-off took 50), until the bracket stops shrinking."""
    lo = 0.0
    hi = 1.0
    g_lo = h * d0
    g_hi = h * d1
    rising = d0 > 0.0
    kept = 0  # the end the last step kept (+1: hi, −1: lo); kept twice, its slope is halved
    theta = 0.5
    for _ in range(60):
        theta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        if not (lo < theta < hi):
            break
        g = dense_slope(y0, y1, d0, d1, h, r, theta)
        if g == 0.0:
            break
        if (g > 0.0) == rising:
            lo = theta
            g_lo = g
            if kept == 1:
                g_hi *= 0.5
            kept = 1
        else:
            hi = theta
            g_hi = g
            if kept == -1:
                g_lo *= 0.5
            kept = -1
    return min(max(theta, lo), hi)


@jit
def dense_crossing(y0, y1, d0, d1, h, r, level):
    """Fraction θ of the step where the interpolant rises through ``level``
    (y0 < level ≤ y1; bisection, 50 halvings)."""
    lo = 0.0
    hi = 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if dense_value(y0, y1, d0, d1, h, r, mid) < level:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
