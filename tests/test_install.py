"""rsf-sweep as users meet it: built into a wheel and into an sdist, each installed into a
fresh virtual environment and run from a folder outside the repository.

Every other test imports the checkout (an editable install or ``PYTHONPATH``), so a file
the wheel leaves out goes unnoticed there: the wheel once lacked ``sweep.kernels`` and
``rsf-sweep run quick`` failed after ``pip install .`` (issue 36 §4).

What is real: the wheel is built from a copy of the checkout by ``pip wheel`` (what
``pip install .`` does), the sdist by the build backend's ``build_sdist`` hook in a fresh
environment holding only the ``[build-system]`` requirements (what ``python -m build
--sdist`` does; pip cannot build an sdist), and pip builds the sdist's wheel itself when
it installs it. Both are installed by pip into a new virtual environment, whose own
``rsf-sweep`` console script, ``python -m sweep`` and ``import sweep`` are run with no
``PYTHONPATH``, no numba or rsf-sweep environment variables, from an empty folder, as a
user would (numba compiles the kernels and caches them inside that environment).
The kernels run in the wheel's environment; the sdist's, whose installed files are
asserted to be the same, imports every module but runs no sweep (it would compile the
same code again, 25 s).

The shortcut: the package is installed with ``--no-deps``, and a ``.pth`` file in the new
environment adds, as plain path lines, the folders holding the test's own copies of the
package's declared dependencies: installing them from the package index took 34-42 s and
530 MB per environment on the 2-core test machine, the whole test takes about 45 s per
environment without them (most of it numba's first compile). A plain path line does not
run the editable-install hook (``__editable__*.pth``) that may lie in those folders, and
every module of the package is checked to be imported from the new environment. What this
does not test: that the declared dependencies are complete (the test's environment also
holds the test and optional extras) and that their newest releases work.
"""

import email
import json
import os
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from importlib import metadata
from pathlib import Path

import pytest
import xarray as xr
import yaml
from conftest import ROOT, SUBPROCESS_TIMEOUT

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: pytest depends on tomli there
    import tomli as tomllib

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())

#: Environment variables a user's shell would not set: the test's own import path and
#: virtual environment, and settings of numba and of rsf-sweep (its kernel cache).
ENV_DROPPED_PREFIXES = ("PYTHON", "NUMBA_", "SWEEP_", "VIRTUAL_ENV", "CONDA")


def package_files():
    """The files an install must hold, from the source tree: every module under
    ``sweep/`` and every example config (``configs/*.yaml``, installed as
    ``sweep/configs``), as paths relative to site-packages."""
    modules = {
        p.relative_to(ROOT).as_posix()
        for p in (ROOT / "sweep").rglob("*.py")
        if "__pycache__" not in p.parts
    }
    configs = {f"sweep/configs/{p.name}" for p in (ROOT / "configs").glob("*.yaml")}
    assert "sweep/kernels/__init__.py" in modules and "sweep/configs/quick.yaml" in configs
    return modules | configs


def module_name(file):
    """``sweep/kernels/__init__.py`` -> ``sweep.kernels``."""
    parts = Path(file).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def user_env(venv=None):
    """The environment of a user's shell: this one without :data:`ENV_DROPPED_PREFIXES`
    (pip's settings stay: they name the package index), ``venv/bin`` first on PATH."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(ENV_DROPPED_PREFIXES)}
    if venv is not None:
        env["PATH"] = os.pathsep.join([str(venv / "bin"), env.get("PATH", "")])
    return env


def run(cmd, **options):
    """``cmd`` run to completion (in :func:`user_env` unless told otherwise); fails with
    its output if it exits non-zero. Returns its stdout."""
    options.setdefault("env", user_env())
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                          timeout=SUBPROCESS_TIMEOUT, **options)  # fmt: skip
    assert proc.returncode == 0, f"{cmd} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def copy_checkout(dest):
    """The files of the checkout (tracked or not ignored by git) copied to ``dest``:
    setuptools writes ``build/`` and ``*.egg-info`` into the folder it builds."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=ROOT, capture_output=True, check=True, timeout=60,
        ).stdout.decode().split("\0")  # fmt: skip
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: all but the usual
        ignore = shutil.ignore_patterns(".*", "build", "*.egg-info", "__pycache__", "results")
        shutil.copytree(ROOT, dest, ignore=ignore)
        return
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():  # a tracked file deleted in the working tree is not
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def new_venv(path):
    """A fresh virtual environment at ``path`` (no pip in it: this test's pip installs
    into it with ``--python``). Returns its python."""
    run([sys.executable, "-m", "venv", "--without-pip", path])
    return path / "bin" / "python"


