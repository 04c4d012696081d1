"""Basin fractions of an initial-condition ensemble: which attractor each member reached,
matched into attractors per grid point, with the fraction of the members in each.

A result with ``initial.ensemble: M`` holds M runs per grid point from random starts
(``sweep/engine/grid.py``). :func:`basin_fractions` matches their end states into
attractors and counts them, the generic feature-based estimate of basins of attraction
(as ``basins_fractions`` of Attractors.jl does for one system); each fraction comes with
its 95 % Wilson score interval (E. B. Wilson 1927, *Probable inference, the law of
succession, and statistical inference*, J. Am. Stat. Assoc. 22, 209-212; recommended over
the Wald interval by Brown, Cai & DasGupta 2001, *Interval estimation for a binomial
proportion*, Statistical Science 16, 101-133), the interval of a binomial proportion
that keeps its coverage near 95 % for small counts and fractions near 0 or 1
(:func:`wilson_interval`).

Matching. Two members at one point reach the same attractor when they have the same
``regime`` and ``attractor`` kind and, for a periodic run, the same ``cycle_events``,
``period`` and ``lnv_amplitude`` to within twice the classifier's accuracy (file
attribute ``classification_accuracy``: each settled cycle's features are within that of
the limit cycle's, so two runs on one cycle differ by at most twice as much), and the
same sign of the largest Lyapunov exponent where both have one (a sign counts only
beyond three standard errors, the classifier's test for chaos; otherwise it is 0).
Steady sliding, runaway, quasi-periodic and chaotic motion are one attractor each per
point: their final windows are samples of a set, not features of one orbit. Undecided
runs (``attractor`` unresolved) are no attractor: they count in ``unresolved_fraction``,
as would a run whose ``regime`` is not its attractor's (steady for a fixed point,
stick_slip for a cycle, quasi-periodic or chaotic motion, runaway for unbounded).

Across points. The ``attractor`` coordinate names attractors by kind, the same at every
grid point: ``steady``, ``cycle_<n>ev`` (a periodic attractor of n events per cycle),
``quasi_periodic``, ``chaotic``, ``runaway``; where one point has several distinct
cycles of n events they are ranked by peak-to-peak ln(v/V), smallest first, the second
``cycle_<n>ev_2`` and so on. So ``ds.basin_fraction.sel(attractor="cycle_1ev")`` is one
variable over the map: the fraction of starts reaching the (smallest) simple cycle,
0 where no member reached one.
"""

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike
from scipy.special import ndtri

from ..codes import ATTRACTORS, REGIMES, code

#: The file attribute with the classifier's relative accuracy (``classification.accuracy``).
ACCURACY_ATTR = "classification_accuracy"
#: The order of the attractor kinds along the ``attractor`` coordinate (cycles by n, rank).
KIND_ORDER = ("steady", "cycle", "quasi_periodic", "chaotic", "runaway")
#: Confidence level of the intervals.
CONFIDENCE = 0.95
#: The outputs a match reads, per member.
NEEDED = ("regime", "attractor", "cycle_events", "period", "lnv_amplitude", "t_final")

_PERIODIC = code(ATTRACTORS, "periodic")
#: The regime each attractor kind belongs to (a member whose regime differs: unresolved).
_REGIME_OF = {
    code(ATTRACTORS, "fixed_point"): code(REGIMES, "steady"),
    code(ATTRACTORS, "periodic"): code(REGIMES, "stick_slip"),
    code(ATTRACTORS, "quasi_periodic"): code(REGIMES, "stick_slip"),
    code(ATTRACTORS, "chaotic"): code(REGIMES, "stick_slip"),
    code(ATTRACTORS, "unbounded"): code(REGIMES, "runaway"),
}
_KIND = {
    code(ATTRACTORS, "fixed_point"): "steady",
    code(ATTRACTORS, "quasi_periodic"): "quasi_periodic",
    code(ATTRACTORS, "chaotic"): "chaotic",
    code(ATTRACTORS, "unbounded"): "runaway",
}


