"""Basin fractions (``sweep/results/basins.py``): the Wilson interval against textbook
values, the matching on a synthetic ensemble, and the engine's fractions at a multistable
point (configs/basins.yaml) against SciPy runs of the same starts.

The SciPy reference is written here from the physics brief (section 4, inertia; the log
form of section 2), not from ``sweep``: one inertial block, aging law, time in D0/V,
κ = K D0/W, M̂ = m V²/(W D0), z = (m/W) dv/dt::

    ψ' = e^(−ψ) − e^ℓ,   ℓ' = z e^(−ℓ) / M̂,   z' = κ(1 − e^ℓ) − B ψ' − A ℓ'

started at ℓ = ln(v/V) + offset, ψ = ln(Φ/Φss) + offset, z = 0 (force balance), the
offsets drawn as the config's ``initial`` says (uniform in ±amplitude from the seed, one
row of (ℓ, ψ) offsets per member). Its own rule classifies a run: integrated by LSODA
(rtol 1e-9) in windows of 100 D0/V, "cycle" once two successive windows have a
peak-to-peak ln(v/V) above 3 (the stable cycle's is about 4.2), "steady" once one has it
below 0.1 and falling (the steady runs seen decay from 1.6 by a factor 0.58 per window).
"""

import numpy as np
import pytest
import xarray as xr
from scipy.integrate import solve_ivp

import sweep
from sweep.results.basins import basin_fractions, members_needed, wilson_interval, wilson_members

CONFIG = "configs/basins.yaml"
#: The multistable point of the check: K/Kc = 1.006 (both attractors near half).
RATIO = 1.006
#: The axis keys of the config's K_W to drop for a list of values.
AXIS_KEYS = {"start": None, "stop": None, "num": None, "scale": None}


def test_wilson_interval_textbook_values():
    """Newcombe (1998, Stat. Med. 17, 857, Table II, method 3): 81/263, 15/148, 0/20, 1/29."""
    for count, n, low, high in (
        (81, 263, 0.2553, 0.3662),
        (15, 148, 0.0624, 0.1605),
        (0, 20, 0.0, 0.1611),
        (1, 29, 0.0061, 0.1718),
    ):
        got = wilson_interval(count, n)
        assert got == pytest.approx((low, high), abs=6e-5)
    assert wilson_interval(0, 20)[0] == 0.0 and wilson_interval(20, 20)[1] == 1.0


def test_wilson_members_by_hand():
    """At p = 1/2 the width is z / sqrt(n + z²): n = z²/w² − z², rounded up (381 for
    w = 0.1, 1534 for 0.05); at other p the returned n is the first where the width, from
    the formula written out here, is at most w."""
    z = 1.959963984540054
    for w in (0.1, 0.05, 0.2):
        assert wilson_members(0.5, w) == int(np.ceil(z**2 / w**2 - z**2))

    def width(p, n):
        return 2 * z * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / (1 + z**2 / n)

    for p, w in ((0.1, 0.1), (0.02, 0.05), (0.0, 0.1)):
        n = int(wilson_members(p, w))
        assert width(p, n) <= w < width(p, n - 1)


