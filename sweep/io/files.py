"""Files on disk: atomic writes, output locks and probes of where a file can go.

Every file rsf-sweep writes goes through :func:`replaced_atomically` (written beside
the target, synced, renamed), every output path is probed first
(:func:`check_writable`), and a run or merge holds its output's lock
(:func:`output_lock`) while it works on it and its parts.
"""

import contextlib
import fcntl
import glob
import os
import secrets
import socket
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError, OutputBusy

#: The suffix of a Zarr directory store (``sweep/io/zarr.py``).
ZARR_SUFFIX = ".zarr"


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
