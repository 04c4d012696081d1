"""Every number of a few small runs is bit-identical to the code of a reference commit.

The last bits of a result depend on the machine as well as on the code: NumPy picks
its ``exp`` and LAPACK kernels by CPU (AVX-512 or AVX2), and a one-ulp difference in
a start value grows in the chaotic two-block runs. A stored file of numbers written
on one machine therefore fails on another for reasons that have nothing to do with
a refactoring. So the reference is computed here, on this machine, by the code of
:data:`REFERENCE_COMMIT`, and compared with the code as it is now.

That code is kept in the repository, not looked up in its history (which a shallow
clone or an unpacked release lacks): :data:`REFERENCE_ARCHIVE` is ``git archive`` of
the commit's ``sweep/`` and ``tests/bit_identity_cases.py`` (about 120 kB), and git
writes the commit's id into its header. To move the reference, which rewrites the
archive and :data:`REFERENCE_COMMIT`::

    make bit-identity-reference COMMIT=<commit>

Move it only in a commit that says which numbers changed and why (a changed method,
controller or classifier), never to make the test pass.

The reference commit's code is compiled cold in a fresh tree (about 3 minutes of a core
for every case here), and its numbers are a function of that code, this machine and the
compiling and numeric libraries: they are kept in :func:`reference_cache`, a folder of
this clone, under a key of exactly those (:func:`reference_key`), so that a later run in
the same clone compares with them instead of recompiling (as numba's cache of the
package's own kernels does; ``make clean`` removes both). A fresh clone always computes
them: the suite's cost does not depend on what ran on the machine before.
``SWEEP_BIT_IDENTITY_CACHE=0`` turns the cache off; another path moves it.

The cases come in two sets (:data:`CASE_SETS`): ``make test`` compares the first (the
default method, with and without early exit: one group of kernels for the reference's
code to compile cold, 58 s of CPU on the project's 2-core machine where the inertial,
two-block and trace cases made it 94 s), ``make test-all`` both.
"""

import hashlib
import io
import os
import platform
import subprocess
import sys
import tarfile
from pathlib import Path, PurePosixPath

import llvmlite
import numba
import numpy as np
import pytest
from conftest import SUBPROCESS_TIMEOUT

from bit_identity_cases import NAMES, compute, flatten

#: The code every number is compared with: main after issue 51's mends of the tests. Its
#: numbers are those of afbbb92 (main after issue 36: the tangent as the exact derivative
#: of each method's step), bit for bit: this guard passed against afbbb92 on its code.
#: Moved for its script, which computes the cases it is given (a tier's set).
REFERENCE_COMMIT = "37d4a860af9e25930cc1d9a88ca89e59d8ac6d69"
#: That commit's ``sweep/`` and ``tests/bit_identity_cases.py`` (``git archive``).
REFERENCE_ARCHIVE = Path(__file__).parent / "data" / "bit_identity_reference.tar.gz"
#: Seconds the reference commit's code may take for the cases (about 100 s cold on two
#: busy cores): a hung process fails the test instead of blocking it.
REFERENCE_TIMEOUT = 1800


#: Where the reference's numbers computed in this clone are kept (``.gitignore``d).
CACHE = Path(__file__).resolve().parents[1] / ".cache" / "bit-identity"

#: The cases compared by ``make test`` ("fast") and those only ``make test-all`` adds.
FAST_CASES = ("dop853", "dop853_no_early_exit")
CASE_SETS = {"fast": FAST_CASES, "rest": tuple(n for n in NAMES if n not in FAST_CASES)}


def reference_cache():
    """Folder of the reference's numbers computed in this clone: ``$SWEEP_BIT_IDENTITY_CACHE``,
    else :data:`CACHE`; None if that variable is ``0``."""
    setting = os.environ.get("SWEEP_BIT_IDENTITY_CACHE")
    if setting == "0":
        return None
    return Path(setting) if setting else CACHE


