"""The paper's figures, reproduced honestly (``python -m sweep figures``, ``make figures``).

Every system is derived from ``configs/paper.yaml`` (the paper's one-block
system, read with D0 = 1 µm: erratum 1) and integrated as a trace
(``sweep/commands/trace.py``); the phase diagram and bifurcation diagram come from
ordinary sweeps (``configs/twoblock.yaml``, ``configs/bifurcation_*.yaml``), the orbit
diagram of two unequal inertial blocks from ``configs/route_to_chaos.yaml``, and the
refined map of two unequal radiation-damped blocks from ``configs/unequal_qd.yaml``
(:func:`figure_refined`), the long chain's statistics from ``configs/long_chain.yaml``
and the fast events of a laboratory slider from ``configs/fast_events.yaml``
(:func:`figure_fast_events`).

Where the paper's quasi-static model runs away (K < Kc has no stick-slip limit
cycle), the figures show the runaway and, beside it, the same system with a
small radiation damping η̂ = ηV/W = 0.001 (quasi-dynamic model), which has a
true stick-slip cycle. Its critical stiffness is Kc/W = (B − A − η̂)/D0 =
0.049 µm⁻¹, so K/W = 0.046 µm⁻¹ is 6 % below it; the larger η̂ = 0.01 would
move Kc/W to 0.040 µm⁻¹ and make K/W = 0.046 µm⁻¹ steady.
"""

import math
from pathlib import Path

import numpy as np

from ..config import load_config, with_changes
from ..errors import InputError
from ..io.files import check_writable
from ..model import physics
from ..plot import draw_trace, save_figure
from ..plot.common import DPI, initial_text, new_figure, parameter_text, power_text
from ..plot.trace import BLOCK_STYLES
from ..results.dataset import parameter_values
from .trace import compute_trace, pin_config

#: Radiation damping per normal load of the quasi-dynamic comparison (s/µm): η̂ = η V/W = 0.001.
ETA_W = 0.01
#: Coupling-spring stiffness per normal load of the paper's two-block figure (µm⁻¹).
K2_W = 0.05
#: Length of the two-block runs relative to the paper config's t_end: an out-of-phase
#: start excites the in-phase (unstable) mode only at second order, so it takes
#: about twice as long to grow.
TWO_BLOCK_SPAN = 2.0
#: Synchronisation errors of exactly zero are drawn at this floor on the log axis.
SYNC_FLOOR = 1e-18
#: State perturbations (Φ/Φss per block) of the two-block runs: the paper's, and out of phase.
IN_PHASE = (1.01, 1.01)
OUT_OF_PHASE = (1.01, 0.99)

#: Keys of ``initial`` that set up an ensemble of random starts.
ENSEMBLE_KEYS = ("ensemble", "seed", "amplitude")
#: Rows of the one-block figure: label and changes to the paper config.
ONE_BLOCK_ROWS = (
    ("quasi-static (the paper's equations)", {}),
    (
        "quasi-dynamic: radiation damping η/W = {eta_W:g} s/µm (ηV/W = {eta_hat:g})",
        {"model": "quasi-dynamic", "eta_W": ETA_W},
    ),
)
#: Rows of the two-block figure (all with k2/W = K2_W).
TWO_BLOCK_ROWS = (
    ("quasi-static, both blocks start at Φ/Φss = 1.01 (the paper)", {"phi": IN_PHASE}),
    ("quasi-static, out of phase: Φ/Φss = 1.01 and 0.99", {"phi": OUT_OF_PHASE}),
    (
        "quasi-dynamic (ηV/W = {eta_hat:g}), out of phase",
        {"phi": OUT_OF_PHASE, "model": "quasi-dynamic", "eta_W": ETA_W},
    ),
)


