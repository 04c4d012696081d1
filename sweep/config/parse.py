"""YAML run configs: read, parsed once, validated completely, frozen.

:func:`load_config` and :func:`parse_config` turn a file, YAML text or a mapping into a
:class:`~sweep.config.schema.Config`; :func:`with_changes` and :func:`config_mapping` go
back to a mapping and again; :func:`range_values` is the one formula of range axes.
Every problem in a config is collected and reported together, each naming the
file, the key path, what is allowed and what was found, e.g.::

    configs/bad.yaml: parameters.A must be in (0, inf), got -0.01

Nothing downstream reads raw dicts: it gets a Config.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..codes import COUPLINGS, METHODS
from ..errors import ConfigError
from ..kernels.layout import N_EVENT_FIELDS
from ..model.heterogeneity import (
    DISTRIBUTIONS,
    PER_BLOCK,
    SEED_AXIS,
    SPREAD_AXES,
    SPREAD_PREFIX,
    spread_pattern,
)
from ..model.physics import INITIAL_AXES, MODELS, PARAMETERS, STATE_LAWS, interval_text
from .schema import (
    DEFAULT_MAX_STEPS,
    INT32_MAX,
    MAX_AXIS_POINTS,
    MAX_BLOCKS,
    MAX_CATALOGUE_BYTES,
    MAX_REFINE_LEVELS,
    MAX_RUNS,
    REFINE_ENSEMBLE_OUTPUTS,
    REFINE_OUTPUTS,
    TOP_LEVEL_KEYS,
    Axis,
    Catalogue,
    Classification,
    Config,
    Initial,
    Integrator,
    Refine,
    Spread,
    blocks_may_differ,
    default_method,
    output_features,
    required_parameters,
)

#: ``source`` of a config given as a mapping (no file): provenance says so.
MAPPING_SOURCE = "<mapping>"


class _Loader(yaml.SafeLoader):
    """YAML 1.1 loader that also reads ``1e6`` and ``1.0e-8`` as floats (YAML 1.2 style)
    and refuses a key given twice in one mapping (plain YAML keeps the last silently)."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag.endswith(":merge"):
                continue
            key = self.construct_object(key_node)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    f"key {key!r} is given twice in one mapping (first on line "
                    f"{seen[key] + 1}; YAML would keep only the last)",
                    key_node.start_mark,
                )
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _numeric(text):
    """Whether ``text`` is a string holding a number."""
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return isinstance(text, str)


class _Checker:
    """Collects problems while reading a raw mapping."""

    def __init__(self):
        self.problems = []

    def add(self, message):
        self.problems.append(message)

    def number(self, value, key, low=-math.inf, low_open=False, high=math.inf, high_open=False):
        """A finite real within bounds, or None after recording the problem."""
        close = ")" if high_open or high == math.inf else "]"
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}{close}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            hint = " (text, not a number: PyYAML's safe_load reads 1.0e6 as text)"
            self.add(f"{key} must be a number in {interval}, got {value!r}{hint * _numeric(value)}")
            return None
        value = float(value)
        if not math.isfinite(value):
            self.add(f"{key} must be a finite number in {interval}, got {value!r}")
            return None
        too_low = value <= low if low_open else value < low
        too_high = value >= high if high_open else value > high
        if too_low or too_high:
            self.add(f"{key} must be in {interval}, got {value:g}")
            return None
        return value

    def integer(self, value, key, low, high=INT32_MAX):
        """An integer in [low, high] (files store 32-bit integers), or None after
        recording the problem."""
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            self.add(f"{key} must be an integer in [{low}, {high}], got {value!r}")
            return None
        return value

    def choice(self, value, key, allowed):
        if not isinstance(value, Hashable) or value not in allowed:
            self.add(f"{key} must be one of {', '.join(map(str, allowed))}; got {value!r}")
            return None
        return value

    def mapping(self, value, key):
        if not isinstance(value, dict):
            self.add(f"{key} must be a mapping of keys to values, got {type(value).__name__}")
            return {}
        return value

    def unknown(self, mapping, key, allowed):
        for k in mapping:
            if k not in allowed:
                where = f"{key}.{k}" if key else str(k)
                self.add(f"unknown key {where}; allowed keys: {', '.join(allowed)}")

    def setting(self, value, key, kind, spec):
        """``value`` of a setting of type ``kind`` checked against its :class:`Setting`."""
        if kind is bool:
            if not isinstance(value, bool):
                self.add(f"{key} must be true or false, got {value!r}")
                return None
            return value
        if kind is str:
            return self.choice(value, key, spec.allowed)
        low, low_open, high, high_open = spec.bounds()
        if kind is int:
            return self.integer(value, key, int(low), INT32_MAX if math.isinf(high) else int(high))
        return self.number(value, key, low, low_open, high, high_open)

    def section(self, spec, prefix, cls, defaults, given=None):
        """Every setting of the dataclass ``cls`` read from ``spec`` (else ``defaults``)
        and checked; ``given`` holds settings already read (skipped here)."""
        values = dict(given or {})
        for f in dataclasses.fields(cls):
            if f.name not in values:
                value = spec.get(f.name, getattr(defaults, f.name))
                kind = type(f.default) if f.default is not None else float
                values[f.name] = self.setting(value, prefix + f.name, kind, f.metadata["setting"])
        return values

    def parameter(self, name, value, key):
        info = PARAMETERS[name]
        return self.number(value, key, low=info.low, low_open=info.low_open)