def reference_key(archive=None):
    """A digest of everything the reference's numbers depend on besides the code under
    test: the archive's bytes, Python, NumPy, numba and llvmlite, numba's settings from
    the environment, and the CPU (its model and flags, which pick NumPy's and LLVM's
    kernels)."""
    digest = hashlib.sha256(Path(archive or REFERENCE_ARCHIVE).read_bytes())
    cpu = ""
    if os.path.exists("/proc/cpuinfo"):
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        cpu = "\n".join(
            sorted({line for line in lines if line.startswith(("model name", "flags"))})
        )
    numba_env = sorted((k, v) for k, v in os.environ.items() if k.startswith("NUMBA_"))
    for part in (sys.version, platform.machine(), platform.processor(), cpu, np.__version__,
                 numba.__version__, llvmlite.__version__, repr(numba_env)):  # fmt: skip
        digest.update(part.encode())
    return digest.hexdigest()[:32]


def cache_name(case_set):
    """The name of ``case_set``'s numbers in :func:`reference_cache`: :func:`reference_key`
    and a digest of the set's cases (a set whose cases change is computed afresh)."""
    cases = hashlib.sha256(" ".join(CASE_SETS[case_set]).encode()).hexdigest()[:8]
    return f"{reference_key()}-{case_set}-{cases}"


def extract(archive, tree):
    """Extract the tar file ``archive`` into the folder ``tree``, refusing any member
    but a plain file or folder inside ``tree`` (``tarfile.TarError``).

    The check is what tarfile's "data" filter does from Python 3.10.12 / 3.11.4 on; it
    is done here on every Python the package allows, and the filter used where it exists.
    """
    with tarfile.open(archive) as tar:
        members = tar.getmembers()
        for member in members:
            path = PurePosixPath(member.name)
            if not (member.isfile() or member.isdir()) or path.is_absolute() or ".." in path.parts:
                raise tarfile.TarError(f"{archive}: {member.name!r} is not a file in the tree")
        safe = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
        tar.extractall(tree, members=members, **safe)


def archived_commit(archive):
    """The commit ``git archive`` wrote into the header of ``archive`` (None if none)."""
    with tarfile.open(archive) as tar:
        return tar.pax_headers.get("comment")


def test_the_archive_holds_the_reference_commit():
    assert archived_commit(REFERENCE_ARCHIVE) == REFERENCE_COMMIT, (
        f"{REFERENCE_ARCHIVE.name} is not the code of {REFERENCE_COMMIT}: "
        "make bit-identity-reference COMMIT=<commit> writes both"
    )


@pytest.fixture(scope="module", params=["fast", pytest.param("rest", marks=pytest.mark.slow)])
def case_set(request):
    """The name of a set of :data:`CASE_SETS` (its cases: ``CASE_SETS[name]``)."""
    return request.param


@pytest.fixture(scope="module")
def reference_run(case_set, tmp_path_factory):
    """The reference's numbers of ``case_set`` from :func:`reference_cache` if this clone
    computed them before, else the reference commit's code extracted from
    :data:`REFERENCE_ARCHIVE` to a temporary tree and started there on the set's cases in
    its own process, which computes while this one computes :func:`computed` (two cores:
    half the wait). Yields ``(file, process)``: the ``.npz`` the numbers are (or will be)
    in, and the process (None if cached)."""
    cache = reference_cache()
    cached = cache / f"{cache_name(case_set)}.npz" if cache else None
    if cached is not None and cached.is_file():
        yield cached, None
        return
    tree = tmp_path_factory.mktemp(f"reference_commit_{case_set}")
    extract(REFERENCE_ARCHIVE, tree)
    # The reference commit's script writes tests/data/bit_identity.npz beside itself.
    script = tree / "tests" / "bit_identity_cases.py"
    env = dict(os.environ, PYTHONPATH=str(tree))
    with open(tree / "stderr.txt", "w") as stderr:
        proc = subprocess.Popen([sys.executable, str(script), *CASE_SETS[case_set]], cwd=tree,
                                env=env, stdout=subprocess.DEVNULL, stderr=stderr)  # fmt: skip
    yield tree / "tests" / "data" / "bit_identity.npz", proc
    if proc.poll() is None:
        proc.kill()
        proc.wait(timeout=SUBPROCESS_TIMEOUT)


@pytest.fixture(scope="module")
def computed(case_set, reference_run):
    """``{"case/var": array}`` of ``case_set`` computed by the code as it is now (the
    reference is being computed meanwhile)."""
    return flatten(compute(CASE_SETS[case_set]))


