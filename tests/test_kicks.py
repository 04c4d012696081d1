"""The start as a swept dimension and the critical kick (``sweep/results/kicks.py``,
``sweep/engine/kicks.py``): config, starts, the reduction on hand-made outcomes, the
bisection (resumed or not), the CLI and bad input. The thresholds against SciPy are in
``tests/test_kick_reference_checks.py``."""

import kick_reference as ref
import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import PAPER_A, PAPER_B, config_dict, make_config, write_config

from sweep import cli
from sweep.codes import REGIMES, code
from sweep.commands.trace import pin_config
from sweep.engine import grid
from sweep.engine.kicks import bisect_critical_kick
from sweep.errors import ConfigError, InputError
from sweep.results.kicks import (
    KICK_STATUSES,
    THRESHOLD_KINDS,
    bisect_brackets,
    critical_kick,
    open_brackets,
    scan_brackets,
    threshold_kinds,
)

S, T, R, U = (code(REGIMES, name) for name in ("steady", "stick_slip", "runaway", "undecided"))
KICKS = {"start": 1.0, "stop": 1.0e4, "num": 5, "scale": "log"}


def kick_config(**sections):
    """One quasi-static aging-law block swept over K/W and the velocity kick."""
    sweep = {"K_W": [0.0505, 0.06, 0.09], "initial_v_over_V": KICKS}
    return config_dict({"sweep": sweep, "initial": {"phi_over_phi_ss": 1.0}}, **sections)


def test_kick_axis_sets_the_start_of_the_kicked_blocks_only():
    cfg = make_config(
        {
            "blocks": 2,
            "parameters": {"k2_W": 0.01},
            "sweep": {"K_W": [0.05], "initial_v_over_V": [2.0, 30.0]},
            "initial": {"v_over_V": [1.5, 0.5], "phi_over_phi_ss": 1.2, "kicked_blocks": [1]},
        }
    )
    g = grid.build_grid(cfg)
    # columns: ln v of blocks 0, 1, then ln(Φ/Φss) of blocks 0, 1
    expected = np.log([[1.5, 2.0, 1.2, 1.2], [1.5, 30.0, 1.2, 1.2]])
    np.testing.assert_allclose(g.y0, expected, rtol=0, atol=1e-15)


def test_state_axis_sets_every_block_by_default():
    cfg = make_config(
        {
            "blocks": 2,
            "parameters": {"k2_W": 0.01},
            "sweep": {"K_W": [0.05], "initial_phi_over_phi_ss": [0.5]},
        }
    )
    g = grid.build_grid(cfg)
    np.testing.assert_allclose(g.y0[0, 2:], np.log([0.5, 0.5]))
    np.testing.assert_allclose(g.y0[0, :2], 0.0)


@pytest.mark.parametrize(
    "initial, sweep, message",
    [
        ({"kicked_blocks": [0]}, {}, "neither is swept"),
        ({"kicked_blocks": [3]}, {"initial_v_over_V": [2.0]}, "initial.kicked_blocks[0]"),
        ({"kicked_blocks": 0}, {"initial_v_over_V": [2.0]}, "must be a list"),
        ({"kicked_blocks": [0, 0]}, {"initial_v_over_V": [2.0]}, "lists a block twice"),
        ({}, {"initial_v_over_V": [2.0, 0.0]}, "sweep.initial_v_over_V[1]"),
        ({}, {"initial_phi_over_phi_ss": {"start": -1, "stop": 2, "num": 3}}, "initial_phi"),
    ],
)
def test_bad_kick_settings_name_the_key(initial, sweep, message):
    with pytest.raises(ConfigError) as err:
        make_config({"sweep": {"K_W": [0.05], **sweep}, "initial": initial})
    assert message in str(err.value)


def test_unknown_axis_lists_the_start_axes():
    with pytest.raises(ConfigError, match="initial_v_over_V"):
        make_config({"sweep": {"K_W": [0.05], "v0": [2.0]}})