def _synthetic():
    """Two points × 10 members with known attractors (regime, attractor codes of the
    engine's tables: steady 0 / fixed_point 0, stick_slip 1 / periodic 1, chaotic 3,
    undecided 3 / unresolved 4)."""
    nan = np.nan
    regime = [[0, 0, 0, 1, 1, 1, 1, 1, 1, 3], [1, 1, 1, 1, 1, 1, 1, 1, 0, 1]]
    attractor = [[0, 0, 0, 1, 1, 1, 1, 1, 1, 4], [1, 1, 1, 1, 1, 3, 3, 1, 0, 1]]
    events = [[0, 0, 0, 1, 1, 1, 1, 1, 1, 0], [1, 1, 2, 2, 2, 0, 0, 1, 0, 1]]
    # point 0: cycle A (period 60, amplitude 5) ×4 within 1e-3, cycle B (amplitude 2) ×2;
    # point 1: cycle of 1 event ×2 (+1 with the opposite sign of λ1 beyond 3 errors), a
    # cycle of 2 events ×3, chaotic ×2, steady ×1, a cycle 1 % off in amplitude ×1
    period = [[nan] * 3 + [60.0, 60.05, 20.0, 59.97, 20.01, 60.0, nan], [60, 60, 90, 90, 90.1]]
    period[1] += [nan, nan, 60.0, nan, 60.0]
    amplitude = [[0.01] * 3 + [5.0, 5.004, 2.0, 4.997, 2.001, 5.0, 1.0]]
    amplitude += [[5.0, 5.0, 3.0, 3.0, 3.001, 7.0, 6.0, 5.0, 0.001, 5.05]]
    lyapunov = [[-0.1] * 3 + [0.0] * 6 + [nan], [0.0, 0.0, 0.0, 0.0, 0.0, 0.2, 0.3, -0.5, -0.1]]
    lyapunov[1] += [0.0]
    error = np.full((2, 10), 0.01)
    t_final = np.arange(20, dtype=float).reshape(2, 10) * 100.0
    dims = ("K_W", "member")
    return xr.Dataset(
        {
            "regime": (dims, np.array(regime, np.int8)),
            "attractor": (dims, np.array(attractor, np.int8)),
            "cycle_events": (dims, np.array(events, np.int32)),
            "period": (dims, np.array(period, float)),
            "lnv_amplitude": (dims, np.array(amplitude, float)),
            "lyapunov_exponent": (dims, np.array(lyapunov, float)),
            "lyapunov_error": (dims, error),
            "t_final": (dims, t_final),
            "K_over_Kc": (("K_W",), np.array([1.0, 1.1])),
        },
        coords={"K_W": [0.05, 0.055], "member": np.arange(10)},
        attrs={"classification_accuracy": 1e-3},
    )


def test_matching_on_a_synthetic_ensemble():
    b = basin_fractions(_synthetic())
    names = list(b["attractor"].values)
    assert names == ["steady", "cycle_1ev", "cycle_1ev_2", "cycle_1ev_3", "cycle_2ev", "chaotic"]
    expected = [[3, 2, 4, 0, 0, 0], [1, 2, 1, 1, 3, 2]]
    # point 0: ranked by amplitude, smallest first: B (2.0) is cycle_1ev, A (5.0) the second;
    # point 1: amplitude 5.0 with λ1 ≈ 0 (2), λ1 = −0.5 (1, member 7), 5.05 (1, member 9)
    assert b["basin_count"].values.tolist() == expected
    assert b["unresolved_fraction"].values.tolist() == [0.1, 0.0]
    assert b["basin_fraction"].sum("attractor").values + b["unresolved_fraction"].values == (
        pytest.approx([1.0, 1.0])
    )
    assert b["basin_representative"].values.tolist() == [
        [0, 5, 3, -1, -1, -1],
        [8, 0, 7, 9, 2, 5],
    ]
    # mean t_final of members 3, 4, 6, 8 (cycle A at point 0): (300 + 400 + 600 + 800) / 4
    assert float(b["basin_settle_time"][0, 2]) == pytest.approx(525.0)
    assert b["basin_lnv_amplitude"][1].values.tolist()[1:5] == [5.0, 5.0, 5.05, 3.0]
    low, high = wilson_interval(4, 10)
    assert (
        float(b["basin_fraction_low"][0, 2]) == low
        and float(b["basin_fraction_high"][0, 2]) == high
    )
    assert b["K_over_Kc"].values.tolist() == [1.0, 1.1]
    assert all(b[v].attrs.get("units") for v in b.data_vars if v != "K_over_Kc")


