"""The catalogue's statistics on synthetic catalogues (issue 53), no kernel: the
Gutenberg–Richter fits and when they are refused, the truncated fit, the
characteristic-event diagnostic, the recurrence's intervals, the moment magnitude and
the config keys. Every expectation is a theory, a hand formula or SciPy."""

import math

import numpy as np
import pytest
import scipy.optimize
import scipy.stats
from conftest import make_config

from sweep.codes import B_VALUE_STATUSES, RECURRENCE_STATUSES
from sweep.config import ConfigError
from sweep.engine.grid import build_grid
from sweep.kernels import layout
from sweep.results import gutenberg_richter as gr
from sweep.results.catalogue_statistics import catalogue_fields, recurrence, statistics

LN10 = math.log(10.0)


def gr_sample(n, b, seed, m_max=None):
    """``n`` continuous magnitudes ≥ 0 of a Gutenberg–Richter law of ``b`` (truncated
    at ``m_max`` if given), drawn by inverse CDF."""
    q = np.random.default_rng(seed).random(n)
    beta = b * LN10
    if m_max is None:
        return -np.log1p(-q) / beta
    return -np.log1p(-q * (1.0 - math.exp(-beta * m_max))) / beta


def one_run(mag, completeness=0.0, extent=None, start=None, nb=10):
    """The statistics of one run of magnitudes ``mag`` (all events spanning 1 block
    unless ``extent`` is given)."""
    mag = np.asarray(mag, float)[None]
    extent = np.ones_like(mag) if extent is None else np.asarray(extent, float)[None]
    start = np.arange(mag.size, dtype=float)[None] if start is None else np.asarray(start)[None]
    return {k: v[0] for k, v in statistics(mag, extent, start, nb, completeness).items()}


def status(name):
    return B_VALUE_STATUSES.index(name)


def test_gutenberg_richter_sample_is_accepted_with_the_right_b():
    """3000 magnitudes of b = 1 above m_c = 0: b within two standard errors of 1 and of
    SciPy's exponential fit, the law accepted (p ≥ 0.1; p is uniform under the law,
    so one sample in ten would be rejected: this seed's is not), the KS distance
    SciPy's."""
    m = gr_sample(3000, 1.0, seed=7)
    s = one_run(m)
    assert s["b_value_status"] == status("ok")
    assert abs(s["b_value"] - 1.0) < 2 * s["b_value_error"]
    loc, scale = scipy.stats.expon.fit(m, floc=0.0)
    assert s["b_value"] == pytest.approx(math.log10(math.e) / scale, rel=1e-12)
    assert s["b_value_error"] == pytest.approx(1.0 / math.sqrt(3000), rel=0.1)  # Aki: b/√n
    assert s["b_value_ks_p"] >= gr.P_ACCEPT
    mine = gr.ks_distance(np.sort(m)[None], 0.0, s["b_value"] * LN10)[0]
    assert mine == pytest.approx(scipy.stats.kstest(m, "expon", args=(0.0, scale)).statistic)
    assert s["b_value_truncated_status"] == status("ok")  # m_max = 3.8 barely truncates
    assert abs(s["b_value_truncated"] - 1.0) < 2 * s["b_value_truncated_error"]


@pytest.mark.parametrize("seed, mc_from_sample", [(2, False), (1, True)])
def test_gutenberg_richter_p_value_is_scipys(seed, mc_from_sample):
    """The bootstrap p-value agrees with SciPy's own parametric bootstrap of the KS
    statistic (``scipy.stats.goodness_of_fit``, the exponential law refitted to each
    synthetic sample, m_c known or fitted as the smallest value) within Monte Carlo
    error (2500 samples each: p near 0.5 to about ±0.01): 500 magnitudes of b = 1
    blurred by up to 0.04, p between 0.01 and 0.7."""
    rng = np.random.default_rng(seed + 10)
    m = gr_sample(500, 1.0, seed) + 0.04 * rng.random(500)
    known = {} if mc_from_sample else {"loc": 0.0}
    scipy_p = scipy.stats.goodness_of_fit(
        scipy.stats.expon,
        m,
        known_params=known,
        statistic="ks",
        n_mc_samples=2500,
        rng=np.random.default_rng(0),
    ).pvalue
    mine = gr.fit_run(m, m.min() if mc_from_sample else 0.0, mc_from_sample)["b_p"]
    assert 0.01 < scipy_p < 0.7
    assert mine == pytest.approx(scipy_p, abs=0.05)


