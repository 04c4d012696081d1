"""The kernels' array layout: codes and column indices shared with the Python side.

Plain Python (no numba): the grid builder, the Dataset constructor and the tests
read results with these names without compiling anything. In the kernels they are
compile-time constants. The codes are those of the tables in ``sweep/codes.py``.

State of one system with ``nb`` blocks: ``y[i] = ℓ_i`` (ln v/V), ``y[nb+i] = ψ_i``
(ln VΦ/D0) and, for the inertial model, ``y[2nb+i] = z_i`` (inertial force
m dv/dt per unit normal load). Time τ is in units of D0/V.
"""

from ..codes import (
    ATTRACTORS,
    COUPLINGS,
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


# --- columns of the per-system parameter array (all dimensionless) ----------
N_PARAMS = 11
(
    P_A,  # direct effect
    P_B,  # evolution effect
    P_KAPPA1,  # driving stiffness K D0/W
    P_KAPPA2,  # coupling stiffness k2 D0/W
    P_ETA,  # radiation damping ηV/W
    P_MASS,  # mass mV²/(W D0)
    P_TAU_END,  # end time (D0/V)
    P_DT,  # fixed step of rk4 (D0/V)
    P_MAX_STEP,  # largest adaptive step (D0/V)
    P_TAU_MAX,  # unsettled runs continue up to this time (D0/V), ≥ P_TAU_END
    P_LIN_GROWTH,  # max Re λ of the linearisation at steady sliding (V/D0)
) = range(N_PARAMS)
# Rows whose blocks differ have N_BLOCK_PARAMS × nb more columns after N_PARAMS:
# column N_PARAMS + k nb + i holds quantity k of block i (B_* below). Without them
# (p.size == N_PARAMS) every block takes P_A, P_B, P_KAPPA1 and rate factor 1.
N_BLOCK_PARAMS = 4
(
    B_A,  # direct effect of block i
    B_B,  # evolution effect of block i
    B_KAPPA1,  # driving stiffness K_i D0/W (D0: the reference D0)
    B_RATE,  # state-rate factor D0/D0_i
) = range(N_BLOCK_PARAMS)

# --- entries of the settings array, shared by all systems of a sweep --------
N_SETTINGS = 19
(
    S_MODEL,  # QUASI_STATIC | QUASI_DYNAMIC | INERTIAL
    S_LAW,  # AGING | SLIP
    S_METHOD,  # DOPRI5 | RK4 | ROSENBROCK | DOP853
    S_NBLOCKS,  # number of blocks
    S_RTOL,  # relative tolerance of the adaptive methods
    S_ATOL,  # absolute tolerance of the adaptive methods
    S_MAX_STEPS,  # step budget per run (accepted + rejected)
    S_LNV_CAP,  # runaway when any ln(v/V) exceeds this
    S_STEADY_AMP,  # steady when every |state variable| falls below this
    S_ACCURACY,  # relative accuracy of the extrapolated limit that settles a run
    S_CONFIRM_CYCLES,  # consecutive cycles a verdict must hold to settle a run early
    S_EARLY_EXIT,  # 1: stop as soon as the regime is settled
    S_SLIP_LNV,  # a block slips (slip events, R_SLIP_PARTICIPATION) while ℓ_i exceeds this
    S_COUPLING,  # CHAIN | RING | ALL
    S_LYAPUNOV,  # LYAP_NEVER | LYAP_UNSETTLED | LYAP_ALWAYS
    S_EVENTS,  # events whose ℓ_0 maxima and intervals each run reports (columns after R_*)
    S_CATALOGUE,  # slip events each run's catalogue keeps (0: no catalogue)
    S_CATALOGUE_AFTER,  # events starting before this fraction of tau_end are not catalogued
    S_CATALOGUE_LNV,  # a block slips in the catalogue's events while ℓ_i exceeds this
) = range(N_SETTINGS)

# --- columns of the per-system statistics array -----------------------------
N_RESULTS = 22
(
    R_REGIME,  # STEADY | STICK_SLIP | RUNAWAY | UNDECIDED
    R_TAU_FINAL,  # time the run stopped (D0/V)
    R_N_STEPS,  # accepted steps
    R_N_REJECTED,  # rejected steps
    R_LNV_MAX,  # max ln(v/V) over blocks, final window
    R_LNV_MIN,  # min ln(v/V) over blocks, final window
    R_PERIOD,  # last peak-to-peak time of ℓ_0 (D0/V)
    R_GROWTH,  # envelope growth rate from the last two cycles (V/D0)
    R_FRICTION_DROP,  # max over blocks of max − min friction in the final window
    R_TAU_RUNAWAY,  # time ℓ crossed the cap or went non-finite (D0/V)
    R_SYNC_ERROR,  # max |ℓ_i − ℓ_0| over blocks, final window
    R_PHASE_LAG,  # (t peak of ℓ_last − t peak of ℓ_0) / period, in [−0.5, 0.5)
    R_N_PEAKS,  # maxima of ℓ_0 seen
    R_LNV_MAX_RUN,  # max ln(v/V) over the whole run
    R_N_RECORDED,  # points written to the recording buffers
    R_CONVERGENCE,  # estimated relative distance of the last cycle to its limit
    R_SYNC_ORDER,  # Kuramoto order parameter of the blocks' phases, final window
    R_SLIP_PARTICIPATION,  # mean fraction of blocks slipping per slip event, final window
    R_ATTRACTOR,  # FIXED_POINT | PERIODIC | QUASI_PERIODIC | CHAOTIC | UNRESOLVED | UNBOUNDED
    R_CYCLE_EVENTS,  # events (maxima of ℓ_0) per cycle of a periodic run, else 0
    R_LYAPUNOV,  # largest Lyapunov exponent (V/D0); NaN where the tangent was not carried
    R_LYAPUNOV_ERROR,  # its standard error (V/D0)
) = range(N_RESULTS)
# After the R_* columns: the last S_EVENTS events' maxima of ℓ_0, then their intervals
# from the event before (D0/V), oldest first, NaN before the first.


# Then, with a catalogue (S_CATALOGUE > 0): the number of slip events the run had (all,
# kept or not), then S_CATALOGUE events of N_EVENT_FIELDS columns each (E_*), NaN where
# none (kernels/catalogue.py).
N_EVENT_FIELDS = 9
(
    E_T_START,  # time the first block's v rose through the threshold (D0/V)
    E_T_END,  # time the last block's v fell through it (D0/V)
    E_FIRST_BLOCK,  # the block whose v rose through it first
    E_N_BLOCKS,  # blocks whose v exceeded it during the event
    E_EXTENT,  # blocks spanned by them along the chain (ring: the shortest arc; all: count)
    E_BLOCK_LO,  # the lowest index of a block that slipped
    E_BLOCK_HI,  # the highest
    E_SLIP,  # Σ over those blocks of their slip during the event, ∫ v_i/V dτ (D0)
    E_LNV_PEAK,  # the largest ln(v/V) of any block during the event
) = range(N_EVENT_FIELDS)


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