def test_matching_tolerance_is_twice_the_accuracy():
    """Amplitudes 5.0 and 5.05 (1 % apart) are one cycle at accuracy 1e-2 (tolerance 2e-2)."""
    b = basin_fractions(_synthetic(), accuracy=1e-2)
    assert "cycle_1ev_3" not in b["attractor"].values
    assert int(b["basin_count"].sel(attractor="cycle_1ev")[1]) == 3


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="member dimension"):
        basin_fractions(_synthetic().isel(member=0))
    bare = _synthetic()
    bare.attrs = {}
    with pytest.raises(ValueError, match="classification_accuracy"):
        basin_fractions(bare)
    with pytest.raises(ValueError, match="lacks period"):
        basin_fractions(_synthetic().drop_vars("period"))


def test_larger_ensemble_keeps_the_first_members():
    """numpy's Generator fills the (members, 2 × blocks) offsets in C order, so the starts of
    an ensemble of M are the first M starts of any larger ensemble with the same seed."""
    from sweep.engine.grid import ensemble_offsets

    small = ensemble_offsets(sweep.with_changes(CONFIG, {"initial": {"ensemble": 8}}))
    large = ensemble_offsets(sweep.with_changes(CONFIG, {"initial": {"ensemble": 40}}))
    assert np.array_equal(small, large[:8])
    assert np.array_equal(large, np.random.default_rng(1).uniform(-1.0, 1.0, (40, 2)))
    # so the runs too: an ensemble of 3 is the first 3 members of one of 6, bit for bit
    point = {"sweep": {"K_W": {**AXIS_KEYS, "values": [0.052]}}}
    runs = [
        sweep.run(
            sweep.with_changes(CONFIG, {**point, "initial": {"ensemble": m}}),
            threads=1,
            progress=False,
        )
        for m in (3, 6)
    ]
    for name in ("lnv_final", "ln_state_final", "t_final", "n_steps", "regime"):
        assert np.array_equal(runs[0][name], runs[1][name].isel(member=slice(0, 3))), name


A, B = 0.03, 0.08


def _rhs(t, y, kappa, mass):
    lnv, psi, z = y
    dpsi = np.exp(-psi) - np.exp(lnv)
    dlnv = z * np.exp(-lnv) / mass
    return [dlnv, dpsi, kappa * (1.0 - np.exp(lnv)) - B * dpsi - A * dlnv]


def _jacobian(t, y, kappa, mass):
    lnv, psi, z = y
    v, decay = np.exp(lnv), np.exp(-psi)
    dlnv = z / (v * mass)
    return [
        [-dlnv, 0.0, 1.0 / (v * mass)],
        [-v, -decay, 0.0],
        [(B - kappa) * v + A * dlnv, B * decay, -A / (v * mass)],
    ]


def _scipy_attractor(lnv0, psi0, kappa, mass, window=100.0, t_max=4000.0):
    """ "cycle", "steady" or "unresolved" by the module docstring's rule."""
    y, t, spans = np.array([lnv0, psi0, 0.0]), 0.0, []
    while t < t_max:
        sol = solve_ivp(
            _rhs,
            (t, t + window),
            y,
            method="LSODA",
            rtol=1e-9,
            atol=1e-12,
            jac=_jacobian,
            args=(kappa, mass),
            dense_output=True,
        )
        assert sol.success, sol.message
        lnv = sol.sol(np.linspace(t, t + window, 4001))[0]
        spans.append(lnv.max() - lnv.min())
        y, t = sol.y[:, -1], t + window
        if len(spans) >= 2 and min(spans[-2:]) > 3.0:
            return "cycle"
        if len(spans) >= 2 and spans[-1] < 0.1 and spans[-1] < spans[-2]:
            return "steady"
    return "unresolved"


