"""The result Dataset: schema from ``sweep/variables.py``, units, derived fields, and
atomic NetCDF writing."""

import math
import os

import numpy as np
import pytest
import xarray as xr
from conftest import KC_W, PAPER_A, PAPER_B, make_config, run_grid

from sweep.engine import runner
from sweep.errors import ConfigError, InputError, RunError
from sweep.io.netcdf import write_netcdf
from sweep.kernels import layout
from sweep.model.physics import PARAMETERS
from sweep.results.dataset import stored_config
from sweep.variables import BY_NAME, FLAGS, REGIMES, VARIABLES, variables_for

A, B = PAPER_A, PAPER_B
#: The flag variables: CF flag_values/flag_meanings instead of units.
ONE_BLOCK = {"sweep": {"K_W": (KC_W * np.array([0.8, 0.95, 1.0, 1.1])).tolist()}}
TWO_BLOCKS = {
    "blocks": 2,
    "sweep": {"K_W": [0.045, 0.055], "k2_W": [0.0, 0.05, 0.5]},
    "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
}


@pytest.fixture(scope="module", params=[1, 2], ids=["one block", "two blocks"])
def result(request):
    config = make_config(ONE_BLOCK if request.param == 1 else TWO_BLOCKS)
    return config, runner.compute(config, show_progress=False)


def test_variables_follow_the_table(result):
    config, ds = result
    dims = tuple(a.name for a in config.axes)
    expected = {v.name for v in variables_for(config.blocks, config.model, config.features)}
    assert set(ds.data_vars) == expected
    assert ("sync_error" in ds) == (config.blocks >= 2)
    for name in expected:
        var, da = BY_NAME[name], ds[name]
        trailing = ("block",) * var.per_block + ("event",) * var.per_event
        assert da.dims == dims + trailing, name
        assert da.dtype == np.dtype(var.dtype), name
        assert da.attrs["long_name"] == var.long_name
        if name not in FLAGS:  # a flag variable has flag_values instead of units
            assert da.attrs["units"] == var.units, name


def test_inertial_results_store_the_inertial_force():
    """The inertial model's state has a third variable per block, z = (m/W) dv/dt; the
    file stores it beside lnv_final and ln_state_final, so a run can be restarted."""
    config = make_config(
        model="inertial", parameters={"m_W": 1.0}, sweep={"K_W": [0.06, 0.08]},
        integrator={"method": "rosenbrock", "t_end": 100.0},
    )  # fmt: skip
    ds = runner.compute(config, show_progress=False)
    _, y_final = run_grid(config)
    assert set(ds.data_vars) == {v.name for v in variables_for(1, "inertial", config.features)}
    assert ds["inertial_force_final"].dims == ("K_W", "block")
    assert ds["inertial_force_final"].attrs["units"] == "1"
    np.testing.assert_array_equal(ds["inertial_force_final"].values, y_final[:, 2:3])
    assert "inertial_force_final" not in {v.name for v in variables_for(1, "quasi-dynamic")}


def test_table_is_complete():
    """Every variable the brief's issue names is declared, with units."""
    for name in (
        "regime", "lnv_amplitude", "v_max", "v_min", "period", "growth_rate",
        "friction_drop", "t_runaway", "linear_growth_rate", "sync_error",
    ):  # fmt: skip
        assert name in BY_NAME and BY_NAME[name].units
    assert len(BY_NAME) == len(VARIABLES)  # names are unique


def test_regime_flags_and_axes(result):
    config, ds = result
    regime = ds["regime"]
    np.testing.assert_array_equal(regime.attrs["flag_values"], np.arange(4, dtype=np.int8))
    assert regime.attrs["flag_meanings"].split() == list(REGIMES)
    assert [REGIMES[c] for c in (layout.STEADY, layout.STICK_SLIP, layout.RUNAWAY,
                                 layout.UNDECIDED)] == ["steady", "stick_slip", "runaway",
                                                         "undecided"]  # fmt: skip
    for axis in config.axes:
        coord = ds[axis.name]
        np.testing.assert_array_equal(coord.values, axis.values)
        assert coord.attrs["units"] == PARAMETERS[axis.name].units
        assert coord.attrs["long_name"] == PARAMETERS[axis.name].long_name


