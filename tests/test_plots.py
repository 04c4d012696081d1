"""Figures (sweep/plot/, sweep/commands/figures.py): phase diagrams, bifurcation, paper figures."""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import python_stdout

from sweep.cli import main
from sweep.config import config_mapping, load_config, parse_config, with_changes
from sweep.engine.runner import compute
from sweep.io.netcdf import write_netcdf
from sweep.plot import plot_bifurcation, plot_result, plot_variable, save_figure
from sweep.plot.bifurcation import bifurcation_curves
from sweep.plot.common import REGIME_COLOURS, axis_label, stiffness_ratio, unit_text
from sweep.plot.maps import critical_crossings
from sweep.variables import REGIMES

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
PAPER_FIGURES = (
    "fig1_one_block", "fig2_two_blocks", "phase_twoblock", "bifurcation", "nblock",
    "route_to_chaos", "floquet", "refined_unequal_qd", "long_chain", "catalogue_threshold",
    "fast_events", "critical_kick", "basins",
)  # fmt: skip


def small(path, name, **changes):
    """A config from ``path`` with changes: ``sweep`` replaces the axes, other mappings
    (parameters, integrator, ...) are updated key by key."""
    raw = config_mapping(load_config(path))
    raw["name"] = name
    for key, value in changes.items():
        merge = key != "sweep" and isinstance(raw.get(key), dict)
        raw[key] = {**raw[key], **value} if merge else value
    return parse_config(raw, f"{path} ({name})")


def saved(fig, path):
    """``fig`` written to ``path`` (the format from the suffix); returns the path."""
    return save_figure(fig, path)


def assert_png(path, min_bytes=10_000):
    """A real, non-trivial PNG: right magic bytes, decodable, not a blank canvas."""
    import matplotlib.image

    data = Path(path).read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > min_bytes
    pixels = matplotlib.image.imread(path)
    assert min(pixels.shape[:2]) > 200 and pixels[..., :3].std() > 0.05


@pytest.fixture(scope="module")
def one_d():
    return compute(load_config(CONFIGS / "quick.yaml"), show_progress=False)


@pytest.fixture(scope="module")
def two_d():
    config = small(
        CONFIGS / "twoblock.yaml",
        "twoblock_small",
        sweep={"K_W": [0.04, 0.045, 0.0475, 0.0525, 0.055, 0.06], "k2_W": [0.0, 0.05, 0.1]},
        integrator={"t_end": 1000.0},
    )
    return compute(config, show_progress=False)


@pytest.fixture(scope="module")
def quasi_dynamic():
    config = small(
        CONFIGS / "bifurcation_qd.yaml",
        "qd_small",
        sweep={"eta_W": [0.01, 0.1], "K_W": [0.03, 0.035, 0.0375, 0.045, 0.05]},
    )
    return compute(config, show_progress=False)


def test_every_regime_has_its_own_colour():
    assert set(REGIME_COLOURS) == set(REGIMES)
    assert len(set(REGIME_COLOURS.values())) == len(REGIMES)


@pytest.mark.parametrize(
    "units, text",
    [
        ("um-1", "µm⁻¹"),
        ("s um-1", "s µm⁻¹"),
        ("um s-1", "µm s⁻¹"),
        ("s2 um-1", "s² µm⁻¹"),
        ("1", ""),
        ("s", "s"),
    ],
)
def test_unit_text(units, text):
    assert unit_text(units) == text


def test_critical_line_sits_at_the_analytic_kc(one_d, two_d):
    # Kc/W = (B - A)/D0 = 0.05 um^-1 (physics brief, section 3); K/Kc is linear in K,
    # so interpolating between grid points is exact up to rounding (1e-12).
    (kc,) = critical_crossings(one_d["K_W"].values, one_d["K_over_Kc"].values)
    assert kc == pytest.approx((0.08 - 0.03) / 1.0, rel=1e-12)
    for j in range(two_d.sizes["k2_W"]):
        ratio = two_d["K_over_Kc"].isel(k2_W=j).values
        (kc,) = critical_crossings(two_d["K_W"].values, ratio)
        assert kc == pytest.approx(0.05, rel=1e-12)