#: pip as this test runs it. No cache: pip would reuse a wheel it built before from an
#: sdist at the same path (a temporary folder of an earlier run) instead of this one.
PIP = [sys.executable, "-m", "pip", "--no-cache-dir", "--quiet"]


def pip_install(python, *args):
    run([*PIP, "--python", python, "install", *args])


def build_wheel(src, out):
    run([*PIP, "wheel", "--no-deps", "--wheel-dir", out, src])
    (wheel,) = out.glob("*.whl")
    return wheel


def build_sdist(src, out):
    """The sdist of ``src`` in ``out``: the ``[build-system]`` backend's ``build_sdist``
    hook, run in ``src`` by a fresh environment holding only its requirements."""
    system = tomllib.loads((src / "pyproject.toml").read_text())["build-system"]
    python = new_venv(src.parent / "build-env")
    pip_install(python, *system["requires"])
    module, _, attr = system["build-backend"].partition(":")
    code = (
        "import importlib, sys\n"
        "backend = importlib.import_module(sys.argv[1])\n"
        "backend = getattr(backend, sys.argv[2]) if sys.argv[2] else backend\n"
        "backend.build_sdist(sys.argv[3])\n"
    )
    run([python, "-c", code, module, attr, out], cwd=src)
    (sdist,) = out.glob("*.tar.gz")
    return sdist


def assert_holds(files, expected, what, exactly=True):
    """``files`` are ``expected`` (or with ``exactly=False`` include them), saying which
    are missing or extra."""
    missing, extra = sorted(expected - files), sorted(files - expected) if exactly else []
    assert not missing and not extra, f"{what} lacks {missing}, has extra {extra}"


def check_wheel(wheel, expected):
    """The wheel holds the files ``expected`` below ``sweep/`` and nothing else but its
    ``.dist-info`` (no tests, docs or results)."""
    names = zipfile.ZipFile(wheel).namelist()
    tops = {name.split("/")[0] for name in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"sweep"}, sorted(tops)
    assert_holds({n for n in names if n.startswith("sweep/")}, expected, "the wheel")


def check_sdist(sdist, src, expected):
    """The sdist holds what the wheel is built from: pyproject.toml (and setup.py if
    there is one), the readme and license files, and the files ``expected`` at their
    places in the source tree (``configs/`` for ``sweep/configs/``)."""
    with tarfile.open(sdist) as tar:
        names = {m.name.split("/", 1)[1] for m in tar.getmembers() if m.isfile()}
    project = PYPROJECT["project"]
    needed = {"pyproject.toml", project["readme"], *project["license-files"]}
    needed |= {"setup.py"} if (src / "setup.py").exists() else set()
    needed |= {f.replace("sweep/configs/", "configs/") for f in expected}
    assert_holds(names, needed, "the sdist", exactly=False)


def site_packages(python):
    return Path(run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"])
                .strip())  # fmt: skip


def make_dependencies_visible(site):
    """The shortcut: a ``.pth`` file in ``site`` listing the folders of this process's
    copies of the installed package's unconditional dependencies (Requires-Dist)."""
    (dist_info,) = site.glob("rsf_sweep-*.dist-info")
    requires = email.message_from_bytes((dist_info / "METADATA").read_bytes())
    names = [re.match(r"[\w.-]+", r)[0] for r in requires.get_all("Requires-Dist") if ";" not in r]
    folders = {Path(metadata.distribution(n).locate_file("")).resolve() for n in names}
    # the test's environment may lie inside the checkout (make test's .venv): what must
    # not be on the path is a folder that holds the package itself
    assert not any((f / "sweep").exists() for f in folders), folders
    (site / "_test_install_dependencies.pth").write_text("".join(f"{f}\n" for f in folders))


