"""From a validated config to a :class:`Grid`: every system, as the kernels take it.

The grid is the Cartesian product of the sweep axes, flattened in C order (the
last axis varies fastest); with an initial-condition ensemble each grid point is
repeated for its members (the fastest index of all). Every run is one system; its
physical parameters become one row of dimensionless parameters (``layout.P_*``,
followed by per-block columns ``layout.B_*`` when blocks differ) and its initial
perturbation one row of initial state. A Grid is built once per run
(:func:`build_grid`) and handed on to the kernels and the Dataset.

Per-block parameters are made dimensionless with one reference D0 (the common
value, ``sweep/model/heterogeneity.py``): κ1_i = K_i D0/W, and block i's state evolves
at the rate factor D0/D0_i (ψ_i' = (D0/D0_i)(e^(−ψ_i) − e^ℓ_i)).
"""

import math
from dataclasses import dataclass

import numpy as np

from .. import codes
from ..kernels import layout
from ..model import heterogeneity, linear, physics


def physical_parameters(config, points=None):
    """Every physical parameter at every grid point, flattened (name → 1-D array).

    Parameters a config leaves out default to zero (k2_W, eta_W, m_W); the
    reference V0 is derived from Phi0 (V0 = D0/Phi0) or the other way round.
    Swept spread sizes appear as ``spread_<name>``; per-block lists by their common
    value (the mean). With an ensemble every grid point is repeated per member.
    ``points``: axis name → 1-D array of values, the points to take instead of the
    grid (e.g. those of a refinement, ``sweep/refine/lattice.py``), in order.
    """
    if points is None:
        mesh = np.meshgrid(*(np.asarray(a.values) for a in config.axes), indexing="ij")
        points = {a.name: m.ravel() for a, m in zip(config.axes, mesh, strict=True)}
    values = {a.name: np.asarray(points[a.name], float) for a in config.axes}
    n = values[config.axes[0].name].size
    if config.initial.ensemble:
        values = {k: np.repeat(v, config.members) for k, v in values.items()}
        n *= config.members
    for name, value in config.parameters:
        values[name] = np.full(n, value)
    for name in ("k2_W", "eta_W", "m_W"):
        values.setdefault(name, np.zeros(n))
    if "V0" not in values:
        values["V0"] = values["D0"] / values["Phi0"]
    if "Phi0" not in values:
        values["Phi0"] = values["D0"] / values["V0"]
    return values


def settings_array(config):
    """The kernels' settings array (``layout.S_*``), shared by all systems."""
    s = np.zeros(layout.N_SETTINGS)
    integ, cls = config.integrator, config.classification
    s[layout.S_MODEL] = codes.code(codes.MODELS, config.model)
    s[layout.S_LAW] = codes.code(codes.STATE_LAWS, config.state_law)
    s[layout.S_METHOD] = codes.code(codes.METHODS, integ.method)
    s[layout.S_NBLOCKS] = config.blocks
    s[layout.S_RTOL] = integ.rtol
    s[layout.S_ATOL] = integ.atol
    s[layout.S_MAX_STEPS] = integ.max_steps
    s[layout.S_LNV_CAP] = math.log(cls.v_cap_over_V)
    s[layout.S_STEADY_AMP] = cls.steady_amplitude
    s[layout.S_ACCURACY] = cls.accuracy
    s[layout.S_CONFIRM_CYCLES] = cls.confirm_cycles
    s[layout.S_EARLY_EXIT] = 1.0 if cls.early_exit else 0.0
    s[layout.S_SLIP_LNV] = math.log(cls.slip_v_over_V)
    s[layout.S_COUPLING] = codes.code(codes.COUPLINGS, config.coupling)
    s[layout.S_LYAPUNOV] = codes.code(codes.LYAPUNOV_MODES, cls.lyapunov)
    s[layout.S_FLOQUET] = codes.code(codes.FLOQUET_MODES, cls.floquet)
    s[layout.S_EVENTS] = cls.events
    s[layout.S_CATALOGUE] = config.catalogue.capacity
    s[layout.S_CATALOGUE_AFTER] = config.catalogue.after
    s[layout.S_CATALOGUE_LNV] = math.log(config.catalogue_slip_v_over_V)
    refine = config.refine
    s[layout.S_LINEAR_VERDICTS] = 1.0 if refine is not None and not refine.full_runs else 0.0
    return s


@dataclass(frozen=True, eq=False)
class Grid:
    """Every system of ``config``: physical and dimensionless parameters, kernel arrays.

    ``physical``: name → 1-D array per system (physical units, see
    :func:`physical_parameters`); ``dimensionless``: ``physics.dimensionless`` of
    those (``time_unit`` = D0/V in s per system); ``blocks``: A, B, D0 and K_W of every
    block, (n, blocks) each (``heterogeneity.block_values``; empty where the blocks
    are equal by config); ``linear``: ``linear.theory`` per system; ``params`` (n,
    N_PARAMS [+ N_BLOCK_PARAMS × blocks]), ``y0`` (n, n_vars) and ``settings``
    (N_SETTINGS,): the kernels' arrays.
    """

    config: object
    physical: dict
    dimensionless: dict
    blocks: dict
    linear: dict
    params: np.ndarray
    y0: np.ndarray
    settings: np.ndarray

    @property
    def n(self):
        """Number of systems."""
        return self.params.shape[0]

    @property
    def time_unit(self):
        """D0/V in s, per system."""
        return self.dimensionless["time_unit"]

    def rows(self, index):
        """The grid of the systems ``index`` only (kernel arrays C-contiguous)."""
        pick = {name: values[index] for name, values in self.physical.items()}
        return Grid(
            self.config,
            pick,
            {name: values[index] for name, values in self.dimensionless.items()},
            {name: values[index] for name, values in self.blocks.items()},
            {name: values[index] for name, values in self.linear.items()},
            np.ascontiguousarray(self.params[index]),
            np.ascontiguousarray(self.y0[index]),
            self.settings,
        )