def load_config(config: str | os.PathLike | Mapping[str, Any] | Config) -> Config:
    """A validated :class:`Config` from a path, a packaged example's name, a mapping or a Config.

    Parameters
    ----------
    config : str, os.PathLike, Mapping or Config
        A YAML file; else, if no such file exists, the name of a packaged example
        (:func:`sweep.examples.names`, e.g. ``"quick"``); a mapping as the YAML would
        read (its ``source`` is ``"<mapping>"``); or a Config, returned as it is.

    Returns
    -------
    Config
        The validated config.

    Raises
    ------
    ConfigError
        The file cannot be read or the config is not valid (every problem listed).
    """
    if isinstance(config, Config):
        return config
    if hasattr(config, "data_vars"):  # an xarray Dataset is a Mapping too
        raise ConfigError(
            "<config>",
            [
                "a result Dataset is not a config; the config that made "
                "it is sweep.parse_config(ds.attrs['config_text'])"
            ],
        )
    if isinstance(config, Mapping):
        return parse_config(config)
    from .. import examples

    if not isinstance(config, (str, os.PathLike)) or not os.fspath(config):
        what = "an empty path" if isinstance(config, (str, os.PathLike)) else type(config).__name__
        raise ConfigError(
            "<config>",
            [
                f"a config must be a YAML file's path, a packaged "
                f"example's name, a mapping or a Config; got {what}"
            ],
        )
    path = Path(config)
    if not path.exists() and examples.is_example(str(config)):
        path = examples.path(str(config))
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        hint = f" (packaged examples: {', '.join(examples.names())})" if not path.exists() else ""
        raise ConfigError(path, [f"cannot read config: {exc.strerror or exc}{hint}"]) from None
    except UnicodeDecodeError:
        raise ConfigError(
            path,
            [
                "cannot read config: not UTF-8 text; a config is a YAML file "
                "(a result, .nc, is opened with xarray.open_dataset)"
            ],
        ) from None
    return parse_config(text, source=str(path))


def parse_config(config: str | Mapping[str, Any], source: str | None = None) -> Config:
    """Validate a config given as YAML text or as a mapping, not as a file.

    Parameters
    ----------
    config : str or Mapping
        YAML text, or a mapping as the YAML would read (numpy numbers and arrays
        are accepted; a mapping's ``config_text`` is its YAML).
    source : str, optional
        How error messages and provenance name it (default: ``"<config>"`` for
        text, ``"<mapping>"`` for a mapping).

    Returns
    -------
    Config
        The validated config.

    Raises
    ------
    ConfigError
        The text is not YAML, or the config is not valid (every problem listed,
        each naming its key, what is allowed and what was found).
    """
    if isinstance(config, Mapping):
        source = source or MAPPING_SOURCE
        raw = _plain(config)
        try:
            text = yaml.safe_dump(raw, sort_keys=False, allow_unicode=True)
        except yaml.YAMLError as exc:
            problem = f"config mapping holds a value YAML cannot store: {exc}"
            raise ConfigError(source, [problem]) from None
    elif isinstance(config, str):
        source = source or "<config>"
        text = config
        try:
            raw = yaml.load(text, Loader=_Loader)
        except yaml.YAMLError as exc:
            raise ConfigError(source, [f"not valid YAML: {exc}"]) from None
    else:
        raise ConfigError(
            source or "<config>",
            [f"a config must be YAML text or a mapping, got {type(config).__name__}"],
        )
    return _validate(raw, text, source)


def parse_stored_config(text: str, source: str, method: str | None = None) -> Config:
    """The config stored in a result (its ``config_text``), as the result's runs used it.

    A config that names no method gets the default of the version that ran it, which a
    later version may change (the inertial model's became ``rosenbrock-structured`` from
    :data:`STRUCTURED_FROM` blocks on): where the result's ``method`` (its
    ``integrator_method``) is not today's default, the config is read with ``method``
    named, so extending or auditing it integrates as its runs did. A config that names
    its method is read as it stands.

    Parameters
    ----------
    text : str
        The stored config (YAML text).
    source : str
        How error messages and provenance name it.
    method : str, optional
        The method the result's runs used (its ``integrator_method``); None: unknown.

    Returns
    -------
    Config
        The validated config, with ``method`` where it names none.

    Raises
    ------
    ConfigError
        The text is no longer a valid config.
    """
    config = parse_config(text, source)
    if method is None or method == config.integrator.method or method not in METHODS:
        return config
    raw = yaml.load(text, Loader=_Loader)
    if "method" in raw.get("integrator", {}):
        return config
    raw["integrator"] = {**raw.get("integrator", {}), "method": method}
    return parse_config(raw, source)


def _plain(value):
    """A config mapping with numpy scalars and arrays, tuples and Mappings made plain
    Python (what ``yaml.safe_dump`` and the checks expect)."""
    if type(value).__module__ == "numpy":
        value = value.tolist()  # numpy scalar or array → Python number or list
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _default_name(source):
    """A config's name when it gives none: its file's stem; ``sweep`` for a mapping."""
    return "sweep" if source.startswith("<") else Path(source).stem


