"""End to end: ``python -m sweep run`` in a subprocess, the file it writes read back
by plain xarray, and the pure-Python path of the kernels (NUMBA_DISABLE_JIT=1)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import KC_W, SUBPROCESS_TIMEOUT, make_config, write_config

from sweep import cli
from sweep.engine import runner
from sweep.model.physics import PARAMETERS
from sweep.variables import FLAGS, REGIMES, variables_for

ROOT = Path(__file__).resolve().parent.parent
QUICK = ROOT / "configs" / "quick.yaml"

# Reads a result file with xarray alone and prints its schema as JSON; it must not
# import the sweep package (the file has to stand on its own).
READER = r"""
import json, sys
import xarray as xr
ds = xr.open_dataset(sys.argv[1])
def plain(v):
    return v.tolist() if hasattr(v, "tolist") else v
out = {
    "dims": dict(ds.sizes),
    "coords": {n: {"dims": list(c.dims), **{k: plain(v) for k, v in c.attrs.items()}}
               for n, c in ds.coords.items()},
    "vars": {n: {"dims": list(v.dims), "dtype": str(v.dtype),
                 **{k: plain(a) for k, a in v.attrs.items()}} for n, v in ds.data_vars.items()},
    "attrs": {k: plain(v) for k, v in ds.attrs.items()},
    "scalars": {n: c.item() for n, c in ds.coords.items() if c.ndim == 0},
    "regime": ds["regime"].values.tolist(),
    "sweep_imported": "sweep" in sys.modules,
}
print(json.dumps(out))
"""


def run(args, cwd, env=None, check=False):
    proc = subprocess.run(
        [sys.executable, *args], cwd=cwd, capture_output=True, text=True,
        timeout=SUBPROCESS_TIMEOUT, env={**os.environ, **(env or {})},
    )  # fmt: skip
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``python -m sweep run configs/quick.yaml --out tmp/x.nc`` in a fresh directory."""
    cwd = tmp_path_factory.mktemp("cli")
    proc = run(["-m", "sweep", "run", str(QUICK), "--out", "tmp/x.nc"], cwd)
    return cwd, proc


@pytest.mark.slow
def test_run_prints_regimes_and_path(quick_run):
    cwd, proc = quick_run
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [line.split()[0] for line in lines[:-1]] == list(REGIMES)
    assert lines[-1].startswith("wrote tmp/x.nc (9 runs")
    counts = [int(line.split()[1]) for line in lines[:-1]]
    assert sum(counts) == 9
    assert (cwd / "tmp" / "x.nc").is_file()


@pytest.fixture(scope="module")
def schema(quick_run):
    cwd, _ = quick_run
    proc = run(["-c", READER, "tmp/x.nc"], cwd, check=True)
    return json.loads(proc.stdout)


@pytest.mark.slow
def test_file_opens_without_the_package(schema):
    assert schema["sweep_imported"] is False
    assert schema["dims"] == {"K_W": 9, "block": 1, "event": 32}


def test_file_schema(schema):
    coord = schema["coords"]["K_W"]
    assert coord["dims"] == ["K_W"]
    assert coord["units"] == PARAMETERS["K_W"].units == "um-1"
    assert coord["long_name"] == PARAMETERS["K_W"].long_name
    table = {v.name: v for v in variables_for(1, features=("events",))}
    assert set(schema["vars"]) == set(table)
    for name, var in table.items():
        got = schema["vars"][name]
        assert got["dims"] == ["K_W"] + ["block"] * var.per_block + ["event"] * var.per_event
        assert got["dtype"] == var.dtype, name
        assert got["long_name"] == var.long_name, name
        if name not in FLAGS:  # flags: flag_values, no units
            assert got["units"] == var.units, name
    regime = schema["vars"]["regime"]
    assert regime["dtype"] == "int8"
    assert regime["flag_values"] == [0, 1, 2, 3]
    assert regime["flag_meanings"] == " ".join(REGIMES)
    for name in ("lnv_amplitude", "v_max", "v_min", "period", "growth_rate", "friction_drop",
                 "t_runaway", "linear_growth_rate"):  # fmt: skip
        assert name in schema["vars"]
    attrs = schema["attrs"]
    coords = schema["coords"]
    for name, units in (("A", "1"), ("B", "1"), ("mu0", "1"), ("V", "um s-1"), ("Phi0", "s"),
                        ("D0", "um")):  # fmt: skip
        assert coords[name]["dims"] == [] and coords[name]["units"] == units
    assert schema["scalars"]["V"] == 0.1 and schema["scalars"]["D0"] == 1.0
    for key in ("integrator_method", "integrator_rtol", "integrator_atol", "integrator_t_end",
                "package_version", "numba_version", "created"):  # fmt: skip
        assert key in attrs
    assert attrs["config_text"] == QUICK.read_text()


