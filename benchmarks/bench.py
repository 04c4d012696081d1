"""``make bench``: how fast the engine is, as ratios measured in one process.

Prints and writes ``results/bench.json``:

* the engine versus a plain ``scipy.integrate.solve_ivp`` loop (LSODA and DOP853)
  over the same one-block grid to the same end time, with the classification
  agreement outside a ±1 % band around Kc;
* the engine versus a single-purpose numba DOPRI5 loop and CyRK's C++ DOP853 and
  RK45 called from numba (the ``bench`` extra) on K/Kc 0.8-1.2;
* kernel throughput (integration steps per second per core) for one and two
  blocks and every model, and the fixed-step RK4 kernel beside the same
  arithmetic written as plainly as possible;
* throughput per block-step of chains and rings of 2 and 32 blocks (the issue's
  target: 32 blocks within 2x of 2 blocks per block-step);
* the inertial model's RODAS4 step in a chain, ring and all-to-all of 8, 32 and 128
  blocks, with its dense LU and its structured solve (issue 39's target: 128 blocks
  within 2x of 8 per block-step);
* the cost of classifying beyond the simple cycle: runs that settle as before, with
  and without the Lyapunov tangent and event bookkeeping, and a step that carries the
  tangent against a plain step (DOPRI5, RODAS4);
* ``configs/twoblock.yaml`` wall time on 1 and 2 threads (JIT cache warm) and
  the 2-thread speed-up; JIT compile time measured separately, in a fresh
  process with the cache off and on;
* the critical kick of ``configs/kick_slip_law.yaml`` on 64 stiffnesses bisected to 1 %:
  runs, rounds and wall time on 2 threads against a uniform scan of the kicks;
* basin fractions (``configs/basins.yaml``): 10⁴ random starts at one multistable point
  against as many runs of a uniform sweep (runs/s), and the matching's own cost apart;
* a refinement by label (``configs/unequal_qd.yaml``, 8 levels: 1/256 of each grid
  step): its runs against the uniform grid of its finest cells, its wall time on 2
  threads, and its time beyond the integration (planning, bookkeeping, the file)
  against the integration's. ``--refine-only`` runs only refinements, those of
  :data:`REFINE_TARGETS` (issue 37's targets, with ``configs/twoblock.yaml``: hours on 2
  cores, its finest runs lie within 1e-4 of Kc and go on to ``max_t_end``), and
  updates the ``refine`` entry of ``--out``.

Timings are not asserted anywhere; ``--quick`` shrinks every size and
``--smoke`` makes them tiny (``tests/test_bench.py`` runs every code path so). The
physics comes from the package: the paper's parameters from ``configs/paper.yaml``
and Kc from ``sweep.model.physics``; the SciPy loops' right-hand side (:func:`scipy_rhs`)
is the tests' reference ``sweep.model.physics.log_form_rhs`` on scalars, checked equal to it
in ``tests/test_bench.py``. Run it as ``python benchmarks/bench.py`` (``make bench``).
"""

import argparse
import contextlib
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from sweep.config import load_config, parse_config, with_changes
from sweep.engine.backends import DaskTasks, LocalThreads, Resources
from sweep.engine.chunks import integrate_in_memory
from sweep.engine.dispatch import load_kernel
from sweep.engine.distributed import connect
from sweep.engine.grid import build_grid
from sweep.engine.runner import compute, run_sweep
from sweep.kernels import layout
from sweep.model import physics
from sweep.variables import REGIMES

ROOT = Path(__file__).resolve().parent.parent
#: The seed paper's fixed parameters (A, B, mu0, V, Phi0, D0; physical units).
PAPER = load_config(ROOT / "configs" / "paper.yaml").fixed
KC_W = float(physics.critical_kappa("quasi-static", PAPER["A"], PAPER["B"])) / PAPER["D0"]  # um^-1


def one_block_config(
    k_values,
    t_end,
    model="quasi-static",
    blocks=1,
    extra=None,
    early=True,
    method="dopri5",
    dt=0.01,
):
    """A config over ``K_W = k_values`` with the paper's parameters (D0 = 1 um)."""
    raw = {
        "name": "bench",
        "blocks": blocks,
        "model": model,
        "parameters": dict(PAPER, **(extra or {})),
        "sweep": {"K_W": {"values": [float(k) for k in k_values]}},
        "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.01},
        "integrator": {"t_end": float(t_end), "method": method, "dt": dt},
        "classification": {"early_exit": early},
        "output": "results/bench.nc",
    }
    if blocks > 1:
        raw["parameters"]["k2_W"] = 0.05
    return parse_config(yaml.safe_dump(raw), source="<bench>")


def engine_run(config, threads=1, repeats=1, passes=1):
    """(results, seconds per sweep) of the engine on ``config``, compiled beforehand.

    Best of ``repeats`` timings, each of ``passes`` back-to-back sweeps (sweeps of
    a fraction of a second are otherwise at the mercy of scheduler jitter).
    """
    g = build_grid(config)
    params, y0, settings = g.params, g.y0, g.settings
    integrate_in_memory(params[:1], y0[:1], settings, threads=threads)  # JIT warm-up
    out = {}

    def run():
        for _ in range(passes):
            out["results"], _ = integrate_in_memory(params, y0, settings, threads=threads)

    seconds = _best_of(repeats, run) / passes
    return out["results"], seconds


def one_block_slopes(lnv, psi, A, B, kappa):
    """(d ln v/dt, dψ/dt) of the one-block quasi-static aging case of
    ``sweep.model.physics.log_form_rhs``, on scalars with ``math``: the peers' right-hand side
    (SciPy's, and CyRK's compiled by numba). The numpy reference costs 32 instead of
    9 µs per call under LSODA (2-element arrays), which would make the SciPy loops
    about 3.5x slower than a user's need be. ``tests/test_bench.py`` checks that the
    two agree."""
    e = math.exp(lnv)
    dpsi = math.exp(-psi) - e
    return (kappa * (1.0 - e) - B * dpsi) / A, dpsi


def scipy_rhs(t, y, A, B, kappa):
    """:func:`one_block_slopes` as ``solve_ivp`` calls a right-hand side."""
    return list(one_block_slopes(y[0], y[1], A, B, kappa))


def scipy_classify(k_w, t_end, method, lnv_cap):
    """What a user's plain SciPy loop would do: integrate, then classify.

    Runaway: ln v crosses the cap (terminal event). Otherwise the amplitude of
    (ln v, ln Φ/Φss) over the last fifth of the run against the fifth before it:
    shrinking → steady, within 1 % → stick_slip, growing → undecided.
    """
    from scipy.integrate import solve_ivp

    def cap(t, y, *args):
        return y[0] - lnv_cap

    cap.terminal = True
    A, B = PAPER["A"], PAPER["B"]
    y0 = [0.0, math.log(1.01)]
    sol = solve_ivp(
        scipy_rhs,
        (0.0, t_end),
        y0,
        method=method,
        rtol=1e-8,
        atol=1e-10,
        args=(A, B, k_w * PAPER["D0"]),
        events=cap,
        dense_output=True,
    )
    if sol.status == 1 or not np.all(np.isfinite(sol.y[:, -1])):
        return "runaway"
    t = np.linspace(0.6 * t_end, t_end, 4000)
    amp = np.abs(sol.sol(t)).max(axis=0)
    before, last = amp[:2000].max(), amp[2000:].max()
    if last < 1e-6 or last < 0.99 * before:
        return "steady"
    return "stick_slip" if last <= 1.01 * before else "undecided"


def bench_scipy(n_points, t_end):
    """Engine (1 thread) vs SciPy LSODA and DOP853 loops on one one-block grid."""
    k_values = np.linspace(0.5 * KC_W, 1.5 * KC_W, n_points)
    config = one_block_config(k_values, t_end)
    results, engine_s = engine_run(config, threads=1, repeats=3)
    full, _ = engine_run(one_block_config(k_values, t_end, early=False))
    engine_regimes = [REGIMES[int(r)] for r in results[:, layout.R_REGIME]]
    outside = np.abs(k_values / KC_W - 1.0) > 0.01
    cap = math.log(config.classification.v_cap_over_V)
    out = {
        "grid_points": n_points,
        "t_end_D0_over_V": t_end,
        "engine_seconds": engine_s,
        "mean_steps_per_run": float(results[:, layout.R_N_STEPS].mean()),
        "mean_steps_per_run_without_early_exit": float(full[:, layout.R_N_STEPS].mean()),
    }
    for method in ("LSODA", "DOP853"):
        start = time.perf_counter()
        ref = [scipy_classify(k, t_end, method, cap) for k in k_values]
        seconds = time.perf_counter() - start
        agree = [a == b for a, b, o in zip(engine_regimes, ref, outside, strict=True) if o]
        out[method] = {
            "seconds": seconds,
            "speedup_per_core": seconds / engine_s,
            "agreement_percent": 100.0 * sum(agree) / len(agree),
        }
    return out