@pytest.mark.slow
def test_no_critical_line_or_curve_point_where_kc_is_not_positive(tmp_path):
    # Radiation damping eta V/W >= B - A makes steady sliding stable at every K
    # (Kc <= 0, physics brief section 4); K/Kc is then meaningless and must not
    # produce a second crossing or bifurcation points at K/Kc < 0.
    config = small(
        CONFIGS / "bifurcation_qd.yaml",
        "eta_sweep",
        parameters={"K_W": 0.045},
        sweep={"eta_W": {"values": [0.01, 0.03, 0.1, 0.3, 0.6, 1.0]}},
    )
    ds = compute(config, show_progress=False)
    eta = ds["eta_W"].values
    (crossing,) = critical_crossings(eta, stiffness_ratio(ds).values)
    # K/Kc = (K/W) D0 / (B - A - eta V/W) = 1 at eta/W = 0.05 s/um; the line is drawn by
    # linear interpolation of K/Kc between the grid points 0.03 and 0.1, whose value
    # follows from the closed form (to rounding, 1e-12), a little off 0.05 (K/Kc is
    # convex in eta)
    ratio = {e: 0.045 / (0.08 - 0.03 - e * 0.1) for e in (0.03, 0.1)}
    expected = 0.03 + (1 - ratio[0.03]) / (ratio[0.1] - ratio[0.03]) * (0.1 - 0.03)
    assert crossing == pytest.approx(expected, rel=1e-12)
    assert abs(expected - 0.05) < 0.005
    ((_, curve),) = bifurcation_curves(ds)
    assert curve.sizes["eta_W"] == np.count_nonzero(eta * 0.1 < 0.05)
    assert np.all(curve["K_over_Kc"].values > 0)
    assert_png(saved(plot_result(ds), tmp_path / "eta.png"))


def test_phase_diagram_of_a_1d_sweep(one_d, tmp_path):
    assert_png(saved(plot_result(one_d), tmp_path / "one_d.png"))


@pytest.mark.slow
def test_phase_diagram_of_a_2d_sweep(two_d, tmp_path):
    assert_png(saved(plot_result(two_d), tmp_path / "two_d.png"))


def test_phase_diagram_draws_into_a_given_axes(one_d, two_d):
    """plot_result(ds, ax=ax), as a user lays out a figure: only the regime panel, on
    that axes (2-D: the regime map with its legend counting every run; 1-D: the first
    measure coloured by regime), and no other axes added."""
    from matplotlib.figure import Figure

    fig = Figure()
    left, right = fig.subplots(1, 2)
    assert plot_result(two_d, ax=left) is fig
    assert len(fig.axes) == 2 and not right.has_data()
    assert left.get_xlabel() == axis_label(two_d[two_d.regime.dims[0]])
    assert left.get_ylabel() == axis_label(two_d[two_d.regime.dims[1]])
    counts = [int(t.get_text().split("(")[1].rstrip(")")) for t in left.get_legend().get_texts()]
    assert sum(counts) == two_d.regime.size
    assert plot_result(one_d, ax=right) is fig
    assert sum(len(c.get_offsets()) for c in right.collections) == one_d.regime.size


def test_bifurcation_curves_one_per_model_and_damping(one_d, quasi_dynamic):
    labels = [label for label, _ in bifurcation_curves(one_d)]
    assert labels == ["quasi-static"]
    curves = list(bifurcation_curves(quasi_dynamic))
    # eta_hat = eta V / W with V = 0.1 um/s
    assert [label for label, _ in curves] == [
        "quasi-dynamic, η̂ = ηV/W = 0.001",
        "quasi-dynamic, η̂ = ηV/W = 0.01",
    ]
    for _, curve in curves:
        assert curve["K_over_Kc"].dims == ("K_W",)
        assert np.all(np.diff(curve["K_over_Kc"].values) > 0)


@pytest.mark.slow
def test_bifurcation_diagram(one_d, quasi_dynamic, tmp_path):
    assert_png(saved(plot_bifurcation([one_d, quasi_dynamic]), tmp_path / "bifurcation.png"))


@pytest.mark.slow
def test_plot_and_bifurcation_commands(one_d, quasi_dynamic, tmp_path):
    qs = write_netcdf(one_d, tmp_path / "qs.nc")
    qd = write_netcdf(quasi_dynamic, tmp_path / "qd.nc")
    assert main(["plot", str(qs)]) == 0
    assert_png(tmp_path / "qs.png")
    assert main(["bifurcation", str(qs), str(qd), "--out", str(tmp_path / "b.png")]) == 0
    assert_png(tmp_path / "b.png")


def test_plot_command_rejects_a_missing_file(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "none.nc")]) == 2
    assert "cannot read result file" in capsys.readouterr().err