def test_quick_regimes_match_theory(schema):
    """quick.yaml sweeps K/W = 0.040 … 0.060 µm⁻¹ across Kc/W = 0.05: below, runaway
    (no limit cycle, physics brief section 4); above, steady."""
    k_w = np.linspace(0.040, 0.060, 9)
    regime = np.array(schema["regime"])
    assert np.all(regime[k_w < KC_W - 1e-12] == REGIMES.index("runaway"))
    assert np.all(regime[k_w > KC_W + 1e-12] == REGIMES.index("steady"))


@pytest.mark.slow
def test_bad_config_subprocess_exit_status(tmp_path):
    path = write_config(tmp_path / "bad.yaml", {"parameters": {"A": -0.01}})
    proc = run(["-m", "sweep", "run", str(path)], tmp_path)
    assert proc.returncode == 2
    assert f"{path}: parameters.A must be in (0, inf), got -0.01" in proc.stderr
    assert proc.stdout == ""


@pytest.mark.parametrize(
    "option", [["--threads", "0"], ["--chunk-size", "0"], ["--bogus"], ["--out", ""]]
)
def test_bad_arguments_exit_2(option, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["run", str(QUICK), *option])
    assert info.value.code == 2


def test_an_empty_out_is_refused_not_replaced_by_the_default(capsys):
    """``--out ""`` used to write the config's default output instead."""
    with pytest.raises(SystemExit):
        cli.main(["run", str(QUICK), "--out", ""])
    assert "argument --out: must be a path, got an empty string" in capsys.readouterr().err


def test_extend_of_a_config_says_it_reads_results(capsys):
    assert cli.main(["extend", str(QUICK)]) == 2
    err = capsys.readouterr().err
    assert f"{QUICK}: extend reads a result file (.nc" in err
    assert "must be a file name" not in err  # it used to blame an --out never given