#: Run in the new environment: the Python API on the packaged example (if the first
#: argument is "run"), and every module of the source tree imported (their names are the
#: other arguments), as JSON.
API_RUN = """
import importlib, json, sys
import sweep
ds = sweep.run("quick", progress=False) if sys.argv[1] == "run" else None
print(json.dumps({
    "sweep": sweep.__file__,
    "modules": {name: importlib.import_module(name).__file__ for name in sys.argv[2:]},
    "regime_dims": None if ds is None else list(ds.regime.dims),
    "regime": None if ds is None else ds.regime.values.tolist(),
    "K_W": None if ds is None else ds.K_W.values.tolist(),
}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["wheel", "sdist"])
def test_installed_package_runs_outside_the_repository(kind, tmp_path):
    assert not tmp_path.resolve().is_relative_to(ROOT)
    src, dist = tmp_path / "src", tmp_path / "dist"
    copy_checkout(src)
    expected = package_files()
    if kind == "wheel":
        artefact = build_wheel(src, dist)
        check_wheel(artefact, expected)
    else:
        artefact = build_sdist(src, dist)
        check_sdist(artefact, src, expected)

    venv = tmp_path / "venv"
    python = new_venv(venv)
    pip_install(python, "--no-deps", artefact)  # an sdist: pip builds its wheel
    site = site_packages(python)
    installed = {
        p.relative_to(site).as_posix()
        for p in (site / "sweep").rglob("*")
        if p.suffix in (".py", ".yaml") and "__pycache__" not in p.parts
    }
    assert_holds(installed, expected, "the installed package")
    make_dependencies_visible(site)

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = user_env(venv)
    rsf_sweep = venv / "bin" / "rsf-sweep"

    # the example configs, from the installed package
    listing = run([rsf_sweep, "examples"], cwd=elsewhere, env=env).splitlines()
    stems = sorted(p.stem for p in (ROOT / "configs").glob("*.yaml"))
    assert [line.split()[0] for line in listing[:-1]] == stems, listing
    assert f"(in {site.resolve() / 'sweep' / 'configs'};" in listing[-1], listing
    version = run([python, "-m", "sweep", "--version"], cwd=elsewhere, env=env)
    assert version.startswith("rsf-sweep "), version

    # (a) the Python API, and every module of the source tree, from the new environment.
    # The kernels run in the wheel's environment only: the sdist's holds the same files
    # (asserted above), and a run there would compile the same code again (25 s).
    names = sorted(module_name(f) for f in expected if f.endswith(".py"))
    names.remove("sweep.__main__")  # importing it runs the CLI: python -m sweep ran above
    runs = kind == "wheel"
    got = json.loads(run([python, "-c", API_RUN, "run" if runs else "import", *names],
                         cwd=elsewhere, env=env))  # fmt: skip
    for name, file in {"sweep": got["sweep"], **got["modules"]}.items():
        assert Path(file).resolve().is_relative_to(venv.resolve()), (name, file)
    if not runs:
        return

    # (b) the console script, on the packaged example: the API's numbers
    out = tmp_path / "q.nc"
    run([rsf_sweep, "run", "quick", "--out", out], cwd=elsewhere, env=env)
    with xr.open_dataset(out) as ds:
        ds.load()
    quick = yaml.safe_load((ROOT / "configs" / "quick.yaml").read_text())
    axis = quick["sweep"]["K_W"]
    assert ds.regime.dims == ("K_W",) and ds.sizes["K_W"] == axis["num"]
    assert ds.K_W.values[[0, -1]].tolist() == [axis["start"], axis["stop"]]
    meanings = ds.regime.attrs["flag_meanings"].split()
    # the example spans the transition at Kc/W = 0.05: runaway below, steady above
    assert [meanings[r] for r in ds.regime.values[[0, -1]]] == ["runaway", "steady"]
    assert got["regime_dims"] == ["K_W"]
    assert got["regime"] == ds.regime.values.tolist()
    assert got["K_W"] == ds.K_W.values.tolist()