def _validate(raw, text, source):
    """The checks of :func:`parse_config` on the parsed mapping ``raw``."""
    c = _Checker()
    if not isinstance(raw, dict):
        raise ConfigError(source, ["a config must be a YAML mapping of keys to values"])
    c.unknown(raw, "", TOP_LEVEL_KEYS)

    name = raw.get("name", _default_name(source))
    if not isinstance(name, str) or not name or any(ch in name for ch in "/\\ "):
        c.add(f"name must be a non-empty string without spaces or slashes, got {name!r}")
        name = "sweep"
    description = raw.get("description", "")
    if not isinstance(description, str):
        c.add(f"description must be a string, got {description!r}")
        description = ""
    if "blocks" not in raw:
        c.add("missing key blocks (number of blocks: 1, 2, or more for an open chain)")
    blocks = c.integer(raw.get("blocks", 1), "blocks", 1, MAX_BLOCKS) or 1
    model = c.choice(raw.get("model", "quasi-static"), "model", MODELS) or "quasi-static"
    coupling = _parse_coupling(c, raw, blocks)
    law = c.choice(raw.get("state_law", "aging"), "state_law", STATE_LAWS) or "aging"

    axes = _parse_sweep(c, raw)
    # every named axis counts as swept, valid or not: a bad axis is reported once, not
    # again as a missing parameter
    spec = raw.get("sweep")
    swept = {name for name in spec if name in PARAMETERS} if isinstance(spec, dict) else set()
    params, lists = _parse_parameters(c, raw, blocks, model, swept)
    spread = _parse_spread(c, raw, blocks, lists, axes)
    if model == "inertial":
        _check_mass(c, params, axes)
    initial = _parse_initial(c, raw, blocks)
    if initial.kicked_blocks and not any(a.name in INITIAL_AXES for a in axes):
        c.add(
            "initial.kicked_blocks names the blocks the sweep axes "
            f"{' and '.join(INITIAL_AXES)} set, but neither is swept"
        )
    _check_runs(c, axes, initial.ensemble)
    if not c.problems:
        _check_spread_values(c, params, spread, axes, blocks)
    integrator = _parse_integrator(c, raw, model, blocks, coupling)
    classification = _parse_classification(c, raw, integrator.t_end)
    catalogue = _parse_catalogue(c, raw, axes, initial)
    output = raw.get("output", f"results/{name}.nc")
    if not isinstance(output, str) or not output.endswith((".nc", ".zarr")):
        c.add(f"output must be a path ending in .nc (NetCDF) or .zarr (Zarr), got {output!r}")
        output = f"results/{name}.nc"
    heterogeneous = blocks_may_differ(lists, spread, axes)
    features = output_features(
        blocks,
        heterogeneous,
        initial.ensemble,
        classification.events,
        catalogue.capacity,
        moment=catalogue.shear_modulus is not None,
    )
    refine = _parse_refine(c, raw, axes, initial, blocks, model, features, output)
    if c.problems:
        raise ConfigError(source, c.problems)
    return Config(
        name=name,
        source=source,
        text=text,
        blocks=blocks,
        model=model,
        state_law=law,
        parameters=tuple(params.items()),
        axes=tuple(axes),
        initial=initial,
        integrator=integrator,
        classification=classification,
        output=output,
        catalogue=catalogue,
        description=description,
        coupling_key=coupling,
        block_parameters=tuple(lists.items()),
        spread=spread,
        refine=refine,
    )


def _start_values(values):
    """A start value of every block as written back: one number where the blocks share
    it, so a changed number of blocks starts each block there too; else the list."""
    return values[0] if len(set(values)) == 1 else list(values)


def config_mapping(config: Config) -> dict[str, Any]:
    """A :class:`Config` as the mapping it could be read from (every setting explicit).

    ``output`` is left out where it is the default ``results/<name>.nc``, so a
    renamed copy writes under its new name. Start values the blocks share are one
    number, so :func:`with_changes` of ``blocks`` alone keeps them.
    """
    raw = {
        "name": config.name,
        "description": config.description,
        "blocks": config.blocks,
        "model": config.model,
        "state_law": config.state_law,
        "parameters": {
            **dict(config.parameters),
            **{k: list(v) for k, v in config.block_parameters},
        },
        "sweep": {a.name: _axis_mapping(a) for a in config.axes},
        "initial": {
            "v_over_V": _start_values(config.initial.v_over_V),
            "phi_over_phi_ss": _start_values(config.initial.phi_over_phi_ss),
            **(
                {"kicked_blocks": list(config.initial.kicked_blocks)}
                if config.initial.kicked_blocks
                else {}
            ),
        },
        "integrator": dataclasses.asdict(config.integrator),
        "classification": dataclasses.asdict(config.classification),
    }
    if config.catalogue != Catalogue():
        raw["catalogue"] = dataclasses.asdict(config.catalogue)
    if config.coupling_key is not None:
        raw["coupling"] = config.coupling_key
    sp = config.spread
    if sp.sizes or sp != Spread():
        raw["spread"] = {**sp.sizes_dict, "distribution": sp.distribution, "seed": sp.seed}
        if any(a.name == SEED_AXIS for a in config.axes):
            del raw["spread"]["seed"]  # the seeds are the axis
    if config.initial.ensemble:
        ini = config.initial
        raw["initial"].update(ensemble=ini.ensemble, seed=ini.seed, amplitude=ini.amplitude)
    if config.refine is not None:
        refine = dataclasses.asdict(config.refine)
        raw["refine"] = {**refine, "outputs": list(refine["outputs"])}
    if config.output != f"results/{config.name}.nc":
        raw["output"] = config.output
    return raw