def test_plot_commands_reject_what_they_cannot_draw_or_write(tmp_path, capsys):
    """Exit 2 with one line, no traceback and no file: a single-point result, a
    non-PNG output name, an output under a regular file."""
    single = compute(small(CONFIGS / "quick.yaml", "single", sweep={"K_W": [0.04]}),
                     show_progress=False)  # fmt: skip
    path = write_netcdf(single, tmp_path / "single.nc")
    (tmp_path / "afile").write_text("")
    for argv in (
        ["plot", str(path)],
        ["plot", str(path), "--out", str(tmp_path / "x.txt")],
        ["bifurcation", str(path), "--out", str(tmp_path / "afile" / "b.png")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "single.nc"]


def test_bifurcation_of_runaways_only(tmp_path):
    """Every run below Kc runs away: the diagram still draws (runaway markers only)."""
    ds = compute(small(CONFIGS / "quick.yaml", "runaways", sweep={"K_W": [0.03, 0.04]}),
                 show_progress=False)  # fmt: skip
    assert set(ds["regime"].values) == {REGIMES.index("runaway")}
    assert_png(saved(plot_bifurcation([ds]), tmp_path / "b.png"), min_bytes=5_000)


def test_bifurcation_configs_show_the_jump_and_the_continuous_onset():
    """What the bifurcation figure claims (physics brief, section 4)."""
    qs = compute(load_config(CONFIGS / "bifurcation_qs.yaml"), show_progress=False)
    ratio = qs["K_over_Kc"].values
    regime = qs["regime"].values
    # quasi-static: every K < Kc runs away, every K > Kc decays (the jump)
    assert np.all(regime[ratio < 1 - 1e-9] == REGIMES.index("runaway"))
    assert np.all(regime[ratio > 1 + 1e-9] == REGIMES.index("steady"))
    qd = compute(load_config(CONFIGS / "bifurcation_qd.yaml"), show_progress=False)
    for label, curve in bifurcation_curves(qd):
        ratio = curve["K_over_Kc"].values
        regime = curve["regime"].values
        below, above = ratio < 1 - 1e-9, ratio > 1 + 1e-9
        assert np.all(regime[below] == REGIMES.index("stick_slip")), label
        assert np.all(regime[above] == REGIMES.index("steady")), label
        # the cycle shrinks continuously towards Kc: amplitude falls as K rises
        amplitude = curve["lnv_amplitude"].values[below]
        assert np.all(np.diff(amplitude) < 0), label


def test_quasi_dynamic_cycle_near_onset_matches_the_physics_brief():
    # Physics brief, section 4 (checked there): eta_hat = 0.01, K = 0.99 Kc gives a
    # limit cycle with v_max/V ~ 1.6; quoted to two digits, hence +-0.05.
    config = small(
        CONFIGS / "bifurcation_qd.yaml", "qd_onset", sweep={"eta_W": [0.1], "K_W": [0.99 * 0.04]}
    )
    ds = compute(config, show_progress=False)
    assert int(ds["regime"].item()) == REGIMES.index("stick_slip")
    assert float(ds["v_max"].item() / 0.1) == pytest.approx(1.6, abs=0.05)


@pytest.mark.slow
def test_make_figures_on_small_configs(tmp_path):
    from sweep.commands.figures import make_figures

    paper = small(CONFIGS / "paper.yaml", "paper_small", integrator={"t_end": 400.0})
    twoblock = small(
        CONFIGS / "twoblock.yaml",
        "twoblock_small",
        sweep={"K_W": [0.045, 0.055], "k2_W": [0.0, 0.1]},
        integrator={"t_end": 500.0},
    )
    qs = small(CONFIGS / "bifurcation_qs.yaml", "qs_small", sweep={"K_W": [0.04, 0.045, 0.055]})
    nblock, heterogeneous = small_nblock_configs()
    route = small(CONFIGS / "route_to_chaos.yaml", "route_small",
                  sweep={"K_W": [0.0042, 0.005]}, classification={"max_t_end": 3000.0})  # fmt: skip
    refined = small(CONFIGS / "unequal_qd.yaml", "unequal_qd", refine={"levels": 2},
                    sweep={"K_W": [0.05, 0.07], "k2_W": [0.005, 0.02]})  # fmt: skip
    chain = small(CONFIGS / "long_chain.yaml", "long_chain", blocks=8,
                  initial={"v_over_V": 1.0, "phi_over_phi_ss": 1.05},
                  sweep={"k2_W": [0.05, 0.2], "spread_D0": [0.0, 0.2]},
                  integrator={"t_end": 400.0})  # fmt: skip
    damped = small(CONFIGS / "quasidynamic.yaml", "damped_small",
                   sweep={"K_W": [0.03, 0.045], "eta_W": [0.05, 0.1]})  # fmt: skip
    kicks = [
        small(CONFIGS / f"kick_{law}_law.yaml", f"kick_{law}",
              sweep={"K_W": [0.055, 0.085], "initial_v_over_V": [1.0, 1e5]})
        for law in ("slip", "aging")
    ]  # fmt: skip
    basins = small(CONFIGS / "basins.yaml", "basins_small", sweep={"K_W": [0.0518, 0.0522]},
                   initial={"ensemble": 4})  # fmt: skip
    paths = []
    for config in (paper, twoblock, qs, nblock, heterogeneous, route, refined, chain, damped,
                   *kicks, basins):  # fmt: skip
        path = tmp_path / f"{config.name}.yaml"
        path.write_text(config.text)
        paths.append(path)
    out = make_figures(
        paths[0], paths[1], (paths[2],), nblock=paths[3:5], route=paths[5],
        out_dir=tmp_path / "figures", threads=1, refined=paths[6], long_chain=paths[7],
        damped=paths[8], kicks=paths[9:11], basins=paths[11],
    )  # fmt: skip
    assert [p.stem for p in out] == list(PAPER_FIGURES)
    for path in out:
        assert_png(path)


def small_nblock_configs():
    """configs/nblock.yaml and configs/heterogeneous.yaml on 2 x 2 grids; the second
    includes points where its four starts disagree (in the full map; nblock's starts
    agree everywhere: SciPy confirms the cycle its last mixed point's two runaways
    settle on, docs/changelog.md)."""
    nblock = small(
        CONFIGS / "nblock.yaml",
        "nblock_small",
        sweep={"K_W": [0.0495, 0.054], "k2_W": [0.01, 0.03]},
    )
    heterogeneous = small(
        CONFIGS / "heterogeneous.yaml",
        "heterogeneous_small",
        sweep={"K_W": [0.0435, 0.054], "spread_D0": [0.0, 0.25]},
    )
    return nblock, heterogeneous


@pytest.mark.slow
def test_nblock_figure_draws_the_ensemble_and_kc():
    """Panels 2 and 3: the regime of most starts in each cell (hatched where they
    disagree, in the heterogeneous map at least one), the stored critical_K_W as a
    dashed line; panel 1 one curve per coupling."""
    import xarray as xr
    from matplotlib.patches import Rectangle

    from sweep.plot import plot_nblock

    nblock, heterogeneous = (compute(c, show_progress=False) for c in small_nblock_configs())
    sizes = xr.DataArray(
        np.ones((2, 3, 2)),
        dims=("coupling", "blocks", "seed"),
        coords={"coupling": ["chain", "all"], "blocks": [3, 4, 8]},
    )
    fig = plot_nblock(sizes, heterogeneous, nblock)
    assert len(fig.axes[0].get_lines()) == 3  # two couplings and the identical-block line
    for ax, ds in zip(fig.axes[1:], (heterogeneous, nblock), strict=True):
        mixed = int((ds.regime_fraction.max("regime_name") < 1).sum())
        hatched = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_hatch()]
        assert len(hatched) == mixed
        kc = ds.critical_K_W.isel(K_W=0).values
        np.testing.assert_array_equal(ax.get_lines()[0].get_xdata(), kc)
        dominant = ds.regime_fraction.argmax("regime_name").transpose(*ax_dims(ds)).values
        np.testing.assert_array_equal(
            np.asarray(ax.collections[0].get_array()).ravel(), dominant.ravel()
        )
    assert (heterogeneous.regime_fraction.max("regime_name") < 1).any()  # a hatched cell


