"""N blocks end to end: the transition of identical blocks with every coupling, of
unequal blocks at the Jacobian's prediction, the two-block chain unchanged, and
initial-condition ensembles independent of chunking and threads."""

import numpy as np
import pytest
from conftest import KC_W, config_dict

import sweep
from sweep.variables import REGIMES

STEADY = REGIMES.index("steady")


def nblock(blocks, coupling, **sections):
    """A quasi-static config of ``blocks`` blocks started off their in-phase motion:
    Φ_i/Φss = 1.01 + 0.005 sin(1.7 i) excites every mode."""
    phi = [1.01 + 0.005 * np.sin(1.7 * i) for i in range(blocks)]
    base = config_dict(
        {"blocks": blocks, "coupling": coupling, "parameters": {"k2_W": 0.02},
         "initial": {"v_over_V": 1.0, "phi_over_phi_ss": phi},
         "integrator": {"t_end": 1500.0}},
    )  # fmt: skip
    return config_dict(base, **sections) if sections else base


def transition_is_between(ds, lower, upper):
    """Steady at every K/W ≥ upper, not steady at every K/W ≤ lower (all other axes)."""
    regime = ds.regime
    above = regime.sel(K_W=ds.K_W[ds.K_W >= upper])
    below = regime.sel(K_W=ds.K_W[ds.K_W <= lower])
    return bool((above == STEADY).all()) and bool((below != STEADY).all())


# one grid step of 0.002 um-1 on each side of Kc/W = 0.05 um-1 (4 % of Kc)
K_GRID = [0.046, 0.048, 0.052, 0.054]


@pytest.mark.slow
@pytest.mark.parametrize("blocks", [3, 8, 32])
@pytest.mark.parametrize("coupling", ["chain", "ring", "all"])
def test_identical_blocks_switch_at_the_one_block_kc(blocks, coupling):
    """Identical blocks, every coupling and k2: steady above Kc/W = (B − A)/D0, not
    below, within one grid step (the in-phase mode never stretches a coupling spring)."""
    cfg = nblock(blocks, coupling, parameters={"k2_W": None},
                 sweep={"K_W": K_GRID, "k2_W": [0.002, 0.1]})  # fmt: skip
    ds = sweep.run(cfg, threads=2, progress=False)
    assert transition_is_between(ds, 0.048, 0.052), ds.regime.values
    np.testing.assert_allclose(ds.critical_K_W, KC_W, rtol=1e-12)  # analytic: (B − A)/D0


@pytest.mark.slow
@pytest.mark.parametrize(
    "blocks, coupling, extra",
    [
        (3, "chain", {"parameters": {"D0": [1.0, 1.3, 0.8]}}),
        (4, "ring", {"spread": {"D0": 0.3, "B": 0.1, "seed": 2}}),
        (5, "all", {"spread": {"A": 0.2, "K_W": 0.1, "distribution": "normal", "seed": 1}}),
    ],
    ids=["chain-D0-list", "ring-D0-B-spread", "all-A-K-normal"],
)
def test_unequal_blocks_switch_at_the_jacobian_prediction(blocks, coupling, extra):
    """Unequal blocks: steady above the stored critical_K_W and not below it, within one
    grid step (2 % of Kc) on each side."""
    cfg = nblock(blocks, coupling, **extra, sweep={"K_W": [0.05]})
    kc = float(sweep.run(cfg, progress=False).critical_K_W[0])
    assert abs(kc / KC_W - 1) > 0.01  # unequal blocks move Kc off the one-block value
    grid_k = [kc * f for f in (0.96, 0.98, 1.02, 1.04)]
    ds = sweep.run(sweep.with_changes(cfg, {"sweep": {"K_W": grid_k}}), threads=2, progress=False)
    assert transition_is_between(ds, 0.99 * kc, 1.01 * kc), ds.regime.values
    np.testing.assert_allclose(ds.K_over_Kc, np.array(grid_k) / kc, rtol=1e-12)
    assert np.all((ds.linear_growth_rate > 0) == (ds.K_W < kc))