def test_provenance_attributes(result):
    config, ds = result
    attrs = ds.attrs
    for name, value in config.parameters:  # scalar coordinates, so results combine along them
        assert ds[name].ndim == 0 and float(ds[name]) == value
        assert ds[name].attrs["units"] == PARAMETERS[name].units
        assert ds[name].attrs["long_name"] == PARAMETERS[name].long_name
        assert name not in attrs  # a global attribute would be wrong once combined
    for key in ("method", "rtol", "atol", "dt", "max_step", "t_end", "t_unit", "max_steps"):
        assert attrs[f"integrator_{key}"] == getattr(config.integrator, key)
    assert attrs["config_text"] == config.text
    for key in ("package_version", "numba_version", "created", "Conventions"):
        assert attrs[key]


def test_each_kernel_column_is_declared_once():
    """A variable read from one column of the kernels' results names it in its
    declaration (``variables.py``): the column exists, no two variables read the same
    one, every conversion is known, and the column no variable reads is the kernels'
    bookkeeping (the count of recorded points)."""
    from sweep.variables import SCALES, VARIABLES

    columns = [v.column for v in VARIABLES if v.column]
    assert len(columns) == len(set(columns))
    kernel_columns = {name for name in vars(layout) if name.startswith("R_")}
    assert set(columns) <= kernel_columns
    assert kernel_columns - set(columns) == {"R_N_RECORDED"}
    assert {v.scale for v in VARIABLES} <= set(SCALES)
    assert sorted(getattr(layout, name) for name in kernel_columns) == list(range(layout.N_RESULTS))


def test_derived_fields_in_physical_units():
    """Kernel numbers (units of D0/V) → seconds and µm/s with D0/V = 10 s, V = 0.1 µm/s;
    analytic fields from the brief's closed forms."""
    config = make_config(ONE_BLOCK)
    results, y_final = run_grid(config)
    ds = runner.compute(config, show_progress=False)
    t_unit, V = 10.0, 0.1
    k_w = np.asarray(config.axes[0].values)
    np.testing.assert_allclose(ds["period"], results[:, layout.R_PERIOD] * t_unit, rtol=1e-15)
    np.testing.assert_allclose(ds["t_runaway"], results[:, layout.R_TAU_RUNAWAY] * t_unit)
    np.testing.assert_allclose(ds["growth_rate"], results[:, layout.R_GROWTH] / t_unit)
    np.testing.assert_allclose(ds["v_max"], V * np.exp(results[:, layout.R_LNV_MAX]))
    np.testing.assert_allclose(
        ds["lnv_amplitude"], results[:, layout.R_LNV_MAX] - results[:, layout.R_LNV_MIN]
    )
    np.testing.assert_array_equal(ds["lnv_final"].values[:, 0], y_final[:, 0])
    np.testing.assert_array_equal(ds["ln_state_final"].values[:, 0], y_final[:, 1])
    np.testing.assert_allclose(ds["critical_K_W"], (B - A) / 1.0)
    np.testing.assert_allclose(ds["K_over_Kc"], k_w / KC_W)
    # Re λ = (B − A − κ)/(2A) per D0/V while the pair is complex (all four points)
    np.testing.assert_allclose(
        ds["linear_growth_rate"], (B - A - k_w) / (2 * A) / t_unit, rtol=1e-12, atol=1e-15
    )
    np.testing.assert_allclose(ds["onset_period"], 2 * math.pi / math.sqrt((B - A) / A) * t_unit)
    stick_slip = ds["regime"].values == layout.STICK_SLIP
    assert stick_slip.any()
    np.testing.assert_allclose(
        ds["slip_per_event"].values[stick_slip], V * ds["period"][stick_slip]
    )
    assert np.isnan(ds["slip_per_event"].values[~stick_slip]).all()