def ax_dims(ds):
    """The (y, x) dimensions of a regime map of ``ds``."""
    xdim, ydim = (d for d in ds.regime_fraction.dims if d != "regime_name")
    return ydim, xdim


@pytest.mark.parametrize("name", PAPER_FIGURES)
def test_committed_figures_are_present_and_small(name):
    path = ROOT / "results" / f"{name}.png"
    assert_png(path)
    assert path.stat().st_size < 300_000


@pytest.mark.slow
def test_plots_are_figures_drawn_without_pyplot(one_d, tmp_path):
    """Library plots return Figures and never touch pyplot or the backend (a notebook's
    backend stays as it is); run in a fresh process to see what gets imported."""
    result = write_netcdf(one_d, tmp_path / "q.nc")
    code = f"""
import sys, matplotlib
matplotlib.use = lambda *args, **kwargs: sys.exit("matplotlib.use was called")
from sweep.io.netcdf import read_result
from sweep.plot import plot_result, plot_variable, save_figure
ds = read_result({str(result)!r})
fig = plot_result(ds)
save_figure(plot_variable(ds, "period"), {str(tmp_path / "p.svg")!r})
print(type(fig).__name__, "matplotlib.pyplot" in sys.modules)
"""
    assert python_stdout(code).split() == ["Figure", "False"]
    assert (tmp_path / "p.svg").read_text().lstrip().startswith("<?xml")


def test_plot_variable_labels_units_and_draws_on_a_given_axes(one_d, two_d):
    from matplotlib.figure import Figure

    fig = plot_variable(two_d, "v_max")
    assert fig.axes[-1].get_ylabel().startswith("maximum slip velocity [µm s⁻¹]")  # colour bar
    ax = Figure().subplots()
    assert plot_variable(one_d, "period", ax=ax) is ax.figure
    assert ax.get_ylabel() == "oscillation period [s]"
    assert plot_variable(two_d, "regime").axes[0].get_title() == "dynamical regime"
    with pytest.raises(ValueError, match="valid names: regime, attractor"):
        plot_variable(one_d, "nope")