def variant(config, name, model=None, eta_W=None, k2_W=None, phi=None):
    """``config`` changed to another model, damping, coupling or start (validated).

    ``phi``: Φ/Φss per block, which also sets the number of blocks (each starts
    at v = V). ``eta_W`` in s/µm, ``k2_W`` in µm⁻¹.
    """
    changes = {"name": name}
    if model is not None:
        changes["model"] = model
    parameters = {k: v for k, v in (("eta_W", eta_W), ("k2_W", k2_W)) if v is not None}
    if parameters:
        changes["parameters"] = parameters
    if phi is not None:
        changes["blocks"] = len(phi)
        # exactly this start: no ensemble of random starts around it
        changes["initial"] = {"v_over_V": [1.0] * len(phi), "phi_over_phi_ss": list(phi),
                              **dict.fromkeys(ENSEMBLE_KEYS)}  # fmt: skip
    return with_changes(config, changes, f"{config.source} ({name})")


def stiffnesses(config):
    """The K/W values (µm⁻¹) of the paper config's one sweep axis."""
    if [a.name for a in config.axes] != ["K_W"]:
        swept = ", ".join(a.name for a in config.axes)
        raise InputError(config.source, [f"the paper config must sweep K_W and nothing else; "
                                         f"it sweeps {swept}"])  # fmt: skip
    return config.axes[0].values


def trace_grid(config, rows, points, t_end=None):
    """Traces for every (row, K/W): rows of (label, variant changes); ``t_end`` in
    the config's time unit (default: the config's)."""
    return [
        [
            compute_trace(
                pin_config(variant(config, f"{config.name}_{r}", **changes), {"K_W": k}, t_end),
                points,
            )
            for k in stiffnesses(config)
        ]
        for r, (_, changes) in enumerate(rows)
    ]


def _panel_title(ax, label, ds):
    """Row label (η/W and ηV/W filled in) and the panel's K/W, Kc/W and K/Kc."""
    a, p = ds.attrs, parameter_values(ds)
    label = label.format(eta_W=ETA_W, eta_hat=ETA_W * p["V"])
    k = f"K/W = {p['K_W']:g} µm⁻¹, Kc/W = {a['critical_K_W']:.3g} µm⁻¹: K/Kc = {a['K_over_Kc']:.3g}"
    ax.set_title(f"{label}\n{k}", fontsize=9)


def _trace_panels(rows, traces, height, extra_rows=0, legend_first=False):
    """Figure with one row of trace panels per ``rows`` entry (one column per K/W) and
    ``extra_rows`` free rows below; time labels on the bottom row only. Returns
    ``(fig, axes)``."""
    n_rows, ncol = len(traces) + extra_rows, len(traces[0])
    fig = new_figure(figsize=(5.6 * ncol, height))
    axes = fig.subplots(n_rows, ncol, sharex=True, squeeze=False)
    for r, (label, _) in enumerate(rows):
        for c, ds in enumerate(traces[r]):
            draw_trace(axes[r, c], ds, legend=legend_first and r == 0 and c == 0)
            _panel_title(axes[r, c], label, ds)
            if r < n_rows - 1:
                axes[r, c].set_xlabel("")
    return fig, axes


def figure_one_block(config, points=3000):
    """The paper's Fig. 1 (one block at each K/W) with the quasi-dynamic comparison;
    returns the Figure."""
    traces = trace_grid(config, ONE_BLOCK_ROWS, points)
    fig, _ = _trace_panels(ONE_BLOCK_ROWS, traces, height=6.6)
    ds = traces[0][0]
    fig.suptitle(
        f"Fig. 1 reproduced: one block, {parameter_text(_fixed(ds))}; {initial_text(ds)}\n"
        "D0 = 1 µm, not the printed 0.1 µm (erratum 1): then the printed K/W bracket "
        f"Kc/W = {ds.attrs['critical_K_W']:.3g} µm⁻¹",
        fontsize=10,
    )
    return fig


