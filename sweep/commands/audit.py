"""Self-audit: rerun points of a result for much longer, and with tighter tolerances,
and compare the regimes.

A sweep stops each run as soon as its regime looks settled (early exit) and
classifies the rest at the end time. The audit checks those calls: it reruns a
seeded random sample of grid points plus every point near the critical
stiffness (|K/Kc − 1| ≤ ``near_kc``) from the config's initial state, with
early exit off and a much later end time, and compares the two regimes point
by point. It also reruns them with the file's own settings but rtol and atol
divided by a factor: a label that changes with the tolerance (a chaotic transient
whose runaway the looser run misses, or blocks merged by round-off onto an orbit
they would leave) is not a property of the equations.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import xarray as xr

from ..engine.chunks import integrate_in_memory
from ..engine.grid import build_grid, initial_state, physical_parameters
from ..errors import InputError
from ..kernels import layout
from ..progress import Progress
from ..results.dataset import parameter_attrs, stored_config
from ..variables import ATTRACTORS, REGIMES
from .extend import final_state, load_result


def audit_points(ds, sample=20, near_kc=0.01, seed=0):
    """Flat grid indices to audit: ``sample`` random ones (seeded) and all near Kc.

    Returns ``(rows, near)``: sorted unique indices (C order over the sweep
    axes) and a mask of those within ``near_kc`` of K/Kc = 1.
    """
    k_over_kc = ds["K_over_Kc"].values.ravel()
    n = k_over_kc.size
    drawn = np.random.default_rng(seed).choice(n, size=min(sample, n), replace=False)
    close = np.flatnonzero(np.abs(k_over_kc - 1.0) <= near_kc)
    rows = np.union1d(drawn, close)
    return rows, np.isin(rows, close)


def audit_config(config, t_end):
    """``config`` with end time ``t_end`` (its ``t_unit``) and early exit off; λ1 (unless
    the config never computes it) over the whole run, which tells chaotic and
    quasi-periodic motion from undecided at the end."""
    cls = config.classification
    lyapunov = cls.lyapunov if cls.lyapunov == "never" else "always"
    return dataclasses.replace(
        config,
        integrator=dataclasses.replace(config.integrator, t_end=float(t_end)),
        classification=dataclasses.replace(cls, early_exit=False, lyapunov=lyapunov),
    )


#: The smallest relative tolerance a tightened rerun may ask for: below about 100
#: machine epsilons the error estimates of the methods are round-off.
MIN_TIGHT_RTOL = 1e-13


def tight_config(config, tighten):
    """``config`` with rtol and atol divided by ``tighten`` (> 1) and rk4's fixed step by
    ``tighten`` ** (1/4) (its error, fourth order, then falls by ``tighten`` too); nothing
    else changed."""
    integ = config.integrator
    tighter = dataclasses.replace(
        integ, rtol=integ.rtol / tighten, atol=integ.atol / tighten, dt=integ.dt / tighten**0.25
    )
    return dataclasses.replace(config, integrator=tighter)


def audit_result(
    result: str | os.PathLike | xr.Dataset,
    sample: int = 20,
    near_kc: float = 0.01,
    t_end: float | None = None,
    seed: int = 0,
    threads: int | None = None,
    source: str | None = None,
    tighten: float | None = 100.0,
    show_progress: bool = False,
) -> xr.Dataset:
    """Rerun a sample of a result's grid points for longer, and with tighter tolerances,
    and compare regimes.

    Parameters
    ----------
    result : str, os.PathLike or xarray.Dataset
        A result of ``python -m sweep run`` or :func:`sweep.run` (it holds its
        config), or the path of its file.
    sample : int, default 20
        Number of grid points drawn at random (all of them if the grid is
        smaller).
    near_kc : float, default 0.01
        Every point with ``|K/Kc − 1| ≤ near_kc`` is audited too (a fraction, 1).
    t_end : float, optional
        End time of the audit runs, in the config's ``t_unit``. Default: 10 ×
        the file's end time.
    seed : int, default 0
        Seed of the random draw.
    threads : int, optional
        Threads on this machine (default: all cores).
    source : str, optional
        Name of the result in error messages (default: its path).
    tighten : float or None, default 100.0
        The same points are also rerun with the file's settings (end time, early
        exit) but its ``rtol`` and ``atol`` divided by ``tighten`` (> 1; the tightened
        rtol at least 1e-13; rk4: its step ``dt`` by ``tighten`` ** (1/4)). None: no
        such rerun.
    show_progress : bool, default False
        Report each rerun's progress on stderr (as a sweep does).

    Returns
    -------
    xarray.Dataset
        One row per audited run (dimension ``point``; with an ensemble, every member
        of each drawn grid point, ``member`` saying which): the sweep axes'
        values (physical units), ``index`` (flat grid index), ``near_kc``
        (audited for being near Kc), ``K_over_Kc``, ``regime_file``,
        ``regime_audit`` and ``agree`` (the long run's regime), and unless
        ``tighten`` is None the rerun with tighter tolerances: ``regime_tight``,
        ``attractor_file`` / ``attractor_tight``, ``cycle_events_file`` /
        ``cycle_events_tight``, and ``agree_tight`` (all three the same); and
        ``merged_blocks`` (:func:`merged_blocks`). Attributes: the audit settings.

    Raises
    ------
    InputError
        The result cannot be read or holds no config, or ``sample``, ``near_kc``,
        ``tighten`` or ``t_end`` is out of range or ``t_end`` not later than the file's
        (every problem listed).
    ConfigError
        The stored config is no longer valid.
    """
    ds, source = load_result(result, source)
    config = stored_config(ds, source)
    problems = []
    if sample < 0:
        problems.append(f"--sample must be >= 0, got {sample}")
    if not near_kc >= 0:
        problems.append(f"--near-kc must be in [0, inf), got {near_kc}")
    t_end = 10.0 * config.integrator.t_end if t_end is None else float(t_end)
    if not config.integrator.t_end < t_end < np.inf:
        problems.append(
            f"--t-end must be finite and later than the file's t_end, "
            f"{config.integrator.t_end:g} {config.integrator.t_unit} (the audit "
            f"runs for longer), got {t_end:g}"
        )
    rtol = config.integrator.rtol
    if tighten is not None and not (1.0 < tighten < np.inf and rtol / tighten >= MIN_TIGHT_RTOL):
        problems.append(
            f"--tighten must be finite, above 1 and keep rtol / FACTOR >= {MIN_TIGHT_RTOL:g} "
            f"(the file's rtol is {rtol:g}), got {tighten:g}"
        )
    if problems:
        raise InputError(source, problems)
    points, near_points = audit_points(ds, sample, near_kc, seed)
    # with an ensemble every member of a drawn grid point is a run of its own
    members = config.members
    runs = (points[:, None] * members + np.arange(members)).ravel()
    rows, near = np.repeat(points, members), np.repeat(near_points, members)
    regime_file = ds["regime"].values.ravel()[runs]
    long_run = audit_config(config, t_end)
    regime_audit = rerun_labels(long_run, runs, threads, "audit: long run", show_progress)[0]
    flags = {
        "flag_values": np.arange(len(REGIMES), dtype=np.int8),
        "flag_meanings": " ".join(REGIMES),
    }
    index = np.unravel_index(rows, config.shape)
    coords = {
        axis.name: (
            "point",
            np.asarray(axis.values)[i],
            parameter_attrs(axis.name),
        )
        for axis, i in zip(config.axes, index, strict=True)
    }
    coords["index"] = ("point", rows, {"long_name": "flat grid index (C order over the axes)"})
    if config.initial.ensemble:
        coords["member"] = ("point", runs % members, {"long_name": "ensemble member"})
    data_vars = {
        "near_kc": ("point", near, {"long_name": f"|K/Kc - 1| <= {near_kc:g}"}),
        "K_over_Kc": ("point", ds["K_over_Kc"].values.ravel()[rows], {"units": "1"}),
        "regime_file": ("point", regime_file, {"long_name": "regime in the file", **flags}),
        "regime_audit": (
            "point",
            regime_audit,
            {"long_name": "regime of the long run without early exit", **flags},
        ),
        "agree": ("point", regime_file == regime_audit, {"long_name": "same regime"}),
    }
    if tighten is not None:
        tight = tight_labels(ds, config, runs, tighten, threads, flags, show_progress)
        data_vars.update(tight)
    merged = merged_blocks(ds, config, runs)
    if merged is not None:
        data_vars["merged_blocks"] = (
            "point",
            merged,
            {
                "long_name": "blocks whose final state equals another block's bit for bit, "
                "although the two started apart (merged by round-off)"
            },
        )
    attrs = {
        "title": f"Audit of the rsf-sweep result {source}",
        "audit_source": source,
        "audit_t_end": t_end,
        "audit_t_unit": config.integrator.t_unit,
        "file_t_end": config.integrator.t_end,
        "audit_sample": np.int64(sample),
        "audit_near_kc": float(near_kc),
        "audit_seed": np.int64(seed),
        "audit_tighten": np.nan if tighten is None else float(tighten),
        "sweep_axes": " ".join(a.name for a in config.axes),
    }
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)


def merged_blocks(ds, config, runs):
    """Per run of ``runs``: how many blocks end in the same state as another block, bit
    for bit, although the two started apart (int32; None when the file lacks its final
    states). Distinct states of an ODE never meet, so such blocks were merged by
    round-off, and the engine's symmetric arithmetic then keeps them together: harmless
    on a synchrony that is stable, an artefact on an orbit they would leave."""
    try:
        end = final_state(ds, config)[runs]
    except InputError:  # an inertial result written before inertial_force_final existed
        return None
    if not runs.size:
        return np.zeros(0, np.int32)
    nb = config.blocks
    end = end.reshape(runs.size, -1, nb)
    phys = physical_parameters(config)
    start = initial_state(config, ds["regime"].size, phys)[runs].reshape(runs.size, -1, nb)
    same_end = (end[:, :, :, None] == end[:, :, None, :]).all(axis=1)
    same_start = (start[:, :, :, None] == start[:, :, None, :]).all(axis=1)
    return (same_end & ~same_start).any(axis=2).sum(axis=1).astype(np.int32)


def rerun_labels(config, runs, threads, desc, show_progress):
    """Regime (int8), attractor (int8) and cycle_events (int32) of the flat run indices
    ``runs`` of ``config``'s grid; progress as ``desc`` if ``show_progress``."""
    if not runs.size:
        return np.empty(0, np.int8), np.empty(0, np.int8), np.empty(0, np.int32)
    picked = build_grid(config).rows(runs)
    progress = Progress(runs.size, desc=desc, enabled=show_progress)
    try:
        results, _ = integrate_in_memory(
            picked.params, picked.y0, picked.settings, threads, progress=progress
        )
    finally:
        progress.close()
    return (
        results[:, layout.R_REGIME].astype(np.int8),
        results[:, layout.R_ATTRACTOR].astype(np.int8),
        results[:, layout.R_CYCLE_EVENTS].astype(np.int32),
    )


def tight_labels(ds, config, runs, tighten, threads, regime_flags, show_progress):
    """The audit's variables of the rerun with tolerances / ``tighten``: its regime,
    attractor and cycle_events beside the file's, and ``agree_tight`` (all three equal)."""
    tight = tight_config(config, tighten)
    desc = "audit: tighter tolerance"
    regime, attractor, events = rerun_labels(tight, runs, threads, desc, show_progress)
    attractor_flags = {
        "flag_values": np.arange(len(ATTRACTORS), dtype=np.int8),
        "flag_meanings": " ".join(ATTRACTORS),
    }
    in_file = {
        name: ds[name].values.ravel()[runs] for name in ("regime", "attractor", "cycle_events")
    }
    same = (
        (in_file["regime"] == regime)
        & (in_file["attractor"] == attractor)
        & (in_file["cycle_events"] == events)
    )
    rerun = f"the rerun with rtol and atol / {tighten:g}"
    return {
        "regime_tight": ("point", regime, {"long_name": f"regime of {rerun}", **regime_flags}),
        "attractor_file": (
            "point",
            in_file["attractor"],
            {"long_name": "attractor in the file", **attractor_flags},
        ),
        "attractor_tight": (
            "point",
            attractor,
            {"long_name": f"attractor of {rerun}", **attractor_flags},
        ),
        "cycle_events_file": (
            "point",
            in_file["cycle_events"],
            {"long_name": "events per cycle in the file"},
        ),
        "cycle_events_tight": ("point", events, {"long_name": f"events per cycle of {rerun}"}),
        "agree_tight": (
            "point",
            same,
            {"long_name": "same regime, attractor and events per cycle with tighter tolerances"},
        ),
    }
