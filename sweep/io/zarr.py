"""The Zarr result store: created full size up front, filled chunk by chunk.

For sweeps too large to wait for (10⁶ systems and more), ``--out x.zarr`` writes
the result as a Zarr (format 3) directory store instead of NetCDF. The store is
created before the first run with every variable of the schema at its final
shape, every coordinate and attribute of the NetCDF result, and consolidated
metadata. Nothing but data chunks is written after that, so ``xr.open_zarr``
reads it at any time during the run.

Its arrays are chunked so that each Zarr chunk holds a contiguous range of
points of the flattened (C-ordered) grid: chunk shape ``(1, …, 1, c, n_{k+1},
…)`` over the sweep axes, trailing dimensions (member, block, regime_name,
event) whole. Those points' runs (every ensemble member of each: regime_fraction is
counted per chunk) are the runner's chunks, so every finished chunk fills whole
Zarr chunks (no chunk is written twice or by two writers). Each Zarr chunk file
is written atomically (zarr's local store renames a temporary file), and
``regime`` is written last: a chunk counts as done once its regime is stored.

Points not computed yet read ``regime == -1`` (``PENDING``, the array's fill
value, not one of the ``flag_values``), NaN in every float variable and -1 in the
counts. ``--resume`` recomputes only the chunks whose regime is still pending,
after checking the store's ``config_hash`` attribute (``sweep.io.parts.config_hash``).
"""

import itertools
import logging
import math
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import InputError
from ..kernels.layout import result_width
from ..results.dataset import data_variables, derived_fields, parameter_coords, provenance
from .files import require_zarr
from .parts import config_hash

log = logging.getLogger(__name__)

#: ``regime`` (and the counts) at grid points not computed yet.
PENDING = -1
#: Global attribute that says how to tell pending points from computed ones.
PENDING_NOTE = (
    "regime is -1 (the array fill value) at grid points not computed yet; their float "
    "variables are NaN and their counts -1. The sweep is complete when no regime is -1."
)