def bench_throughput(n_systems, t_end):
    """Integration steps per second per core (1 thread), per model, stepper and blocks.

    Each case is a limit cycle or a slowly decaying oscillation near its own Kc,
    run to ``t_end`` without early exit, so every case does real work.
    """
    cases = {
        "quasi-static dopri5": ("quasi-static", {}, 1.02, "dopri5"),
        "quasi-dynamic dopri5": ("quasi-dynamic", {"eta_W": 0.1}, 0.9, "dopri5"),
        "inertial dopri5": ("inertial", {"m_W": 1.0}, 0.95, "dopri5"),
        "inertial rosenbrock": ("inertial", {"m_W": 1.0}, 0.95, "rosenbrock"),
    }
    out = {}
    for label, (model, extra, k_over_kc, method) in cases.items():
        for blocks in (1, 2):
            kc = _critical_k_w(model, extra)
            k_values = np.linspace(k_over_kc, k_over_kc * 1.01, n_systems) * kc
            config = one_block_config(
                k_values, t_end, model, blocks, extra, early=False, method=method
            )
            results, seconds = engine_run(config, threads=1)
            steps = results[:, layout.R_N_STEPS].sum() + results[:, layout.R_N_REJECTED].sum()
            out[f"{label}/{blocks}"] = {"steps": int(steps), "steps_per_second": steps / seconds}
    for key, value in out.items():
        reference = out["quasi-static dopri5/" + key.rsplit("/", 1)[1]]["steps_per_second"]
        value["relative_to_quasi_static"] = value["steps_per_second"] / reference
    return out


def bench_block_scaling(n_systems, t_end, sizes=(2, 32)):
    """Block-steps (accepted and rejected steps × blocks) per second per core, per
    case and number of blocks, relative to the smallest chain of the same model and method.

    Identical blocks near their Kc (k2/W = 0.05 µm⁻¹), started with
    Φ_i/Φss = 1.01 + 0.005 sin(1.7 i) so every mode moves, run to ``t_end`` without
    early exit: quasi-static DOPRI5 in a chain, ring and all-to-all (K/Kc = 1.02-1.03),
    and the inertial model's default RODAS4 in a chain (m/W = 1 s²/µm, K/Kc = 0.95;
    its Jacobian is dense, so an LU solve costs O(N³) per stage).
    """
    cases = {
        "chain": ("quasi-static", {}, 1.02, "dopri5", "chain"),
        "ring": ("quasi-static", {}, 1.02, "dopri5", "ring"),
        "all": ("quasi-static", {}, 1.02, "dopri5", "all"),
        "inertial rodas4 chain": ("inertial", {"m_W": 1.0}, 0.95, "rosenbrock", "chain"),
    }
    out = {}
    for label, (model, extra, k_over_kc, method, coupling) in cases.items():
        for blocks in sizes:
            if coupling == "ring" and blocks < 3:
                continue
            k_values = np.linspace(k_over_kc, k_over_kc * 1.01, n_systems) * _critical_k_w(
                model, extra
            )
            config = with_changes(
                one_block_config(k_values, t_end, model, blocks, extra, early=False,
                                 method=method),
                {"coupling": coupling,
                 "initial": {"phi_over_phi_ss": [1.01 + 0.005 * math.sin(1.7 * i)
                                                 for i in range(blocks)]}},
            )  # fmt: skip
            results, seconds = engine_run(config, threads=1, repeats=2)
            steps = results[:, layout.R_N_STEPS].sum() + results[:, layout.R_N_REJECTED].sum()
            out[f"{label}/{blocks}"] = {
                "steps": int(steps),
                "block_steps_per_second": steps * blocks / seconds,
                "ns_per_step": 1e9 * seconds / steps,
            }
    for key, value in out.items():
        base = "inertial rodas4 chain" if key.startswith("inertial") else "chain"
        reference = out[f"{base}/{sizes[0]}"]["block_steps_per_second"]
        value["relative_to_smallest_chain"] = value["block_steps_per_second"] / reference
    return out


def bench_implicit_scaling(n_systems, t_end, sizes=(8, 32, 128)):
    """µs per step and ns per block-step (accepted and rejected steps, 1 thread) of the
    inertial model's RODAS4 with its dense LU (``rosenbrock``) and its structured solve
    (``rosenbrock-structured``, issue 39: O(N) per step), in a chain, ring and
    all-to-all of ``sizes`` blocks, each per block-step relative to its own smallest
    size (the target: within 2x at 128 blocks), and structured against dense.

    Identical blocks below their Kc (m/W = 1 s²/µm, K/Kc = 0.95, k2/W = 0.05 µm⁻¹),
    started with Φ_i/Φss = 1.01 + 0.005 sin(1.7 i), run to ``t_end`` without early exit.
    """
    extra = {"m_W": 1.0}
    k_values = np.linspace(0.95, 0.95 * 1.01, n_systems) * _critical_k_w("inertial", extra)
    out = {}
    for coupling in ("chain", "ring", "all"):
        for method in ("rosenbrock", "rosenbrock-structured"):
            for blocks in sizes:
                config = with_changes(
                    one_block_config(k_values, t_end, "inertial", blocks, extra, early=False,
                                     method=method),
                    {"coupling": coupling,
                     "initial": {"phi_over_phi_ss": [1.01 + 0.005 * math.sin(1.7 * i)
                                                     for i in range(blocks)]}},
                )  # fmt: skip
                results, seconds = engine_run(config, threads=1)
                steps = results[:, layout.R_N_STEPS].sum() + results[:, layout.R_N_REJECTED].sum()
                out[f"{coupling} {method}/{blocks}"] = {
                    "steps": int(steps),
                    "us_per_step": 1e6 * seconds / steps,
                    "ns_per_block_step": 1e9 * seconds / (steps * blocks),
                }
    for key, value in out.items():
        case, blocks = key.rsplit("/", 1)
        value["relative_to_smallest"] = (
            value["ns_per_block_step"] / out[f"{case}/{sizes[0]}"]["ns_per_block_step"]
        )
        if "structured" in case:
            dense = out[f"{case.replace('-structured', '')}/{blocks}"]
            value["dense_over_structured"] = dense["us_per_step"] / value["us_per_step"]
    return out


#: Numbers of blocks at which :func:`bench_structured_crossing` compares the two RODAS4
#: solves (rings from 3 blocks, all-to-all and unequal blocks from 2).
CROSSING_SIZES = (1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 32)
#: The unequal blocks of :func:`bench_structured_crossing`: a seeded spread of D0 and A.
CROSSING_SPREAD = {"D0": 0.2, "A": 0.05, "seed": 0}


