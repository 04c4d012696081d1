"""Files on disk: the chunk store of a sweep, its output lock and atomic writes.

Every file rsf-sweep writes goes through :func:`replaced_atomically` (written
beside the target, synced, renamed), and every output path is probed first
(:func:`check_writable`).

Finished chunks of a sweep are kept as small, self-checking files.

A sweep's systems (rows of the C-ordered grid) are computed in chunks; each
finished chunk is written at once to a *part* file in a working directory
beside the output (``results/quick.nc`` → ``results/quick.parts/``)::

    <config hash>_<start>-<stop>_of_<n>.npz

holding rows ``start:stop`` of the kernels' ``results`` and ``y_final`` arrays,
the config text and a SHA-256 of the arrays. Parts are written to a temporary
file, flushed to disk and renamed, so a part either exists complete or not at
all; reading one checks the zip CRCs, the checksum, the shapes and that the
name agrees with the content, so a truncated or corrupt part is never used.

A temporary file is named ``.part-<host>-<pid>-<random>.tmp`` after the machine
and process writing it. A process killed during a write (``kill -9``, a node
crash) leaves it behind; it is removed once that process is known to be gone
(same host, no process with that pid), and never while its writer may still be
running, e.g. a shard on another node sharing the folder.

The config hash covers everything that changes the numbers: the validated
config fields (not its whitespace, name, description or output path) and the
source of the code that turns them into numbers. A changed config therefore
never mixes with old parts. Parts store their row range, so parts written with
another chunk size (or by other shards) can still be used row by row.
"""

import contextlib
import fcntl
import glob
import hashlib
import json
import os
import re
import secrets
import socket
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import InputError, OutputBusy, PartError

#: Bumped when the layout of a part file changes.
PART_FORMAT = 1
#: Modules whose code decides the numbers stored in a part (accelerate.py: fastmath,
#: error model; dispatch.py: which compiled variant integrates a run): grid.py and
#: dispatch.py and everything in the package they import; ``kernels`` is the kernel
#: package and the numba policy (``accelerate.source_digest``).
NUMERIC_MODULES = (
    "kernels",
    "grid.py",
    "physics.py",
    "linear.py",
    "heterogeneity.py",
    "codes.py",
    "accelerate.py",
    "dispatch.py",
)
PART_NAME = re.compile(r"^(?P<hash>[0-9a-f]{16})_(?P<start>\d+)-(?P<stop>\d+)_of_(?P<n>\d+)\.npz$")
TEMP_PREFIX = ".part-"
#: The suffix of a Zarr directory store (``sweep/io/zarr.py``).
ZARR_SUFFIX = ".zarr"
#: A temporary part file: ``.part-<host>-<pid>-<random>.tmp`` (see ``replaced_atomically``).
TEMP_NAME = re.compile(r"^\.part-(?P<host>.+)-(?P<pid>\d+)-[0-9a-f]+\.tmp$")


def config_hash(config):
    """16 hex digits identifying the numbers a config produces.

    Built from the validated fields that change results (blocks, coupling, model,
    law, fixed and per-block parameters, spread, axes in order, initial state, integrator,
    classification and, where there is one, catalogue settings), the package version and
    the source of the numeric modules. Fixed parameters are sorted, since their order in the
    file does not matter; axis order does (it orders the grid).
    """
    fields = {
        "blocks": config.blocks,
        "coupling": config.coupling_key,
        "model": config.model,
        "state_law": config.state_law,
        "parameters": sorted(config.parameters),
        "block_parameters": sorted(config.block_parameters),
        "spread": asdict(config.spread),
        "axes": [[a.name, list(a.values)] for a in config.axes],
        "initial": asdict(config.initial),
        "integrator": asdict(config.integrator),
        "classification": asdict(config.classification),
    }
    if config.catalogue.capacity:  # a catalogue's columns are part of each results row
        fields["catalogue"] = asdict(config.catalogue)
    digest = hashlib.sha256(json.dumps(fields, sort_keys=True).encode())
    digest.update(f"rsf-sweep {__version__} parts {PART_FORMAT}".encode())
    here = Path(__file__).parent
    for name in NUMERIC_MODULES:
        if name == "kernels":
            from ..accelerate import source_digest  # numba: only where parts are keyed

            digest.update(source_digest().encode())
        else:
            digest.update((here / name).read_bytes())
    return digest.hexdigest()[:16]


