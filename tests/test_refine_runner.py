"""Refined sweeps (sweep/engine/refined.py) keep the guarantees of the uniform sweep.

The plan of each level is a function of the runs of the levels before, and every run
is integrated independently, so the refined file must be *identical* (bit for bit, all
but the creation time and command line: ``assert_same_file``) whatever the thread
count, the chunk size, Dask, sharding, a stop or a kill -9 and ``--resume``; and every
refined point must be the very run a uniform grid makes at its parameter values.
"""

import re
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest
import xarray as xr
from conftest import SUBPROCESS_TIMEOUT, assert_same_file, make_config, read_line, reference_file
from test_runner import HELD_SWEEP, StopAfterFirstCheck

from sweep.cli import main
from sweep.config import load_config, with_changes
from sweep.engine import runner
from sweep.engine.backends import Resources
from sweep.errors import InputError, Interrupted, RunError
from sweep.io import parts as store
from sweep.refine.dataset import to_grid

#: Two quasi-static blocks over K/W × k2/W around Kc/W = 0.05 µm⁻¹ (between grid points),
#: 3 levels: 15 cells, about 60 runs, none closer to Kc than 1 % (runs of a few 1000 D0/V).
TWO_BLOCKS = {
    "blocks": 2,
    "parameters": {"k2_W": None},
    "sweep": {"K_W": {"start": 0.031, "stop": 0.071, "num": 6}, "k2_W": [0.0, 0.1, 0.2]},
    "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
    "refine": {"levels": 3},
}

#: Two unequal quasi-dynamic blocks (D0 = 1.0 and 0.6 µm, ηV/W = 0.001): cycles of one
#: and two events and steady sliding meet on this grid (the map of configs/unequal_qd.yaml).
COMPLEX = {
    "blocks": 2,
    "model": "quasi-dynamic",
    "parameters": {"V": 1.0, "D0": [1.0, 0.6], "eta_W": 0.001},
    "sweep": {"K_W": {"start": 0.05, "stop": 0.07, "num": 3},
              "k2_W": {"start": 0.005, "stop": 0.02, "num": 3}},
    "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
    "integrator": {"method": "dop853", "t_end": 3000.0},
    "classification": {"events": 8},
    "refine": {"levels": 2},
}  # fmt: skip


@pytest.fixture(scope="module")
def two_blocks():
    return make_config(TWO_BLOCKS)


@pytest.fixture(scope="module")
def two_blocks_file(two_blocks, tmp_path_factory):
    """The plainest refined run (one thread, one run per chunk), written."""
    return reference_file(two_blocks, tmp_path_factory.mktemp("reference") / "two.nc")


# --- every refined point is the uniform grid's run there ------------------------------------


@pytest.fixture(scope="module")
def complex_uniform():
    """The uniform grid of COMPLEX's finest level (2), as a grid sweep runs it."""
    config = make_config(COMPLEX)
    fine = {a.name: {"start": a.span[1], "stop": a.span[2], "num": 9} for a in config.axes}
    return runner.compute(with_changes(config, {"refine": None, "sweep": fine}),
                          show_progress=False)  # fmt: skip


def refined_on_uniform(config, uniform):
    """The refinement of ``config`` run, on the grid of its level 2 (``to_grid``), and
    which of its points it ran (``exact``), checked to lie on ``uniform``'s."""
    ds = runner.compute(config, show_progress=False)
    labels = {tuple(x) for x in np.stack([ds.regime, ds.attractor, ds.cycle_events], -1).tolist()}
    assert len(labels) >= 3, labels
    assert (ds.level.values > 0).sum() > 0
    grid = to_grid(ds, 2)
    exact = grid["exact"].values
    assert exact.sum() == ds.sizes["point"]
    for name in ("K_W", "k2_W"):
        assert grid[name].values.tobytes() == uniform[name].values.tobytes()
    return grid, exact


@pytest.mark.slow
def test_refined_points_are_the_runs_of_the_uniform_grid_of_their_level(complex_uniform):
    """On a map where cycles of one and two events and steady sliding meet, every run of
    a refinement with ``full_runs: true`` equals (bit for bit, every output) the run of
    the uniform grid of the finest level at the same point, whose values it has exactly."""
    config = make_config(COMPLEX, refine={"full_runs": True})
    grid, exact = refined_on_uniform(config, complex_uniform)
    assert "linear_verdict" not in grid
    for name, var in complex_uniform.data_vars.items():
        got, want = grid[name].values[exact], var.values[exact]
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), name


