"""The chunk store: part files are complete or rejected, and never mix configs."""

import logging
import signal
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import (
    QUICK,
    ROOT,
    SUBPROCESS_TIMEOUT,
    assert_same_file,
    interrupted_part_writer,
    reference_file,
    without_provenance,
)

from sweep.config import parse_config
from sweep.engine import runner
from sweep.errors import RunError
from sweep.io import parts as store


@pytest.fixture(scope="module")
def quick_reference(quick):
    return without_provenance(runner.compute(quick, threads=1, chunk_size=1, show_progress=False))


@pytest.fixture
def one_part(quick, tmp_path):
    """A part holding rows 3:5 of a 9-system sweep, with recognisable numbers."""
    rng = np.random.default_rng(0)
    results, y_final = rng.normal(size=(2, 15)), rng.normal(size=(2, 2))
    path = store.write_part(tmp_path, quick, store.config_hash(quick), 3, 5, 9, results, y_final)
    return path, results, y_final


def test_part_round_trip(quick, one_part):
    path, results, y_final = one_part
    part = store.read_part(path)
    assert (part.start, part.stop, part.n, part.config_hash) == (3, 5, 9, store.config_hash(quick))
    np.testing.assert_array_equal(part.results, results)
    np.testing.assert_array_equal(part.y_final, y_final)
    assert parse_config(part.config_text, part.config_source) == quick
    assert [f.name for f in path.parent.iterdir()] == [path.name]  # no temporary file left


def _truncate_to_zero(path):
    path.write_bytes(b"")


def _truncate_half(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _flip_a_data_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside meta.npy (the config text): zipfile's CRC catches it
    path.write_bytes(bytes(data))


def _rename_to_other_rows(path):
    path.rename(path.with_name(path.name.replace("3-5", "4-6")))


@pytest.mark.parametrize(
    "damage", [_truncate_to_zero, _truncate_half, _flip_a_data_byte, _rename_to_other_rows]
)
def test_damaged_part_is_rejected(one_part, damage):
    path = one_part[0]
    damage(path)
    (damaged,) = path.parent.iterdir()
    with pytest.raises(store.PartError, match=damaged.name):
        store.read_part(damaged)


def test_changed_numbers_with_intact_zip_fail_the_checksum(one_part):
    """A part rewritten as a well-formed archive (valid zip CRCs, right name, shapes and
    metadata) whose numbers differ in one bit: only the SHA-256 in the metadata can
    catch it, so the message must be the checksum's, not zipfile's."""
    path, results, y_final = one_part
    with np.load(path) as data:
        meta = data["meta"]
    changed = results.copy()
    changed.view(np.uint64)[1, 7] ^= 1  # the last bit of one number
    with open(path, "wb") as f:
        np.savez(f, results=changed, y_final=y_final, meta=meta)
    with np.load(path) as data:  # the archive itself is sound
        np.testing.assert_array_equal(data["results"], changed)
    with pytest.raises(store.PartError, match=rf"{path.name}: checksum mismatch"):
        store.read_part(path)


def test_hash_follows_the_numbers_not_the_wording():
    text = QUICK.read_text()
    base = store.config_hash(parse_config(text))
    same = [
        text.replace("name: quick", "name: other").replace("t_end: 2000.0", "t_end: 2000"),
        text.replace("output: results/quick.nc", "output: elsewhere/x.nc") + "\n# a comment\n",
        text.replace("description: One block", "description: Another block"),
        text.replace("  A: 0.03\n  B: 0.08\n", "  B: 0.08\n  A: 0.03\n"),  # fixed-parameter order
        text + "catalogue:\n  capacity: 0\n  after: 0.5\n",  # no catalogue: its settings unused
    ]
    changed = [
        text.replace("t_end: 2000.0", "t_end: 2001.0"),
        text.replace("A: 0.03", "A: 0.031"),
        text.replace("num: 9", "num: 10"),
        text.replace("phi_over_phi_ss: 1.01", "phi_over_phi_ss: 1.02"),
        text.replace("v_cap_over_V: 1.0e+6", "v_cap_over_V: 1.0e+5"),
        text + "catalogue:\n  capacity: 10\n",
        text + "catalogue:\n  capacity: 10\n  after: 0.5\n",
    ]
    for variant in same:
        assert variant != text and store.config_hash(parse_config(variant)) == base
    for variant in changed:
        assert variant != text and store.config_hash(parse_config(variant)) != base
    hashes = {store.config_hash(parse_config(variant)) for variant in changed}
    assert len(hashes) == len(changed)


def test_truncated_part_is_reported_and_recomputed(quick, quick_reference_file, tmp_path, caplog):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=3, shard=(0, 1), show_progress=False)
    victim = sorted(store.parts_dir_for(out).glob("*.npz"))[1]  # rows 3:6
    victim.write_bytes(b"")
    with caplog.at_level(logging.INFO, logger="sweep"):
        result = runner.run_sweep(quick, out=out, chunk_size=3, resume=True, show_progress=False)
    assert f"unusable part, its runs will be recomputed: {victim}" in caplog.text
    assert (result.reused, result.computed) == (6, 3)
    assert_same_file(out, quick_reference_file)


