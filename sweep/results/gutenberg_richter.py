"""Gutenberg–Richter fits of one run's magnitudes, given only where the law holds.

Continuous magnitudes m ≥ m_c (no binning), an exponential density of rate
β = b ln 10 above m_c:

- **Aki–Utsu** (Aki 1965; Utsu 1965): β̂ = 1 / (mean(m) − m_c), with the Shi & Bolt
  (1982) standard error 2.30 b² √(Σ(m − mean m)² / (n (n − 1))).
- **Truncated** (Page 1968, BSSA 58, 1131): the doubly truncated exponential between
  m_c and m_max, m_max the largest magnitude observed (its maximum-likelihood
  estimate, biased low by about the mean gap between the largest events); β̂ solves
  1/β − Δ/(e^{βΔ} − 1) = mean(m) − m_c, Δ = m_max − m_c, and may be negative (a density
  that grows towards m_max: characteristic events). Its standard error is the
  Cramér–Rao bound 1/√(n Var_β(m)) of that law, with m_max held fixed.
- **Goodness of fit** of each: the Kolmogorov–Smirnov distance between the sample and
  the fitted law, its p-value by the parametric bootstrap of Clauset, Shalizi & Newman
  (2009, SIAM Review 51, 661, §4.1): :data:`N_BOOTSTRAP` samples of the fitted law of the
  sample's size, each refitted the same way (m_c, and the truncated law's m_max, taken
  from the synthetic sample where they were taken from the data), p the share of their
  distances at least the observed one. The law is rejected at p < :data:`P_ACCEPT`, as
  they do.

A fit is given (status ``ok``, ``codes.B_VALUE_STATUSES``) only with at least
:data:`MIN_EVENTS` events above m_c, a magnitude span m_max − m_c of at least
:data:`MIN_SPAN` and p ≥ :data:`P_ACCEPT`; otherwise its b-value and error are NaN and
its status says which condition failed first (in that order). The KS p-value is
computed only where the first two hold. The bootstrap draws from a generator seeded
with :data:`SEED` afresh for each run: a run's result does not depend on the others.

No library fits this over many runs: ``scipy.stats.expon.fit`` gives the untruncated
estimate and ``scipy.stats.kstest`` the distance but no p-value for parameters fitted
from the same data (its tables assume a law given in advance, far too lenient here);
``scipy.stats.goodness_of_fit`` does this bootstrap for the untruncated law (the tests
check the p-values agree) but refits one synthetic sample at a time and has no
truncated law of negative b;
``powerlaw`` (Alstott et al. 2014) implements Clauset et al. for one continuous sample
but without the truncated exponential, and would be a new dependency for a loop of
numpy lines.
"""

import math

import numpy as np

from ..codes import B_VALUE_STATUSES, code

#: Fewest events above m_c for a b-value: Nava et al. (2017, J. Seismol. 21, 127)
#: show by Monte Carlo that the Aki–Utsu estimate of smaller samples is often far off;
#: 200 events is the size their results support for b to about ±0.1 (at b = 1 the
#: Aki standard error b/√n is then 0.07).
MIN_EVENTS = 200
#: Smallest span m_max − m_c (magnitude units) over which a law is fitted: a decade of
#: size for each 2/3 unit, and fewer than 1.5 decades say nothing about a power law.
MIN_SPAN = 1.0
#: Smallest KS bootstrap p-value at which the law is accepted (Clauset et al. 2009).
P_ACCEPT = 0.1
#: Synthetic samples of the bootstrap: p to within about ±0.01 (Clauset et al. 2009:
#: ε^−2/4 samples for an accuracy ε), enough near the threshold 0.1.
N_BOOTSTRAP = 2500
#: Seed of the bootstrap's generator (results are deterministic).
SEED = 20090601
#: Most numbers drawn at once (bootstrap samples × events), to bound the memory.
CHUNK = 2_000_000
LN10 = math.log(10.0)


def aki_utsu(m, mc):
    """Aki–Utsu b and its Shi–Bolt error of magnitudes ``m`` (all ≥ ``mc``); NaN below two."""
    n = m.size
    if n < 2:
        return math.nan, math.nan
    mean = m.mean()
    with np.errstate(divide="ignore"):
        b = math.log10(math.e) / (mean - mc) if mean > mc else math.inf
    err = 2.30 * b**2 * math.sqrt(((m - mean) ** 2).sum() / (n * (n - 1.0)))
    return b, err


def _h(u):
    """1/u − 1/(e^u − 1): the truncated law's mean excess over Δ at βΔ = u (decreasing,
    1 at −∞, 1/2 at 0, 0 at +∞)."""
    u = np.asarray(u, dtype=float)
    small = np.abs(u) < 1e-4
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        h = 1.0 / u - 1.0 / np.expm1(u)
    return np.where(small, 0.5 - u / 12.0 + u**3 / 720.0, h)


def truncated_beta(mean_excess, span):
    """β̂ of the doubly truncated exponential (Page 1968) from the mean excess
    mean(m) − m_c and the span Δ = m_max − m_c (arrays): the root of
    1/β − Δ/(e^{βΔ} − 1) = mean excess, by bisection in u = βΔ; ±inf at the ends."""
    r = np.asarray(mean_excess, dtype=float) / np.asarray(span, dtype=float)
    lo, hi = np.full(r.shape, -700.0), np.full(r.shape, 700.0)
    for _ in range(80):  # |u| < 700 halved 80 times: below 1e-21
        mid = 0.5 * (lo + hi)
        above = _h(mid) > r  # h decreases: the root lies higher
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    u = 0.5 * (lo + hi)
    u = np.where(r <= 0.0, np.inf, np.where(r >= 1.0, -np.inf, u))
    return u / span


