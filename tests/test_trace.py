"""Single-system traces (sweep/commands/trace.py) and ``python -m sweep trace``."""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from scipy.integrate import solve_ivp

from sweep.cli import main
from sweep.commands.trace import (
    compute_trace,
    decimate,
    pin_config,
)
from sweep.config import ConfigError, config_mapping, load_config, parse_config, with_changes
from sweep.engine.dispatch import integrate_grid
from sweep.engine.grid import build_grid
from sweep.engine.runner import compute
from sweep.errors import InputError
from sweep.kernels import layout

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
QUICK = CONFIGS / "quick.yaml"
TWOBLOCK = CONFIGS / "twoblock.yaml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def kernel_final_state(config):
    """(results row, y_final row) of the one system of ``config`` from the sweep's grid kernel."""
    g = build_grid(config)
    params, y0, settings = g.params, g.y0, g.settings
    results = np.empty((1, layout.result_width(settings)))
    y_final = np.empty_like(y0)
    integrate_grid(params, y0, settings, results, y_final)
    return results[0], y_final[0]


def quasi_dynamic_two_blocks():
    """twoblock.yaml with radiation damping (eta V/W = 0.001) and an out-of-phase start."""
    raw = config_mapping(load_config(TWOBLOCK))
    raw["model"] = "quasi-dynamic"
    raw["parameters"]["eta_W"] = 0.01
    raw["initial"]["phi_over_phi_ss"] = [1.01, 0.99]
    raw["integrator"]["t_end"] = 800.0
    return parse_config(raw, "twoblock, quasi-dynamic")


def test_config_mapping_round_trip():
    config = load_config(TWOBLOCK)
    again = parse_config(config_mapping(config), "round trip")
    for field in ("blocks", "model", "state_law", "parameters", "axes", "initial", "output"):
        assert getattr(again, field) == getattr(config, field)
    assert again.integrator == config.integrator
    assert again.classification == config.classification


def test_pin_config_pins_axes_and_overrides_fixed_parameters():
    pinned = pin_config(load_config(TWOBLOCK), {"K_W": 0.046, "k2_W": 0.05, "A": 0.02}, 500.0)
    assert pinned.shape == (1, 1)
    assert {a.name: a.values for a in pinned.axes} == {"K_W": (0.046,), "k2_W": (0.05,)}
    assert pinned.fixed["A"] == 0.02
    assert pinned.fixed["B"] == 0.08  # not given: keeps the config's value
    assert pinned.integrator.t_end == 500.0
    assert pinned.classification.early_exit is False


def test_pin_config_missing_axis_is_an_error_naming_it():
    with pytest.raises(InputError) as err:
        pin_config(load_config(TWOBLOCK), {"K_W": 0.046})
    assert not isinstance(err.value, ConfigError)  # the --at values are wrong, not the config
    assert any("k2_W" in p and "--at k2_W=" in p for p in err.value.problems)


@pytest.mark.parametrize(
    ("at", "message"),
    [
        ({"K_W": 0.046, "stiffness": 1.0}, "unknown parameter"),
        ({"K_W": 0.046, "eta_W": 0.1}, "eta_W only applies to model quasi-dynamic"),
        ({"K_W": -1.0}, r"--at K_W=-1: sweep.K_W\[0\] must be in \(0, inf\), got -1"),
    ],
)
def test_pin_config_rejects_unknown_and_inapplicable_parameters(at, message):
    with pytest.raises(InputError, match=message) as err:
        pin_config(load_config(QUICK), at)
    assert not isinstance(err.value, ConfigError)


def test_pin_config_pins_a_spread_axis_and_sets_a_spread_size():
    """A spread axis (configs/heterogeneous.yaml's spread_D0) is pinned like a parameter
    axis and named when missing (it was an unknown parameter, and leaving it out raised
    KeyError); on a config without that axis, --at spread_D0 sets the spread size."""
    heterogeneous = load_config(CONFIGS / "heterogeneous.yaml")
    pinned = pin_config(heterogeneous, {"K_W": 0.05, "spread_D0": 0.2})
    assert {a.name: a.values for a in pinned.axes} == {"K_W": (0.05,), "spread_D0": (0.2,)}
    with pytest.raises(InputError, match=r"sweep axis spread_D0 needs a value.* 0 to 0.3 1\)"):
        pin_config(heterogeneous, {"K_W": 0.05})
    unswept = with_changes(heterogeneous, {"sweep": {"spread_D0": None}})
    sized = pin_config(unswept, {"K_W": 0.05, "spread_D0": 0.1})
    assert sized.spread.sizes_dict == {"D0": 0.1}