def test_changed_config_never_uses_old_parts(quick, tmp_path, caplog):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=3, shard=(0, 1), show_progress=False)
    changed = parse_config(QUICK.read_text().replace("t_end: 2000.0", "t_end: 1500.0"))
    with caplog.at_level(logging.INFO, logger="sweep"):
        result = runner.run_sweep(changed, out=out, chunk_size=3, resume=True, show_progress=False)
    assert "ignoring 3 parts of another config" in caplog.text
    assert (result.reused, result.computed) == (0, 9)
    assert_same_file(out, reference_file(changed, tmp_path / "reference.nc"))
    assert not store.parts_dir_for(out).exists()  # old and new parts cleaned up


def test_merge_uses_the_complete_config_and_ignores_others(
    quick, quick_reference, quick_reference_file, tmp_path
):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=4, shard=(0, 1), show_progress=False)
    other = parse_config(QUICK.read_text().replace("t_end: 2000.0", "t_end: 1500.0"))
    runner.run_sweep(other, out=out, chunk_size=4, shard=(0, 2), show_progress=False)
    merged = tmp_path / "merged.nc"
    ds = runner.merge_parts([store.parts_dir_for(out)], merged)
    xr.testing.assert_identical(without_provenance(ds), quick_reference)
    assert_same_file(merged, quick_reference_file)
    left = list(store.parts_dir_for(out).glob("*.npz"))
    assert len(left) == 2 and all(store.config_hash(other) in f.name for f in left)


def test_merge_never_uses_a_corrupt_part(quick, tmp_path):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=4, shard=(0, 1), show_progress=False)
    victim = sorted(store.parts_dir_for(out).glob("*.npz"))[2]  # rows 8:9
    victim.write_bytes(victim.read_bytes()[:100])
    merged = tmp_path / "merged.nc"
    with pytest.raises(RunError, match=r"corrupt part.*rows 8:9 missing") as info:
        runner.merge_parts([store.parts_dir_for(out)], merged)
    assert victim.name in str(info.value)
    assert not merged.exists()


@pytest.mark.slow
def test_temp_files_of_killed_writers_are_removed_live_ones_kept(quick, tmp_path):
    """Writers stopped inside a part write leave their temporary file. Once the sweep's
    output is written, remove_parts deletes the parts and the temporary files of dead
    writers on this host, and keeps those of a writer still running (a shard) and of
    writers on other hosts (their pids mean nothing here)."""
    folder = tmp_path / "r.parts"
    folder.mkdir()
    before = set()
    for mode in ("killed", "elsewhere", "stuck"):
        result = interrupted_part_writer(folder, mode)
        (temp,) = set(folder.iterdir()) - before  # the writer's temporary file
        before.add(temp)
        if mode == "killed":
            dead = temp
        elif mode == "elsewhere":
            elsewhere = temp
        else:
            live, writer = temp, result
    try:
        done = store.write_part(folder, quick, store.config_hash(quick), 0, 9, 9,
                                np.zeros((9, 15)), np.zeros((9, 2)))  # fmt: skip
        (folder / "notes.txt").write_text("not ours")
        assert store.remove_parts(folder) == 2  # the part and the dead writer's file
        assert set(folder.iterdir()) == {live, elsewhere, folder / "notes.txt"}
        assert not dead.exists() and not done.exists()
    finally:
        writer.kill()
        writer.wait(timeout=SUBPROCESS_TIMEOUT)
    (folder / "notes.txt").unlink()
    store.remove_parts(folder)  # the stuck writer is gone now: only elsewhere's file stays
    assert set(folder.iterdir()) == {elsewhere}