def test_main_leaves_the_sweep_logger_as_it_found_it(tmp_path, capsys):
    """The CLI logs to the stderr of the command it runs and removes its handler after:
    a notebook or a later test calling ``main`` again sees no handler it left behind,
    bound to an earlier stderr (a handler used to stay on the ``sweep`` logger)."""
    import logging

    logger = logging.getLogger("sweep")
    before = (list(logger.handlers), logger.level)
    out = tmp_path / "q.nc"
    assert cli.main(["run", str(QUICK), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert (list(logger.handlers), logger.level) == before
    assert cli.main(["extend", str(QUICK)]) == 2  # an error too restores them
    assert (list(logger.handlers), logger.level) == before


def test_out_of_memory_is_an_error_message_not_a_traceback(monkeypatch, capsys):
    """A grid too large for memory (numpy's MemoryError) ends with a message and exit 1."""

    def too_large(args):
        raise MemoryError("Unable to allocate 74.5 GiB for an array with shape (10000000000,)")

    monkeypatch.setitem(cli.COMMANDS, "run", too_large)
    assert cli.main(["run", str(QUICK)]) == 1
    err = capsys.readouterr().err
    assert (
        err.startswith("error: not enough memory: Unable to allocate 74.5 GiB")
        and "Trace" not in err
    )


@pytest.mark.slow
def test_python_m_sweep_cli_runs_the_command_line(tmp_path):
    proc = run(["-m", "sweep.cli", "run", str(tmp_path / "missing.yaml")], tmp_path)
    assert proc.returncode == 2 and "cannot read config" in proc.stderr


def test_compile_loads_every_configs_kernels(tmp_path, capsys):
    """``compile CONFIG...`` (warming numba's cache before job arrays) builds, in this
    process, the kernel of each config's variant and the one with the tangent where
    its unsettled runs ask for λ1; a bad config is refused with every problem and exit 2,
    before anything is compiled."""
    from sweep.config import load_config
    from sweep.engine.dispatch import grid_kernel
    from sweep.engine.grid import build_grid

    path = write_config(tmp_path / "damped.yaml", {"model": "quasi-dynamic",
                                                    "parameters": {"eta_W": 0.01}})  # fmt: skip
    assert cli.main(["compile", str(QUICK), str(path)]) == 0
    assert "the kernels of 2 config(s)" in capsys.readouterr().out
    for config in (load_config(QUICK), load_config(path)):
        g = build_grid(config)
        for tangent in (False, True):
            assert grid_kernel(g.params, g.settings, tangent).signatures, (config, tangent)
    bad = write_config(tmp_path / "bad.yaml", {"parameters": {"A": -0.01}})
    assert cli.main(["compile", str(QUICK), str(bad)]) == 2
    assert f"{bad}: parameters.A must be in (0, inf), got -0.01" in capsys.readouterr().err


#: Two stiffnesses either side of Kc, short runs: runaway at 0.8 Kc, steady at 1.2 Kc.
TINY = {"sweep": {"K_W": [0.8 * KC_W, 1.2 * KC_W]}, "integrator": {"t_end": 150.0}}


@pytest.mark.slow
def test_pure_python_kernels(tmp_path):
    """NUMBA_DISABLE_JIT=1 runs the kernels as plain Python: same regimes as the JIT.
    Numbers agree to 1e-6 relative: numpy's and LLVM's exp may differ in the last bit,
    the adaptive steps carry that along, and a value taken at a step end inside a fast
    slip (lnv_max of the runaway run, where ℓ' ~ 1e4) magnifies it (seen: 5e-9)."""
    path = write_config(tmp_path / "tiny.yaml", TINY)
    run(["-m", "sweep", "run", str(path), "--out", "nojit.nc", "--quiet"], tmp_path,
        env={"NUMBA_DISABLE_JIT": "1"}, check=True)  # fmt: skip
    jit = runner.compute(make_config(TINY), show_progress=False)
    with xr.open_dataset(tmp_path / "nojit.nc") as nojit:
        np.testing.assert_array_equal(nojit["regime"], jit["regime"])
        assert list(jit["regime"].values) == [REGIMES.index("runaway"), REGIMES.index("steady")]
        for name in ("t_final", "lnv_max", "lnv_min", "t_runaway", "period"):
            np.testing.assert_allclose(nojit[name], jit[name], rtol=1e-6, err_msg=name)


@pytest.mark.slow
def test_run_refine_and_max_runs_options(tmp_path, capsys):
    """--refine LEVELS refines a grid config, --max-runs caps it; the summary gives the
    runs per level, and plot draws the refined file."""
    out = tmp_path / "r.nc"
    args = ["run", str(QUICK), "--out", str(out), "--quiet", "--refine", "4", "--max-runs", "14"]
    assert cli.main(args) == 0
    printed = capsys.readouterr().out
    assert (
        "refined 3 levels (the next level would pass refine.max_runs): runs per level "
        "9, 2, 2, 1" in printed
    ), printed
    with xr.open_dataset(out) as ds:
        assert ds.sizes["point"] == 14 and ds.attrs["refine_max_runs"] == 14
    assert cli.main(["plot", str(out)]) == 0
    assert out.with_suffix(".png").stat().st_size > 0
    assert cli.main(["plot", str(out), "--var", "t_final"]) == 0


def test_max_runs_needs_a_refinement(capsys):
    assert cli.main(["run", str(QUICK), "--max-runs", "20", "--quiet"]) == 2
    assert "--max-runs needs --refine or a refine section" in capsys.readouterr().err
