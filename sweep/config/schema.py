"""What a config is: the frozen dataclasses a YAML config becomes, and its tables.

:class:`Config` and its parts (:class:`Axis`, :class:`Initial`, :class:`Spread`,
:class:`Integrator`, :class:`Classification`, :class:`Catalogue`, :class:`Refine`), the
keys, defaults, limits and allowed values, and each setting's reference text (its
:class:`Setting`, from which the docs' config reference is generated). No parsing here:
``parse.py`` reads and checks a config against these.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ..codes import FLOQUET_MODES, LYAPUNOV_MODES, METHODS
from ..model.heterogeneity import SPREAD_AXES

#: Default integrator per model where it is not dop853: the inertial model is stiff
#: in stick phases (decay rate A e^(-ln v/V)/M̂ towards force balance). The explicit
#: methods are held to steps below their stability limit there (with M̂ = 1e-3 dopri5
#: spends 2e7 steps on the first 30 D0/V) and their stability-limited ripple adds false
#: maxima; the linearly implicit rosenbrock stepper needs ~1e3 steps per cycle.
DEFAULT_METHODS = {"inertial": "rosenbrock"}
#: Blocks from which such a run gets the default's structured solve instead, per
#: coupling: ``rosenbrock-structured``, the same RODAS4 steps with their linear systems
#: solved in O(N) operations (a band, or block by block with a rank-one correction)
#: instead of the dense LU's O(N³), costs less per step from there on and more below.
#: Measured by ``bench_structured_crossing`` in ``benchmarks/bench.py`` (its
#: ``crossing``; ``results/bench.json``, ``structured_crossing``; the table in
#: docs/performance.md), the two timed run by run: dense over structured time per step,
#: equal blocks (unequal alike), 0.94 at 8 and 1.13 at 10 blocks in a chain, 0.94 at 10
#: and 1.04 at 12 in a ring, 0.92 at 5 and 1.12 at 6 all-to-all.
STRUCTURED_FROM = {"chain": 10, "ring": 12, "all": 6}
#: The structured solve of a default method (:data:`STRUCTURED_FROM`).
STRUCTURED_METHODS = {"rosenbrock": "rosenbrock-structured"}
#: Default step-size cap (D0/V) of the methods that have one: RODAS4 (either way of
#: solving) reads extrema from a cubic Hermite interpolant, whose error grows with the step.
DEFAULT_MAX_STEPS = {"rosenbrock": 0.5, "rosenbrock-structured": 0.5}
#: Units of ``integrator.t_end`` and ``classification.max_t_end``.
TIME_UNITS = ("D0/V", "s")
#: Most events whose maxima a run can report: the cycles the classifier keeps
#: (``kernels.classify.state.HISTORY``; a test checks the two agree).
MAX_EVENTS = 128
#: The keys a config may give at its top level.
TOP_LEVEL_KEYS = (
    "name",
    "description",
    "blocks",
    "coupling",
    "model",
    "state_law",
    "parameters",
    "spread",
    "sweep",
    "initial",
    "integrator",
    "classification",
    "catalogue",
    "refine",
    "output",
)
#: Largest integer setting: integers are stored as 32-bit integers (CF-1.11 files).
INT32_MAX = 2**31 - 1
#: Largest step budget (step counts are stored as 32-bit integers too).
MAX_STEPS_LIMIT = INT32_MAX
#: Most blocks a config may have: every run holds per-block rows of this length.
MAX_BLOCKS = 100_000
#: Most points of one range axis, and most runs of a whole sweep (ensemble members
#: included): a config past them is refused before any array is built.
MAX_AXIS_POINTS = 10_000_000
MAX_RUNS = 1_000_000_000


@dataclass(frozen=True)
class Axis:
    """One sweep axis: a model parameter (see ``physics.PARAMETERS``) and its values.

    ``span``: ``(scale, start, stop)`` for values given as a range (``len(values)``
    points from start to stop, evenly spaced in ``scale``, linear or log; see
    :func:`.parse.range_values`), ``()`` for a list. Refinement (``sweep/refine/lattice.py``)
    places its points between the values by the same rule.
    """

    name: str
    values: tuple
    span: tuple = ()


@dataclass(frozen=True)
class Initial:
    """Initial perturbation, one entry per block.

    ``v_over_V``: slip velocity / load-point velocity; ``phi_over_phi_ss``: state
    Φ / its steady value D0/V. The spring stretch follows from force balance.
    ``ensemble``: number of random starts per grid point (0: the one start above);
    member m starts from ln(v/V) and ln(Φ/Φss) above plus independent uniform
    offsets in ±``amplitude``, drawn once from ``seed`` (the same M starts at every
    grid point); without an ensemble ``seed`` and ``amplitude`` are not used.
    The defaults are one block's: a config that leaves out ``v_over_V`` or
    ``phi_over_phi_ss`` starts every block there (v = V, Φ = 1.01 Φss).
    ``kicked_blocks``: the blocks whose start the sweep axes ``initial_v_over_V`` and
    ``initial_phi_over_phi_ss`` set (``physics.INITIAL_AXES``; empty: every block); the
    others start from the values above.
    """

    v_over_V: tuple = (1.0,)
    phi_over_phi_ss: tuple = (1.01,)  # a 1 % perturbation of the state (the paper's)
    ensemble: int = 0
    seed: int = 0
    amplitude: float = 0.1
    kicked_blocks: tuple = ()


@dataclass(frozen=True)
class Spread:
    """Seeded relative spread of per-block values (``sweep/model/heterogeneity.py``).

    ``sizes``: ((name, s), ...) for fixed spread sizes (swept ones are axes
    ``spread_<name>``); ``distribution``: uniform (ξ in (−1, 1)) or normal; ``seed``:
    the pattern's seed (not used where the seeds are the axis ``spread_seed``).
    """

    sizes: tuple = ()
    distribution: str = "uniform"
    seed: int = 0

    @property
    def sizes_dict(self):
        return dict(self.sizes)


@dataclass(frozen=True)
class Setting:
    """What one integrator or classification setting means, in what unit, and what is
    allowed: an interval such as ``(0, 1)`` or ``[1, inf)`` for numbers and integers,
    or a tuple of choices. Validation and its messages read it from here; the
    default is the dataclass field's."""

    doc: str
    allowed: object = None
    units: str = "1"
    default_text: str = None  # what a default of None stands for (the docs say it)

    def bounds(self):
        """``(low, low_open, high, high_open)`` of an interval ``allowed``."""
        low, high = (float(x) for x in self.allowed[1:-1].split(","))
        return low, self.allowed[0] == "(", high, self.allowed[-1] == ")"


