"""Part files: the finished chunks of a sweep, kept as small, self-checking files until
its result is written.

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

Parts are written and read back through :class:`PartStore` alone (:class:`ZarrSink` is
its like for ``.zarr`` outputs, which keep no parts), by uniform sweeps and
refinements alike.
"""

import hashlib
import json
import logging
import os
import re
import socket
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import ConfigError, PartError, RunError
from .files import replaced_atomically

log = logging.getLogger(__name__)

#: Bumped when the layout of a part file changes.
PART_FORMAT = 1
#: The folders of the package whose code decides the numbers stored in a part, besides
#: every module on its ground floor (``sweep/*.py``: the numba policy, the code tables):
#: the kernels, the model (the grid's parameters and linear theory) and the engine (the
#: grid, which compiled variant runs it). Every file under them is hashed, so a module
#: added there changes the key without being named anywhere.
NUMERIC_FOLDERS = ("kernels", "model", "engine")
PART_NAME = re.compile(r"^(?P<hash>[0-9a-f]{16})_(?P<start>\d+)-(?P<stop>\d+)_of_(?P<n>\d+)\.npz$")
TEMP_PREFIX = ".part-"
#: A temporary part file: ``.part-<host>-<pid>-<random>.tmp`` (see ``replaced_atomically``).
TEMP_NAME = re.compile(r"^\.part-(?P<host>.+)-(?P<pid>\d+)-[0-9a-f]+\.tmp$")


def config_hash(config):
    """16 hex digits identifying the numbers a config produces.

    Built from the validated fields that change results (blocks, coupling, model,
    law, fixed and per-block parameters, spread, axes in order, initial state, integrator,
    classification and, where there is one, catalogue settings), the package version and
    the source of the numeric code (:func:`numeric_source_digest`). Fixed parameters are
    sorted, since their order in the file does not matter; axis order does (it orders the
    grid).
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
    digest.update(numeric_source_digest().encode())
    return digest.hexdigest()[:16]


def numeric_source_digest(package=None):
    """SHA-256 (hex) of every ``.py`` file on the package's ground floor and under its
    :data:`NUMERIC_FOLDERS`, each path with its bytes, in path order. ``package``: the
    package's folder (default: this one's)."""
    package = Path(package or Path(__file__).resolve().parents[1])
    paths = [*package.glob("*.py")]
    for folder in NUMERIC_FOLDERS:
        paths.extend((package / folder).rglob("*.py"))
    digest = hashlib.sha256()
    for path in sorted(paths):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


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
    expected = {
        "format": PART_FORMAT,
        "config_hash": match["hash"],
        "start": start,
        "stop": stop,
        "n": n,
    }
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
    return Part(
        path,
        match["hash"],
        start,
        stop,
        n,
        meta["config_text"],
        meta["config_source"],
        results,
        y_final,
    )


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


def _fill(entries, results, y_final, have, wanted):
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


class PartStore:
    """The kernels' arrays of a sweep's runs (or of one level of a refinement) and the
    parts folder where each finished chunk is saved: the one way parts are written and
    read back.

    ``shape``: (runs, result columns, state size); parts are named by ``chash`` (default:
    the config's hash, :func:`config_hash`).
    """

    def __init__(self, folder, config, shape, chash=None):
        n, width, n_vars = shape
        self.folder = Path(folder)
        self.config = config
        self.chash = chash or config_hash(config)
        self.n = n
        self.results = np.empty((n, width))
        self.y_final = np.empty((n, n_vars))
        self.saved = 0

    def make_folder(self):
        """Create the parts folder (a failure is a :class:`RunError`)."""
        try:
            self.folder.mkdir(exist_ok=True)
        except OSError as exc:
            raise RunError(
                f"cannot create the parts folder {self.folder}: {exc.strerror or exc}"
            ) from None

    def save(self, a, b):
        """Write rows ``a:b`` as a part; a failure is a :class:`RunError` saying what is kept."""
        try:
            write_part(
                self.folder,
                self.config,
                self.chash,
                a,
                b,
                self.n,
                self.results[a:b],
                self.y_final[a:b],
            )
        except OSError as exc:
            raise RunError(
                f"cannot write a part to {self.folder}: {exc.strerror or exc}; the parts "
                "written so far are kept, rerun with --resume once this is fixed"
            ) from None
        self.saved += b - a

    def fill(self, have, wanted, entries=None, merging=False):
        """Rows ``wanted`` and not yet ``have`` (boolean masks over the runs) read from the
        parts ``entries`` (default: this store's in its folder, :func:`scan`); ``have`` is
        updated. Returns ``(used, bad)``: the parts read, and ``(path, reason)`` for those
        unusable. While running (not ``merging``) an unusable part is reported and
        removed, so its runs are computed again; a merge reports them itself."""
        if entries is None:
            entries = scan(self.folder).get(self.chash, [])
        used, bad = _fill(entries, self.results, self.y_final, have, wanted)
        if not merging:
            for path, reason in bad:
                log.warning("unusable part, its runs will be recomputed: %s", reason)
                path.unlink(missing_ok=True)
        return used, bad

    def reuse(self, owned, resume):
        """Fill the rows ``owned`` (a mask) from the valid parts of this store (if
        ``resume``); return the mask of rows filled. Parts of other configs in the folder
        are named and left alone."""
        have = np.zeros(self.n, bool)
        groups = scan(self.folder)
        others = sum(len(v) for h, v in groups.items() if h != self.chash)
        if others:
            log.info("ignoring %d parts of another config in %s", others, self.folder)
        mine = groups.get(self.chash, [])
        if not resume:
            if mine:
                log.info(
                    "not reusing %d parts of this sweep in %s (--resume reuses them)",
                    len(mine),
                    self.folder,
                )
            return have
        used, _ = self.fill(have, owned, mine)
        log.info(
            "resuming from %s: reusing %d runs from %d parts",
            self.folder,
            int(have.sum()),
            len(used),
        )
        return have


class ZarrSink:
    """The kernels' arrays of a sweep's runs and the Zarr store (``sweep.io.zarr.ZarrResult``)
    each finished chunk is written into: a :class:`PartStore` for ``.zarr`` outputs, which
    keep no parts."""

    def __init__(self, zarr_result, shape):
        n, width, n_vars = shape
        self.store = zarr_result
        self.folder = zarr_result.path
        self.results = np.empty((n, width))
        self.y_final = np.empty((n, n_vars))

    @property
    def saved(self):
        return self.store.saved

    def save(self, a, b):
        """Write rows ``a:b`` into the store; a failure is a :class:`RunError`."""
        try:
            self.store.save(a, b, self.results[a:b], self.y_final[a:b])
        except OSError as exc:
            raise RunError(
                f"cannot write to {self.folder}: {exc.strerror or exc}; the chunks written so "
                "far are kept, rerun with --resume once this is fixed"
            ) from None


def stored_config(entries, parse):
    """The config stored in the first readable part of ``entries``, parsed by ``parse``
    (``parse(text, source)``), or None."""
    for *_, path in entries:
        try:
            part = read_part(path)
            return parse(part.config_text, part.config_source)
        except (PartError, ConfigError):
            continue
    return None


def remove_merged(used, paths):
    """After a merge: remove the parts ``used``, then in the folders of ``paths`` the
    temporary files of killed writers, then those folders if empty."""
    for f in used:
        f.unlink()
    for folder in {Path(p) for p in paths if Path(p).is_dir()}:
        for f in stale_temp_files(folder):
            f.unlink(missing_ok=True)
        if not any(folder.iterdir()):
            folder.rmdir()
