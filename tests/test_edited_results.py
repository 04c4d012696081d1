"""Results that were edited, cut or are not results at all, and odd arguments of the
commands and functions that read them: each stops with a message that names the file
or argument and what is wrong, never a traceback or a wrong answer."""

import numpy as np
import pytest
import xarray as xr

import sweep
from sweep import cli
from sweep.commands.trace import compute_trace
from sweep.config import load_config, with_changes
from sweep.engine.runner import run_sweep


@pytest.fixture(scope="module")
def undecided_file(quick, tmp_path_factory):
    """A quick sweep stopped early enough that a run is still undecided (extend's work)."""
    config = with_changes(quick, {"integrator": {"t_end": 100},
                                  "classification": {"max_t_end": 100}})  # fmt: skip
    path = tmp_path_factory.mktemp("edited") / "u.nc"
    run_sweep(config, out=path, show_progress=False)
    return path


def edited(path, tmp_path, name, change):
    """A copy of the result at ``path`` with ``change(ds)`` applied, written to ``name``."""
    ds = change(xr.load_dataset(path))
    out = tmp_path / name
    ds.to_netcdf(out)
    return out


@pytest.mark.parametrize(
    "name, change, says",
    [
        ("sorted.nc", lambda ds: ds.sortby("K_W", ascending=False), "the file's K_W differ"),
        ("cut.nc", lambda ds: ds.isel(K_W=slice(0, 3)), "regime has dims"),
        ("other_A.nc", lambda ds: ds.assign_attrs(
            config_text=ds.attrs["config_text"].replace("A: 0.03", "A: 0.05")),
         "the file's A differ"),
    ],
    ids=["sorted", "cut", "config edited"],
)  # fmt: skip
def test_extend_and_audit_refuse_a_file_whose_runs_no_longer_match_its_config(
    undecided_file, tmp_path, capsys, name, change, says
):
    """A result sorted, cut or with its stored config edited after the run: its rows are
    no longer the runs of its config. extend and audit used to continue or rerun other
    parameters' runs and report them as the file's (a silently wrong answer)."""
    path = edited(undecided_file, tmp_path, name, change)
    before = path.read_bytes()
    for command in (["extend", str(path)], ["audit", str(path), "--sample", "2"]):
        assert cli.main(command) == 2, command
        err = capsys.readouterr().err
        assert f"{path}" in err and says in err, err
    assert path.read_bytes() == before


def without_blocks(ds):
    """``ds`` without its ``blocks`` attribute."""
    ds.attrs.pop("blocks")
    return ds


@pytest.mark.parametrize(
    "change, says",
    [
        (lambda ds: ds.drop_vars("t_final"), "no t_final"),
        (lambda ds: ds.drop_vars("critical_K_W"), "no critical_K_W"),
        (without_blocks, "no blocks attribute"),
    ],
    ids=["variable", "Kc", "attribute"],
)
def test_an_incomplete_result_is_named_as_such(undecided_file, tmp_path, capsys, change, says):
    """A result missing a variable or attribute its run writes is refused with what is
    missing (plot, extend and bifurcation raised KeyError from deep inside)."""
    path = edited(undecided_file, tmp_path, "incomplete.nc", change)
    for command in (["plot", str(path), "--out", str(tmp_path / "p.png")],
                    ["extend", str(path), "--out", str(tmp_path / "e.nc")],
                    ["bifurcation", str(path), "--out", str(tmp_path / "b.png")]):  # fmt: skip
        assert cli.main(command) == 2, command
        err = capsys.readouterr().err
        assert f"{path}: not a complete sweep result: {says}" in err, err