def test_scan_brackets_on_hand_made_outcomes():
    kicks = np.array([1.0, 2.0, 4.0, 8.0])
    regime = np.array(
        [
            [S, S, R, R],  # found between 2 and 4
            [S, S, S, S],  # none up to 8
            [T, T, T, T],  # the smallest kick leaves
            [S, U, R, R],  # undecided where the bracket would be
            [U, S, S, S],  # undecided, and none leaves
            [S, T, S, R],  # the first that leaves counts
        ]
    )
    peak = np.array([[0.1, 0.7, 14.0, 14.0]] * 6)
    b = scan_brackets(kicks, regime, peak)
    names = ["found", "none_up_to_max", "below_min", "undecided", "undecided", "found"]
    assert list(b["status"]) == [code(KICK_STATUSES, n) for n in names]
    np.testing.assert_equal(b["low"], [2.0, np.nan, np.nan, np.nan, np.nan, 1.0])
    np.testing.assert_equal(b["high"], [4.0, np.nan, np.nan, np.nan, np.nan, 2.0])
    assert b["regime_high"][0] == R and b["regime_high"][5] == T and b["regime_high"][1] == -1
    # probes: the largest kick at or below 0.9 × critical_kick (row 0: 2 below 4; row 5:
    # 1 below 2)
    np.testing.assert_equal(b["probe"], [2.0, np.nan, np.nan, np.nan, np.nan, 1.0])
    kinds = threshold_kinds(b, lnv_cap=14.0)
    assert kinds[0] == code(THRESHOLD_KINDS, "sharp")  # runaway: 0.7 against the cap 14
    assert kinds[5] == code(THRESHOLD_KINDS, "basin_boundary")  # to a stick-slip attractor
    assert threshold_kinds(b, lnv_cap=2.0)[0] == code(THRESHOLD_KINDS, "cap_limited")
    assert kinds[1] == code(THRESHOLD_KINDS, "not_found")
    b["peak_probe"][0] = np.nan  # a probe that did not return
    assert threshold_kinds(b, 14.0)[0] == code(THRESHOLD_KINDS, "undetermined")


def test_bisection_step_keeps_the_half_where_the_outcome_changes():
    b = scan_brackets(np.array([1.0, 4.0]), np.array([[S, R], [S, R], [S, R]]), np.zeros((3, 2)))
    todo = open_brackets(b, 0.5)
    np.testing.assert_equal(todo, [0, 1, 2])
    bisect_brackets(b, np.full(3, 2.0), np.array([R, S, U]), np.array([14.0, 1.0, 3.0]), todo)
    np.testing.assert_equal(b["low"], [1.0, 2.0, np.nan])
    np.testing.assert_equal(b["high"], [2.0, 4.0, np.nan])
    assert b["status"][2] == code(KICK_STATUSES, "undecided")
    np.testing.assert_equal(open_brackets(b, 0.5), [0, 1])  # width 1 > 0.5
    np.testing.assert_equal(open_brackets(b, 1.0), [])


def test_reduction_of_a_kick_sweep_refuses_results_without_one():
    ds = xr.Dataset({"regime": (("K_W",), np.zeros(2, np.int8))}, coords={"K_W": [1.0, 2.0]})
    with pytest.raises(InputError, match="one swept start axis"):
        critical_kick(ds)


@pytest.fixture(scope="module")
def aging_kicks(tmp_path_factory):
    """The bisection of :func:`kick_config` to 2 %, written to a file."""
    out = tmp_path_factory.mktemp("kick") / "kick.nc"
    cfg = make_config(kick_config())
    return cfg, out, bisect_critical_kick(cfg, rtol=0.02, out=out, progress=False)