def build_grid(config, points=None):
    """The :class:`Grid` of a validated config, or of its ``points`` only (see
    :func:`physical_parameters`).

    With ``t_unit: s`` the end time is converted to units of D0/V per system;
    step sizes are always in D0/V.
    """
    phys = physical_parameters(config, points)
    dl = physics.dimensionless(
        phys["A"],
        phys["B"],
        phys["D0"],
        phys["V"],
        phys["K_W"],
        phys["k2_W"],
        phys["eta_W"],
        phys["m_W"],
    )
    blocks = heterogeneity.block_values(config, phys) if config.heterogeneous else {}
    n = phys["A"].size
    nb = config.blocks
    integ = config.integrator
    to_tau = 1.0 / dl["time_unit"] if integ.t_unit == "s" else np.ones(n)
    width = layout.N_PARAMS + (layout.N_BLOCK_PARAMS * nb if config.heterogeneous else 0)
    params = np.empty((n, width))
    params[:, layout.P_A] = dl["A"]
    params[:, layout.P_B] = dl["B"]
    params[:, layout.P_KAPPA1] = dl["kappa1"]
    params[:, layout.P_KAPPA2] = dl["kappa2"]
    params[:, layout.P_ETA] = dl["eta_hat"]
    params[:, layout.P_MASS] = dl["mass_hat"]
    params[:, layout.P_TAU_END] = integ.t_end * to_tau
    params[:, layout.P_DT] = integ.dt
    params[:, layout.P_MAX_STEP] = integ.max_step
    max_t_end = config.classification.max_t_end
    max_t_end = 10.0 * integ.t_end if max_t_end is None else max_t_end
    params[:, layout.P_TAU_MAX] = max_t_end * to_tau
    if config.heterogeneous:
        for k, values in enumerate(block_parameters(blocks, phys)):
            start = layout.N_PARAMS + k * nb
            params[:, start : start + nb] = values
    lin = linear.theory(config, phys, dl, blocks)
    params[:, layout.P_LIN_GROWTH] = lin["growth_rate"]
    y0 = initial_state(config, n, phys)
    return Grid(config, phys, dl, blocks, lin, params, y0, settings_array(config))


def block_parameters(values, phys):
    """Dimensionless per-block columns: (A_i, B_i, κ1_i, D0/D0_i), each (n, blocks),
    in the order of ``layout.B_*``, from the blocks' ``values``
    (``heterogeneity.block_values``) and the common ``phys``."""
    D0 = phys["D0"][:, None]
    return (values["A"], values["B"], values["K_W"] * D0, D0 / values["D0"])


def state_size(config):
    """State variables per system: ℓ and ψ per block, and z per block (inertial model)."""
    return config.blocks * layout.values_per_block(codes.code(codes.MODELS, config.model))


def initial_state(config, n_systems, phys=None):
    """Initial log-form state of ``n_systems`` systems (rows) from the config's perturbation.

    ℓ_i = ln(v_i/V), ψ_i = ln(Φ_i/Φss); for the inertial model the spring force
    starts in balance with friction: inertial force z_i = 0 (zero acceleration).
    Where the start is swept (``physics.INITIAL_AXES``; their values per system in
    ``phys``, :func:`physical_parameters`), the blocks of ``initial.kicked_blocks`` (all
    if empty) start from the axis's value. With an ensemble, member m adds the m-th of
    the random offsets (:func:`ensemble_offsets`) at every grid point.
    """
    nb = config.blocks
    ini = config.initial
    lnv = np.broadcast_to(np.log(np.asarray(ini.v_over_V, float)), (n_systems, nb))
    psi = np.broadcast_to(np.log(np.asarray(ini.phi_over_phi_ss, float)), (n_systems, nb))
    columns = [lnv, psi]
    kicked = list(ini.kicked_blocks) or slice(None)
    for k, name in enumerate(physics.INITIAL_AXES):
        if phys is not None and name in phys:
            columns[k] = columns[k].copy()
            columns[k][:, kicked] = np.log(phys[name])[:, None]
    if config.initial.ensemble:
        offsets = np.tile(ensemble_offsets(config), (n_systems // config.members, 1))
        columns = [columns[0] + offsets[:, :nb], columns[1] + offsets[:, nb:]]
    if config.model == "inertial":
        columns.append(np.zeros((n_systems, nb)))
    return np.ascontiguousarray(np.concatenate(columns, axis=1))


def ensemble_offsets(config):
    """Random offsets (members, 2 × blocks) of (ln v/V, ln Φ/Φss), uniform in ±amplitude,
    drawn once from ``initial.seed``: the same starts at every grid point."""
    ini = config.initial
    rng = np.random.default_rng(ini.seed)
    return rng.uniform(-ini.amplitude, ini.amplitude, (config.members, 2 * config.blocks))