def test_stored_config_errors_say_whether_the_config_or_the_file_is_at_fault(result):
    config, ds = result
    assert stored_config(ds, "x.nc").axes == config.axes
    cut = ds.isel({config.axes[0].name: slice(1, None)})  # a grid the config does not make
    with pytest.raises(InputError, match="x.nc: regime has dims") as err:
        stored_config(cut, "x.nc")
    assert not isinstance(err.value, ConfigError)
    bad = ds.assign_attrs(config_text=ds.attrs["config_text"].replace("blocks: ", "blocks: -"))
    with pytest.raises(ConfigError, match="x.nc: stored config_text: blocks must be"):
        stored_config(bad, "x.nc")


def test_netcdf_round_trip(in_tmp, result):
    _, ds = result
    path = write_netcdf(ds, in_tmp / "out" / "r.nc")
    with xr.open_dataset(path) as back:
        for name in ds.data_vars:
            a, b = ds[name].values, back[name].values
            assert b.dtype == a.dtype, name
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
            assert back[name].attrs.get("units") == ds[name].attrs.get("units")
        np.testing.assert_array_equal(back["regime"].attrs["flag_values"], np.arange(4))
        assert back.attrs["config_text"] == ds.attrs["config_text"]
    assert sorted(os.listdir(in_tmp / "out")) == ["r.nc"]  # no temporary file left


def failing_to_netcdf(self, path, *args, **kwargs):
    """Stand-in for Dataset.to_netcdf that writes a partial file, then fails."""
    with open(path, "wb") as f:
        f.write(b"partial")
    raise OSError(28, "No space left on device")


def test_failed_write_keeps_earlier_result(in_tmp, result, monkeypatch):
    _, ds = result
    target = in_tmp / "r.nc"
    target.write_bytes(b"earlier result")
    monkeypatch.setattr(xr.Dataset, "to_netcdf", failing_to_netcdf)
    with pytest.raises(OSError, match="No space left"):
        write_netcdf(ds, target)
    assert target.read_bytes() == b"earlier result"
    assert sorted(os.listdir(in_tmp)) == ["r.nc"]


def test_failed_sweep_write_keeps_earlier_result(in_tmp, monkeypatch):
    """The same through ``run_sweep``: its writability probe leaves nothing behind, and
    the finished chunks stay as parts so that ``--resume`` can finish the job."""
    config = make_config(ONE_BLOCK, output="res/r.nc")
    (in_tmp / "res").mkdir()
    (in_tmp / "res" / "r.nc").write_bytes(b"earlier result")
    monkeypatch.setattr(xr.Dataset, "to_netcdf", failing_to_netcdf)
    with pytest.raises(RunError, match="No space left"):
        runner.run_sweep(config, show_progress=False)
    assert (in_tmp / "res" / "r.nc").read_bytes() == b"earlier result"
    assert sorted(os.listdir(in_tmp / "res")) == ["r.nc", "r.parts"]