@pytest.mark.slow
def test_plot_command_maps_any_variable_in_any_format(one_d, tmp_path, capsys):
    path = write_netcdf(one_d, tmp_path / "q.nc")
    assert main(["plot", str(path), "--var", "friction_drop"]) == 0
    assert_png(tmp_path / "q_friction_drop.png")
    for suffix, magic in ((".pdf", b"%PDF"), (".svg", b"<?xml")):
        out = tmp_path / f"v{suffix}"
        assert main(["plot", str(path), "--var", "v_max", "--out", str(out)]) == 0
        assert out.read_bytes().lstrip()[: len(magic)] == magic
    small_png, big_png = tmp_path / "s.png", tmp_path / "b.png"
    assert main(["plot", str(path), "--out", str(small_png), "--dpi", "50"]) == 0
    assert main(["plot", str(path), "--out", str(big_png), "--dpi", "200"]) == 0
    assert big_png.stat().st_size > 2 * small_png.stat().st_size
    capsys.readouterr()
    assert main(["plot", str(path), "--var", "nope"]) == 2
    err = capsys.readouterr().err
    assert "no variable 'nope'" in err and "period" in err


@pytest.mark.slow
def test_reading_and_plotting_results_loads_no_numba():
    """Plots and result files need no kernels: importing them loads no numba (1.25 s)."""
    code = "import sys, sweep.plot, sweep.results.dataset; print('numba' in sys.modules)"
    assert python_stdout(code).strip() == "False"


def test_orbit_diagram_plots_each_runs_events_by_attractor(one_d, two_d, tmp_path, capsys):
    """plot_orbit_diagram: every finite event maximum of every run along the axis,
    coloured by attractor, λ1 below; with ``ax`` only the orbit panel there; along a
    chosen axis of a 2-D result; a result without events or a wrong axis is refused.
    The CLI draws it with ``plot --orbit``."""
    from matplotlib.figure import Figure

    from sweep.plot import plot_orbit_diagram

    fig = plot_orbit_diagram(one_d)
    orbit, lam = fig.axes
    drawn = sum(len(c.get_offsets()) for c in orbit.collections)
    assert drawn == np.isfinite(one_d["event_lnv_peak"].values).sum()
    assert lam.get_ylabel().startswith("largest Lyapunov exponent")
    ax = Figure().subplots()
    assert plot_orbit_diagram(two_d, axis=two_d.regime.dims[1], ax=ax) is ax.figure
    assert ax.get_xlabel() == axis_label(two_d[two_d.regime.dims[1]])
    with pytest.raises(ValueError, match="no sweep axis 'nope'"):
        plot_orbit_diagram(one_d, axis="nope")
    # a result of classification.events: 0 (its stored config says so)
    without = with_changes(parse_config(one_d.attrs["config_text"]),
                           {"classification": {"events": 0}})  # fmt: skip
    no_events = one_d.drop_vars(["event_lnv_peak", "event_interval"]).assign_attrs(
        config_text=without.text)  # fmt: skip
    with pytest.raises(ValueError, match="no event maxima"):
        plot_orbit_diagram(no_events)
    path = write_netcdf(one_d, tmp_path / "q.nc")
    assert main(["plot", str(path), "--orbit"]) == 0
    assert_png(tmp_path / "q_orbit.png")
    capsys.readouterr()
    assert main(["plot", str(path), "--orbit", "--var", "period"]) == 2
    assert "give one of --var, --orbit and --catalogue" in capsys.readouterr().err


# --- refined results ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def refined_two_d():
    config = small(
        CONFIGS / "twoblock.yaml",
        "twoblock_refined",
        sweep={"K_W": {"start": 0.0303, "stop": 0.0703, "num": 5}, "k2_W": [0.0, 0.1, 0.2]},
        refine={"levels": 4},
    )
    return compute(config, show_progress=False)


@pytest.mark.slow
def test_a_refined_map_draws_its_cells_at_their_level_and_its_boundaries(refined_two_d,
                                                                          tmp_path):  # fmt: skip
    """Left: every unsplit cell coloured by its runs' attractor (a mixed cell by quarters),
    the boundary on top; right: each cell's level. The cells tile the map."""
    from matplotlib.collections import PolyCollection

    from sweep.refine.dataset import lattice_index, refined_config
    from sweep.refine.lattice import Lattice, cell_tree

    fig = plot_result(refined_two_d, "a caption")
    assert_png(saved(fig, tmp_path / "refined.png"))
    cells_ax, levels_ax = fig.axes[:2]
    (cells,) = [c for c in cells_ax.collections if isinstance(c, PolyCollection)]
    (levels,) = [c for c in levels_ax.collections if isinstance(c, PolyCollection)]
    area = sum(abs(np.prod(np.ptp(p.vertices[:4], axis=0))) for p in cells.get_paths())
    assert area == pytest.approx(0.04 * 0.2, rel=1e-9)  # no gap, no overlap
    lattice = Lattice(refined_config(refined_two_d))
    tree = cell_tree(lattice, lattice_index(refined_two_d, lattice))
    assert len(levels.get_paths()) == sum(int((~split).sum()) for _, split in tree)
    assert sorted(set(levels.get_array().tolist())) == list(range(5))
    boundary_lines = [line for line in cells_ax.get_lines() if line.get_linestyle() == "-"]
    assert boundary_lines  # the steady/runaway boundary
    assert "refined 4 levels" in fig._suptitle.get_text()