@pytest.mark.slow
def test_fractions_against_scipy_at_a_multistable_point():
    """At K/Kc = 1.006 (M̂ = 1e-3, subcritical Hopf) the engine's fraction of starts reaching
    the cycle holds SciPy's fraction of the same starts in its 95 % Wilson interval, and
    the two agree start by start."""
    kc_w = (B - A) * (1 + 1e-3 / A)  # per µm, D0 = 1 µm (physics brief, section 4)
    config = sweep.with_changes(
        CONFIG,
        {"sweep": {"K_W": {**AXIS_KEYS, "values": [RATIO * kc_w]}}},
    )
    ds = sweep.run(config, threads=1, progress=False)
    b = basin_fractions(ds).isel(K_W=0)
    assert float(b["K_over_Kc"]) == pytest.approx(RATIO, rel=1e-9)
    members, amplitude = config.initial.ensemble, config.initial.amplitude
    offsets = np.random.default_rng(config.initial.seed).uniform(
        -amplitude, amplitude, (members, 2)
    )
    reference = [
        _scipy_attractor(lnv, psi, RATIO * (B - A) * (1 + 1e-3 / A), 1e-3) for lnv, psi in offsets
    ]
    assert "unresolved" not in reference
    cycle = np.array([r == "cycle" for r in reference])
    fraction = cycle.mean()
    assert 0.1 < fraction < 0.9  # multistable: both basins hold a share of the starts
    engine = b.sel(attractor="cycle_1ev")
    assert float(engine["basin_fraction_low"]) <= fraction <= float(engine["basin_fraction_high"])
    engine_cycle = ds["attractor"].isel(K_W=0).values == 1
    assert (engine_cycle == cycle).mean() >= 0.95


def test_members_needed_for_a_width():
    """Point 0 of the synthetic ensemble: fractions 0.3, 0.2, 0.4 and 0.1 unresolved of 10;
    the widest at w = 0.2 is p = 0.4 (closest to 1/2), n from the width formula by hand."""
    b = basin_fractions(_synthetic())
    z = 1.959963984540054
    needed = members_needed(b, 0.2).values
    width = [2 * z * np.sqrt(0.4 * 0.6 / n + z**2 / (4 * n**2)) / (1 + z**2 / n) for n in (88, 89)]
    assert width[1] <= 0.2 < width[0]
    assert needed[0] == 89
    assert members_needed(b, 0.9).values.tolist() == [10, 10]  # never fewer than it has


def _described(ds):
    """The synthetic ensemble with the attributes and parameters a caption reads."""
    return ds.assign_coords(A=0.03, B=0.08, D0=1.0, V=0.1, m_W=0.1).assign_attrs(
        blocks=1,
        model="inertial",
        state_law="aging",
        initial_v_over_V=np.array([1.0]),
        initial_phi_over_phi_ss=np.array([1.0]),
        initial_amplitude=1.0,
        initial_seed=1,
    )