def test_gutenberg_richter_p_value_rejects_a_wrong_law():
    """Magnitudes whose sizes follow a lognormal law (a curved size-frequency plot)
    are rejected by the bootstrap test, though enough and wide enough."""
    m = np.random.default_rng(3).normal(1.0, 0.5, 2000)
    s = one_run(m[m >= 0.0])
    assert s["b_value_status"] == status("rejected_by_goodness_of_fit")
    assert s["b_value_ks_p"] < gr.P_ACCEPT
    assert np.isnan(s["b_value"]) and np.isnan(s["b_value_error"])


def test_characteristic_sample_is_rejected_with_its_status():
    """Most events near one magnitude (2 ± 0.05), a few small ones spread below: both
    the Gutenberg–Richter and the truncated law are rejected, b is NaN, and the large
    events exceed the Gutenberg–Richter extrapolation (twice over: the Aki–Utsu fit,
    dominated by the peak, has a small b itself)."""
    rng = np.random.default_rng(5)
    m = np.concatenate([rng.normal(2.0, 0.05, 1800), rng.uniform(0.0, 1.9, 200)])
    extent = np.where(m > 1.9, 10, 2)
    s = one_run(m, extent=extent)
    for key in ("b_value", "b_value_truncated"):
        assert s[f"{key}_status"] == status("rejected_by_goodness_of_fit"), key
        assert np.isnan(s[key]) and s[f"{key}_ks_p"] < 0.01
    # the diagnostic by hand: the untruncated Aki-Utsu b whatever the status
    b = math.log10(math.e) / m.mean()
    m_large = m[extent == 10].min()
    expected = m.size * 10 ** (-b * m_large)
    assert s["large_event_magnitude"] == pytest.approx(m_large)
    assert s["large_event_excess"] == pytest.approx((m >= m_large).sum() / expected)
    assert s["large_event_excess"] > 2  # 2.4: the fit to the peak itself has a small b
    size = 10 ** (1.5 * m)
    assert s["system_wide_size_share"] == pytest.approx(size[extent == 10].sum() / size.sum())


def test_too_few_events_no_events_and_narrow_span():
    """Each condition's status, checked in order: no events; fewer than 200 above m_c;
    a span below one unit (500 events of b = 1 cut at m = 0.8)."""
    assert one_run([np.nan] * 5)["b_value_status"] == status("no_events")
    few = one_run(gr_sample(gr.MIN_EVENTS - 1, 1.0, seed=1))
    assert few["b_value_status"] == status("too_few_events")
    assert np.isnan(few["b_value"]) and np.isnan(few["b_value_ks_p"])
    enough = one_run(gr_sample(gr.MIN_EVENTS, 1.0, seed=1))
    assert enough["b_value_status"] != status("too_few_events")
    narrow = one_run(gr_sample(500, 1.0, seed=2, m_max=0.8))
    assert narrow["b_value_status"] == status("span_below_one_unit")
    assert narrow["b_value_truncated_status"] == status("span_below_one_unit")
    assert np.isnan(narrow["b_value_truncated"])
    above = one_run(gr_sample(400, 1.0, seed=2), completeness=5.0)  # none above m_c
    assert above["b_value_status"] == status("no_events")


