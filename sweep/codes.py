"""The code tables: one per choice a config or a result file names.

Each table lists the names a config uses (or a file writes, as CF ``flag_meanings``) in
code order: a name's code is its place in the table. The config parser checks names
against these tables, the grid builder turns them into the codes the kernels take
(``kernels/layout.py`` names each code), and the Dataset writes the regime,
attractor and catalogue status tables as ``flag_values``/``flag_meanings``. Plain
Python: importing it loads no numba. The kernels compile these codes in as constants,
so this file is part of the source their cache is keyed on (``accelerate.source_digest``).
"""

#: The models (``model:``).
MODELS = ("quasi-static", "quasi-dynamic", "inertial")
#: The state evolution laws (``state_law:``).
STATE_LAWS = ("aging", "slip")
#: Which blocks a coupling spring k2 joins (``coupling:``): neighbours in an open chain,
#: neighbours in a closed ring, or every pair.
COUPLINGS = ("chain", "ring", "all")
#: When the largest Lyapunov exponent is computed (``classification.lyapunov``): never;
#: from t_end on, for runs not settled by then; or over every whole run.
LYAPUNOV_MODES = ("never", "unsettled", "always")
#: When a periodic run's Floquet multipliers are computed (``classification.floquet``):
#: never; for runs labelled periodic whose state is small (``engine/floquet.py``); or for
#: every run labelled periodic.
FLOQUET_MODES = ("never", "auto", "always")
#: The integration methods (``integrator.method``), each name with its module in
#: ``sweep/kernels/methods``: the registry of the methods. Adding a method is its
#: module and a line here.
METHODS = {
    "dopri5": "dopri5",
    "rk4": "rk4",
    "rosenbrock": "rodas4",
    "dop853": "dop853",
    "bs23": "bs23",
    "rosenbrock-structured": "rodas4_structured",
}
#: Regimes (the ``regime`` variable's flag meanings).
REGIMES = ("steady", "stick_slip", "runaway", "undecided")
#: What a run settled on (the ``attractor`` variable's flag meanings).
ATTRACTORS = ("fixed_point", "periodic", "quasi_periodic", "chaotic", "unresolved", "unbounded")
#: Why a run's Gutenberg-Richter b-value is given or not (the ``b_value_status`` and
#: ``b_value_truncated_status`` variables' flag meanings; ``results/gutenberg_richter.py``).
B_VALUE_STATUSES = (
    "ok",
    "no_events",
    "too_few_events",
    "span_below_one_unit",
    "rejected_by_goodness_of_fit",
)
#: Why a run's recurrence statistics of system-wide events are given or not (the
#: ``recurrence_status`` variable's flag meanings).
RECURRENCE_STATUSES = ("ok", "no_system_wide_events", "too_few_intervals")
#: Why a run's Floquet multipliers are given or not (the ``floquet_status`` variable's flag
#: meanings; ``engine/floquet.py``): not computed (not periodic, or not asked), computed,
#: computed but the largest non-trivial modulus is below the matrix's round-off (the value
#: given is that floor, an upper bound), no return to the section within the window, the
#: integration failed, or the trivial multiplier is too far from 1 for the others to be
#: trusted (``engine/floquet.py``, ``TRIVIAL_TOLERANCE``).
FLOQUET_STATUSES = ("not_computed", "ok", "at_resolution", "no_return", "failed", "inaccurate")


def code(table, name):
    """The code of ``name`` in ``table`` (its place there; ValueError if absent)."""
    return list(table).index(name)


#: What the steady state's loss of stability at Kc is (the ``hopf_criticality`` variable's
#: flag meanings; ``model/hopf.py``): the sign of the first Lyapunov coefficient l1, zero
#: within its tolerance, or why l1 is not given (the critical pair of eigenvalues is not
#: simple; no pair crosses at any positive stiffness).
HOPF_CRITICALITIES = ("supercritical", "subcritical", "degenerate", "not_simple", "no_hopf")