def bench_structured_crossing(n_systems, t_end, seconds, sizes=CROSSING_SIZES, min_pairs=5):
    """Where the inertial model's structured RODAS4 (``rosenbrock-structured``) becomes
    cheaper per step than the dense one (``rosenbrock``): the number of blocks from which
    an inertial run that names no method gets the structured one
    (``sweep.config.schema.STRUCTURED_FROM``).

    Per coupling (chain, ring, all) and equal or unequal blocks (a seeded spread,
    :data:`CROSSING_SPREAD`), at each of ``sizes`` blocks: the same runs (m/W = 1 s²/µm,
    K/Kc = 0.95 of identical blocks, k2/W = 0.05 µm⁻¹, Φ_i/Φss = 1.01 + 0.005 sin(1.7 i),
    early exit off, 1 thread) with either method, both kernels compiled beforehand, run
    in pairs, dense and structured one after the other (the order swapped every pair),
    as many pairs as take about ``seconds`` of CPU time (at least ``min_pairs``; both
    methods take the same steps). Each pair gives a ratio of CPU time per step (accepted
    and rejected steps), dense over structured; the entry keeps their median and the
    ratio of each method's shortest time per step. ``crossing``: per case the smallest
    size from which the median ratio is above 1 at every larger size measured (None:
    dense is as fast at the largest size). The machine's load average before and after
    says how much other work shared it.
    """
    extra = {"m_W": 1.0}
    k_values = np.linspace(0.95, 0.95 * 1.01, n_systems) * _critical_k_w("inertial", extra)
    methods = ("rosenbrock", "rosenbrock-structured")
    out = {"sizes": list(sizes), "seconds_per_size": seconds, "t_end_D0_over_V": t_end,
           "systems": n_systems, "load_average_before": os.getloadavg()[0]}  # fmt: skip
    crossing = {}
    for coupling in ("chain", "ring", "all"):
        for blocks_differ in (False, True):
            case = f"{coupling} {'unequal' if blocks_differ else 'equal'}"
            ratios = {}
            for blocks in sizes:
                if (coupling == "ring" and blocks < 3) or (
                    (coupling == "all" or blocks_differ) and blocks < 2
                ):
                    continue
                changes = {"coupling": coupling,
                           "initial": {"phi_over_phi_ss": [1.01 + 0.005 * math.sin(1.7 * i)
                                                           for i in range(blocks)]}}  # fmt: skip
                if blocks_differ:
                    changes["spread"] = CROSSING_SPREAD
                configs = [
                    with_changes(one_block_config(k_values, t_end, "inertial", blocks, extra,
                                                  early=False, method=method), changes)
                    for method in methods
                ]  # fmt: skip
                us, steps = _paired_us_per_step(configs, seconds, min_pairs)
                pairs = np.divide(us[0], us[1])
                ratios[blocks] = float(np.median(pairs))
                out[f"{case}/{blocks}"] = {
                    "steps": steps,
                    "pairs": len(pairs),
                    "dense_us_per_step": float(np.median(us[0])),
                    "structured_us_per_step": float(np.median(us[1])),
                    "dense_over_structured": ratios[blocks],
                    "dense_over_structured_quartiles": np.quantile(pairs, [0.25, 0.75]).tolist(),
                    "dense_over_structured_shortest": min(us[0]) / min(us[1]),
                }
            faster = [n for n in ratios if all(ratios[m] > 1.0 for m in ratios if m >= n)]
            crossing[case] = min(faster) if faster else None
    out["crossing"] = crossing
    out["load_average_after"] = os.getloadavg()[0]  # other work on the machine's cores
    return out


#: Most pairs :func:`_paired_us_per_step` times (the smallest systems take milliseconds).
MAX_PAIRS = 100


def _paired_us_per_step(configs, seconds, min_pairs):
    """CPU µs per step (accepted and rejected) of each config's runs on 1 thread, timed
    in turn, one integration of the runs each, as many rounds as take about ``seconds``
    (``min_pairs`` to :data:`MAX_PAIRS`; the order reversed every other round), after
    compiling each kernel (a call on one run); and each config's steps. Timing the
    configs run by run puts each pair under the same load of a shared machine; the
    process's CPU time, not the wall time, leaves out the time other work holds the
    core (it still shares the caches)."""
    grids = [build_grid(config) for config in configs]
    for g in grids:  # compile or load every kernel before any timing
        integrate_in_memory(g.params[:1], g.y0[:1], g.settings, threads=1)
    steps, once = [], []
    for g in grids:  # one untimed integration: the step counts and the time of a round
        start = time.process_time()
        results, _ = integrate_in_memory(g.params, g.y0, g.settings, threads=1)
        once.append(time.process_time() - start)
        steps.append(
            int(results[:, layout.R_N_STEPS].sum() + results[:, layout.R_N_REJECTED].sum())
        )
    rounds = min(MAX_PAIRS, max(min_pairs, math.ceil(seconds / max(sum(once), 1e-9))))
    us = [[] for _ in grids]
    for r in range(rounds):
        for i in range(len(grids)) if r % 2 == 0 else reversed(range(len(grids))):
            g = grids[i]
            start = time.process_time()
            integrate_in_memory(g.params, g.y0, g.settings, threads=1)
            us[i].append(1e6 * (time.process_time() - start) / steps[i])
    return us, steps


def _critical_k_w(model, extra):
    d = physics.dimensionless(
        PAPER["A"],
        PAPER["B"],
        PAPER["D0"],
        PAPER["V"],
        1.0,
        0.0,
        extra.get("eta_W", 0.0),
        extra.get("m_W", 0.0),
    )
    return (
        float(physics.critical_kappa(model, d["A"], d["B"], d["eta_hat"], d["mass_hat"]))
        / PAPER["D0"]
    )


def _plain_rk4_source():
    """The one-block quasi-static aging RK4 loop written as plainly as possible."""

    def plain_rk4(lnv, psi, A, B, kappa, dt, n_steps):
        for _ in range(n_steps):
            e = math.exp(lnv)
            d1 = math.exp(-psi) - e
            l1 = (kappa * (1 - e) - B * d1) / A
            a, b = lnv + 0.5 * dt * l1, psi + 0.5 * dt * d1
            e = math.exp(a)
            d2 = math.exp(-b) - e
            l2 = (kappa * (1 - e) - B * d2) / A
            a, b = lnv + 0.5 * dt * l2, psi + 0.5 * dt * d2
            e = math.exp(a)
            d3 = math.exp(-b) - e
            l3 = (kappa * (1 - e) - B * d3) / A
            a, b = lnv + dt * l3, psi + dt * d3
            e = math.exp(a)
            d4 = math.exp(-b) - e
            l4 = (kappa * (1 - e) - B * d4) / A
            lnv += dt / 6 * (l1 + 2 * l2 + 2 * l3 + l4)
            psi += dt / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
        return lnv, psi

    return plain_rk4


def _plain_rk4_lanes_source():
    """The plain RK4 loop over several systems at once (one lane each, the lane the
    innermost loop): what vectorising RK4 across systems would give."""

    def plain_rk4_lanes(lnv, psi, A, B, kappa, dt, n_steps):
        lanes = lnv.size
        y0, y1 = lnv.copy(), psi.copy()
        s0, s1, l, d = np.empty(lanes), np.empty(lanes), np.empty(lanes), np.empty(lanes)
        for _ in range(n_steps):
            for stage in range(4):
                c = 0.0 if stage == 0 else (0.5 * dt if stage < 3 else dt)
                w = dt / 6 if stage in (0, 3) else dt / 3
                for j in range(lanes):
                    if stage == 0:
                        s0[j], s1[j], l[j], d[j] = y0[j], y1[j], 0.0, 0.0
                    e = math.exp(y0[j] + c * l[j])
                    d[j] = math.exp(-(y1[j] + c * d[j])) - e
                    l[j] = (kappa * (1 - e) - B * d[j]) / A
                    s0[j] += w * l[j]
                    s1[j] += w * d[j]
            y0[:], y1[:] = s0, s1
        return y0, y1

    return plain_rk4_lanes