def test_merge_removes_temp_files_of_killed_writers(quick, quick_reference, tmp_path):
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=4, shard=(0, 1), show_progress=False)
    folder = store.parts_dir_for(out)
    interrupted_part_writer(folder, "killed")
    assert len(list(folder.iterdir())) == 4  # 3 parts and the killed writer's file
    merged = tmp_path / "merged.nc"
    xr.testing.assert_identical(without_provenance(runner.merge_parts([folder], merged)),
                                quick_reference)  # fmt: skip
    assert not folder.exists()


def test_concurrent_runs_on_one_output_refuse_naming_the_other(quick, tmp_path, lock_holder):
    """A run or merge on an output another process is running refuses at once with a
    message naming that process (exit 1 from the CLI), and leaves the earlier result and
    the parts alone; shards share the lock with each other but not with a full run."""
    from sweep.cli import main

    out = tmp_path / "r.nc"
    out.write_bytes(b"earlier result")
    holder = lock_holder(out)
    busy = rf"r.nc is in use by another run \(the lock was last taken by pid {holder.pid} on "
    with pytest.raises(RunError, match=busy):
        runner.run_sweep(quick, out=out, show_progress=False)
    with pytest.raises(RunError, match=f"pid {holder.pid}"):
        runner.run_sweep(quick, out=out, show_progress=False, shard=(0, 2))
    assert main(["run", str(QUICK), "--out", str(out), "--quiet"]) == 1
    assert out.read_bytes() == b"earlier result"
    assert not store.parts_dir_for(out).exists()

    shared = tmp_path / "s.nc"
    other = lock_holder(shared, "shared")
    result = runner.run_sweep(quick, out=shared, show_progress=False, shard=(0, 2))
    assert result.dataset is None and result.computed > 0  # two shards side by side
    with pytest.raises(RunError, match="s.nc is in use by another run"):
        runner.run_sweep(quick, out=shared, show_progress=False)
    other.kill()
    other.wait(timeout=SUBPROCESS_TIMEOUT)
    assert runner.run_sweep(quick, out=shared, show_progress=False, resume=True).dataset is not None


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["exclusive", "shared"])
def test_merge_refuses_parts_their_owner_is_still_writing(quick, tmp_path, lock_holder, mode):
    """``merge x.parts --out y.nc`` while a run (``--resume``, exclusive) or a shard
    (shared) works on x.nc refuses naming that process, and leaves every part in place
    (it once removed parts under the running sweep, which then crashed)."""
    out = tmp_path / "x.nc"
    runner.run_sweep(quick, out=out, chunk_size=4, shard=(0, 1), show_progress=False)
    parts = sorted(store.parts_dir_for(out).glob("*.npz"))
    holder = lock_holder(out, mode)
    with pytest.raises(RunError, match=rf"x.nc is in use .* pid {holder.pid} "):
        runner.merge_parts([store.parts_dir_for(out)], tmp_path / "y.nc")
    with pytest.raises(RunError, match=f"pid {holder.pid}"):
        runner.merge_parts(parts[:1], tmp_path / "y.nc")
    assert sorted(store.parts_dir_for(out).glob("*.npz")) == parts
    assert not (tmp_path / "y.nc").exists()
    holder.kill()
    holder.wait(timeout=SUBPROCESS_TIMEOUT)
    assert runner.merge_parts([store.parts_dir_for(out)], tmp_path / "y.nc") is not None


def test_sharded_ensemble_merges_to_the_full_run(tmp_path):
    """Ensemble members are rows of the parts: shards of an ensemble sweep merge into
    the result of one full run (merge once counted grid points, not runs, and called
    the parts corrupt)."""
    config = parse_config(QUICK.read_text().replace(
        "initial:", "initial:\n  ensemble: 3\n  seed: 4\n  amplitude: 0.3\n  "
    ).replace("t_end: 2000.0", "t_end: 300.0"))  # fmt: skip
    assert config.run_shape == (9, 3)
    out = tmp_path / "e.nc"
    for i in range(2):
        runner.run_sweep(config, out=out, chunk_size=5, shard=(i, 2), show_progress=False)
    merged = runner.merge_parts([store.parts_dir_for(out)], tmp_path / "merged.nc")
    full = runner.compute(config, show_progress=False)
    xr.testing.assert_identical(without_provenance(merged), without_provenance(full))


