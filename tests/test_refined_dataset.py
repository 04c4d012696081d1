"""The refined result (sweep/refine/dataset.py): one CF point file, and to_grid.

to_grid(ds, 0) must be the uniform sweep of the config's grid (bit for bit), and at a
finer level every grid point must hold its own run where it has one and else the
nearest corner's of the unsplit cell it lies in (checked here against a direct search).
"""

import numpy as np
import pytest
import xarray as xr
from conftest import make_config
from test_dataset import cf_report

from sweep.engine import runner
from sweep.errors import InputError
from sweep.io.netcdf import write_netcdf
from sweep.refine.dataset import (
    is_refined,
    lattice_index,
    nearest_runs,
    refined_config,
    to_grid,
)
from sweep.refine.lattice import Lattice, cell_tree

#: Two quasi-static blocks about Kc/W = 0.05 µm⁻¹ (between points of every level), 4 levels.
TWO_BLOCKS = {
    "blocks": 2,
    "parameters": {"k2_W": None},
    "sweep": {"K_W": {"start": 0.0303, "stop": 0.0703, "num": 6}, "k2_W": [0.0, 0.1, 0.2]},
    "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0]},
    "refine": {"levels": 4},
}
#: File attributes a refinement adds to those of a grid result.
REFINE_ATTRS = {"featureType", "refine_levels", "refine_outputs", "refine_rtol",
                "refine_points", "refine_runs", "refine_stopped", "refine_grid_level"}  # fmt: skip
#: Attributes that say when, how and from which text a file was made.
MADE_ATTRS = {"created", "history", "config_text"}


@pytest.fixture(scope="module")
def refined():
    config = make_config(TWO_BLOCKS)
    return config, runner.compute(config, show_progress=False)


def assert_grid_equals_uniform(grid, uniform):
    """Every variable and coordinate identical (values bit for bit, attributes); the file
    attributes those of the uniform result, but for refinement's and provenance."""
    grid = grid.drop_vars(["level", "exact"])
    xr.testing.assert_identical(
        grid.assign_attrs(refine_grid_level=0).drop_attrs(deep=False),
        uniform.drop_attrs(deep=False),
    )
    for name, var in uniform.variables.items():
        assert grid[name].values.tobytes() == var.values.tobytes(), name
    drop = REFINE_ATTRS | MADE_ATTRS
    assert {k: v for k, v in grid.attrs.items() if k not in drop}.keys() == {
        k for k in uniform.attrs if k not in drop
    }
    for key, value in uniform.attrs.items():
        if key not in drop:
            np.testing.assert_array_equal(grid.attrs[key], value, err_msg=key)


def test_level_0_is_the_uniform_sweep_of_the_grid(refined):
    """With ``full_runs: true``, bit for bit; by default (linear-regime verdicts) the
    labels bit for bit, and a run no such verdict stopped is the grid's, every output."""
    config, ds = refined
    uniform = runner.compute(runner_config(config), show_progress=False)
    full = runner.compute(make_config(TWO_BLOCKS, refine={"full_runs": True}),
                          show_progress=False)  # fmt: skip
    assert_grid_equals_uniform(to_grid(full, 0), uniform)
    grid = to_grid(ds, 0)
    linear = grid["linear_verdict"].values == 1
    for name, var in uniform.data_vars.items():
        if name in ("regime", "attractor", "cycle_events"):
            np.testing.assert_array_equal(grid[name].values, var.values, err_msg=name)
        else:
            keep = ~linear.reshape(linear.shape + (1,) * (var.ndim - linear.ndim))
            keep = np.broadcast_to(keep, var.shape)
            assert grid[name].values[keep].tobytes() == var.values[keep].tobytes(), name


def runner_config(config):
    """``config`` without its refine section."""
    import dataclasses

    return dataclasses.replace(config, refine=None)


def test_an_ensemble_refines_on_the_regime_fractions_and_its_grid_is_the_uniform_one():
    """With an ensemble the runs carry a member dimension, regime_fraction is per point,
    and level 0 is again the uniform sweep."""
    config = make_config(
        sweep={"K_W": {"start": 0.0403, "stop": 0.0603, "num": 5}},
        initial={"ensemble": 2, "amplitude": 0.05},
        refine={"levels": 3, "full_runs": True},
    )
    assert config.refine.outputs == ("regime_fraction",)
    ds = runner.compute(config, show_progress=False)
    assert ds["regime"].dims == ("point", "member")
    assert ds["regime_fraction"].dims == ("point", "regime_name")
    assert ds.attrs["refine_runs"].tolist() == [2 * n for n in ds.attrs["refine_points"]]
    assert (ds.level > 0).any()
    uniform = runner.compute(runner_config(config), show_progress=False)
    assert_grid_equals_uniform(to_grid(ds, 0), uniform)