def test_decimate_keeps_every_extreme_and_the_last_sample():
    rng = np.random.default_rng(1)
    lnv = rng.normal(size=(10_001, 2)).cumsum(axis=0)
    keep = decimate(lnv, 100)
    assert np.all(np.diff(keep) > 0)
    assert keep[0] == 0 and keep[-1] == lnv.shape[0] - 1
    assert keep.size <= 100 * (1 + 2 * 2) + 1
    for b in range(2):
        assert np.argmax(lnv[:, b]) in keep and np.argmin(lnv[:, b]) in keep
        # the decimated series has the same envelope as the full one, bin by bin
        assert lnv[keep, b].max() == lnv[:, b].max()
    assert np.array_equal(decimate(lnv[:50], 100), np.arange(50))


@pytest.mark.slow
@pytest.mark.parametrize(
    "make_config, at",
    [
        (lambda: load_config(QUICK), {"K_W": 0.046}),  # quasi-static, runs away
        (lambda: load_config(QUICK), {"K_W": 0.054}),  # quasi-static, decays
        (quasi_dynamic_two_blocks, {"K_W": 0.046, "k2_W": 0.05}),  # bounded oscillation
    ],
    ids=["runaway", "steady", "two-blocks-quasi-dynamic"],
)
def test_trace_ends_at_the_kernels_final_state(make_config, at):
    pinned = pin_config(make_config(), at)
    ds = compute_trace(pinned, points=500)
    result, y_final = kernel_final_state(pinned)
    nb = pinned.blocks
    V = pinned.fixed["V"]
    time_unit = build_grid(pinned).time_unit
    # Same kernel, same arithmetic (recording only interpolates): agreement to rounding.
    np.testing.assert_allclose(ds["lnv"].isel(time=-1).values, y_final[:nb], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        ds["ln_state"].isel(time=-1).values, y_final[nb:], rtol=1e-12, atol=1e-12
    )
    np.testing.assert_allclose(
        ds["velocity"].isel(time=-1).values, V * np.exp(y_final[:nb]), rtol=1e-12
    )
    np.testing.assert_allclose(
        ds["time"].isel(time=-1).values, result[layout.R_TAU_FINAL] * time_unit[0]
    )
    assert (
        ds.attrs["regime"]
        == ("steady", "stick_slip", "runaway", "undecided")[int(result[layout.R_REGIME])]
    )


def test_quasi_static_trace_ends_at_the_sweeps_runaway_time():
    config = load_config(QUICK)
    sweep = compute(config, show_progress=False)
    runaway = sweep["regime"].values == layout.RUNAWAY
    below = sweep["K_over_Kc"].values < 1.0
    assert runaway[below].all() and runaway.any()
    points = 400
    for k_w in sweep["K_W"].values[runaway]:
        ds = compute_trace(pin_config(config, {"K_W": float(k_w)}), points)
        t_runaway = float(sweep["t_runaway"].sel(K_W=k_w))
        step = ds.attrs["t_end"] / points  # one output step (time bin) of the trace
        assert ds.attrs["regime"] == "runaway"
        assert abs(ds["time"].isel(time=-1).values - t_runaway) <= step
        # Same system, same path: the sweep's early exit never triggers on a growing envelope.
        assert ds.attrs["t_runaway"] == pytest.approx(t_runaway, rel=1e-12)


@pytest.mark.parametrize(
    "v0, psi0, k_over_kc, tau_runaway, tol",
    [
        # physics brief, section 4: SciPy DOP853, rtol 1e-10, time to v = 1e6 V (D0/V),
        # quoted to 3-4 digits (tol = half the last quoted digit)
        (1.05, 0.0, 0.5, 8.71, 0.005),
        (1.05, 0.0, 0.9, 61.28, 0.005),
        (1.05, 0.0, 0.99, 633.9, 0.05),
        (1.0, 0.01, 0.9, 68.4, 0.05),
        # solve_ivp(method="DOP853", rtol=1e-10, atol=1e-12) on the log form with a
        # terminal event at ln(v/V) = ln(1e6): 768.606 (the brief's 962 did not reproduce)
        (1.0, 0.01, 0.99, 768.606, 0.005),
    ],
)
def test_runaway_time_of_a_trace_matches_the_reference(v0, psi0, k_over_kc, tau_runaway, tol):
    raw = config_mapping(load_config(QUICK))  # paper A, B; D0 = 1 um, V = 0.1 um/s
    raw["initial"] = {"v_over_V": [v0], "phi_over_phi_ss": [float(np.exp(psi0))]}
    config = parse_config(raw, "quick, brief's start")
    ds = compute_trace(pin_config(config, {"K_W": k_over_kc * 0.05}), points=200)
    assert ds.attrs["regime"] == "runaway"
    time_unit = 1.0 / 0.1  # D0/V in s
    assert ds.attrs["t_runaway"] / time_unit == pytest.approx(tau_runaway, abs=tol)
    # the series ends with the step that crossed the cap, within one output step
    assert ds["time"].isel(time=-1).values - ds.attrs["t_runaway"] <= ds.attrs["t_end"] / 200


