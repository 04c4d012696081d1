"""The product: kernel statistics → a self-describing xarray.Dataset → NetCDF.

One dimension per sweep axis, named after the parameter, with CF ``units`` and
``long_name``; every fixed parameter a scalar coordinate with the same attributes
(so results that differ in it combine along it, e.g. ``xr.concat([a, b], "A")``);
data variables from the table in ``sweep/variables.py``; provenance (config text,
versions, creation time) in the attributes. Files follow CF-1.11 (checked with the
IOOS compliance checker in ``tests/test_dataset.py``) and are written to a
temporary name beside the target and renamed, so a failed write never replaces an
earlier result.
"""

import dataclasses
import datetime

import numpy as np
import xarray as xr

from .._version import __version__
from ..config import parse_stored_config
from ..errors import ConfigError, InputError
from ..model import heterogeneity, hopf
from ..model.physics import INITIAL_AXES, PARAMETERS
from ..variables import REGIMES, SCALES, VARIABLES, variable_attrs, variables_for
from .catalogue_statistics import (
    MAGNITUDE_CONVENTION,
    MAGNITUDE_EDGES,
    MOMENT_MAGNITUDE_CONVENTION,
    catalogue_fields,
)


def derived_fields(grid, results, y_final):
    """Every output variable as a flat array (per system, or per system × block).

    ``grid``: the :class:`~sweep.engine.grid.Grid` the kernels ran (its physical and
    dimensionless parameters); ``results``, ``y_final``: their outputs, one row per
    system of the grid.
    """
    from ..kernels import layout

    config, phys, time_unit = grid.config, grid.physical, grid.time_unit
    r = results
    nb = config.blocks
    V = phys["V"]
    lin = grid.linear
    growth, kc, omega = lin["growth_rate"], lin["kappa_c"], lin["omega"]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # the variables read from one column of the kernels' results (their declaration)
        fields = {
            var.name: SCALES[var.scale](r[:, getattr(layout, var.column)], time_unit)
            for var in VARIABLES
            if var.column
        }
        events, period = fields["cycle_events"], fields["period"]
        fields |= {
            "lnv_amplitude": r[:, layout.R_LNV_MAX] - r[:, layout.R_LNV_MIN],
            "v_max": V * np.exp(r[:, layout.R_LNV_MAX]),
            "v_min": V * np.exp(r[:, layout.R_LNV_MIN]),
            "slip_per_event": np.where(events > 0, V * period / np.maximum(events, 1), np.nan),
            "cycle_decay_rate": np.log(1.0 / fields["floquet_modulus"]) / fields["floquet_period"],
            "lnv_final": y_final[:, :nb],
            "ln_state_final": y_final[:, nb : 2 * nb],
            "linear_growth_rate": growth / time_unit,
            "critical_K_W": kc / phys["D0"],
            "K_over_Kc": phys["K_W"] * phys["D0"] / kc,
            "onset_period": 2 * np.pi / omega * time_unit,
        }
    hopf_point = hopf.theory(config, phys, grid.dimensionless, grid.blocks, growth)
    fields |= {f"hopf_{name}": value for name, value in hopf_point.items()}
    m = config.classification.events
    if m:
        start = layout.N_RESULTS
        fields["event_lnv_peak"] = r[:, start : start + m]
        fields["event_interval"] = r[:, start + m : start + 2 * m] * time_unit[:, None]
    if config.catalogue.capacity:
        fields |= catalogue_fields(grid, results)
    if config.model == "inertial":
        fields["inertial_force_final"] = y_final[:, 2 * nb : 3 * nb]
    if config.heterogeneous:
        for name, values in grid.blocks.items():
            fields[f"{name}_block"] = values
    return fields


def trailing_length(config, dim):
    """Length of a variable's trailing dimension ``dim`` (``variables.Variable.dim``)."""
    if dim == "slip_event":
        return config.catalogue.capacity
    return len(MAGNITUDE_EDGES) - 1


def regime_fractions(regime):
    """Fraction of the members (last axis of ``regime``) in each regime: axis ``regime`` last."""
    return np.stack([(regime == k).mean(axis=-1) for k in range(len(REGIMES))], axis=-1)


