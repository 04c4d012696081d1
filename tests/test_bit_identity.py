"""Every number of a few small runs is bit-identical to the code of a reference commit.

The last bits of a result depend on the machine as well as on the code: NumPy picks
its ``exp`` and LAPACK kernels by CPU (AVX-512 or AVX2), and a one-ulp difference in
a start value grows in the chaotic two-block runs. A stored file of numbers written
on one machine therefore fails on another for reasons that have nothing to do with
a refactoring. So the reference is computed here, on this machine, by the code of
:data:`REFERENCE_COMMIT` (``git archive`` of its ``sweep/`` and its
``tests/bit_identity_cases.py``), and compared with the code as it is now.

Move :data:`REFERENCE_COMMIT` only in a commit that says which numbers changed and
why (a changed method, controller or classifier), never to make the test pass.
"""

import io
import os
import subprocess
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest

from bit_identity_cases import compute_all, flatten

#: The code every number is compared with: the layout before issues 12 and 15.
REFERENCE_COMMIT = "759d878b932fa928c93cc2fc632af2ddc4ca7772"

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    """The reference commit's code (its ``sweep/`` and ``tests/bit_identity_cases.py``)
    extracted to a temporary tree and started there in its own process, which
    computes while this one computes :func:`computed` (two cores: half the wait)."""
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout: the reference commit's code is not at hand")
    paths = ["sweep", "tests/bit_identity_cases.py"]
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", REFERENCE_COMMIT, *paths], capture_output=True
    )
    if archive.returncode != 0:
        pytest.skip(f"reference commit not in this clone: {archive.stderr.decode().strip()}")
    tree = tmp_path_factory.mktemp("reference_commit")
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        # the "data" filter (no absolute paths, links out of the tree or devices) exists
        # from Python 3.10.12 / 3.11.4 on; git's own archive of this repository is trusted
        safe = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}
        tar.extractall(tree, **safe)
    # The reference commit's script writes tests/data/bit_identity.npz beside itself.
    script = tree / "tests" / "bit_identity_cases.py"
    env = dict(os.environ, PYTHONPATH=str(tree))
    with open(tree / "stderr.txt", "w") as stderr:
        proc = subprocess.Popen([sys.executable, str(script)], cwd=tree, env=env,
                                stdout=subprocess.DEVNULL, stderr=stderr)  # fmt: skip
    yield tree, proc
    if proc.poll() is None:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def computed(reference_run):
    """``{"case/var": array}`` computed by the code as it is now (the reference is
    being computed meanwhile)."""
    return flatten(compute_all())


@pytest.fixture(scope="module")
def reference(reference_run, computed):
    """``{"case/var": array}`` computed by the reference commit's code, on this machine."""
    tree, proc = reference_run
    assert proc.wait() == 0, (tree / "stderr.txt").read_text()
    with np.load(tree / "tests" / "data" / "bit_identity.npz") as ref:
        return {key: ref[key] for key in ref.files}


def test_every_reference_number_is_still_computed(reference, computed):
    """Variables may be added (new outputs); none of the reference's may vanish."""
    assert set(reference) <= set(computed), sorted(set(reference) - set(computed))


def test_numbers_are_bit_identical(reference, computed):
    differ = [
        key
        for key, a in reference.items()
        if a.shape != computed[key].shape or a.tobytes() != computed[key].tobytes()
    ]
    assert not differ, f"changed bits in {differ}"