def chunk_shape(shape, rows):
    """Zarr chunk shape for a grid of ``shape`` whose chunks are contiguous ranges of about
    ``rows`` points each: ``(1, …, 1, c, shape[k+1], …)``, ``c`` as even as can be."""
    k = next(k for k in range(len(shape)) if math.prod(shape[k + 1 :]) <= rows)
    per_chunk = max(1, rows // math.prod(shape[k + 1 :]))
    splits = math.ceil(shape[k] / per_chunk)
    return (1,) * k + (math.ceil(shape[k] / splits),) + tuple(shape[k + 1 :])


def chunk_regions(shape, chunks):
    """``(start, stop, region)`` of every chunk in C order: its points of the flattened
    grid and its region (a tuple of slices). ``chunks`` as from :func:`chunk_shape`."""
    out = []
    for origin in itertools.product(*(range(0, s, c) for s, c in zip(shape, chunks, strict=True))):
        region = tuple(
            slice(o, min(o + c, s)) for o, c, s in zip(origin, chunks, shape, strict=True)
        )
        start = int(np.ravel_multi_index(origin, shape))
        out.append((start, start + math.prod(r.stop - r.start for r in region), region))
    return out


class ZarrResult:
    """An open result store at ``path`` for the sweep on ``grid``.

    ``ranges``: the row ranges of its chunks (the runner's chunks); ``have``: which
    rows are stored already (boolean, per system). :meth:`save` writes rows.
    """

    def __init__(self, path, grid, chunk_rows, resume, command="run"):
        self.path = Path(path)
        self.grid = grid
        self.zarr = require_zarr(grid.config.source)
        shape, members = grid.config.shape, grid.config.members
        if self.path.exists():
            chunks = self._reopen(resume)[: len(shape)]
        else:
            chunks = chunk_shape(shape, max(1, chunk_rows // members))
            self._create(chunks, command)
        self.group = self.zarr.open_group(self.path, mode="r+")
        regions = chunk_regions(shape, chunks)  # of grid points; a run per member of each
        self.regions = {a * members: region for a, _, region in regions}
        self.ranges = [(a * members, b * members) for a, b, _ in regions]
        self.have = np.asarray(self.group["regime"][...]).reshape(-1) != PENDING
        self.saved = 0
        if resume:
            log.info(
                "resuming %s: %d of %d runs are stored", self.path, int(self.have.sum()), grid.n
            )

    def _reopen(self, resume):
        """Check that the existing store is this sweep's and may be continued; its chunks."""
        source = str(self.path)
        if not resume:
            raise InputError(
                source,
                [
                    "exists; --resume continues it (same config), or remove it or choose "
                    "another --out (an existing Zarr store is never overwritten)"
                ],
            )
        try:
            group = self.zarr.open_group(self.path, mode="r")
            attrs, chunks = dict(group.attrs), tuple(group["regime"].chunks)
        except Exception as exc:  # zarr raises several kinds for a folder that is not a store
            raise InputError(source, [f"not a Zarr result store of rsf-sweep ({exc})"]) from None
        want = config_hash(self.grid.config)
        if attrs.get("config_hash") != want:
            raise InputError(
                source,
                [
                    f"was made by another config (config_hash {attrs.get('config_hash')}, sweep "
                    f"{attrs.get('sweep_name')!r}), not by this one ({want}); it is left as it is: "
                    "remove it or choose another --out"
                ],
            )
        return chunks

    def _create(self, chunks, command):
        """Write the full-size store (fill values only) beside ``path``, then rename it.

        ``chunks``: the chunk shape over the grid points; trailing dimensions (member,
        block, regime_name, event) are whole in every chunk.
        """
        config = self.grid.config
        one_point = {
            name: np.full(shape, PENDING, dtype)
            for name, (shape, dtype) in _field_shapes(self.grid).items()
        }
        data_vars, encoding = {}, {}
        for name, (dims, data, attrs) in data_variables(
            config, one_point, (1,) * len(config.shape)
        ).items():
            fill = np.nan if data.dtype.kind == "f" else PENDING
            trailing = data.shape[len(config.shape) :]
            full = np.broadcast_to(np.array(fill, data.dtype), config.shape + trailing)
            data_vars[name] = (dims, full, attrs)
            encoding[name] = {"chunks": chunks + trailing}
            if data.dtype.kind != "f":
                encoding[name]["fill_value"] = PENDING
        attrs = {
            **provenance(config, command),
            "config_hash": config_hash(config),
            "pending": PENDING_NOTE,
        }
        ds = xr.Dataset(data_vars, coords=parameter_coords(config), attrs=attrs)
        tmp = Path(tempfile.mkdtemp(dir=self.path.parent, prefix=f".{self.path.name}."))
        try:
            with warnings.catch_warnings():
                # consolidated metadata and fixed-length strings (the regime_name
                # coordinate of ensembles) are not in the v3 spec yet; zarr-python reads both
                warnings.filterwarnings("ignore", message="Consolidated metadata")
                warnings.filterwarnings("ignore", message=".*does not have a Zarr V3 spec")
                ds.to_zarr(tmp, mode="w", encoding=encoding, consolidated=True, zarr_format=3)
            os.rename(tmp, self.path)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise

    def save(self, a, b, results, y_final):
        """Write rows ``a:b`` (one chunk of :attr:`ranges`) from the kernels' ``results`` and
        ``y_final`` for those rows; ``regime`` last, so the chunk counts as done only then."""
        region = self.regions[a]
        fields = derived_fields(self.grid.rows(slice(a, b)), results, y_final)
        shape = tuple(r.stop - r.start for r in region)
        data_vars = data_variables(self.grid.config, fields, shape)
        for name in sorted(data_vars, key=lambda name: name == "regime"):
            data = data_vars[name][1]
            self.group[name][region + (slice(None),) * (data.ndim - len(region))] = data
        self.have[a:b] = True
        self.saved += b - a


def _field_shapes(grid):
    """Shape and dtype of every flat field of one grid point (all its members):
    ``derived_fields`` of the grid's first rows."""
    m = grid.config.members
    results = np.zeros((m, result_width(grid.settings)))
    fields = derived_fields(grid.rows(slice(0, m)), results, grid.y0[:m])
    return {name: (f.shape, f.dtype) for name, f in fields.items()}


def open_result(path):
    """The result store at ``path`` as a lazily loaded Dataset (no dask needed)."""
    import xarray as xr

    return xr.open_dataset(path, engine="zarr", chunks=None)