def test_recorded_samples_lie_on_the_scipy_trajectory():
    # One quasi-static block at K/Kc = 0.92 for 60 D0/V (growing oscillation, no runaway yet).
    config = load_config(QUICK)
    pinned = pin_config(config, {"K_W": 0.046}, t_end=60.0)
    ds = compute_trace(pinned, points=300)
    A, B, kappa = 0.03, 0.08, 0.046 * 1.0  # kappa = K D0/W, D0 = 1 um

    def rhs(_, y):  # physics brief, section 2 (log form, aging law)
        dpsi = np.exp(-y[1]) - np.exp(y[0])
        return [(kappa * (1 - np.exp(y[0])) - B * dpsi) / A, dpsi]

    tau = ds["time"].values / (1.0 / 0.1)  # time unit D0/V = 10 s
    ref = solve_ivp(
        rhs,
        (0, tau[-1]),
        [0.0, np.log(1.01)],
        method="DOP853",
        rtol=1e-11,
        atol=1e-12,
        dense_output=True,
    ).sol(tau)
    # Tolerance 1e-5: the kernel's DOPRI5 (rtol 1e-8) plus cubic Hermite recording
    # errs by < 1e-6 here; a sample stamped one fine step (0.004 D0/V) off would err
    # by ~5e-3 (slope of ln v up to ~1.3 per D0/V).
    np.testing.assert_allclose(ds["lnv"].isel(block=0).values, ref[0], atol=1e-5)
    np.testing.assert_allclose(ds["ln_state"].isel(block=0).values, ref[1], atol=1e-5)
    mu_ss = 0.4 + (0.03 - 0.08) * np.log(0.1 / 1.0)  # V0 = D0/Phi0 = 1 um/s
    np.testing.assert_allclose(
        ds["friction"].isel(block=0).values, mu_ss + A * ref[0] + B * ref[1], atol=1e-6
    )


def test_trace_command_writes_netcdf_and_png(tmp_path):
    nc = tmp_path / "trace.nc"
    code = main(["trace", str(QUICK), "--at", "K_W=0.046", "--out", str(nc), "--points", "300"])
    assert code == 0
    png = nc.with_suffix(".png")
    assert png.read_bytes()[:8] == PNG_MAGIC and png.stat().st_size > 10_000
    with xr.open_dataset(nc) as ds:
        assert ds["velocity"].dims == ("block", "time")
        assert ds["time"].attrs["units"] == "s" and ds["velocity"].attrs["units"] == "um s-1"
        assert {"lnv", "ln_state", "friction"} <= set(ds.data_vars)
        assert ds.attrs["regime"] == "runaway"
        assert ds.attrs["t_runaway_units"] == "s"
        assert np.all(np.diff(ds["time"].values) > 0)


def test_trace_command_missing_axis_exits_2(tmp_path, capsys):
    code = main(["trace", str(TWOBLOCK), "--at", "K_W=0.046", "--out", str(tmp_path / "t.nc")])
    assert code == 2
    assert "k2_W" in capsys.readouterr().err
    assert not (tmp_path / "t.nc").exists()


def test_the_trace_module_computes_and_draws_nothing():
    """sweep/commands/trace.py computes traces and the trace command draws them: the module
    imports nothing from sweep/plot/, not even inside a function."""
    import ast

    import sweep.commands.trace

    tree = ast.parse(Path(sweep.commands.trace.__file__).read_text())
    imported = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert [m for m in imported if m.split(".")[0] == "plot"] == []


def test_trace_figure_ends_where_the_run_ended_and_takes_an_axes():
    """A runaway at ~970 s of a 20000 s end time: the time axis stops at the last sample,
    not at the end time. CF attributes of the time coordinate are set."""
    from matplotlib.figure import Figure

    from sweep.plot import plot_trace

    ds = compute_trace(pin_config(load_config(QUICK), {"K_W": 0.046}, 2000.0), points=300)
    assert ds.attrs["regime"] == "runaway" and ds.attrs["t_end"] == 20000.0
    ax = Figure().subplots()
    assert plot_trace(ds, ax=ax) is ax.figure
    assert ax.get_xlim()[1] == ds["time"].values[-1] < 1000.0
    assert ds["time"].attrs["standard_name"] == "time" and ds["time"].attrs["axis"] == "T"