def test_truncated_fit_recovers_b_and_matches_a_direct_likelihood():
    """A doubly truncated sample (b = 1 between 0 and 1.5, 3000 events): Page's b within
    two of its standard errors of 1 while the untruncated Aki–Utsu b is biased high;
    β̂ is where SciPy maximises the truncated law's log-likelihood; the standard error is
    the spread of the estimate over 300 samples of 300 events within 15 %."""
    m = gr_sample(3000, 1.0, seed=11, m_max=1.5)
    s = one_run(m)
    assert s["b_value_truncated_status"] == status("ok")
    assert abs(s["b_value_truncated"] - 1.0) < 2 * s["b_value_truncated_error"]
    assert s["b_value_status"] == status("rejected_by_goodness_of_fit")  # bent down
    span = m.max()

    def minus_log_likelihood(beta):
        return -(m.size * math.log(beta / -math.expm1(-beta * span)) - beta * m.sum())

    best = scipy.optimize.minimize_scalar(minus_log_likelihood, (0.5, 5.0), tol=1e-12)
    assert s["b_value_truncated"] * LN10 == pytest.approx(best.x, rel=1e-6)
    estimates = [
        float(gr.truncated_beta(x.mean(), x.max())) / LN10
        for x in (gr_sample(300, 1.0, seed=100 + i, m_max=1.5) for i in range(300))
    ]
    error = gr.truncated_error(LN10, 1.5, 300)
    assert np.std(estimates) == pytest.approx(error, rel=0.15)


def test_truncated_fit_of_a_density_growing_towards_the_top():
    """The truncated law takes negative b (more large events than small ones): a
    sample drawn with b = −0.5 between 0 and 2 gives it back within two errors."""
    m = gr_sample(3000, -0.5, seed=4, m_max=2.0)
    s = one_run(m)
    assert s["b_value_truncated_status"] == status("ok")
    assert abs(s["b_value_truncated"] + 0.5) < 2 * s["b_value_truncated_error"]


def test_recurrence_intervals_cover_the_truth():
    """Gamma intervals (mean 10, CV 0.5), 30 per run, 200 runs: the Student-t interval
    covers the mean in about 95 % of them (at least 90 %), the bootstrap interval the
    CV in at least 80 % (a percentile interval of 30 intervals is short)."""
    rng = np.random.default_rng(2)
    runs, n, shape = 200, 30, 4.0
    intervals = rng.gamma(shape, 10.0 / shape, (runs, n))
    starts = np.concatenate([np.zeros((runs, 1)), np.cumsum(intervals, axis=1)], axis=1)
    rng.permuted(starts, axis=1, out=starts)  # stored in any order
    r = recurrence(starts)
    assert (r["recurrence_intervals"] == n).all()
    assert (r["recurrence_status"] == RECURRENCE_STATUSES.index("ok")).all()
    np.testing.assert_allclose(r["recurrence_mean"], intervals.mean(axis=1), rtol=1e-12)
    sd = intervals.std(axis=1, ddof=1)
    np.testing.assert_allclose(r["recurrence_cv"], sd / intervals.mean(axis=1), rtol=1e-12)
    low, high = scipy.stats.t.interval(0.95, n - 1, intervals.mean(axis=1), sd / math.sqrt(n))
    np.testing.assert_allclose(r["recurrence_mean_low"], low, rtol=1e-12)
    np.testing.assert_allclose(r["recurrence_mean_high"], high, rtol=1e-12)
    covered = (r["recurrence_mean_low"] <= 10.0) & (10.0 <= r["recurrence_mean_high"])
    assert covered.mean() >= 0.90
    cv = 1.0 / math.sqrt(shape)
    covered = (r["recurrence_cv_low"] <= cv) & (cv <= r["recurrence_cv_high"])
    assert covered.mean() >= 0.80


def test_recurrence_needs_ten_intervals():
    """Nine intervals: NaN and too_few_intervals; ten: given; none: no_system_wide_events."""
    starts = np.full((3, 12), np.nan)
    starts[0, :10] = np.arange(10.0)
    starts[1, :11] = np.arange(11.0)
    r = recurrence(starts)
    assert np.isnan(r["recurrence_mean"][0]) and np.isnan(r["recurrence_cv_high"][0])
    assert r["recurrence_mean"][1] == 1.0 and r["recurrence_cv"][1] == 0.0
    names = [RECURRENCE_STATUSES[c] for c in r["recurrence_status"]]
    assert names == ["too_few_intervals", "ok", "no_system_wide_events"]
    assert list(r["recurrence_intervals"]) == [9, 10, 0]