#: CF citation of the model this package implements (the seed paper; no journal,
#: year or DOI is given in its text).
REFERENCES = (
    "J. Szkutnik and K. Kułakowski, Transition from Uniform Motion to Stick-Slip in the "
    "Rice-Ruina Model of One and Two Blocks, Department of Applied Computer Science, AGH "
    "University of Science and Technology, Kraków"
)


#: What the coordinate ``spread_seed`` is (its long name and description).
SEED_DESCRIPTION = "seed of the spread's pattern ξ; each value one realisation of the disorder"


def parameter_attrs(name):
    """CF attributes (``units``, ``long_name``) of the coordinate of model parameter ``name``
    or of a spread axis ``spread_<name>`` or ``spread_seed``."""
    if name == heterogeneity.SEED_AXIS:
        return {"units": "1", "long_name": SEED_DESCRIPTION, "description": SEED_DESCRIPTION}
    if name.startswith(heterogeneity.SPREAD_PREFIX):
        of = name[len(heterogeneity.SPREAD_PREFIX) :]
        return {"units": "1", "long_name": f"relative spread of {of} between blocks"}
    info = PARAMETERS.get(name) or INITIAL_AXES[name]
    return {"units": info.units, "long_name": info.long_name}


def axis_coordinate(name, values):
    """The values of sweep axis ``name`` as its coordinate: seeds as int32, else floats."""
    return np.asarray(values, np.int32 if name == heterogeneity.SEED_AXIS else float)


def parameter_coords(config):
    """Coordinates of a result: one per sweep axis (a dimension) and one scalar
    coordinate per fixed parameter, each with units and long name."""
    coords = {
        a.name: (a.name, axis_coordinate(a.name, a.values), parameter_attrs(a.name))
        for a in config.axes
    }
    for name, value in config.parameters:
        coords[name] = ((), value, parameter_attrs(name))
    coords["block"] = (
        "block",
        np.arange(config.blocks, dtype=np.int32),
        {"long_name": "block index", "units": "1"},
    )
    if config.classification.events:
        m = config.classification.events
        coords["event"] = (
            "event",
            np.arange(1 - m, 1, dtype=np.int32),
            {
                "long_name": "event counted back from the last (0: the last event of the run)",
                "units": "1",
            },
        )
    if config.catalogue.capacity:
        coords["slip_event"] = (
            "slip_event",
            np.arange(config.catalogue.capacity, dtype=np.int32),
            {"long_name": "slip event of the run's catalogue, in order of time", "units": "1"},
        )
        centres = (MAGNITUDE_EDGES[:-1] + MAGNITUDE_EDGES[1:]) / 2
        coords["magnitude"] = (
            "magnitude",
            centres,
            {
                "long_name": "centre of the magnitude bin (width 0.2; the end bins hold the events "
                "beyond)",
                "units": "1",
            },
        )
    if config.initial.ensemble:
        coords["member"] = (
            "member",
            np.arange(config.members, dtype=np.int32),
            {"long_name": "member of the initial-condition ensemble", "units": "1"},
        )
        coords["regime_name"] = ("regime_name", np.array(REGIMES), {"long_name": "regime"})
    return coords


def parameter_values(ds):
    """The model parameters of a result or trace that have one value: name → float
    (in the units of ``physics.PARAMETERS``). Reads the scalar coordinates, or the
    global attributes of files written before version 0.2."""
    values = {}
    for name in PARAMETERS:
        if name in ds.coords and ds[name].ndim == 0:
            values[name] = float(ds[name])
        elif name in ds.attrs and name not in ds.coords:
            values[name] = float(ds.attrs[name])
    return values


def build_dataset(grid, results, y_final, command="run"):
    """Assemble the result Dataset of a sweep from the kernels' outputs on ``grid``.

    ``command``: what made it, for ``history`` (see :func:`provenance`).
    """
    config = grid.config
    data_vars = data_variables(config, derived_fields(grid, results, y_final))
    ds = xr.Dataset(data_vars, coords=parameter_coords(config), attrs=provenance(config, command))
    return without_coordinate_fill(ds)