def setting(default, doc, allowed=None, units="1", default_text=None):
    """A dataclass field with its :class:`Setting` (the one place a setting is stated)."""
    spec = Setting(doc, allowed, units, default_text)
    return dataclasses.field(default=default, metadata={"setting": spec})


@dataclass(frozen=True)
class Integrator:
    """Integrator settings. ``t_end`` is in ``t_unit`` (``"D0/V"`` or ``"s"``); the step
    sizes ``dt`` and ``max_step`` resolve the dynamics, whose time scale is D0/V,
    so they are always in units of D0/V."""

    method: str = setting(
        "dop853",
        "stepper",
        METHODS,
        default_text=f"dop853; model inertial: rosenbrock, and rosenbrock-structured from "
        f"{STRUCTURED_FROM['chain']} blocks in a chain, {STRUCTURED_FROM['ring']} in a ring and "
        f"{STRUCTURED_FROM['all']} all-to-all",
    )
    rtol: float = setting(1e-8, "relative tolerance of the adaptive methods", "(0, 1)")
    atol: float = setting(1e-10, "absolute tolerance of the adaptive methods", "(0, inf)")
    dt: float = setting(0.01, "fixed step of rk4", "(0, inf)", "D0/V")
    # Largest step of the adaptive methods. DOPRI5 and DOP853 need none: their dense
    # output is as accurate as their steps, and extrema that do not stand out of the
    # error scale count as no events (kernels/classify/extrema.py, TURN_FACTOR). RODAS4 keeps
    # 0.5 D0/V (DEFAULT_MAX_STEPS; docs/internals.md, "max_step").
    max_step: float = setting(
        math.inf,
        "largest step of the adaptive methods (.inf: no cap; rosenbrock's default: 0.5)",
        "(0, inf)",
        "D0/V",
    )
    t_end: float = setting(3000.0, "end time", "(0, inf)", "t_unit")
    t_unit: str = setting("D0/V", "unit of t_end and max_t_end", TIME_UNITS)
    max_steps: int = setting(
        20_000_000, "step budget per run; past it the run is undecided", f"[1, {MAX_STEPS_LIMIT}]"
    )