def test_a_refined_result_draws_on_a_given_axes_and_as_a_variable(refined_two_d, tmp_path):
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.subplots()
    assert plot_result(refined_two_d, ax=ax) is fig and len(fig.axes) == 1
    fig = plot_variable(refined_two_d, "t_final")
    assert_png(saved(fig, tmp_path / "t_final.png"), min_bytes=5000)


def test_a_refined_axis_is_drawn_along_its_runs(tmp_path):
    """One refined axis: the runs sorted along it, the boundaries' cells shaded."""
    config = small(CONFIGS / "quick.yaml", "quick_refined", refine={"levels": 5})
    ds = compute(config, show_progress=False)
    fig = plot_result(ds)
    assert_png(saved(fig, tmp_path / "line.png"))
    x = np.sort(ds["K_W"].values)
    for ax in fig.axes:
        assert len(ax.patches) >= 2  # a shaded cell per boundary
        points = np.concatenate([c.get_offsets() for c in ax.collections])
        assert len(points) == len(x) and np.isin(points[:, 0], x).all()


# --- what a referee checks: runaway runs, captions, the classes of a refined map ---------------


def test_no_amplitude_is_drawn_for_a_runaway_run(two_d):
    """Runaway runs have no bounded attractor: the amplitude map leaves their cells out
    of its data (they get the runaway colour, named in the legend)."""
    fig = plot_result(two_d)
    amplitude_ax = fig.axes[1]
    mesh = amplitude_ax.collections[0]
    drawn = np.ma.masked_invalid(mesh.get_array()).ravel()
    runaway = (two_d["regime"] == REGIMES.index("runaway")).transpose("k2_W", "K_W").values.ravel()
    assert runaway.any() and (~runaway).any()
    # the twoblock config's runaways are the runs below Kc/W = (B - A)/D0 = 0.05 um^-1
    below = np.broadcast_to(two_d["K_W"].values < 0.05, (two_d.sizes["k2_W"], two_d.sizes["K_W"]))
    np.testing.assert_array_equal(runaway, below.ravel())
    assert np.ma.getmaskarray(drawn)[runaway].all()
    amplitudes = two_d["lnv_amplitude"].transpose("k2_W", "K_W").values.ravel()
    assert not np.isin(amplitudes[runaway], drawn.compressed()).any()
    legend = [t.get_text() for t in amplitude_ax.get_legend().get_texts()]
    assert any(t.startswith("runaway: no amplitude") for t in legend)


def test_bifurcation_marks_runaway_runs_off_the_amplitude_axis(one_d):
    """The runaway runs of a quasi-static sweep (K < Kc) are triangles in a strip above
    each panel, at their K/Kc = K D0/(B - A) (quick.yaml: D0 = 1 um, B - A = 0.05); no
    point of theirs is on the amplitude axes."""
    fig = plot_bifurcation([one_d])
    strips = [ax for ax in fig.axes if [t.get_text() for t in ax.get_yticklabels()] == ["runaway"]]
    assert len(strips) == 2
    runaway = one_d["regime"].values == REGIMES.index("runaway")
    assert runaway.any()
    ratio = one_d["K_W"].values / 0.05
    for strip in strips:
        (markers,) = strip.collections
        np.testing.assert_allclose(np.sort(markers.get_offsets()[:, 0]), np.sort(ratio[runaway]))
    data_axes = [ax for ax in fig.axes if ax not in strips]
    for ax in data_axes:
        xs = np.concatenate([c.get_offsets()[:, 0] for c in ax.collections if len(c.get_offsets())])
        xs = np.concatenate([xs, *(line.get_xdata() for line in ax.get_lines())])
        assert not np.isclose(xs[:, None], ratio[runaway][None, :], rtol=1e-12).any()


