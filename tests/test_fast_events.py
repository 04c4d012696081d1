"""configs/fast_events.yaml: a laboratory slider's fast stick-slip, checked against SciPy.

Two points of the shipped config (K/Kc = 0.5 and 0.7) run through the engine and through
SciPy Radau (rtol 1e-10) on the inertial equations written here from the physics brief,
not from the engine: with τ = tV/D0, ℓ = ln(v/V), ψ = ln(VΦ/D0) and the spring's excess
stress s = K(Vt − x)/W − μ_ss(V) (μ_ss(V) = μ0 + (A − B) ln(VΦ0/D0)),

    M̂ e^ℓ ℓ' = z,  z = s − A ℓ − B ψ   (m ẍ = K(Vt − x) − W μ, M̂ = mV²/(W D0))
    ψ' = e^(−ψ) − e^ℓ                    (aging law)
    z' = κ (1 − e^ℓ) − A ℓ' − B ψ'        (s' = κ (1 − e^ℓ), κ = K D0/W)

with the inertial force z as a variable (s − Aℓ − Bψ would cancel to rounding in the stick
phases, where e^(−ℓ)/M̂ multiplies it by up to 1e13). Started as the config
says: v = V, Φ = 1.01 Φ_ss, zero inertial force.
The engine's peak ln(v/V) and period of the limit cycle must match the reference's last
cycle, and the peak must be at least 10³ V (fast events, not slow slip).
"""

from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from sweep.config import parse_config
from sweep.engine.runner import compute

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "fast_events.yaml"
#: K/Kc of the two points checked (the config's first two, to 1e-6) and the reference's run
#: length in D0/V: seven cycles or more (periods 66 and 41 D0/V), the last two intervals
#: then agree to 1e-4 (checked), the engine's period being that of the settled cycle.
POINTS = {0.5: 500.0, 0.7: 420.0}
RATIOS = tuple(POINTS)
SEGMENT = 1.0  # D0/V (see reference)
LNV_TOL = 1e-3  # absolute, on the peak ln(v/V): 0.1 % in v_max
PERIOD_RTOL = 1e-3


def _raw():
    """The shipped config as a mapping."""
    return yaml.safe_load(CONFIG.read_text())


def _dimensionless(raw):
    """(A, B, M̂, Kc/W in µm⁻¹) of the config, from its parameters (µm, s)."""
    p = raw["parameters"]
    mass = p["m_W"] * p["V"] ** 2 / p["D0"]
    kc_w = (p["B"] - p["A"]) / p["D0"] * (1.0 + mass / p["A"])  # Rice & Ruina (1983)
    return p["A"], p["B"], mass, kc_w


def _rhs(a, b, mass, kappa):
    """The right-hand side in (ℓ, ψ, z) and its Jacobian, derived by hand (module docstring)."""

    def rhs(t, y):
        lnv, psi, z = y
        dlnv, dpsi = z * np.exp(-lnv) / mass, np.exp(-psi) - np.exp(lnv)
        return [dlnv, dpsi, kappa * (1.0 - np.exp(lnv)) - a * dlnv - b * dpsi]

    def jac(t, y):
        lnv, psi, z = y
        em = np.exp(-lnv) / mass
        return [[-z * em, 0.0, em],
                [-np.exp(lnv), -np.exp(-psi), 0.0],
                [(b - kappa) * np.exp(lnv) + a * z * em, b * np.exp(-psi), -a * em]]  # fmt: skip

    return rhs, jac


def reference(ratio):
    """(peak ln(v/V) of the last cycle, last interval between peaks in D0/V) at K/Kc.

    Integrated in segments of one D0/V, each from its own t = 0 (the equations do not
    depend on t): as the block stops after an event Radau's steps can fall below the
    spacing of floating-point times far from t = 0 (seen at t ≈ 50 D0/V, M̂ = 1e-8 with
    A = 0.03, B = 0.08)."""
    raw = _raw()
    a, b, mass, kc_w = _dimensionless(raw)
    kappa = ratio * kc_w * raw["parameters"]["D0"]
    rhs, jac = _rhs(a, b, mass, kappa)
    y = [0.0, np.log(raw["initial"]["phi_over_phi_ss"]), 0.0]
    segments, times, lnv = [], [], []
    for offset in np.arange(0.0, POINTS[ratio], SEGMENT):
        sol = solve_ivp(rhs, (0.0, SEGMENT), y, method="Radau", jac=jac, rtol=1e-10,
                        atol=1e-12, dense_output=True)  # fmt: skip
        assert sol.success, f"{sol.message} at t = {offset + sol.t[-1]}"
        segments.append((offset, sol))
        times.append(offset + sol.t[1:])
        lnv.append(sol.y[0, 1:])
        y = sol.y[:, -1]
    times, lnv = np.concatenate(times), np.concatenate(lnv)
    peaks = np.flatnonzero((lnv[1:-1] > lnv[:-2]) & (lnv[1:-1] >= lnv[2:]) & (lnv[1:-1] > 1)) + 1
    assert len(peaks) >= 4, "fewer than four events: lengthen the run (POINTS)"
    # each peak refined on the dense output of its segment, between its neighbour steps
    peak_times, heights = [], []
    for k in peaks[-3:]:
        offset, sol = segments[int(times[k] // SEGMENT)]
        lo, hi = max(times[k - 1], offset), min(times[k + 1], offset + SEGMENT)
        grid = np.linspace(lo, hi, 2001)
        values = sol.sol(grid - offset)[0]
        peak_times.append(grid[values.argmax()])
        heights.append(values.max())
    intervals = np.diff(peak_times)
    assert abs(intervals[1] - intervals[0]) < 1e-4 * intervals[1], "cycle not settled"
    return heights[-1], intervals[1]


@pytest.fixture(scope="module")
def engine():
    """The engine's runs at the two points, and the time unit D0/V in s."""
    raw = _raw()
    kc_w = _dimensionless(raw)[3]
    raw["sweep"] = {"K_W": [r * kc_w for r in RATIOS]}
    ds = compute(parse_config(raw, str(CONFIG)), show_progress=False)
    t_unit = raw["parameters"]["D0"] / raw["parameters"]["V"]  # s
    return ds, t_unit


@pytest.mark.slow
@pytest.mark.parametrize("index, ratio", list(enumerate(RATIOS)))
def test_fast_events_match_scipy(engine, index, ratio):
    """Peak v/V and period of the engine's cycle equal SciPy Radau's (rtol 1e-10), and
    the events are fast: v_max/V ≥ 10³."""
    ds, t_unit = engine
    run = ds.isel(K_W=index)
    np.testing.assert_allclose(float(run.K_over_Kc), ratio, rtol=1e-6)
    assert str(run.regime.attrs.get("flag_meanings", "")).split()[int(run.regime)] == "stick_slip"
    lnv_peak, interval = reference(ratio)
    assert abs(float(run.lnv_max) - lnv_peak) < LNV_TOL
    np.testing.assert_allclose(float(run.period) / t_unit, interval, rtol=PERIOD_RTOL)
    assert np.exp(lnv_peak) >= 1e3