def test_interrupted_write_keeps_earlier_result(in_tmp, result, monkeypatch):
    """Ctrl-C while writing: the temporary file goes too."""
    _, ds = result
    target = in_tmp / "r.nc"
    target.write_bytes(b"earlier result")

    def interrupted(self, path, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(xr.Dataset, "to_netcdf", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_netcdf(ds, target)
    assert target.read_bytes() == b"earlier result"
    assert sorted(os.listdir(in_tmp)) == ["r.nc"]


def test_docs_table_matches_the_schema():
    """The output-variable table of the docs' outputs page lists exactly the declared
    variables, with their units."""
    import re
    from pathlib import Path

    page = Path(__file__).resolve().parents[1] / "docs" / "guide" / "outputs.md"
    text = page.read_text()
    start = text.index("| name | units | meaning |")
    section = text[start:].split("\n\n", 1)[0]
    pretty = {"–": None, "1": "1", "s": "s", "µm": "um", "s⁻¹": "s-1", "µm s⁻¹": "um s-1",
              "µm⁻¹": "um-1", "N m": "N m", "rad": "rad"}  # fmt: skip
    documented = {}
    for row in section.splitlines()[2:]:
        names, units = (cell.strip() for cell in row.strip("|").split("|")[:2])
        for name in re.findall(r"`(\w+)`", names):
            documented[name] = pretty[units]
    declared = {v.name: (None if v.name in FLAGS else v.units) for v in VARIABLES}
    assert documented == declared


def cf_report(path, tmp_path):
    """The IOOS compliance checker's CF-1.11 report on ``path`` (JSON as a dict)."""
    import json

    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    out = tmp_path / f"{os.path.basename(path)}.cf.json"
    ComplianceChecker.run_checker(
        str(path), ["cf:1.11"], verbose=0, criteria="strict", output_filename=str(out),
        output_format="json",
    )  # fmt: skip
    return json.loads(out.read_text())["cf:1.11"]


#: CF checks a trace file fails on purpose, both for one reason: CF wants the units of
#: a time coordinate (standard_name time, axis T) as "<unit> since <epoch>", but a
#: trace's time is elapsed model time in s; with an invented epoch xarray would decode
#: it to calendar dates.
TRACE_CF_EXCEPTIONS = {"§3.1 Units", "§4.4 Time Coordinate"}


@pytest.mark.slow
def test_result_and_trace_files_pass_the_cf_checker(result, tmp_path):
    """Every CF-1.11 check of the IOOS compliance checker passes, warnings included
    (criteria strict): no _FillValue on coordinates, 32-bit counts, references. Traces:
    all but :data:`TRACE_CF_EXCEPTIONS`. compliance-checker is a test dependency."""
    from sweep.commands.trace import compute_trace, pin_config

    config, ds = result
    trace = compute_trace(pin_config(config, {a.name: a.values[0] for a in config.axes}, 50.0))
    for data, allowed in ((ds, set()), (trace, TRACE_CF_EXCEPTIONS)):
        path = write_netcdf(data, tmp_path / f"{data.attrs['title'].split()[-2]}.nc")
        report = cf_report(path, tmp_path)
        failed = {
            check["name"]: check["msgs"]
            for check in report["all_priorities"]
            if check["value"][0] < check["value"][1]
        }
        assert set(failed) == allowed, failed


@pytest.mark.slow
def test_plain_to_netcdf_of_a_run_passes_the_cf_checker(tmp_path):
    """What users type: ``sweep.run(...).to_netcdf(path)`` without write_netcdf's
    encoding writes no _FillValue on coordinates, so the file passes every CF check
    (and so does a trace's, but for its elapsed-time axis)."""
    import sweep
    from sweep.commands.trace import compute_trace, pin_config

    config = make_config(TWO_BLOCKS)
    ds = sweep.run(config, progress=False)
    trace = compute_trace(pin_config(config, {a.name: a.values[0] for a in config.axes}, 50.0))
    for data, allowed in ((ds, set()), (trace, TRACE_CF_EXCEPTIONS)):
        path = tmp_path / f"{data.attrs['title'].split()[-2]}.nc"
        data.to_netcdf(path)
        failed = {
            check["name"]
            for check in cf_report(path, tmp_path)["all_priorities"]
            if check["value"][0] < check["value"][1]
        }
        assert failed == allowed


def test_cf_attributes(result, tmp_path):
    """What the checker cannot judge: the conventions named, the seed paper cited, no
    misused ``institution``, counts 32-bit and coordinates without _FillValue in the file."""
    _, ds = result
    assert ds.attrs["Conventions"] == "CF-1.11"
    assert "Szkutnik" in ds.attrs["references"] and "Kułakowski" in ds.attrs["references"]
    assert "institution" not in ds.attrs
    path = write_netcdf(ds, tmp_path / "r.nc")
    with xr.open_dataset(path, decode_cf=False) as raw:
        for name in raw.coords:
            assert "_FillValue" not in raw[name].attrs, name
        for name in ("n_steps", "n_rejected", "n_peaks", "block"):
            assert raw[name].dtype == np.int32, name