@pytest.mark.slow
def test_by_default_refined_runs_have_the_uniform_grids_labels(complex_uniform):
    """With linear-regime verdicts (the default) every refined run has the label of the
    uniform grid's run (regime, attractor, cycle_events), and a run that no such verdict
    stopped is that run bit for bit; one that one did stopped earlier."""
    grid, exact = refined_on_uniform(make_config(COMPLEX), complex_uniform)
    linear = grid["linear_verdict"].values[exact] == 1
    for name, var in complex_uniform.data_vars.items():
        got, want = grid[name].values[exact], var.values[exact]
        if name in ("regime", "attractor", "cycle_events"):
            np.testing.assert_array_equal(got, want, err_msg=name)
        else:
            assert got[~linear].tobytes() == want[~linear].tobytes(), name
    t_final = complex_uniform["t_final"].values[exact]
    assert (grid["t_final"].values[exact][linear] < t_final[linear]).all()


# --- determinism: threads, chunks, stops and resumption --------------------------------------


@pytest.mark.parametrize("threads, chunk_size", [(1, 3), (2, 1), (2, None)])
def test_threads_and_chunks_give_identical_refined_files(two_blocks, two_blocks_file, tmp_path,
                                                          threads, chunk_size):  # fmt: skip
    out = tmp_path / "r.nc"
    result = runner.run_sweep(two_blocks, out=out, resources=Resources(threads),
                              chunk_size=chunk_size, show_progress=False)  # fmt: skip
    assert_same_file(out, two_blocks_file)
    assert result.computed == result.dataset.sizes["point"] and result.reused == 0
    assert not store.parts_dir_for(out).exists()


def test_a_stop_keeps_the_saved_chunks_and_resume_completes(two_blocks, two_blocks_file, tmp_path):
    out = tmp_path / "r.nc"
    with pytest.raises(Interrupted, match=r"SIGTERM: level 0: 4 of 18 runs are saved"):
        runner.run_sweep(two_blocks, out=out, chunk_size=4, show_progress=False,
                         stop=StopAfterFirstCheck())  # fmt: skip
    result = runner.run_sweep(two_blocks, out=out, chunk_size=5, resume=True,
                              show_progress=False)  # fmt: skip
    assert result.reused == 4 and result.computed == result.dataset.sizes["point"] - 4
    assert_same_file(out, two_blocks_file)


