"""A fixed table of runs near the critical stiffness, each with the labels theory or
SciPy allows: a guard that fails when a change to the classifier moves a label near Kc
(as the complex-attractor verdicts once called a slowly growing spiral below Kc
``stick_slip`` / ``quasi_periodic``, issue 36 §2).

Every run uses the settings users get: the default method, tolerances, velocity cap,
``max_t_end`` (ten times ``t_end``) and λ1 where a run is unsettled at ``t_end``. The
expected labels come from:

- the physics brief, section 4: below Kc the quasi-static model has no bounded
  attractor (its oscillations grow until v diverges); above Kc steady sliding is
  linearly stable and small oscillations decay at (κ − κc)/(2A) per D0/V; radiation
  damping unfolds the degenerate Hopf bifurcation into a supercritical one, with a
  limit cycle below its Kc = (W(B − A) − ηV)/D0;
- SciPy (``conftest.scipy_runaway_time``: DOP853, rtol 1e-10) for the time one block
  reaches the cap (the brief's, from v = 1.05 V: K/Kc 0.9 τ = 61.28, 0.99 633.9);
- the brief's SciPy runs (LSODA, rtol 1e-10) of two weakly coupled blocks (κ2 = 0.001,
  K/Kc = 0.99): an in-phase start is one block and runs away, an anti-phase start
  settles on a bounded out-of-phase cycle (also ``test_classification.py``).
"""

import math

import pytest
from conftest import KC_W, make_config, run_grid, scipy_runaway_time

from sweep.kernels import layout

NAMES = {layout.STEADY: "steady", layout.STICK_SLIP: "stick_slip",
         layout.RUNAWAY: "runaway", layout.UNDECIDED: "undecided"}  # fmt: skip
FROM_V = {"v_over_V": 1.05, "phi_over_phi_ss": 1.0}
FROM_PHI = {"v_over_V": 1.0, "phi_over_phi_ss": 1.01}
#: radiation damping η̂ = ηV/W = 0.01 (V = 0.1 µm/s): Kc/W = (B − A) − η̂ per µm (D0 = 1 µm)
ETA_W = 0.1
KC_QD = KC_W - ETA_W * 0.1
PAIR = {"blocks": 2, "parameters": {"k2_W": 0.001}}
IN_PHASE = {"v_over_V": [1.01, 1.01], "phi_over_phi_ss": [1.01, 1.01]}
ANTI_PHASE = {"v_over_V": [1.01, 0.99], "phi_over_phi_ss": [1.01, 0.99]}

UNBOUNDED = {"runaway", "undecided"}  # below Kc: grows, runs away once it reaches the cap
STABLE = {"steady", "undecided"}  # above Kc: decays, steady once it is known to

#: (name, sections, K/Kc values, t_end in D0/V, allowed labels, why, whether SciPy's
#:  time to the cap is checked)
CASES = [
    ("below, runs away", {"initial": FROM_V}, [0.9], 30.0, {"runaway"},
     "SciPy reaches the cap within max_t_end", True),
    ("below, runs away", {"initial": FROM_V}, [0.99], 300.0, {"runaway"},
     "SciPy reaches the cap within max_t_end", True),
    ("below, runs away", {"initial": FROM_PHI}, [0.9], 30.0, {"runaway"},
     "SciPy reaches the cap within max_t_end", True),
    ("below, runs away", {"initial": FROM_PHI}, [0.99], 300.0, {"runaway"},
     "SciPy reaches the cap within max_t_end", True),
    *[("just below, growing", {"initial": start}, [0.999, 0.9999, 0.99999], t_end, UNBOUNDED,
       "no bounded attractor below Kc: growing at (κc − κ)/(2A)", False)
      for start in (FROM_V, FROM_PHI) for t_end in (300.0, 3000.0)],
    *[("just above, decaying", {"initial": start}, [1.00001, 1.0001, 1.001], t_end, STABLE,
       "linearly stable: decaying at (κ − κc)/(2A)", False)
      for start in (FROM_V, FROM_PHI) for t_end in (300.0, 3000.0)],
    ("above, decayed", {"initial": FROM_PHI}, [1.01, 1.1], 3000.0, {"steady"},
     "decays by e every 2A/(κ − κc) ≤ 120 D0/V, 25 times within t_end", False),
    ("radiation damping, below", {"model": "quasi-dynamic", "parameters": {"eta_W": ETA_W},
     "initial": FROM_PHI, "kc": KC_QD}, [0.9, 0.99], 3000.0, {"stick_slip"},
     "supercritical Hopf: an attracting limit cycle (brief: v_max/V ≈ 1.56 at 0.99)", False),
    ("radiation damping, above", {"model": "quasi-dynamic", "parameters": {"eta_W": ETA_W},
     "initial": FROM_PHI, "kc": KC_QD}, [1.01], 3000.0, {"steady"},
     "linearly stable, decays by e every 2(A + η̂)/(κ − κc) < 200 D0/V", False),
    ("two blocks, in phase", {**PAIR, "initial": IN_PHASE}, [0.99], 3000.0, {"runaway"},
     "the synchronous manifold is one block: it runs away", False),
    ("two blocks, anti-phase", {**PAIR, "initial": ANTI_PHASE}, [0.99], 3000.0,
     {"stick_slip"}, "SciPy: a bounded out-of-phase cycle, converged to 1e-4 by τ = 4470", False),
]  # fmt: skip


def case_id(case):
    name, sections, ratios, t_end = case[:4]
    start = sections.get("initial")
    which = "v" if start is FROM_V else "phi" if start is FROM_PHI else ""
    return f"{name} {which} K/Kc={','.join(f'{r:g}' for r in ratios)} t_end={t_end:g}"


@pytest.mark.parametrize("case", CASES, ids=[case_id(c) for c in CASES])
def test_labels_near_kc(case):
    """Every run of the case gets one of the allowed labels; never stick_slip with a
    growing envelope, never steady below Kc; where SciPy reaches the cap within
    max_t_end, runaway at SciPy's time."""
    name, sections, ratios, t_end, allowed, why, check_cap_time = case
    sections = dict(sections)
    kc = sections.pop("kc", KC_W)
    config = make_config(
        {"integrator": {"method": None}},
        sweep={"K_W": [r * kc for r in ratios]},
        integrator={"t_end": t_end},
        **sections,
    )
    results, _ = run_grid(config)
    for ratio, row in zip(ratios, results, strict=True):
        label = NAMES[int(row[layout.R_REGIME])]
        facts = {k: float(row[getattr(layout, f"R_{k.upper()}")])
                 for k in ("tau_final", "growth", "tau_runaway", "lnv_max")}  # fmt: skip
        assert label in allowed, (
            f"K/Kc = {ratio}: {label}, allowed {sorted(allowed)} ({why}); {facts}"
        )
        if label == "stick_slip":
            assert int(row[layout.R_ATTRACTOR]) == layout.PERIODIC, facts
        if check_cap_time:  # one block: the start of the case
            start = sections["initial"]
            lnv0, psi0 = math.log(start["v_over_V"]), math.log(start["phi_over_phi_ss"])
            tau = scipy_runaway_time(ratio, lnv0, psi0, t_max=10 * t_end)
            # 1e-4: the cap ends tens of cycles whose phase error accumulates
            assert row[layout.R_TAU_RUNAWAY] == pytest.approx(tau, rel=1e-4), facts
