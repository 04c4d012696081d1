"""The engine's critical kick against SciPy (``tests/kick_reference.py``: LSODA, rtol
1e-10, its own right-hand side from the physics brief), one quasi-static block, the
issue's checks: the slip law's sharp threshold within 2 % at three stiffnesses, the aging
law's cap-limited one within 2 % at two caps (moving with the cap as SciPy's does), and
no threshold up to 10⁵ far above Kc."""

import kick_reference as ref
import numpy as np
import pytest
from conftest import PAPER_A, PAPER_B, make_config

from sweep.codes import code
from sweep.engine.kicks import bisect_critical_kick
from sweep.results.kicks import KICK_STATUSES, PROBE, THRESHOLD_KINDS

#: Relative width of the engine's and SciPy's brackets (both well inside the 2 % checked).
RTOL = 1e-3


def engine_kicks(law, ratios, cap=1e6):
    """The engine's bisected critical kicks at K/Kc ``ratios`` (Kc/W = 0.05 µm⁻¹)."""
    config = make_config(
        {
            "state_law": law,
            "sweep": {
                "K_W": [r * (PAPER_B - PAPER_A) for r in ratios],
                "initial_v_over_V": {"start": 1.0, "stop": 1e5, "num": 11, "scale": "log"},
            },
            "initial": {"phi_over_phi_ss": 1.0},
            "classification": {"v_cap_over_V": cap},
        }
    )
    return bisect_critical_kick(config, rtol=RTOL, progress=False)


def scipy_kick(law, ratio, cap):
    """SciPy's bracket ``(low, high)`` of the critical kick and its probe's peak."""
    low, high, _, _ = ref.critical_kick(law, PAPER_A, PAPER_B, ratio, cap=cap, rtol=RTOL)
    _, probe_peak = ref.kick_outcome(law, PAPER_A, PAPER_B, ratio, PROBE * high, cap=cap)
    return low, high, probe_peak


def check_against_scipy(law, ratios, cap, kind):
    ds = engine_kicks(law, ratios, cap)
    assert (ds["critical_kick_status"] == code(KICK_STATUSES, "found")).all()
    assert (ds["kick_threshold"] == code(THRESHOLD_KINDS, kind)).all()
    found = []
    for i, ratio in enumerate(ratios):
        low, high, probe_peak = scipy_kick(law, ratio, cap)
        engine = np.sqrt(float(ds["critical_kick_low"][i]) * float(ds["critical_kick"][i]))
        assert engine == pytest.approx(np.sqrt(low * high), rel=0.02), (law, ratio, cap)
        # SciPy's probe tells the same kind: sharp far below the cap, cap-limited near it
        assert (np.log(cap) - probe_peak > np.log(10.0)) == (kind == "sharp")
        found.append(np.sqrt(low * high))
    return ds, np.array(found)


@pytest.mark.slow  # the only fast test of the quasi-static slip law's kernels (make test-all)
def test_slip_law_threshold_is_sharp_and_where_scipy_finds_it():
    check_against_scipy("slip", [1.2], 1e6, "sharp")


@pytest.mark.slow
def test_slip_law_threshold_at_three_more_stiffnesses():
    check_against_scipy("slip", [1.02, 1.05, 1.5], 1e6, "sharp")


@pytest.mark.slow
def test_aging_law_threshold_is_set_by_the_cap():
    check_against_scipy("aging", [1.05], 1e6, "cap_limited")


@pytest.mark.slow
def test_aging_law_threshold_moves_with_the_cap_as_scipy_s_does():
    ratios = [1.01, 1.1]
    low_cap, scipy_low = check_against_scipy("aging", ratios, 1e6, "cap_limited")
    high_cap, scipy_high = check_against_scipy("aging", ratios, 1e9, "cap_limited")
    moved = high_cap["critical_kick"].values / low_cap["critical_kick"].values
    np.testing.assert_allclose(moved, scipy_high / scipy_low, rtol=0.02)
    assert np.all(moved > 1.4)  # a threshold set by the cap moves with it


@pytest.mark.slow
@pytest.mark.parametrize("cap", [1e6, 1e9])
def test_aging_law_far_above_kc_has_no_threshold(cap):
    """K/Kc = 1.7: no kick up to 10⁵ V reaches the cap, in the engine as in SciPy."""
    ds = engine_kicks("aging", [1.7], cap)
    assert ds["critical_kick_status"].item() == code(KICK_STATUSES, "none_up_to_max")
    assert np.isnan(ds["critical_kick"].item())
    leaves, _ = ref.kick_outcome("aging", PAPER_A, PAPER_B, 1.7, 1e5, cap=cap)
    assert not leaves
