"""How a catalogue's statistics move with its slip threshold.

A block slips in an event while its v/V exceeds ``catalogue.slip_v_over_V``
(``sweep/kernels/slip_events.py``): the threshold sets where events begin and end, which
neighbours they join and so their sizes. :func:`threshold_sensitivity` runs a config's
catalogue at several thresholds, over its grid or a part of it, and returns the results
along a ``slip_v_over_V`` dimension, statistics included, for ``plot_threshold_sensitivity``
(``make figures``: ``results/catalogue_threshold.png``).
"""

import os
from collections.abc import Mapping, Sequence
from typing import Any

import xarray as xr

from ..config import Config, load_config, with_changes
from ..engine.runner import compute
from ..errors import InputError


def threshold_sensitivity(
    config: str | os.PathLike | Mapping[str, Any] | Config,
    thresholds: Sequence[float],
    sweep: Mapping[str, Sequence[float]] | None = None,
    threads: int | None = None,
    progress: bool = False,
) -> xr.Dataset:
    """Run ``config``'s catalogue at each slip threshold and stack the results.

    Parameters
    ----------
    config : str, os.PathLike, Mapping or Config
        A config with a catalogue (``catalogue.capacity`` > 0), as :func:`sweep.run`
        takes it.
    thresholds : sequence of float
        Values of ``catalogue.slip_v_over_V`` (v/V, each > 0, distinct).
    sweep : Mapping, optional
        Sweep axes replaced for these runs (e.g. ``{"spread_D0": [0.15]}``: one column of
        the grid), merged into the config's ``sweep`` section.
    threads : int, optional
        Threads (default: all cores).
    progress : bool, default False
        Show each run's progress.

    Returns
    -------
    xarray.Dataset
        The results along a new ``slip_v_over_V`` dimension (its coordinate in v/V), each
        with the catalogue and its statistics as :func:`sweep.run` gives them.

    Raises
    ------
    InputError
        No catalogue in the config, or thresholds empty, not positive or repeated.
    """
    base = load_config(config)
    if base.catalogue.capacity <= 0:
        raise InputError(base.source, ["catalogue.capacity is 0: no catalogue to test"])
    values = [float(t) for t in thresholds]
    if not values or min(values) <= 0.0 or len(set(values)) != len(values):
        problem = f"thresholds must be distinct positive v/V values, got {thresholds!r}"
        raise InputError("thresholds", [problem])
    results = []
    for value in values:
        changes = {"catalogue": {"slip_v_over_V": value}}
        if sweep:
            changes["sweep"] = {k: list(v) for k, v in sweep.items()}
        ds = compute(with_changes(base, changes), threads=threads, show_progress=progress)
        results.append(ds.expand_dims(slip_v_over_V=[value]))
    out = xr.concat(results, "slip_v_over_V", combine_attrs="override")
    out["slip_v_over_V"].attrs.update(
        units="1",
        long_name="slip threshold v/V",
        description="catalogue.slip_v_over_V: a block slips in an event while v/V exceeds it",
    )
    return out.sortby("slip_v_over_V")