def test_a_file_that_is_not_netcdf_is_one_line(tmp_path, capsys):
    path = tmp_path / "config.nc"
    path.write_text("blocks: 1\n")
    assert cli.main(["plot", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"error: {path}: cannot read result file: not a NetCDF file (a result is "
                   "the NetCDF file or Zarr store of rsf-sweep run)")  # fmt: skip


def test_bifurcation_of_one_run_and_of_one_dataset(quick_reference_file, tmp_path, capsys):
    """A single run has no axis to draw along (it raised IndexError); one Dataset or a
    generator of them is drawn like a list."""
    one = edited(quick_reference_file, tmp_path, "one.nc", lambda ds: ds.isel(K_W=[0]))
    assert cli.main(["bifurcation", str(one), "--out", str(tmp_path / "b.png")]) == 2
    assert "needs a sweep axis with more than one value" in capsys.readouterr().err
    ds = xr.load_dataset(quick_reference_file)
    for datasets in (ds, (d for d in [ds])):
        panels = [a.get_title()[:3] for a in sweep.plot_bifurcation(datasets).axes]
        assert [t for t in panels if t in ("(a)", "(b)")] == ["(a)", "(b)"]  # and runaway strips


@pytest.mark.parametrize(
    "argv, says",
    [
        (["audit", "r.nc", "--seed", "-5"], "--seed: must be in [0, 2147483647], got -5"),
        (["plot", "r.nc", "--catalogue", "K_W=nan"], "with a finite number"),
        (["trace", "quick", "--at", "K_W=inf"], "with a finite number"),
        (["trace", "quick", "--points", "100000000000"], "--points: must be in [1, 10000000]"),
    ],
    ids=["negative seed", "nan axis value", "inf --at", "points"],
)
def test_bad_numbers_in_arguments_exit_2(argv, says, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2 and says in capsys.readouterr().err


def test_audit_must_run_longer_than_the_file(quick_reference_file, capsys):
    assert cli.main(["audit", str(quick_reference_file), "--t-end", "1", "--sample", "2"]) == 2
    assert "--t-end must be finite and later than the file's t_end, 2000 D0/V" in (
        capsys.readouterr().err
    )


def test_plot_arguments_that_name_nothing(quick_reference_file, tmp_path, capsys):
    """``--var ""`` used to draw the phase diagram; a repeated --catalogue axis used the
    last value."""
    out = str(tmp_path / "p.png")
    assert cli.main(["plot", str(quick_reference_file), "--var", "", "--out", out]) == 2
    assert "no variable '' to plot" in capsys.readouterr().err
    argv = ["plot", str(quick_reference_file), "--catalogue", "K_W=0.04", "K_W=0.05"]
    assert cli.main([*argv, "--out", out]) == 2
    assert "--catalogue gives K_W more than once" in capsys.readouterr().err


def test_per_block_plots_and_boundaries_check_their_arguments(tmp_path):
    ds = sweep.run(with_changes("twoblock", {"sweep": {"K_W": [0.04, 0.06],
                                                       "k2_W": [0.05, 0.1]}}),
                   progress=False)  # fmt: skip
    for block in (2, -1, "a", True):
        with pytest.raises(ValueError, match=r"block must be an integer in \[0, 1\]"):
            sweep.plot_variable(ds, "lnv_final", block=block)
    assert sweep.plot_variable(ds, "lnv_final", block=np.int64(1)) is not None
    refined = sweep.run("quick", refine=1, progress=False)
    with pytest.raises(ValueError, match="outputs must be a list of variable names"):
        sweep.boundaries(refined, "regime")
    with pytest.raises(ValueError, match="outputs: no variable nope in this result"):
        sweep.boundaries(refined, ["nope"])


@pytest.mark.slow
def test_api_arguments_of_numpy_and_of_the_wrong_kind(tmp_path):
    """numpy integers count as integers; a result Dataset given as config says what to
    pass instead (it is a Mapping, and was read as a config with 15 lines of problems);
    a completeness magnitude that is not finite is refused (it gave NaN b-values)."""
    ds = sweep.run("quick", threads=np.int64(1), progress=False)
    with pytest.raises(sweep.ConfigError, match="a result Dataset is not a config"):
        sweep.run(ds)
    catalogue = sweep.run(with_changes("quick", {"catalogue": {"capacity": 50}}), progress=False)
    for completeness in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="completeness must be a finite magnitude"):
            sweep.catalogue_statistics(catalogue, completeness)


def test_plotting_functions_say_what_they_were_given(quick_reference_file):
    """Given something that is not a result, or a result missing what its run writes,
    the plotting functions name the argument and what is missing (they failed with
    KeyError from inside xarray)."""
    ds = xr.load_dataset(quick_reference_file)
    without_model = ds.copy()
    without_model.attrs.pop("model")
    calls = {
        "plot_result": sweep.plot_result,
        "plot_variable": lambda d: sweep.plot_variable(d, "period"),
        "plot_orbit_diagram": sweep.plot_orbit_diagram,
        "plot_bifurcation": sweep.plot_bifurcation,
        "plot_catalogue": sweep.plot_catalogue,
        "catalogue_statistics": sweep.catalogue_statistics,
    }
    for call in calls.values():
        with pytest.raises(TypeError, match="must be a result Dataset"):
            call(str(quick_reference_file))
        with pytest.raises(ValueError, match="is not a complete sweep result: no growth_rate"):
            call(ds.drop_vars("growth_rate"))
        with pytest.raises(ValueError, match="is not a complete sweep result: no model attribute"):
            call(without_model)
    with pytest.raises(ValueError, match="must be a trace Dataset"):
        sweep.plot_trace(ds)


def edited_trace(trace, change):
    """A copy of ``trace`` with ``change`` applied to its attributes."""
    edited = trace.copy()
    change(edited.attrs)
    return edited


def test_plot_trace_names_what_an_edited_trace_lacks():
    """A trace whose regime attribute was edited, or whose statistics were dropped, is a
    ValueError naming them (it was a KeyError from inside the figure)."""
    trace = compute_trace(with_changes(load_config("quick"), {"sweep": {"K_W": [0.03]}}), 200)
    assert trace.attrs["regime"] == "runaway"
    cases = [
        (lambda a: a.update(regime="chaos"), "regime attribute must be one of steady, "),
        (lambda a: a.pop("regime"), "got None"),
        (lambda a: a.pop("t_runaway"), "not a complete trace: no t_runaway attribute"),
        (lambda a: a.pop("K_over_Kc"), "not a complete trace: no K_over_Kc attribute"),
    ]
    for change, says in cases:
        with pytest.raises(ValueError, match=says):
            sweep.plot_trace(edited_trace(trace, change))
    with pytest.raises(ValueError, match="not a complete trace: no lnv"):
        sweep.plot_trace(trace.drop_vars("lnv"))
    with pytest.raises(TypeError, match="ds must be a trace Dataset, got dict"):
        sweep.plot_trace({"velocity": 1})
    assert len(sweep.plot_trace(trace).axes) == 1


def test_a_refined_result_cut_by_hand_and_arguments_of_the_wrong_type(quick_reference_file):
    """A refined result holding only some of its points (its lattice has holes) is named
    so by to_grid, boundaries and plot_result (AssertionError and IndexError before);
    a caption, ax or fig of the wrong type is a TypeError naming it."""
    refined = sweep.run(with_changes("twoblock", {"sweep": {
        "K_W": {"start": 0.04, "stop": 0.06, "num": 5}, "k2_W": [0.05, 0.1]}}),
        refine=1, progress=False)  # fmt: skip
    cut = refined.isel(point=slice(0, refined.sizes["point"] // 2))
    with pytest.raises(ValueError, match="lacks runs of its level-0 grid"):
        sweep.to_grid(cut)
    for call in (sweep.boundaries, sweep.plot_result):
        with pytest.raises(ValueError, match="lacks the runs at some cells' corners"):
            call(cut)
    ds = xr.load_dataset(quick_reference_file)
    with pytest.raises(TypeError, match="caption must be a string, got int"):
        sweep.plot_result(ds, caption=5)
    with pytest.raises(TypeError, match="ax must be a matplotlib Axes, got str"):
        sweep.plot_variable(ds, "period", ax="x")
    with pytest.raises(TypeError, match="source must be a string naming the config"):
        with_changes("quick", {"blocks": 1}, source=123)