def _axis_mapping(axis):
    """An :class:`Axis` as the YAML gives it: its range, or the list of its values."""
    if not axis.span:
        return list(axis.values)
    scale, start, stop = axis.span
    return {"start": start, "stop": stop, "num": len(axis.values), "scale": scale}


def with_changes(
    config: str | os.PathLike | Mapping[str, Any] | Config,
    changes: Mapping[str, Any],
    source: str | None = None,
) -> Config:
    """``config`` with some values changed, validated again like a file.

    Parameters
    ----------
    config : str, os.PathLike, Mapping or Config
        The starting config (anything :func:`load_config` takes).
    changes : Mapping
        Nested like the YAML: e.g. ``{"integrator": {"t_end": 5000}, "parameters":
        {"A": 0.02}}``. Mappings are merged key by key; any other value replaces
        the old one; ``None`` removes the key (e.g. ``{"sweep": {"K_W": None},
        "parameters": {"K_W": 0.05}}`` fixes a swept parameter).
    source : str, optional
        How errors and provenance name the result (default: the starting
        config's source and the changed key paths).

    Returns
    -------
    Config
        The changed config, validated.

    Raises
    ------
    ConfigError
        ``changes`` is not a mapping, or the changed config is not valid (every
        problem listed; the source names the changed key paths).
    """
    config = load_config(config)
    if source is not None and not isinstance(source, str):
        raise TypeError(f"source must be a string naming the config, got {source!r}")
    if not isinstance(changes, Mapping):
        raise ConfigError(
            config.source,
            [f"changes must be a mapping like the YAML, got {type(changes).__name__}"],
        )
    keys = _key_paths(changes)
    source = source or f"{config.source} with changes to {', '.join(keys)}"
    return parse_config(_merged(config_mapping(config), _plain(changes)), source)


def _merged(base, changes):
    """``base`` with ``changes`` merged in (nested mappings key by key; None deletes)."""
    out = dict(base)
    for key, value in changes.items():
        if value is None:
            out.pop(key, None)
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merged(out[key], value)
        else:
            out[key] = value
    return out


def _key_paths(changes, prefix=""):
    """Dotted key paths of the leaves of a nested mapping, e.g. ``integrator.t_end``."""
    paths = []
    for key, value in changes.items():
        if isinstance(value, Mapping) and value:
            paths.extend(_key_paths(value, f"{prefix}{key}."))
        else:
            paths.append(f"{prefix}{key}")
    return paths


def _parse_sweep(c, raw):
    if "sweep" not in raw:
        c.add("missing key sweep (at least one axis, e.g. K_W: {start: 0.04, stop: 0.06, num: 21})")
        return []
    sweep = c.mapping(raw["sweep"], "sweep")
    if not sweep and isinstance(raw["sweep"], dict):
        c.add("sweep must name at least one axis")
    axes = []
    for name, spec in sweep.items():
        key = f"sweep.{name}"
        if name == SEED_AXIS:
            seeds = _seed_values(c, spec, key)
            if seeds is not None:
                axes.append(Axis(name, seeds))
            continue
        if name in SPREAD_AXES:
            values, span = _axis_values(c, spec, key, 0.0, False)
            if values is not None and all(
                c.number(v, f"{key}[{i}]", low=0.0) is not None for i, v in enumerate(values)
            ):
                axes.append(Axis(name, tuple(float(v) for v in values), span))
            continue
        if name in INITIAL_AXES:
            values, span = _axis_values(c, spec, key, 0.0, True)
            if values is not None and all(
                c.number(v, f"{key}[{i}]", low=0.0, low_open=True) is not None
                for i, v in enumerate(values)
            ):
                axes.append(Axis(name, tuple(float(v) for v in values), span))
            continue
        if name not in PARAMETERS:
            allowed = ", ".join((*PARAMETERS, *INITIAL_AXES, *SPREAD_AXES, SEED_AXIS))
            c.add(f"unknown sweep axis {key}; allowed: {allowed}")
            continue
        values, span = _axis_values(c, spec, key, PARAMETERS[name].low, PARAMETERS[name].low_open)
        if values is None:
            continue
        # each listed value checked as written (a range's ends were, by _axis_values:
        # an interval holds every point between its ends)
        listed = [] if isinstance(spec, dict) and "values" not in spec else values
        bad = [i for i, v in enumerate(listed) if c.parameter(name, v, f"{key}[{i}]") is None]
        if not bad:
            axes.append(Axis(name, tuple(float(v) for v in values), span))
    return axes


