"""The notebook API (sweep/api.py, sweep/__init__.py) and the packaged examples
(sweep/examples.py): configs from paths, names, mappings and changes; results that
combine along a fixed parameter; nothing written."""

import contextlib
import json
import os
import signal
import time

import numpy as np
import pytest
import xarray as xr
from conftest import QUICK, ROOT, SUBPROCESS_TIMEOUT, python_stdout, without_provenance

import sweep
from sweep import examples
from sweep.cli import main
from sweep.config import config_mapping
from sweep.config.parse import MAPPING_SOURCE
from sweep.engine import runner
from sweep.errors import InputError
from sweep.io.netcdf import write_netcdf


def without_file_attrs(ds):
    """``ds`` with no file (global) attributes."""
    out = ds.copy()
    out.attrs = {}
    return out


@pytest.fixture(scope="module")
def quick_result():
    return sweep.run(QUICK, threads=1, progress=False)


def test_import_loads_neither_numba_nor_matplotlib_nor_xarray():
    code = (
        "import sys, sweep; "
        "print([m for m in ('numba', 'matplotlib', 'xarray') if m in sys.modules])"
    )
    assert python_stdout(code).strip() == "[]"


def test_run_from_a_path_a_name_and_a_mapping_agree(quick_result, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a folder with no configs/: the name is the packaged example
    by_name = sweep.run("quick", threads=1, progress=False)
    raw = config_mapping(sweep.load_config(QUICK))
    del raw["name"]
    by_mapping = sweep.run(raw, threads=1, progress=False)
    for ds in (by_name, by_mapping):
        # the numbers and their attributes; file attributes name the config's origin
        xr.testing.assert_identical(without_file_attrs(ds), without_file_attrs(quick_result))
    assert list(tmp_path.iterdir()) == []  # nothing written
    # provenance says where the config came from, and invents no file
    assert quick_result.attrs["history"].endswith(f"sweep.run() in Python from config {QUICK}")
    assert by_mapping.attrs["config_path"] == MAPPING_SOURCE
    assert by_mapping.attrs["history"].endswith(f"from config {MAPPING_SOURCE}")
    assert by_mapping.attrs["sweep_name"] == "sweep"
    assert sweep.load_config(raw).output == "results/sweep.nc"


def test_parse_config_takes_a_mapping_with_numpy_values():
    raw = config_mapping(sweep.load_config(QUICK))
    raw["sweep"]["K_W"] = np.linspace(0.04, 0.06, 3)
    raw["parameters"]["A"] = np.float64(0.02)
    config = sweep.parse_config(raw)
    assert config.axes[0].values == (0.04, 0.05, 0.06)
    assert config.fixed["A"] == 0.02 and config.source == MAPPING_SOURCE


def test_with_changes_revalidates_and_names_the_keys():
    config = sweep.with_changes("quick", {"integrator": {"t_end": 5000}, "parameters": {"A": 0.02}})
    assert config.integrator.t_end == 5000.0 and config.fixed["A"] == 0.02
    assert config.fixed["B"] == 0.08  # untouched values stay
    assert "with changes to integrator.t_end, parameters.A" in config.source
    fixed = sweep.with_changes(config, {"sweep": {"K_W": None, "A": [0.02, 0.03]},
                                        "parameters": {"K_W": 0.05, "A": None}})  # fmt: skip
    assert [a.name for a in fixed.axes] == ["A"] and fixed.fixed["K_W"] == 0.05
    with pytest.raises(sweep.ConfigError) as err:
        sweep.with_changes("quick", {"integrator": {"t_ned": 1}, "parameters": {"A": -1}})
    problems = "\n".join(err.value.problems)
    assert "unknown key integrator.t_ned" in problems
    assert "parameters.A must be in (0, inf), got -1" in problems


def test_a_text_number_from_safe_load_gets_a_hint():
    raw = config_mapping(sweep.load_config(QUICK))
    raw["classification"]["v_cap_over_V"] = "1.0e6"  # what yaml.safe_load makes of 1.0e6
    with pytest.raises(sweep.ConfigError, match="text, not a number"):
        sweep.parse_config(raw)


@pytest.mark.parametrize("name", sweep.examples.names())
def test_every_shipped_config_reads_the_same_through_yaml_safe_load(name):
    """What the Python API section shows: ``sweep.run(yaml.safe_load(open(path)))``.
    PyYAML's safe_load (YAML 1.1) reads 1.0e6 as text, so the shipped configs write
    1.0e+6: the mapping gives the same config as the file."""
    import dataclasses

    import yaml

    path = sweep.examples.path(name)
    from_file = sweep.load_config(path)
    with open(path) as f:
        from_mapping = sweep.parse_config(yaml.safe_load(f))
    same = {"source": from_file.source, "text": from_file.text}
    assert dataclasses.replace(from_mapping, **same) == from_file


def test_a_mapping_from_yaml_safe_load_runs():
    import yaml

    with open(QUICK) as f:
        ds = sweep.run(yaml.safe_load(f), progress=False)
    assert ds.regime.size == 9 and int((ds.regime == 3).sum()) == 0


def test_run_rejects_bad_threads():
    """A bad argument is the user's to fix (InputError, exit 2) but not a config problem."""
    with pytest.raises(sweep.InputError, match="threads must be an integer") as err:
        sweep.run(QUICK, threads=0, progress=False)
    assert not isinstance(err.value, sweep.ConfigError)


def test_results_differing_in_a_fixed_parameter_combine_along_it(quick_result, tmp_path):
    """Fixed parameters are scalar coordinates: open_mfdataset labels each file by its A."""
    pytest.importorskip("dask")
    other = sweep.run(sweep.with_changes(QUICK, {"parameters": {"A": 0.02}}), progress=False)
    paths = [write_netcdf(quick_result, tmp_path / "a.nc"), write_netcdf(other, tmp_path / "b.nc")]
    with xr.open_mfdataset(paths, combine="nested", concat_dim="A") as both:
        np.testing.assert_array_equal(both["A"].values, [0.03, 0.02])
        assert both["A"].attrs["units"] == "1"
        assert both["regime"].dims == ("A", "K_W")
        np.testing.assert_array_equal(both["regime"].sel(A=0.02), other["regime"])


def test_examples_list_every_config_of_the_repository():
    assert examples.names() == sorted(p.stem for p in QUICK.parent.glob("*.yaml"))
    assert examples.path("quick").read_text() == QUICK.read_text()
    with pytest.raises(KeyError, match="quick"):
        examples.path("nope")


def test_cli_version_and_examples(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"rsf-sweep {sweep.__version__}"
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in examples.names())


def test_cli_runs_a_packaged_example_from_any_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "quick", "--quiet", "--threads", "1"]) == 0
    assert (tmp_path / "results" / "quick.nc").is_file()
    assert "wrote results/quick.nc" in capsys.readouterr().out
    assert main(["run", "nonesuch"]) == 2
    err = capsys.readouterr().err
    assert "cannot read config" in err and "packaged examples: " in err


