"""The critical kick: the smallest start that leaves steady sliding, at every grid point.

A sweep over the start (a sweep axis of ``physics.INITIAL_AXES``, e.g. the velocity jump
``initial_v_over_V`` from steady sliding on a log axis) labels every kick: the run comes
back to steady sliding (regime ``steady``) or leaves it, for runaway past the velocity cap
or another attractor (``runaway`` or ``stick_slip``). Along the kick axis, at every point
of the other axes, the critical kick is the smallest kick that leaves; it is bracketed by
the largest kick below it that returns (:func:`scan_brackets`), and bisection in ln(kick)
narrows the bracket (``sweep/engine/kicks.py``) to a relative width ``critical_kick_rtol``.

The kind of threshold (Gu, Rice, Ruina & Tse 1984 for the quasi-static slip law: a finite
jump sets off unstable slip; Ranjith & Rice 1999 for the aging law: every perturbation
decays, so only a velocity cap makes a threshold). Where the run that leaves settles on
another attractor (``stick_slip``: a cycle beside stable steady sliding past a subcritical
Hopf bifurcation) the threshold is a **basin_boundary**: the cap plays no part. Where it
runs away, the excursion's peak ln(v/V) (output ``lnv_peak``) of a *probe*, a kick that
returns :data:`PROBE` times the critical kick (10 % below it), decides: **sharp** where it
stays more than :data:`SHARP_JUMP` (a factor 10 in velocity) below ln of the cap,
**cap_limited** where it already comes within it, the peak growing smoothly up to the
cap. The peak just below a sharp threshold is no measure: it grows without bound as the
kick nears the threshold (slip law, SciPy, ``tests/kick_reference.py``: by about 1.6 per
decade of 1 − kick/kick_c, 11.5 at 1e-4 from it where the cap is at 13.8), so the probe
sits at a fixed distance.
A scan (:func:`critical_kick`) takes as its probe the largest kick it ran at or below 10 %
under the critical kick (or the bracket's lower end if there is none: closer, so a
``sharp`` verdict holds and a ``cap_limited`` one may not); bisection runs the probe
(``sweep/engine/kicks.py``). ``undetermined``: the probe did not return (outcomes that
cross more than once, or an undecided probe).

Statuses (``critical_kick_status``): ``found`` (a bracket: critical_kick and
critical_kick_low given), ``none_up_to_max`` (every kick tried returned: "none up to the
largest kick tried", no number), ``below_min`` (the smallest kick tried already leaves:
steady sliding there is linearly unstable or the threshold is below the axis),
``undecided`` (an undecided run at or below the first kick that leaves, where the
bracket would be: no number).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..codes import REGIMES, code
from ..errors import InputError
from ..model.physics import INITIAL_AXES

#: The statuses of ``critical_kick_status`` (flag meanings, in code order).
KICK_STATUSES = ("found", "none_up_to_max", "below_min", "undecided")
#: The kinds of threshold of ``kick_threshold`` (flag meanings, in code order).
THRESHOLD_KINDS = ("sharp", "cap_limited", "basin_boundary", "undetermined", "not_found")
#: Gap of the peak ln(v/V) between the probe and the run that leaves above which a
#: threshold is sharp: ln 10.
SHARP_JUMP = float(np.log(10.0))
#: The probe's kick as a fraction of the critical kick.
PROBE = 0.9

_STEADY = code(REGIMES, "steady")
_UNDECIDED = code(REGIMES, "undecided")
_RUNAWAY = code(REGIMES, "runaway")


def outcomes(regime, peak, lnv_cap):
    """Regime codes as the critical kick reads them: a steady run whose excursion's peak
    (``peak``, lnv_peak) passed ``lnv_cap`` (ln of the velocity cap) counts as runaway.
    The kernels test the cap at the ends of steps; a maximum between two of them, read from
    the dense output, can pass it by a little (within 0.03 in ln v near a cap-limited
    threshold), as SciPy's cap event can miss one within a step
    (``tests/kick_reference.py``)."""
    regime = np.asarray(regime)
    return np.where((regime == _STEADY) & (np.asarray(peak) >= lnv_cap), _RUNAWAY, regime)


def leaves(regime):
    """Whether runs of these regime codes left steady sliding (runaway or stick-slip)."""
    regime = np.asarray(regime)
    return (regime != _STEADY) & (regime != _UNDECIDED)


def scan_brackets(kicks, regime, peak):
    """Brackets of the critical kick from a scan: ``kicks`` (k,) ascending, ``regime`` and
    ``peak`` (n, k) per point (regime codes, lnv_peak).

    Returns a dict of (n,) arrays: ``low``, ``high`` (the bracket; NaN unless found),
    ``peak_low``, ``peak_high``, ``regime_high`` (−1 where none), ``status`` (codes of
    :data:`KICK_STATUSES`), ``probe``, ``peak_probe`` (the module's probe; NaN unless
    found).
    """
    kicks = np.asarray(kicks, float)
    regime = np.asarray(regime)
    peak = np.asarray(peak, float)
    n = regime.shape[0]
    left = leaves(regime)
    undecided = regime == _UNDECIDED
    any_left = left.any(axis=1)
    first = np.where(any_left, left.argmax(axis=1), kicks.size)
    before = np.arange(kicks.size)[None, :] < first[:, None]
    unsure = (undecided & before).any(axis=1)
    status = np.where(
        unsure,
        code(KICK_STATUSES, "undecided"),
        np.where(
            ~any_left,
            code(KICK_STATUSES, "none_up_to_max"),
            np.where(first == 0, code(KICK_STATUSES, "below_min"), code(KICK_STATUSES, "found")),
        ),
    ).astype(np.int8)
    found = status == code(KICK_STATUSES, "found")
    rows = np.arange(n)
    hi = np.minimum(first, kicks.size - 1)
    lo = np.maximum(first - 1, 0)
    out = {
        "low": np.where(found, kicks[lo], np.nan),
        "high": np.where(found, kicks[hi], np.nan),
        "peak_low": np.where(found, peak[rows, lo], np.nan),
        "peak_high": np.where(any_left & ~unsure, peak[rows, hi], np.nan),
        "regime_high": np.where(any_left & ~unsure, regime[rows, hi], -1).astype(np.int8),
        "status": status,
    }
    below = kicks[None, :] <= PROBE * out["high"][:, None]
    probe = np.where(below.any(axis=1), kicks.size - 1 - below[:, ::-1].argmax(axis=1), lo)
    out["probe"] = np.where(found, kicks[probe], np.nan)
    out["peak_probe"] = np.where(found, peak[rows, probe], np.nan)
    return out


def bisect_brackets(brackets, mid, regime, peak, todo):
    """Narrow the brackets of the points ``todo`` (indices) by runs at kicks ``mid`` with
    outcomes ``regime`` and ``peak`` (one per point of ``todo``), in place: a run that
    leaves is the new high end, one that returns the new low end, an undecided one makes
    the point ``undecided`` (its bracket dropped)."""
    left = leaves(regime)
    steady = regime == _STEADY
    b = brackets
    hi, lo = todo[left], todo[steady]
    b["high"][hi], b["peak_high"][hi], b["regime_high"][hi] = mid[left], peak[left], regime[left]
    b["low"][lo], b["peak_low"][lo] = mid[steady], peak[steady]
    unsure = todo[~left & ~steady]
    b["status"][unsure] = code(KICK_STATUSES, "undecided")
    for name in ("low", "high", "peak_low", "peak_high", "probe", "peak_probe"):
        b[name][unsure] = np.nan
    b["regime_high"][unsure] = -1


def open_brackets(brackets, rtol):
    """Indices of the points whose bracket is found and wider than ``rtol`` (relative)."""
    found = brackets["status"] == code(KICK_STATUSES, "found")
    with np.errstate(invalid="ignore"):
        wide = brackets["high"] / brackets["low"] - 1.0 > rtol
    return np.flatnonzero(found & wide)


def stale_probes(brackets):
    """Indices of the found points whose probe is not at :data:`PROBE` × critical kick."""
    found = brackets["status"] == code(KICK_STATUSES, "found")
    return np.flatnonzero(found & ~(brackets["probe"] == PROBE * brackets["high"]))


def set_probes(brackets, kicks, regime, peak, todo):
    """Record probe runs at ``kicks`` with outcomes ``regime``, ``peak`` for the points
    ``todo``, in place; a probe that did not return keeps no peak (``undetermined``)."""
    brackets["probe"][todo] = kicks
    brackets["peak_probe"][todo] = np.where(regime == _STEADY, peak, np.nan)


def threshold_kinds(brackets, lnv_cap):
    """Codes of :data:`THRESHOLD_KINDS` per point: ``basin_boundary`` where the run that
    leaves settles on another attractor; else (runaway) the probe's peak against
    ``lnv_cap`` (ln of the velocity cap)."""
    gap = lnv_cap - brackets["peak_probe"]
    found = brackets["status"] == code(KICK_STATUSES, "found")
    kind = np.where(
        np.isnan(gap),
        code(THRESHOLD_KINDS, "undetermined"),
        np.where(
            gap > SHARP_JUMP, code(THRESHOLD_KINDS, "sharp"), code(THRESHOLD_KINDS, "cap_limited")
        ),
    )
    kind = np.where(
        brackets["regime_high"] == _RUNAWAY, kind, code(THRESHOLD_KINDS, "basin_boundary")
    )
    return np.where(found, kind, code(THRESHOLD_KINDS, "not_found")).astype(np.int8)


def kick_axis(ds, axis=None):
    """The kick axis of a result: ``axis`` or its one swept ``physics.INITIAL_AXES`` axis."""
    source = ds.attrs.get("sweep_name", "<dataset>")
    swept = [name for name in INITIAL_AXES if name in ds.dims]
    if axis is None:
        if len(swept) != 1:
            found = ", ".join(swept) or "none"
            raise InputError(
                source,
                [
                    f"critical kick needs one swept start axis of {', '.join(INITIAL_AXES)} "
                    f"(found: {found}); name it with axis="
                ],
            )
        axis = swept[0]
    if axis not in ds.dims:
        raise InputError(source, [f"critical kick: {axis!r} is not a dimension of the result"])
    if "member" in ds.dims:
        raise InputError(
            source,
            [
                "critical kick of an initial-condition ensemble: the kick and the random "
                "starts would mix; select one member (ds.isel(member=m)) or use "
                "sweep.basin_fractions"
            ],
        )
    return axis


def critical_kick(ds: xr.Dataset, axis: str | None = None) -> xr.Dataset:
    """The critical kick at every point of a result swept over the start.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`sweep.run` (or a file read back) with a sweep axis of
        ``physics.INITIAL_AXES`` and the outputs ``regime`` and ``lnv_peak``.
    axis : str, optional
        The kick axis (default: the one start axis swept).

    Returns
    -------
    xarray.Dataset
        Over the other axes: ``critical_kick`` (the smallest kick that left),
        ``critical_kick_low`` (the largest below it that returned), their relative
        width, the status, the kind of threshold, the peaks on both sides and the
        regime above; see :func:`kick_dataset`.
    """
    axis = kick_axis(ds, axis)
    ordered = ds.sortby(axis)
    others = [d for d in ordered["regime"].dims if d != axis]
    regime = ordered["regime"].transpose(*others, axis)
    peak = ordered["lnv_peak"].transpose(*others, axis)
    shape = regime.shape[:-1]
    k = regime.shape[-1]
    lnv_cap = np.log(float(ds.attrs["classification_v_cap_over_V"]))
    peak = peak.values.reshape(-1, k)
    regime = outcomes(regime.values.reshape(-1, k), peak, lnv_cap)
    brackets = scan_brackets(ordered[axis].values, regime, peak)
    template = ordered.isel({axis: 0}, drop=True)
    runs = np.full(int(np.prod(shape)), k, np.int32)
    searched = (float(ordered[axis][0]), float(ordered[axis][-1]))
    return kick_dataset(template, axis, searched, brackets, runs, shape, others)


#: Variables of a result that do not depend on the start, carried to the kick dataset.
CARRIED = ("K_over_Kc", "critical_K_W", "linear_growth_rate", "onset_period", "hopf_l1")


def kick_dataset(template, axis, searched, brackets, runs, shape, dims):
    """The critical-kick Dataset over ``dims`` (``shape``) from flat ``brackets`` and the
    number of ``runs`` per point, the kicks ``searched`` (smallest, largest) in the
    attributes ``kick_min``, ``kick_max``; coordinates, carried variables
    (:data:`CARRIED`) and attributes from ``template`` (a result at one kick, the kick
    axis dropped)."""
    info = INITIAL_AXES[axis]
    status = brackets["status"]
    found = status == code(KICK_STATUSES, "found")
    width = np.where(found, brackets["high"] / brackets["low"] - 1.0, np.nan)
    regime_flags = {
        "flag_values": np.arange(len(REGIMES), dtype=np.int8),
        "flag_meanings": " ".join(REGIMES),
        "_FillValue": np.int8(-1),
    }

    def var(values, attrs):
        return (dims, np.asarray(values).reshape(shape), attrs)

    data = {
        "critical_kick": var(
            brackets["high"],
            {
                "units": info.units,
                "long_name": f"critical kick: smallest {info.long_name} that leaves steady sliding",
                "description": "the smallest start tried that ran away past the cap or "
                "reached another attractor; the threshold lies between critical_kick_low "
                "and it; NaN unless critical_kick_status is found",
            },
        ),
        "critical_kick_low": var(
            brackets["low"],
            {
                "units": info.units,
                "long_name": f"largest {info.long_name} below the critical kick that returns",
                "description": "the run there came back to steady sliding; NaN unless found",
            },
        ),
        "critical_kick_rtol": var(
            width,
            {
                "units": "1",
                "long_name": "relative width of the critical kick's bracket",
                "description": "critical_kick / critical_kick_low - 1",
            },
        ),
        "critical_kick_status": var(
            status,
            {
                "long_name": "what the critical kick is",
                "description": "found; none_up_to_max (every kick tried returned); below_min "
                "(the smallest kick tried left); undecided (an undecided run where the "
                "bracket would be)",
                "flag_values": np.arange(len(KICK_STATUSES), dtype=np.int8),
                "flag_meanings": " ".join(KICK_STATUSES),
            },
        ),
        "kick_threshold": var(
            threshold_kinds(brackets, np.log(float(template.attrs["classification_v_cap_over_V"]))),
            {
                "long_name": "kind of threshold",
                "description": "of a runaway threshold, sharp: the peak ln(v/V) of the probe "
                "(kick_probe, 10 % below the critical kick) stays more than ln 10 below ln of "
                "the cap; cap_limited: it comes within ln 10, the excursion growing smoothly "
                "up to the cap; basin_boundary: the run that leaves settles on another "
                "attractor (stick_slip); undetermined: the probe did not return; not_found "
                "unless found",
                "flag_values": np.arange(len(THRESHOLD_KINDS), dtype=np.int8),
                "flag_meanings": " ".join(THRESHOLD_KINDS),
            },
        ),
        "lnv_peak_below": var(
            brackets["peak_low"],
            {
                "units": "1",
                "long_name": "peak ln(v/V) of the run at critical_kick_low",
                "description": "the largest ln(v/V) of the returning excursion",
            },
        ),
        "lnv_peak_above": var(
            brackets["peak_high"],
            {
                "units": "1",
                "long_name": "peak ln(v/V) of the run at critical_kick",
                "description": "at least ln(classification_v_cap_over_V) for a runaway run",
            },
        ),
        "kick_probe": var(
            brackets["probe"],
            {
                "units": info.units,
                "long_name": "the probe's kick",
                "description": "a kick that returns 0.9 times critical_kick (from a scan: the "
                "largest kick run at or below it, else critical_kick_low), whose peak "
                "decides kick_threshold",
            },
        ),
        "lnv_peak_probe": var(
            brackets["peak_probe"],
            {
                "units": "1",
                "long_name": "peak ln(v/V) of the run at kick_probe",
                "description": "NaN where the probe did not return",
            },
        ),
        "regime_above": var(
            brackets["regime_high"], {"long_name": "regime at critical_kick", **regime_flags}
        ),
        "kick_runs": var(runs, {"units": "1", "long_name": "runs made at the point"}),
    }
    carried = {name: template[name] for name in CARRIED if name in template and template[name].ndim}
    coords = {name: c for name, c in template.coords.items() if set(c.dims) <= set(dims)}
    ds = xr.Dataset({**data, **carried}, coords=coords, attrs=dict(template.attrs))
    ds.attrs["title"] = f"Critical kicks: {template.attrs.get('sweep_name', '')}".strip()
    ds.attrs["kick_axis"] = axis
    ds.attrs["kick_min"], ds.attrs["kick_max"] = searched
    ds.attrs["kick_sharp_jump"] = SHARP_JUMP
    ds.attrs["kick_probe_fraction"] = PROBE
    return ds
