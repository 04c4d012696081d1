"""The slip-event catalogue of each run and its statistics, in physical units.

The kernels write each run's catalogue as it goes (``kernels/slip_events.py``: what an
event is, how its slip is integrated); here it becomes output variables along a
``slip_event`` dimension and the statistics of each run:

- ``magnitude`` m = (2/3) log10(S/D0) of an event of summed slip S: the moment
  magnitude's scaling of a moment-like size (S × block area × shear modulus, all
  blocks alike), so that a Gutenberg–Richter b-value of 1 is a cumulative size
  distribution N(≥ S) ∝ S^(−2/3);
- the b-value by the Aki–Utsu maximum-likelihood estimate over the events with
  m ≥ m_c, b = log10(e) / (mean(m) − m_c) (continuous magnitudes: no bin
  correction), with the Shi & Bolt (1982) standard error
  2.30 b² √(Σ(m − mean m)² / (n (n − 1)));
- the mean and coefficient of variation (sample standard deviation / mean) of the
  intervals between the starts of system-wide events (every block slipped), and the
  fraction of events that are system-wide;
- the number of events in each magnitude bin (:data:`MAGNITUDE_EDGES`).

Statistics are over the events a run kept (its first ``catalogue.capacity`` after
the transient). No library is used: the estimates are a few lines of numpy over
every run at once (``powerlaw`` fits one sample at a time and answers a different
question, the power law's range).
"""

import math

import numpy as np
import xarray as xr

from ..kernels import layout
from .checks import check_result

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


def magnitude(slip_over_d0):
    """Magnitude (2/3) log10(S/D0) of events of summed slip S (module docstring); NaN
    where no event."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 / 3.0 * np.log10(slip_over_d0)


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
    in physical units: times in s from the run's start, slip in um, velocities in um/s
    (``grid``: the :class:`~sweep.engine.grid.Grid` the kernels ran)."""
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
    completeness = grid.config.catalogue.completeness
    fields |= statistics(
        fields["slip_event_magnitude"],
        fields["slip_event_blocks"],
        fields["slip_event_start"],
        grid.config.blocks,
        completeness,
    )
    return fields


def statistics(mag, blocks, start, nb, completeness=None):
    """The statistics of each run (module docstring) from its events' magnitudes,
    blocks that slipped and start times (s), arrays (runs, events) with NaN / −1 where
    none; ``nb`` blocks; ``completeness``: m_c (None: each run's smallest magnitude).
    Returns flat arrays per run."""
    kept = ~np.isnan(mag)
    with np.errstate(invalid="ignore", divide="ignore"):
        if completeness is None:
            mc = np.min(np.where(kept, mag, np.inf), axis=1, initial=np.inf)
            mc[~np.isfinite(mc)] = np.nan
        else:
            mc = np.full(len(mag), float(completeness))
        above = kept & (mag >= mc[:, None])
        n = above.sum(axis=1)
        mean = np.where(above, mag, 0.0).sum(axis=1) / n
        b = np.log10(np.e) / (mean - mc)
        spread = np.where(above, (mag - mean[:, None]) ** 2, 0.0).sum(axis=1)
        b_err = 2.30 * b**2 * np.sqrt(spread / (n * (n - 1.0)))
        ok = n >= 2
        whole = kept & (blocks == nb)
        mean_int, cv = recurrence(np.where(whole, start, np.nan))
        frac = whole.sum(axis=1) / kept.sum(axis=1)
    lo, hi = MAGNITUDE_EDGES[0], MAGNITUDE_EDGES[-1]
    counts = [
        np.histogram(np.clip(m[k], lo, hi), MAGNITUDE_EDGES)[0]
        for m, k in zip(mag, kept, strict=True)
    ]
    return {
        "b_value": np.where(ok, b, np.nan),
        "b_value_error": np.where(ok, b_err, np.nan),
        "magnitude_completeness": mc,
        "recurrence_mean": mean_int,
        "recurrence_cv": cv,
        "system_wide_fraction": frac,
        "magnitude_count": np.reshape(counts, (len(mag), len(MAGNITUDE_EDGES) - 1)),
    }


def recurrence(starts):
    """Mean and coefficient of variation (sample standard deviation / mean) of the
    intervals between successive finite values of each row of ``starts`` (NaN: not an
    event of interest); NaN with fewer than two intervals."""
    means = np.full(len(starts), np.nan)
    cvs = np.full(len(starts), np.nan)
    for r, row in enumerate(starts):
        intervals = np.diff(row[np.isfinite(row)])
        if intervals.size >= 2:
            means[r] = intervals.mean()
            cvs[r] = intervals.std(ddof=1) / means[r]
    return means, cvs


def catalogue_statistics(ds: xr.Dataset, completeness: float | None = None) -> xr.Dataset:
    """The statistics of every run of a result with a catalogue, recomputed from its
    ``slip_event_*`` variables (e.g. with another completeness magnitude).

    Parameters
    ----------
    ds : xarray.Dataset
        A result with a catalogue (config key ``catalogue.capacity``), in memory or
        opened from its file.
    completeness : float, optional
        The magnitude m_c above which the b-value is estimated (default: each run's
        smallest magnitude).

    Returns
    -------
    xarray.Dataset
        ``b_value``, ``b_value_error``, ``magnitude_completeness``, ``recurrence_mean``
        (s), ``recurrence_cv``, ``system_wide_fraction`` and ``magnitude_count`` over the
        result's sweep axes (and members).

    Raises
    ------
    TypeError
        ``ds`` is not a Dataset.
    ValueError
        ``ds`` is not a complete result, has no catalogue, or ``completeness`` is not
        finite.
    """
    check_result(ds)
    if "slip_event_magnitude" not in ds:
        raise ValueError("this result has no slip-event catalogue (config key catalogue.capacity)")
    if completeness is not None and not math.isfinite(completeness):
        raise ValueError(f"completeness must be a finite magnitude, got {completeness!r}")
    mag = ds["slip_event_magnitude"]
    dims = mag.dims[:-1]
    flat = {
        name: ds[name].transpose(*dims, "slip_event").values.reshape(-1, ds.sizes["slip_event"])
        for name in ("slip_event_magnitude", "slip_event_blocks", "slip_event_start")
    }
    blocks = np.where(
        np.isnan(flat["slip_event_blocks"].astype(float)), -1, flat["slip_event_blocks"]
    )
    stats = statistics(
        flat["slip_event_magnitude"],
        blocks,
        flat["slip_event_start"],
        int(ds.attrs["blocks"]),
        completeness,
    )
    shape = tuple(ds.sizes[d] for d in dims)
    out = {}
    for name, values in stats.items():
        if name == "magnitude_count":
            out[name] = (dims + ("magnitude",), values.reshape(shape + (-1,)))
        else:
            out[name] = (dims, values.reshape(shape))
    return xr.Dataset(out, coords={d: ds[d] for d in dims + ("magnitude",) if d in ds.coords})
