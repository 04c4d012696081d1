"""The slip-event catalogue of each run and its statistics, in physical units.

The kernels write each run's catalogue as it goes (``kernels/slip_events.py``: what an
event is, how its slip is integrated); here it becomes output variables along a
``slip_event`` dimension and the statistics of each run:

- ``magnitude`` m = (2/3) log10(S/D0) of an event of summed slip S: the moment
  magnitude's scaling of a moment-like size (S × block area × shear modulus, all
  blocks alike), so that a Gutenberg–Richter b-value of 1 is a cumulative size
  distribution N(≥ S) ∝ S^(−2/3). With ``catalogue.shear_modulus`` G and
  ``catalogue.block_area`` a also the seismic moment M0 = G a S (N·m, S in m) and the
  moment magnitude Mw = (2/3)(log10 M0 − 9.1) (Hanks & Kanamori 1979 with the constant
  of Kanamori 1977 adopted by IASPEI 2005/2013 for M0 in N·m; Hanks & Kanamori's own
  10.7 for dyne·cm gives 9.05); Mw − m = (2/3)(log10(G a D0) − 9.1), D0 in m, the same
  for every event of a run, so b does not depend on which is used. The statistics use m.
- the Gutenberg–Richter b-value (Aki–Utsu) and a truncated fit (Page 1968), each only
  where the law holds: enough events, a span of at least one unit and a bootstrap
  Kolmogorov–Smirnov test passed (``results/gutenberg_richter.py``), with a status
  saying why not;
- a characteristic-event diagnostic: the share of the summed size (the moment, all
  blocks alike) in system-wide events, and the number of events at or above the
  smallest system-wide magnitude m_L (at least m_c) against the number the
  untruncated Aki–Utsu fit predicts there, n(m ≥ m_c) 10^(−b (m_L − m_c)), b the
  estimate whatever its status;
- the recurrence of system-wide events (extent ≥ ``catalogue.system_wide_extent`` ×
  blocks): from at least :data:`MIN_INTERVALS` intervals between their starts (sorted:
  events are stored in the order they end), the mean with its Student-t 95 % interval
  and the coefficient of variation (sample standard deviation / mean) with a 95 %
  bootstrap percentile interval (Efron & Tibshirani 1993, ch. 13: :data:`N_RESAMPLES`
  resamples of the intervals, seeded: it treats the intervals as independent);
  NaN below, with a status;
- the number of events in each magnitude bin (:data:`MAGNITUDE_EDGES`).

Statistics are over the events a run kept (its first ``catalogue.capacity`` after
the transient).
"""

import math

import numpy as np
import scipy.stats
import xarray as xr

from ..codes import RECURRENCE_STATUSES, code
from ..kernels import layout
from .checks import check_result
from .gutenberg_richter import fit_run

#: Edges of the magnitude bins of ``magnitude_count``: −4 to 4 in steps of 0.2
#: (events beyond them count in the end bins).
MAGNITUDE_EDGES = np.round(np.arange(-4.0, 4.0001, 0.2), 10)
#: The event fields stored as integers (block indices and counts), −1 where no event.
INTEGER_FIELDS = {
    "slip_event_first_block": layout.E_FIRST_BLOCK,
    "slip_event_blocks": layout.E_N_BLOCKS,
    "slip_event_extent": layout.E_EXTENT,
    "slip_event_block_low": layout.E_BLOCK_LO,
    "slip_event_block_high": layout.E_BLOCK_HI,
}
#: Fewest intervals between system-wide events for recurrence statistics.
MIN_INTERVALS = 10
#: Bootstrap resamples of the coefficient of variation's interval, and their seed.
N_RESAMPLES = 2000
SEED = 1993
#: log10 M0 (N·m) at Mw = 0 (IASPEI 2005; Kanamori 1977).
MW_CONSTANT = 9.1
#: The conventions a result states in its attributes.
MAGNITUDE_CONVENTION = (
    "slip_event_magnitude m = (2/3) log10(S/D0), S the event's summed slip, D0 the common "
    "D0: the moment magnitude's scaling of a dimensionless size"
)
MOMENT_MAGNITUDE_CONVENTION = (
    "M0 = G a S (N m; G catalogue_shear_modulus, a catalogue_block_area, S in m); "
    "Mw = (2/3)(log10 M0 - 9.1) (Hanks & Kanamori 1979; constant of Kanamori 1977, IASPEI "
    "2005); Mw - m = (2/3)(log10(G a D0) - 9.1), D0 in m (moment_magnitude_offset)"
)


def magnitude(slip_over_d0):
    """Magnitude (2/3) log10(S/D0) of events of summed slip S (module docstring); NaN
    where no event."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 / 3.0 * np.log10(slip_over_d0)


def moment_magnitude(moment):
    """Moment magnitude Mw = (2/3)(log10 M0 − 9.1) of moments M0 in N·m."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 / 3.0 * (np.log10(moment) - MW_CONSTANT)


