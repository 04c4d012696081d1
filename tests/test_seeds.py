"""Realisations of the disorder: the sweep axis ``spread_seed`` (sweep/model/heterogeneity.py,
sweep/config/parse.py, sweep/engine/grid.py) and the statistics over it
(sweep/results/realisations.py).

The expected per-block values are drawn here with numpy's generator as the
heterogeneity docstring states it (ξ rows A, B, D0, K_W of ``default_rng(seed)``), and the
expected statistics are computed by hand, never by the code under test.
"""

import warnings

import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import config_dict, make_config

import sweep
from sweep.commands.trace import pin_config
from sweep.config import ConfigError, config_mapping, parse_config
from sweep.engine import grid
from sweep.results.dataset import extra_provenance, parameter_coords

NB = {"blocks": 3, "parameters": {"k2_W": 0.02}}
ROW = {"A": 0, "B": 1, "D0": 2, "K_W": 3}  # the order the pattern's rows are drawn in


def seeds_config(**sections):
    """A three-block config with ``sections`` merged in (nothing is run)."""
    merged = {**NB, **sections}
    merged["parameters"] = {**NB["parameters"], **sections.get("parameters", {})}
    return make_config(merged)


def pattern(seed, blocks=3, distribution="uniform"):
    """The pattern ξ of ``seed`` (4 rows: A, B, D0, K_W), drawn here independently."""
    rng = np.random.default_rng(seed)
    if distribution == "normal":
        return rng.standard_normal((4, blocks))
    return rng.uniform(-1.0, 1.0, (4, blocks))


def test_one_seed_axis_is_bit_identical_to_spread_seed():
    """sweep.spread_seed: [7] gives the per-block values and kernel rows of spread.seed: 7."""
    spread = {"D0": 0.2, "A": 0.1, "distribution": "normal"}
    sweep_axes = {"K_W": [0.04, 0.05], "spread_K_W": [0.0, 0.3]}
    axis = grid.build_grid(seeds_config(sweep={**sweep_axes, "spread_seed": [7]}, spread=spread))
    fixed = grid.build_grid(seeds_config(sweep=sweep_axes, spread={**spread, "seed": 7}))
    for name in ("A", "B", "D0", "K_W"):
        assert np.array_equal(axis.blocks[name], fixed.blocks[name]), name
    assert np.array_equal(axis.params, fixed.params)
    for name in ("growth_rate", "kappa_c", "omega"):
        assert np.array_equal(axis.linear[name], fixed.linear[name], equal_nan=True), name


def test_each_seed_gives_its_own_pattern():
    """x_i = x (1 + s ξ_i) with ξ the pattern of the row's own seed, at every K_W."""
    config = seeds_config(
        sweep={"K_W": [0.04, 0.05], "spread_seed": [3, 11]}, spread={"D0": 0.2, "K_W": 0.1}
    )
    g = grid.build_grid(config)
    kw = np.array([0.04, 0.04, 0.05, 0.05])
    seeds = [3, 11, 3, 11]  # C order: the last axis fastest
    d0 = np.array([1.0 * (1.0 + 0.2 * pattern(s)[ROW["D0"]]) for s in seeds])
    k = np.array([w * (1.0 + 0.1 * pattern(s)[ROW["K_W"]]) for w, s in zip(kw, seeds, strict=True)])
    np.testing.assert_allclose(g.blocks["D0"], d0, rtol=1e-15)
    np.testing.assert_allclose(g.blocks["K_W"], k, rtol=1e-15)
    assert not np.allclose(g.blocks["D0"][0], g.blocks["D0"][1])  # two realisations
    assert np.all(g.blocks["A"] == config.fixed["A"])  # no spread on A: exactly A


def test_a_rows_values_do_not_depend_on_the_split_of_the_work():
    """Rows built alone, in another order or as a chunk of the whole grid get the same
    per-block values and kernel rows: a row's pattern depends on its seed only."""
    config = seeds_config(
        sweep={"spread_seed": [5, 1, 9], "K_W": [0.03, 0.04, 0.05], "spread_D0": [0.1, 0.3]}
    )
    whole = grid.build_grid(config)
    names = [a.name for a in config.axes]
    points = grid.physical_parameters(config)
    for index in ([0], [17, 2, 9], np.arange(7, 18), np.arange(whole.n)[::-1]):
        part = grid.build_grid(config, {n: points[n][index] for n in names})
        chunk = whole.rows(np.asarray(index))
        for name in ("A", "B", "D0", "K_W"):
            assert np.array_equal(part.blocks[name], chunk.blocks[name]), (name, index)
        assert np.array_equal(part.params, chunk.params)
    seed = points["spread_seed"].astype(int)
    size = points["spread_D0"]
    expected = 1.0 + size[:, None] * np.array([pattern(s)[ROW["D0"]] for s in seed])
    np.testing.assert_allclose(whole.blocks["D0"], expected, rtol=1e-15)