def test_system_wide_by_extent():
    """With 12 blocks and the default 0.9, events spanning 11 or 12 blocks are
    system-wide (11 ≥ 10.8), 10 is not; a fraction of 1 asks for every block."""
    mag = np.array([[0.1, 0.2, 0.3, 0.4]])
    extent = np.array([[12, 11, 10, 5]])
    start = np.array([[0.0, 1.0, 2.0, 3.0]])
    assert statistics(mag, extent, start, 12)["system_wide_fraction"][0] == 0.5
    assert statistics(mag, extent, start, 12, None, 1.0)["system_wide_fraction"][0] == 0.25


def catalogue_config(**catalogue):
    return make_config(
        {
            "blocks": 2,
            "coupling": "chain",
            "parameters": {"k2_W": 0.1, "eta_W": 0.05},
            "model": "quasi-dynamic",
            "sweep": {"K_W": [0.02, 0.03]},
            "catalogue": {"capacity": 3} | catalogue,
        }
    )


def test_moment_magnitude_by_hand():
    """G = 30 GPa, a = 1 km², an event of 2 um of summed slip: M0 = 3e10 × 1e6 × 2e-6 =
    6e10 N·m and Mw = (2/3)(log10 6e10 − 9.1) = 1.119 (IASPEI 2005); its magnitude
    (2/3) log10(2/D0) with D0 = 1 um differs from Mw by (2/3)(log10(G a D0) − 9.1)."""
    config = catalogue_config(shear_modulus=3e10, block_area=1e6)
    grid = build_grid(config)
    results = np.full((2, layout.result_width(grid.settings)), np.nan)
    start = layout.catalogue_start(grid.settings)
    results[:, start] = 1
    event = results[:, start + 1 : start + 1 + layout.N_EVENT_FIELDS]
    event[:, [layout.E_T_START, layout.E_T_END, layout.E_SLIP]] = [0.0, 1.0, 2.0]
    event[:, [layout.E_LNV_PEAK, layout.E_FIRST_BLOCK, layout.E_N_BLOCKS]] = [3.0, 0, 2]
    event[:, [layout.E_EXTENT, layout.E_BLOCK_LO, layout.E_BLOCK_HI]] = [2, 0, 1]
    f = catalogue_fields(grid, results)
    assert f["slip_event_moment"][0, 0] == pytest.approx(6e10)
    assert f["slip_event_moment_magnitude"][0, 0] == pytest.approx(1.1188, abs=1e-4)
    offset = 2 / 3 * (math.log10(3e10 * 1e6 * 1e-6) - 9.1)
    assert f["moment_magnitude_offset"][0] == pytest.approx(offset)
    assert f["slip_event_moment_magnitude"][0, 0] - f["slip_event_magnitude"][0, 0] == (
        pytest.approx(offset)
    )
    assert "moment" in config.features and "moment" not in catalogue_config().features


@pytest.mark.parametrize(
    "catalogue, says",
    [
        ({"shear_modulus": 3e10}, "catalogue.shear_modulus needs catalogue.block_area"),
        ({"block_area": 1e6}, "catalogue.block_area needs catalogue.shear_modulus"),
        ({"shear_modulus": -1.0, "block_area": 1e6}, "catalogue.shear_modulus"),
        ({"shear_modulus": 3e10, "block_area": 0.0}, "catalogue.block_area"),
        ({"system_wide_extent": 0.0}, "catalogue.system_wide_extent"),
        ({"system_wide_extent": 1.5}, "catalogue.system_wide_extent"),
    ],
)
def test_bad_moment_and_extent_settings_are_refused(catalogue, says):
    with pytest.raises(ConfigError, match=says):
        catalogue_config(**catalogue)
