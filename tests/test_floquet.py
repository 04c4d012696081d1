"""Floquet multipliers of periodic runs (``kernels/monodromy.py``, ``engine/floquet.py``)
against independent SciPy computations (``tests/floquet_reference.py``): Liouville's
formula for one radiation-damped block, central differences of SciPy's own Poincaré
return map for a cycle of two events and a three-block ring, and the classifier's
cycle-to-cycle convergence and events per cycle as consistency checks."""

import math

import numpy as np
import pytest
import yaml
from floquet_reference import (
    DampedBlock,
    liouville_multiplier,
    on_section,
    poincare_multipliers,
    settle,
)

from sweep.codes import FLOQUET_STATUSES
from sweep.config import parse_config
from sweep.engine import runner

A, B = 0.03, 0.08
#: SciPy's runs of the radiation-damped block (not stiff): onto the cycle, and around it
#: (rtol 1e-12: the same μ as Radau at rtol 1e-11 to 2e-12, 50× faster).
DOP853 = {"method": "DOP853", "rtol": 1e-10, "atol": 1e-12}
DOP853_TIGHT = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-14}


def run(raw):
    return runner.compute(parse_config(yaml.safe_dump(raw), "<test>"), show_progress=False)


def damped_block(law, k_values, **classification):
    """One quasi-dynamic block, η̂ = ηV/W = 0.01 (Kc/W = 0.04 µm⁻¹), D0 = 1 µm, V = 0.1
    µm/s (time unit 10 s), over K/W = ``k_values``; DOP853 at rtol 1e-10."""
    return {
        "name": "damped", "blocks": 1, "model": "quasi-dynamic", "state_law": law,
        "parameters": {"A": A, "B": B, "mu0": 0.4, "V": 0.1, "Phi0": 1.0, "D0": 1.0,
                       "eta_W": 0.1},
        "sweep": {"K_W": k_values}, "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.01},
        "integrator": {"method": "dop853", "rtol": 1e-10, "atol": 1e-12, "t_end": 3000.0},
        "classification": classification, "output": "damped.nc",
    }  # fmt: skip


def test_reference_trace_is_the_divergence_of_its_rhs():
    """The reference's hand-written tr J against central differences of its own
    right-hand side (so that Liouville's check rests on the equations alone)."""
    for law in ("aging", "slip"):
        block = DampedBlock(A, B, 0.035, 0.01, law)
        for y in ([0.3, -0.2], [-4.0, 3.5], [2.0, -2.5]):
            y = np.array(y)
            h = 1e-6
            div = sum(
                (block.rhs(0, y + h * e)[j] - block.rhs(0, y - h * e)[j]) / (2 * h)
                for j, e in enumerate(np.eye(2))
            )
            assert block.trace(y) == pytest.approx(div, rel=1e-7, abs=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("law", ["aging", "slip"])
def test_damped_block_multiplier_is_liouvilles(law):
    """One radiation-damped block (a state of two values): the non-trivial multiplier is
    exp(∮ tr J dt) along SciPy's own cycle (DOP853, rtol 1e-12), within 1e-3, at K/Kc
    0.75, 0.9 and 0.97; the trivial multiplier within 1e-4 of 1, the matrix's period within
    1e-5 of SciPy's."""
    k_values = [0.030, 0.036, 0.0388]
    ds = run(damped_block(law, k_values))
    for i, k in enumerate(k_values):
        point = ds.isel(K_W=i)
        assert FLOQUET_STATUSES[int(point["floquet_status"])] == "ok"
        block = DampedBlock(A, B, k, 0.01, law)
        y = settle(block.rhs, np.array([0.0, math.log(1.01)]), 1500.0, DOP853)
        y = on_section(block.rhs, y, 0.0, 1000.0, DOP853_TIGHT)
        mu, period = liouville_multiplier(block, y, 0.0, 1000.0, DOP853_TIGHT)
        assert float(point["floquet_modulus"]) == pytest.approx(mu, rel=1e-3, abs=1e-6)
        assert float(point["floquet_argument"]) == 0.0  # a real, positive multiplier
        assert float(point["floquet_trivial_error"]) < 1e-4
        time_unit = 10.0  # D0/V in s
        assert float(point["floquet_period"]) / time_unit == pytest.approx(period, rel=1e-5)
        rate = -math.log(mu) / (period * time_unit)
        assert float(point["cycle_decay_rate"]) == pytest.approx(rate, rel=2e-3)


@pytest.mark.slow
def test_decay_rate_is_the_cycle_to_cycle_convergence_of_the_run():
    """Consistency, not a reference: the engine's own run (a trace, K/Kc 0.9 and 0.97,
    aging law) approaches its cycle with successive maxima of ln v whose differences shrink
    by |μ| per cycle; the fitted ratio (from the largest difference down to 30× the trace's
    sampling noise) is floquet_modulus within 10 %."""
    from sweep.commands.trace import compute_trace, pin_config

    for k in (0.036, 0.0388):
        config = parse_config(yaml.safe_dump(damped_block("aging", [k])), "<test>")
        trace = compute_trace(pin_config(config, {"K_W": k}))
        lnv = trace["lnv"].values.ravel()
        peaks = np.flatnonzero((lnv[1:-1] > lnv[:-2]) & (lnv[1:-1] >= lnv[2:])) + 1
        d = np.abs(np.diff(lnv[peaks]))
        noise = np.median(d[d.size // 2 :])
        start = int(np.argmax(d))
        stop = start + int(np.argmax(d[start:] < 30 * noise))
        assert stop - start >= 4, "too few cycles of convergence to fit"
        slope = np.polyfit(np.arange(start, stop), np.log(d[start:stop]), 1)[0]
        assert math.exp(slope) == pytest.approx(trace.attrs["floquet_modulus"], rel=0.1)


@pytest.mark.slow
def test_multiplier_reaches_minus_one_where_the_cycle_doubles():
    """The inertial pair of configs/route_to_chaos.yaml (k2/W = 0.005 µm⁻¹): as K/W falls
    toward 0.00413 µm⁻¹ the simple cycle's largest multiplier is real and negative (argument
    π) with |μ| rising toward 1, and |μ| extrapolated linearly to 1 falls within one cell
    (1e-5 µm⁻¹) of where the runs' events per cycle double; on the doubled side the new
    cycle's multiplier starts near +1 (the square of −1)."""
    from test_attractors import inertial_pair
    from test_attractors import run as run_pair

    k_values = [0.00416, 0.00414, 0.00413, 0.00412]
    ds = run_pair(inertial_pair({"K_W": k_values}))
    events = ds["cycle_events"].values
    modulus, argument = ds["floquet_modulus"].values, ds["floquet_argument"].values
    assert list(events) == [1, 1, 1, 2]
    assert np.all(np.abs(argument[:3]) > 3.0)  # the approach toward −1
    assert np.all(np.diff(modulus[:3]) > 0) and modulus[2] < 1.0
    slope = (modulus[2] - modulus[1]) / (k_values[2] - k_values[1])
    k_unit = k_values[2] + (1.0 - modulus[2]) / slope
    assert k_values[3] - 1e-5 <= k_unit <= k_values[2] + 1e-5
    assert abs(argument[3]) < 0.1 and modulus[3] > 0.9  # the doubled cycle, born at +1