@dataclass(frozen=True)
class Classification:
    """How a run's oscillation becomes a regime (README: How a run is classified).

    ``steady_amplitude`` applies only where steady sliding is linearly stable;
    ``accuracy`` is the relative accuracy to which the limit of the cycle-to-cycle
    sequence (zero, or a limit cycle's features) must be known to settle a run;
    ``max_t_end`` (``None``: ten times ``integrator.t_end``) must be at least
    ``integrator.t_end``.
    """

    v_cap_over_V: float = setting(1e6, "runaway once any v/V exceeds this", "(1, inf)")
    steady_amplitude: float = setting(
        1e-6,
        "steady once every |ln v/V|, |ln Phi/Phi_ss| (and inertial force) is below this",
        "(0, inf)",
    )
    accuracy: float = setting(1e-3, "relative accuracy of the extrapolated limit", "(0, 0.5]")
    confirm_cycles: int = setting(
        2, "consecutive cycles a verdict must hold to stop early", f"[1, {INT32_MAX}]"
    )
    max_t_end: float = setting(
        None, "unsettled runs go on up to this time", "(0, inf)", "t_unit", "10 × t_end"
    )
    early_exit: bool = setting(
        True, "stop each run as soon as its regime is settled", (True, False)
    )
    slip_v_over_V: float = setting(
        2.0, "a block slips (slip_participation) while its v/V exceeds this", "(0, inf)"
    )
    lyapunov: str = setting(
        "unsettled",
        "when lyapunov_exponent is computed: from t_end on for runs not settled by "
        "then, over every whole run (no run then stops before t_end), or never",
        LYAPUNOV_MODES,
    )
    floquet: str = setting(
        "auto",
        "when the Floquet multipliers of runs labelled periodic are computed: never, for "
        "systems of at most 16 state values (auto), or always; each costs about (state "
        "values + 1) x one period of the run",
        FLOQUET_MODES,
    )
    events: int = setting(
        32,
        "events (maxima of ln v of block 0) whose values and intervals each run reports "
        "(the event dimension)",
        f"[0, {MAX_EVENTS}]",
    )


#: Most events a run's catalogue can keep (``catalogue.capacity``).
MAX_CATALOGUE = 1_000_000
#: Largest catalogue of a whole sweep, in bytes (``catalogue.capacity`` × runs ×
#: ``kernels.layout.N_EVENT_FIELDS`` × 8): past it the config is refused.
MAX_CATALOGUE_BYTES = 4 * 2**30


@dataclass(frozen=True)
class Catalogue:
    """The catalogue of slip events of each run (``sweep/kernels/slip_events.py``,
    ``sweep/results/catalogue_statistics.py``). An event is a connected rupture: blocks
    slipping (v/V above ``slip_v_over_V``, by default the threshold of
    ``slip_participation``, ``classification.slip_v_over_V``), neighbours along the chain
    or ring, overlapping in time; each run keeps the first ``capacity`` events to end of
    those that start after ``after`` × t_end (0: the catalogue is off) and counts them
    all. ``system_wide_extent`` defines the system-wide events of the statistics;
    ``shear_modulus`` and ``block_area`` (both or neither) add each event's seismic
    moment and moment magnitude."""

    capacity: int = setting(
        0, "slip events each run keeps (0: no catalogue)", f"[0, {MAX_CATALOGUE}]"
    )
    after: float = setting(
        0.0, "fraction of t_end before which events are not catalogued (the transient)", "[0, 1)"
    )
    completeness: float = setting(
        None,
        "magnitude above which the b-value is estimated (Aki-Utsu)",
        "(-inf, inf)",
        default_text="the smallest magnitude of each run's catalogue",
    )
    slip_v_over_V: float = setting(
        None,
        "a block slips in an event while its v/V exceeds this",
        "(0, inf)",
        default_text="classification.slip_v_over_V",
    )
    system_wide_extent: float = setting(
        0.9,
        "an event is system-wide when its extent spans at least this fraction of the blocks",
        "(0, 1]",
    )
    shear_modulus: float = setting(
        None,
        "shear modulus G of the seismic moment G a (summed slip); with block_area",
        "(0, inf)",
        "Pa",
        default_text="none: no moment or moment magnitude",
    )
    block_area: float = setting(
        None,
        "slipping area a of one block, of the seismic moment; with shear_modulus",
        "(0, inf)",
        "m^2",
        default_text="none: no moment or moment magnitude",
    )