def test_part_hash_covers_every_module_that_decides_the_numbers():
    """Every module of the package that ``engine/grid.py`` and ``engine/dispatch.py``
    import, directly or not (imports read from the source), is hashed into the parts'
    key: it lies on the ground floor or under ``store.NUMERIC_FOLDERS``."""
    import ast

    package = ROOT / "sweep"
    todo, seen = [package / "engine" / "grid.py", package / "engine" / "dispatch.py"], set()
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = path.parents[node.level - 1]
                for name in [node.module] if node.module else [a.name for a in node.names]:
                    target = base.joinpath(*name.split("."))
                    if target.is_dir():
                        todo.extend(target.rglob("*.py"))
                    elif target.with_suffix(".py").exists():
                        todo.append(target.with_suffix(".py"))
    hashed = {*package.glob("*.py")}
    for folder in store.NUMERIC_FOLDERS:
        hashed.update((package / folder).rglob("*.py"))
    assert seen <= hashed, sorted(str(p.relative_to(package)) for p in seen - hashed)


@pytest.mark.parametrize("where", ["model/new_law.py", "engine/new_module.py",
                                   "kernels/methods/new_method.py", "new_table.py"])  # fmt: skip
def test_a_new_numeric_module_changes_the_parts_key(tmp_path, where):
    """A module added under a numeric folder (or on the ground floor) changes the key of
    the parts without being named anywhere; one added to the commands does not."""
    import shutil

    copy = tmp_path / "sweep"
    shutil.copytree(ROOT / "sweep", copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = store.numeric_source_digest(copy)
    (copy / "commands" / "new_command.py").write_text("X = 1\n")
    assert store.numeric_source_digest(copy) == before
    (copy / where).write_text("X = 1\n")
    assert store.numeric_source_digest(copy) != before


def test_a_writer_killed_before_its_rename_leaves_nothing_for_long(quick, tmp_path):
    """``kill -9`` during the write leaves the writer's temporary file beside the
    output (the earlier result stays whole); the next run on that output removes it,
    and leaves another output's alone."""
    out = tmp_path / "r.nc"
    out.write_bytes(b"earlier result")
    killed = (
        "import os, signal, sys\nfrom sweep.io import files\n"
        "with files.replaced_atomically(sys.argv[1]) as tmp:\n"
        "    open(tmp, 'wb').write(b'half a file')\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run([sys.executable, "-c", killed, str(out)], cwd=ROOT,
                          timeout=SUBPROCESS_TIMEOUT)  # fmt: skip
    assert proc.returncode == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir() if p.suffix == ".tmp"]
    assert len(left) == 1 and left[0].startswith(".r.nc.")
    assert out.read_bytes() == b"earlier result"
    stale_other = tmp_path / left[0].replace(".r.nc.", ".r.nc4.")  # r.nc4's, not r.nc's
    stale_other.write_bytes(b"another output's")
    runner.run_sweep(quick, out=out, show_progress=False)
    assert xr.open_dataset(out).sizes  # the new result
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".tmp") == [stale_other.name]


def test_a_part_named_for_rows_outside_the_sweep_is_named_so(quick, tmp_path):
    """A part whose name claims rows beyond the sweep (copied or renamed by hand) is
    reported with those rows; it was reported as "made for a sweep of 9 systems, not 9"."""
    out = tmp_path / "r.nc"
    runner.run_sweep(quick, out=out, chunk_size=4, shard=(0, 1), show_progress=False)
    last = sorted(store.parts_dir_for(out).glob("*.npz"))[2]  # rows 8:9
    stray = last.with_name(last.name.replace("_8-9_", "_9-10_"))
    assert stray != last
    last.rename(stray)
    with pytest.raises(RunError, match=r"rows 9:10 are not rows of the sweep's 0:9"):
        runner.merge_parts([store.parts_dir_for(out)], tmp_path / "merged.nc")
