"""Zarr output: the store is readable while a sweep runs, resumable, and once complete
holds exactly the NetCDF result.

The reference is always the NetCDF file of the plainest run (``reference_file``: one
thread, one system per chunk), so no expected value comes from the Zarr code.
"""

import errno
import math
import os
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import PROVENANCE_ATTRS, QUICK, SUBPROCESS_TIMEOUT, reference_file, write_config
from hypothesis import given
from hypothesis import strategies as st
from test_nblock import nblock
from test_runner import SLOW, held_sweep, sweep_cli

from sweep.cli import main
from sweep.config import load_config
from sweep.engine import run_control, runner
from sweep.engine.backends import Resources
from sweep.errors import InputError, Interrupted, RunError
from sweep.io import zarr as zarr_store
from sweep.io.netcdf import read_result
from sweep.variables import variables_for

#: File attributes only a Zarr store has: how to resume it and how to read it mid-run.
ZARR_ATTRS = ("config_hash", "pending")


def plain(value):
    """An attribute value as a plain Python list (NetCDF gives numpy scalars and arrays,
    and reads a one-element array back as a scalar; Zarr gives JSON numbers and lists)."""
    return np.atleast_1d(value).tolist()


def assert_same_as_netcdf(store, netcdf):
    """The Zarr store holds the NetCDF result: every variable and coordinate (decoded as
    a reader sees them) bit for bit, with the same dims, dtype and attributes, and the
    same file attributes except provenance and :data:`ZARR_ATTRS`."""
    with xr.open_zarr(store) as got, xr.open_dataset(netcdf) as want:
        got, want = got.load(), want.load()
        assert set(got.variables) == set(want.variables)
        for name, var in want.variables.items():
            a, b = got[name].variable, var
            assert (a.dims, a.dtype, a.shape) == (b.dims, b.dtype, b.shape), name
            assert a.values.tobytes() == b.values.tobytes(), name
            assert {k: plain(v) for k, v in a.attrs.items()} == {
                k: plain(v) for k, v in b.attrs.items()
            }, name
        skip = set(PROVENANCE_ATTRS) | set(ZARR_ATTRS)
        assert {k: plain(v) for k, v in got.attrs.items() if k not in skip} == {
            k: plain(v) for k, v in want.attrs.items() if k not in skip
        }
        assert set(ZARR_ATTRS) <= set(got.attrs)


# --- layout: Zarr chunks are contiguous row ranges -------------------------------------


@given(
    shape=st.lists(st.integers(1, 7), min_size=1, max_size=4).map(tuple),
    rows=st.integers(1, 60),
)
def test_chunks_are_contiguous_row_ranges_of_the_grid(shape, rows):
    """Every chunk's region holds exactly the rows start:stop of the C-ordered grid, the
    chunks cover the grid once in order, and none is larger than asked for unless one
    grid line along the last axis already is."""
    chunks = zarr_store.chunk_shape(shape, rows)
    flat = np.arange(math.prod(shape)).reshape(shape)
    end = 0
    for start, stop, region in zarr_store.chunk_regions(shape, chunks):
        assert start == end
        assert (flat[region].ravel() == np.arange(start, stop)).all()
        assert stop - start <= max(rows, 1)
        end = stop
    assert end == flat.size


# --- results -----------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("chunk_size", [1, 4, None])
def test_zarr_equals_netcdf(quick, quick_reference_file, tmp_path, threads, chunk_size):
    out = tmp_path / "r.zarr"
    result = runner.run_sweep(quick, out=out, resources=Resources(threads),
                              chunk_size=chunk_size, show_progress=False)  # fmt: skip
    assert (result.path, result.computed, result.reused) == (out, 9, 0)
    assert_same_as_netcdf(out, quick_reference_file)
    assert not (tmp_path / "r.parts").exists()  # a Zarr run keeps no parts


@pytest.mark.slow
@pytest.mark.parametrize("chunk_size", [2, 6])
def test_two_axes_equal_netcdf(tmp_path, chunk_size):
    """A 4 × 3 grid of two blocks: chunks of 2 split the k2 axis (chunk shape (1, 2)),
    chunks of 6 the K axis ((2, 3))."""
    config = load_config(write_config(
        tmp_path / "two.yaml", blocks=2,
        sweep={"K_W": [0.04, 0.048, 0.052, 0.06], "k2_W": [0.0, 0.05, 0.5]},
        parameters={"k2_W": None}, initial={"phi_over_phi_ss": [1.01, 0.99]},
        integrator={"t_end": 300.0},
    ))  # fmt: skip
    reference = reference_file(config, tmp_path / "reference.nc")
    out = tmp_path / "two.zarr"
    runner.run_sweep(config, out=out, chunk_size=chunk_size, show_progress=False)
    assert xr.open_zarr(out)["regime"].encoding["chunks"] == {2: (1, 2), 6: (2, 3)}[chunk_size]
    assert_same_as_netcdf(out, reference)


