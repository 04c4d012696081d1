"""``make bench`` (``benchmarks/bench.py``) runs end to end: every benchmark at tiny
sizes (``--smoke``), in a fresh process as ``make bench`` starts it. Timings are
not checked (they depend on the machine); what is checked is that every figure
the README quotes is computed and finite, and that the SciPy loops integrate the
tests' reference right-hand side."""

import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import SUBPROCESS_TIMEOUT

from sweep.model.physics import log_form_rhs

ROOT = Path(__file__).resolve().parent.parent


def load_bench():
    """``benchmarks/bench.py`` as a module (it is a script outside the package)."""
    spec = importlib.util.spec_from_file_location("bench", ROOT / "benchmarks" / "bench.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_scipy_loops_integrate_the_reference_rhs():
    """The benchmark's scalar right-hand side is ``physics.log_form_rhs`` for one
    quasi-static block under the aging law, at random states and stiffnesses."""
    bench = load_bench()
    rng = np.random.default_rng(0)
    for _ in range(50):
        y = rng.normal(scale=2.0, size=2)
        kappa = rng.uniform(0.01, 0.1)
        got = bench.scipy_rhs(0.0, y, bench.PAPER["A"], bench.PAPER["B"], kappa)
        want = log_form_rhs(0.0, y, bench.PAPER["A"], bench.PAPER["B"], kappa)
        # the same arithmetic in math and in numpy: equal to rounding
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)


def numbers(tree, prefix=""):
    """Every number of a nested dict as ``(key path, value)``."""
    for key, value in tree.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            yield from numbers(value, path + ".")
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            yield path, value


@pytest.mark.slow
def test_every_benchmark_runs_at_smoke_size(tmp_path):
    pytest.importorskip("distributed")  # the Dask comparison is one of the benchmarks
    out = tmp_path / "bench.json"
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench.py"), "--smoke", "--out", str(out)],
        cwd=tmp_path,  # the script finds configs/ from its own location
        capture_output=True,
        text=True,
        timeout=SUBPROCESS_TIMEOUT,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    figures = json.loads(out.read_text())
    sections = {"scipy", "single_purpose", "scipy_hard", "threads_large", "throughput", "rk4",
                "oneblock", "dask", "compile", "attractors", "refine",
                "implicit_scaling", "structured_crossing", "critical_kick", "basins"}  # fmt: skip
    assert sections <= set(figures)
    for section in sections:
        values = dict(numbers(figures[section]))
        assert values, f"{section} holds no figures"
        bad = {k: v for k, v in values.items() if not math.isfinite(v)}
        assert not bad, f"{section}: not finite: {bad}"
    assert figures["oneblock"]["config"] == "configs/quick.yaml"
    refine = figures["refine"]["quick"]
    assert refine["runs"] == sum(refine["runs_per_level"]) < refine["uniform_runs"] == 33
    for method in ("LSODA", "DOP853"):
        assert 0.0 <= figures["scipy"][method]["agreement_percent"] <= 100.0
        assert figures["scipy"][method]["seconds"] > 0.0
    # K = Kc: neither decays nor runs away; 1000 steps of dt, one more when rounding
    # leaves a sliver before the end time
    assert figures["rk4"]["steps"] in (1000, 1001)
    # the per-system peers (the bench extra, which the Makefile installs): CyRK's DOP853 takes
    # fewer, larger steps than the DOPRI5 loops on the same runs
    sp = figures["single_purpose"]
    for method in ("DOP853", "RK45"):
        assert sp[f"cyrk_{method}"]["systems_per_second"] > 0.0
        assert sp["engine_early_exit_on"][f"vs_cyrk_{method}"] > 0.0
    assert sp["cyrk_DOP853"]["steps_per_run"] < 0.5 * sp["cyrk_RK45"]["steps_per_run"]
    assert "wrote" in run.stdout


def load_plot():
    """``benchmarks/plot_bench.py`` as a module."""
    spec = importlib.util.spec_from_file_location(
        "plot_bench", ROOT / "benchmarks" / "plot_bench.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_peers_plot_draws_the_recorded_figures(tmp_path):
    """``make bench``'s second step draws results/bench_peers.png (the performance
    page's plot) from results/bench.json: every bar is a figure of that file, CyRK's
    bars are left out where CyRK was not installed, and the committed plot stays small."""
    plot = load_plot()
    figures = json.loads((ROOT / "results" / "bench.json").read_text())
    rates = dict((label, rate) for label, rate, _ in plot.peer_rates(figures))
    sp = figures["single_purpose"]
    for label, key, _ in plot.BARS:
        assert rates[label] == sp[key]["systems_per_second"]
    hard = figures["scipy_hard"]
    assert rates["SciPy solve_ivp LSODA loop"] == hard["grid_points"] / hard["scipy_seconds"]
    without_cyrk = {**figures, "single_purpose": {k: v for k, v in sp.items() if "cyrk" not in k}}
    (tmp_path / "bench.json").write_text(json.dumps(without_cyrk))
    assert (
        plot.main(["--json", str(tmp_path / "bench.json"), "--out", str(tmp_path / "p.png")]) == 0
    )
    assert (tmp_path / "p.png").read_bytes().startswith(b"\x89PNG")
    assert not any("CyRK" in label for label, _, _ in plot.peer_rates(without_cyrk))
    assert (ROOT / "results" / "bench_peers.png").stat().st_size < 150_000
