"""The kernels' array layout: codes and column indices shared with the Python side.

Plain Python (no numba): the grid builder, the Dataset constructor and the tests
read results with these names without compiling anything. In the kernels they are
compile-time constants. The codes are those of the tables in ``sweep/codes.py``.

State of one system with ``nb`` blocks: ``y[i] = ℓ_i`` (ln v/V), ``y[nb+i] = ψ_i``
(ln VΦ/D0) and, for the inertial model, ``y[2nb+i] = z_i`` (inertial force
m dv/dt per unit normal load). Time τ is in units of D0/V.
"""

import itertools

from ..codes import (
    ATTRACTORS,
    COUPLINGS,
    FLOQUET_MODES,
    LYAPUNOV_MODES,
    METHODS,
    MODELS,
    REGIMES,
    STATE_LAWS,
    code,
)

# --- codes: each name of the tables of sweep/codes.py, as the kernels take it --------
QUASI_STATIC = code(MODELS, "quasi-static")
QUASI_DYNAMIC = code(MODELS, "quasi-dynamic")
INERTIAL = code(MODELS, "inertial")
AGING = code(STATE_LAWS, "aging")
SLIP = code(STATE_LAWS, "slip")
DOPRI5 = code(METHODS, "dopri5")
RK4 = code(METHODS, "rk4")
ROSENBROCK = code(METHODS, "rosenbrock")
DOP853 = code(METHODS, "dop853")
CHAIN = code(COUPLINGS, "chain")
RING = code(COUPLINGS, "ring")
ALL = code(COUPLINGS, "all")
# when the tangent for λ1 is carried (S_LYAPUNOV)
LYAP_NEVER = code(LYAPUNOV_MODES, "never")
LYAP_UNSETTLED = code(LYAPUNOV_MODES, "unsettled")
LYAP_ALWAYS = code(LYAPUNOV_MODES, "always")
# when a periodic run's Floquet multipliers are computed (S_FLOQUET)
FLOQUET_NEVER = code(FLOQUET_MODES, "never")
FLOQUET_AUTO = code(FLOQUET_MODES, "auto")
FLOQUET_ALWAYS = code(FLOQUET_MODES, "always")
STEADY = code(REGIMES, "steady")
STICK_SLIP = code(REGIMES, "stick_slip")
RUNAWAY = code(REGIMES, "runaway")
UNDECIDED = code(REGIMES, "undecided")
# what a run settled on (R_ATTRACTOR)
FIXED_POINT = code(ATTRACTORS, "fixed_point")
PERIODIC = code(ATTRACTORS, "periodic")
QUASI_PERIODIC = code(ATTRACTORS, "quasi_periodic")
CHAOTIC = code(ATTRACTORS, "chaotic")
UNRESOLVED = code(ATTRACTORS, "unresolved")
UNBOUNDED = code(ATTRACTORS, "unbounded")


def values_per_block(model):
    """State values per block of model code ``model``: ℓ and ψ, and z if inertial."""
    return 3 if model == INERTIAL else 2


# Each table below is numbered in the order it is written, and its N_* count is the
# number after its last entry: a column is added (or removed) by its own line alone.

# --- columns of the per-system parameter array (all dimensionless) ----------
_p = itertools.count()
P_A = next(_p)  # direct effect
P_B = next(_p)  # evolution effect
P_KAPPA1 = next(_p)  # driving stiffness K D0/W
P_KAPPA2 = next(_p)  # coupling stiffness k2 D0/W
P_ETA = next(_p)  # radiation damping ηV/W
P_MASS = next(_p)  # mass mV²/(W D0)
P_TAU_END = next(_p)  # end time (D0/V)
P_DT = next(_p)  # fixed step of rk4 (D0/V)
P_MAX_STEP = next(_p)  # largest adaptive step (D0/V)
P_TAU_MAX = next(_p)  # unsettled runs continue up to this time (D0/V), ≥ P_TAU_END
P_LIN_GROWTH = next(_p)  # max Re λ of the linearisation at steady sliding (V/D0)
N_PARAMS = next(_p)
# Rows whose blocks differ have N_BLOCK_PARAMS × nb more columns after N_PARAMS:
# column N_PARAMS + k nb + i holds quantity k of block i (B_* below). Without them
# (p.size == N_PARAMS) every block takes P_A, P_B, P_KAPPA1 and rate factor 1.
_b = itertools.count()
B_A = next(_b)  # direct effect of block i
B_B = next(_b)  # evolution effect of block i
B_KAPPA1 = next(_b)  # driving stiffness K_i D0/W (D0: the reference D0)
B_RATE = next(_b)  # state-rate factor D0/D0_i
N_BLOCK_PARAMS = next(_b)