def test_a_result_written_by_the_api_is_what_the_runner_writes(quick_result):
    computed = runner.compute(sweep.load_config(QUICK), threads=1, show_progress=False)
    xr.testing.assert_identical(without_provenance(quick_result), without_provenance(computed))


def test_license_and_citation_are_shipped():
    import yaml

    assert "MIT License" in (ROOT / "LICENSE").read_text()
    assert "2026 rsf-sweep contributors" in (ROOT / "LICENSE").read_text()
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["version"] == sweep.__version__
    paper = cff["references"][0]  # the seed paper first; then friction laws, integrators, λ1
    assert paper["title"].startswith("Transition from Uniform Motion to Stick-Slip")
    assert [a["family-names"] for a in paper["authors"]] == ["Szkutnik", "Kułakowski"]


@pytest.mark.slow
def test_compile_kernels_compiles_only_the_configs_variants():
    """``sweep.compile_kernels(config)`` (warming numba's cache before job arrays)
    compiles, in a fresh process, the grid kernel of that config's variant and, where
    runs unsettled at t_end ask for λ1 (the default), the same variant with the
    tangent, and builds no other variant; with ``lyapunov: never`` only the first."""
    code = (
        "import sys, sweep\nfrom sweep.engine import dispatch\n"
        "from sweep.kernels import integrate\n"
        "from sweep.engine.grid import build_grid\n"
        "config = sweep.with_changes('quick', {'classification': {'lyapunov': sys.argv[1]}})\n"
        "sweep.compile_kernels(config)\n"
        "g = build_grid(config)\n"
        "print(integrate.grid_kernel.cache_info().currsize,"
        " *(len(dispatch.grid_kernel(g.params, g.settings, t).signatures) for t in (0, 1)))"
    )
    for mode, expected in (("unsettled", "2 1 1"), ("never", "1 1 0")):
        assert python_stdout(code, mode).split() == expected.split(), mode


