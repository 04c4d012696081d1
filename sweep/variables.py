"""The output schema: every data variable of a result file, declared once.

This table feeds the Dataset constructor (``sweep/results/dataset.py``) and the tests;
the README's reference table is checked against it. ``per_block``: the variable has a
trailing ``block`` dimension; ``min_blocks``: written only for sweeps of at least that
many blocks; ``models``: written only for these models (empty: every model);
``feature``: written only for sweeps with that feature (``Config.features``: ``nblock``,
``heterogeneous``, ``ensemble``, ``events``, ``catalogue``, ``linear_verdicts``);
``per_member``: one value per run (with an ensemble, a ``member`` dimension), else one
per grid point; ``per_regime``: a trailing ``regime_name`` dimension; ``per_event``: a
trailing ``event`` dimension (the last events of each run); ``dim``: another trailing
dimension, ``slip_event`` (the events of the run's catalogue) or ``magnitude`` (its
magnitude bins; ``sweep/results/catalogue_statistics.py``). ``column``: the column of
the kernels' results it is read from (the name of a ``kernels.layout`` ``R_*`` index;
empty: computed from several), ``scale`` its conversion to physical units
(:data:`SCALES`).
"""

from dataclasses import dataclass

import numpy as np

#: The regime and attractor names in code order (the flag_values / flag_meanings of
#: ``regime`` and ``attractor``): the code tables of ``sweep/codes.py``.
from .codes import (
    ATTRACTORS,
    B_VALUE_STATUSES,
    FLOQUET_STATUSES,
    HOPF_CRITICALITIES,
    RECURRENCE_STATUSES,
    REGIMES,
)

#: The variables that are codes: each with its table (CF ``flag_values``/``flag_meanings``).
FLAGS = {
    "regime": REGIMES,
    "attractor": ATTRACTORS,
    "b_value_status": B_VALUE_STATUSES,
    "b_value_truncated_status": B_VALUE_STATUSES,
    "recurrence_status": RECURRENCE_STATUSES,
    "floquet_status": FLOQUET_STATUSES,
    "hopf_criticality": HOPF_CRITICALITIES,
}

#: Conversions of a kernel column to physical units, given D0/V in s per system: as is,
#: a time (× D0/V: s), a rate (÷ D0/V: s⁻¹).
SCALES = {
    "": lambda x, time_unit: x,
    "time": lambda x, time_unit: x * time_unit,
    "rate": lambda x, time_unit: x / time_unit,
}


@dataclass(frozen=True)
class Variable:
    """One output variable: name, dtype, units, long name and description."""

    name: str
    dtype: str
    units: str
    long_name: str
    description: str
    per_block: bool = False
    min_blocks: int = 1
    models: tuple = ()
    feature: str = ""
    per_member: bool = True
    per_regime: bool = False
    per_event: bool = False
    dim: str = ""
    column: str = ""
    scale: str = ""


