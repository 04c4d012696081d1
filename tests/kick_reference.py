"""An independent reference for the critical kick of one quasi-static block, plain numpy + SciPy.

Written from the physics brief (``shared/physics.md`` §1–4, §5d), not from ``sweep``: one
block, no inertia, no damping, state ℓ = ln(v/V), ψ = ln(VΦ/D0) = ln(Φ/Φss) (Φss = D0/V, 0
at steady sliding), time in D0/V, κ = K D0/W, κc = B − A (Kc/W = (B − A)/D0)::

    ψ' = e^(−ψ) − e^ℓ (aging)   or   −e^ℓ (ℓ + ψ) (slip)
    ℓ' = [κ (1 − e^ℓ) − B ψ'] / A

The kick (the engine's definition): at t = 0, ℓ = ln(kick) with kick = v0/V and ψ = ln(phi0)
with phi0 = Φ/Φss (1: the state unchanged); the spring stretch follows from the force
balance, so nothing else is set. A run "leaves" if ℓ reaches ln(cap) (cap = v_cap/V) before
``t_end``, else it "returns"; its peak is the largest ℓ over the run, t = 0 included.

Findings (SciPy results, not engine output): ``critical_kick(law, 0.03, 0.08, K/Kc, cap,
check_t_end=True)`` (the A, B of configs/oneblock.yaml and slip_law.yaml), LSODA, rtol 1e-10,
t_end 200 D0/V, phi0 = 1, bracket to 1e-4; kick = v0/V, peaks are ln(v/V); "peak 0.99" is
the peak of the kick 0.99 kick_low (ln cap: 13.816 for 1e6, 20.723 for 1e9)::

    slip law       cap 1e6 and cap 1e9 (the same brackets to all digits shown)
    K/Kc   kick_low   kick_high  peak_low  peak 0.99  peak 0.9  peak 0.5
    1.02   2.03253    2.03271    6.330     3.008      1.458     0.020
    1.05   2.10836    2.10854    6.657     3.111      1.526     0.066
    1.1    2.24088    2.24107    6.572     3.279      1.637     0.140
    1.2    2.53076    2.53099    8.512     3.619      1.855     0.285
    1.3    2.85539    2.85564    7.711     3.947      2.067     0.424
    1.5    3.62375    3.62407    11.491    4.617      2.485     0.694
    1.7    4.57630    4.57671    11.066    5.281      2.897     0.956

    aging law      cap 1e6                           cap 1e9
    K/Kc   kick_low   kick_high  peak 0.99   kick_low   kick_high  peak 0.99
    1.001  24.9448    24.9470    13.675      37.2332    37.2365    20.512
    1.01   28.1841    28.1866    13.689      44.5283    44.5322    20.544
    1.02   32.4028    32.4056    13.703      54.7996    54.8044    20.571
    1.05   50.3460    50.3505    13.733      107.650    107.659    20.624
    1.1    112.019    112.029    13.762      382.966    383.000    20.665
    1.3    4332.15    4332.53    13.795      none up to 1e5 (peak 20.090 at 1e5)
    1.7    none up to 1e5 (peak = ln 1e5 = 11.513, the kick itself: κ > B, ℓ'(0) < 0)

- Slip law: a sharp threshold that does not move with the cap (1e6 and 1e9 give the same
  bracket). The run that leaves does so in its first excursion (t < 1 D0/V). The peak
  just below the threshold is not bounded: it grows by about 1.6 per decade of the
  distance δ = 1 − kick/kick_c (K/Kc = 1.3: 3.95, 5.73, 7.28 at δ = 1e-2, 1e-3, 1e-4), so
  peak_low depends on where the bracket falls (6.3 to 11.5 at 1e-4, about 3 to 5 at 1 %);
  the ~1.6 of physics.md §5d is the peak at δ ≈ 0.1 (K/Kc ≈ 1.1).
- Aging law: the threshold is set by the cap: the peak grows smoothly and steeply with the
  kick (about 14 ln(kick) near K/Kc = 1.001, about 2 ln(kick) at 1.3) and is within 1e-3
  of ln cap just below the threshold; the threshold moves with the cap (×1.5 at K/Kc =
  1.001, ×3.4 at 1.1 from cap 1e6 to 1e9). For K/Kc > B/(B − A) = 1.6, ℓ'(0) = (B − κ)
  (kick − 1)/A < 0 and (seen at 1.7) the peak is the kick: only kick ≥ cap leaves.
- LSODA at rtol 1e-10 and 1e-11 and Radau at 1e-10 and 1e-11 agree on every outcome at the
  bracket ends (slip 1.02, 1.3, 1.7; aging 1.001, 1.05, 1.1) and on the peaks within 3e-6.
  t_end 2000 instead of 200 changed no outcome at any bracket end. A scan of 41 kicks from
  1.01 to 1e5 (both laws, both caps, four K/Kc each) switched from returns to leaves once
  and the peaks of the returns grew with the kick: the bisection's single crossing holds.
- Wall time (2 shared cores, niced; ``call_time``): a call that leaves 0.005–0.04 s, one
  that returns near the threshold 0.1–0.35 s (up to 0.8 s under load) with LSODA, Radau
  30–60× slower; a bisection to 1e-4 (about 17 calls) 1–8 s.
"""