def figure_two_blocks(config, points=3000):
    """The paper's Fig. 2 (two blocks, k2/W = 0.05 µm⁻¹), with an out-of-phase start,
    the quasi-dynamic comparison, and the synchronisation of the blocks; returns the
    Figure."""
    rows = tuple((label, {**changes, "k2_W": K2_W}) for label, changes in TWO_BLOCK_ROWS)
    traces = trace_grid(config, rows, points, TWO_BLOCK_SPAN * config.integrator.t_end)
    fig, axes = _trace_panels(rows, traces, height=11.5, extra_rows=1, legend_first=True)
    ncol = len(traces[0])
    for c in range(ncol):
        ax = axes[-1, c]
        for r in range(1, len(rows)):
            ds = traces[r][c]
            lnv = ds["lnv"]
            gap = np.abs(lnv.isel(block=0).values - lnv.isel(block=1).values)
            colour, _ = BLOCK_STYLES[r - 1]
            label = rows[r][0].format(eta_hat=ETA_W * parameter_values(ds)["V"])
            ax.plot(
                ds["time"].values, np.maximum(gap, SYNC_FLOOR), color=colour, lw=1.0, label=label
            )
        ax.set_yscale("log")
        ax.set_ylim(bottom=SYNC_FLOOR / 3)
        ax.set_xlabel("time t [s]")
        ax.set_ylabel("|ln(v1/v2)|")
        ax.set_title(
            f"out-of-phase starts synchronise (exact 0 drawn at {power_text(SYNC_FLOOR)})",
            fontsize=9,
        )
        ax.legend(loc="upper right", fontsize=8)
    ds = traces[0][0]
    fig.suptitle(
        f"Fig. 2 reproduced: two blocks, {parameter_text(_fixed(ds))}\n"
        "D0 = 1 µm (erratum 1); the in-phase mode is the one-block system, "
        "so Kc is the one-block value for every k2",
        fontsize=10,
    )
    return fig


def _fixed(ds):
    """Parameters of a trace for a figure title, without the per-panel K/W."""
    values = parameter_values(ds)
    return {k: values[k] for k in ("A", "B", "D0", "V", "k2_W") if k in values}


#: Sizes, couplings, spread (relative, of D0) and seeds of the critical-stiffness panel of
#: the N-block figure; the other settings (A, B, D0, k2/W) are the heterogeneous config's.
NBLOCK_SIZES = (3, 4, 6, 8, 12, 16, 32)
NBLOCK_COUPLINGS = ("chain", "ring", "all")
NBLOCK_SPREAD = 0.2
NBLOCK_SEEDS = range(10)


def critical_ratios(
    config, sizes=NBLOCK_SIZES, couplings=NBLOCK_COUPLINGS, spread=NBLOCK_SPREAD, seeds=NBLOCK_SEEDS
):
    """Critical stiffness of unequal blocks relative to identical blocks with their
    mean D0, (B − A)/⟨D0_i⟩, from the linear theory for every block count, coupling and
    spread seed (D0_i = D0 (1 + ``spread`` ξ_i)); ``config`` gives the other parameters.
    Returns a DataArray (coupling, blocks, seed)."""
    import xarray as xr

    from ..engine import grid
    from ..model import heterogeneity

    # None removes a key: one K/W, identical starts at steady sliding, a D0 spread only
    changes = {
        "sweep": {**dict.fromkeys(a.name for a in config.axes),
                  "K_W": [float(config.axes[0].values[0])]},
        "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.0, **dict.fromkeys(ENSEMBLE_KEYS)},
    }  # fmt: skip
    out = np.empty((len(couplings), len(sizes), len(seeds)))
    for i, coupling in enumerate(couplings):
        for j, n in enumerate(sizes):
            for k, seed in enumerate(seeds):
                changes |= {"blocks": n, "coupling": coupling}
                changes["spread"] = {**dict.fromkeys(heterogeneity.PER_BLOCK), "D0": spread,
                                     "distribution": "uniform", "seed": seed}  # fmt: skip
                source = f"{config.source} (N = {n}, {coupling}, seed {seed})"
                cfg = with_changes(config, changes, source)
                g = grid.build_grid(cfg)
                phys = g.physical
                kc_w = g.linear["kappa_c"][0] / phys["D0"][0]
                out[i, j, k] = kc_w * g.blocks["D0"][0].mean() / (phys["B"][0] - phys["A"][0])
    title = (
        f"D0 spread {spread:g} (uniform, seeds {seeds[0]}–{seeds[-1]}), "
        f"k2/W = {config.fixed['k2_W']:g} µm⁻¹: Jacobian Kc"
    )
    return xr.DataArray(
        out,
        dims=("coupling", "blocks", "seed"),
        name="Kc_ratio",
        coords={"coupling": list(couplings), "blocks": list(sizes), "seed": list(seeds)},
        attrs={"title": title},
    )