# Compiles two variants of quick.yaml side by side (or, with the cache off, here), runs
# one of them and reports the run's numbers and how numba's cache served the kernels.
#: Two variants of the packaged example (DOP853 and DOPRI5, without λ1).
SIDE_BY_SIDE_CONFIGS = [
    {"integrator": {"method": m}, "classification": {"lyapunov": "never"}}
    for m in ("dop853", "dopri5")
]
SIDE_BY_SIDE = (
    f"CONFIGS = {SIDE_BY_SIDE_CONFIGS!r}\n"
    + """
import json, sys, sweep
from sweep.engine import dispatch
from sweep.engine.grid import build_grid
configs = [sweep.with_changes('quick', c) for c in CONFIGS]
sweep.compile_kernels(*configs, processes=2)
stats = [dispatch.grid_kernel(g.params, g.settings).stats for g in map(build_grid, configs)]
ds = sweep.run(configs[1], progress=False)
print(json.dumps({"hits": [sum(s.cache_hits.values()) for s in stats],
                  "misses": [sum(s.cache_misses.values()) for s in stats],
                  "n_steps": ds["n_steps"].values.tolist(),
                  "period": ds["period"].values.tolist()}))
"""
)


@pytest.mark.slow
def test_compile_kernels_builds_variants_side_by_side(tmp_path):
    """``compile_kernels(*configs, processes=2)``: the variants are compiled in other
    processes, which write numba's cache (this one only loads them: hits, no
    misses), and a run with them gives the same numbers as this test process's own run
    (its kernels compiled elsewhere, from the same sources)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), SWEEP_NUMBA_CACHE="1",
               NUMBA_DISABLE_JIT="0")  # fmt: skip
    side_by_side = json.loads(python_stdout(SIDE_BY_SIDE, env=env).splitlines()[-1])
    assert side_by_side["hits"] == [1, 1] and side_by_side["misses"] == [0, 0]
    here = sweep.run(sweep.with_changes("quick", SIDE_BY_SIDE_CONFIGS[1]), progress=False)
    assert side_by_side["n_steps"] == here["n_steps"].values.tolist()
    np.testing.assert_array_equal(side_by_side["period"], here["period"].values)


def test_processes_share_variant_groups_each_compiled_once(tmp_path, monkeypatch):
    """The variants that differ only in the tangent or the state size form one group
    (they call the same helpers specialised on their codes). A process takes a group no
    other has started, its variants one at a time, and when none is left to start,
    helps with the variants left in the others': every variant compiled once."""
    from sweep.engine import dispatch
    from sweep.engine.grid import build_grid

    grids = [
        build_grid(sweep.with_changes("quick", change))
        for change in (
            {},
            {"blocks": 2, "parameters": {"k2_W": 0.5}},
            {"integrator": {"method": "dopri5"}},
        )
    ]
    jobs = [(g.params, g.settings, tangent) for g in grids for tangent in (False, True)]
    groups = dispatch.variant_groups(jobs)
    assert [len(group) for group in groups] == [4, 2]  # DOP853: 1 and 2 blocks; DOPRI5
    codes = [{dispatch.variant(*job)[:5] for job in group} for group in groups]
    assert all(len(c) == 1 for c in codes) and codes[0] != codes[1]
    spec = dispatch.compile_spec(groups, tmp_path)
    compiled = []
    monkeypatch.setattr(dispatch, "ready_kernel", lambda p, s, t: compiled.append((s, t)))
    for name in ("0", "0-0"):  # another process started group 0 and took its first
        os.close(os.open(tmp_path / name, os.O_CREAT | os.O_EXCL))
    dispatch.compile_specs(spec)
    expected = [*groups[1], *groups[0][1:]]
    assert [(s.tolist(), t) for s, t in compiled] == [(s.tolist(), t) for _, s, t in expected]
    compiled.clear()
    dispatch.compile_specs(spec)  # all claimed: nothing left
    assert compiled == []