import time

import numpy as np
from scipy.integrate import solve_ivp

#: The laws ``kick_outcome`` knows.
LAWS = ("aging", "slip")

#: Default run length (D0/V): see ``kick_outcome``.
T_END = 200.0


def _check_law(law):
    if law not in LAWS:
        raise ValueError(f"law: {law!r} is not a state law; allowed: {', '.join(LAWS)}")


def rhs_and_jacobian(law, A, B, kappa):
    """``(rhs, jac)`` of the log form for ``solve_ivp`` (state ℓ, ψ; time in D0/V).

    Parameters
    ----------
    law : str
        "aging" (dΦ/dt = 1 − vΦ/D0) or "slip" (dΦ/dt = −(vΦ/D0) ln(vΦ/D0)).
    A, B : float
        Rate-and-state parameters (dimensionless).
    kappa : float
        κ = K D0/W (dimensionless).
    """
    _check_law(law)
    aging = law == "aging"

    def dpsi(lnv, psi, v):
        return np.exp(-psi) - v if aging else -v * (lnv + psi)

    def rhs(t, y):
        lnv, psi = y
        v = np.exp(lnv)
        d = dpsi(lnv, psi, v)
        return np.array([(kappa * (1.0 - v) - B * d) / A, d])

    def jac(t, y):
        lnv, psi = y
        v = np.exp(lnv)
        if aging:
            d_l, d_p = -v, -np.exp(-psi)
        else:
            d_l, d_p = -v * (lnv + psi + 1.0), -v
        return np.array([[(-kappa * v - B * d_l) / A, -B * d_p / A], [d_l, d_p]])

    return rhs, jac


def kick_run(
    law, A, B, K_over_Kc, kick, cap=1e6, phi0=1.0, t_end=T_END, method="LSODA", rtol=1e-10
):
    """The SciPy solution of one kick (``solve_ivp`` result), stopped at the cap.

    Events: 0, ℓ rising through ln(cap) (terminal); 1, the maxima of ℓ (ℓ' falling through 0).
    Arguments as in ``kick_outcome``.
    """
    kappa = K_over_Kc * (B - A)
    rhs, jac = rhs_and_jacobian(law, A, B, kappa)
    lncap = np.log(cap)

    def at_cap(t, y):
        return y[0] - lncap

    at_cap.terminal, at_cap.direction = True, 1.0

    def maximum(t, y):
        return rhs(t, y)[0]

    maximum.direction = -1.0
    y0 = [np.log(kick), np.log(phi0)]
    jac_arg = {} if method in ("RK45", "RK23", "DOP853") else {"jac": jac}
    return solve_ivp(
        rhs,
        (0.0, t_end),
        y0,
        method=method,
        rtol=rtol,
        atol=rtol * 1e-2,
        events=(at_cap, maximum),
        **jac_arg,
    )