def event_table(results, settings):
    """``(count, events)``: the number of slip events of each run and the (runs,
    capacity, N_EVENT_FIELDS) table of those kept (``layout.E_*``, NaN where none), read
    from the kernels' results rows."""
    start = layout.catalogue_start(settings)
    capacity = int(settings[layout.S_CATALOGUE])
    block = results[:, start + 1 : start + 1 + capacity * layout.N_EVENT_FIELDS]
    return results[:, start], block.reshape(len(results), capacity, layout.N_EVENT_FIELDS)


def catalogue_fields(grid, results):
    """The catalogue's output variables as flat arrays (per run, or per run × event),
    in physical units: times in s from the run's start, slip in um, velocities in um/s,
    moments in N·m (``grid``: the :class:`~sweep.engine.grid.Grid` the kernels ran)."""
    count, ev = event_table(results, grid.settings)
    time_unit = grid.time_unit[:, None]
    d0 = grid.physical["D0"] * np.ones(len(results))
    v = grid.physical["V"] * np.ones(len(results))
    fields = {
        "slip_event_count": count,
        "slip_event_start": ev[..., layout.E_T_START] * time_unit,
        "slip_event_duration": (ev[..., layout.E_T_END] - ev[..., layout.E_T_START]) * time_unit,
        "slip_event_slip": ev[..., layout.E_SLIP] * d0[:, None],
        "slip_event_magnitude": magnitude(ev[..., layout.E_SLIP]),
        "slip_event_v_peak": v[:, None] * np.exp(ev[..., layout.E_LNV_PEAK]),
    }
    for name, column in INTEGER_FIELDS.items():
        fields[name] = np.where(np.isnan(ev[..., column]), -1, ev[..., column])
    cat = grid.config.catalogue
    if cat.shear_modulus is not None:
        ga = cat.shear_modulus * cat.block_area
        fields["slip_event_moment"] = ga * fields["slip_event_slip"] * 1e-6  # um to m
        fields["slip_event_moment_magnitude"] = moment_magnitude(fields["slip_event_moment"])
        fields["moment_magnitude_offset"] = moment_magnitude(ga * d0 * 1e-6)
    fields |= statistics(
        fields["slip_event_magnitude"],
        fields["slip_event_extent"],
        fields["slip_event_start"],
        grid.config.blocks,
        cat.completeness,
        cat.system_wide_extent,
    )
    return fields


def statistics(mag, extent, start, nb, completeness=None, system_wide_extent=0.9):
    """The statistics of each run (module docstring) from its events' magnitudes,
    extents (blocks) and start times (s), arrays (runs, events) with NaN / −1 where
    none; ``nb`` blocks; ``completeness``: m_c (None: each run's smallest magnitude);
    ``system_wide_extent``: the fraction of ``nb`` a system-wide event spans at least.
    Returns flat arrays per run."""
    kept = np.isfinite(mag)
    if completeness is None:
        mc = np.min(np.where(kept, mag, np.inf), axis=1, initial=np.inf)
        mc[~np.isfinite(mc)] = np.nan
    else:
        mc = np.full(len(mag), float(completeness))
    fits = [fit_run(m[k], c, completeness is None) for m, k, c in zip(mag, kept, mc, strict=True)]
    out = {
        name: np.array([f[key] for f in fits])
        for name, key in (
            ("b_value", "b"),
            ("b_value_error", "b_error"),
            ("b_value_ks_p", "b_p"),
            ("b_value_status", "b_status"),
            ("b_value_truncated", "b_truncated"),
            ("b_value_truncated_error", "b_truncated_error"),
            ("b_value_truncated_ks_p", "b_truncated_p"),
            ("b_value_truncated_status", "b_truncated_status"),
            ("magnitude_max", "m_max"),
            ("magnitude_events", "n"),
        )
    }
    out["magnitude_completeness"] = mc
    whole = kept & (extent >= system_wide_extent * nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        size = np.where(kept, 10.0 ** (1.5 * np.where(kept, mag, 0.0)), 0.0)  # S/D0
        out["system_wide_fraction"] = whole.sum(axis=1) / kept.sum(axis=1)
        out["system_wide_size_share"] = np.where(whole, size, 0.0).sum(axis=1) / size.sum(axis=1)
        m_large = np.maximum(np.min(np.where(whole, mag, np.inf), axis=1, initial=np.inf), mc)
        m_large[~np.isfinite(m_large)] = np.nan
        observed = (kept & (mag >= m_large[:, None])).sum(axis=1)
        b_raw = np.array([f["b_raw"] for f in fits])
        expected = out["magnitude_events"] * 10.0 ** (-b_raw * (m_large - mc))
        out["large_event_magnitude"] = m_large
        out["large_event_excess"] = observed / expected
    out |= recurrence(np.where(whole, start, np.nan))
    lo, hi = MAGNITUDE_EDGES[0], MAGNITUDE_EDGES[-1]
    counts = [
        np.histogram(np.clip(m[k], lo, hi), MAGNITUDE_EDGES)[0]
        for m, k in zip(mag, kept, strict=True)
    ]
    out["magnitude_count"] = np.reshape(counts, (len(mag), len(MAGNITUDE_EDGES) - 1))
    return out


def recurrence(starts):
    """Recurrence statistics of the finite values of each row of ``starts`` (NaN: not a
    system-wide event), in any order: the number of intervals between successive ones,
    their mean with its 95 % Student-t interval, their coefficient of variation with
    its 95 % bootstrap percentile interval, and a status (``codes.RECURRENCE_STATUSES``);
    NaN with fewer than :data:`MIN_INTERVALS` intervals."""
    names = ("mean", "mean_low", "mean_high", "cv", "cv_low", "cv_high")
    out = {f"recurrence_{k}": np.full(len(starts), np.nan) for k in names}
    n_int = np.zeros(len(starts), dtype=np.int64)
    status = np.zeros(len(starts), dtype=np.int64)
    for r, row in enumerate(starts):
        intervals = np.diff(np.sort(row[np.isfinite(row)]))
        n = n_int[r] = intervals.size
        if n < MIN_INTERVALS:
            why = "too_few_intervals" if np.isfinite(row).any() else "no_system_wide_events"
            status[r] = code(RECURRENCE_STATUSES, why)
            continue
        mean, sd = intervals.mean(), intervals.std(ddof=1)
        half = scipy.stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)
        resampled = intervals[np.random.default_rng(SEED).integers(0, n, (N_RESAMPLES, n))]
        cvs = resampled.std(axis=1, ddof=1) / resampled.mean(axis=1)
        low, high = np.percentile(cvs, [2.5, 97.5])
        for k, value in zip(
            names, (mean, mean - half, mean + half, sd / mean, low, high), strict=True
        ):
            out[f"recurrence_{k}"][r] = value
    out["recurrence_intervals"] = n_int
    out["recurrence_status"] = status
    return out