@pytest.fixture(scope="module")
def reference(case_set, reference_run, computed):
    """``{"case/var": array}`` of ``case_set`` computed by the reference commit's code, on
    this machine; a fresh computation is kept in :func:`reference_cache` (written to a
    temporary name and renamed, so a concurrent or killed run leaves no partial file)."""
    numbers, proc = reference_run
    if proc is not None:
        assert proc.wait(timeout=REFERENCE_TIMEOUT) == 0, (
            numbers.parents[2] / "stderr.txt"
        ).read_text()
        cache = reference_cache()
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            name = cache_name(case_set)
            partial = cache / f"{name}.{os.getpid()}.tmp"
            partial.write_bytes(numbers.read_bytes())
            os.replace(partial, cache / f"{name}.npz")
    cases = CASE_SETS[case_set]
    with np.load(numbers) as ref:
        # a reference commit older than the case sets computes every case: keep the set's
        return {key: ref[key] for key in ref.files if key.split("/")[0] in cases}


def test_the_case_sets_are_every_case_once():
    assert sorted(CASE_SETS["fast"] + CASE_SETS["rest"]) == sorted(NAMES)


def test_the_cache_key_is_the_archives(tmp_path):
    """The same bytes give the same key; one changed byte (another reference) another."""
    copy = tmp_path / "copy.tar.gz"
    data = REFERENCE_ARCHIVE.read_bytes()
    copy.write_bytes(data)
    assert reference_key(copy) == reference_key()
    copy.write_bytes(data[:-1] + bytes([data[-1] ^ 1]))
    assert reference_key(copy) != reference_key()


def test_every_reference_number_is_still_computed(case_set, reference, computed):
    """Variables may be added (new outputs); none of the reference's may vanish, and the
    reference has every case of the set."""
    assert set(reference) <= set(computed), sorted(set(reference) - set(computed))
    assert {key.split("/")[0] for key in reference} == set(CASE_SETS[case_set])


def test_numbers_are_bit_identical(reference, computed):
    differ = [
        key
        for key, a in reference.items()
        if a.shape != computed[key].shape or a.tobytes() != computed[key].tobytes()
    ]
    assert not differ, f"changed bits in {differ}"


# --- extraction on every Python the package allows ----------------------------------------


@pytest.fixture(params=["data filter", "no filter"])
def tar_python(request, monkeypatch):
    """tarfile as on Python ≥ 3.10.12 / 3.11.4 (the "data" filter) or before (no filter:
    ``extractall`` takes no ``filter`` argument); yields the filters passed to it."""
    passed = []
    extractall = tarfile.TarFile.extractall
    if request.param == "no filter":
        monkeypatch.delattr(tarfile, "data_filter", raising=False)

        def old_extractall(self, path=".", members=None, *, numeric_owner=False):
            passed.append(None)
            return extractall(self, path, members, numeric_owner=numeric_owner)

        monkeypatch.setattr(tarfile.TarFile, "extractall", old_extractall)
    else:
        if not hasattr(tarfile, "data_filter"):
            pytest.skip("this Python's tarfile has no data filter")

        def new_extractall(self, *args, filter=None, **kwargs):
            passed.append(filter)
            return extractall(self, *args, filter=filter, **kwargs)

        monkeypatch.setattr(tarfile.TarFile, "extractall", new_extractall)
    return request.param, passed


def test_the_reference_extracts(tar_python, tmp_path):
    kind, passed = tar_python
    extract(REFERENCE_ARCHIVE, tmp_path)
    assert passed == ["data" if kind == "data filter" else None]
    assert (tmp_path / "tests" / "bit_identity_cases.py").is_file()
    assert (tmp_path / "sweep" / "__init__.py").is_file()


@pytest.mark.parametrize("name, kind", [("../outside.py", tarfile.REGTYPE),
                                        ("/tmp/absolute.py", tarfile.REGTYPE),
                                        ("sweep/link.py", tarfile.SYMTYPE)])  # fmt: skip
def test_members_outside_the_tree_are_refused(tar_python, tmp_path, name, kind):
    archive = tmp_path / "bad.tar.gz"
    with tarfile.open(archive, "w:gz") as tar:
        member = tarfile.TarInfo(name)
        member.type = kind
        member.linkname = "/etc/passwd" if kind == tarfile.SYMTYPE else ""
        tar.addfile(member, None if kind == tarfile.SYMTYPE else io.BytesIO())
    with pytest.raises(tarfile.TarError, match="is not a file in the tree"):
        extract(archive, tmp_path / "tree")
    assert not (tmp_path / "tree").exists()