# --- entries of the settings array, shared by all systems of a sweep --------
_s = itertools.count()
S_MODEL = next(_s)  # QUASI_STATIC | QUASI_DYNAMIC | INERTIAL
S_LAW = next(_s)  # AGING | SLIP
S_METHOD = next(_s)  # DOPRI5 | RK4 | ROSENBROCK | DOP853
S_NBLOCKS = next(_s)  # number of blocks
S_RTOL = next(_s)  # relative tolerance of the adaptive methods
S_ATOL = next(_s)  # absolute tolerance of the adaptive methods
S_MAX_STEPS = next(_s)  # step budget per run (accepted + rejected)
S_LNV_CAP = next(_s)  # runaway when any ln(v/V) exceeds this
S_STEADY_AMP = next(_s)  # steady when every |state variable| falls below this
S_ACCURACY = next(_s)  # relative accuracy of the extrapolated limit that settles a run
S_CONFIRM_CYCLES = next(_s)  # consecutive cycles a verdict must hold to settle a run early
S_EARLY_EXIT = next(_s)  # 1: stop as soon as the regime is settled
S_SLIP_LNV = next(_s)  # a block slips (slip events, R_SLIP_PARTICIPATION) while ℓ_i exceeds this
S_COUPLING = next(_s)  # CHAIN | RING | ALL
S_LYAPUNOV = next(_s)  # LYAP_NEVER | LYAP_UNSETTLED | LYAP_ALWAYS
S_EVENTS = next(_s)  # events whose ℓ_0 maxima and intervals each run reports (columns after R_*)
S_CATALOGUE = next(_s)  # slip events each run's catalogue keeps (0: no catalogue)
S_CATALOGUE_AFTER = next(_s)  # events starting before this fraction of tau_end are not catalogued
S_CATALOGUE_LNV = next(_s)  # a block slips in the catalogue's events while ℓ_i exceeds this
S_LINEAR_VERDICTS = next(_s)  # 1: linear-regime verdicts on (classify/linear.py)
S_FLOQUET = next(_s)  # FLOQUET_NEVER | FLOQUET_AUTO | FLOQUET_ALWAYS (engine/floquet.py)
N_SETTINGS = next(_s)