@pytest.mark.slow
def test_sigkill_in_a_later_level_then_resume(two_blocks, tmp_path):
    """kill -9 while level 2 runs (its first chunk saved); --resume reuses every saved
    chunk of every level and writes the same file."""
    config = tmp_path / "two.yaml"
    config.write_text(two_blocks.text)
    out = tmp_path / "r.nc"
    args = ["run", config, "--out", out, "--chunk-size", "4", "--threads", "1", "--quiet"]
    proc = subprocess.Popen([sys.executable, "-c", HELD_SWEEP, *map(str, args)], cwd=tmp_path,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    saved = 0
    while True:
        assert read_line(proc) == "saved\n"
        saved += 1
        levels = {store.read_part(p).config_text for p in store.parts_dir_for(out).glob("*.npz")}
        keys = {p.name.split("_")[0] for p in store.parts_dir_for(out).glob("*.npz")}
        if len(keys) == 3:  # levels 0, 1 and the first chunk of 2
            break
        proc.stdin.write("go on\n")
        proc.stdin.flush()
    assert len(levels) == 1  # every part holds the config
    proc.kill()
    proc.communicate(timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == -signal.SIGKILL
    resumed = subprocess.run([sys.executable, "-m", "sweep", *map(str, args[:-1]), "--resume"],
                             cwd=tmp_path, capture_output=True, text=True,
                             timeout=SUBPROCESS_TIMEOUT)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    log = resumed.stderr
    reused = [int(n) for n in re.findall(r"level \d: reusing (\d+) runs", log)]
    runs = [int(n) for n in re.findall(r"test: level \d: (\d+) runs\n", log)]
    assert reused[:2] == runs[:2] and reused[2] == 4, log  # levels 0, 1 and a chunk of 2
    assert_same_file(out, reference_file(load_config(config), tmp_path / "reference.nc"))
    assert not store.parts_dir_for(out).exists()


@pytest.mark.slow
def test_shards_meet_between_levels_and_merge_to_the_same_file(two_blocks, two_blocks_file,
                                                               tmp_path, capsys):  # fmt: skip
    """Two shards run at once (threads here, job-array tasks elsewhere): each runs every
    other chunk of a level, waits for the other's parts, plans the next level as the
    other does; merge assembles the file."""
    out = tmp_path / "r.nc"
    results, errors = {}, []

    def shard(i):
        try:
            results[i] = runner.run_sweep(two_blocks, out=out, resources=Resources(1), chunk_size=2,
                                          shard=(i, 2), show_progress=False)  # fmt: skip
        except BaseException as exc:  # raised again below
            errors.append(exc)

    threads = [threading.Thread(target=shard, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=SUBPROCESS_TIMEOUT)
    assert not errors, errors
    assert results[0].dataset is None and not out.exists()
    assert 0 < results[0].computed < results[0].computed + results[1].computed
    parts = store.parts_dir_for(out)
    assert main(["merge", str(parts), "--out", str(out)]) == 0
    assert_same_file(out, two_blocks_file)
    assert not parts.exists()


def test_merge_names_the_level_whose_runs_are_missing(two_blocks, tmp_path):
    out = tmp_path / "r.nc"
    with pytest.raises(Interrupted):
        runner.run_sweep(two_blocks, out=out, chunk_size=4, show_progress=False,
                         stop=StopAfterFirstCheck())  # fmt: skip
    with pytest.raises(RunError, match=r"level 0: rows 4:18 missing \(14 of 18 runs\)"):
        runner.merge_parts([store.parts_dir_for(out)], tmp_path / "merged.nc")
    assert not (tmp_path / "merged.nc").exists()


@pytest.mark.slow
def test_dask_workers_give_the_same_refined_file(two_blocks, two_blocks_file, tmp_path):
    pytest.importorskip("distributed")
    out = tmp_path / "r.nc"
    runner.run_sweep(two_blocks, out=out, resources=Resources(dask_local=2), chunk_size=3,
                     show_progress=False)  # fmt: skip
    assert_same_file(out, two_blocks_file)


# --- budget, progress, refusals -----------------------------------------------------------------


def test_max_runs_is_honoured_exactly_and_counted_per_level(quick, tmp_path):
    """quick.yaml (9 runs) refined 10 levels with at most 14 runs: a point per level and
    transition (runaway, then a band of slowly growing cycles labelled stick-slip near
    Kc, then steady), so the level that would pass 14 is cut to the cell that fits."""
    config = with_changes(quick, {"refine": {"levels": 10, "max_runs": 14}})
    ds = runner.compute(config, show_progress=False)
    assert ds.attrs["refine_runs"].tolist() == [9, 2, 2, 1]
    assert ds.sizes["point"] == 14
    assert "max_runs" in ds.attrs["refine_stopped"] and ds.attrs["refine_max_runs"] == 14


def test_progress_is_shown_per_level(quick, capsys):
    config = with_changes(quick, {"refine": {"levels": 2}})
    runner.compute(config, threads=1)
    err = capsys.readouterr().err
    for level, runs in enumerate((9, 2, 2)):
        assert f"quick level {level}/2: {runs}/{runs} runs (100%)" in err, err


def test_a_refined_sweep_refuses_a_zarr_output(two_blocks, tmp_path):
    with pytest.raises(InputError, match=r"must be a file name ending in \.nc"):
        runner.run_sweep(two_blocks, out=tmp_path / "r.zarr", show_progress=False)


def test_the_file_opens_with_plain_xarray(two_blocks_file):
    with xr.open_dataset(two_blocks_file) as ds:
        assert ds.attrs["featureType"] == "point"
        assert ds["regime"].dims == ("point",)
        assert set(ds["K_W"].dims) == {"point"} and ds["level"].max() == 3
        assert ds.attrs["refine_runs"].sum() == ds.sizes["point"]
        assert ds["regime"].attrs["flag_meanings"].split()[0] == "steady"