def figure_nblock(nblock="nblock", heterogeneous="heterogeneous", threads=None):
    """Many contact points: the critical stiffness against N and coupling, and the
    ensemble regime maps of ``heterogeneous`` (K/W × spread of D0) and ``nblock``
    (K/W × k2/W); returns the Figure."""
    from ..engine.runner import compute
    from ..plot import plot_nblock

    spread_config, coupling_config = load_config(heterogeneous), load_config(nblock)
    sizes = critical_ratios(spread_config)
    spread = compute(spread_config, threads=threads, show_progress=False)
    coupling = compute(coupling_config, threads=threads, show_progress=False)
    caption = (
        "identical blocks lose steady sliding at the one-block Kc for every N and "
        "coupling; unequal ones at their own Kc, with bounded stick-slip below it"
    )
    return plot_nblock(sizes, spread, coupling, caption)


def figure_refined(ds):
    """The refined map ``ds`` (a refined result): its cells at their level and the
    boundaries between its labels (``plot.plot_refined``), with the runs it took beside
    those of the uniform grid of its finest cells; returns the Figure."""
    from ..plot import plot_result
    from ..refine.dataset import refined_config

    config = refined_config(ds)
    levels = config.refine.levels
    runs = int(ds["regime"].size)
    uniform = math.prod((len(a.values) - 1) * 2**levels + 1 for a in config.axes)
    uniform *= config.members
    caption = (
        f"{runs} runs where the uniform grid of the finest cells (1/{2**levels} of a grid "
        f"step) would take {uniform:,}: {100 * runs / uniform:.2g} %"
    )
    return plot_result(ds, caption)


#: The statistics mapped over a long chain's sweep, beside one run's catalogue.
LONG_CHAIN_MAPS = ("system_wide_fraction", "b_value", "large_event_excess", "recurrence_cv")


def figure_long_chain(ds, point=None):
    """A long chain's sweep ``ds`` (a result with a catalogue): maps of the fraction of
    system-wide events, the b-value (blank where the Gutenberg–Richter law is
    rejected), the excess of large events over its extrapolation and the recurrence's
    coefficient of variation over the sweep, on even cells
    (``sweep.plot.catalogue.catalogue_map``), above one run's events in space and time
    and its size–frequency plot (``sweep.plot_catalogue`` at ``point``; default: the run
    with the most events); titled with every fixed setting; returns the Figure."""
    from ..plot import plot_catalogue
    from ..plot.catalogue import catalogue_caption, catalogue_map
    from ..plot.common import _suptitle

    if point is None:
        busiest = ds["slip_event_count"].argmax(...)
        point = {dim: float(ds[dim][i]) for dim, i in busiest.items()}
    fig = new_figure(figsize=(15, 10))
    top, bottom = fig.subfigures(2, 1, height_ratios=(1, 1.15))
    for i, (ax, name) in enumerate(
        zip(top.subplots(1, len(LONG_CHAIN_MAPS)), LONG_CHAIN_MAPS, strict=True)
    ):
        catalogue_map(ds, name, ax, ylabel=i == 0)
    plot_catalogue(ds, point, fig=bottom, caption=False)
    _suptitle(fig, catalogue_caption(ds))
    return fig


#: Slip thresholds v/V of the long chain's sensitivity figure, and the part of its grid
#: they are run on: the weakest and strongest coupling, the middle spread, one seed.
THRESHOLDS = (2.0, 3.0, 5.0, 10.0, 20.0)
THRESHOLD_SWEEP = {"k2_W": [0.1, 1.0], "spread_D0": [0.15], "spread_seed": [1]}