def test_every_seed_is_checked_for_values_that_leave_the_interval():
    """A spread of 1.2 is fine for a seed whose D0 pattern stays above −1/1.2 and refused
    for one below it, naming that seed."""
    s = 1.2
    lows = {seed: pattern(seed)[ROW["D0"]].min() for seed in range(40)}
    good = [seed for seed, low in lows.items() if 1.0 + s * low > 0.0]
    bad = [seed for seed, low in lows.items() if 1.0 + s * low < 0.0]
    seeds_config(sweep={"K_W": [0.05], "spread_seed": good[:3]}, spread={"D0": s})
    with pytest.raises(ConfigError) as info:
        seeds_config(sweep={"K_W": [0.05], "spread_seed": [good[0], bad[0]]}, spread={"D0": s})
    (problem,) = info.value.problems
    assert "spread.D0 = 1.2 makes D0 of block" in problem
    assert f"pattern of seed {bad[0]}" in problem


SPREAD = {"spread": {"D0": 0.2}}
# (id, sections, the message the refusal must hold)
BAD = [
    ("repeated seed", {"sweep": {"K_W": [0.05], "spread_seed": [1, 2, 1]}, **SPREAD},
     "sweep.spread_seed must be distinct seeds; 1 given more than once"),
    ("negative seed", {"sweep": {"K_W": [0.05], "spread_seed": [1, -2]}, **SPREAD},
     "sweep.spread_seed[1] must be an integer in [0, 2147483647], got -2"),
    ("seed not an integer", {"sweep": {"K_W": [0.05], "spread_seed": [1.5]}, **SPREAD},
     "sweep.spread_seed[0] must be an integer"),
    ("seed too large", {"sweep": {"K_W": [0.05], "spread_seed": [2**31]}, **SPREAD},
     "sweep.spread_seed[0] must be an integer in [0, 2147483647]"),
    ("seed range", {"sweep": {"K_W": [0.05], "spread_seed": {"start": 1, "stop": 3, "num": 3}},
                    **SPREAD}, "sweep.spread_seed must be a non-empty list of distinct integers"),
    ("empty seed list", {"sweep": {"K_W": [0.05], "spread_seed": []}, **SPREAD},
     "sweep.spread_seed must be a non-empty list"),
    ("seed in two places", {"sweep": {"K_W": [0.05], "spread_seed": [1]},
                            "spread": {"D0": 0.2, "seed": 1}},
     "spread.seed is also a sweep axis (sweep.spread_seed); give it in one place only"),
    ("seeds without a spread", {"sweep": {"K_W": [0.05], "spread_seed": [1, 2]}},
     "sweep.spread_seed draws realisations of the spread's pattern, but no spread size is "
     "above 0"),
    ("seeds of a zero spread", {"sweep": {"K_W": [0.05], "spread_seed": [1, 2],
                                          "spread_D0": [0.0]}},
     "no spread size is above 0"),
    ("seeds of a list", {"sweep": {"K_W": [0.05], "spread_seed": [1, 2]},
                         "parameters": {"D0": [1.0, 1.2, 0.9]}},
     "no spread size is above 0"),
    ("seeds of one block", {"blocks": 1, "sweep": {"K_W": [0.05], "spread_seed": [1, 2]}},
     "sweep.spread_seed (seeds of a spread between blocks) needs blocks >= 2"),
    ("seeds and refine", {"sweep": {"K_W": [0.04, 0.05], "spread_seed": [1, 2]},
                          "refine": {"levels": 2}, **SPREAD},
     "refine cannot split sweep.spread_seed: seeds are realisations, not points of a range"),
    ("one seed and refine", {"sweep": {"K_W": [0.04, 0.05], "spread_seed": [1]},
                             "refine": {"levels": 2}, **SPREAD},
     "refine one realisation per config (spread.seed)"),
]  # fmt: skip


