"""Per-block parameters and the N-block config keys: coupling, lists, seeded spreads,
spread axes and initial-condition ensembles (sweep/model/heterogeneity.py,
sweep/config/, sweep/engine/grid.py)."""

import numpy as np
import pytest
from conftest import ROOT, make_config

from sweep.config import ConfigError, config_mapping, parse_config
from sweep.engine import grid
from sweep.kernels import layout
from sweep.model import heterogeneity

NB = {"blocks": 3, "parameters": {"k2_W": 0.02}}


def nblock_config(**sections):
    """A three-block config with ``sections`` merged in."""
    merged = {**NB, **sections}
    merged["parameters"] = {**NB["parameters"], **sections.get("parameters", {})}
    return make_config(merged)


# (id, overrides, the key path and the allowed values the message must name)
BAD = [
    ("unknown coupling", {"coupling": "star"}, "coupling must be one of chain, ring, all"),
    ("ring of two", {"blocks": 2, "coupling": "ring"}, "coupling ring needs blocks >= 3"),
    ("list too short", {"parameters": {"D0": [1.0, 1.3]}}, "parameters.D0 must be one number or "
     "a list of 3"),
    ("list value out of range", {"parameters": {"A": [0.03, -0.01, 0.03]}},
     "parameters.A[1] must be in (0, inf), got -0.01"),
    ("list of a shared parameter", {"parameters": {"V": [0.1, 0.1, 0.1]}}, "parameters.V must be"),
    ("unknown spread key", {"spread": {"mu0": 0.1}}, "unknown key spread.mu0"),
    ("negative spread", {"spread": {"D0": -0.1}}, "spread.D0 must be in [0, inf)"),
    ("bad distribution", {"spread": {"D0": 0.1, "distribution": "cauchy"}},
     "spread.distribution must be one of uniform, normal"),
    ("spread and list", {"parameters": {"D0": [1.0, 1.3, 0.8]}, "spread": {"D0": 0.1}},
     "spread.D0 and a list parameters.D0"),
    ("spread and axis", {"spread": {"D0": 0.1}, "sweep": {"K_W": [0.05], "spread_D0": [0.1]}},
     "spread.D0 is also a sweep axis"),
    ("spread too large", {"spread": {"K_W": 1.5}}, "spread.K_W = 1.5 makes K_W of block 2"),
    ("spread axis too large", {"sweep": {"K_W": [0.05], "spread_A": [0.0, 2.0]}},
     "sweep.spread_A = 2 makes A of block"),
    ("negative spread axis", {"sweep": {"K_W": [0.05], "spread_A": [-0.1]}},
     "sweep.spread_A[0] must be in [0, inf)"),
    ("spread axis of a shared parameter", {"sweep": {"K_W": [0.05], "spread_V": [0.1]}},
     "unknown sweep axis sweep.spread_V"),
    ("negative ensemble", {"initial": {"ensemble": -1}}, "initial.ensemble must be an integer"),
    ("negative amplitude", {"initial": {"ensemble": 2, "amplitude": -0.1}},
     "initial.amplitude must be in [0, inf)"),
]  # fmt: skip