@contextmanager
def output_lock(output, shared=False):
    """Hold the lock of ``output`` (a hidden ``.<name>.lock`` file beside it) while a
    run or merge works on it and its parts.

    Full runs and merges take it exclusively; shards (``shared=True``) share it, so
    several shards fill one parts folder side by side while nothing assembles or
    removes it. Taken without waiting: if another process holds it, raise
    :class:`OutputBusy` naming the process that last took it (pid, host, command,
    start time, as each holder writes into the lock file). The operating system releases the
    lock when the holder exits, even after ``kill -9``; an exclusive holder removes the
    file when it is done, and on taking it the temporary files of ``output`` that a
    writer killed before its rename left behind (:func:`replaced_atomically`): nobody
    else can be writing them.
    """
    output = Path(output)
    lock_path = output.with_name(f".{output.name}.lock")
    handle = _locked_file(lock_path, shared, output)
    try:
        if not shared:
            for stale in output.parent.glob(f".{glob.escape(output.name)}.*.tmp"):
                with contextlib.suppress(OSError):
                    stale.unlink()
        handle.seek(0)
        handle.truncate()  # the newest holder names itself (with shards: one of them)
        handle.write(
            f"pid {os.getpid()} on {socket.gethostname()} "
            f"({' '.join(sys.argv) or 'python'}, started {_now()})\n"
        )
        handle.flush()
        yield
    finally:
        if not shared:  # removed while still held: nobody else can hold it now
            lock_path.unlink(missing_ok=True)
        handle.close()