def wilson_interval(
    count: ArrayLike, n: ArrayLike, confidence: float = CONFIDENCE
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of a binomial proportion ``count / n`` (Wilson 1927).

    (p̂ + z²/2n ± z sqrt(p̂(1 − p̂)/n + z²/4n²)) / (1 + z²/n), z the two-sided normal
    quantile of ``confidence`` (1.95996 at 95 %); exactly 0 (1) where count = 0 (= n).

    Parameters
    ----------
    count : array_like
        Successes (members reaching the attractor); broadcast with ``n``.
    n : array_like
        Trials (members).
    confidence : float, default 0.95
        Confidence level.

    Returns
    -------
    tuple of numpy.ndarray
        ``(low, high)``, floats in [0, 1]; (0, 1) where n = 0.
    """
    count, n = np.asarray(count, float), np.asarray(n, float)
    z = ndtri(0.5 + confidence / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = count / n
        centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
        half = z / (1 + z**2 / n) * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    low = np.where(count == 0, 0.0, np.clip(centre - half, 0.0, 1.0))  # exact at the ends
    high = np.where(count == n, 1.0, np.clip(centre + half, 0.0, 1.0))
    return low, high


def wilson_members(
    fraction: ArrayLike, width: ArrayLike, confidence: float = CONFIDENCE
) -> np.ndarray:
    """Fewest members n for which the Wilson interval (:func:`wilson_interval`) of a
    proportion ``fraction`` is at most ``width`` wide (``fraction`` held fixed as n grows;
    0.5, the widest, gives the bound for any fraction).

    The width 2 z sqrt(p(1 − p) n + z²/4) / (n + z²) falls monotonically in n; the
    smallest n is found by bisection on integers. At p = 1/2 it is z²/w² − z² rounded up
    (381 members for w = 0.1, 1534 for 0.05).

    Parameters
    ----------
    fraction : array_like
        The proportion, in [0, 1]; broadcast with ``width``.
    width : array_like
        The widest interval allowed, in (0, 1).
    confidence : float, default 0.95
        Confidence level.

    Returns
    -------
    numpy.ndarray
        int64, the fewest members.

    Raises
    ------
    ValueError
        A width outside (0, 1) or a fraction outside [0, 1].
    """
    p, w = np.broadcast_arrays(np.asarray(fraction, float), np.asarray(width, float))
    if np.any((w <= 0) | (w >= 1)) or np.any((p < 0) | (p > 1)):
        raise ValueError("width must lie in (0, 1) and fraction in [0, 1]")
    z = ndtri(0.5 + confidence / 2)

    def wide(n):
        return 2 * z * np.sqrt(p * (1 - p) * n + z**2 / 4) / (n + z**2) > w

    low = np.zeros(p.shape)  # too few (width > w at n = 0 for every w < 1)
    high = np.full(p.shape, np.ceil(z**2 / w**2) + 1)  # enough: width <= z / sqrt(n)
    while np.any(high - low > 1):
        mid = np.floor((low + high) / 2)
        too_wide = wide(mid)
        low = np.where(too_wide, mid, low)
        high = np.where(too_wide, high, mid)
    return high.astype(np.int64)


def members_needed(ds_basins: xr.Dataset, width: float) -> xr.DataArray:
    """Members each grid point needs for every Wilson interval of its fractions (each
    attractor's and the unresolved one) to be at most ``width`` wide, the fractions held
    at their present values (:func:`wilson_members`): at least the present ``members``.

    Parameters
    ----------
    ds_basins : xarray.Dataset
        From :func:`basin_fractions`.
    width : float
        The widest interval allowed, in (0, 1).

    Returns
    -------
    xarray.DataArray
        ``members_needed``, int64 over the grid's dimensions. The starts of an ensemble
        of M are the first M of a larger one with the same seed (``engine/grid.py``:
        numpy's Generator fills the offsets in C order), so the members beyond M are new
        runs, the first M the same runs.
    """
    level = float(ds_basins.attrs.get("basin_confidence", CONFIDENCE))
    widest = xr.apply_ufunc(
        wilson_members, ds_basins["basin_fraction"], kwargs={"width": width, "confidence": level}
    )
    unresolved = wilson_members(ds_basins["unresolved_fraction"].values, width, level)
    needed = np.maximum(widest.max("attractor"), unresolved)
    needed = np.maximum(needed, ds_basins["members"]).rename("members_needed")
    needed.attrs = {}
    return needed.assign_attrs(
        units="1",
        long_name=f"members for {100 * level:g} % Wilson intervals at most {width:g} wide",
        description="the largest over the point's fractions of the fewest members whose "
        "Wilson interval at that fraction is at most the width",
    )


def basin_fractions(
    ds: xr.Dataset, accuracy: float | None = None, confidence: float = CONFIDENCE
) -> xr.Dataset:
    """Per grid point, the attractors the ensemble's members reached and the fraction of
    the members in each, with its Wilson interval (see the module docstring for how
    members are matched, and across points by the ``attractor`` coordinate).

    Parameters
    ----------
    ds : xarray.Dataset
        A result with a ``member`` dimension (``initial.ensemble``), with at least
        ``regime``, ``attractor``, ``cycle_events``, ``period``, ``lnv_amplitude`` and
        ``t_final`` (and ``lyapunov_exponent``, ``lyapunov_error``, ``t_runaway`` if
        present).
    accuracy : float, optional
        Relative accuracy of the cycles' features (default: the file's
        ``classification_accuracy``); periodic members match within twice it.
    confidence : float, default 0.95
        Confidence level of the intervals.

    Returns
    -------
    xarray.Dataset
        Over the grid's dimensions and ``attractor``: ``basin_fraction``,
        ``basin_fraction_low``, ``basin_fraction_high``, ``basin_count``,
        ``basin_representative`` (a member that reached it; -1: none),
        ``basin_settle_time``, ``basin_period``, ``basin_lnv_amplitude``; over the grid's
        dimensions: ``unresolved_fraction`` (with ``_low``, ``_high``), ``members`` and
        the per-point outputs of ``ds`` (``K_over_Kc``, ``critical_K_W``, ...).
        Its coordinates are those of ``ds`` without ``member``; its attributes those of
        ``ds`` and ``basin_matching_tolerance``, ``basin_confidence``.

    Raises
    ------
    TypeError
        ``ds`` is not a Dataset.
    ValueError
        ``ds`` has no ``member`` dimension, lacks an output the match reads, or has no
        ``classification_accuracy`` and none is given.
    """
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be an xarray Dataset, got {type(ds).__name__}")
    if "member" not in ds.dims:
        raise ValueError(
            "ds has no member dimension: basin fractions need an initial-condition ensemble "
            "(initial.ensemble: M in the config)"
        )
    missing = [name for name in NEEDED if name not in ds]
    if missing:
        raise ValueError(f"ds lacks {', '.join(missing)}: basin fractions read {NEEDED}")
    if accuracy is None:
        if ACCURACY_ATTR not in ds.attrs:
            raise ValueError(
                f"ds has no attribute {ACCURACY_ATTR} (the classifier's accuracy): give accuracy="
            )
        accuracy = float(ds.attrs[ACCURACY_ATTR])
    tolerance = 2.0 * accuracy
    point_dims = [d for d in ds["regime"].dims if d != "member"]
    members = _member_table(ds, point_dims)
    n_points, n_members = members["regime"].shape
    labels = [_match(members, k, tolerance) for k in range(n_points)]
    names = sorted({name for point in labels for name in point}, key=_label_order)
    shape = tuple(ds.sizes[d] for d in point_dims)
    out = _tabulate(members, labels, names, shape)
    return _dataset(ds, out, names, point_dims, n_members, tolerance, confidence)


def _member_table(ds, point_dims):
    """The outputs a match reads, each (points, members), NaN where not in ``ds``."""
    order = point_dims + ["member"]
    table = {}
    for name in NEEDED + ("lyapunov_exponent", "lyapunov_error", "t_runaway"):
        if name in ds:
            values = ds[name].transpose(*order).values
        else:
            values = np.full(ds["regime"].transpose(*order).shape, np.nan)
        table[name] = values.reshape(-1, ds.sizes["member"])
    return table


def _lyapunov_sign(value, error):
    """+1/-1 beyond three standard errors, 0 within, None where not computed."""
    if not np.isfinite(value):
        return None
    margin = 3.0 * error if np.isfinite(error) else 0.0
    return int(np.sign(value)) if abs(value) > margin else 0


def _close(a, b, tolerance):
    """|a - b| within ``tolerance`` of the larger modulus (NaN: only with NaN)."""
    if not (np.isfinite(a) and np.isfinite(b)):
        return np.isnan(a) and np.isnan(b)
    return abs(a - b) <= tolerance * max(abs(a), abs(b))


def _match(m, k, tolerance):
    """Members of point ``k`` grouped into attractors: label → member indices."""
    groups = {}  # (kind, events, λ sign) → list of clusters (lists of members)
    for j in range(m["regime"].shape[1]):
        attractor, regime = int(m["attractor"][k, j]), int(m["regime"][k, j])
        if _REGIME_OF.get(attractor) != regime:
            continue  # undecided (attractor unresolved), or regime and attractor disagree
        periodic = attractor == _PERIODIC and np.isfinite(m["period"][k, j])
        if attractor == _PERIODIC and not periodic:
            continue  # a cycle without a period cannot be matched: unresolved
        kind = "cycle" if periodic else _KIND[attractor]
        events = int(m["cycle_events"][k, j]) if periodic else 0
        sign = _lyapunov_sign(m["lyapunov_exponent"][k, j], m["lyapunov_error"][k, j])
        clusters = groups.setdefault((kind, events), [])
        for cluster in clusters if periodic else clusters[:1]:
            first = cluster[0]
            other = _lyapunov_sign(m["lyapunov_exponent"][k, first], m["lyapunov_error"][k, first])
            if not periodic or (
                _close(m["period"][k, j], m["period"][k, first], tolerance)
                and _close(m["lnv_amplitude"][k, j], m["lnv_amplitude"][k, first], tolerance)
                and (sign is None or other is None or sign == other)
            ):
                cluster.append(j)
                break
        else:
            clusters.append([j])
    labels = {}
    for (kind, events), clusters in groups.items():
        if kind != "cycle":
            labels[kind] = clusters[0]
            continue
        clusters.sort(key=lambda c: m["lnv_amplitude"][k, c[0]])
        for rank, cluster in enumerate(clusters):
            labels[f"cycle_{events}ev" + (f"_{rank + 1}" if rank else "")] = cluster
    return labels


def _label_order(label):
    """Sort key of an attractor label: kind, then events per cycle, then rank."""
    if label.startswith("cycle_"):
        events, _, rank = label[len("cycle_") :].partition("ev")
        return (KIND_ORDER.index("cycle"), int(events), int(rank.lstrip("_") or 1))
    return (KIND_ORDER.index(label), 0, 0)


def _tabulate(m, labels, names, shape):
    """Counts, representatives and means per point and attractor, reshaped to the grid."""
    n_points, n_members = m["regime"].shape
    size = (n_points, len(names))
    count = np.zeros(size, np.int32)
    representative = np.full(size, -1, np.int32)
    settle, period, amplitude = (np.full(size, np.nan) for _ in range(3))
    settle_times = np.where(np.isfinite(m["t_runaway"]), m["t_runaway"], m["t_final"])
    for k, point in enumerate(labels):
        for name, members in point.items():
            a = names.index(name)
            count[k, a] = len(members)
            representative[k, a] = members[0]
            settle[k, a] = np.mean(settle_times[k, members])
            if name.startswith("cycle_"):
                period[k, a] = m["period"][k, members[0]]
                amplitude[k, a] = m["lnv_amplitude"][k, members[0]]
    resolved = count.sum(axis=1)
    grid = shape + (len(names),)
    return {
        "count": count.reshape(grid),
        "representative": representative.reshape(grid),
        "settle": settle.reshape(grid),
        "period": period.reshape(grid),
        "amplitude": amplitude.reshape(grid),
        "unresolved": (n_members - resolved).reshape(shape),
    }


def _dataset(ds, out, names, point_dims, n_members, tolerance, confidence):
    """The basin Dataset from the tabulated arrays, with CF attributes."""
    level = f"{100 * confidence:g} %"
    dims = tuple(point_dims) + ("attractor",)
    low, high = wilson_interval(out["count"], n_members, confidence)
    u_low, u_high = wilson_interval(out["unresolved"], n_members, confidence)
    wilson = f"{level} Wilson score interval of the fraction (Wilson 1927; Brown et al. 2001)"
    data = {
        "basin_fraction": (
            dims,
            out["count"] / n_members,
            {
                "units": "1",
                "long_name": "fraction of the ensemble's starts reaching the attractor",
                "description": "members matched to the attractor / members; 0 where none",
                "ancillary_variables": "basin_fraction_low basin_fraction_high basin_count",
            },
        ),
        "basin_fraction_low": (
            dims,
            low,
            {"units": "1", "long_name": "lower bound of basin_fraction", "description": wilson},
        ),
        "basin_fraction_high": (
            dims,
            high,
            {"units": "1", "long_name": "upper bound of basin_fraction", "description": wilson},
        ),
        "basin_count": (
            dims,
            out["count"],
            {"units": "1", "long_name": "members reaching the attractor"},
        ),
        "basin_representative": (
            dims,
            out["representative"],
            {
                "units": "1",
                "long_name": "a member reaching the attractor",
                "description": "the lowest member index matched to it (its run's outputs "
                "describe the attractor); -1: no member reached it",
                "_FillValue": np.int32(-1),
            },
        ),
        "basin_settle_time": (
            dims,
            out["settle"],
            {
                "units": "s",
                "long_name": "mean time to settle on the attractor",
                "description": "mean over its members of t_final, the time the classifier "
                "settled the run (the cycle's features known to classification_accuracy and "
                "confirmed over classification_confirm_cycles cycles: an upper bound of the "
                "time to come that close to the attractor), or t_runaway for runaway; "
                "meaningful only with classification_early_exit (else every run ends at "
                "t_end); NaN where no member reached it",
            },
        ),
        "basin_period": (
            dims,
            out["period"],
            {
                "units": "s",
                "long_name": "period of the cycle",
                "description": "period of the representative member (periodic attractors "
                "only, else NaN)",
            },
        ),
        "basin_lnv_amplitude": (
            dims,
            out["amplitude"],
            {
                "units": "1",
                "long_name": "peak-to-peak ln(v/V) of the cycle",
                "description": "lnv_amplitude of the representative member (periodic "
                "attractors only, else NaN)",
            },
        ),
        "unresolved_fraction": (
            tuple(point_dims),
            out["unresolved"] / n_members,
            {
                "units": "1",
                "long_name": "fraction of the ensemble's starts not matched to an attractor",
                "description": "members whose run stayed undecided (attractor unresolved), "
                "periodic without a period, or whose regime is not their attractor's",
                "ancillary_variables": "unresolved_fraction_low unresolved_fraction_high",
            },
        ),
        "unresolved_fraction_low": (
            tuple(point_dims),
            u_low,
            {
                "units": "1",
                "long_name": "lower bound of unresolved_fraction",
                "description": wilson,
            },
        ),
        "unresolved_fraction_high": (
            tuple(point_dims),
            u_high,
            {
                "units": "1",
                "long_name": "upper bound of unresolved_fraction",
                "description": wilson,
            },
        ),
        "members": (
            (),
            np.int32(n_members),
            {"units": "1", "long_name": "members of the ensemble at each point"},
        ),
    }
    coords = {name: c for name, c in ds.coords.items() if set(c.dims) <= set(point_dims)}
    data |= {  # the per-point outputs (K/Kc, Kc, linear theory): the context of a fraction
        name: da
        for name, da in ds.data_vars.items()
        if "member" not in da.dims and set(da.dims) <= set(point_dims)
    }
    coords["attractor"] = (
        "attractor",
        np.array(names, dtype=str),
        {
            "long_name": "attractor, named by kind the same at every grid point",
            "description": "steady, cycle_<n>ev (periodic, n events per cycle; a second "
            "distinct cycle of n events at a point cycle_<n>ev_2, ranked by peak-to-peak "
            "ln(v/V), smallest first), quasi_periodic, chaotic, runaway",
        },
    )
    attrs = {
        **ds.attrs,
        "basin_matching_tolerance": tolerance,
        "basin_confidence": confidence,
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)
