"""Continue the undecided runs of a result to a later end time.

A run is undecided when its oscillation had not settled by the end time. The
log-form equations are autonomous (the load point's position does not enter
them), so the stored final state (``lnv_final``, ``ln_state_final`` and, for
the inertial model, ``inertial_force_final``) is all a run needs to go on:
each undecided run is integrated again from that state for the time left up
to the new end, with the config's settings otherwise, and its statistics
replace the old ones. Times are shifted by the old ``t_final`` and the step
and peak counts are added, so the file reads as if each run had gone straight
on; the cycle statistics (envelope, period, the events) start afresh at the
restart. The continuation is judged like a run whose end time is half the time
left: it stops once settled, and still unsettled at half time it carries the
tangent for λ1 over the second half (without early exit, over all of it), so
chaotic and quasi-periodic motion can be told from undecided. Every other run
is left as it was, bit for bit.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import xarray as xr

from ..config import with_changes
from ..engine.chunks import integrate_in_memory
from ..engine.grid import build_grid
from ..errors import InputError, RunError
from ..io.files import ZARR_SUFFIX, check_writable, output_lock
from ..io.netcdf import read_result, write_netcdf
from ..kernels import layout
from ..progress import Progress
from ..results.dataset import derived_fields, regime_fractions, stored_config, utc_now
from ..variables import variables_for

#: Variables from linear theory, not from the run: never recomputed.
LINEAR_THEORY = (
    "linear_growth_rate",
    "critical_K_W",
    "K_over_Kc",
    "onset_period",
    "hopf_l1",
    "hopf_criticality",
    "hopf_lnv_amplitude",
)
#: Times (s) of the continued run, shifted by the old t_final.
SHIFTED = ("t_final", "t_runaway")
#: Counts of the continued run, added to the old ones.
SUMMED = ("n_steps", "n_rejected", "n_peaks")
#: The stored final state, block-major columns of the kernels' state y.
FINAL_STATE = ("lnv_final", "ln_state_final", "inertial_force_final")


def load_result(result, source=None):
    """``(dataset, source)`` of a result given as a path or as a Dataset.

    ``source`` names the result in errors (default: the path, or ``<dataset>``).
    """
    if isinstance(result, (str, bytes)) or hasattr(result, "__fspath__"):
        return read_result(result, needs_config=True), str(source or result)
    return result, str(source or "<dataset>")


def undecided_rows(ds):
    """Flat grid indices (C order over the sweep axes) of the undecided runs."""
    return np.flatnonzero(ds["regime"].values.ravel() == layout.UNDECIDED)


def final_state(ds, config):
    """The stored final state of every run as kernel rows ``(n, n_vars)``.

    Raises :class:`~sweep.errors.InputError` if the file lacks a part of it
    (inertial results written before ``inertial_force_final`` existed).
    """
    names = FINAL_STATE if config.model == "inertial" else FINAL_STATE[:2]
    missing = [name for name in names if name not in ds]
    if missing:
        raise InputError(
            config.source,
            [
                f"no {', '.join(missing)} in the file: the final state cannot be restarted; "
                "run the config again with this version of rsf-sweep"
            ],
        )
    n = ds["regime"].size
    return np.concatenate([ds[name].values.reshape(n, config.blocks) for name in names], axis=1)


def horizon(config):
    """The latest time a run of ``config`` can have reached (its ``t_unit``): the end
    time, or with early exit the ``max_t_end`` up to which unsettled runs continue."""
    cls, t_end = config.classification, config.integrator.t_end
    if not cls.early_exit:
        return t_end
    return 10.0 * t_end if cls.max_t_end is None else cls.max_t_end


def with_end_time(config, t_end, early_exit=None, source=None):
    """``config`` with end time ``t_end`` (its ``t_unit``), no continuation past it,
    and, if given, ``early_exit``.

    The config text is rewritten to match (``sweep.config.with_changes``), so a
    file's ``config_text`` stays the config that made it.
    """
    classification = {"max_t_end": float(t_end)}
    if early_exit is not None:
        classification["early_exit"] = bool(early_exit)
    changes = {"integrator": {"t_end": float(t_end)}, "classification": classification}
    changed = with_changes(config, changes, source or config.source)
    return dataclasses.replace(changed, source=config.source)


def extend_result(
    result: str | os.PathLike | xr.Dataset,
    t_end: float | None = None,
    threads: int | None = None,
    source: str | None = None,
    show_progress: bool = False,
) -> xr.Dataset:
    """Continue the undecided runs of a result up to the end time ``t_end``.

    Parameters
    ----------
    result : str, os.PathLike or xarray.Dataset
        A result of ``python -m sweep run`` or :func:`sweep.run` (it holds its
        config), or the path of its file.
    t_end : float, optional
        New end time, in the config's ``t_unit`` (D0/V or s); must exceed the
        old horizon (``max_t_end``, up to which unsettled runs already went on;
        the end time without early exit). Default: 4 × that horizon.
    threads : int, optional
        Threads on this machine (default: all cores).
    source : str, optional
        Name of the result in error messages (default: its path).
    show_progress : bool, default False
        Report the continued runs' progress on stderr (as a sweep does).

    Returns
    -------
    xarray.Dataset
        The result with the undecided runs continued (regime and every run
        statistic from the continued run; ``t_final``, ``t_runaway`` in s
        counted from the original start; ``n_steps``, ``n_rejected``,
        ``n_peaks`` summed over both parts), the new end time in ``config_text``
        and ``integrator_t_end`` and an entry in ``history``. Other runs are
        unchanged. A result without undecided runs is returned as it is.

    Raises
    ------
    InputError
        The file cannot be read or continued (not a result, no stored config or
        final state), or ``t_end`` is not later than the old horizon.
    ConfigError
        The stored config is no longer valid.
    """
    ds, source = load_result(result, source)
    config = stored_config(ds, source)
    old_end, unit = horizon(config), config.integrator.t_unit
    t_end = 4.0 * old_end if t_end is None else float(t_end)
    if not t_end > old_end:
        raise InputError(
            source,
            [
                f"--t-end must be later than the time its undecided runs already reached "
                f"({old_end:g} {unit}: max_t_end, or t_end without early exit), got {t_end:g}"
            ],
        )
    rows = undecided_rows(ds)
    if rows.size == 0:
        return ds
    y_stored = final_state(ds, config)
    longer = with_end_time(config, t_end, source=source)
    grid = build_grid(longer)
    n = grid.n
    t_final = ds["t_final"].values.reshape(n)[rows]
    undecided = grid.rows(rows)
    params, settings = undecided.params, undecided.settings.copy()
    remaining = params[:, layout.P_TAU_END] - t_final / undecided.time_unit
    params[:, layout.P_TAU_MAX] = remaining
    params[:, layout.P_TAU_END] = remaining
    if longer.classification.early_exit:
        # as a run: settle if it can; still unsettled at half time, carry the tangent
        # for λ1 over the second half (classification.lyapunov: unsettled)
        params[:, layout.P_TAU_END] = 0.5 * remaining
    elif settings[layout.S_LYAPUNOV] == layout.LYAP_UNSETTLED:
        settings[layout.S_LYAPUNOV] = layout.LYAP_ALWAYS  # fixed length: λ1 over all of it
    y0 = np.ascontiguousarray(y_stored[rows])
    progress = Progress(rows.size, desc="extend", enabled=show_progress)
    try:
        results, y_final = integrate_in_memory(params, y0, settings, threads, progress=progress)
    finally:
        progress.close()
    fields = derived_fields(undecided, results, y_final)
    out = ds.copy(deep=True)
    for var in variables_for(config.blocks, config.model, config.features):
        if var.name in LINEAR_THEORY or not var.per_member:
            continue
        da = out[var.name]
        flat = da.values.reshape((n, -1) if var.per_block or var.per_event else n).copy()
        new = fields[var.name]
        if var.name in SHIFTED:
            new = new + t_final
        elif var.name in SUMMED:
            new = new + flat[rows]
        flat[rows] = new
        out[var.name] = da.copy(data=flat.reshape(da.shape))
    if "regime_fraction" in out:
        out["regime_fraction"].values[...] = regime_fractions(out["regime"].values)
    out.attrs.update(
        integrator_t_end=longer.integrator.t_end,
        config_text=longer.text,
        history=f"{ds.attrs.get('history', '')}\n{utc_now()} extended by python -m sweep extend: "
        f"{rows.size} undecided runs continued from t_end = {old_end:g} to {t_end:g} {unit}",
    )
    return out


def write_extended(ds, path, source):
    """Write an extended result atomically; ``source`` (the input file) is named on failure.

    Raises ``RunError`` if the file cannot be written; the earlier file at
    ``path`` is then left as it was.
    """
    try:
        write_netcdf(ds, path)
    except (OSError, RuntimeError) as exc:
        raise RunError(
            f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}; {source} is unchanged"
        ) from None
    return path


def extend_file(
    path: str | os.PathLike,
    t_end: float | None = None,
    out: str | os.PathLike | None = None,
    threads: int | None = None,
    show_progress: bool = False,
) -> tuple[xr.Dataset, int]:
    """Extend a result file's undecided runs (:func:`extend_result`) and write it.

    Holds the lock of ``out`` from reading to writing, so a run or another extend
    on it refuses instead of one overwriting the other's result. The file is
    written through a temporary file, so a failed write leaves it as it was.

    Parameters
    ----------
    path : str or os.PathLike
        A result file (NetCDF, or a complete Zarr store with ``out`` given).
    t_end : float, optional
        New end time, as for :func:`extend_result`.
    out : str or os.PathLike, optional
        Where to write the extended result, a ``.nc`` path (default: ``path``,
        in place).
    threads : int, optional
        Threads on this machine (default: all cores).
    show_progress : bool, default False
        As for :func:`extend_result`.

    Returns
    -------
    dataset : xarray.Dataset
        The extended result.
    n_continued : int
        Runs continued; 0 when no run was undecided, and then nothing is written.

    Raises
    ------
    InputError
        As for :func:`extend_result`; also an ``out`` that cannot be written, or a
        Zarr store to be extended in place.
    RunError
        The file cannot be written (the old one is kept), or another process holds
        the output's lock.
    """
    if out is None and Path(path).suffix == ZARR_SUFFIX:
        raise InputError(path, ["extend writes NetCDF: give --out PATH.nc to extend a Zarr store"])
    if Path(path).suffix not in (".nc", ZARR_SUFFIX):
        raise InputError(
            path,
            [
                "extend reads a result file (.nc, or a .zarr store with --out); "
                "a config is run with rsf-sweep run"
            ],
        )
    out = path if out is None else out
    check_writable(out, path, "--out")
    with output_lock(out):
        ds = read_result(path, needs_config=True)
        extended = extend_result(ds, t_end, threads, source=path, show_progress=show_progress)
        n_continued = undecided_rows(ds).size
        if n_continued:
            write_extended(extended, out, path)
    return extended, n_continued