def without_coordinate_fill(ds):
    """``ds`` with no ``_FillValue`` on its coordinates when written (CF: coordinates
    hold no missing values), so a plain ``ds.to_netcdf`` writes a CF-clean file too."""
    for name in ds.coords:
        ds[name].encoding["_FillValue"] = None
    return ds


def data_variables(config, fields, shape=None, dims=None):
    """The data variables ``{name: (dims, data, attrs)}``, in the schema's dtypes, from the
    flat ``fields`` (as from :func:`derived_fields`) of the grid points of a block of
    ``shape`` (default: the whole grid), every ensemble member of each included.
    ``dims``: the dimensions of those points (default: the sweep axes; a refinement's
    points lie along one, ``("point",)``)."""
    shape = config.shape if shape is None else tuple(shape)
    run_shape = shape + config.run_shape[len(config.shape) :]
    dims = tuple(a.name for a in config.axes) if dims is None else tuple(dims)
    ensemble = config.initial.ensemble > 0
    run_dims = dims + (("member",) if ensemble else ())
    data_vars = {}
    for var in variables_for(config.blocks, config.model, config.features):
        attrs = variable_attrs(var)
        if var.per_regime:
            regime = fields["regime"].reshape(run_shape)
            data, var_dims = regime_fractions(regime), dims + ("regime_name",)
        else:
            block = (config.blocks,) if var.per_block else ()
            block += (config.classification.events,) if var.per_event else ()
            block += (trailing_length(config, var.dim),) if var.dim else ()
            data = fields[var.name].reshape(run_shape + block)
            var_dims = run_dims + (("block",) if var.per_block else ())
            var_dims += ("event",) if var.per_event else ()
            var_dims += (var.dim,) if var.dim else ()
            if ensemble and not var.per_member:  # the same for every member: the first
                data = data[(..., 0) + (slice(None),) * len(block)]
                var_dims = dims + var_dims[len(run_dims) :]
        if var.feature == "catalogue" and var.dtype == "int32":
            attrs["_FillValue"] = np.int32(-1)  # no event
        data_vars[var.name] = (var_dims, data.astype(var.dtype), attrs)
    return data_vars


COUPLING_TEXT = {
    "chain": "open chain, coupling spring k2 between neighbouring blocks",
    "ring": "ring, coupling spring k2 between neighbouring blocks and between the last and first",
    "all": "all pairs, coupling spring k2 between every pair of blocks",
}


def provenance(config, command="run"):
    """File attributes: model, settings, versions and where the config came from.

    ``command``: the CLI subcommand that made the file (``run``, ``merge``,
    ``trace``), or the Python function (``sweep.run``). ``history`` names it and
    the config's source: a file path, ``<mapping>`` for a config given as a
    mapping, or a derived config's description.
    """
    import numba

    integ, cls = config.integrator, config.classification
    if cls.max_t_end is None:  # written as the value it stands for
        cls = dataclasses.replace(cls, max_t_end=10.0 * integ.t_end)
    if command.startswith("sweep."):
        made_by = f"{command}() in Python from config {config.source}"
    else:
        made_by = f"python -m sweep {command} {config.source}"
    attrs = {
        "Conventions": "CF-1.11",
        "title": f"Rice-Ruina spring-block sweep: {config.name}",
        "source": f"rsf-sweep {__version__} (sweep package), numba {numba.__version__}",
        "references": REFERENCES,
        "history": f"{utc_now()} created by {made_by}",
        "created": utc_now(),
        "sweep_name": config.name,
        "description": config.description,
        "model": config.model,
        "state_law": config.state_law,
        "blocks": np.int32(config.blocks),
        "coupling": COUPLING_TEXT[config.coupling],
        "sweep_axes": " ".join(a.name for a in config.axes),
        "time_unit_note": "the dynamics scale with D0/V; times are stored in s",
        "initial_v_over_V": np.asarray(config.initial.v_over_V, float),
        "initial_phi_over_phi_ss": np.asarray(config.initial.phi_over_phi_ss, float),
        **settings_attrs("integrator", integ),
        **settings_attrs("classification", cls),
        **(catalogue_attrs(config) if config.catalogue.capacity else {}),
        "package_version": __version__,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "xarray_version": xr.__version__,
        **extra_provenance(config),
        "config_path": config.source,
        "config_text": config.text,
    }
    return attrs