@pytest.mark.slow
@pytest.mark.parametrize("chunk_size", [3, 7])
def test_ensemble_of_unequal_blocks_equals_netcdf(tmp_path, chunk_size):
    """Three unequal blocks in a ring, an ensemble of 3 per point: a chunk holds every
    member of its points (3 rows: one point; 7 rows: two points), so regime_fraction is
    counted per chunk."""
    config = load_config(nblock(3, "ring", parameters={"D0": [1.0, 1.3, 0.8]},
                                sweep={"K_W": [0.046, 0.049, 0.054]},
                                initial={"ensemble": 3, "seed": 0},
                                integrator={"t_end": 200.0}))  # fmt: skip
    reference = reference_file(config, tmp_path / "reference.nc")
    out = tmp_path / "e.zarr"
    result = runner.run_sweep(config, out=out, chunk_size=chunk_size, show_progress=False)
    assert result.computed == 9
    with xr.open_zarr(out) as ds:
        assert ds["regime"].encoding["chunks"] == ({3: 1, 7: 2}[chunk_size], 3)
        assert {"regime_fraction", "D0_block", "sync_order"} <= set(ds.data_vars)
    assert_same_as_netcdf(out, reference)


def test_cli_writes_a_zarr_store(tmp_path, capsys, quick_reference_file):
    out = tmp_path / "sub" / "q.zarr"
    assert main(["run", str(QUICK), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out} (9 runs" in printed and "steady" in printed
    assert_same_as_netcdf(out, quick_reference_file)
    ds = read_result(out)  # what plot, extend and audit read
    assert int((ds["regime"] >= 0).sum()) == 9


def test_plot_and_extend_read_a_complete_store(tmp_path, capsys):
    """plot reads the store; extend says it writes NetCDF unless given --out x.nc."""
    out = tmp_path / "q.zarr"
    assert main(["run", str(QUICK), "--out", str(out), "--quiet"]) == 0
    png = tmp_path / "q.png"
    assert main(["plot", str(out), "--out", str(png)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert main(["extend", str(out)]) == 2
    assert "extend writes NetCDF: give --out PATH.nc" in capsys.readouterr().err
    assert main(["extend", str(out), "--out", str(tmp_path / "e.nc")]) == 0
    assert "no undecided runs" in capsys.readouterr().out  # quick settles every run


# --- readable while running, resumable ------------------------------------------------------


@pytest.mark.slow
def test_sigkill_then_resume_recomputes_only_unfinished_chunks(tmp_path):
    """kill -9 of the CLI once one chunk (of 8 runs, ``SLOW``) is in the store; --resume
    computes the others and the store equals the NetCDF result."""
    slow_config = tmp_path / "slow.yaml"
    slow_config.write_text(SLOW)
    out = tmp_path / "slow.zarr"
    args = ["run", slow_config, "--out", out, "--chunk-size", "1", "--threads", "1"]
    proc = held_sweep(*args, cwd=tmp_path)  # its first chunk stored, the sweep waits
    proc.kill()
    proc.communicate(timeout=SUBPROCESS_TIMEOUT)
    with xr.open_zarr(out) as ds:
        assert int((ds["regime"] >= 0).sum()) == 1
    proc = sweep_cli(*args, "--resume", cwd=tmp_path)
    _, err = proc.communicate(timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == 0, err
    assert "1 of 8 runs are stored" in err
    assert "computing 7 runs in 7 chunks" in err
    assert_same_as_netcdf(out, reference_file(load_config(slow_config), tmp_path / "ref.nc"))


def test_readable_mid_run_and_resume_completes_it(
    quick, quick_reference_file, tmp_path, monkeypatch
):
    """After each saved chunk another reader opens the store: the chunks saved so far are
    the reference's rows, the rest pending (regime -1, NaN, counts -1). A stop after the
    second chunk keeps them, and --resume computes only the other rows."""
    out = tmp_path / "r.zarr"
    reference = xr.load_dataset(quick_reference_file)
    stop = run_control.StopRequest()
    save, seen = zarr_store.ZarrResult.save, []

    def save_then_read(self, a, b, results, y_final):
        save(self, a, b, results, y_final)
        with xr.open_zarr(out) as ds:
            regime = ds["regime"].values
        seen.append(b)
        assert (regime[:b] == reference["regime"].values[:b]).all()
        assert (regime[b:] == zarr_store.PENDING).all()
        if len(seen) == 2:
            stop.signum = 15

    monkeypatch.setattr(zarr_store.ZarrResult, "save", save_then_read)
    with pytest.raises(Interrupted, match=r"6 of 9 runs are saved in .*r\.zarr"):
        runner.run_sweep(quick, out=out, chunk_size=3, resources=Resources(1),
                         show_progress=False, stop=stop)  # fmt: skip
    assert seen == [3, 6]
    with xr.open_zarr(out) as ds:
        part = ds.load()
    for name in ("lnv_max", "period", "t_final", "K_over_Kc"):
        assert part[name].values[:6].tobytes() == reference[name].values[:6].tobytes(), name
        assert np.isnan(part[name].values[6:]).all(), name
    assert (part["n_steps"].values[6:] == -1).all()
    assert (part["lnv_final"].values[6:] != part["lnv_final"].values[6:]).all()  # NaN
    with pytest.raises(InputError, match="3 of 9 runs are not computed yet"):
        read_result(out)

    monkeypatch.undo()
    result = runner.run_sweep(quick, out=out, chunk_size=5, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (6, 3)  # the store's chunks of 3, not 5
    assert_same_as_netcdf(out, quick_reference_file)
    again = runner.run_sweep(quick, out=out, resume=True, show_progress=False)
    assert (again.reused, again.computed) == (9, 0)


def test_disk_full_inside_a_chunk_leaves_it_pending(
    quick, quick_reference_file, tmp_path, monkeypatch
):
    """The disk fills up while the third chunk's variables are written: the sweep stops
    with the cause, the chunk's regime (written last) stays pending although some of its
    variables are stored, and --resume recomputes exactly that chunk and the rest."""
    import zarr

    out = tmp_path / "r.zarr"
    setitem, save, calls = zarr.Array.__setitem__, zarr_store.ZarrResult.save, []
    per_chunk = len(variables_for(quick.blocks, quick.model, quick.features))

    def fill_up(self, key, value):  # counts the writes of chunks, not of the creation
        calls.append(self.basename)
        if self.basename == "lnv_min" and calls.count("lnv_min") == 3:  # the third chunk's
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        setitem(self, key, value)

    def save_filling_up(*args):
        monkeypatch.setattr(zarr.Array, "__setitem__", fill_up)
        save(*args)

    monkeypatch.setattr(zarr_store.ZarrResult, "save", save_filling_up)
    with pytest.raises(RunError, match=r"cannot write to .*r\.zarr: No space left"):
        runner.run_sweep(quick, out=out, chunk_size=3, resources=Resources(1),
                         show_progress=False)  # fmt: skip
    monkeypatch.undo()
    assert calls[per_chunk - 1] == "regime" and "regime" not in calls[2 * per_chunk :]
    assert calls[-2] == "lnv_max"
    with xr.open_zarr(out) as ds:
        regime, lnv_max = ds["regime"].values, ds["lnv_max"].values
    assert (regime[:6] >= 0).all() and (regime[6:] == zarr_store.PENDING).all()
    assert not np.isnan(lnv_max[6:]).all()  # a variable of the third chunk was stored
    result = runner.run_sweep(quick, out=out, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (6, 3)
    assert_same_as_netcdf(out, quick_reference_file)


def test_existing_store_needs_resume_and_the_same_config(quick, tmp_path, capsys):
    """Without --resume, or with another config, an existing store is refused (exit 2,
    naming it and the way out) and left exactly as it was."""
    out = tmp_path / "r.zarr"
    runner.run_sweep(quick, out=out, chunk_size=9, show_progress=False)
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    assert main(["run", str(QUICK), "--out", str(out), "--quiet"]) == 2
    assert "exists; --resume continues it" in capsys.readouterr().err
    other = tmp_path / "other.yaml"
    other.write_text(QUICK.read_text().replace("t_end: 2000.0", "t_end: 2500.0"))
    assert main(["run", str(other), "--out", str(out), "--resume", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{out}: was made by another config" in err and "choose another --out" in err
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before


def test_a_folder_that_is_not_a_store_is_refused(tmp_path, capsys):
    out = tmp_path / "r.zarr"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["run", str(QUICK), "--out", str(out), "--resume", "--quiet"]) == 2
    assert "not a Zarr result store" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


# --- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, message",
    [("r.zip", r"--out .*r\.zip must be a file name ending in \.nc or \.zarr"),
     ("file.zarr", r"--out .*file\.zarr is a file; a Zarr store \(\.zarr\) is a directory")],
)  # fmt: skip
def test_bad_output_is_bad_input(tmp_path, capsys, name, message):
    (tmp_path / "file.zarr").write_text("a file")
    assert main(["run", str(QUICK), "--out", str(tmp_path / name), "--quiet"]) == 2
    assert __import__("re").search(message, capsys.readouterr().err)
    assert not (tmp_path / "r.zip").exists()


def test_shards_need_netcdf(tmp_path, capsys):
    out = tmp_path / "r.zarr"
    assert main(["run", str(QUICK), "--out", str(out), "--shard", "0/2", "--quiet"]) == 2
    assert "--shard keeps parts for merge" in capsys.readouterr().err
    assert not out.exists()


def test_without_zarr_installed_says_how_to_get_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "zarr", None)  # import zarr raises ImportError
    out = tmp_path / "r.zarr"
    assert main(["run", str(QUICK), "--out", str(out), "--quiet"]) == 2
    assert "pip install 'rsf-sweep[zarr]'" in capsys.readouterr().err
    assert not out.exists()


def test_config_output_may_be_a_zarr_store(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(QUICK.read_text().replace("results/quick.nc", "results/quick.zarr"))
    assert load_config(path).output == "results/quick.zarr"
    path.write_text(QUICK.read_text().replace("results/quick.nc", "results/quick.h5"))
    with pytest.raises(InputError, match=r"output must be a path ending in \.nc .* or \.zarr"):
        load_config(path)