def catalogue_statistics(ds: xr.Dataset, completeness: float | None = None) -> xr.Dataset:
    """The statistics of every run of a result with a catalogue, recomputed from its
    ``slip_event_*`` variables (e.g. with another completeness magnitude).

    Parameters
    ----------
    ds : xarray.Dataset
        A result with a catalogue (config key ``catalogue.capacity``), in memory or
        opened from its file. System-wide events span at least its
        ``catalogue_system_wide_extent`` × blocks (0.9 where a file predates it).
    completeness : float, optional
        The magnitude m_c above which the b-values are estimated (default: each run's
        smallest magnitude).

    Returns
    -------
    xarray.Dataset
        Over the result's sweep axes (and members), with the attributes a result gives
        them: ``b_value``, ``b_value_error``, ``b_value_ks_p``, ``b_value_status``, their
        ``b_value_truncated*`` counterparts, ``magnitude_completeness``,
        ``magnitude_max``, ``magnitude_events``, ``system_wide_fraction``,
        ``system_wide_size_share``, ``large_event_magnitude``, ``large_event_excess``,
        ``recurrence_mean`` (s) and its ``_low``/``_high`` bounds, ``recurrence_cv`` and
        its bounds, ``recurrence_intervals``, ``recurrence_status`` and
        ``magnitude_count``.

    Raises
    ------
    TypeError
        ``ds`` is not a Dataset.
    ValueError
        ``ds`` is not a complete result, has no catalogue, or ``completeness`` is not
        finite.
    """
    from ..variables import BY_NAME, variable_attrs

    check_result(ds)
    if "slip_event_magnitude" not in ds:
        raise ValueError("this result has no slip-event catalogue (config key catalogue.capacity)")
    if completeness is not None and not math.isfinite(completeness):
        raise ValueError(f"completeness must be a finite magnitude, got {completeness!r}")
    dims = ds["slip_event_magnitude"].dims[:-1]
    flat = {
        name: ds[name].transpose(*dims, "slip_event").values.reshape(-1, ds.sizes["slip_event"])
        for name in ("slip_event_magnitude", "slip_event_extent", "slip_event_start")
    }
    extent = flat["slip_event_extent"].astype(float)
    stats = statistics(
        flat["slip_event_magnitude"],
        np.where(np.isnan(extent), -1, extent),
        flat["slip_event_start"],
        int(ds.attrs["blocks"]),
        completeness,
        float(ds.attrs.get("catalogue_system_wide_extent", 0.9)),
    )
    shape = tuple(ds.sizes[d] for d in dims)
    out = {}
    for name, values in stats.items():
        var = BY_NAME[name]
        trailing = (var.dim,) if var.dim else ()
        data = values.reshape(shape + ((-1,) if var.dim else ())).astype(var.dtype)
        out[name] = (dims + trailing, data, variable_attrs(var))
    return xr.Dataset(out, coords={d: ds[d] for d in dims + ("magnitude",) if d in ds.coords})