def _seed_values(c, spec, key):
    """The seeds of the axis ``spread_seed``: a list (or {values: [...]}) of distinct
    integers in [0, 2^31 - 1], as a tuple; None after a problem."""
    if isinstance(spec, dict) and set(spec) == {"values"}:
        spec = spec["values"]
    if not isinstance(spec, list) or not spec:
        c.add(
            f"{key} must be a non-empty list of distinct integers in [0, {INT32_MAX}] (seeds of "
            f"the spread's pattern, one realisation each), e.g. [1, 2, 3]; got {spec!r}"
        )
        return None
    seeds = [c.integer(v, f"{key}[{i}]", 0) for i, v in enumerate(spec)]
    if None in seeds:
        return None
    if len(set(seeds)) != len(seeds):
        twice = sorted({s for s in seeds if seeds.count(s) > 1})
        c.add(f"{key} must be distinct seeds; {', '.join(map(str, twice))} given more than once")
        return None
    return tuple(seeds)


def _n_runs(axes, ensemble):
    """Runs of a sweep over ``axes`` with ``ensemble`` members per grid point (0: none)."""
    return math.prod(len(a.values) for a in axes) * max(1, ensemble)


def _check_runs(c, axes, ensemble):
    """At most ``MAX_RUNS`` runs in the whole sweep, ensemble members included."""
    runs = _n_runs(axes, ensemble)
    if runs > MAX_RUNS:
        sizes = [f"{len(a.values)} {a.name}" for a in axes]
        sizes += [f"{ensemble} members"] if ensemble else []
        c.add(
            f"the sweep has {runs:.3g} runs ({' × '.join(sizes)}), more than {MAX_RUNS:.0e}: "
            "split it into several configs, or refine where the labels change (refine:)"
        )