def test_bisection_brackets_the_scipy_outcomes(aging_kicks):
    """Each found bracket: SciPy (``tests/kick_reference.py``, LSODA, its own right-hand
    side) runs away past the cap at the upper kick and not at the lower one; K/Kc = 1.8
    has no threshold up to 10⁴ in either."""
    cfg, _, ds = aging_kicks
    status = ds["critical_kick_status"].values
    assert list(status) == [code(KICK_STATUSES, n) for n in ("found", "found", "none_up_to_max")]
    assert np.all(ds["critical_kick_rtol"].values[:2] <= 0.02)
    for i in range(3):
        ratio = float(ds["K_over_Kc"][i])
        if i < 2:
            lo, hi = float(ds["critical_kick_low"][i]), float(ds["critical_kick"][i])
            assert ref.kick_outcome("aging", PAPER_A, PAPER_B, ratio, hi)[0]
            assert not ref.kick_outcome("aging", PAPER_A, PAPER_B, ratio, lo)[0]
        else:
            assert not ref.kick_outcome("aging", PAPER_A, PAPER_B, ratio, 1e4)[0]
    assert (ds["kick_threshold"].values[:2] == code(THRESHOLD_KINDS, "cap_limited")).all()
    assert ds["critical_kick"].attrs["units"] == "1"
    assert ds.attrs["kick_complete"] == 1


def test_resumed_bisection_gives_the_same_numbers(aging_kicks, tmp_path):
    """A search stopped at 30 % and resumed to 2 % ends where one search to 2 % does."""
    cfg, _, whole = aging_kicks
    out = tmp_path / "k.nc"
    coarse = bisect_critical_kick(cfg, rtol=0.3, out=out, progress=False)
    assert coarse.attrs["kick_rounds"] < whole.attrs["kick_rounds"]
    resumed = bisect_critical_kick(cfg, rtol=0.02, out=out, progress=False)
    for name in ("critical_kick", "critical_kick_low", "lnv_peak_below", "lnv_peak_above"):
        np.testing.assert_array_equal(resumed[name].values, whole[name].values)
    # the coarse search's probes went stale as the brackets narrowed: one more run each
    found = whole["critical_kick_status"].values == code(KICK_STATUSES, "found")
    np.testing.assert_array_equal(resumed["kick_runs"].values, whole["kick_runs"].values + found)
    np.testing.assert_array_equal(resumed["lnv_peak_probe"].values, whole["lnv_peak_probe"].values)
    with xr.open_dataset(out) as stored:
        np.testing.assert_array_equal(stored["critical_kick"].values, whole["critical_kick"].values)


def test_reduction_of_the_scan_agrees_with_round_zero(aging_kicks):
    """The reduction of a plain sweep over the kicks brackets the bisection's threshold."""
    import sweep

    cfg, _, bisected = aging_kicks
    scan = critical_kick(sweep.run(cfg, progress=False))
    assert np.all(scan["kick_runs"].values == 5)
    found = scan["critical_kick_status"].values == code(KICK_STATUSES, "found")
    assert found[:2].all()
    assert np.all(scan["critical_kick_low"].values[:2] <= bisected["critical_kick_low"].values[:2])
    assert np.all(scan["critical_kick"].values[:2] >= bisected["critical_kick"].values[:2])


def test_kick_file_of_another_config_is_refused_and_kept(aging_kicks):
    cfg, out, _ = aging_kicks
    before = out.read_bytes()
    other = make_config(kick_config(classification={"v_cap_over_V": 1e9}))
    with pytest.raises(InputError, match="another config"):
        bisect_critical_kick(other, out=out, progress=False)
    assert out.read_bytes() == before


@pytest.mark.parametrize(
    "sweep, initial, message",
    [
        ({"K_W": [0.06]}, {}, "exactly one start axis"),
        ({"K_W": [0.06], "initial_v_over_V": KICKS}, {"ensemble": 4}, "no initial.ensemble"),
        ({"K_W": [0.06], "initial_v_over_V": [3.0]}, {}, "at least two values"),
    ],
)
def test_kick_command_bad_input_exits_2(tmp_path, capsys, sweep, initial, message):
    raw = config_dict({"sweep": sweep, "initial": initial})
    raw["sweep"] = sweep
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    status = cli.main(["kick", str(path), "--out", str(tmp_path / "k.nc"), "--quiet"])
    assert status == 2
    err = capsys.readouterr().err
    assert message in err and str(path) in err
    assert not (tmp_path / "k.nc").exists()