@pytest.mark.slow
def test_critical_stiffness_varies_along_a_spread_axis():
    """A swept spread: zero spread gives the analytic Kc; the pattern is scaled."""
    cfg = nblock(4, "ring", sweep={"K_W": [0.05], "spread_D0": [0.0, 0.1, 0.2]},
                 integrator={"t_end": 10.0})  # fmt: skip
    ds = sweep.run(cfg, progress=False)
    kc = ds.critical_K_W.sel(K_W=0.05).values
    assert kc[0] == KC_W  # identical blocks: the analytic value, exactly
    assert abs(kc[1] - KC_W) > 1e-4 and abs(kc[2] - kc[1]) > 1e-4
    np.testing.assert_allclose(
        ds.D0_block.sel(K_W=0.05, spread_D0=0.0), 1.0, rtol=0
    )  # no spread: exactly the common value


@pytest.mark.slow
def test_two_block_chain_is_the_existing_two_block_model():
    """Naming the coupling (chain) and passing through the per-block columns (a zero
    spread) changes no number of the two-block model."""
    cfg = config_dict(
        {"blocks": 2, "parameters": {"k2_W": 0.001}, "sweep": {"K_W": [0.0495, 0.06]},
         "initial": {"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.05, 0.95]},
         "integrator": {"t_end": 1500.0}},
    )  # fmt: skip
    old = sweep.run(cfg, threads=1, progress=False)
    named = sweep.run(config_dict(cfg, coupling="chain"), threads=1, progress=False)
    zero = sweep.run(config_dict(cfg, spread={"D0": 0.0}), threads=1, progress=False)
    for var in old.data_vars:
        np.testing.assert_array_equal(named[var].values, old[var].values, err_msg=var)
        np.testing.assert_array_equal(zero[var].values, old[var].values, err_msg=var)


@pytest.mark.slow
def test_ensemble_does_not_depend_on_chunks_or_threads():
    cfg = nblock(3, "ring", sweep={"K_W": [0.046, 0.054]},
                 initial={"ensemble": 5, "seed": 3, "amplitude": 0.3},
                 integrator={"t_end": 400.0})  # fmt: skip
    config = sweep.load_config(cfg)
    a = sweep.engine.runner.compute(config, threads=1, chunk_size=1, show_progress=False)
    b = sweep.engine.runner.compute(config, threads=2, chunk_size=7, show_progress=False)
    for var in a.data_vars:
        np.testing.assert_array_equal(a[var].values, b[var].values, err_msg=var)
    assert a.regime.dims == ("K_W", "member")
    assert a.regime_fraction.dims == ("K_W", "regime_name")
    np.testing.assert_allclose(a.regime_fraction.sum("regime_name"), 1.0, rtol=1e-15)
    counts = [(a.regime.sel(K_W=0.054) == k).mean() for k in range(len(REGIMES))]
    np.testing.assert_array_equal(a.regime_fraction.sel(K_W=0.054), counts)
    assert not np.array_equal(a.lnv_final.values[0, 0], a.lnv_final.values[0, 1])


def test_linear_theory_is_computed_once_per_parameter_set():
    """Repeated rows (an ensemble, a swept K) share one critical-stiffness search."""
    cfg = sweep.load_config(nblock(3, "chain", parameters={"D0": [1.0, 1.3, 0.8]},
                                   sweep={"K_W": [0.04, 0.05, 0.06]}))  # fmt: skip
    kc = sweep.engine.grid.build_grid(cfg).linear["kappa_c"]
    assert np.unique(kc).size == 1


@pytest.mark.slow
def test_weakly_coupled_blocks_slip_one_at_a_time():
    """Physics brief, section 4: two blocks with k2/W = 0.001 µm⁻¹ at K/Kc = 0.99
    started in anti-phase settle on a bounded out-of-phase cycle: every slip event
    involves one of the two blocks, and their phases are apart (R < 1)."""
    cfg = config_dict(
        {"blocks": 2, "coupling": "chain", "parameters": {"k2_W": 0.001},
         "sweep": {"K_W": [0.99 * KC_W]},
         "initial": {"v_over_V": 1.0, "phi_over_phi_ss": [1.05, 0.95]},
         "integrator": {"t_end": 3000.0}},
    )  # fmt: skip
    ds = sweep.run(cfg, progress=False).isel(K_W=0)
    assert REGIMES[int(ds.regime)] == "stick_slip"
    assert float(ds.slip_participation) == 0.5
    assert 0.5 < float(ds.sync_order) < 0.99


@pytest.mark.slow
def test_identical_starts_stay_in_phase():
    """Identical blocks started identically move as one: R = 1 and every block takes
    part in every slip (quasi-dynamic limit cycle well below Kc)."""
    cfg = config_dict(
        {"blocks": 4, "coupling": "ring", "model": "quasi-dynamic",
         "parameters": {"k2_W": 0.05, "eta_W": 0.1}, "sweep": {"K_W": [0.03]},
         "integrator": {"t_end": 2000.0}},
    )  # fmt: skip
    ds = sweep.run(cfg, progress=False).isel(K_W=0)
    assert REGIMES[int(ds.regime)] == "stick_slip"
    assert float(ds.sync_order) == pytest.approx(1.0, abs=1e-12)  # cos of round-off phases
    assert float(ds.slip_participation) == 1.0


@pytest.mark.slow
def test_extending_an_ensemble_updates_its_regime_fractions(tmp_path):
    """``extend`` continues undecided members and recounts regime_fraction."""
    from sweep.commands import extend

    cfg = nblock(3, "ring", parameters={"D0": [1.0, 1.3, 0.8]}, sweep={"K_W": [0.046, 0.049]},
                 initial={"ensemble": 3, "seed": 0}, integrator={"t_end": 50.0},
                 classification={"max_t_end": 50.0})  # fmt: skip
    ds = sweep.run(cfg, progress=False)
    assert (ds.regime == REGIMES.index("undecided")).all()
    path = tmp_path / "e.nc"
    sweep.write_netcdf(ds, path)
    out, n = extend.extend_file(path, t_end=3000.0)
    assert n == 6 and not (out.regime == REGIMES.index("undecided")).all()
    counts = [(out.regime == k).mean("member") for k in range(len(REGIMES))]
    np.testing.assert_array_equal(out.regime_fraction.transpose("regime_name", "K_W"), counts)


@pytest.mark.slow
@pytest.mark.parametrize("model_name", ["quasi-static", "inertial"])
def test_sixty_four_unequal_blocks_run(model_name):
    """64 unequal blocks, every pair coupled (the dense Jacobian of the Rosenbrock
    method for the inertial model, named: at this size the default is the structured
    solve): the runs end with finite statistics and a critical stiffness near the
    one-block value (spreads of a few per cent)."""
    extra = {"m_W": 0.01} if model_name == "inertial" else {}
    method = {"method": "rosenbrock"} if model_name == "inertial" else {}
    cfg = nblock(64, "all", model=model_name, parameters={"k2_W": 0.01, **extra},
                 spread={"D0": 0.05, "A": 0.05, "seed": 3}, sweep={"K_W": [0.045, 0.055]},
                 integrator={"t_end": 5.0, **method})  # fmt: skip
    ds = sweep.run(cfg, threads=2, progress=False)
    assert np.isfinite(ds.lnv_final).all() and (ds.n_steps > 0).all()
    kc = ds.critical_K_W.values
    assert kc[0] == kc[1] and abs(kc[0] / KC_W - 1) < 0.2  # inertia raises Kc by 1 + M/A
    assert ds.D0_block.sizes["block"] == 64
