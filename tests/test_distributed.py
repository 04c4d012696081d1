"""Scaling out: Dask workers and job-array shards give the same numbers as threads.

Results must be identical (no tolerance): each system is integrated by the same
code whichever process, thread or shard runs it: ``assert_same_file`` compares
every variable and attribute of the files, all but the creation time and command.
"""

import numpy as np
import pytest
from conftest import QUICK, SUBPROCESS_TIMEOUT, assert_same_file

from sweep import accelerate
from sweep.cli import main
from sweep.config import load_config
from sweep.engine import chunks, runner
from sweep.engine.backends import Resources
from sweep.engine.dispatch import grid_kernel, load_kernel
from sweep.engine.grid import build_grid
from sweep.io import parts as store

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")

from sweep.engine import distributed as sweep_distributed  # noqa: E402


@pytest.fixture(scope="module")
def local_client():
    """A LocalCluster of 2 single-threaded worker processes, as ``--dask-local 2`` starts."""
    with sweep_distributed.connect(local_workers=2) as client:
        client.wait_for_workers(2, timeout=SUBPROCESS_TIMEOUT)
        yield client


def test_serial_task_kernel_matches_threads_on_read_only_input(quick):
    """Arrays unpickled on a worker may be read-only; the task copes and agrees."""
    g = build_grid(quick)
    params, y0, settings = g.params, g.y0, g.settings
    for a in (params, y0, settings):
        a.flags.writeable = False
    results, y_final = sweep_distributed.chunk_task(params, y0, settings)
    threaded, y_threaded = chunks.integrate_in_memory(params.copy(), y0.copy(), settings.copy())
    np.testing.assert_array_equal(results, threaded)
    np.testing.assert_array_equal(y_final, y_threaded)


@pytest.mark.slow
def test_local_cluster_gives_identical_results(quick, quick_reference_file, local_client, tmp_path):
    """Through ``Resources(scheduler=...)``, i.e. ``--scheduler ADDRESS``, in chunks of 2."""
    out = tmp_path / "r.nc"
    address = local_client.scheduler.address
    runner.run_sweep(quick, out=out, resources=Resources(scheduler=address), chunk_size=2,
                     show_progress=False)  # fmt: skip
    assert_same_file(out, quick_reference_file)


@pytest.mark.slow
def test_local_cluster_fills_a_zarr_store(quick, quick_reference_file, local_client, tmp_path):
    """Dask tasks finish in any order; each fills its own chunks of the store."""
    pytest.importorskip("zarr")
    from test_zarr_store import assert_same_as_netcdf

    out = tmp_path / "r.zarr"
    runner.run_sweep(quick, out=out, resources=Resources(scheduler=local_client), chunk_size=2,
                     show_progress=False)  # fmt: skip
    assert_same_as_netcdf(out, quick_reference_file)


@pytest.mark.slow
def test_workers_load_the_kernel_from_the_cache(local_client):
    """The parent compiles the serial kernel before it submits a task; the workers
    then only load it from numba's cache and never compile it themselves, so no two
    processes write the cache at once (numba#4807)."""
    if not accelerate.CACHE:
        pytest.skip("numba cache disabled (SWEEP_NUMBA_CACHE=0)")

    g = build_grid(load_config(QUICK))

    def compile_stats():
        stats = grid_kernel(g.params, g.settings).stats
        return len(stats.cache_hits), len(stats.cache_misses)

    load_kernel(g.params, g.settings)
    local_client.run(load_kernel, g.params, g.settings)
    for hits, misses in local_client.run(compile_stats).values():
        assert (hits, misses) == (1, 0)


def test_three_shards_and_merge_give_identical_results(quick_reference_file, tmp_path, capsys):
    out = tmp_path / "r.nc"
    for i in range(3):
        args = ["run", str(QUICK), "--out", str(out), "--shard", f"{i}/3", "--chunk-size", "2"]
        assert main([*args, "--quiet"]) == 0
        assert not out.exists()
    parts_dir = store.parts_dir_for(out)
    assert "python -m sweep merge" in capsys.readouterr().out
    assert main(["merge", str(parts_dir), "--out", str(out)]) == 0
    assert_same_file(out, quick_reference_file)
    assert not parts_dir.exists()


def test_unreachable_scheduler_is_a_clear_error(tmp_path, capsys):
    out = tmp_path / "r.nc"
    out.write_bytes(b"earlier result")
    address = "tcp://127.0.0.1:1"  # port 1: nothing listens there
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        code = main(["run", str(QUICK), "--out", str(out), "--scheduler", address, "--quiet"])
    assert code == 1
    assert f"cannot reach the Dask scheduler at {address}" in capsys.readouterr().err
    assert out.read_bytes() == b"earlier result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc"]


def test_threads_and_dask_do_not_mix(tmp_path, capsys):
    out = tmp_path / "r.nc"
    assert main(["run", str(QUICK), "--out", str(out), "--threads", "1", "--dask-local", "2"]) == 2
    assert "--threads" in capsys.readouterr().err


@pytest.mark.slow
def test_api_runs_on_a_client_a_cluster_or_not_a_client(quick, quick_reference_file, local_client,
                                                        tmp_path):  # fmt: skip
    """``sweep.run(client=...)`` and ``Resources(scheduler=...)`` take a Client (left
    open) or a Cluster; anything else is the tool's InputError, not a TypeError."""
    import sweep
    from sweep.io.netcdf import write_netcdf

    for k, client in enumerate((local_client, local_client.cluster)):
        ds = sweep.run(quick, client=client, progress=False)
        assert_same_file(write_netcdf(ds, tmp_path / f"{k}.nc"), quick_reference_file)
    assert local_client.status == "running"
    with pytest.raises(sweep.InputError, match="must be a dask distributed Client"):
        sweep.run(quick, client=3, progress=False)
    with pytest.raises(sweep.InputError, match="threads is for local threads"):
        sweep.run(quick, client=local_client, threads=1, progress=False)


@pytest.mark.slow
def test_run_sweep_takes_a_client(quick, quick_reference_file, local_client, tmp_path):
    """``run_sweep`` with a Client as scheduler used to raise TypeError."""
    result = runner.run_sweep(quick, out=tmp_path / "c.nc", show_progress=False,
                              resources=Resources(scheduler=local_client))  # fmt: skip
    assert_same_file(result.path, quick_reference_file)


@pytest.mark.slow
def test_the_dashboard_of_a_cluster_that_serves_one_is_logged(quick, quick_reference_file,
                                                              tmp_path, caplog):  # fmt: skip
    """A scheduler with a dashboard (bokeh, which serves it, is in the ``distributed``
    extra): its link is logged, which the CLI prints on stderr. (``--dask-local`` starts
    its cluster without one.)"""
    import logging

    caplog.set_level("INFO", logger="sweep")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address="127.0.0.1:0",
                                  silence_logs=logging.ERROR) as cluster:  # fmt: skip
        link = cluster.dashboard_link
        result = runner.run_sweep(quick, out=tmp_path / "d.nc", show_progress=False,
                                  resources=Resources(scheduler=cluster))  # fmt: skip
    assert link.startswith("http://127.0.0.1:")
    assert f"Dask dashboard: {link}" in caplog.text
    assert_same_file(result.path, quick_reference_file)