def test_kick_command_writes_netcdf_and_figure(tmp_path, capsys):
    path = write_config(tmp_path / "kick.yaml", kick_config(sweep={"K_W": [0.06, 0.09]}))
    out = tmp_path / "kick.nc"
    status = cli.main(["kick", str(path), "--rtol", "0.1", "--out", str(out), "--quiet"])
    assert status == 0
    text = capsys.readouterr().out
    assert "found                1 points" in text and "none_up_to_max       1 points" in text
    assert out.with_suffix(".png").stat().st_size > 10_000
    with xr.open_dataset(out) as ds:
        assert ds["critical_kick_status"].attrs["flag_meanings"] == " ".join(KICK_STATUSES)
        assert ds.attrs["kick_axis"] == "initial_v_over_V"


def test_trace_pins_a_kick_axis():
    cfg = make_config(kick_config())
    pinned = pin_config(cfg, {"K_W": 0.06, "initial_v_over_V": 25.0})
    g = grid.build_grid(pinned)
    np.testing.assert_allclose(g.y0[0], [np.log(25.0), 0.0])


def test_refinement_bisects_the_kick_boundary(aging_kicks):
    """``refine`` on a sweep over (K/W, kick) splits the cells where the kicks' outcomes
    change: at each K/W with a threshold the finest kicks that return and leave bracket
    the bisection's critical kick."""
    import sweep

    cfg, _, bisected = aging_kicks
    refined = sweep.run(cfg, refine=4, progress=False)
    for i, k_w in enumerate(cfg.axes[0].values[:2]):
        at = refined.where(refined["K_W"] == k_w, drop=True)
        kicks, regime = at["initial_v_over_V"].values, at["regime"].values
        left = (regime != S) & (regime != U)
        below, above = kicks[~left & (regime == S)].max(), kicks[left].min()
        assert above / below < 10 ** (4 / 4) / 2**3  # finer than the scan's factor 10
        assert below <= float(bisected["critical_kick_low"][i]) * 1.03
        assert above >= float(bisected["critical_kick"][i]) / 1.03


def test_critical_kick_figure_marks_each_kind_and_pickles(aging_kicks):
    """The figure draws the found thresholds by kind and the point without one, and
    pickles (the docs' gallery copies figures so)."""
    import pickle

    import sweep

    _, _, ds = aging_kicks
    fig = sweep.plot_critical_kick(ds, caption="test")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["critical kick: cap-limited", "critical kick: none up to the max"]
    assert fig.axes[0].get_yscale() == "log"
    assert "runaway past v/V = 1e+06" in fig._suptitle.get_text()
    pickle.loads(pickle.dumps(fig))


def test_captions_name_a_swept_start(aging_kicks):
    """A map over the kick says the start is swept, not the config's fixed value."""
    import sweep
    from sweep.plot.common import initial_text

    cfg, _, _ = aging_kicks
    ds = sweep.run(cfg, progress=False)
    assert initial_text(ds) == "start Φ/Φss = 1; v/V = swept (initial_v_over_V)"
    assert initial_text(ds.isel(initial_v_over_V=2)) == "start Φ/Φss = 1; v/V = 100"


def test_kick_command_on_one_point_prints_its_bracket(tmp_path, capsys):
    """A search at one point (only the kick swept) writes its file, prints the bracket
    and draws no figure."""
    path = tmp_path / "one.yaml"
    path.write_text(yaml.safe_dump(kick_config(sweep={"K_W": None}, parameters={"K_W": 0.06})))
    out = tmp_path / "one.nc"
    assert cli.main(["kick", str(path), "--rtol", "0.1", "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "critical kick between" in text and "no figure" in text
    with xr.open_dataset(out) as ds:
        assert ds["critical_kick"].ndim == 0 and ds.attrs["kick_complete"] == 1
    assert not out.with_suffix(".png").exists()