@pytest.mark.slow
def test_plot_over_one_axis_draws_the_fraction_and_its_interval(tmp_path):
    from sweep.plot import save_figure
    from sweep.plot.basins import plot_basin_fractions

    b = basin_fractions(_described(_synthetic()))
    fig = plot_basin_fractions(b, attractor="cycle_1ev_2")
    (ax,) = fig.axes
    band = ax.collections[0].get_paths()[0].vertices[:, 1]
    low, high = wilson_interval(np.array([4, 1]), 10)  # cycle_1ev_2: 4 and 1 of 10
    assert band.min() == pytest.approx(min(low)) and band.max() == pytest.approx(max(high))
    assert ax.lines[0].get_ydata().tolist() == [0.4, 0.1]
    title = fig._suptitle.get_text()
    for text in ("M̂ = mV²/(W·D0) = 0.001", "K/Kc = 1, 1.1", "10 members", "±1", "aging"):
        assert text in title
    assert save_figure(fig, tmp_path / "b.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="its attractors: steady"):
        plot_basin_fractions(b, attractor="cycle_3ev")


def test_plot_over_two_axes_maps_the_fraction_and_the_width():
    from sweep.plot.basins import plot_basin_fractions

    b = basin_fractions(_described(_synthetic()))
    two = b.drop_vars("m_W").expand_dims(m_W=[0.1, 0.2])
    fig = plot_basin_fractions(two, attractor="steady")
    fraction, width = (ax.collections[0].get_array() for ax in fig.axes[:2])
    assert np.asarray(fraction).ravel().tolist() == [0.3, 0.1, 0.3, 0.1]
    low, high = wilson_interval(np.array([3, 1]), 10)
    assert np.asarray(width).ravel() == pytest.approx(np.tile(high - low, 2))


def test_a_member_whose_regime_is_not_its_attractors_is_unresolved():
    ds = _synthetic()
    ds["regime"][0, 0] = 1  # stick_slip with attractor fixed_point
    b = basin_fractions(ds)
    assert int(b["basin_count"].sel(attractor="steady")[0]) == 2
    assert float(b["unresolved_fraction"][0]) == pytest.approx(0.2)


def test_basins_command_writes_fractions_and_figure(tmp_path, capsys):
    """``python -m sweep basins`` on a small ensemble of the multistable config: the
    fractions' NetCDF (with members_needed), the figure, and a line per attractor."""
    from sweep import cli

    config = sweep.with_changes(
        CONFIG, {"sweep": {"K_W": {**AXIS_KEYS, "values": [0.0518, 0.0522]}},
                 "initial": {"ensemble": 4}}
    )  # fmt: skip
    result = tmp_path / "ens.nc"
    sweep.write_netcdf(sweep.run(config, progress=False), result)
    out = tmp_path / "b.nc"
    status = cli.main(["basins", str(result), "--out", str(out), "--width", "0.3",
                       "--attractor", "steady"])  # fmt: skip
    assert status == 0
    text = capsys.readouterr().out
    assert "steady" in text and "members for every interval at most 0.3 wide" in text
    with xr.open_dataset(out) as ds:
        assert ds["members_needed"].dims == ("K_W",)
        assert (ds["members_needed"] >= 4).all()
        fractions = ds["basin_fraction"].sum("attractor") + ds["unresolved_fraction"]
        np.testing.assert_allclose(fractions, 1.0)
    assert out.with_suffix(".png").stat().st_size > 10_000


def test_basins_command_refuses_a_result_without_members(tmp_path, capsys):
    from sweep import cli

    result = tmp_path / "one.nc"
    config = sweep.with_changes(
        CONFIG, {"sweep": {"K_W": {**AXIS_KEYS, "values": [0.0518]}}, "initial": {"ensemble": 0}}
    )
    sweep.write_netcdf(sweep.run(config, progress=False), result)
    status = cli.main(["basins", str(result), "--out", str(tmp_path / "b.nc")])
    assert status == 2
    assert "initial.ensemble" in capsys.readouterr().err
    assert not (tmp_path / "b.nc").exists()


@pytest.mark.slow
def test_critical_kick_to_the_cycle_against_scipy():
    """Past the subcritical Hopf bifurcation (K/Kc = 1.004, 1.006) the smallest velocity
    jump that reaches the cycle, bisected by the engine to 1 %, is a basin boundary: SciPy
    (this module's reference) settles 2 % below it on steady sliding and 2 % above it on
    the cycle."""
    from sweep.codes import code
    from sweep.results.kicks import THRESHOLD_KINDS

    kc_w = (B - A) * (1 + 1e-3 / A)
    ratios = [1.004, 1.006]
    config = sweep.with_changes(
        CONFIG,
        {
            "sweep": {
                "K_W": {**AXIS_KEYS, "values": [r * kc_w for r in ratios]},
                "initial_v_over_V": {"start": 1.001, "stop": 100.0, "num": 9, "scale": "log"},
            },
            "initial": {"ensemble": 0},
        },
    )
    kicks = sweep.bisect_critical_kick(config, rtol=0.01, progress=False)
    assert (kicks["kick_threshold"] == code(THRESHOLD_KINDS, "basin_boundary")).all()
    for i, ratio in enumerate(ratios):
        kick = float(kicks["critical_kick"][i])
        kappa = ratio * (B - A) * (1 + 1e-3 / A)
        assert _scipy_attractor(np.log(kick / 1.02), 0.0, kappa, 1e-3) == "steady"
        assert _scipy_attractor(np.log(kick * 1.02), 0.0, kappa, 1e-3) == "cycle"