def bench_rk4_reference(n_steps, lanes=16):
    """The engine's RK4 kernel vs the plain loop: time per step, same system and dt;
    and the plain loop over ``lanes`` systems at once, time per system-step, with
    numba's SVML state (vectorised exp; off unless llvmlite is built with it).

    The system sits at K = Kc, where the quasi-static oscillation neither decays
    nor grows, so both loops do ``n_steps`` steps of ordinary arithmetic.
    """
    import llvmlite.binding
    import numba

    plain = numba.njit(nogil=True)(_plain_rk4_source())
    plain_lanes = numba.njit(nogil=True, error_model="numpy")(_plain_rk4_lanes_source())
    dt = 0.01
    config = one_block_config([KC_W], n_steps * dt, early=False, method="rk4", dt=dt)
    results, engine_s = engine_run(config, threads=1)
    steps = int(results[0, layout.R_N_STEPS])
    A, B, kappa = PAPER["A"], PAPER["B"], KC_W * PAPER["D0"]
    plain(0.0, math.log(1.01), A, B, kappa, dt, 10)
    plain_s = _best_of(3, lambda: plain(0.0, math.log(1.01), A, B, kappa, dt, steps))
    start = (np.zeros(lanes), np.full(lanes, math.log(1.01)))
    plain_lanes(*start, A, B, kappa, dt, 10)
    lanes_s = _best_of(3, lambda: plain_lanes(*start, A, B, kappa, dt, -(-steps // lanes)))
    return {
        "steps": steps,
        "engine_ns_per_step": 1e9 * engine_s / steps,
        "plain_ns_per_step": 1e9 * plain_s / steps,
        "engine_over_plain": engine_s / plain_s,
        "lanes": lanes,
        "plain_lanes_ns_per_system_step": 1e9 * lanes_s / (lanes * -(-steps // lanes)),
        "svml": {
            "numba_using_svml": bool(numba.config.USING_SVML),
            "llvmlite_has_svml": bool(llvmlite.binding.has_svml),
        },
    }


def _plain_dopri5_source():
    """One quasi-static aging block with a textbook DOPRI5 loop (Hairer, Nørsett &
    Wanner II.4: error norm, safety 0.9, step factors 0.2-10, no step cap), written
    for this system only; it stops at the velocity cap and keeps no statistics."""

    def plain_dopri5(psi0, A, B, kappa, t_end, rtol, atol, lnv_cap):
        def f(lnv, psi):
            e = math.exp(lnv)
            dpsi = math.exp(-psi) - e
            return (kappa * (1.0 - e) - B * dpsi) / A, dpsi

        t, h, steps = 0.0, 1e-3, 0
        y0, y1 = 0.0, psi0
        k1a, k1b = f(y0, y1)
        while t < t_end and y0 < lnv_cap:
            h = min(h, t_end - t)
            k2a, k2b = f(y0 + h * 0.2 * k1a, y1 + h * 0.2 * k1b)
            k3a, k3b = f(
                y0 + h * (3 / 40 * k1a + 9 / 40 * k2a), y1 + h * (3 / 40 * k1b + 9 / 40 * k2b)
            )
            k4a, k4b = f(
                y0 + h * (44 / 45 * k1a - 56 / 15 * k2a + 32 / 9 * k3a),
                y1 + h * (44 / 45 * k1b - 56 / 15 * k2b + 32 / 9 * k3b),
            )
            k5a, k5b = f(
                y0 + h * (19372 / 6561 * k1a - 25360 / 2187 * k2a + 64448 / 6561 * k3a
                          - 212 / 729 * k4a),
                y1 + h * (19372 / 6561 * k1b - 25360 / 2187 * k2b + 64448 / 6561 * k3b
                          - 212 / 729 * k4b),
            )  # fmt: skip
            k6a, k6b = f(
                y0 + h * (9017 / 3168 * k1a - 355 / 33 * k2a + 46732 / 5247 * k3a
                          + 49 / 176 * k4a - 5103 / 18656 * k5a),
                y1 + h * (9017 / 3168 * k1b - 355 / 33 * k2b + 46732 / 5247 * k3b
                          + 49 / 176 * k4b - 5103 / 18656 * k5b),
            )  # fmt: skip
            za = y0 + h * (35 / 384 * k1a + 500 / 1113 * k3a + 125 / 192 * k4a
                           - 2187 / 6784 * k5a + 11 / 84 * k6a)  # fmt: skip
            zb = y1 + h * (35 / 384 * k1b + 500 / 1113 * k3b + 125 / 192 * k4b
                           - 2187 / 6784 * k5b + 11 / 84 * k6b)  # fmt: skip
            k7a, k7b = f(za, zb)
            ea = h * (71 / 57600 * k1a - 71 / 16695 * k3a + 71 / 1920 * k4a
                      - 17253 / 339200 * k5a + 22 / 525 * k6a - 1 / 40 * k7a)  # fmt: skip
            eb = h * (71 / 57600 * k1b - 71 / 16695 * k3b + 71 / 1920 * k4b
                      - 17253 / 339200 * k5b + 22 / 525 * k6b - 1 / 40 * k7b)  # fmt: skip
            sa = atol + rtol * max(abs(y0), abs(za))
            sb = atol + rtol * max(abs(y1), abs(zb))
            err = math.sqrt(0.5 * ((ea / sa) ** 2 + (eb / sb) ** 2))
            if err <= 1.0:
                t += h
                y0, y1, k1a, k1b = za, zb, k7a, k7b
                steps += 1
                h *= min(10.0, max(0.2, 0.9 * max(err, 1e-10) ** -0.2))
            else:
                steps += 1
                h *= max(0.2, 0.9 * err**-0.2)
        return steps

    return plain_dopri5


def _cyrk_loop():
    """A loop over one-block runs through CyRK's C++ solver (``nbsolve2_ivp``), called
    from numba as a user who ``pip install cyrk`` would write it, or None when CyRK
    is not installed (``pip install -e '.[bench]'``; ``make bench`` installs it).
    Returns ``(run_all, diffeq_address)``; ``run_all`` fills accepted steps per run."""
    try:
        from CyRK import nb_diffeq_addr, nbsolve2_ivp
    except ImportError:
        return None
    import numba

    slopes = numba.njit(one_block_slopes)

    def diffeq(dy, t, y, args):  # ln v/V and psi of one quasi-static aging block
        dy[0], dy[1] = slopes(y[0], y[1], args[0], args[1], args[2])

    @numba.njit
    def run_all(address, kappas, A, B, psi0, t_end, rtol, atol, method, steps):
        y0 = np.array([0.0, psi0])
        for i in range(kappas.size):
            args = np.array([A, B, kappas[i]])
            out = nbsolve2_ivp(
                address, (0.0, t_end), y0, method=method, args=args, rtol=rtol, atol=atol
            )
            steps[i] = out.steps_taken
            out.free()

    return run_all, nb_diffeq_addr(diffeq)


#: CyRK's methods the engine is compared with (its fastest here, and its DOPRI5).
CYRK_METHODS = ("DOP853", "RK45")
#: The engine's runs of the single-purpose comparison: (label, early exit, method).
ENGINE_RUNS = (
    ("engine_early_exit_off", False, "dop853"),
    ("engine_early_exit_on", True, "dop853"),
    ("engine_dopri5_early_exit_off", False, "dopri5"),
    ("engine_dopri5_early_exit_on", True, "dopri5"),
)


def bench_single_purpose(n_points, t_end):
    """The engine (early exit off and on) against a single-purpose DOPRI5 loop and, where
    CyRK is installed, CyRK's DOP853 and RK45 (``CYRK_METHODS``) on the hard grid
    K/Kc = 0.8-1.2 (1 thread, rtol 1e-8, atol 1e-10, the paper's start): systems/s,
    accepted steps per run, ns per (accepted or rejected) step. CyRK has no event
    to stop at the velocity cap: its runaway runs end where its step size fails."""
    import numba

    plain = numba.njit(nogil=True)(_plain_dopri5_source())
    k_values = np.linspace(0.8 * KC_W, 1.2 * KC_W, n_points)
    A, B, psi0 = PAPER["A"], PAPER["B"], math.log(1.01)
    lnv_cap = math.log(1e6)
    plain(psi0, A, B, k_values[0], 1.0, 1e-8, 1e-10, lnv_cap)
    steps = np.zeros(n_points)

    def run_plain():
        for i, k in enumerate(k_values):
            steps[i] = plain(psi0, A, B, k * PAPER["D0"], t_end, 1e-8, 1e-10, lnv_cap)

    plain_s = _best_of(3, run_plain)
    out = {
        "grid": "K/Kc 0.8-1.2",
        "grid_points": n_points,
        "t_end_D0_over_V": t_end,
        "plain": {
            "systems_per_second": n_points / plain_s,
            "steps_per_run": float(steps.mean()),
            "ns_per_step": 1e9 * plain_s / steps.sum(),
        },
    }
    peers = {}
    cyrk = _cyrk_loop()
    if cyrk is not None:
        run_all, address = cyrk
        kappas = k_values * PAPER["D0"]
        for method in CYRK_METHODS:
            run_all(address, kappas[:1], A, B, psi0, 1.0, 1e-8, 1e-10, method, steps[:1])
            seconds = _best_of(3, lambda m=method: run_all(
                address, kappas, A, B, psi0, t_end, 1e-8, 1e-10, m, steps))  # fmt: skip
            peers[method] = seconds
            out[f"cyrk_{method}"] = {
                "systems_per_second": n_points / seconds,
                "steps_per_run": float(steps.mean()),
                "ns_per_step": 1e9 * seconds / steps.sum(),
            }
    for label, early, method in ENGINE_RUNS:
        config = one_block_config(k_values, t_end, early=early, method=method)
        results, seconds = engine_run(config, repeats=3)
        tried = results[:, layout.R_N_STEPS].sum() + results[:, layout.R_N_REJECTED].sum()
        out[label] = {
            "systems_per_second": n_points / seconds,
            "steps_per_run": float(results[:, layout.R_N_STEPS].mean()),
            "ns_per_step": 1e9 * seconds / tried,
            "vs_plain": plain_s / seconds,
            **{f"vs_cyrk_{m}": peer / seconds for m, peer in peers.items()},
        }
    return out


def bench_scipy_hard(n_points, t_end):
    """Engine with early exit vs a SciPy LSODA loop per core on K/Kc = 0.8-1.2."""
    k_values = np.linspace(0.8 * KC_W, 1.2 * KC_W, n_points)
    _, engine_s = engine_run(one_block_config(k_values, t_end), threads=1, repeats=3)
    cap = math.log(1e6)
    start = time.perf_counter()
    for k in k_values:
        scipy_classify(k, t_end, "LSODA", cap)
    seconds = time.perf_counter() - start
    return {"grid_points": n_points, "scipy_seconds": seconds, "engine_seconds": engine_s,
            "speedup_per_core": seconds / engine_s}  # fmt: skip


def bench_attractors(n_points, t_end):
    """What the classification beyond the simple cycle costs, per step (one block, the
    paper's start; two inertial blocks for RODAS4).

    ``settling``: runs that settle by t_end (K/Kc 0.5-0.95 and 1.05-1.5), the default
    classification (λ1 for runs unsettled at t_end, 32 events kept) against
    ``lyapunov: never, events: 0``: the same runs and steps, so any difference is the
    bookkeeping. ``tangent/<method>``: K/Kc 0.8-1.2, early exit off, λ1 over every
    whole run (``always``) against ``never``: the cost of a step that carries the
    tangent.
    """
    half = max(1, n_points // 2)
    settling = np.concatenate([np.linspace(0.5, 0.95, half), np.linspace(1.05, 1.5, half)])
    grid = np.linspace(0.8 * KC_W, 1.2 * KC_W, n_points)
    out = {"grid_points": n_points, "t_end_D0_over_V": t_end}

    def per_step(config):
        results, seconds = engine_run(config, repeats=3, passes=2)
        return 1e9 * seconds / results[:, layout.R_N_STEPS].sum()

    lean = {"lyapunov": "never", "events": 0}
    base = one_block_config(settling * KC_W, t_end)
    ns_lean = per_step(with_changes(base, {"classification": lean}))
    ns_default = per_step(base)
    out["settling"] = {"ns_per_step_lean": ns_lean, "ns_per_step_default": ns_default,
                       "default_over_lean": ns_default / ns_lean}  # fmt: skip
    inertial = one_block_config(
        np.linspace(0.004, 0.006, max(2, n_points // 4)), t_end, model="inertial", blocks=2,
        extra={"m_W": 1.0, "V": 1.0, "D0": 0.8}, method="rosenbrock", early=False,
    )  # fmt: skip
    for method, config in (("dopri5", one_block_config(grid, t_end, early=False)),
                           ("rosenbrock", inertial)):  # fmt: skip
        plain = per_step(with_changes(config, {"classification": {"lyapunov": "never"}}))
        tangent = per_step(with_changes(config, {"classification": {"lyapunov": "always"}}))
        out[f"tangent/{method}"] = {"ns_per_step": plain, "ns_per_step_with_tangent": tangent,
                                    "tangent_over_plain": tangent / plain}  # fmt: skip
    return out


def bench_threads_large(n_points, t_end):
    """2-thread speed-up on a one-block sweep of ``n_points`` (K/Kc 0.5-1.5)."""
    config = one_block_config(np.linspace(0.5 * KC_W, 1.5 * KC_W, n_points), t_end)
    _, one = engine_run(config, threads=1)
    _, two = engine_run(config, threads=2, repeats=2)
    return {"grid_points": n_points, "seconds_1_thread": one, "seconds_2_thread": two,
            "speedup_2_threads": one / two}  # fmt: skip


def _best_of(repeats, func):
    """Shortest wall time (s) of ``repeats`` calls of ``func``."""
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def bench_sweep(config_path):
    """Wall time and runs/s of a whole config on 1 and 2 threads (JIT warm; best of 5)."""
    config = load_config(config_path)
    n = math.prod(config.shape)
    out = {"config": os.path.relpath(config_path, ROOT), "runs": n}
    for threads in (1, 2):
        _, seconds = engine_run(config, threads=threads, repeats=5, passes=5)
        out[f"seconds_{threads}_thread"] = seconds
        out[f"runs_per_second_{threads}_thread"] = n / seconds
    out["speedup_2_threads"] = out["seconds_1_thread"] / out["seconds_2_thread"]
    return out


#: The multistable point of ``configs/basins.yaml`` the basin benchmark starts from (K/Kc).
BASINS_RATIO = 1.006
#: The keys of a swept axis to drop for a list of values (``with_changes``).
AXIS_KEYS = {"start": None, "stop": None, "num": None, "scale": None}


def bench_basins(n_starts, threads=2):
    """``n_starts`` random starts at one point (``configs/basins.yaml`` at K/Kc = 1.006:
    one inertial block, steady sliding and a cycle coexist) against a uniform sweep of
    the same box of starts at that point (ln v/V and ln Φ/Φss each in ±1, the ensemble's
    amplitude, on a √n × √n grid of the start axes); runs/s of each on ``threads``
    threads (JIT warm), and the cost of :func:`~sweep.results.basins.basin_fractions` on the
    ensemble's Dataset apart (matching only: the Dataset built beforehand)."""
    from sweep.results.basins import basin_fractions
    from sweep.results.dataset import build_dataset

    base = load_config(repo_config("basins"))
    fixed = base.fixed
    kc = physics.critical_kappa(
        "inertial", fixed["A"], fixed["B"], mass_hat=(fixed["m_W"] * fixed["V"] ** 2 / fixed["D0"])
    )
    k_w = float(kc) / fixed["D0"] * BASINS_RATIO
    ensemble = with_changes(
        base, {"sweep": {"K_W": {**AXIS_KEYS, "values": [k_w]}}, "initial": {"ensemble": n_starts}}
    )
    side = max(2, math.isqrt(n_starts))
    box = {"start": math.exp(-1.0), "stop": math.exp(1.0), "num": side, "scale": "log"}
    uniform = with_changes(
        base,
        {
            "sweep": {
                "K_W": {**AXIS_KEYS, "values": [k_w]},
                "initial_v_over_V": box,
                "initial_phi_over_phi_ss": box,
            },
            "initial": {"ensemble": 0},
        },
    )
    out = {
        "config": "configs/basins.yaml",
        "K_over_Kc": BASINS_RATIO,
        "starts": n_starts,
        "threads": threads,
    }
    for name, config in (("uniform", uniform), ("ensemble", ensemble)):
        g = build_grid(config)
        integrate_in_memory(g.params[:1], g.y0[:1], g.settings, threads=1)  # JIT warm-up
        start = time.perf_counter()
        results, y_final = integrate_in_memory(g.params, g.y0, g.settings, threads=threads)
        seconds = time.perf_counter() - start
        out[f"{name}_seconds"] = seconds
        out[f"{name}_runs"] = g.n
        out[f"{name}_runs_per_second"] = g.n / seconds
    ds = build_dataset(g, results, y_final)  # the ensemble's, the last run
    start = time.perf_counter()
    basins = basin_fractions(ds)
    out["matching_seconds"] = time.perf_counter() - start
    out["matching_over_integration"] = out["matching_seconds"] / out["ensemble_seconds"]
    out["fractions"] = {
        str(a): float(f)
        for a, f in zip(
            basins["attractor"].values, basins["basin_fraction"].values.ravel(), strict=True
        )
    }
    out["unresolved_fraction"] = float(basins["unresolved_fraction"].values.ravel()[0])
    return out


#: A run of a tiny sweep of CONFIG (with CHANGES) in a fresh process: prints its seconds.
COMPILE_RUN = (
    "import ast, time, sys; t=time.perf_counter();"
    "from sweep.config import load_config, with_changes; from sweep.engine.runner import compute;"
    "compute(with_changes(load_config(sys.argv[1]), ast.literal_eval(sys.argv[2])),"
    " show_progress=False);"
    "print(time.perf_counter()-t)"
)
#: Another model than the default config's: a variant whose kernel is not cached.
FURTHER_VARIANT = {"model": "quasi-dynamic", "parameters": {"eta_W": 0.1}}


def bench_compile(config_path, empty_cache=True):
    """JIT time: fresh processes running a tiny sweep with an empty numba cache (which
    they fill), then with it warm; and a further variant (another model), with only the
    helpers it shares cached. ``empty_cache=False`` (``--smoke``) runs the same processes
    on the package's own cache: a check that the code runs, whose figures are loads."""

    def seconds(changes=None):
        env = dict(os.environ, SWEEP_NUMBA_CACHE="1")
        if cache_dir is not None:
            env["NUMBA_CACHE_DIR"] = cache_dir
        command = [sys.executable, "-c", COMPILE_RUN, str(config_path), repr(changes or {})]
        run = subprocess.run(command, env=env, check=True, capture_output=True)
        return float(run.stdout.split()[-1])

    out = {}
    folder = tempfile.TemporaryDirectory() if empty_cache else contextlib.nullcontext()
    with folder as cache_dir:
        out["cold_seconds"] = seconds()  # compiles the kernel and every helper
        out["cache_warm_seconds"] = seconds()
        out["further_variant_seconds"] = seconds(FURTHER_VARIANT)
        out["further_warm_seconds"] = seconds(FURTHER_VARIANT)
    out["compile_seconds"] = out["cold_seconds"] - out["cache_warm_seconds"]
    out["further_compile_seconds"] = out["further_variant_seconds"] - out["further_warm_seconds"]
    return out


def time_compute(config, threads=None, client=None):
    """Wall time (s) to compute ``config`` in memory, kernels compiled beforehand."""
    g = build_grid(config)
    (LocalThreads(threads) if client is None else DaskTasks(client)).compile(g.params, g.settings)
    start = time.perf_counter()
    compute(config, threads, show_progress=False, client=client)
    return time.perf_counter() - start


def bench_dask(config_path, workers=2):
    """Wall times (s) of computing a config on 1 and ``workers`` local threads and on a
    LocalCluster of ``workers`` processes (kernels compiled beforehand).

    ``threads_1``, ``threads_n``, ``speedup`` (threads_1 / threads_n),
    ``cluster_start`` (starting the LocalCluster and its workers), ``cluster`` (the
    computation on it) and ``cluster_over_threads``.
    """
    config = load_config(config_path)
    times = {"threads_1": time_compute(config, threads=1)}
    times["threads_n"] = time_compute(config, threads=workers)
    times["speedup"] = times["threads_1"] / times["threads_n"]
    start = time.perf_counter()
    with connect(local_workers=workers) as client:
        client.wait_for_workers(workers)
        g = build_grid(config)
        client.run(load_kernel, g.params, g.settings)
        times["cluster_start"] = time.perf_counter() - start
        times["cluster"] = time_compute(config, client=client)
    times["cluster_over_threads"] = times["cluster"] / times["threads_n"]
    return times


def bench_refine(config_path, levels, threads=2):
    """A refinement of ``config_path`` to ``levels`` levels on ``threads`` threads, written
    to a file (kernels compiled beforehand): its runs against the uniform grid of its
    finest cells, and what is not integration (planning and labelling each level,
    bookkeeping, writing the file) against the integration's wall time."""
    config = with_changes(load_config(config_path), {"refine": {"levels": levels}})
    with tempfile.TemporaryDirectory() as folder:
        # warm-up: the grid alone (level 0), which compiles and loads the NetCDF writer
        grid_only = with_changes(config, {"refine": {"levels": 0}})
        run_sweep(grid_only, Path(folder) / "grid.nc", resources=Resources(threads),
                  show_progress=False)  # fmt: skip
        start = time.perf_counter()
        result = run_sweep(config, Path(folder) / "refined.nc", resources=Resources(threads),
                           show_progress=False)  # fmt: skip
        seconds = time.perf_counter() - start
    runs = int(result.dataset["regime"].size)
    uniform = math.prod((len(a.values) - 1) * 2**levels + 1 for a in config.axes)
    uniform *= config.members
    t = result.timings
    return {
        "config": os.path.relpath(config_path, ROOT),
        "levels": levels,
        "threads": threads,
        "runs": runs,
        "runs_per_level": [int(r) for r in result.dataset.attrs["refine_runs"]],
        "uniform_runs": uniform,
        "runs_over_uniform": runs / uniform,
        "seconds": seconds,
        "integration_seconds": t["integration"],
        "planning_seconds": t["planning"],
        "file_seconds": t["file"],
        "overhead_over_integration": (seconds - t["integration"]) / t["integration"],
    }


def bench_refinements(entries):
    """:func:`bench_refine` of each ``(config name, levels)``, printed as it finishes;
    returns ``{config name: figures}``."""
    found = {}
    for name, levels in entries:
        found[name] = rf = bench_refine(repo_config(name), levels)
        print(
            f"{rf['config']} refined {rf['levels']} levels: {rf['runs']} runs, "
            f"{100 * rf['runs_over_uniform']:.2g} % of the {rf['uniform_runs']} of a uniform "
            f"grid of the finest cells; {rf['seconds']:.1f} s on {rf['threads']} threads, of "
            f"which {100 * rf['overhead_over_integration']:.1f} % beyond the integration "
            f"(planning {rf['planning_seconds']:.2f} s, file {rf['file_seconds']:.2f} s)",
            flush=True,
        )
    return found


def _print_refine_targets(found):
    """Issue 37's targets beside the measured figures of each refinement."""
    print("\nrefinement targets:")
    for name, rf in found.items():
        rows = [
            (f"{name}: runs vs the uniform grid of 1/{2 ** rf['levels']} steps", "<= 1 %",
             f"{100 * rf['runs_over_uniform']:.3g} % ({rf['runs']} of {rf['uniform_runs']})"),
            (f"{name}: wall time, {rf['threads']} threads", "minutes",
             f"{rf['seconds'] / 60:.1f} min"),
            (f"{name}: time beyond the integration", "<= 5 %",
             f"{100 * rf['overhead_over_integration']:.2f} %"),
        ]  # fmt: skip
        for what, target, measured in rows:
            print(f"  {what:<48} target {target:<10} measured {measured}")


def bench_critical_kick(n_stiffness, rtol, threads=2):
    """The critical kick of ``configs/kick_slip_law.yaml`` on ``n_stiffness`` stiffnesses
    (K/Kc 1.01-1.7) bisected to ``rtol`` on ``threads`` threads (kernels compiled
    beforehand): runs, rounds and wall time, against the runs of a uniform scan of the
    same kick range at that resolution."""
    from sweep.engine.kicks import bisect_critical_kick

    config = load_config(repo_config("kick_slip_law"))
    k_axis = {"start": 0.0505, "stop": 0.085, "num": n_stiffness}
    config = with_changes(config, {"sweep": {"K_W": k_axis}})
    small = with_changes(config, {"sweep": {"K_W": [0.06]}})
    bisect_critical_kick(small, rtol=0.5, threads=threads, progress=False)  # compiles
    start = time.perf_counter()
    ds = bisect_critical_kick(config, rtol=rtol, threads=threads, progress=False)
    seconds = time.perf_counter() - start
    kicks = next(a.values for a in config.axes if a.name == "initial_v_over_V")
    uniform = n_stiffness * math.ceil(math.log(max(kicks) / min(kicks)) / math.log1p(rtol))
    runs = int(ds["kick_runs"].sum())
    return {
        "config": "configs/kick_slip_law.yaml",
        "stiffnesses": n_stiffness,
        "rtol": rtol,
        "threads": threads,
        "runs": runs,
        "rounds": int(ds.attrs["kick_rounds"]),
        "found": int((ds["critical_kick_status"] == 0).sum()),
        "seconds": seconds,
        "runs_per_second": runs / seconds,
        "uniform_scan_runs": uniform,
        "runs_over_uniform_scan": runs / uniform,
    }


def _print_critical_kick(ck):
    print(
        f"critical kick of {ck['stiffnesses']} stiffnesses to {100 * ck['rtol']:g} % "
        f"({ck['config']}): {ck['runs']} runs in {ck['rounds']} rounds, {ck['seconds']:.2f} s "
        f"on {ck['threads']} threads ({ck['runs_per_second']:.0f} runs/s); a uniform scan at "
        f"that resolution: {ck['uniform_scan_runs']} runs ({ck['runs_over_uniform_scan']:.3f}x)"
    )


#: The refinements of issue 37's targets (``--refine-only``): the shipped refined example
#: and the two-block map, each to 1/256 of its grid steps.
REFINE_TARGETS = (("unequal_qd", 8), ("twoblock", 8))

#: Problem sizes: the figures of the README (``full``), a quicker look (``quick``) and
#: the smallest that still runs every code path (``smoke``, for the test suite).
SIZES = {
    "full": {"scipy": (41, 2000), "single_purpose": (401, 2000), "scipy_hard": (101, 2000),
             "attractors": (201, 2000),
             "threads_large": (10_000, 2000), "throughput": (16, 500), "rk4": 2_000_000,
             "block_scaling": (8, 500), "implicit_scaling": (2, 100),
             "structured_crossing": (2, 100, 4.0),
             "configs": ("oneblock", "twoblock"), "dask": "twoblock", "compile": "twoblock",
             "refine": (("unequal_qd", 8),), "critical_kick": (64, 0.01),
             "basins": 10_000},
    "quick": {"scipy": (6, 300), "single_purpose": (21, 300), "scipy_hard": (5, 2000),
              "attractors": (21, 300),
              "threads_large": (200, 2000), "throughput": (2, 50), "rk4": 10_000,
              "block_scaling": (2, 50), "implicit_scaling": (1, 30),
              "structured_crossing": (1, 30, 0.5),
              "configs": ("quick", "quick"), "dask": "quick", "compile": "quick",
              "refine": (("unequal_qd", 2),), "critical_kick": (8, 0.01),
              "basins": 400},
    "smoke": {"scipy": (3, 100), "single_purpose": (3, 100), "scipy_hard": (2, 100),
              "attractors": (3, 100),
              "threads_large": (4, 100), "throughput": (1, 10), "rk4": 1_000,
              "block_scaling": (1, 10), "implicit_scaling": (1, 2),
              "structured_crossing": (1, 2, 0.0, (1, 3)),
              "configs": ("quick",), "dask": "quick", "compile": "quick", "empty_cache": False,
              "refine": (("quick", 2),), "critical_kick": (2, 0.1),
              "basins": 4},
}  # fmt: skip


def repo_config(name):
    """The path of a config in the repository's ``configs/`` folder."""
    return ROOT / "configs" / f"{name}.yaml"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python benchmarks/bench.py", description=__doc__)
    sizes = parser.add_mutually_exclusive_group()
    sizes.add_argument("--quick", action="store_const", const="quick", dest="size",
                       help="small sizes (a quicker look)")  # fmt: skip
    sizes.add_argument("--smoke", action="store_const", const="smoke", dest="size",
                       help="tiny sizes: runs every code path (tests/test_bench.py)")  # fmt: skip
    parser.add_argument("--out", default=str(ROOT / "results" / "bench.json"),
                        help="where to write the figures")  # fmt: skip
    parser.add_argument(
        "--refine-only",
        action="store_true",
        help="run only the refinements; update the refine entry of --out",
    )
    parser.add_argument(
        "--crossing-only",
        action="store_true",
        help="run only the structured-vs-dense RODAS4 crossing; update the "
        "structured_crossing entry of --out",
    )
    args = parser.parse_args(argv)
    size = SIZES[args.size or "full"]
    if args.crossing_only:
        out = Path(args.out)
        figures = json.loads(out.read_text()) if out.exists() else {}
        figures["structured_crossing"] = bench_structured_crossing(*size["structured_crossing"])
        _print_structured_crossing(figures["structured_crossing"])
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(figures, indent=2) + "\n")
        print(f"wrote {out}")
        return 0
    if args.refine_only:
        out = Path(args.out)
        figures = json.loads(out.read_text()) if out.exists() else {}
        entries = REFINE_TARGETS if args.size is None else size["refine"]
        figures["refine"] = bench_refinements(entries)
        _print_refine_targets(figures["refine"])
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(figures, indent=2) + "\n")
        print(f"wrote {out}")
        return 0
    figures = {"quick": args.size is not None, "machine_cores": os.cpu_count()}
    figures["scipy"] = bench_scipy(*size["scipy"])
    _print_scipy(figures["scipy"])
    figures["single_purpose"] = sp = bench_single_purpose(*size["single_purpose"])
    _print_single_purpose(sp)
    figures["scipy_hard"] = h = bench_scipy_hard(*size["scipy_hard"])
    print(
        f"K/Kc 0.8-1.2, {h['grid_points']} runs: engine with early exit "
        f"{h['speedup_per_core']:.0f}x faster per core than a SciPy LSODA loop"
    )
    figures["attractors"] = a = bench_attractors(*size["attractors"])
    s = a["settling"]
    print(
        f"classification beyond the simple cycle, runs that settle: {s['ns_per_step_default']:.0f}"
        f" ns per step vs {s['ns_per_step_lean']:.0f} without lambda1 or events "
        f"({s['default_over_lean']:.3f}x)"
    )
    for method in ("dopri5", "rosenbrock"):
        v = a[f"tangent/{method}"]
        print(
            f"a {method} step carrying the tangent: {v['ns_per_step_with_tangent']:.0f} ns vs "
            f"{v['ns_per_step']:.0f} ns ({v['tangent_over_plain']:.2f}x)"
        )
    figures["threads_large"] = tl = bench_threads_large(*size["threads_large"])
    print(
        f"{tl['grid_points']}-point one-block sweep: {tl['seconds_1_thread']:.2f} s on 1 "
        f"thread, {tl['seconds_2_thread']:.2f} s on 2: speed-up {tl['speedup_2_threads']:.2f}x"
    )
    figures["throughput"] = bench_throughput(*size["throughput"])
    _print_throughput(figures["throughput"])
    figures["block_scaling"] = bench_block_scaling(*size["block_scaling"])
    _print_block_scaling(figures["block_scaling"])
    figures["implicit_scaling"] = bench_implicit_scaling(*size["implicit_scaling"])
    _print_implicit_scaling(figures["implicit_scaling"])
    figures["structured_crossing"] = bench_structured_crossing(*size["structured_crossing"])
    _print_structured_crossing(figures["structured_crossing"])
    figures["rk4"] = r = bench_rk4_reference(size["rk4"])
    print(
        f"RK4 kernel {r['engine_ns_per_step']:.0f} ns/step vs plain loop "
        f"{r['plain_ns_per_step']:.0f} ns/step: ratio {r['engine_over_plain']:.2f}; plain "
        f"loop over {r['lanes']} systems at once {r['plain_lanes_ns_per_system_step']:.0f} ns "
        f"per system-step (SVML: {r['svml']})"
    )
    for name, config in zip(("oneblock", "twoblock"), size["configs"], strict=False):
        figures[name] = t = bench_sweep(repo_config(config))
        print(
            f"{t['config']} ({t['runs']} runs): {t['seconds_1_thread']:.2f} s on 1 thread "
            f"({t['runs_per_second_1_thread']:.0f} runs/s), {t['seconds_2_thread']:.2f} s on 2 "
            f"({t['runs_per_second_2_thread']:.0f} runs/s), speed-up {t['speedup_2_threads']:.2f}x"
        )
    figures["dask"] = d = bench_dask(repo_config(size["dask"]))
    print(
        f"LocalCluster of 2 workers: start {d['cluster_start']:.1f} s, sweep {d['cluster']:.2f} s "
        f"= {d['cluster_over_threads']:.1f}x the 2-thread time ({d['threads_n']:.2f} s)"
    )
    figures["compile"] = c = bench_compile(repo_config(size["compile"]),
                                           size.get("empty_cache", True))  # fmt: skip
    print(
        f"JIT compile {c['compile_seconds']:.1f} s (fresh process: {c['cold_seconds']:.1f} s "
        f"with an empty cache, {c['cache_warm_seconds']:.1f} s with a warm cache); a further "
        f"variant (another model), shared helpers cached: {c['further_compile_seconds']:.1f} s"
    )
    figures["critical_kick"] = ck = bench_critical_kick(*size["critical_kick"])
    _print_critical_kick(ck)
    figures["basins"] = b = bench_basins(size["basins"])
    print(
        f"{b['starts']} starts at K/Kc = {b['K_over_Kc']} ({b['config']}): "
        f"{b['ensemble_runs_per_second']:.0f} runs/s on {b['threads']} threads vs "
        f"{b['uniform_runs_per_second']:.0f} runs/s for a uniform sweep of the same box of starts "
        f"({b['uniform_runs']} runs); "
        f"matching {b['matching_seconds']:.3f} s ({100 * b['matching_over_integration']:.2g} % "
        f"of the integration); fractions {b['fractions']}"
    )
    figures["refine"] = bench_refinements(size["refine"])
    if "twoblock" in figures:
        _print_targets(figures)
    _print_refine_targets(figures["refine"])
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(figures, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


def _print_single_purpose(sp):
    peers = [f"cyrk_{m}" for m in CYRK_METHODS if f"cyrk_{m}" in sp]
    if not peers:
        print("CyRK not installed: no CyRK lines (pip install -e '.[bench]')")
    for label in ("plain", *peers, *(run[0] for run in ENGINE_RUNS)):
        v = sp[label]
        ratio = f", {v['vs_plain']:.2f}x the plain loop" if "vs_plain" in v else ""
        for m in CYRK_METHODS:
            if f"vs_cyrk_{m}" in v:
                ratio += f", {v[f'vs_cyrk_{m}']:.2f}x CyRK {m}"
        print(
            f"K/Kc 0.8-1.2, {sp['grid_points']} runs to {sp['t_end_D0_over_V']:g} D0/V, "
            f"{label}: {v['systems_per_second']:.0f} systems/s, {v['steps_per_run']:.0f} "
            f"steps per run, {v['ns_per_step']:.0f} ns per step{ratio}"
        )


def _print_targets(f):
    """The issue tracker's speed targets beside the measured figures."""
    lsoda = f["scipy"]["LSODA"]
    sp = f["single_purpose"]
    rows = [
        (
            "one block vs SciPy LSODA per core",
            ">= 300x at >= 99 % agreement",
            f"{lsoda['speedup_per_core']:.0f}x at {lsoda['agreement_percent']:.1f} %",
        ),
        (
            "engine (dopri5), early exit off, vs single-purpose DOPRI5 loop",
            ">= 1.0x",
            f"{sp['engine_dopri5_early_exit_off']['vs_plain']:.2f}x",
        ),
        *(
            (
                f"engine ({method}), early exit {state}, vs CyRK DOP853",
                target,
                f"{sp[f'engine{tag}_early_exit_{state}']['vs_cyrk_DOP853']:.2f}x",
            )
            for method, tag in (("dop853", ""), ("dopri5", "_dopri5"))
            for state, target in (("on", ">= 3x"), ("off", ">= 1.2x"))
            if "vs_cyrk_DOP853" in sp["engine_early_exit_on"]
        ),
        (
            "engine with early exit vs LSODA, K/Kc 0.8-1.2",
            ">= 1000x",
            f"{f['scipy_hard']['speedup_per_core']:.0f}x",
        ),
        (
            "2-thread speed-up, 1e4-point sweep",
            ">= 1.9x",
            f"{f['threads_large']['speedup_2_threads']:.2f}x",
        ),
        ("cold JIT compile (default config)", "< 10 s", f"{f['compile']['compile_seconds']:.1f} s"),
        (
            "JIT compile of a further variant (another model), shared helpers cached",
            "< 10 s",
            f"{f['compile']['further_compile_seconds']:.1f} s",
        ),
        (
            "settling runs: default classification vs none beyond the simple cycle",
            "<= 1.03x per step",
            f"{f['attractors']['settling']['default_over_lean']:.3f}x",
        ),
        (
            "a step carrying the tangent (dopri5 / rosenbrock)",
            "<= 2.5x a plain step",
            f"{f['attractors']['tangent/dopri5']['tangent_over_plain']:.2f}x / "
            f"{f['attractors']['tangent/rosenbrock']['tangent_over_plain']:.2f}x",
        ),
        (
            "two-block default config, 2 threads, JIT warm",
            "< 10 s",
            f"{f['twoblock']['seconds_2_thread']:.2f} s",
        ),
        (
            "two-block default config incl. JIT compile",
            "< 30 s",
            f"{f['twoblock']['seconds_2_thread'] + f['compile']['compile_seconds']:.1f} s",
        ),
        (
            "2-thread speed-up (two-block config)",
            ">= 1.8x",
            f"{f['twoblock']['speedup_2_threads']:.2f}x",
        ),
        (
            "RK4 kernel time per step vs plain loop",
            "<= 1.2x",
            f"{f['rk4']['engine_over_plain']:.2f}x",
        ),
    ]
    explicit = [v for k, v in f["throughput"].items() if "dopri5" in k and "quasi-static" not in k]
    worst = min(v["relative_to_quasi_static"] for v in explicit)
    rows.append(
        (
            "regularised kernels (dopri5) steps/s vs quasi-static",
            ">= 0.5x",
            f"{worst:.2f}x (lowest)",
        )
    )
    print("\ntargets:")
    for what, target, measured in rows:
        print(f"  {what:<48} target {target:<30} measured {measured}")


def _print_scipy(s):
    print(
        f"one block, {s['grid_points']} runs to {s['t_end_D0_over_V']:g} D0/V: "
        f"{s['mean_steps_per_run']:.0f} steps per run with early exit, "
        f"{s['mean_steps_per_run_without_early_exit']:.0f} without"
    )
    for method in ("LSODA", "DOP853"):
        m = s[method]
        print(
            f"one block, {s['grid_points']} runs to {s['t_end_D0_over_V']:g} D0/V: engine "
            f"{m['speedup_per_core']:.0f}x faster per core than a SciPy {method} loop, "
            f"{m['agreement_percent']:.1f} % same regime outside +-1 % of Kc"
        )


def _print_block_scaling(b):
    for key, value in b.items():
        coupling, blocks = key.rsplit("/", 1)
        print(
            f"{coupling:<21} {blocks:>2} blocks: {value['block_steps_per_second'] / 1e6:5.2f} M "
            f"block-steps/s per core, {value['ns_per_step']:.0f} ns per step "
            f"({value['relative_to_smallest_chain']:.2f}x the smallest chain per block-step)"
        )


def _print_implicit_scaling(b):
    for key, value in b.items():
        case, blocks = key.rsplit("/", 1)
        versus = value.get("dense_over_structured")
        print(
            f"inertial {case:<29} {blocks:>3} blocks: {value['us_per_step']:8.1f} us per step, "
            f"{value['ns_per_block_step']:6.0f} ns per block-step "
            f"({value['relative_to_smallest']:.2f}x the smallest)"
            + (f", {versus:.1f}x faster than dense" if versus else "")
        )


def _print_structured_crossing(c):
    for key, value in c.items():
        if "/" not in key:
            continue
        case, blocks = key.rsplit("/", 1)
        print(
            f"inertial {case:<13} {blocks:>3} blocks: dense {value['dense_us_per_step']:7.2f} us "
            f"per step, structured {value['structured_us_per_step']:7.2f} us: dense / "
            f"structured {value['dense_over_structured']:.2f} (quartiles "
            f"{value['dense_over_structured_quartiles'][0]:.2f}-"
            f"{value['dense_over_structured_quartiles'][1]:.2f} of {value['pairs']} pairs; "
            f"shortest times {value['dense_over_structured_shortest']:.2f})"
        )
    for case, blocks in c["crossing"].items():
        print(f"rosenbrock-structured faster per step from: {case}: {blocks} blocks")


def _print_throughput(t):
    for key, value in t.items():
        label, blocks = key.rsplit("/", 1)
        print(
            f"{label:<21} {blocks} block(s): {value['steps_per_second'] / 1e6:5.2f} M steps/s "
            f"per core ({value['relative_to_quasi_static']:.2f}x quasi-static dopri5)"
        )


if __name__ == "__main__":
    sys.exit(main())