@pytest.mark.slow
@pytest.mark.parametrize("level", [2, 4])
def test_a_finer_grid_takes_a_run_of_the_unsplit_cell_each_point_lies_in(refined, level):
    """At a finer level every grid point holds its own run where it was run (and is
    exact there); elsewhere a run on the closed unsplit cell around it, no farther than
    half that cell's step along any axis, with the regime the cell's corners agree on."""
    config, ds = refined
    grid = to_grid(ds, level)
    lattice = Lattice(config)
    index = lattice_index(ds, lattice)
    shape = grid["regime"].shape
    targets = np.stack(
        [m.ravel() for m in np.meshgrid(*(np.arange(n, dtype=np.int64) << (4 - level)
                                          for n in shape), indexing="ij")], axis=-1,
    )  # fmt: skip
    rows, exact = nearest_runs(lattice, index, targets, level)
    for name in ("regime", "lnv_max", "K_over_Kc", "event_lnv_peak"):
        want = ds[name].values[rows].reshape(grid[name].shape)
        np.testing.assert_array_equal(grid[name].values, want, err_msg=name)
    run_here = {tuple(p) for p in index.tolist()}
    assert exact.tolist() == [tuple(p) in run_here for p in targets.tolist()]
    assert np.array_equal(grid["exact"].values.ravel(), exact)
    leaves = [(lv, cells[~split]) for lv, (cells, split) in enumerate(cell_tree(lattice, index))]
    regime = ds["regime"].values
    for k in np.flatnonzero(~exact):
        p, r = targets[k], index[rows[k]]
        holders = [(lv, c) for lv, cells in leaves for c in cells
                   if np.all((c <= p) & (p <= c + lattice.step(lv)))]  # fmt: skip
        assert holders, p
        ok = False
        for lv, cell in holders:
            step = lattice.step(lv)
            inside = np.all((cell <= r) & (r <= cell + step))
            near = np.all(np.abs(r - p) * 2 <= step)
            near &= not np.any(r - p == step // 2)  # at a tie, the lower neighbour
            corners = lattice.corners(cell[None], lv)[0]
            labels = {regime[rows_of(index, c)] for c in corners}
            agrees = len(labels) > 1 or regime[rows[k]] in labels
            ok |= bool(inside and near and agrees)
        assert ok, (p, r)


def rows_of(index, point):
    return int(np.flatnonzero(np.all(index == point, axis=1))[0])


@pytest.mark.slow
def test_the_file_passes_the_cf_checker_and_reads_back(refined, tmp_path):
    """Every CF-1.11 check passes, warnings included (criteria strict). The checker's
    domain-variable check stops on files of featureType point without ragged arrays
    (compliance-checker 6.1: IndexError inside it, reported as a warning, no result)."""
    _, ds = refined
    path = write_netcdf(ds, tmp_path / "refined.nc")
    failed = {c["name"]: c["msgs"] for c in cf_report(path, tmp_path)["all_priorities"]
              if c["value"][0] < c["value"][1]}  # fmt: skip
    assert failed == {}
    with xr.open_dataset(path) as back:
        back.load()
    assert is_refined(back)
    xr.testing.assert_identical(to_grid(back, 3), to_grid(ds, 3))


def test_to_grid_refuses_what_it_cannot_do(refined, quick, monkeypatch):
    _, ds = refined
    with pytest.raises(ValueError, match=r"level must be an integer in \[0, 4\], got 5"):
        to_grid(ds, 5)
    monkeypatch.setattr("sweep.refine.dataset.MAX_GRID_POINTS", 100)
    with pytest.raises(ValueError, match="the grid of level 4 has 2.67e\\+03 points"):
        to_grid(ds, 4)
    with pytest.raises(InputError, match="not a refined result"):
        to_grid(runner.compute(quick, show_progress=False), 0)
    assert refined_config(ds).refine.levels == 4


def test_extend_and_audit_say_a_refined_result_is_not_a_grid(refined, tmp_path, capsys):
    from sweep.cli import main

    _, ds = refined
    path = write_netcdf(ds, tmp_path / "refined.nc")
    for command in ("extend", "audit"):
        assert main([command, str(path)]) == 2
        assert "a refined result (its runs along point) is not a grid" in capsys.readouterr().err