def _axis_values(c, spec, key, low, low_open):
    """Values of one axis and its span (see :class:`Axis`): a list, {values: [...]}, or
    {start, stop, num[, scale]}; ``(None, ())`` after a problem. A range's ends are
    checked against the axis's lower bound ``low`` (open or not); listed values are
    checked by the caller, each under its own key."""
    if isinstance(spec, list):
        spec = {"values": spec}
    if not isinstance(spec, dict):
        c.add(f"{key} must be a list of values or a mapping with start/stop/num or values")
        return None, ()
    if "values" in spec:
        c.unknown(spec, key, ("values",))
        values = spec["values"]
        if not isinstance(values, list) or not values:
            c.add(f"{key}.values must be a non-empty list of numbers, got {values!r}")
            return None, ()
        numbers = [v for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if len(set(numbers)) != len(numbers):
            c.add(f"{key}.values must be distinct, got {values!r}")
            return None, ()
        return values, ()
    c.unknown(spec, key, ("start", "stop", "num", "scale"))
    missing = [k for k in ("start", "stop", "num") if k not in spec]
    if missing:
        c.add(f"{key} is missing {', '.join(missing)} (give start, stop and num, or values)")
        return None, ()
    start = c.number(spec["start"], f"{key}.start", low, low_open)
    stop = c.number(spec["stop"], f"{key}.stop", low, low_open)
    num = c.integer(spec["num"], f"{key}.num", 1, MAX_AXIS_POINTS)
    scale = c.choice(spec.get("scale", "linear"), f"{key}.scale", ("linear", "log"))
    if None in (start, stop, num, scale):
        return None, ()
    if num > 1 and start == stop:
        c.add(f"{key}: start and stop must differ when num > 1, got {start:g} twice")
        return None, ()
    if scale == "log" and (start <= 0 or stop <= 0):
        c.add(f"{key}: a log-scale axis needs start > 0 and stop > 0")
        return None, ()
    if num == 1:
        return [start], (scale, start, stop)
    values = range_values(scale, start, stop, np.arange(num), num - 1)
    return [float(v) for v in values], (scale, start, stop)


def range_values(
    scale: str, start: float, stop: float, k: np.ndarray, intervals: int
) -> np.ndarray:
    """Points ``k`` (an integer array) of the range from ``start`` to ``stop`` cut into
    ``intervals`` equal steps, linear or in log (``scale``).

    The one formula of range axes: the k-th of ``num`` values is point k of
    ``num - 1`` intervals, and point ``k * 2^L`` of ``(num - 1) * 2^L`` intervals is
    the same number bit for bit (both integers are scaled by a power of two), so a
    refined point has the value of a finer range's point.
    """
    k = np.asarray(k)
    if scale == "log":
        low, high = math.log(start), math.log(stop)
        flat = [math.exp(low + (high - low) * int(i) / intervals) for i in k.ravel()]
        return np.array(flat, float).reshape(k.shape)
    return start + (stop - start) * k.astype(float) / intervals


def _parse_parameters(c, raw, blocks, model, swept):
    if "parameters" not in raw:
        c.add("missing key parameters (A, B, mu0, V, D0, V0 or Phi0, K_W, ...)")
    given = c.mapping(raw.get("parameters", {}), "parameters")
    c.unknown(given, "parameters", tuple(PARAMETERS))
    params = {}
    lists = {}
    for name, value in given.items():
        if name in PER_BLOCK and isinstance(value, list):
            values = _block_list(c, name, value, blocks)
            if values is not None:
                lists[name] = values
                params[name] = math.fsum(values) / blocks  # the common value: the mean
        elif name in PARAMETERS:
            v = c.parameter(name, value, f"parameters.{name}")
            if v is not None:
                params[name] = v
    present = set(given) | swept
    for name in required_parameters(blocks, model):
        if name not in present:
            c.add(
                f"missing key parameters.{name} ({PARAMETERS[name].long_name}, "
                f"{PARAMETERS[name].units}, in {interval_text(name)}); give it or sweep it"
            )
    reference = [n for n in ("V0", "Phi0") if n in present]
    if len(reference) != 1:
        c.add(
            "parameters must give exactly one of V0 (um/s) or Phi0 (s), "
            f"the reference point of the friction law; got {reference or 'neither'}"
        )
    for name, needs in (("eta_W", "quasi-dynamic"), ("m_W", "inertial")):
        if name in present and model != needs:
            c.add(
                f"parameters.{name} only applies to model {needs}; this config's model is {model}"
            )
    if "k2_W" in present and blocks == 1:
        c.add("parameters.k2_W (coupling spring) needs blocks >= 2")
    for name in swept & set(given):
        c.add(f"parameters.{name} is also a sweep axis; give it in one place only")
    return params, lists


def _block_list(c, name, value, blocks):
    """A list of per-block values of parameter ``name`` → tuple, or None after a problem."""
    key = f"parameters.{name}"
    if len(value) != blocks:
        c.add(f"{key} must be one number or a list of {blocks} (one per block), got {value!r}")
        return None
    out = [c.parameter(name, v, f"{key}[{i}]") for i, v in enumerate(value)]
    return None if None in out else tuple(out)


def _parse_coupling(c, raw, blocks):
    """The ``coupling`` key (None when not given: an open chain)."""
    if "coupling" not in raw:
        return None
    coupling = c.choice(raw["coupling"], "coupling", COUPLINGS)
    if coupling == "ring" and blocks < 3:
        c.add(
            f"coupling ring needs blocks >= 3 (a ring of {blocks} is a chain); got blocks {blocks}"
        )
    elif coupling is not None and coupling != "chain" and blocks < 2:
        c.add(f"coupling {coupling} needs blocks >= 2, got blocks {blocks}")
    return coupling


def _parse_spread(c, raw, blocks, lists, axes):
    """The ``spread`` section: relative spread sizes of per-block values, distribution, seed."""
    swept = {a.name[len(SPREAD_PREFIX) :] for a in axes if a.name in SPREAD_AXES}
    seed_axis = next((a for a in axes if a.name == SEED_AXIS), None)
    if swept and blocks < 2:
        c.add(f"sweep.spread_{sorted(swept)[0]} (a spread between blocks) needs blocks >= 2")
    for name in sorted(swept & set(lists)):
        c.add(f"sweep.spread_{name} and a list parameters.{name}: give per-block values one way")
    if "spread" not in raw:
        _check_seed_axis(c, seed_axis, Spread(), axes, blocks)
        return Spread()
    spec = c.mapping(raw["spread"], "spread")
    c.unknown(spec, "spread", (*PER_BLOCK, "distribution", "seed"))
    if blocks < 2:
        c.add("spread (per-block values) needs blocks >= 2")
    sizes = {}
    for name in PER_BLOCK:
        if name not in spec:
            continue
        key = f"spread.{name}"
        s = c.number(spec[name], key, low=0.0)
        if name in lists:
            c.add(f"{key} and a list parameters.{name}: give per-block values one way")
        elif name in swept:
            c.add(f"{key} is also a sweep axis (sweep.spread_{name}); give it in one place only")
        elif s is not None:
            sizes[name] = s
    d = Spread()
    dist = c.choice(spec.get("distribution", d.distribution), "spread.distribution", DISTRIBUTIONS)
    seed = c.integer(spec.get("seed", d.seed), "spread.seed", 0)
    if seed_axis is not None and "seed" in spec:
        c.add(f"spread.seed is also a sweep axis (sweep.{SEED_AXIS}); give it in one place only")
    if None in (dist, seed):  # a problem was recorded: the config is rejected
        return d
    spread = Spread(tuple(sizes.items()), dist, seed)
    _check_seed_axis(c, seed_axis, spread, axes, blocks)
    return spread


def _check_seed_axis(c, seed_axis, spread, axes, blocks):
    """A seed axis needs a spread to draw: more than one block and a spread size > 0,
    fixed or swept (else every seed would run the same systems)."""
    if seed_axis is None:
        return
    if blocks < 2:
        c.add(f"sweep.{SEED_AXIS} (seeds of a spread between blocks) needs blocks >= 2")
        return
    sizes = [s for _, s in spread.sizes] + [
        v for a in axes if a.name in SPREAD_AXES for v in a.values
    ]
    if not any(s > 0 for s in sizes):
        c.add(
            f"sweep.{SEED_AXIS} draws realisations of the spread's pattern, but no spread "
            "size is above 0 (spread.<name> or sweep.spread_<name>, name one of "
            f"{', '.join(PER_BLOCK)}): every seed would run the same systems"
        )


def _check_spread_values(c, params, spread, axes, blocks):
    """Every per-block value a spread makes stays in its parameter's interval.

    The factor 1 + s ξ_i is checked at the largest spread size of the sweep, against
    the interval of the parameter (e.g. D0 in (0, inf)).
    """
    largest = dict(spread.sizes)
    seeds = [spread.seed]
    for a in axes:
        if a.name in SPREAD_AXES:
            largest[a.name[len(SPREAD_PREFIX) :]] = max(a.values)
        elif a.name == SEED_AXIS:
            seeds = a.values
    for seed in seeds:
        xi = spread_pattern(blocks, spread.distribution, seed)
        for name, s in largest.items():
            factors = 1.0 + s * xi[name]
            i = int(np.argmin(factors))
            info = PARAMETERS[name]
            if factors[i] < 0.0 or (info.low_open and factors[i] <= 0.0):
                where = (
                    f"sweep.spread_{name}" if name not in spread.sizes_dict else f"spread.{name}"
                )
                c.add(
                    f"{where} = {s:g} makes {name} of block {i} leave {interval_text(name)}: its "
                    f"factor 1 + s*xi = {factors[i]:.3g} (xi = {xi[name][i]:.3g}, "
                    f"{spread.distribution} pattern of seed {seed}); use a smaller spread or "
                    "another seed"
                )


def _check_mass(c, params, axes):
    """The inertial model divides by the mass: m_W = 0 is the quasi-static model."""
    where = [("parameters.m_W", [params["m_W"]])] if "m_W" in params else []
    where += [("sweep.m_W", a.values) for a in axes if a.name == "m_W"]
    for key, values in where:
        if min(values) <= 0.0:
            c.add(
                f"{key} must be in (0, inf) for model inertial, got {min(values):g} "
                "(m = 0 is model quasi-static)"
            )


def _per_block(c, value, key, blocks):
    """A positive finite scalar or list of ``blocks`` of them → tuple per block."""
    values = value if isinstance(value, list) else [value] * blocks
    if len(values) != blocks:
        c.add(f"{key} must be one number or a list of {blocks} (one per block), got {value!r}")
        return None
    out = [c.number(v, key, low=0.0, low_open=True) for v in values]
    return None if None in out else tuple(out)


def _parse_initial(c, raw, blocks):
    spec = c.mapping(raw.get("initial", {}), "initial")
    d = Initial()
    c.unknown(spec, "initial", tuple(Initial.__dataclass_fields__))
    v = _per_block(c, spec.get("v_over_V", d.v_over_V[0]), "initial.v_over_V", blocks)
    phi = spec.get("phi_over_phi_ss", d.phi_over_phi_ss[0])
    phi = _per_block(c, phi, "initial.phi_over_phi_ss", blocks)
    ensemble = c.integer(spec.get("ensemble", d.ensemble), "initial.ensemble", 0, MAX_RUNS)
    seed = c.integer(spec.get("seed", d.seed), "initial.seed", 0)
    amplitude = c.number(spec.get("amplitude", d.amplitude), "initial.amplitude", low=0.0)
    kicked = _kicked_blocks(c, spec.get("kicked_blocks", list(d.kicked_blocks)), blocks)
    if None in (v, phi, ensemble, seed, amplitude, kicked):  # a problem was recorded: rejected
        return d
    return Initial(v, phi, ensemble, seed, amplitude, kicked)


def _kicked_blocks(c, value, blocks):
    """``initial.kicked_blocks``: distinct block indices in [0, blocks) → sorted tuple."""
    key = "initial.kicked_blocks"
    if not isinstance(value, list):
        c.add(f"{key} must be a list of block indices (0 to {blocks - 1}), got {value!r}")
        return None
    out = [c.integer(v, f"{key}[{i}]", 0, blocks - 1) for i, v in enumerate(value)]
    if None in out:
        return None
    if len(set(out)) != len(out):
        c.add(f"{key} lists a block twice: {value!r}")
        return None
    return tuple(sorted(out))


def _parse_integrator(c, raw, model, blocks, coupling):
    spec = c.mapping(raw.get("integrator", {}), "integrator")
    method = default_method(model, blocks, coupling or "chain")
    chosen = spec.get("method", method)
    cap = DEFAULT_MAX_STEPS.get(chosen, math.inf) if isinstance(chosen, str) else math.inf
    defaults = Integrator(method=method, max_step=cap)
    c.unknown(spec, "integrator", tuple(Integrator.__dataclass_fields__))
    given = {}
    if spec.get("max_step", defaults.max_step) in (None, math.inf):  # no cap (.inf or null)
        given["max_step"] = math.inf
    values = c.section(spec, "integrator.", Integrator, defaults, given)
    if None in values.values():
        return defaults
    return Integrator(**values)


#: Classification keys of earlier versions and what replaced them.
RETIRED_CLASSIFICATION_KEYS = {
    "envelope_tolerance": "accuracy (relative accuracy of the extrapolated limit, default 1e-3)",
    "trend_cycles": "confirm_cycles (consecutive cycles a verdict must hold, default 2)",
}


def _parse_classification(c, raw, t_end):
    spec = c.mapping(raw.get("classification", {}), "classification")
    d = Classification()
    key = "classification."
    for old, new in RETIRED_CLASSIFICATION_KEYS.items():
        if old in spec:
            c.add(f"{key}{old} is no longer used; use {key}{new}")
    spec = {k: v for k, v in spec.items() if k not in RETIRED_CLASSIFICATION_KEYS}
    c.unknown(spec, "classification", tuple(Classification.__dataclass_fields__))
    given = {} if spec.get("max_t_end") is not None else {"max_t_end": None}  # 10 t_end
    values = c.section(spec, key, Classification, d, given)
    max_t_end, max_ok = values["max_t_end"], True
    if "max_t_end" not in given:
        max_ok = max_t_end is not None
        if max_ok and t_end is not None and max_t_end < t_end:
            c.add(
                f"{key}max_t_end must be at least integrator.t_end ({t_end:g}), got {max_t_end:g}"
            )
            max_ok = False
    if not max_ok or None in (v for k, v in values.items() if k != "max_t_end"):
        return d
    return Classification(**values)


def _parse_catalogue(c, raw, axes, initial):
    spec = c.mapping(raw.get("catalogue", {}), "catalogue")
    d = Catalogue()
    c.unknown(spec, "catalogue", tuple(Catalogue.__dataclass_fields__))
    optional = ("completeness", "slip_v_over_V", "shear_modulus", "block_area")
    given = {k: None for k in optional if spec.get(k) is None}
    values = c.section(spec, "catalogue.", Catalogue, d, given)
    if None in (v for k, v in values.items() if k not in optional):
        return d
    moment = [k for k in ("shear_modulus", "block_area") if spec.get(k) is not None]
    if len(moment) == 1:
        other = "block_area" if moment == ["shear_modulus"] else "shear_modulus"
        c.add(
            f"catalogue.{moment[0]} needs catalogue.{other} too (the seismic moment is "
            "shear_modulus x block_area x slip): give both or neither"
        )
        return d
    if any(values[k] is None for k in moment):  # given, but refused above
        return d
    runs = _n_runs(axes, initial.ensemble)
    size = values["capacity"] * runs * N_EVENT_FIELDS * 8
    if size > MAX_CATALOGUE_BYTES:
        c.add(
            f"catalogue.capacity {values['capacity']} over {runs} runs needs "
            f"{size / 2**30:.1f} GiB (at most {MAX_CATALOGUE_BYTES / 2**30:.0f}): keep fewer "
            "events per run or split the sweep"
        )
        return d
    return Catalogue(**values)


def _parse_refine(c, raw, axes, initial, blocks, model, features, output):
    """The ``refine`` section (None when not given): levels, run budget, outputs, rtol."""
    if raw.get("refine") is None:
        return None
    from ..variables import variables_for

    spec = c.mapping(raw["refine"], "refine")
    c.unknown(spec, "refine", tuple(Refine.__dataclass_fields__))
    d = Refine()
    problems = len(c.problems)
    levels = c.integer(spec.get("levels", d.levels), "refine.levels", 0, MAX_REFINE_LEVELS)
    rtol = c.number(spec.get("rtol", d.rtol), "refine.rtol", low=0.0, low_open=True)
    known = [v.name for v in variables_for(blocks, model, features)]
    outputs = _refine_outputs(c, spec, known, "ensemble" in features)
    max_runs = spec.get("max_runs", d.max_runs)
    if max_runs is not None:
        runs = _n_runs(axes, initial.ensemble)
        if c.integer(max_runs, "refine.max_runs", runs) is None:
            c.problems[-1] += f" (the {runs} runs of the grid come first)"
    if any(a.name == SEED_AXIS for a in axes):
        c.add(
            f"refine cannot split sweep.{SEED_AXIS}: seeds are realisations, not points of a "
            "range; refine one realisation per config (spread.seed), or sweep the seeds "
            "without refine"
        )
    split = [a for a in axes if len(a.values) > 1]
    if axes and not split:
        c.add("refine needs a sweep axis with at least two values (cells to split)")
    if isinstance(levels, int) and split:
        points = math.prod((len(a.values) - 1) * 2**levels + 1 for a in split)
        if points > 2**62:
            c.add(
                f"refine.levels = {levels} makes a finest grid of {points:.3g} points on these "
                "axes, more than 2^62 (its indices are 64-bit integers); give fewer levels"
            )
    if isinstance(output, str) and output.endswith(".zarr"):
        c.add(f"output {output}: a refined sweep is written as NetCDF; give a path ending in .nc")
    split_undecided = c.setting(
        spec.get("split_undecided", d.split_undecided), "refine.split_undecided", bool, None
    )
    full_runs = c.setting(spec.get("full_runs", d.full_runs), "refine.full_runs", bool, None)
    if len(c.problems) > problems:
        return d
    return Refine(levels, max_runs, outputs, rtol, split_undecided, full_runs)


def _refine_outputs(c, spec, known, ensemble):
    """``refine.outputs`` checked against the output variables ``known`` of this config."""
    default = REFINE_ENSEMBLE_OUTPUTS if ensemble else REFINE_OUTPUTS
    outputs = spec.get("outputs", list(default))
    if not isinstance(outputs, list) or not outputs:
        c.add(
            f"refine.outputs must be a non-empty list of output variables, e.g. "
            f"[{', '.join(default)}]; got {outputs!r}"
        )
        return None
    ok = True
    for i, name in enumerate(outputs):
        if name == "regime_fraction" and not ensemble:
            c.add(
                f"refine.outputs[{i}]: regime_fraction needs an initial-condition ensemble "
                "(initial.ensemble > 0)"
            )
            ok = False
        elif name not in known:
            c.add(
                f"refine.outputs[{i}] must be an output variable of this sweep, one of "
                f"{', '.join(known)}; got {name!r}"
            )
            ok = False
    if ok and len(set(outputs)) != len(outputs):
        c.add(f"refine.outputs must name each output once, got {outputs!r}")
        ok = False
    return tuple(outputs) if ok else None