#: K/Kc of the two traces of the fast-events figure (points of ``configs/fast_events.yaml``)
#: and their length in D0/V: past those runs' early exit (484 and 498 D0/V), so the
#: classifier has decided, with nine events or more at the longer period (66 D0/V).
FAST_RATIOS = (0.5, 0.9)
FAST_T_END = 600.0


def figure_fast_events(config, points=8000):
    """Fast events of one inertial block (``configs/fast_events.yaml``): v on a log axis
    at K/Kc = :data:`FAST_RATIOS` (K/W pinned to K/Kc × the config's Kc/W), captioned
    with M̂ = mV²/(W D0) and each run's v_max/V (its peak from the solver's
    interpolant: the plotted series samples a time grid and can fall short of it);
    returns the Figure."""
    from ..engine.grid import build_grid

    if config.model != "inertial":
        problem = f"model: the fast-events figure draws the inertial model, not {config.model}"
        raise InputError(config.source, [problem])
    g = build_grid(pin_config(config, {a.name: a.values[0] for a in config.axes}))
    D0, V = float(g.physical["D0"][0]), float(g.physical["V"][0])  # µm, µm/s
    kc_w = float(g.linear["kappa_c"][0]) / D0  # µm⁻¹
    t_end = FAST_T_END * (1.0 if config.integrator.t_unit == "D0/V" else D0 / V)
    traces = [
        compute_trace(pin_config(config, {"K_W": ratio * kc_w}, t_end), points)
        for ratio in FAST_RATIOS
    ]
    fig = new_figure(figsize=(11.2, 4.4))
    axes = fig.subplots(1, len(traces), sharey=True)
    peaks = []
    for ax, ds in zip(axes, traces, strict=True):
        draw_trace(ax, ds, legend=ax is axes[0])
        peaks.append(ds.attrs["v_max"] / V)
        ax.set_title(f"K/Kc = {ds.attrs['K_over_Kc']:.3g}: v_max/V = {peaks[-1]:.2g}", fontsize=9)
    p = parameter_values(traces[0])
    mass_hat = float(
        physics.dimensionless(p["A"], p["B"], D0, V, p["K_W"], m_W=p["m_W"])["mass_hat"]
    )
    fixed = parameter_text({k: v for k, v in p.items() if k != "K_W"})
    fig.suptitle(
        f"one block, inertial, {config.state_law} law: {fixed}; Kc/W = {kc_w:.3g} µm⁻¹\n"
        f"M̂ = mV²/(W D0) = {mass_hat:.3g} (a laboratory slider): fast events, "
        f"v_max/V = {' and '.join(f'{v:.2g}' for v in peaks)}",
        fontsize=10,
    )
    return fig


def figure_floquet(damped, route):
    """How stable each cycle is: (a) the largest non-trivial Floquet multiplier's modulus
    over the damped block's map (``damped``, two axes), (b) along the route to chaos
    (``route``, one axis) by kind of multiplier, with the boundaries' types; returns the
    Figure."""
    from ..plot import plot_floquet

    fig = new_figure(figsize=(8.0, 8.4))
    top, bottom = fig.subplots(2, 1, height_ratios=(1.15, 1.0))
    plot_floquet(damped, ax=top)
    plot_floquet(route, ax=bottom)
    values = parameter_values(damped)
    eta_hat = damped["eta_W"].values * float(values["V"])
    top.set_title(
        f"(a) one radiation-damped block, aging law, {parameter_text(_fixed(damped))},\n"
        f"η̂ = ηV/W = {eta_hat.min():g}–{eta_hat.max():g}: |μ| → 1 at Kc (dashed); "
        "grey: no periodic run",
        fontsize=9,
    )
    values = parameter_values(route)
    mass_hat = float(values["m_W"]) * float(values["V"]) ** 2 / float(np.mean(values["D0"]))
    bottom.set_title(
        f"(b) two inertial blocks, aging law, {parameter_text(_fixed(route))},\n"
        f"m/W = {float(values['m_W']):g} s²/µm (M̂ = {mass_hat:g}), K/Kc ≪ 1\n"
        "dotted: boundaries, by type (PD period doubling, ? undetermined: see the guide)",
        fontsize=9,
    )
    fig.suptitle(
        "Largest non-trivial Floquet multiplier |μ| of every periodic run\n"
        "(exact tangent of the step map over one period; perturbations shrink by |μ| a cycle)",
        fontsize=10,
    )
    return fig


