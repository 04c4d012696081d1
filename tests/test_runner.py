"""The runner: chunked, resumable and interruptible sweeps give the same numbers every way.

Every system is integrated independently and deterministically, so the result
file must hold *identical* data (bit for bit, no tolerance) whatever the chunk
size, thread count, resumption or interruption: ``assert_same_file`` compares
every variable and attribute, all but the creation time and command line.
"""

import ctypes
import errno
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numba
import numpy as np
import pytest
import xarray as xr
from conftest import (
    QUICK,
    SUBPROCESS_TIMEOUT,
    assert_same_file,
    interrupted_part_writer,
    read_line,
    reference_file,
)
from hypothesis import given
from hypothesis import strategies as st

from sweep.cli import main
from sweep.config import load_config, parse_config
from sweep.engine import backends, chunks, run_control, runner
from sweep.engine.backends import LocalThreads, Resources
from sweep.engine.dispatch import ready_kernel
from sweep.engine.grid import build_grid
from sweep.errors import Interrupted, RunError
from sweep.io import netcdf
from sweep.io import parts as store

#: 8 slow runs, for a kernel call long enough to signal during it: fixed-step RK4 with
#: 1e6 steps per run (about 0.2 s each on one thread), runs kept going to t_end
#: (early_exit false, and a steady threshold the slowly decaying oscillation just above
#: Kc/W never reaches).
SLOW = """\
name: slow
blocks: 1
model: quasi-static
state_law: aging
parameters: {A: 0.03, B: 0.08, mu0: 0.4, V: 0.1, Phi0: 1.0, D0: 1.0}
sweep:
  K_W: {start: 0.0502, stop: 0.051, num: 8}
integrator: {method: rk4, dt: 0.002, t_end: 2000.0}
classification: {early_exit: false, steady_amplitude: 1.0e-12}
"""


@pytest.fixture
def slow_config(tmp_path):
    path = tmp_path / "slow.yaml"
    path.write_text(SLOW)
    return path


def sweep_cli(*args, cwd, **popen):
    """Start ``python -m sweep ARGS`` in ``cwd``, stderr piped."""
    return subprocess.Popen(
        [sys.executable, "-m", "sweep", *map(str, args)],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **popen,
    )


#: ``python -c HELD_SWEEP ARGS`` is ``python -m sweep ARGS`` that prints "saved" after
#: saving each chunk (a part or Zarr chunk) and then waits for a line on its stdin: a
#: test signals or kills it at a known point, whatever the kernel's speed.
HELD_SWEEP = r"""
import sys
from sweep import cli
from sweep.io import parts

def held(save):
    def save_then_wait(self, a, b):
        save(self, a, b)
        print("saved", flush=True)
        sys.stdin.readline()
    return save_then_wait

parts.PartStore.save = held(parts.PartStore.save)
parts.ZarrSink.save = held(parts.ZarrSink.save)
sys.exit(cli.main(sys.argv[1:]))
"""