def test_captions_carry_the_dimensionless_number_and_the_largest_peak(two_d, quasi_dynamic):
    """eta_hat = eta V/W (the quasi_dynamic fixture: eta/W = 0.01 and 0.1 s/um, V = 0.1 um/s);
    the largest v_max/V of the runs drawn that do not run away, from the result's v_max.
    The bifurcation diagram draws the K/Kc range both curves cover, 2 % of it either side,
    with Kc/W = (B - A - eta_hat)/D0 = 0.049 and 0.040 um^-1 (physics brief, section 4)."""
    title = plot_result(two_d).get_suptitle()
    assert "M̂ = η̂ = 0" in title
    fig = plot_bifurcation([quasi_dynamic])
    assert "η̂ = ηV/W = 0.001, 0.01" in fig.get_suptitle()
    k = quasi_dynamic["K_W"].values
    kc = np.array([0.049, 0.04])[:, None]  # along eta_W, the fixture's first axis
    low, high = max(k.min() / kc.ravel()), min(k.max() / kc.ravel())
    pad = 0.02 * (high - low)
    ratio = (k[None, :] / kc) * np.ones(quasi_dynamic["regime"].shape)
    shown = (ratio >= low - pad) & (ratio <= high + pad)
    kept = shown & (quasi_dynamic["regime"].values != REGIMES.index("runaway"))
    assert quasi_dynamic["regime"].dims == ("eta_W", "K_W") and not shown.all()
    peak = np.nanmax(quasi_dynamic["v_max"].values[kept]) / 0.1
    assert peak > 10  # a stick-slip cycle of the fixture
    assert f"largest v_max/V of the bounded runs {peak:.3g}" in fig.get_suptitle()


def test_inertial_caption_names_the_dimensionless_mass():
    """M-hat = m V^2/(W D0): m/W = 2e-3 s^2/um, V = 0.5 um/s, D0 = 2 um give 2.5e-4."""
    import xarray as xr

    from sweep.plot.common import dimensionless_text

    ds = xr.Dataset(coords={"m_W": 2e-3, "V": 0.5, "D0": 2.0}, attrs={"model": "inertial"})
    assert dimensionless_text(ds) == "M̂ = mV²/(W·D0) = 0.00025"
    coords = {"m_W": ("m_W", [1e-3, 4e-3]), "V": 0.5, "D0": 2.0, "eta_W": 0.01}
    swept = xr.Dataset(coords=coords, attrs={"model": "inertial"})
    assert dimensionless_text(swept) == "M̂ = mV²/(W·D0) = 0.000125, 0.0005, η̂ = ηV/W = 0.005"


@pytest.fixture(scope="module")
def refined_unequal():
    """configs/unequal_qd.yaml across its band of two-event cycles and its Kc, 3 levels."""
    config = small(
        CONFIGS / "unequal_qd.yaml",
        "unequal_small",
        sweep={"K_W": [0.05, 0.07], "k2_W": [0.0025, 0.0175]},
        refine={"levels": 3},
    )
    return compute(config, show_progress=False)


@pytest.mark.slow  # unequal radiation-damped blocks: kernels no other fast test needs
def test_a_refined_map_names_every_class_and_its_kc(refined_unequal):
    """Every attractor present is in the legend, periodic cycles by their number of events
    (1, 2, 3 or more: their own colours); unequal blocks' Kc is named the Jacobian's; the
    title gives D0 per block and eta_hat = eta V/W = 0.001 s/um x 1 um/s."""
    from matplotlib.colors import to_hex

    ds = refined_unequal
    fig = plot_result(ds)
    cells_ax, levels_ax = fig.axes[:2]
    names = ds["attractor"].attrs["flag_meanings"].split()
    attractor = np.array([names[int(c)] for c in ds["attractor"].values])
    events = ds["cycle_events"].values
    expected = set(attractor[attractor != "periodic"])
    for n, text in ((1, "1 event"), (2, "2 events"), (3, "3 or more events")):
        if np.any((attractor == "periodic") & (np.minimum(events, 3) == n)):
            expected.add(f"periodic, {text} a cycle")
    assert {"periodic, 1 event a cycle", "periodic, 2 events a cycle"} <= expected
    legend = cells_ax.get_legend()
    labels = [t.get_text().split(" (")[0].replace("-", "_") for t in legend.get_texts()]
    assert set(labels) == {e.replace("-", "_") for e in expected}
    colours = [
        to_hex(h.get_color() if hasattr(h, "get_marker") else h.get_facecolor())
        for h in legend.legend_handles
    ]
    assert len(set(colours)) == len(colours)
    kc = [t.get_text() for t in levels_ax.get_legend().get_texts() if "Kc" in t.get_text()]
    assert kc and kc[0].startswith("Kc of the Jacobian")
    title = fig.get_suptitle()
    assert "D0 = 1, 0.6 µm" in title and "η̂ = ηV/W = 0.001" in title