# --- columns of the per-system statistics array -----------------------------
_r = itertools.count()
R_REGIME = next(_r)  # STEADY | STICK_SLIP | RUNAWAY | UNDECIDED
R_TAU_FINAL = next(_r)  # time the run stopped (D0/V)
R_N_STEPS = next(_r)  # accepted steps
R_N_REJECTED = next(_r)  # rejected steps
R_LNV_MAX = next(_r)  # max ln(v/V) over blocks, final window
R_LNV_MIN = next(_r)  # min ln(v/V) over blocks, final window
R_PERIOD = next(_r)  # last peak-to-peak time of ℓ_0 (D0/V)
R_GROWTH = next(_r)  # envelope growth rate from the last two cycles (V/D0)
R_FRICTION_DROP = next(_r)  # max over blocks of max − min friction in the final window
R_TAU_RUNAWAY = next(_r)  # time ℓ crossed the cap or went non-finite (D0/V)
R_SYNC_ERROR = next(_r)  # max |ℓ_i − ℓ_0| over blocks, final window
R_PHASE_LAG = next(_r)  # (t peak of ℓ_last − t peak of ℓ_0) / period, in [−0.5, 0.5)
R_N_PEAKS = next(_r)  # maxima of ℓ_0 seen
R_LNV_MAX_RUN = next(_r)  # max ln(v/V) over the whole run
R_N_RECORDED = next(_r)  # points written to the recording buffers
R_CONVERGENCE = next(_r)  # estimated relative distance of the last cycle to its limit
R_SYNC_ORDER = next(_r)  # Kuramoto order parameter of the blocks' phases, final window
R_SLIP_PARTICIPATION = next(_r)  # mean fraction of blocks slipping per slip event, final window
R_ATTRACTOR = next(_r)  # FIXED_POINT | PERIODIC | QUASI_PERIODIC | CHAOTIC | UNRESOLVED | UNBOUNDED
R_CYCLE_EVENTS = next(_r)  # events (maxima of ℓ_0) per cycle of a periodic run, else 0
R_LYAPUNOV = next(_r)  # largest Lyapunov exponent (V/D0); NaN where the tangent was not carried
R_LYAPUNOV_ERROR = next(_r)  # its standard error (V/D0)
R_LINEAR_VERDICT = next(_r)  # 1: labelled by a linear-regime verdict (classify/linear.py), else 0
# Floquet multipliers of a periodic run (engine/floquet.py, after the grid kernel; NaN else)
R_FLOQUET_MODULUS = next(_r)  # largest modulus of the non-trivial multipliers
R_FLOQUET_ARGUMENT = next(_r)  # its argument (rad, in (−π, π])
R_FLOQUET_TRIVIAL = next(_r)  # |μ − 1| of the trivial multiplier (along the flow): the accuracy
R_RETURN_TIME = next(_r)  # the period the matrix spans: return time to the section (D0/V)
R_FLOQUET_STATUS = next(_r)  # code of FLOQUET_STATUSES (sweep/codes.py)
N_RESULTS = next(_r)
# After the R_* columns: the last S_EVENTS events' maxima of ℓ_0, then their intervals
# from the event before (D0/V), oldest first, NaN before the first.


# Then, with a catalogue (S_CATALOGUE > 0): the number of slip events the run had (all,
# kept or not), then the first S_CATALOGUE to end of N_EVENT_FIELDS columns each (E_*),
# NaN where none (kernels/slip_events.py: an event is a connected rupture).
_e = itertools.count()
E_T_START = next(_e)  # time the event's first block rose through the threshold (D0/V)
E_T_END = next(_e)  # time its last one fell through it (D0/V)
E_FIRST_BLOCK = next(_e)  # the block that rose through it first (the hypocentre)
E_N_BLOCKS = next(_e)  # blocks that slipped in the event
E_EXTENT = next(_e)  # blocks it spans: along the chain or ring (all-to-all: E_N_BLOCKS)
E_BLOCK_LO = next(_e)  # its first block going up the chain (ring: the arc's, may exceed E_BLOCK_HI)
E_BLOCK_HI = next(_e)  # its last
E_SLIP = next(_e)  # Σ of its blocks' slip while they slipped in it, ∫ v_i/V dτ (D0)
E_LNV_PEAK = next(_e)  # the largest ln(v/V) of its blocks while they slipped in it
N_EVENT_FIELDS = next(_e)


def catalogue_start(settings):
    """Column of a run's slip-event count; its catalogue follows (``E_*`` per event)."""
    return N_RESULTS + 2 * int(settings[S_EVENTS])


def result_width(settings):
    """Columns of the statistics array of a run with ``settings`` (``S_*``)."""
    capacity = int(settings[S_CATALOGUE])
    return catalogue_start(settings) + (1 + capacity * N_EVENT_FIELDS if capacity else 0)


# Outcomes of a step's runaway test besides the index of the block that crossed
# the cap (runaway_index).
NO_RUNAWAY, NOT_FINITE = -1, -2

# R_REGIME of a run that a kernel without the tangent stopped at tau_end, unsettled,
# with λ1 asked for there (LYAP_UNSETTLED): the kernel with the tangent redoes it
# (dispatch.integrate_grid).
TANGENT_NEEDED = -1