def truncated_error(beta, span, n):
    """Standard error of the truncated law's b: 1 / (ln 10 √(n Var(m))), Var(m) =
    Δ² (1/u² − 1/(4 sinh²(u/2))) at u = βΔ (Δ²/12 at u = 0)."""
    u = beta * span
    if abs(u) < 1e-3:
        var = span**2 * (1.0 / 12.0 - u**2 / 240.0)
    else:
        var = span**2 * (1.0 / u**2 - 1.0 / (4.0 * math.sinh(u / 2.0) ** 2))
    return 1.0 / (LN10 * math.sqrt(n * var)) if var > 0 else math.nan


def _cdf(x, mc, beta, span):
    """CDF of the exponential law of rate ``beta`` above ``mc`` (span None), or of the
    one truncated at mc + span (broadcast over rows)."""
    z = x - mc
    if span is None:
        return -np.expm1(-beta * z)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f = np.expm1(-beta * z) / np.expm1(-beta * span)
    return np.where(np.abs(beta * span) < 1e-9, z / span, f)


def ks_distance(x, mc, beta, span=None):
    """Kolmogorov–Smirnov distance of each row of sorted ``x`` from the fitted law."""
    n = x.shape[-1]
    f = _cdf(x, mc, beta, span)
    i = np.arange(1, n + 1)
    return np.maximum((i / n - f).max(axis=-1), (f - (i - 1) / n).max(axis=-1))


def _fit(x, mc, mc_from_sample, truncated):
    """The fit of each row of sorted ``x``: ``(mc, beta, span)`` arrays (span None
    untruncated); m_c the row's smallest value where ``mc_from_sample``."""
    mc = x[:, 0] if mc_from_sample else np.full(len(x), mc)
    excess = x.mean(axis=1) - mc
    if not truncated:
        with np.errstate(divide="ignore"):
            return mc, 1.0 / excess, None
    span = x[:, -1] - mc
    return mc, truncated_beta(excess, span), span


def ks_p_value(m, mc, mc_from_sample, truncated, rng):
    """Bootstrap p-value (Clauset et al. 2009) of the fit of sorted magnitudes ``m``:
    the share of :data:`N_BOOTSTRAP` synthetic samples of the fitted law, refitted,
    whose KS distance is at least the data's."""
    n = m.size
    mc0, beta0, span0 = _fit(m[None], mc, mc_from_sample, truncated)
    observed = ks_distance(m[None], mc0[:, None], beta0[:, None], _col(span0))[0]
    beta0, span0 = beta0[0], None if span0 is None else span0[0]
    at_least, rows = 0, max(1, CHUNK // n)
    for done in range(0, N_BOOTSTRAP, rows):
        x = _draw(rng.random((min(rows, N_BOOTSTRAP - done), n)), mc0[0], beta0, span0)
        x.sort(axis=1)
        mc_s, beta_s, span_s = _fit(x, mc, mc_from_sample, truncated)
        d = ks_distance(x, mc_s[:, None], beta_s[:, None], _col(span_s))
        at_least += int((d >= observed).sum())
    return at_least / N_BOOTSTRAP


def _draw(q, mc, beta, span):
    """Magnitudes of the fitted law (truncated at mc + span unless span is None) at
    uniform deviates ``q``: its inverse CDF."""
    if span is None:
        return mc - np.log1p(-q) / beta
    if abs(beta * span) < 1e-9:  # uniform
        return mc + q * span
    return mc - np.log1p(q * np.expm1(-beta * span)) / beta


def _col(a):
    """``a`` as a column (None stays None)."""
    return None if a is None else a[:, None]


def fit_run(mag, mc, mc_from_sample):
    """Both fits of one run's magnitudes ``mag`` (finite, any order) above ``mc``
    (``mc_from_sample``: m_c is the run's smallest magnitude, and the bootstrap's
    samples take theirs likewise). Returns a dict of scalars (module docstring)."""
    m = np.sort(mag[mag >= mc]) if math.isfinite(mc) else np.empty(0)
    n = m.size
    out = {"n": n, "m_max": m[-1] if n else math.nan}
    b, err = aki_utsu(m, mc)
    out["b_raw"] = b  # the estimate whatever the status (the characteristic diagnostic)
    if n >= 2 and m[-1] > mc:
        beta_t = float(truncated_beta(m.mean() - mc, m[-1] - mc))
        b_t, err_t = beta_t / LN10, truncated_error(beta_t, m[-1] - mc, n)
    else:
        b_t, err_t = math.nan, math.nan
    status = _status_before_test(n, m[-1] - mc if n else 0.0)
    for key, truncated, value, error in (("", False, b, err), ("_truncated", True, b_t, err_t)):
        p = math.nan
        s = status
        if s == "ok":
            p = ks_p_value(m, mc, mc_from_sample, truncated, np.random.default_rng(SEED))
            s = "ok" if p >= P_ACCEPT else "rejected_by_goodness_of_fit"
        ok = s == "ok"
        out[f"b{key}"] = value if ok else math.nan
        out[f"b{key}_error"] = error if ok else math.nan
        out[f"b{key}_p"] = p
        out[f"b{key}_status"] = code(B_VALUE_STATUSES, s)
    return out


def _status_before_test(n, span):
    """The status from the sample's size and span alone (``ok``: go on to the test)."""
    if n == 0:
        return "no_events"
    if n < MIN_EVENTS:
        return "too_few_events"
    if span < MIN_SPAN:
        return "span_below_one_unit"
    return "ok"