def held_sweep(*args, cwd):
    """Start :data:`HELD_SWEEP` with ``ARGS`` in ``cwd``; return it once it has saved its
    first chunk and waits (send a line to its stdin to let it go on)."""
    proc = subprocess.Popen([sys.executable, "-c", HELD_SWEEP, *map(str, args)], cwd=cwd,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    while (line := read_line(proc)) != "saved\n":
        assert line, f"the sweep ended before it saved a chunk: {proc.communicate()[1]}"
    return proc


# --- plan: chunks, shards, rows still missing -----------------------------------


@given(
    n=st.integers(1, 200),
    chunk=st.integers(1, 50),
    n_shards=st.integers(1, 5),
)
def test_shards_partition_the_grid(n, chunk, n_shards):
    """Every row belongs to exactly one chunk of exactly one shard."""
    owner = np.zeros(n, int)
    for i in range(n_shards):
        for a, b in chunks.chunk_ranges(n, chunk, (i, n_shards)):
            assert 0 < b - a <= chunk and a % chunk == 0
            owner[a:b] += 1
    assert (owner == 1).all()


@given(have=st.lists(st.booleans(), min_size=1, max_size=60), chunk=st.integers(1, 9))
def test_missing_ranges_are_exactly_the_missing_rows(have, chunk):
    """The ranges left to compute cover the rows not yet had, each within one chunk."""
    have = np.array(have)
    ranges = chunks.chunk_ranges(len(have), chunk)
    todo = chunks.missing_ranges(ranges, have)
    covered = np.zeros(len(have), int)
    for a, b in todo:
        covered[a:b] += 1
        assert any(c <= a and b <= d for c, d in ranges)
    assert (covered == ~have).all()


# --- determinism ------------------------------------------------------------------


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("chunk_size", [1, 7, None])
def test_chunk_size_and_threads_do_not_change_results(
    quick, quick_reference_file, tmp_path, threads, chunk_size
):
    chunk = chunk_size or quick.shape[0]  # None: the whole grid in one chunk
    out = tmp_path / "r.nc"
    result = runner.run_sweep(
        quick, out=out, resources=Resources(threads), chunk_size=chunk, show_progress=False
    )
    assert_same_file(out, quick_reference_file)
    assert result.computed == quick.shape[0]
    assert not store.parts_dir_for(out).exists()  # parts removed once the file is written


def test_resume_with_another_chunk_size_reuses_saved_rows(quick, quick_reference_file, tmp_path):
    """Parts of chunk size 2 (rows 0-1, 4-5, 8 from shard 0 of 2) serve a resume in chunks of 3."""
    out = tmp_path / "r.nc"
    shard = runner.run_sweep(quick, out=out, chunk_size=2, shard=(0, 2), show_progress=False)
    assert (shard.computed, shard.dataset, out.exists()) == (5, None, False)
    result = runner.run_sweep(quick, out=out, chunk_size=3, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (5, 4)
    assert_same_file(out, quick_reference_file)


def test_without_resume_everything_is_computed_again(quick, tmp_path):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=2, shard=(0, 2), show_progress=False)
    result = runner.run_sweep(quick, out=out, chunk_size=2, show_progress=False)
    assert (result.reused, result.computed) == (0, 9)


def test_default_shard_chunks_do_not_depend_on_the_thread_count(tmp_path):
    """Without --chunk-size, shards run with different thread counts (as on nodes with
    other core counts) still cut the grid alike: their parts merge into the whole
    sweep, no row missing or computed twice. 40 systems, so that a chunk size set by
    the thread count would differ between the shards."""
    config = tmp_path / "wide.yaml"
    config.write_text(QUICK.read_text().replace("num: 9}", "num: 40}"))
    out = tmp_path / "r.nc"
    for shard, threads in (("0/2", "1"), ("1/2", "2")):
        args = ["run", config, "--out", out, "--shard", shard, "--threads", threads, "--quiet"]
        assert main(list(map(str, args))) == 0
    assert main(["merge", str(store.parts_dir_for(out)), "--out", str(out)]) == 0
    reference = reference_file(load_config(config), tmp_path / "reference.nc")
    assert xr.load_dataset(reference).sizes["K_W"] == 40
    assert_same_file(out, reference)


# --- interruption -------------------------------------------------------------------


class StopAfterFirstCheck(run_control.StopRequest):
    """A stop request that a SIGTERM seems to have set before the first check."""

    def __bool__(self):
        self.signum = signal.SIGTERM
        return True


def test_stop_request_keeps_finished_chunks_and_resume_completes(
    quick, quick_reference_file, tmp_path
):
    out = tmp_path / "r.nc"
    with pytest.raises(Interrupted, match=r"SIGTERM: 2 of 9 runs .* --resume") as info:
        runner.run_sweep(
            quick, out=out, chunk_size=2, show_progress=False, stop=StopAfterFirstCheck()
        )
    assert info.value.signum == signal.SIGTERM
    (part,) = store.parts_dir_for(out).glob("*.npz")
    assert (store.read_part(part).start, store.read_part(part).stop) == (0, 2)
    result = runner.run_sweep(quick, out=out, chunk_size=2, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (2, 7)
    assert_same_file(out, quick_reference_file)


def test_ctrl_c_after_the_last_chunk_writes_the_result_and_says_so(
    quick, quick_reference_file, tmp_path, monkeypatch, caplog
):
    """Ctrl-C while the last chunk's part is written stops nothing: the result is
    written whole, and the warning printed on the signal is followed by one saying so."""
    write_part = store.write_part

    def last_write_interrupted(directory, config, chash, start, stop_row, *args, **kwargs):
        if stop_row == 9:  # rows 8:9, the last chunk
            signal.raise_signal(signal.SIGINT)
        return write_part(directory, config, chash, start, stop_row, *args, **kwargs)

    monkeypatch.setattr(store, "write_part", last_write_interrupted)
    out = tmp_path / "r.nc"
    with run_control.stop_on_signals() as stop, caplog.at_level("WARNING"):
        runner.run_sweep(quick, out=out, chunk_size=2, resources=Resources(threads=1),
                         show_progress=False, stop=stop)  # fmt: skip
    assert stop.signum == signal.SIGINT
    assert "SIGINT came after every chunk had finished" in caplog.text
    assert_same_file(out, quick_reference_file)


@pytest.mark.parametrize("signals, saved", [(1, 2), (2, 0)])
def test_a_second_ctrl_c_stops_at_once(quick, tmp_path, monkeypatch, signals, saved):
    """Ctrl-C (real SIGINTs, through the CLI's handler) while the first chunk's part is
    being written: once, the sweep finishes that part and stops after it (2 of 9 runs
    saved); twice, it stops at once, inside the write, and that part is not saved."""
    write_part = store.write_part

    def interrupted_write(*args, **kwargs):
        for _ in range(signals):
            signal.raise_signal(signal.SIGINT)
        return write_part(*args, **kwargs)

    monkeypatch.setattr(store, "write_part", interrupted_write)
    out = tmp_path / "r.nc"
    with (
        run_control.stop_on_signals() as stop,
        pytest.raises(Interrupted, match=f"SIGINT: {saved} of 9 runs are saved") as info,
    ):
        runner.run_sweep(quick, out=out, chunk_size=2, resources=Resources(threads=1),
                         show_progress=False, stop=stop)  # fmt: skip
    assert info.value.signum == signal.SIGINT
    assert len(list(store.parts_dir_for(out).glob("*.npz"))) == saved // 2
    assert not out.exists()


#: libc's usleep, which compiled code calls while it waits: an opaque call, after which
#: the compiled loop reads its flag from memory again.
_usleep = ctypes.CDLL(None).usleep
_usleep.argtypes, _usleep.restype = [ctypes.c_uint], ctypes.c_int


@pytest.mark.slow
@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="NUMBA_DISABLE_JIT=1: no compiled code")
def test_signals_during_a_kernel_are_seen_when_it_returns(monkeypatch):
    """The README's caveat: compiled code cannot be interrupted. Two SIGINTs sent while
    the main thread is inside compiled code, which then integrates a chunk of 8 runs
    on one thread, reach the Python handler once, when the kernel has returned with all
    8 runs done (CPython runs handlers between bytecodes and keeps one pending flag per
    signal). No race: the compiled code says it has started (``flags[0]``), the other
    thread signals, then lets it go on (``flags[1]``)."""
    g = build_grid(parse_config(SLOW.replace("dt: 0.002", "dt: 0.02")))  # 8 × 0.02 s
    grid_kernel = ready_kernel(g.params, g.settings)
    flags = np.zeros(2, np.int64)

    @numba.njit(nogil=True)
    def signalled_then_integrate(flags, params, y0, settings, results, y_final, rec_t, rec_y):
        flags[0] = 1
        while flags[1] == 0:
            _usleep(1000)
        grid_kernel(params, y0, settings, results, y_final, 0.0, rec_t, rec_y)

    finals = []  # the kernel's y_final, NaN until each run writes its final state

    def kernel(params, y0, settings, results, y_final):
        y_final[:] = np.nan
        finals.append(y_final)
        signalled_then_integrate(flags, params, y0, settings, results, y_final, np.empty(0),
                                 np.empty((0, y0.shape[1])))  # fmt: skip

    def runs_done():
        return int(np.isfinite(finals[0]).all(axis=1).sum()) if finals else 0

    sent, handled = [], []  # runs done when each signal was sent / when it was handled
    over = threading.Event()

    def send_two():
        while flags[0] == 0 and not over.is_set():
            time.sleep(0.001)
        if not over.is_set():
            for _ in range(2):
                os.kill(os.getpid(), signal.SIGINT)
                sent.append(runs_done())
        flags[1] = 1

    flags[1] = 1  # compiled first, on no runs and without waiting
    signalled_then_integrate(flags, g.params[:0], g.y0[:0], g.settings, np.empty((0, 0)),
                             g.y0[:0].copy(), np.empty(0), np.empty((0, 2)))  # fmt: skip
    flags[:] = 0
    monkeypatch.setattr(backends, "integrate_grid", kernel)
    previous = signal.signal(signal.SIGINT, lambda *_: handled.append(runs_done()))
    sender = threading.Thread(target=send_two)
    try:
        sender.start()
        (chunk,) = LocalThreads(threads=1).run(g.params, g.y0, g.settings, [(0, 8)])
    finally:
        over.set()
        sender.join(timeout=SUBPROCESS_TIMEOUT)
        signal.signal(signal.SIGINT, previous)
    assert sent == [0, 0]  # both while compiled code ran, before any run
    assert handled == [8]  # once, after the kernel returned with every run done
    assert np.isfinite(chunk[3]).all()


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_keeps_parts_and_says_how_to_resume(slow_config, tmp_path, signum):
    out = tmp_path / "slow.nc"
    args = ["run", slow_config, "--out", out, "--chunk-size", "1", "--threads", "1", "--quiet"]
    proc = held_sweep(*args, cwd=tmp_path)  # its first part saved, the sweep waits
    proc.send_signal(signum)
    _, err = proc.communicate("go on\n", timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == 128 + signum, err
    assert f"interrupted by {signal.Signals(signum).name}" in err
    assert f"{' '.join(map(str, args))} --resume" in err  # the command to continue
    (saved,) = store.parts_dir_for(out).glob("*.npz")  # it stopped after that part
    store.read_part(saved)  # complete and valid: raises PartError otherwise
    assert not out.exists()


@pytest.mark.slow
def test_sigkill_then_resume_recomputes_only_unfinished_chunks(slow_config, tmp_path):
    out = tmp_path / "slow.nc"
    args = ["run", slow_config, "--out", out, "--chunk-size", "1", "--threads", "1"]
    proc = held_sweep(*args, cwd=tmp_path)  # its first part saved, the sweep waits
    parts_dir = store.parts_dir_for(out)
    proc.kill()
    proc.communicate(timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == -signal.SIGKILL
    assert len(list(parts_dir.glob("*.npz"))) == 1  # killed part-way

    proc = sweep_cli(*args, "--resume", cwd=tmp_path)
    _, err = proc.communicate(timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == 0, err
    assert "reusing 1 runs from 1 parts" in err
    assert "computing 7 runs in 7 chunks" in err
    assert_same_file(out, reference_file(load_config(slow_config), tmp_path / "reference.nc"))
    assert not parts_dir.exists()


#: ``python -m sweep ARGS`` that SIGKILLs itself in the middle of writing its third part.
KILLED_WRITING_THIRD_PART = r"""
import os, signal, sys
import numpy as np
from sweep import cli

calls, savez = [], np.savez

def savez_then_die(f, **arrays):
    calls.append(1)
    if len(calls) == 3:
        f.write(b"PK\x03\x04 a part cut short")
        f.flush()
        os.kill(os.getpid(), signal.SIGKILL)
    savez(f, **arrays)

np.savez = savez_then_die
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_kill_during_a_part_write_then_resume_leaves_no_trace(
    quick, quick_reference_file, tmp_path
):
    """kill -9 inside a part write leaves a temporary file, never a part. --resume reuses
    the two finished parts, and once the result is written the dead writer's file goes
    with the parts, while the file of a writer still running (another shard) stays."""
    out = tmp_path / "r.nc"
    folder = store.parts_dir_for(out)
    args = ["run", QUICK, "--out", out, "--chunk-size", "3", "--threads", "1", "--quiet"]
    proc = subprocess.run([sys.executable, "-c", KILLED_WRITING_THIRD_PART, *map(str, args)],
                          cwd=tmp_path, capture_output=True, text=True,
                          timeout=SUBPROCESS_TIMEOUT)  # fmt: skip
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    finished = sorted(folder.glob("*.npz"))
    rows = [(part.start, part.stop) for part in map(store.read_part, finished)]
    assert rows == [(0, 3), (3, 6)]
    (dead,) = set(folder.iterdir()) - set(finished)  # the third part, cut short
    shard = interrupted_part_writer(folder, "stuck")
    try:
        (live,) = set(folder.iterdir()) - set(finished) - {dead}
        result = runner.run_sweep(quick, out=out, chunk_size=3, resume=True, show_progress=False)
        assert (result.reused, result.computed) == (6, 3)
        assert_same_file(out, quick_reference_file)
        assert list(folder.iterdir()) == [live]
    finally:
        shard.kill()
        shard.wait(timeout=SUBPROCESS_TIMEOUT)
    store.remove_parts(folder)  # as the next finished sweep or merge would
    assert not folder.exists()


# --- faults --------------------------------------------------------------------------


def disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_disk_full_while_saving_a_later_chunk_keeps_the_earlier_parts(
    quick, quick_reference_file, tmp_path, monkeypatch
):
    """The disk fills up at the third part of five: the sweep stops with the cause, the
    earlier result is untouched, the two parts written so far stay (valid), and
    --resume reuses them once there is room again."""
    out = tmp_path / "r.nc"
    out.write_bytes(b"earlier result")
    write_part, calls = store.write_part, []

    def fill_up_at_the_third(*args, **kwargs):
        calls.append(args[3:5])  # (start, stop)
        if len(calls) == 3:
            disk_full()
        return write_part(*args, **kwargs)

    monkeypatch.setattr(store, "write_part", fill_up_at_the_third)
    with pytest.raises(RunError, match="cannot write a part .* No space left on device"):
        runner.run_sweep(quick, out=out, chunk_size=2, resources=Resources(threads=1),
                         show_progress=False)  # fmt: skip
    assert calls == [(0, 2), (2, 4), (4, 6)]  # the sweep stopped at the failing write
    assert out.read_bytes() == b"earlier result"
    kept = sorted(store.parts_dir_for(out).iterdir())
    assert [(p.start, p.stop) for p in map(store.read_part, kept)] == [(0, 2), (2, 4)]
    monkeypatch.undo()
    result = runner.run_sweep(quick, out=out, chunk_size=2, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (4, 5)
    assert_same_file(out, quick_reference_file)


def test_disk_full_while_writing_the_result_keeps_the_parts(
    quick, quick_reference_file, tmp_path, monkeypatch
):
    out = tmp_path / "r.nc"
    out.write_bytes(b"earlier result")
    monkeypatch.setattr(netcdf, "write_netcdf", disk_full)
    with pytest.raises(RunError, match=r"cannot write .*r\.nc: No space left on device"):
        runner.run_sweep(quick, out=out, chunk_size=4, show_progress=False)
    assert out.read_bytes() == b"earlier result"
    assert len(list(store.parts_dir_for(out).glob("*.npz"))) == 3
    monkeypatch.undo()
    result = runner.run_sweep(quick, out=out, chunk_size=4, resume=True, show_progress=False)
    assert (result.reused, result.computed) == (9, 0)
    assert_same_file(out, quick_reference_file)


def test_unwritable_output_is_bad_input(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("a file, not a folder")
    assert main(["run", str(QUICK), "--out", str(blocker / "r.nc"), "--quiet"]) == 2
    assert re.search(r"--out .*file/r\.nc cannot be written", capsys.readouterr().err)


@pytest.mark.parametrize("what", ["missing", "empty folder", "not a part"])
def test_merge_of_no_parts_is_bad_input(tmp_path, capsys, what):
    """Exit 2 with one line naming the path; nothing is written."""
    target = tmp_path / "in"
    if what == "empty folder":
        target.mkdir()
    elif what == "not a part":
        target.write_text("hello")
    assert main(["merge", str(target), "--out", str(tmp_path / "r.nc")]) == 2
    err = capsys.readouterr().err
    assert str(target) in err and err.count("\n") == 1
    assert not (tmp_path / "r.nc").exists()
