"""Per-step extremum tracking: the extremes of every block's ℓ and friction and of the
mean ℓ inside each step (read from the step record's interpolant where they matter),
the turning points that count as events, the slip events, and the cap crossing that
ends a runaway."""

from ...accelerate import jit, jit_forceinline, jit_inline
from ..step import (
    MEASURED,
    dense_crossing,
    dense_extremum,
    dense_mix,
    dense_tail,
    dense_value,
    excursion,
)
from .state import (
    C_IN_EVENT,
    C_LNV_MAX_RUN,
    C_PEAK_VALUE,
    C_SLIP_EVENTS,
    C_SLIP_SUM,
    C_SLIPPING,
    C_WIN_MBAR_MAX,
    C_WIN_MBAR_MIN,
    C_WIN_SYNC,
    C_WIN_T_PEAK_LAST,
    T_HIGH,
    T_LAST,
    T_LOW,
    W_LMAX,
    W_LMIN,
    W_MUMAX,
    W_MUMIN,
    W_T_PEAK,
    block_friction,
)

#: An extremum of ℓ_i counts as a turning point (an event, a block's maximum) only
#: when it stands this many times the local error tolerance atol + rtol |ℓ_i| out of
#: the last counted turn (:func:`count_turn`). Once an oscillation has decayed below
#: the tolerance, the step size controller takes steps as long as its period and
#: sustains wiggles of 10–40 × atol (DOPRI5 and DOP853, K/Kc 1.0–1.2: make bench).
TURN_FACTOR = 100.0


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
    (:func:`step.excursion`) keeps it within the local error scale
    (``TURN_FACTOR`` × the tolerance) of the step's ends and, wherever it lies there,
    it could not count as a turn (:func:`count_turn`): the wiggles of an oscillation
    decayed below the tolerance, which otherwise cost root searches (and DOP853 three
    more stages) at almost every step (``docs/internals.md``)."""
    lo = min(y[i], ynew[i])
    hi = max(y[i], ynew[i])
    least = TURN_FACTOR * (atol + rtol * max(0.0, min(abs(lo), abs(hi)) - span))
    if span > least:
        return True
    if f[i] > 0.0:  # a maximum: could it stand out of the last counted minimum?
        return turns[T_LAST, i] <= 0.0 and hi + span - turns[T_LOW, i] > least
    return turns[T_LAST, i] >= 0.0 and turns[T_HIGH, i] - (lo - span) > least


@jit_inline
def extremum_matters(bound, x0, x1, d0, d1, h, r5, tol):
    """Whether the extremum of a quantity in a step of size h where its slope changes
    sign (from ``x0``, slope ``d0`` to ``x1``, slope ``d1``; ``r5`` the fifth coefficient
    of its interpolant) must be located: unless its excursion bound (:func:`step.excursion`
    of kind ``bound``) is within ``TURN_FACTOR`` × its tolerance ``tol``. For a block's
    friction and the mean ℓ, whose extremes are kept but never counted as turns."""
    return excursion(bound, x0, x1, d0, d1, h, r5) > TURN_FACTOR * tol


@jit_inline
def mean_extremum_matters(bound, m0, m1, dm0, dm1, h, r5, rtol, atol):
    """:func:`extremum_matters` for the mean ℓ of several blocks (from ``m0``, slope
    ``dm0`` to ``m1``, slope ``dm1``) at its tolerance atol + rtol |m1|: one test for the
    kernel, which locates the extremum, and :func:`dense_needed`, which must agree."""
    return extremum_matters(bound, m0, m1, dm0, dm1, h, r5, atol + rtol * abs(m1))


@jit_inline
def friction_tolerance(a_i, b_i, lnv, psi, rtol, atol):
    """The tolerance of a block's friction A_i ℓ_i + B_i ψ_i at ℓ_i = ``lnv``, ψ_i = ``psi``."""
    return a_i * (atol + rtol * abs(lnv)) + b_i * (atol + rtol * abs(psi))