VARIABLES = (
    Variable("regime", "int8", "1", "dynamical regime",
             "steady, stick_slip, runaway or undecided (see flag_values/flag_meanings); "
             "stick_slip is bounded oscillation: a cycle of one or more events, or "
             "quasi-periodic or chaotic motion (see attractor)", column="R_REGIME"),
    Variable("attractor", "int8", "1", "kind of attractor",
             "fixed_point (steady), periodic (a cycle of cycle_events events), quasi_periodic "
             "(lyapunov_exponent consistent with 0, no cycle of up to 32 events), chaotic "
             "(lyapunov_exponent > 0 beyond 3 lyapunov_error), unresolved (undecided), "
             "unbounded (runaway); see flag_values/flag_meanings", column="R_ATTRACTOR"),
    Variable("cycle_events", "int32", "1", "events per cycle",
             "number of events (maxima of ln v of block 0) after which a periodic run's "
             "motion repeats: 1 for a simple cycle, n for a period-n cycle; 0 where the run is "
             "not periodic", column="R_CYCLE_EVENTS"),
    Variable("lyapunov_exponent", "float64", "s-1", "largest Lyapunov exponent",
             "lambda1 from a tangent vector carried beside the state (Benettin et al. 1980), a "
             "least-squares fit of its log growth after a transient; computed from t_end on for "
             "runs not settled by then (classification_lyapunov: unsettled), over every run "
             "(always) or never; NaN where not computed or the window was too short",
             column="R_LYAPUNOV", scale="rate"),
    Variable("lyapunov_error", "float64", "s-1", "standard error of lyapunov_exponent",
             "standard error of the slopes of the fit's blocks (the window after the transient "
             "cut into 7 blocks)", column="R_LYAPUNOV_ERROR", scale="rate"),
    Variable("floquet_modulus", "float64", "1", "largest non-trivial Floquet multiplier modulus",
             "|mu| of the largest eigenvalue but the trivial one (along the flow) of the "
             "monodromy matrix: the exact tangent of the run's step map carried once around "
             "the cycle in every state direction (ln v, ln Phi/Phi_ss, inertial force per "
             "block); < 1 stable; NaN where not computed (see floquet_status)",
             column="R_FLOQUET_MODULUS"),
    Variable("floquet_argument", "float64", "rad", "argument of that multiplier",
             "in (-pi, pi]: 0 a real positive multiplier (its approach to +1: fold of cycles), "
             "pi a real negative one (approach to -1: period doubling), else a complex pair "
             "(approach to the unit circle: torus)", column="R_FLOQUET_ARGUMENT"),
    Variable("floquet_trivial_error", "float64", "1", "|mu - 1| of the trivial multiplier",
             "the multiplier along the flow is 1 on an exact cycle: its distance from 1 is the "
             "accuracy of the matrix", column="R_FLOQUET_TRIVIAL"),
    Variable("floquet_period", "float64", "s", "period of the monodromy matrix",
             "return time to the section through the run's final state normal to the flow",
             column="R_RETURN_TIME", scale="time"),
    Variable("cycle_decay_rate", "float64", "s-1", "decay rate of perturbations of the cycle",
             "-ln(floquet_modulus) / floquet_period: perturbations of the cycle shrink as "
             "exp(-rate t); a lower bound where floquet_status is at_resolution"),
    Variable("floquet_status", "int8", "1", "why the Floquet multipliers are given or not",
             "not_computed (not periodic, or classification_floquet does not ask), ok, "
             "at_resolution (the largest modulus is below the eigenvalues' round-off; the "
             "floor is given), no_return, failed or inaccurate (the trivial multiplier more "
             "than 0.01 from 1: modulus and argument not given); see "
             "flag_values/flag_meanings",
             column="R_FLOQUET_STATUS"),
    Variable("lnv_amplitude", "float64", "1", "peak-to-peak ln(v/V)",
             "max - min of ln(v/V) over all blocks in the final window: the last completed "
             "cycle of a periodic run (all its events), the last events kept (up to 128) of "
             "chaotic and quasi-periodic runs, else the last interval between maxima of ln v of "
             "block 0; for runaway runs and runs without two maxima, the interval in progress"),
    Variable("lnv_max", "float64", "1", "maximum ln(v/V)", "in the final window",
             column="R_LNV_MAX"),
    Variable("lnv_min", "float64", "1", "minimum ln(v/V)", "in the final window",
             column="R_LNV_MIN"),
    Variable("lnv_peak", "float64", "1", "peak ln(v/V) of the whole run",
             "maximum of ln(v/V) over all blocks from the start to the end of the run (the "
             "start included; maxima inside a step from its dense output): the excursion of a "
             "kick that returns; for runaway runs at least ln(classification_v_cap_over_V)",
             column="R_LNV_MAX_RUN"),
    Variable("v_max", "float64", "um s-1", "maximum slip velocity",
             "V exp(lnv_max); for runaway runs the velocity after the step that crossed the "
             "cap (at least the cap), or the last finite value if the run blew up first"),
    Variable("v_min", "float64", "um s-1", "minimum slip velocity",
             "V exp(lnv_min); may underflow to 0 in deep stick phases (use lnv_min)"),
    Variable("period", "float64", "s", "oscillation period",
             "of a periodic run the full period of its cycle (the sum of the intervals of its "
             "cycle_events events); otherwise the time between the last two maxima of ln v of "
             "block 0; NaN without two maxima", column="R_PERIOD", scale="time"),
    Variable("growth_rate", "float64", "s-1", "envelope growth rate",
             "ln(ratio of the last two peak-to-trough amplitudes of ln v of block 0, one cycle "
             "apart) / period; "
             "negative: decaying, about 0: limit cycle, positive: growing; NaN where either "
             "amplitude is below classification_steady_amplitude (round-off)",
             column="R_GROWTH", scale="rate"),
    Variable("friction_drop", "float64", "1", "friction drop per event",
             "max - min of the friction coefficient over the final window (largest over blocks)",
             column="R_FRICTION_DROP"),
    Variable("slip_per_event", "float64", "um", "slip per event",
             "V * period / cycle_events for periodic stick-slip (the load point's advance per "
             "event); NaN otherwise"),
    Variable("t_runaway", "float64", "s", "runaway time",
             "time at which v first exceeded the velocity cap or the state became non-finite; "
             "NaN if the run did not run away", column="R_TAU_RUNAWAY", scale="time"),
    Variable("t_final", "float64", "s", "time the run stopped",
             "end time, earlier when the regime was settled (early exit), or later (up to "
             "classification_max_t_end) when it was not settled at the end time",
             column="R_TAU_FINAL", scale="time"),
    Variable("convergence", "float64", "1", "distance of the last cycle to the limit cycle",
             "estimated relative distance of the final cycle's features (extremes of ln v, "
             "peak-to-peak, period) to those of the limit cycle, from the Aitken extrapolation "
             "of the cycle-to-cycle sequence (per residue class for a cycle of several "
             "events); periodic runs have at most classification_accuracy; elsewhere the best "
             "over the cycles tried, inf where the cycles do not contract; NaN for steady and "
             "runaway runs", column="R_CONVERGENCE"),
    Variable("n_steps", "int32", "1", "accepted integration steps", "", column="R_N_STEPS"),
    Variable("n_rejected", "int32", "1", "rejected integration steps", "adaptive method only",
             column="R_N_REJECTED"),
    Variable("n_peaks", "int32", "1", "maxima of ln v of block 0", "", column="R_N_PEAKS"),
    Variable("sync_error", "float64", "1", "synchronisation error",
             "max |ln v_i - ln v_0| over blocks in the final window, at the ends of the "
             "accepted steps (a peak between them reads low: 0.3-0.8 % in two cases checked)",
             min_blocks=2, column="R_SYNC_ERROR"),
    Variable("phase_lag", "float64", "1", "phase lag of the last block",
             "time from a maximum of ln v_0 to the next maximum of ln v of the last block, "
             "as a fraction in [-0.5, 0.5) of the last interval between maxima of ln v_0 (for a "
             "cycle of n events that event's interval, not period)", min_blocks=2,
             column="R_PHASE_LAG"),
    Variable("lnv_final", "float64", "1", "final ln(v/V) per block",
             "state at t_final", per_block=True),
    Variable("ln_state_final", "float64", "1", "final ln(Phi/Phi_ss) per block",
             "state at t_final", per_block=True),
    Variable("inertial_force_final", "float64", "1", "final inertial force per block",
             "z_i = (m/W) dv_i/dt per unit normal load at t_final (the inertial model's third "
             "state variable, as in the kernels' state); with lnv_final and ln_state_final it "
             "restarts the run", per_block=True, models=("inertial",)),
    Variable("sync_order", "float64", "1", "synchronisation order parameter",
             "Kuramoto R = |mean_i exp(i theta_i)| of the blocks' oscillation phases in the final "
             "window, theta_i = 2 pi (time of block i's last maximum of ln v - time of block 0's "
             "maximum) / (the last interval between maxima of ln v_0; for a cycle of n events "
             "that event's interval, not period): 1 in phase, 0 spread evenly; NaN without two "
             "maxima of block 0 or where a block had none in that interval", feature="nblock",
             column="R_SYNC_ORDER"),
    Variable("slip_participation", "float64", "1", "fraction of blocks taking part in a slip",
             "mean over the slip events of the final window of the fraction of blocks that slip "
             "(v > classification_slip_v_over_V * V) during the event; an event lasts while any "
             "block slips; NaN without a completed event", feature="nblock",
             column="R_SLIP_PARTICIPATION"),
    Variable("A_block", "float64", "1", "direct-effect coefficient A per block", "",
             per_block=True, feature="heterogeneous", per_member=False),
    Variable("B_block", "float64", "1", "evolution-effect coefficient B per block", "",
             per_block=True, feature="heterogeneous", per_member=False),
    Variable("D0_block", "float64", "um", "characteristic slip distance D0 per block", "",
             per_block=True, feature="heterogeneous", per_member=False),
    Variable("K_W_block", "float64", "um-1", "driving-spring stiffness per normal load K/W per "
             "block", "", per_block=True, feature="heterogeneous", per_member=False),
    Variable("linear_verdict", "int8", "1", "labelled by the linear growth rate",
             "1 where a refinement's run (refine_full_runs: false) was labelled by a "
             "linear-regime verdict: its envelope followed linear_growth_rate within 1 % in "
             "the linear regime, so it stopped steady (decaying) or undecided (growing, too "
             "slowly to leave the linear regime by classification_max_t_end), the label of the "
             "full run; its other outputs are those of that moment, lyapunov_exponent NaN; "
             "0 otherwise", column="R_LINEAR_VERDICT", feature="linear_verdicts"),
    Variable("regime_fraction", "float64", "1", "fraction of the ensemble in each regime",
             "fraction of the initial-condition ensemble's members that ended in the regime",
             feature="ensemble", per_member=False, per_regime=True),
    Variable("event_lnv_peak", "float64", "1", "ln(v/V) of block 0 at each of the last events",
             "the last classification_events maxima of ln v of block 0 (the events), oldest "
             "first along event (0: the last); NaN before a run's first; an orbit diagram is "
             "this against a swept parameter", feature="events", per_event=True),
    Variable("event_interval", "float64", "s", "time from the previous event",
             "interval between each of the last events and the event before it",
             feature="events", per_event=True),
    Variable("slip_event_count", "int32", "1", "slip events",
             "slip events that began after catalogue_after x t_end (kept or not); an event lasts "
             "while any block's v/V exceeds catalogue_slip_v_over_V (by default "
             "classification_slip_v_over_V)",
             feature="catalogue"),
    Variable("slip_event_start", "float64", "s", "start of the slip event",
             "time from the run's start at which the event's first block's v rose through "
             "the slip threshold (an event: a connected rupture, blocks slipping that are "
             "neighbours and overlap in time); NaN beyond the events kept",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_duration", "float64", "s", "duration of the slip event",
             "from its start to where its last block's v fell through the threshold",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_first_block", "int32", "1", "block where the slip event began",
             "its hypocentre (where two events merged, the earlier one's); -1: no event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_blocks", "int32", "1", "blocks that slipped in the slip event",
             "blocks whose v exceeded the threshold in the event; -1: no event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_extent", "int32", "1", "extent of the slip event",
             "blocks spanned by the rupture along the chain or ring (connected: its blocks); "
             "all-to-all coupling: the blocks that slipped; -1: no event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_block_low", "int32", "1", "first block of the slip event",
             "going up the chain (ring: the arc's first, above block_high where it wraps "
             "past block 0); -1: no event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_block_high", "int32", "1", "last block of the slip event",
             "going up the chain (ring: the arc's last); -1: no event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_slip", "float64", "um", "slip of the slip event",
             "sum over its blocks of each one's slip while it slipped in the event (integral "
             "of v over that time, integrated with the solution): a moment-like size, the "
             "potency per block area", feature="catalogue", dim="slip_event"),
    Variable("slip_event_magnitude", "float64", "1", "magnitude of the slip event",
             "(2/3) log10(slip_event_slip / D0), the moment magnitude's scaling",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_v_peak", "float64", "um s-1", "peak slip velocity of the slip event",
             "largest v of its blocks while they slipped in the event",
             feature="catalogue", dim="slip_event"),
    Variable("slip_event_moment", "float64", "N m", "seismic moment of the slip event",
             "M0 = G a S: catalogue_shear_modulus G x catalogue_block_area a x summed slip S "
             "(in m), all blocks alike", feature="moment", dim="slip_event"),
    Variable("slip_event_moment_magnitude", "float64", "1", "moment magnitude of the slip event",
             "Mw = (2/3)(log10 M0 - 9.1), M0 in N m (Hanks & Kanamori 1979; the constant of "
             "Kanamori 1977 and IASPEI 2005); Mw - slip_event_magnitude = "
             "moment_magnitude_offset", feature="moment", dim="slip_event"),
    Variable("moment_magnitude_offset", "float64", "1", "moment magnitude minus magnitude",
             "Mw - m = (2/3)(log10(G a D0) - 9.1), D0 in m: the same for every event of a run, "
             "so b-values do not depend on which is used", feature="moment"),
    Variable("b_value", "float64", "1", "Gutenberg-Richter b-value",
             "Aki-Utsu maximum-likelihood estimate log10(e) / (mean m - m_c) over the kept "
             "events with magnitude m >= m_c (continuous magnitudes); NaN unless b_value_status "
             "is ok: at least 200 events (Nava et al. 2017), m_max - m_c >= 1 and b_value_ks_p "
             ">= 0.1 (Clauset et al. 2009)", feature="catalogue"),
    Variable("b_value_error", "float64", "1", "standard error of the b-value",
             "Shi & Bolt (1982): 2.30 b^2 sqrt(sum (m - mean m)^2 / (n (n - 1))); sampling error "
             "only", feature="catalogue"),
    Variable("b_value_ks_p", "float64", "1", "goodness-of-fit p-value of the b-value",
             "share of 2500 synthetic samples of the fitted exponential law (same size, refitted) "
             "whose Kolmogorov-Smirnov distance is at least the data's (Clauset, Shalizi & Newman "
             "2009); the law is rejected below 0.1; NaN where not tested (too few events or span "
             "below one unit)", feature="catalogue"),
    Variable("b_value_status", "int8", "1", "why the b-value is given or not",
             "ok, no_events, too_few_events (< 200 above m_c), span_below_one_unit "
             "(m_max - m_c < 1) or rejected_by_goodness_of_fit (b_value_ks_p < 0.1); see "
             "flag_values/flag_meanings", feature="catalogue"),
    Variable("b_value_truncated", "float64", "1", "b-value of the truncated Gutenberg-Richter law",
             "maximum-likelihood b of the exponential law truncated at m_c and "
             "magnitude_max (Page 1968); negative where the density grows towards m_max; NaN "
             "unless b_value_truncated_status is ok", feature="catalogue"),
    Variable("b_value_truncated_error", "float64", "1", "standard error of b_value_truncated",
             "1 / (ln 10 sqrt(n Var(m))) of the truncated law (Cramer-Rao, m_max held fixed)",
             feature="catalogue"),
    Variable("b_value_truncated_ks_p", "float64", "1", "p-value of the truncated fit",
             "as b_value_ks_p, synthetic samples of the truncated law refitted with their own "
             "largest magnitude as m_max", feature="catalogue"),
    Variable("b_value_truncated_status", "int8", "1", "why the truncated b-value is given or not",
             "as b_value_status, with b_value_truncated_ks_p; see flag_values/flag_meanings",
             feature="catalogue"),
    Variable("magnitude_completeness", "float64", "1", "completeness magnitude m_c",
             "catalogue_completeness, or the smallest magnitude of the run's kept events",
             feature="catalogue"),
    Variable("magnitude_max", "float64", "1", "largest magnitude m_max",
             "largest magnitude of the run's kept events: the truncated law's upper bound",
             feature="catalogue"),
    Variable("magnitude_events", "int32", "1", "events above the completeness magnitude",
             "kept events with m >= m_c: the sample of the b-values", feature="catalogue"),
    Variable("system_wide_fraction", "float64", "1", "fraction of system-wide events",
             "fraction of the kept events whose extent spans at least catalogue_system_wide_extent "
             "x blocks", feature="catalogue"),
    Variable("system_wide_size_share", "float64", "1", "share of the size in system-wide events",
             "summed slip (the moment, all blocks alike) of the system-wide events / that of all "
             "kept events: near 1 where system-wide (characteristic) events carry the slip",
             feature="catalogue"),
    Variable("large_event_magnitude", "float64", "1", "magnitude of the large events m_L",
             "smallest magnitude of the run's system-wide events (at least m_c); NaN without any",
             feature="catalogue"),
    Variable("large_event_excess", "float64", "1", "large events observed / Gutenberg-Richter",
             "kept events with m >= m_L / the number the untruncated Aki-Utsu fit predicts, "
             "n(m >= m_c) 10^(-b (m_L - m_c)), b estimated whatever b_value_status: > 1 where "
             "large events are characteristic", feature="catalogue"),
    Variable("recurrence_mean", "float64", "s", "mean recurrence interval of system-wide events",
             "mean interval between the successive starts (sorted) of kept system-wide events; "
             "NaN unless recurrence_status is ok (at least 10 intervals)", feature="catalogue"),
    Variable("recurrence_mean_low", "float64", "s", "lower bound of recurrence_mean",
             "95 % Student-t interval: mean - t(0.975, n-1) sd / sqrt(n)", feature="catalogue"),
    Variable("recurrence_mean_high", "float64", "s", "upper bound of recurrence_mean",
             "95 % Student-t interval: mean + t(0.975, n-1) sd / sqrt(n)", feature="catalogue"),
    Variable("recurrence_cv", "float64", "1", "coefficient of variation of the recurrence",
             "sample standard deviation / mean of those intervals: 0 periodic, 1 Poissonian",
             feature="catalogue"),
    Variable("recurrence_cv_low", "float64", "1", "lower bound of recurrence_cv",
             "2.5th percentile of the CV of 2000 seeded bootstrap resamples of the intervals "
             "(Efron & Tibshirani 1993; the intervals taken as independent)", feature="catalogue"),
    Variable("recurrence_cv_high", "float64", "1", "upper bound of recurrence_cv",
             "97.5th percentile of the same resamples", feature="catalogue"),
    Variable("recurrence_intervals", "int32", "1", "intervals between system-wide events",
             "the sample of the recurrence statistics", feature="catalogue"),
    Variable("recurrence_status", "int8", "1", "why the recurrence statistics are given or not",
             "ok, no_system_wide_events or too_few_intervals (< 10); see "
             "flag_values/flag_meanings", feature="catalogue"),
    Variable("magnitude_count", "int32", "1", "slip events per magnitude bin",
             "kept events whose magnitude falls in each bin (size-frequency)",
             feature="catalogue", dim="magnitude"),
    Variable("linear_growth_rate", "float64", "s-1", "linear growth rate",
             "max Re(lambda) of the system linearised about steady sliding (analytic normal modes "
             "for identical blocks, eigenvalues of the Jacobian for unequal ones)",
             per_member=False),
    Variable("critical_K_W", "float64", "um-1", "critical stiffness Kc/W",
             "critical driving-spring stiffness per normal load (the common K/W; per-block K/W "
             "keep their ratios): analytic for identical blocks, else where the Jacobian's largest "
             "real part crosses zero", per_member=False),
    Variable("K_over_Kc", "float64", "1", "K/Kc", "driving-spring stiffness / critical stiffness",
             per_member=False),
    Variable("onset_period", "float64", "s", "period at onset",
             "2 pi / omega of the linear oscillation at K = Kc", per_member=False),
    Variable("hopf_l1", "float64", "1", "first Lyapunov coefficient at Kc",
             "l1 of the Hopf bifurcation of steady sliding at K = Kc (Kuznetsov 2004, sections "
             "3.5 and 5.4): < 0 supercritical, > 0 subcritical; its sign is coordinate-free, "
             "its size is in the engine's state variables (ln(v_i/V), ln(Phi_i/Phi_ss,i)[, "
             "z_i]) and time unit D0/V, critical eigenvectors normalised <q, q> = <p, q> = 1; "
             "NaN where hopf_criticality is not_simple or no_hopf", per_member=False),
    Variable("hopf_criticality", "int8", "1", "kind of Hopf bifurcation at Kc",
             "supercritical (hopf_l1 < 0), subcritical (> 0), degenerate (|hopf_l1| within "
             "1e-9 of the sum of the moduli of its formula's three terms: zero to round-off, "
             "as for one quasi-static block), not_simple (another eigenvalue crosses with the "
             "pair: identical blocks without coupling springs) or no_hopf (no pair crosses "
             "at a positive stiffness); see flag_values/flag_meanings", per_member=False),
    Variable("hopf_lnv_amplitude", "float64", "1", "normal-form peak-to-peak ln(v/V)",
             "the cycle the normal form predicts near Kc, 4 |z| max_i |q_i| with "
             "|z|^2 = -Re(lambda) / (omega hopf_l1), Re(lambda) = linear_growth_rate D0/V and "
             "omega = 2 pi / onset_period in units of V/D0, q_i block i's ln v entry of the "
             "critical eigenvector: to leading order in K - Kc the lnv_amplitude of the "
             "settled cycle; NaN unless supercritical, K < Kc and near it (0 < Re(lambda) <= "
             "0.1 omega)",
             per_member=False),
)  # fmt: skip

BY_NAME = {v.name: v for v in VARIABLES}


def variable_attrs(var):
    """CF attributes of ``var``: units, long name, description; a code's
    ``flag_values``/``flag_meanings`` (:data:`FLAGS`) in place of units."""
    attrs = {"units": var.units, "long_name": var.long_name}
    if var.description:
        attrs["description"] = var.description
    if var.name in FLAGS:
        attrs["flag_values"] = np.arange(len(FLAGS[var.name]), dtype=np.int8)
        attrs["flag_meanings"] = " ".join(FLAGS[var.name])
        attrs.pop("units")
    return attrs


def variables_for(blocks, model="quasi-static", features=()):
    """The variables a sweep of ``blocks`` blocks of ``model`` with ``features`` writes."""
    return [
        v
        for v in VARIABLES
        if blocks >= v.min_blocks
        and (not v.models or model in v.models)
        and (not v.feature or v.feature in features)
    ]
