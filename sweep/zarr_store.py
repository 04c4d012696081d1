"""The Zarr result store: created full size up front, filled chunk by chunk.

For sweeps too large to wait for (10⁶ systems and more), ``--out x.zarr`` writes
the result as a Zarr (format 3) directory store instead of NetCDF. The store is
created before the first run with every variable of the schema at its final
shape, every coordinate and attribute of the NetCDF result, and consolidated
metadata. Nothing but data chunks is written after that, so ``xr.open_zarr``
reads it at any time during the run.

Its arrays are chunked so that each Zarr chunk holds a contiguous range of rows
of the flattened (C-ordered) grid: chunk shape ``(1, …, 1, c, n_{k+1}, …)``.
Those row ranges are the runner's chunks, so every finished chunk fills whole
Zarr chunks (no chunk is written twice or by two writers). Each Zarr chunk file
is written atomically (zarr's local store renames a temporary file), and
``regime`` is written last: a chunk counts as done once its regime is stored.

Points not computed yet read ``regime == -1`` (``PENDING``, the array's fill
value, not one of the ``flag_values``), NaN in every float variable and -1 in the
counts. ``--resume`` recomputes only the chunks whose regime is still pending,
after checking the store's ``config_hash`` attribute (``store.config_hash``).
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

from .dataset import dataset_from_fields, derived_fields
from .errors import InputError
from .store import config_hash, require_zarr
from .variables import variables_for

log = logging.getLogger(__name__)

#: ``regime`` (and the counts) at grid points not computed yet.
PENDING = -1
#: Global attribute that says how to tell pending points from computed ones.
PENDING_NOTE = (
    "regime is -1 (the array fill value) at grid points not computed yet; their float "
    "variables are NaN and their counts -1. The sweep is complete when no regime is -1."
)


def chunk_shape(shape, rows):
    """Zarr chunk shape for a grid of ``shape`` whose chunks are contiguous row ranges of
    about ``rows`` systems each: ``(1, …, 1, c, shape[k+1], …)``, ``c`` as even as can be."""
    k = next(k for k in range(len(shape)) if math.prod(shape[k + 1 :]) <= rows)
    per_chunk = max(1, rows // math.prod(shape[k + 1 :]))
    splits = math.ceil(shape[k] / per_chunk)
    return (1,) * k + (math.ceil(shape[k] / splits),) + tuple(shape[k + 1 :])


def chunk_regions(shape, chunks):
    """``(start, stop, region)`` of every chunk in C order: its rows of the flattened grid
    and its region (a tuple of slices). ``chunks`` as from :func:`chunk_shape`."""
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
        if self.path.exists():
            chunks = self._reopen(resume)
        else:
            chunks = chunk_shape(grid.config.shape, chunk_rows)
            self._create(chunks, command)
        self.group = self.zarr.open_group(self.path, mode="r+")
        self.regions = {a: region for a, _, region in chunk_regions(grid.config.shape, chunks)}
        self.ranges = [(a, b) for a, b, _ in chunk_regions(grid.config.shape, chunks)]
        self.have = np.asarray(self.group["regime"][...]).reshape(-1) != PENDING
        self.saved = 0
        if resume:
            log.info("resuming %s: %d of %d runs are stored", self.path, int(self.have.sum()),
                     grid.n)  # fmt: skip

    def _reopen(self, resume):
        """Check that the existing store is this sweep's and may be continued; its chunks."""
        source = str(self.path)
        if not resume:
            raise InputError(
                source,
                ["exists; --resume continues it (same config), or remove it or choose "
                 "another --out (an existing Zarr store is never overwritten)"],
            )  # fmt: skip
        try:
            group = self.zarr.open_group(self.path, mode="r")
            attrs, chunks = dict(group.attrs), tuple(group["regime"].chunks)
        except Exception as exc:  # zarr raises several kinds for a folder that is not a store
            raise InputError(source, [f"not a Zarr result store of rsf-sweep ({exc})"]) from None
        want = config_hash(self.grid.config)
        if attrs.get("config_hash") != want:
            raise InputError(
                source,
                [f"was made by another config (config_hash {attrs.get('config_hash')}, sweep "
                 f"{attrs.get('sweep_name')!r}), not by this one ({want}); it is left as it is: "
                 "remove it or choose another --out"],
            )  # fmt: skip
        return chunks

    def _create(self, chunks, command):
        """Write the full-size store (fill values only) beside ``path``, then rename it."""
        config = self.grid.config
        n, nb = self.grid.n, config.blocks
        fields, encoding = {}, {}
        for var in variables_for(nb, config.model):
            fill = np.nan if var.dtype.startswith("float") else PENDING
            rows = (n, nb) if var.per_block else (n,)
            fields[var.name] = np.broadcast_to(np.array(fill, dtype=var.dtype), rows)
            encoding[var.name] = {"chunks": chunks + ((nb,) if var.per_block else ())}
            if fill == PENDING:
                encoding[var.name]["fill_value"] = PENDING
        ds = dataset_from_fields(config, fields, command)
        ds.attrs.update(config_hash=config_hash(config), pending=PENDING_NOTE)
        tmp = Path(tempfile.mkdtemp(dir=self.path.parent, prefix=f".{self.path.name}."))
        try:
            with warnings.catch_warnings():  # consolidated metadata is not yet in the v3 spec
                warnings.filterwarnings("ignore", message="Consolidated metadata")
                ds.to_zarr(tmp, mode="w", encoding=encoding, consolidated=True, zarr_format=3)
            os.rename(tmp, self.path)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise

    def save(self, a, b, results, y_final):
        """Write rows ``a:b`` (one chunk of :attr:`ranges`) from the kernels' ``results`` and
        ``y_final`` for those rows; ``regime`` last, so the chunk counts as done only then."""
        region = self.regions[a]
        shape = tuple(r.stop - r.start for r in region)
        fields = derived_fields(self.grid.rows(slice(a, b)), results, y_final)
        schema = variables_for(self.grid.config.blocks, self.grid.config.model)
        for var in sorted(schema, key=lambda v: v.name == "regime"):
            data = fields[var.name].astype(var.dtype, copy=False)
            if var.per_block:
                self.group[var.name][region + (slice(None),)] = data.reshape(shape + (-1,))
            else:
                self.group[var.name][region] = data.reshape(shape)
        self.have[a:b] = True
        self.saved += b - a


def open_result(path):
    """The result store at ``path`` as a lazily loaded Dataset (no dask needed)."""
    import xarray as xr

    return xr.open_dataset(path, engine="zarr", chunks=None)