@jit_forceinline
def update_cycle(s, t, h, p, nb, A, B, win, cs, slipped, slip_lnv, turns, rtol, atol):
    """Fold the step ``s`` (``step.Step``) from ``t`` to ``t + h`` into the current cycle's
    statistics.

    Extremes of every block's ℓ and friction are located inside the step with
    its interpolant. Blocks with ℓ_i > ``slip_lnv`` after the step are marked in
    ``slipped`` (``cs[C_SLIPPING]``: whether any is). Returns ``(new_peak, theta)``:
    whether ℓ_0 had a maximum in the step that counts as a turn (:func:`count_turn`
    with tolerances ``rtol``, ``atol``; its value goes to ``cs[C_PEAK_VALUE]``) and
    where, as a fraction of the step.
    """
    y, ynew, f, fnew = s.y, s.ynew, s.f, s.fnew
    new_peak = False
    theta_peak = 0.0
    lnv_max_run = cs[C_LNV_MAX_RUN]
    win_sync = cs[C_WIN_SYNC]
    slipping = 0.0
    for i in range(nb):
        rising = f[i] > 0.0
        falling_now = fnew[i] <= 0.0
        if rising == falling_now:  # slope changed sign: one extremum in the step
            r = dense_tail(s, i)
            span = excursion(s.bound, y[i], ynew[i], f[i], fnew[i], h, r[0])
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
            r_mu = dense_mix(a_i, dense_tail(s, i), b_i, dense_tail(s, nb + i))
            tol = friction_tolerance(a_i, b_i, ynew[i], ynew[nb + i], rtol, atol)
            if extremum_matters(s.bound, mu0, mu, dmu0, dmu1, h, r_mu[0], tol):
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
def dense_needed(s, h, p, nb, A, B, turns, rtol, atol):
    """Whether :func:`update_cycle` or the mean ℓ's extremes read the interpolant of the
    step ``s`` of size h: an extremum of some ℓ_i or friction μ_i in it must be located
    (the same tests, term by term, with the excursion bound that reads no coefficient,
    ``step.MEASURED``), or (several blocks) the mean ℓ's slope changes sign. A method
    whose coefficients cost stages (DOP853: three) computes them only then."""
    y, ynew, f, fnew = s.y, s.ynew, s.f, s.fnew
    need = False
    m0 = 0.0  # the mean ℓ and its slope before and after the step
    m1 = 0.0
    dm0 = 0.0
    dm1 = 0.0
    for i in range(nb):
        if (f[i] > 0.0) == (fnew[i] <= 0.0):
            span = excursion(MEASURED, y[i], ynew[i], f[i], fnew[i], h, 0.0)
            if lnv_extremum_matters(i, span, y, ynew, f, turns, rtol, atol):
                need = True
        a_i, b_i = block_friction(p, nb, i, A, B)
        dmu0 = a_i * f[i] + b_i * f[nb + i]
        dmu1 = a_i * fnew[i] + b_i * fnew[nb + i]
        if (dmu0 > 0.0) == (dmu1 <= 0.0):
            mu0 = a_i * y[i] + b_i * y[nb + i]
            mu = a_i * ynew[i] + b_i * ynew[nb + i]
            tol = friction_tolerance(a_i, b_i, ynew[i], ynew[nb + i], rtol, atol)
            if extremum_matters(MEASURED, mu0, mu, dmu0, dmu1, h, 0.0, tol):
                need = True
        m0 += y[i] / nb
        m1 += ynew[i] / nb
        dm0 += f[i] / nb
        dm1 += fnew[i] / nb
    if nb > 1 and (dm0 > 0.0) == (dm1 <= 0.0):
        if mean_extremum_matters(MEASURED, m0, m1, dm0, dm1, h, 0.0, rtol, atol):
            need = True
    return need


@jit
def event_section(s, h, nb, theta, section):
    """Every block's ℓ at the event at fraction ``theta`` of the step ``s`` of size h
    (its interpolant)."""
    for i in range(nb):
        r = dense_tail(s, i)
        section[i] = dense_value(s.y[i], s.ynew[i], s.f[i], s.fnew[i], h, r, theta)


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