def extra_provenance(config):
    """Attributes of the N-block options a config uses: spread pattern, ensemble."""
    attrs = {}
    if config.heterogeneous:
        attrs["spread_distribution"] = config.spread.distribution
        if all(a.name != heterogeneity.SEED_AXIS for a in config.axes):
            attrs["spread_seed"] = np.int32(config.spread.seed)  # else the coordinate
        for name, s in config.spread.sizes:
            attrs[f"spread_{name}"] = s
    if config.initial.ensemble:
        ini = config.initial
        attrs.update(
            initial_ensemble=np.int32(ini.ensemble),
            initial_seed=np.int32(ini.seed),
            initial_amplitude=ini.amplitude,
        )
    return attrs


def settings_attrs(section, settings):
    """File attributes ``<section>_<name>`` of every setting of an ``Integrator`` or
    ``Classification``, in their declared order: integers as int32 and booleans as int8
    (NetCDF has no bool)."""
    attrs = {}
    for field in dataclasses.fields(settings):
        value = getattr(settings, field.name)
        if isinstance(value, bool):
            value = np.int8(value)
        elif isinstance(value, int):
            value = np.int32(value)
        attrs[f"{section}_{field.name}"] = value
    return attrs


def catalogue_attrs(config):
    """File attributes ``catalogue_<name>`` of the catalogue's settings, its threshold as
    the value it stands for (a completeness of None, each run's smallest magnitude, is
    left out; so are a shear modulus and block area not given), and the magnitudes'
    conventions."""
    cat = dataclasses.replace(config.catalogue, slip_v_over_V=config.catalogue_slip_v_over_V)
    values = dataclasses.asdict(cat).items()
    attrs = {
        f"catalogue_{k}": np.int32(v) if isinstance(v, int) else v
        for k, v in values
        if v is not None
    }
    attrs["catalogue_magnitude_convention"] = MAGNITUDE_CONVENTION
    if cat.shear_modulus is not None:
        attrs["catalogue_moment_magnitude_convention"] = MOMENT_MAGNITUDE_CONVENTION
    return attrs


def utc_now():
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def stored_config(ds, source):
    """The :class:`~sweep.config.Config` stored in a result (``config_text``), with the
    method its runs used (``integrator_method``; :func:`~sweep.config.parse_stored_config`).

    ``source`` names the result file in errors; the Config keeps the original
    config path (``config_path``) as its source. Raises
    :class:`~sweep.errors.ConfigError` if the text is no longer a valid config,
    :class:`~sweep.errors.InputError` if its grid is not the file's.
    """
    try:
        config = parse_stored_config(
            ds.attrs["config_text"], f"{source} (config_text)", ds.attrs.get("integrator_method")
        )
    except ConfigError as exc:
        raise ConfigError(source, [f"stored config_text: {p}" for p in exc.problems]) from None
    if "point" in ds["regime"].dims and config.refine is not None:
        raise InputError(
            source,
            [
                "a refined result (its runs along point) is not a grid: extend and audit "
                "take grid results; sweep.to_grid(ds, level) gives one"
            ],
        )
    dims = tuple(a.name for a in config.axes) + (("member",) if config.initial.ensemble else ())
    if ds["regime"].dims != dims or ds["regime"].shape != config.run_shape:
        raise InputError(
            source,
            [
                f"regime has dims {dict(ds['regime'].sizes)}, but the stored config sweeps "
                f"{dict(zip(dims, config.run_shape, strict=True))}"
            ],
        )
    given = [(a.name, a.values) for a in config.axes] + [(k, (v,)) for k, v in config.parameters]
    differ = [
        name
        for name, values in given
        if name in ds.coords and not np.array_equal(np.atleast_1d(ds[name].values), values)
    ]
    if differ:
        raise InputError(
            source,
            [
                f"the file's {', '.join(differ)} differ from its stored config's "
                "(config_text): it was edited, sorted or cut after the run, so its runs "
                "can no longer be matched to their parameters"
            ],
        )
    return dataclasses.replace(config, source=ds.attrs.get("config_path", str(source)))