#: Outputs whose change between neighbouring runs splits a cell, unless ``refine.outputs``
#: says otherwise: the labels of a run; with an initial-condition ensemble the share of its
#: members in each regime (the members' labels differ by start).
REFINE_OUTPUTS = ("regime", "attractor", "cycle_events")
REFINE_ENSEMBLE_OUTPUTS = ("regime_fraction",)
#: Most levels of refinement: each halves the cells, so 20 levels cut a grid step into
#: about 10^6 (lattice indices stay exact in float64; ``sweep/refine/lattice.py``).
MAX_REFINE_LEVELS = 20


@dataclass(frozen=True)
class Refine:
    """Refinement by label (``sweep/refine/lattice.py``): from the swept grid on, every cell whose
    corner runs differ in ``outputs`` is split in two along every axis with more than one
    value, and only the new points are run, level by level, up to ``levels`` levels or
    ``max_runs`` runs in all. Outputs of integer type and ``regime_fraction`` differ on any
    change; continuous ones where their range over the corners exceeds ``rtol`` times the
    largest magnitude there (NaN against a number counts as a change). Undecided corners
    count only with ``split_undecided``. Unless ``full_runs``, a run whose oscillation
    follows the linear theory's rate in the linear regime stops with the label that rate
    gives (``kernels/classify/linear.py``).
    """

    levels: int = setting(
        6,
        "levels of refinement beyond the grid: each halves the cells, so the finest cell is "
        "the grid step / 2^levels",
        f"[0, {MAX_REFINE_LEVELS}]",
    )
    max_runs: int = setting(
        None,
        "most runs in all, the grid's included: a level that would pass it is cut to the "
        "cells that fit (by the order of outputs, then spread evenly) and refinement stops there",
        "[1, inf)",
        default_text="no limit",
    )
    outputs: tuple = setting(
        None,
        "output variables whose change between the corner runs of a cell splits it",
        default_text="regime, attractor, cycle_events; with an ensemble regime_fraction",
    )
    rtol: float = setting(
        0.05, "relative tolerance of the continuous outputs in outputs", "(0, inf)"
    )
    split_undecided: bool = setting(
        False,
        "whether a cell also splits where an undecided corner differs from the others; "
        "false: only where its decided corners differ (an undecided band's edges move with "
        "max_t_end)",
        (True, False),
    )
    full_runs: bool = setting(
        False,
        "run every point as a grid sweep does; false: a run in the linear regime whose "
        "envelope follows the linear theory's rate stops with the label that rate gives",
        (True, False),
    )