ORPHANED_COMPILE = """
import os, subprocess, sys
import sweep
from sweep.engine import dispatch
from sweep.engine.grid import build_grid
g = build_grid(sweep.with_changes("quick", {}))
spec = dispatch.compile_spec([[(g.params, g.settings, False)]], sys.argv[1])
code = "import sys; from sweep.engine.dispatch import compile_specs; compile_specs(sys.argv[1])"
with open(sys.argv[2], "w") as out:
    child = subprocess.Popen([sys.executable, "-c", code + "; print('done')", spec], stdout=out)
print(child.pid, flush=True)
os._exit(0)  # killed, as it were, while its compile process starts
"""


def test_a_compile_process_whose_parent_died_takes_no_variant(tmp_path):
    """A process of :func:`sweep.engine.dispatch.load_kernels` whose parent was killed (a test
    run, a notebook, ``make test``) has no one to compile for: it claims no variant and
    ends, instead of compiling the rest of the list on its own."""
    claims, out = tmp_path / "claims", tmp_path / "child.out"
    claims.mkdir()
    child = int(python_stdout(ORPHANED_COMPILE, str(claims), str(out)))  # its parent has ended
    try:
        deadline = time.monotonic() + SUBPROCESS_TIMEOUT
        while "done" not in out.read_text() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert out.read_text().split() == ["done"]
        assert list(claims.iterdir()) == []
    finally:  # an orphan that hangs is not left running after the test
        with contextlib.suppress(ProcessLookupError):
            os.kill(child, signal.SIGKILL)


@pytest.mark.parametrize("processes", [0, -1, 1.5, True, "2"])
def test_compile_kernels_rejects_a_bad_process_count(processes):
    with pytest.raises(InputError, match="processes must be a positive integer"):
        sweep.compile_kernels("quick", processes=processes)


@pytest.mark.slow
def test_a_sweep_whose_runs_all_settle_never_compiles_the_tangent():
    """The tangent for λ1 is compiled only when a run needs it: a sweep whose runs all
    settle by t_end builds one kernel (issue 24: nothing compiled that the config does
    not use)."""
    code = (
        "import sweep; from sweep.kernels import integrate\n"
        "ds = sweep.run(sweep.with_changes('quick', {'sweep': {'K_W': [0.03, 0.07]}}),"
        " progress=False)\n"
        "print(integrate.grid_kernel.cache_info().currsize, *ds['regime'].values.ravel())"
    )
    count, *regimes = python_stdout(code).split()
    assert count == "1" and len(regimes) == 2


def test_run_refines_by_keyword(quick_result):
    """refine=: levels, a mapping merged into the config's section, True (the config's or
    the defaults), False (the grid only); anything else is refused naming the config."""
    ds = sweep.run(QUICK, refine=2, threads=1, progress=False)
    assert ds["regime"].dims == ("point",) and ds.attrs["refine_levels"] == 2
    grid = sweep.to_grid(ds, 0).drop_vars(["level", "exact"])
    for name, var in quick_result.data_vars.items():
        assert grid[name].values.tobytes() == var.values.tobytes(), name
    config = sweep.with_changes(QUICK, {"refine": {"levels": 3, "max_runs": 12}})
    merged = sweep.run(config, refine={"levels": 1}, threads=1, progress=False)
    assert (merged.attrs["refine_levels"], merged.attrs["refine_max_runs"]) == (1, 12)
    assert sweep.run(config, refine=True, progress=False).attrs["refine_levels"] == 3
    plain = sweep.run(config, refine=False, threads=1, progress=False)
    xr.testing.assert_identical(without_file_attrs(plain), without_file_attrs(quick_result))
    with pytest.raises(sweep.InputError, match=r"quick.yaml: refine must be a number of levels"):
        sweep.run(QUICK, refine="deep", progress=False)
    with pytest.raises(sweep.ConfigError, match=r"refine.levels must be an integer in \[0, 20\]"):
        sweep.run(QUICK, refine=40, progress=False)
    assert [b.between for b in sweep.boundaries(ds)]  # the lazy names resolve to functions