#: The higher velocity cap of the aging law's second curve in :func:`figure_critical_kick`.
HIGH_CAP = 1.0e9


def figure_critical_kick(slip, aging, threads=None):
    """How big a kick leaves steady sliding: the critical velocity jump against K/Kc for
    the slip law (``slip``) and the aging law (``aging``) at its cap and at
    :data:`HIGH_CAP`, each bisected to 1 % (``engine/kicks.py``); returns the Figure."""
    from ..engine.kicks import bisect_critical_kick
    from ..plot import plot_critical_kick

    high = with_changes(
        aging, {"classification": {"v_cap_over_V": HIGH_CAP}}, f"{aging.source} (cap {HIGH_CAP:g})"
    )
    runs = [bisect_critical_kick(c, threads=threads, progress=False) for c in (slip, aging, high)]
    labels = [
        f"{c.state_law} law, cap v/V = {power_text(c.classification.v_cap_over_V)}"
        for c in (slip, aging, high)
    ]
    caption = (
        "slip law: a sharp threshold (Gu et al. 1984); aging law: every kick returns "
        "(Ranjith & Rice 1999), so the threshold is where the excursion passes the cap"
    )
    return plot_critical_kick(runs, labels, caption)


def make_figures(
    paper="paper",
    twoblock="twoblock",
    bifurcation=("bifurcation_qs", "bifurcation_qd"),
    nblock=("nblock", "heterogeneous"),
    route="route_to_chaos",
    out_dir="results",
    threads=None,
    suffix=".png",
    dpi=DPI,
    refined="unequal_qd",
    long_chain="long_chain",
    fast="fast_events",
    damped="quasidynamic",
    kicks=("kick_slip_law", "kick_aging_law"),
    basins="basins",
):
    """Regenerate every paper figure into ``out_dir``; returns the file paths.

    Configs are paths or names of packaged examples (``sweep/examples.py``), so
    this works from any folder; ``route``: the 1-D sweep whose orbit diagram is drawn;
    ``refined``: the refined sweep whose cells and boundaries are drawn; ``long_chain``:
    the sweep with a catalogue whose statistics and busiest run are drawn, and whose
    statistics are drawn against the slip threshold (:data:`THRESHOLDS` on
    :data:`THRESHOLD_SWEEP`, ``catalogue_threshold``); ``fast``: the inertial one-block
    config whose fast events are traced (:func:`figure_fast_events`); ``damped``: the
    two-axis sweep whose Floquet multipliers are mapped beside the route's
    (:func:`figure_floquet`); ``kicks``: the slip- and aging-law configs whose critical
    kicks are drawn (:func:`figure_critical_kick`); ``basins``: the ensemble whose basin
    fractions are drawn. ``suffix``:
    ``.png``, ``.pdf`` or ``.svg``; ``dpi``: resolution of PNGs.
    """
    from ..engine.dispatch import load_kernels
    from ..engine.grid import build_grid
    from ..engine.runner import compute
    from ..plot import plot_basin_fractions, plot_bifurcation, plot_orbit_diagram, plot_result
    from ..plot.catalogue import plot_threshold_sensitivity
    from ..results.basins import basin_fractions
    from .sensitivity import threshold_sensitivity

    out_dir = Path(out_dir)
    # every input and the output folder are checked before any work
    config = load_config(paper)
    phase_config = load_config(twoblock)
    bifurcation_configs = [load_config(p) for p in bifurcation]
    nblock_configs = [load_config(path) for path in nblock]
    route_config = load_config(route)
    refined_config = load_config(refined)
    chain_config = load_config(long_chain)
    fast_config = load_config(fast)
    damped_config = load_config(damped)
    kick_configs = [load_config(c) for c in kicks]
    basins_config = load_config(basins)
    stiffnesses(config)  # checked before any kernel is compiled
    check_writable(out_dir / f"fig1_one_block{suffix}", str(out_dir), "--out-dir", suffix)
    rows = (*ONE_BLOCK_ROWS, *((label, {**c, "k2_W": K2_W}) for label, c in TWO_BLOCK_ROWS))
    trace_configs = [variant(config, f"{config.name}_{r}", **c) for r, (_, c) in enumerate(rows)]
    every = [*trace_configs, phase_config, *bifurcation_configs, *nblock_configs, route_config,
             refined_config, chain_config, fast_config, damped_config,
             *kick_configs, basins_config]  # fmt: skip
    # side by side; each variant here also has runs that need the tangent for λ1
    grids = [build_grid(c) for c in every]
    load_kernels([(g.params, g.settings, t) for g in grids for t in (None, True)], threads)
    paths = [
        save_figure(figure_one_block(config), out_dir / f"fig1_one_block{suffix}", dpi),
        save_figure(figure_two_blocks(config), out_dir / f"fig2_two_blocks{suffix}", dpi),
    ]
    phase = compute(phase_config, threads=threads, show_progress=False)
    caption = "the transition stays at the one-block Kc/W = (B − A)/D0 for every coupling k2"
    paths.append(save_figure(plot_result(phase, caption), out_dir / f"phase_twoblock{suffix}", dpi))
    sweeps = [compute(c, threads=threads, show_progress=False) for c in bifurcation_configs]
    caption = (
        "quasi-static: no cycle below Kc, every run runs away (a jump); "
        "radiation damping: the cycle grows continuously from zero"
    )
    fig = plot_bifurcation(sweeps, caption)
    paths.append(save_figure(fig, out_dir / f"bifurcation{suffix}", dpi))
    fig = figure_nblock(*nblock, threads=threads)
    paths.append(save_figure(fig, out_dir / f"nblock{suffix}", dpi))
    caption = (
        "D0 = 1.0 and 0.6 µm (mean 0.8). K rising: a torus, the simple cycle's period "
        "doubling, the simple cycle, a slip and a stick bump (off the scale, ln v/V ≈ −25) "
        "doubling, periodic windows with tori and chaos between them, a chaotic band, the "
        "simple cycle again"
    )
    route = compute(route_config, threads=threads, show_progress=False)
    fig = plot_orbit_diagram(route, caption=caption, lnv_range=(0.5, 2.5))
    paths.append(save_figure(fig, out_dir / f"route_to_chaos{suffix}", dpi))
    damped_result = compute(damped_config, threads=threads, show_progress=False)
    fig = figure_floquet(damped_result, route)
    paths.append(save_figure(fig, out_dir / f"floquet{suffix}", dpi))
    fig = figure_refined(compute(refined_config, threads=threads, show_progress=False))
    paths.append(save_figure(fig, out_dir / f"refined_{refined_config.name}{suffix}", dpi))
    fig = figure_long_chain(compute(chain_config, threads=threads, show_progress=False))
    paths.append(save_figure(fig, out_dir / f"{chain_config.name}{suffix}", dpi))
    sensitivity = threshold_sensitivity(chain_config, THRESHOLDS, THRESHOLD_SWEEP, threads)
    fig = plot_threshold_sensitivity(sensitivity)
    paths.append(save_figure(fig, out_dir / f"catalogue_threshold{suffix}", dpi))
    fig = figure_fast_events(fast_config)
    paths.append(save_figure(fig, out_dir / f"{fast_config.name}{suffix}", dpi))
    fig = figure_critical_kick(*kick_configs, threads=threads)
    paths.append(save_figure(fig, out_dir / f"critical_kick{suffix}", dpi))
    ensemble = basin_fractions(compute(basins_config, threads=threads, show_progress=False))
    caption = (
        "a subcritical Hopf bifurcation: above Kc stable steady sliding and a stable cycle "
        "coexist until the cycle's fold"
    )
    fig = plot_basin_fractions(ensemble, "cycle_1ev", caption)
    paths.append(save_figure(fig, out_dir / f"basins{suffix}", dpi))
    return paths
