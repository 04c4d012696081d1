"""Small runs whose every number must stay bit-identical across refactoring.

``tests/test_bit_identity.py`` runs these cases twice on the same machine: as this file
stands in the reference commit (``python tests/bit_identity_cases.py [NAME ...]`` writes
the named cases, by default all, to ``tests/data/bit_identity.npz`` beside that copy) and
as it is now, and compares every number. Keep that command line: the test runs the
reference commit's copy through it.
"""

import sys
from pathlib import Path

import numpy as np

REFERENCE = Path(__file__).parent / "data" / "bit_identity.npz"

_ONE_BLOCK = {
    "name": "bitident",
    "blocks": 1,
    "model": "quasi-static",
    "state_law": "aging",
    "parameters": {"A": 0.03, "B": 0.08, "mu0": 0.4, "V": 0.1, "Phi0": 1.0, "D0": 1.0},
    "sweep": {"K_W": {"start": 0.04, "stop": 0.06, "num": 5}},
    "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.01},
    "integrator": {"method": "dopri5", "rtol": 1.0e-8, "atol": 1.0e-10, "t_end": 600.0},
}


def _case(**changes):
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in _ONE_BLOCK.items()}
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key].update(value)
        else:
            out[key] = value
    return out


#: name → config mapping: every model, state law, method and the classifier's branches.
CASES = {
    "quasi_static": _case(),
    "no_early_exit": _case(classification={"early_exit": False}),
    "slip_law": _case(state_law="slip", sweep={"K_W": [0.045, 0.06]}),
    "rk4": _case(integrator={"method": "rk4", "dt": 0.02, "t_end": 300.0}),
    "dop853": _case(integrator={"method": "dop853", "max_step": float("inf")}),
    "dop853_no_early_exit": _case(
        integrator={"method": "dop853", "max_step": float("inf")},
        classification={"early_exit": False},
    ),
    "quasi_dynamic": _case(
        model="quasi-dynamic",
        parameters={**_ONE_BLOCK["parameters"], "eta_W": 0.01},
        sweep={"K_W": [0.03, 0.045, 0.055]},
    ),
    "inertial": _case(
        model="inertial",
        parameters={**_ONE_BLOCK["parameters"], "m_W": 1.0},
        sweep={"K_W": [0.03, 0.049, 0.06]},
        integrator={"method": "rosenbrock", "rtol": 1.0e-6, "atol": 1.0e-9, "t_end": 300.0},
    ),
    "two_blocks": _case(
        blocks=2,
        parameters={**_ONE_BLOCK["parameters"], "k2_W": 0.001},
        sweep={"K_W": [0.0495, 0.06]},
        initial={"v_over_V": [1.0, 1.0], "phi_over_phi_ss": [1.05, 0.95]},
        integrator={"t_end": 1500.0},
    ),
    "three_blocks": _case(
        blocks=3,
        parameters={**_ONE_BLOCK["parameters"], "k2_W": 0.02},
        sweep={"K_W": [0.045, 0.055]},
        initial={"v_over_V": [1.0, 1.0, 1.0], "phi_over_phi_ss": [1.01, 1.0, 0.99]},
    ),
}

#: A trace: the recorded state of one run (interpolated dense output), computed as the
#: case "trace".
TRACE_CASE = "two_blocks"
#: Every case name: the configs, then the trace.
NAMES = (*CASES, "trace")


def compute(names=NAMES):
    """name → {variable: array} for the cases ``names`` ("trace": the trace of
    :data:`TRACE_CASE`)."""
    import sweep
    from sweep.commands.trace import compute_trace

    out = {}
    for name in names:
        if name == "trace":
            trace_cfg = sweep.with_changes(CASES[TRACE_CASE], {"sweep": {"K_W": [0.0495]}})
            tr = compute_trace(trace_cfg, points=300)
            out["trace"] = {v: np.asarray(tr[v].values) for v in sorted(tr.data_vars)}
            out["trace"]["time"] = np.asarray(tr["time"].values)
        else:
            ds = sweep.run(CASES[name], threads=1, progress=False)
            out[name] = {v: np.asarray(ds[v].values) for v in sorted(ds.data_vars)}
    return out


def flatten(computed):
    """``{case: {var: a}}`` → ``{"case/var": a}`` (the npz layout)."""
    return {f"{c}/{v}": a for c, vs in computed.items() for v, a in vs.items()}


if __name__ == "__main__":
    # python tests/bit_identity_cases.py [NAME ...]: the named cases (default: all)
    REFERENCE.parent.mkdir(exist_ok=True)
    np.savez_compressed(REFERENCE, **flatten(compute(sys.argv[1:] or NAMES)))
    print(f"wrote {REFERENCE}", file=sys.stderr)