def _locked_file(lock_path, shared, output):
    """The lock file, opened and locked; retried if an exclusive holder removed it
    between our open and our lock (we would hold a lock on a file nobody sees)."""
    while True:
        handle = open(lock_path, "a+")
        try:
            fcntl.flock(handle, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "an unknown process"
            handle.close()
            raise OutputBusy(
                f"{output} is in use by another run (the lock was last taken by {holder}); "
                "wait for it to finish, or write to another --out"
            ) from None
        try:
            same = os.stat(lock_path).st_ino == os.fstat(handle.fileno()).st_ino
        except FileNotFoundError:
            same = False
        if same:
            return handle
        handle.close()


def _now():
    import datetime

    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def parts_dir_for(output):
    """The working directory for the parts of the sweep written to ``output``."""
    output = Path(output)
    return output.with_name(output.stem + ".parts")


def owner_output(folder):
    """The output whose parts folder ``folder`` is (``x.parts`` → ``x.nc``), or None."""
    folder = Path(folder)
    if folder.suffix != ".parts":
        return None
    return folder.with_name(folder.stem + ".nc")


def part_name(chash, start, stop, n):
    """File name of the part holding rows ``start:stop`` of an ``n``-system sweep."""
    width = len(str(n))
    return f"{chash}_{start:0{width}d}-{stop:0{width}d}_of_{n}.npz"


def _checksum(results, y_final):
    digest = hashlib.sha256(np.ascontiguousarray(results).tobytes())
    digest.update(np.ascontiguousarray(y_final).tobytes())
    return digest.hexdigest()


@dataclass(frozen=True)
class Part:
    """A validated part: rows ``start:stop`` of a sweep of ``n`` systems."""

    path: Path
    config_hash: str
    start: int
    stop: int
    n: int
    config_text: str
    config_source: str
    results: np.ndarray
    y_final: np.ndarray


def write_part(directory, config, chash, start, stop, n, results, y_final):
    """Write rows ``start:stop`` atomically into ``directory``; return the path.

    ``results`` and ``y_final`` are the kernels' outputs for those rows. The
    file is written under a temporary name, synced to disk and renamed.
    """
    directory = Path(directory)
    path = directory / part_name(chash, start, stop, n)
    meta = {
        "format": PART_FORMAT,
        "config_hash": chash,
        "start": start,
        "stop": stop,
        "n": n,
        "sha256": _checksum(results, y_final),
        "config_text": config.text,
        "config_source": config.source,
    }
    prefix = f"{TEMP_PREFIX}{_host()}-"
    with replaced_atomically(path, prefix=prefix) as tmp, open(tmp, "wb") as f:
        np.savez(f, results=results, y_final=y_final, meta=np.array(json.dumps(meta)))
    return path


def read_part(path):
    """Read and validate the part at ``path``; raise :class:`PartError` if unusable."""
    path = Path(path)
    match = PART_NAME.match(path.name)
    if match is None:
        raise PartError(f"{path}: not a part file name (<hash>_<start>-<stop>_of_<n>.npz)")
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            results = data["results"]
            y_final = data["y_final"]
    except Exception as exc:  # zipfile, numpy and json each raise their own kinds
        raise PartError(f"{path}: unreadable ({type(exc).__name__}: {exc})") from None
    start, stop, n = int(match["start"]), int(match["stop"]), int(match["n"])
    expected = {"format": PART_FORMAT, "config_hash": match["hash"], "start": start,
                "stop": stop, "n": n}  # fmt: skip
    wrong = [k for k, v in expected.items() if meta.get(k) != v]
    if wrong:
        raise PartError(f"{path}: name and content disagree on {', '.join(wrong)}")
    if not 0 <= start < stop <= n:
        raise PartError(f"{path}: row range {start}:{stop} is outside 0:{n}")
    rows = stop - start
    if results.ndim != 2 or results.shape[0] != rows or y_final.ndim != 2 or len(y_final) != rows:
        raise PartError(f"{path}: arrays do not hold {rows} rows")
    if _checksum(results, y_final) != meta.get("sha256"):
        raise PartError(f"{path}: checksum mismatch (corrupt data)")
    return Part(path, match["hash"], start, stop, n, meta["config_text"],
                meta["config_source"], results, y_final)  # fmt: skip


def part_files(paths):
    """Part files named in ``paths`` (files, or directories searched one level), sorted."""
    found = []
    for p in map(Path, paths):
        if p.is_dir():
            found.extend(f for f in p.iterdir() if PART_NAME.match(f.name))
        else:
            found.append(p)
    return sorted(set(found))


def group(files):
    """Part files grouped by config hash: {hash: [(start, stop, n, path)]}, in the
    order given; names that are not part names are skipped."""
    groups = {}
    for f in map(Path, files):
        m = PART_NAME.match(f.name)
        if m:
            entry = (int(m["start"]), int(m["stop"]), int(m["n"]), f)
            groups.setdefault(m["hash"], []).append(entry)
    return groups


def scan(directory):
    """Part files in ``directory`` grouped by config hash (see :func:`group`)."""
    directory = Path(directory)
    return group(sorted(directory.iterdir())) if directory.is_dir() else {}


def _host():
    """This machine's name as it appears in temporary file names (no path separators)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", socket.gethostname()) or "localhost"


def _process_exists(pid):
    """Whether a process ``pid`` exists on this machine (a pid of another user's counts)."""
    if pid <= 0:
        return True  # 0 and negative pids name process groups: never ours to judge
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def stale_temp_files(directory):
    """Temporary part files in ``directory`` whose writer is gone.

    That is, written on this host by this process or by a process that no
    longer exists (killed during a write). Temporary files of live processes and
    of other hosts (a shard elsewhere may still be writing) are not listed.
    """
    directory = Path(directory)
    host, own = _host(), os.getpid()
    stale = []
    for f in sorted(directory.iterdir()) if directory.is_dir() else ():
        m = TEMP_NAME.match(f.name)
        if m and m["host"] == host and (int(m["pid"]) == own or not _process_exists(int(m["pid"]))):
            stale.append(f)
    return stale


def remove_parts(directory):
    """Remove every part and the stale temporary files from ``directory``, then the
    folder if it is empty.

    Called once the output those parts were for has been written, which
    supersedes parts of earlier configs too. Temporary files of live processes
    (a shard still writing) or of other hosts, and other files, are left alone
    (see :func:`stale_temp_files`). Returns the number of files removed.
    """
    directory = Path(directory)
    if not directory.is_dir():
        return 0
    doomed = [f for f in directory.iterdir() if PART_NAME.match(f.name)]
    doomed += stale_temp_files(directory)
    for f in doomed:
        f.unlink(missing_ok=True)
    if not any(directory.iterdir()):
        directory.rmdir()
    return len(doomed)


def fill_from_parts(entries, results, y_final, have, wanted):
    """Copy rows from valid parts into ``results``/``y_final``.

    ``entries`` as from :func:`scan` (one config hash); only rows that are
    ``wanted`` and not yet in ``have`` (boolean masks over systems) are taken,
    and ``have`` is updated. Returns ``(used, bad)``: paths of the parts read,
    and ``(path, reason)`` for parts that are corrupt or do not fit.
    """
    used, bad = [], []
    for start, stop, n, path in entries:
        if n != len(have):
            bad.append((path, f"{path}: made for a sweep of {n} systems, not {len(have)}"))
            continue
        if not 0 <= start < stop <= n:
            bad.append((path, f"{path}: rows {start}:{stop} are not rows of the sweep's 0:{n}"))
            continue
        take = wanted[start:stop] & ~have[start:stop]
        if not take.any():
            continue
        try:
            part = read_part(path)
            if (
                part.results.shape[1:] != results.shape[1:]
                or part.y_final.shape[1:] != y_final.shape[1:]
            ):
                raise PartError(f"{path}: array columns do not match this sweep")
        except PartError as exc:
            bad.append((path, str(exc)))
            continue
        results[start:stop][take] = part.results[take]
        y_final[start:stop][take] = part.y_final[take]
        have[start:stop] |= take
        used.append(path)
    return used, bad


def check_writable(path, source="<config>", key="output", suffix=".nc"):
    """Raise :class:`~sweep.errors.InputError` unless a file can be created at ``path``.

    ``suffix``: the file type, or a tuple of those allowed (e.g. ``(".png",
    ".pdf", ".svg")``); a ``.zarr`` path is a directory store, which may exist.
    Creates missing parent directories and a probe file (removed at once), so the
    answer is the file system's, not a guess from permission bits (which root ignores).
    """
    path = Path(path)
    suffixes = (suffix,) if isinstance(suffix, str) else tuple(suffix)
    allowed = " or ".join(suffixes)
    if path.suffix not in suffixes:
        raise InputError(source, [f"{key} {path} must be a file name ending in {allowed}"])
    if path.suffix == ZARR_SUFFIX:  # a directory store: a folder is what it should be
        if path.exists() and not path.is_dir():
            raise InputError(
                source, [f"{key} {path} is a file; a Zarr store ({ZARR_SUFFIX}) is a directory"]
            )
    elif path.is_dir():
        raise InputError(
            source, [f"{key} {path} is a directory; give a file path ending in {allowed}"]
        )
    blocking = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise InputError(
            source, [f"{key} {path} cannot be written: {blocking} is a file, not a directory"]
        )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.probe-"):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise InputError(source, [f"{key} {path} cannot be written: {reason}"]) from None
    if path.exists() and not os.access(path, os.W_OK):
        raise InputError(source, [f"{key} {path} exists and is not writable"])


def require_zarr(source, key="--out"):
    """The ``zarr`` module (for ``.zarr`` outputs), or an :class:`InputError` saying
    how to install it."""
    try:
        import zarr
    except ImportError:
        raise InputError(
            source,
            [
                f"{key}: reading or writing a Zarr store (.zarr) needs the zarr package: "
                "pip install 'rsf-sweep[zarr]'"
            ],
        ) from None
    return zarr


@contextmanager
def replaced_atomically(path, prefix=None):
    """Yield a fresh temporary path in ``path``'s folder; on success rename it to ``path``.

    The temporary file is created with mode 0666 less the umask, like any file the
    user makes, and named ``<prefix><pid>-<random>.tmp`` (default prefix
    ``.<name>.``). If the block raises, Ctrl-C included, it is removed and
    ``path`` is left as it was: a failed write never damages an earlier file.
    The data and then the rename are synced to disk, so a crash right after
    cannot leave a truncated file under the final name.
    """
    path = Path(path)
    prefix = f".{path.name}." if prefix is None else prefix
    tmp = path.with_name(f"{prefix}{os.getpid()}-{secrets.token_hex(4)}.tmp")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp
        _sync(tmp)
        os.replace(tmp, path)
        _sync(path.parent)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _sync(path):
    """fsync a file or folder (folders: where the file system allows it)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        if not os.path.isdir(path):
            raise
    finally:
        os.close(fd)