@dataclass(frozen=True)
class Config:
    """A validated run config: what :func:`load_config` and :func:`parse_config` return.

    Frozen: make a changed copy with :func:`with_changes`. Each field is a config
    key of the same name (the keys are described on the guide's configs page);
    nothing downstream reads the YAML again. Values are in physical units (µm, s).
    """

    #: The sweep's name (``name:``; default the file's stem, ``sweep`` for a mapping).
    name: str
    #: Where the config came from (its path, ``"<mapping>"``, or ``"<config>"`` for
    #: text); error messages and the result's provenance name it.
    source: str
    #: The config as YAML text; stored in every result as ``config_text``.
    text: str
    #: Number of blocks (1, 2, or more for a chain, ring or all-to-all coupling).
    blocks: int
    #: ``quasi-static``, ``quasi-dynamic`` (radiation damping) or ``inertial``.
    model: str
    #: Evolution law of the state Φ, ``aging`` (Dieterich) or ``slip`` (Ruina).
    state_law: str
    #: The fixed (unswept) parameters shared by all blocks, ``((name, value), ...)``.
    parameters: tuple[tuple[str, float], ...]
    #: The sweep axes, in order (the dimensions of the result).
    axes: tuple[Axis, ...]
    #: The initial perturbation and the initial-condition ensemble (``initial:``).
    initial: Initial
    #: Integrator settings (``integrator:``), e.g. method, tolerances, end time.
    integrator: Integrator
    #: How a run is labelled (``classification:``), e.g. velocity cap, accuracy, events.
    classification: Classification
    #: Result path, ``.nc`` (NetCDF) or ``.zarr`` (default ``results/<name>.nc``).
    output: str
    #: The catalogue of slip events (``catalogue:``); off by default.
    catalogue: Catalogue = Catalogue()
    #: Free text (``description:``); the result's ``description`` attribute.
    description: str = ""
    #: ``chain``, ``ring`` or ``all`` as given; None when not given (an open chain,
    #: without the N-block outputs' ``coupling`` attribute). See :attr:`coupling`.
    coupling_key: str | None = None
    #: Per-block parameter lists, ``((name, (value per block, ...)), ...)``.
    block_parameters: tuple[tuple[str, tuple[float, ...]], ...] = ()
    #: The seeded relative spread of per-block values (``spread:``).
    spread: Spread = Spread()
    #: Refinement by label (the ``refine`` section), or None for the grid only.
    refine: Refine | None = None

    @property
    def coupling(self) -> str:
        """Which blocks the coupling springs join (``chain``, the default, ``ring`` or ``all``)."""
        return self.coupling_key or "chain"

    @property
    def heterogeneous(self) -> bool:
        """Whether blocks may differ (a per-block list, or a fixed or swept spread)."""
        return blocks_may_differ(self.block_parameters, self.spread, self.axes)

    @property
    def nblock_outputs(self) -> bool:
        """Whether results carry the N-block outputs (``sync_order``,
        ``slip_participation``), i.e. whether there is more than one block."""
        return self.blocks > 1

    @property
    def features(self) -> tuple[str, ...]:
        """Which optional output groups a result has (``variables.Variable.feature``)."""
        linear = self.refine is not None and not self.refine.full_runs
        return output_features(
            self.blocks,
            self.heterogeneous,
            self.initial.ensemble,
            self.classification.events,
            self.catalogue.capacity,
            linear,
            self.catalogue.shear_modulus is not None,
        )

    @property
    def catalogue_slip_v_over_V(self) -> float:
        """The slip threshold v/V of the catalogue's events (its own, else the classification's)."""
        return self.catalogue.slip_v_over_V or self.classification.slip_v_over_V

    @property
    def members(self) -> int:
        """Runs per grid point (the ensemble size, or 1)."""
        return max(1, self.initial.ensemble)

    @property
    def fixed(self) -> dict[str, float]:
        """The fixed parameters as a dict (name → value, physical units)."""
        return dict(self.parameters)

    @property
    def shape(self) -> tuple[int, ...]:
        """The grid's shape (the length of each sweep axis, in order)."""
        return tuple(len(a.values) for a in self.axes)

    @property
    def run_shape(self) -> tuple[int, ...]:
        """The shape of the runs (the grid, then the ensemble members if any)."""
        return self.shape + ((self.members,) if self.initial.ensemble else ())


def blocks_may_differ(block_parameters, spread, axes):
    """Whether blocks may differ: per-block lists, or a fixed or swept spread."""
    return bool(block_parameters or spread.sizes) or any(a.name in SPREAD_AXES for a in axes)


def output_features(
    blocks, heterogeneous, ensemble, events, catalogue=0, linear=False, moment=False
):
    """The optional output groups (``variables.Variable.feature``) of a sweep of ``blocks``
    blocks, unequal or not, with an ``ensemble`` of starts, ``events`` kept per run, a
    ``catalogue`` of that many slip events per run, ``linear`` verdicts (a refinement's
    runs, ``refine.full_runs: false``) and the catalogue's seismic ``moment`` (its
    ``shear_modulus`` and ``block_area`` given)."""
    flags = (
        ("nblock", blocks > 1),
        ("heterogeneous", heterogeneous),
        ("ensemble", ensemble > 0),
        ("events", events > 0),
        ("catalogue", catalogue > 0),
        ("linear_verdicts", linear),
        ("moment", catalogue > 0 and moment),
    )
    return tuple(name for name, on in flags if on)


def required_parameters(blocks, model):
    """Parameter names a config must set (fixed or swept) for this model."""
    names = ["A", "B", "mu0", "V", "D0", "K_W"]
    if blocks > 1:
        names.append("k2_W")
    if model == "quasi-dynamic":
        names.append("eta_W")
    if model == "inertial":
        names.append("m_W")
    return names


def default_method(model, blocks=1, coupling="chain"):
    """The method a run of ``model`` gets when its config names none, for ``blocks``
    blocks coupled as ``coupling``: ``dop853``; the inertial model's ``rosenbrock``,
    and ``rosenbrock-structured`` from :data:`STRUCTURED_FROM` blocks on (the solve that
    costs less per step there). The parser stores it in the config, so a result's
    ``integrator_method`` is the method its runs used."""
    method = DEFAULT_METHODS.get(model, Integrator.method)
    if method in STRUCTURED_METHODS and blocks >= STRUCTURED_FROM.get(coupling, MAX_BLOCKS + 1):
        return STRUCTURED_METHODS[method]
    return method