@pytest.mark.slow  # unequal radiation-damped blocks: kernels no other fast test needs
def test_a_refined_map_draws_no_boundary_inside_one_colour(refined_unequal):
    """Cycles of 3 or more events share a colour, so a change from 4 to 5 events is not
    drawn: the fixture's two-event cycles relabelled 4 events below k2/W = 0.006 um^-1
    and 5 above; sweep.boundaries finds the 4|5 line, the map draws none of its inner
    vertices, but still the lines to the one-event cycles."""
    from sweep import boundaries

    ds = refined_unequal
    names = ds["attractor"].attrs["flag_meanings"].split()
    two = (ds["attractor"] == names.index("periodic")) & (ds["cycle_events"] == 2)
    relabelled = xr_where(two, np.where(ds["k2_W"].values < 0.006, 4, 5), ds["cycle_events"])
    ds = ds.assign(cycle_events=relabelled)
    inner = [
        b.vertices[1:-1]
        for b in boundaries(ds)
        if {"4 events", "5 events"} <= {t.split(", ")[-1] for t in b.between}
    ]
    inner = np.concatenate(inner)
    assert len(inner)
    fig = plot_result(ds)
    cells_ax = fig.axes[0]
    drawn = np.concatenate([line.get_xydata() for line in cells_ax.get_lines()])
    assert len(drawn)
    assert not np.isclose(drawn[:, None, :], inner[None, :, :], rtol=1e-12).all(-1).any()
    legend = [t.get_text() for t in cells_ax.get_legend().get_texts()]
    assert any(t.startswith("periodic, 3 or more events a cycle") for t in legend)


def xr_where(condition, yes, no):
    """``yes`` where ``condition``, else ``no``, in the dtype and dimensions of ``no``."""
    return no.copy(data=np.where(condition.values, yes, no.values).astype(no.dtype))


def test_a_png_is_saved_without_alpha_and_without_loss(tmp_path):
    """save_figure drops the alpha channel of an opaque figure: the pixels are those
    matplotlib renders itself, and the file's resolution is the dpi asked for. (A figure
    without constrained layout: that one moves by a pixel between draws.)"""
    import io

    import matplotlib.image
    from matplotlib.figure import Figure
    from PIL import Image

    fig = Figure(figsize=(3, 2))
    ax = fig.subplots()
    ax.plot([0, 1, 2], [0, 1, 0.5], color="#D55E00")
    ax.set_title("η̂ = 0.001")
    path = save_figure(fig, tmp_path / "f.png", dpi=80)
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=80, format="png")
    buffer.seek(0)
    reference = matplotlib.image.imread(buffer)
    with Image.open(path) as image:
        assert image.mode == "RGB"
        assert image.info["dpi"] == pytest.approx((80, 80), abs=0.01)
    assert reference.shape[-1] == 4 and (reference[..., 3] == 1).all()
    np.testing.assert_array_equal(matplotlib.image.imread(path), reference[..., :3])


def test_catalogue_map_over_seeds_means_where_the_statistic_applies():
    """A catalogue map of a result with realisations (``spread_seed``): each cell is the
    mean over the seeds where the statistic applies (status ok), written with their
    standard deviation and count; a cell where it applies at no seed is blank with the
    commonest reason."""
    from sweep.codes import B_VALUE_STATUSES
    from sweep.plot.catalogue import catalogue_map
    from sweep.plot.common import new_figure

    b = np.array([[[1.0, 1.2, 9.0], [0.5, 0.7, 0.9]], [[2.0, 3.0, 4.0], [0.8, 0.8, 0.8]]])
    status = np.zeros(b.shape, int)
    status[0, 0, 2] = 4  # rejected at one seed: the 9.0 is left out
    status[1, 0, :] = [1, 3, 3]  # applies at no seed: blank, the commonest reason
    coords = {"k2_W": [0.1, 1.0], "spread_D0": [0.0, 0.3], "spread_seed": [1, 2, 3]}
    dims = ("k2_W", "spread_D0", "spread_seed")
    ds = xr.Dataset(
        {
            "b_value": (dims, b, {"long_name": "b-value", "units": "1"}),
            "b_value_status": (dims, status, {"flag_meanings": " ".join(B_VALUE_STATUSES)}),
        },
        coords,
    )
    ax = new_figure().subplots()
    catalogue_map(ds, "b_value", ax)
    cells = ax.collections[0].get_array()
    expected = [[1.1, 0.7], [np.nan, 0.8]]  # rows k2_W, columns spread_D0
    np.testing.assert_allclose(np.ma.filled(cells, np.nan).reshape(2, 2), expected)
    texts = {t.get_text() for t in ax.texts}
    assert "1.1 ± 0.1\n(2/3 seeds)" in texts and "0.7 ± 0.2\n(3/3 seeds)" in texts
    assert B_VALUE_STATUSES[3].replace("_", "\n") in texts
    assert "mean over 3 seeds" in ax.get_title().replace("\n", " ")
