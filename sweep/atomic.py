"""Atomic file replacement: write beside the target, then rename over it."""

import os
import secrets
from contextlib import contextmanager
from pathlib import Path


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