@pytest.mark.parametrize("sections, message", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_seed_axes_are_refused_naming_the_key(sections, message):
    with pytest.raises(ConfigError) as info:
        seeds_config(**sections)
    assert any(message in p for p in info.value.problems), info.value.problems
    assert info.value.source == "<test>"


def test_refine_is_accepted_with_the_seed_in_spread_seed():
    """What the refusal suggests works: a refined sweep of one realisation."""
    config = seeds_config(
        sweep={"K_W": [0.04, 0.05]}, refine={"levels": 2}, spread={"D0": 0.2, "seed": 2}
    )
    assert config.refine.levels == 2


def test_seed_axis_round_trips_and_is_an_integer_coordinate():
    config = seeds_config(sweep={"K_W": [0.05], "spread_seed": [4, 2]}, spread={"D0": 0.2})
    raw = config_mapping(config)
    assert raw["sweep"]["spread_seed"] == [4, 2]
    assert "seed" not in raw["spread"]  # given in one place: the axis
    assert parse_config(raw).axes == config.axes
    values, coord, attrs = parameter_coords(config)["spread_seed"]
    assert values == "spread_seed"
    assert coord.dtype == np.int32
    np.testing.assert_array_equal(coord, [4, 2])
    assert "each value one realisation of the disorder" in attrs["description"]
    assert "spread_seed" not in extra_provenance(config)  # the coordinate holds them
    plain = seeds_config(sweep={"K_W": [0.05]}, spread={"D0": 0.2, "seed": 4})
    assert extra_provenance(plain)["spread_seed"] == 4


def test_trace_pins_a_seed():
    config = seeds_config(sweep={"K_W": [0.05], "spread_seed": [4, 2]}, spread={"D0": 0.2})
    pinned = pin_config(config, {"K_W": 0.05, "spread_seed": 2})
    assert [(a.name, a.values) for a in pinned.axes] == [("K_W", (0.05,)), ("spread_seed", (2,))]
    fixed = seeds_config(sweep={"K_W": [0.05]}, spread={"D0": 0.2})
    assert pin_config(fixed, {"K_W": 0.05, "spread_seed": 6}).spread.seed == 6


def realisation_dataset():
    """Two K_W × three seeds: a float output with NaN and inf, an integer count with a
    fill value, a label, and a variable without the seed dimension."""
    b = np.array([[1.0, 3.0, np.inf], [np.nan, np.nan, 2.0]])  # inf: not finite, missing
    count = np.array([[2, -1, 4], [1, 1, 1]], np.int32)
    return xr.Dataset(
        {
            "b_value": (("K_W", "spread_seed"), b, {"units": "1", "long_name": "b-value"}),
            "slip_event_count": (
                ("K_W", "spread_seed"),
                count,
                {"units": "1", "long_name": "slip events", "_FillValue": np.int32(-1)},
            ),
            "regime": (
                ("K_W", "spread_seed"),
                np.array([[0, 1, 1], [1, 1, 1]], np.int8),
                {"flag_values": np.arange(4, dtype=np.int8)},
            ),
            "onset": ("K_W", [1.0, 2.0]),
        },
        coords={"K_W": [0.04, 0.05], "spread_seed": np.array([1, 2, 3], np.int32), "A": 0.01},
        attrs={"model": "quasi-static"},
    )


def test_over_realisations_by_hand():
    out = sweep.over_realisations(realisation_dataset())
    # K_W = 0.04: b values 1 and 3 (NaN and inf missing): mean 2, std sqrt(2), count 2;
    # K_W = 0.05: b value 2 only: mean 2, std NaN (one value), count 1
    np.testing.assert_allclose(out["b_value_mean"], [2.0, 2.0], rtol=1e-15)
    np.testing.assert_allclose(out["b_value_std"], [np.sqrt(2.0), np.nan], rtol=1e-15)
    np.testing.assert_array_equal(out["b_value_count"], [2, 1])
    assert out["b_value_count"].dtype == np.int32
    # counts 2, (fill), 4: mean 3, std sqrt(((2-3)^2 + (4-3)^2) / 1); 1, 1, 1: mean 1, std 0
    np.testing.assert_allclose(out["slip_event_count_mean"], [3.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(out["slip_event_count_std"], [np.sqrt(2.0), 0.0], rtol=1e-15)
    np.testing.assert_array_equal(out["slip_event_count_count"], [2, 3])
    assert "regime_mean" not in out and "onset_mean" not in out
    assert out.attrs["realisations_skipped"] == "regime"
    assert out.attrs["realisations"] == 3 and out.attrs["realisations_dim"] == "spread_seed"
    assert out.attrs["model"] == "quasi-static"
    assert "spread_seed" not in out.coords and float(out["A"]) == 0.01
    assert out["b_value_mean"].attrs["cell_methods"] == "spread_seed: mean"
    assert out["b_value_std"].attrs["cell_methods"] == "spread_seed: standard_deviation"
    assert "count - 1" in out["b_value_std"].attrs["comment"]


def test_over_realisations_matches_numpy_on_random_data():
    """Against numpy's nanmean / nanstd(ddof=1) over a random sample with NaN holes."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(4, 5, 7))
    x[rng.uniform(size=x.shape) < 0.3] = np.nan
    x[0, :, 0] = np.nan  # no finite value
    x[1, 1:, 0] = np.nan  # one
    ds = xr.Dataset({"x": (("a", "seed", "block"), x, {"units": "s"})})
    out = sweep.over_realisations(ds, dim="seed")
    n = np.isfinite(x).sum(axis=1)
    with warnings.catch_warnings():  # numpy warns of the empty and one-value slices
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(x, axis=1)
        std = np.where(n > 1, np.nanstd(x, axis=1, ddof=1), np.nan)
    np.testing.assert_allclose(out["x_mean"], mean, rtol=1e-13)
    np.testing.assert_allclose(out["x_std"], std, rtol=1e-12)
    np.testing.assert_array_equal(out["x_count"], n)
    assert n[0, 0] == 0 and n[1, 0] == 1 and np.isnan(out["x_mean"][0, 0])
    assert out["x_mean"].dims == ("a", "block") and out["x_std"].attrs["units"] == "s"


def test_over_realisations_refuses_what_it_cannot_reduce():
    with pytest.raises(ValueError, match="no dimension 'spread_seed'"):
        sweep.over_realisations(realisation_dataset().isel(spread_seed=0))
    with pytest.raises(TypeError, match="must be an xarray Dataset"):
        sweep.over_realisations(realisation_dataset()["b_value"])


@pytest.mark.slow
def test_seed_sweep_end_to_end(tmp_path):
    """``python -m sweep run`` of a three-block chain over two seeds (one row per chunk):
    each seed's runs are those of ``spread.seed`` with its value, bit for bit, the file's
    seed coordinate is int32 and described, and it passes the CF-1.11 checker."""
    from test_dataset import cf_report

    from sweep import cli
    from sweep.engine import runner

    sections = {
        "sweep": {"K_W": [0.04, 0.05], "spread_seed": [1, 2]},
        "spread": {"D0": 0.2},
        "integrator": {"t_end": 100.0},
        "classification": {"max_t_end": 100.0, "lyapunov": "never"},
    }
    path = tmp_path / "seeds.yaml"
    path.write_text(yaml.safe_dump(config_dict({**NB, "parameters": NB["parameters"]}, **sections)))
    out = tmp_path / "seeds.nc"
    args = ["run", str(path), "--out", str(out), "--threads", "1", "--chunk-size", "1", "--quiet"]
    assert cli.main(args) == 0
    with xr.open_dataset(out) as ds:
        ds.load()
    assert ds["spread_seed"].dtype == np.int32
    assert "one realisation of the disorder" in ds["spread_seed"].attrs["description"]
    for seed in (1, 2):
        one = seeds_config(
            sweep={"K_W": [0.04, 0.05]}, spread={"D0": 0.2, "seed": seed},
            integrator=sections["integrator"], classification=sections["classification"],
        )  # fmt: skip
        alone = runner.compute(one, threads=1, show_progress=False)
        expected = 1.0 + 0.2 * pattern(seed)[ROW["D0"]]
        np.testing.assert_allclose(alone["D0_block"].isel(K_W=0), expected, rtol=1e-15)
        for name in alone.data_vars:
            a, b = ds[name].sel(spread_seed=seed).values, alone[name].values
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    means = sweep.over_realisations(ds)["D0_block_mean"]
    hand = 1.0 + 0.2 * (pattern(1)[ROW["D0"]] + pattern(2)[ROW["D0"]]) / 2.0
    np.testing.assert_allclose(means.isel(K_W=1), hand, rtol=1e-15)
    report = cf_report(out, tmp_path)
    failed = [c["name"] for c in report["all_priorities"] if c["value"][0] < c["value"][1]]
    assert failed == []