@pytest.mark.parametrize("overrides, message", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_nblock_configs_are_refused_naming_the_key(overrides, message):
    with pytest.raises(ConfigError) as info:
        nblock_config(**overrides)
    assert any(message in p for p in info.value.problems), info.value.problems


def test_spread_on_one_block_is_refused():
    with pytest.raises(ConfigError, match="spread .per-block values. needs blocks >= 2"):
        make_config({"spread": {"D0": 0.1}})


def test_pattern_is_seeded_and_per_parameter():
    """The same seed gives the same pattern; each parameter has its own row, so the
    D0 pattern does not depend on whether A has a spread."""
    a = heterogeneity.spread_pattern(5, "uniform", 3)
    b = heterogeneity.spread_pattern(5, "uniform", 3)
    for name in heterogeneity.PER_BLOCK:
        np.testing.assert_array_equal(a[name], b[name])
        assert np.all(np.abs(a[name]) < 1.0)
    assert not np.array_equal(a["D0"], heterogeneity.spread_pattern(5, "uniform", 4)["D0"])
    with_a = nblock_config(spread={"D0": 0.1, "A": 0.2, "seed": 3})
    without = nblock_config(spread={"D0": 0.1, "seed": 3})
    d0 = [
        heterogeneity.block_values(c, grid.physical_parameters(c))["D0"] for c in (with_a, without)
    ]
    np.testing.assert_array_equal(d0[0], d0[1])


def test_spread_values_follow_the_stated_formula():
    """x_i = x (1 + s ξ_i) with the seed's pattern; a swept spread scales one realisation."""
    config = nblock_config(sweep={"K_W": [0.05], "spread_D0": [0.0, 0.1, 0.2]},
                           spread={"distribution": "normal", "seed": 5})  # fmt: skip
    values = heterogeneity.block_values(config, grid.physical_parameters(config))["D0"]
    xi = np.random.default_rng(5).standard_normal((4, 3))[2]  # D0 is the third row
    np.testing.assert_allclose(values, 1.0 * (1.0 + np.array([0.0, 0.1, 0.2])[:, None] * xi),
                               rtol=1e-15)  # fmt: skip
    assert np.all(values[0] == 1.0)  # no spread: exactly the common value


def test_list_values_reach_the_kernel_columns():
    """A D0 list: common D0 its mean; rate factors D0/D0_i, κ1_i = K D0/W."""
    d0 = [1.0, 1.3, 0.8]
    config = nblock_config(parameters={"D0": d0}, sweep={"K_W": [0.04, 0.05]})
    assert config.fixed["D0"] == pytest.approx(np.mean(d0), rel=1e-15)
    g = grid.build_grid(config)
    params, time_unit = g.params, g.time_unit
    nb, start = 3, layout.N_PARAMS
    assert params.shape == (2, start + layout.N_BLOCK_PARAMS * nb)
    rate = params[:, start + layout.B_RATE * nb : start + (layout.B_RATE + 1) * nb]
    np.testing.assert_allclose(rate, np.mean(d0) / np.array([d0, d0]), rtol=1e-15)
    kappa1 = params[:, start + layout.B_KAPPA1 * nb : start + (layout.B_KAPPA1 + 1) * nb]
    np.testing.assert_allclose(kappa1[:, 0], [0.04 * np.mean(d0), 0.05 * np.mean(d0)], rtol=1e-15)
    np.testing.assert_allclose(time_unit, np.mean(d0) / 0.1, rtol=1e-15)


def test_identical_blocks_keep_the_narrow_parameter_rows():
    """Without per-block values the kernels get N_PARAMS columns (the identical-block path)."""
    config = nblock_config(coupling="all")
    params = grid.build_grid(config).params
    assert params.shape[1] == layout.N_PARAMS


def test_ensemble_starts_are_seeded_and_shared_by_grid_points():
    config = nblock_config(initial={"ensemble": 4, "seed": 1, "amplitude": 0.2},
                           sweep={"K_W": [0.04, 0.05, 0.06]})  # fmt: skip
    assert config.run_shape == (3, 4)
    y0 = grid.build_grid(config).y0
    assert y0.shape == (12, 6)
    starts = y0.reshape(3, 4, 6)
    np.testing.assert_array_equal(starts[0], starts[2])  # the same M starts everywhere
    base = np.concatenate([np.zeros(3), np.full(3, np.log(1.01))])
    offsets = starts[0] - base
    assert np.all(np.abs(offsets) <= 0.2) and np.unique(offsets).size == offsets.size
    other = nblock_config(initial={"ensemble": 4, "seed": 2}, sweep={"K_W": [0.04]})
    assert not np.array_equal(grid.build_grid(other).y0, starts[0])


def test_config_mapping_round_trips_the_nblock_keys():
    config = nblock_config(
        coupling="ring", parameters={"D0": [1.0, 1.3, 0.8]}, spread={"A": 0.1, "seed": 4},
        initial={"ensemble": 3, "seed": 2, "amplitude": 0.05},
    )  # fmt: skip
    again = parse_config(config_mapping(config))
    for field in ("coupling", "block_parameters", "spread", "initial", "parameters"):
        assert getattr(again, field) == getattr(config, field)
    assert again.features == ("nblock", "heterogeneous", "ensemble", "events")


def test_every_multi_block_config_has_the_nblock_outputs():
    """A chain without the new keys gets the N-block outputs too (sync_order,
    slip_participation: any result of two or more blocks); one block does not."""
    assert nblock_config().features == ("nblock", "events")
    assert nblock_config(coupling="chain").features == ("nblock", "events")
    assert make_config().features == ("events",)
    assert make_config(classification={"events": 0}).features == ()


def test_parts_of_other_couplings_or_blocks_are_not_reused():
    """The part files' config hash sees the coupling, per-block values and spreads."""
    from sweep.io import parts as store

    base = nblock_config(coupling="ring", spread={"A": 0.1, "seed": 1})
    variants = [
        nblock_config(coupling="all", spread={"A": 0.1, "seed": 1}),
        nblock_config(spread={"A": 0.1, "seed": 1}),
        nblock_config(coupling="ring", spread={"A": 0.1, "seed": 2}),
        nblock_config(coupling="ring", spread={"A": 0.1, "seed": 1, "distribution": "normal"}),
        nblock_config(coupling="ring", spread={"A": 0.2, "seed": 1}),
        nblock_config(coupling="ring", spread={"A": 0.1, "seed": 1}, parameters={"D0": [1, 2, 1]}),
        nblock_config(coupling="ring", spread={"A": 0.1, "seed": 1}, initial={"ensemble": 2}),
    ]
    hashes = {store.config_hash(c) for c in variants}
    assert store.config_hash(base) not in hashes and len(hashes) == len(variants)


@pytest.mark.slow
def test_unequal_chain_example_loses_steady_sliding_at_its_own_kc():
    """configs/unequal_chain.yaml (D0 = 1.0/1.3/0.8 µm, K/W × k2/W, four starts): every
    start is steady above the stored Jacobian ``critical_K_W`` and none below, within
    one grid step, for every k2; that Kc moves with k2, towards the smallest D0's
    one-block (B − A)/D0 = 0.0625 µm⁻¹ as the blocks decouple."""
    import sweep

    ds = sweep.run(ROOT / "configs" / "unequal_chain.yaml", progress=False)
    step = float(np.diff(ds["K_W"].values)[0])
    steady = (ds["regime"] == layout.STEADY).all("member")
    for k2 in ds["k2_W"].values:
        kc = float(ds["critical_K_W"].sel(k2_W=k2).isel(K_W=0))
        k_w = ds["K_W"].values
        is_steady = steady.sel(k2_W=k2).values
        assert is_steady[k_w > kc + step].all() and not is_steady[k_w < kc - step].any(), k2
    kc = ds["critical_K_W"].isel(K_W=0).values
    assert np.ptp(kc) > 0.01  # µm⁻¹: the coupling moves Kc by more than ten grid steps
    assert 0.95 < kc[0] / ((0.08 - 0.03) / 0.8) < 1.0  # k2/W = 0.002 µm⁻¹