@jit_forceinline
def mean_extremes(s, h, nb, cs, rtol, atol):
    """Fold the extremes of the mean ℓ of the ``nb`` blocks in the step ``s`` of size h
    into the current cycle's (``cs[C_WIN_MBAR_MAX]``, ``cs[C_WIN_MBAR_MIN]``), located
    with the interpolant where they matter (:func:`mean_extremum_matters`)."""
    y, ynew, f, fnew = s.y, s.ynew, s.f, s.fnew
    m0 = 0.0
    m1 = 0.0
    dm0 = 0.0
    dm1 = 0.0
    for i in range(nb):
        m0 += y[i] / nb
        m1 += ynew[i] / nb
        dm0 += f[i] / nb
        dm1 += fnew[i] / nb
    if (dm0 > 0.0) == (dm1 <= 0.0):
        r5 = 0.0
        r6 = 0.0
        r7 = 0.0
        r8 = 0.0
        for i in range(nb):
            r = dense_tail(s, i)
            r5 += r[0] / nb
            r6 += r[1] / nb
            r7 += r[2] / nb
            r8 += r[3] / nb
        if mean_extremum_matters(s.bound, m0, m1, dm0, dm1, h, r5, rtol, atol):
            theta = dense_extremum(m0, m1, dm0, dm1, h, (r5, r6, r7, r8))
            val = dense_value(m0, m1, dm0, dm1, h, (r5, r6, r7, r8), theta)
            cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], val)
            cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], val)
    cs[C_WIN_MBAR_MAX] = max(cs[C_WIN_MBAR_MAX], m1)
    cs[C_WIN_MBAR_MIN] = min(cs[C_WIN_MBAR_MIN], m1)


@jit_forceinline
def classify_step(s, t, h, p, nb, A, B, win, cs, slipped, slip_lnv, turns, rtol, atol):
    """Fold the accepted step ``s`` (``step.Step``) from ``t`` to ``t + h`` into the
    classifier: the extremes of every block (:func:`update_cycle`), whether a slip event
    goes on and, for several blocks, the mean ℓ's extremes. Returns ``(new_peak, theta,
    slip_ended)``: ``new_peak`` and ``theta`` as :func:`update_cycle`; ``slip_ended``,
    whether a slip event ended with the step. The caller then calls
    :func:`event_section` (at a new peak, several blocks) and :func:`end_slip_event`
    from its own body: reached from here, behind these branches, the calls cost the
    arrays they take an incref and a decref every step (numba#2350)."""
    new_peak, theta = update_cycle(
        s, t, h, p, nb, A, B, win, cs, slipped, slip_lnv, turns, rtol, atol
    )
    slip_ended = cs[C_SLIPPING] == 0.0 and cs[C_IN_EVENT] > 0.0
    if cs[C_SLIPPING] > 0.0:
        cs[C_IN_EVENT] = 1.0
    if nb > 1:
        mean_extremes(s, h, nb, cs, rtol, atol)
    return new_peak, theta, slip_ended


@jit
def cap_crossing(s, i, t, h, nb, lnv_cap, win, cs):
    """End a run whose block ``i`` crossed ``lnv_cap`` in the step ``s`` from ``t`` to
    ``t + h``: keep the step (``y`` becomes ``ynew``, the extremes include it) and
    return the time of the crossing (D0/V, interpolated)."""
    y, ynew = s.y, s.ynew
    r = dense_tail(s, i)
    theta = dense_crossing(y[i], ynew[i], s.f[i], s.fnew[i], h, r, lnv_cap)
    tau = t + (0.0 if y[i] > lnv_cap else theta) * h
    for j in range(nb):
        win[W_LMAX, j] = max(win[W_LMAX, j], ynew[j])
    cs[C_LNV_MAX_RUN] = max(cs[C_LNV_MAX_RUN], lnv_cap)
    for j in range(y.size):
        y[j] = ynew[j]
    return tau
