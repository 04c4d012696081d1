"""The engine against its peers, drawn from ``make bench``'s recorded figures.

Reads ``results/bench.json`` (written by ``benchmarks/bench.py``) and draws one bar
chart, ``results/bench_peers.png``: runs per second on one core of the engine and of
what a user would otherwise run, on one block over K/Kc 0.8-1.2 to 2000 D0/V at rtol
1e-8, atol 1e-10 (the ``single_purpose`` and ``scipy_hard`` entries). Nothing is
measured here; ``make bench`` runs it after the benchmarks. Run it as
``python benchmarks/plot_bench.py [--json FILE] [--out FILE]``.
"""

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: Bars from top to bottom: (label, entry of ``single_purpose``, the engine's?).
BARS = (
    ("engine, DOP853 (default), early exit", "engine_early_exit_on", True),
    ("engine, DOP853, to t_end", "engine_early_exit_off", True),
    ("engine, DOPRI5, early exit", "engine_dopri5_early_exit_on", True),
    ("engine, DOPRI5, to t_end", "engine_dopri5_early_exit_off", True),
    ("CyRK DOP853 (C++), numba loop", "cyrk_DOP853", False),
    ("CyRK RK45 (C++), numba loop", "cyrk_RK45", False),
    ("single-purpose numba DOPRI5 loop", "plain", False),
)


def peer_rates(figures):
    """``[(label, runs per second per core, is the engine)]`` from ``bench.json``'s
    figures: the bars of :data:`BARS` present (CyRK's only where it was installed),
    then SciPy's LSODA loop (``scipy_hard``: the same K/Kc range, fewer runs)."""
    sp = figures["single_purpose"]
    rates = [(label, sp[key]["systems_per_second"], engine)
             for label, key, engine in BARS if key in sp]  # fmt: skip
    hard = figures["scipy_hard"]
    rates.append(("SciPy solve_ivp LSODA loop", hard["grid_points"] / hard["scipy_seconds"], False))
    return rates


def draw(figures):
    """A matplotlib Figure (no pyplot) of :func:`peer_rates`, log scale."""
    from matplotlib.figure import Figure

    rates = peer_rates(figures)
    sp = figures["single_purpose"]
    fig = Figure(figsize=(6.4, 3.4), layout="constrained")
    ax = fig.add_subplot()
    y = range(len(rates))[::-1]
    values = [rate for _, rate, _ in rates]
    colors = ["tab:blue" if engine else "0.6" for _, _, engine in rates]
    ax.barh(list(y), values, color=colors)
    ax.set_yticks(list(y), [label for label, _, _ in rates])
    ax.set_xscale("log")
    ax.set_xlim(1, 3e4)
    for k, value in zip(y, values, strict=True):
        ax.text(value * 1.15, k, f"{value:,.0f}" if value >= 100 else f"{value:.1f}",
                va="center", fontsize=8)  # fmt: skip
    ax.set_xlabel("runs per second, one core (log scale)")
    ax.set_title(
        f"One block, K/Kc 0.8–1.2, {sp['grid_points']} runs to "
        f"{sp['t_end_D0_over_V']:g} D0/V (SciPy: {figures['scipy_hard']['grid_points']})",
        fontsize=9,
    )
    ax.tick_params(labelsize=8)
    return fig


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python benchmarks/plot_bench.py", description=__doc__)
    parser.add_argument("--json", default=str(ROOT / "results" / "bench.json"),
                        help="make bench's figures")  # fmt: skip
    parser.add_argument("--out", default=str(ROOT / "results" / "bench_peers.png"),
                        help="the plot to write")  # fmt: skip
    args = parser.parse_args(argv)
    figures = json.loads(Path(args.json).read_text())
    draw(figures).savefig(args.out, dpi=100)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