def kick_outcome(
    law, A, B, K_over_Kc, kick, cap=1e6, phi0=1.0, t_end=T_END, method="LSODA", rtol=1e-10
):
    """Whether a kick from steady sliding leaves (reaches the velocity cap) and its peak.

    Parameters
    ----------
    law : str
        "aging" or "slip".
    A, B : float
        Rate-and-state parameters (dimensionless).
    K_over_Kc : float
        K/Kc with Kc/W = (B − A)/D0 (dimensionless).
    kick : float
        v0/V at t = 0 (dimensionless; ℓ(0) = ln kick).
    cap : float
        v_cap/V (dimensionless): the run leaves when ℓ reaches ln(cap).
    phi0 : float
        Φ/Φss at t = 0 (dimensionless; ψ(0) = ln phi0; 1: the state unchanged).
    t_end : float
        Run length (D0/V). The default 200 decides every outcome measured here: a kick
        that leaves does so in its first excursion (t < 1 D0/V), and the later maxima of ℓ
        of one that returns only shrink (aging law at K/Kc = 1.001 near the threshold: 13.81,
        13.57, 13.34, ... every 18.9 D0/V with cap 1e6, every 24.5 D0/V with cap 1e9; slip
        law: 6.2, 2.0, 1.5, ...), so 200 D0/V covers eight or more of the largest cycles.
        Doubling and multiplying t_end by ten changed no outcome at the bracket ends of the
        findings. Below Kc a tiny kick grows at (κc − κ)/(2A) per D0/V: pass a longer t_end.
    method : str
        ``solve_ivp`` method ("LSODA", "Radau", ...); the Jacobian is passed to implicit ones.
    rtol : float
        Relative tolerance (atol = rtol/100 on ℓ and ψ, both O(1) logs).

    Returns
    -------
    leaves : bool
        ℓ reached ln(cap) before t_end.
    peak_lnv : float
        The largest ln(v/V) of the run (t = 0 and the stop included; ln(cap) if it leaves).
    """
    sol = kick_run(law, A, B, K_over_Kc, kick, cap, phi0, t_end, method, rtol)
    if sol.status < 0:
        raise RuntimeError(f"solve_ivp failed at t = {sol.t[-1]} D0/V: {sol.message}")
    maxima = np.reshape(sol.y_events[1], (-1, 2))[:, 0]
    peak = max(np.log(kick), sol.y[0, -1], *maxima)
    # A maximum just above the cap can rise and fall within one step, unseen by the cap's
    # event; the maxima's event (ℓ' changes sign there) locates it.
    leaves = sol.t_events[0].size > 0 or peak >= np.log(cap)
    peak = np.log(cap) if leaves else peak
    return bool(leaves), float(peak)


def critical_kick(
    law,
    A,
    B,
    K_over_Kc,
    cap=1e6,
    lo=1.0,
    hi=1e5,
    rtol=1e-4,
    phi0=1.0,
    t_end=T_END,
    method="LSODA",
    ode_rtol=1e-10,
    check_t_end=False,
):
    """The smallest kick v0/V that leaves, by bisection in ln(kick) between ``lo`` and ``hi``.

    Parameters
    ----------
    law, A, B, K_over_Kc, cap, phi0, t_end, method : see ``kick_outcome``.
    lo, hi : float
        The kicks v0/V that bound the search (dimensionless).
    rtol : float
        The bracket's relative width: it stops when kick_high/kick_low − 1 ≤ rtol.
    ode_rtol : float
        ``kick_outcome``'s rtol.
    check_t_end : bool
        Rerun the bracket's ends with 2 t_end and raise if an outcome changes.

    Returns
    -------
    (kick_low, kick_high, peak_low, peak_high)
        Kicks (v0/V) that return and leave, kick_high/kick_low − 1 ≤ rtol, and their peaks
        ln(v/V). Nothing in [lo, hi] leaves: (hi, None, peak at hi, None). Already ``lo``
        leaves: (None, lo, None, ln cap).
    """

    def outcome(kick, t):
        return kick_outcome(law, A, B, K_over_Kc, kick, cap, phi0, t, method, ode_rtol)

    left_lo, peak_lo = outcome(lo, t_end)
    if left_lo:
        return None, lo, None, peak_lo
    left_hi, peak_hi = outcome(hi, t_end)
    if not left_hi:
        return hi, None, peak_hi, None
    while hi / lo - 1.0 > rtol:
        mid = np.sqrt(lo * hi)
        left, peak = outcome(mid, t_end)
        if left:
            hi, peak_hi = mid, peak
        else:
            lo, peak_lo = mid, peak
    if check_t_end:
        for kick, expected in ((lo, False), (hi, True)):
            if outcome(kick, 2.0 * t_end)[0] != expected:
                raise RuntimeError(f"kick {kick}: the outcome changes with t_end = {2 * t_end}")
    return float(lo), float(hi), float(peak_lo), float(peak_hi)


def call_time(law, A, B, K_over_Kc, kick, repeat=3, **kwargs):
    """Median wall time (s) of one ``kick_outcome`` call."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        kick_outcome(law, A, B, K_over_Kc, kick, **kwargs)
        times.append(time.perf_counter() - start)
    return float(np.median(times))
