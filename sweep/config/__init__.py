"""YAML run configs: what a config is (``schema.py``), and how a file or a mapping
becomes one, parsed once, validated completely, frozen (``parse.py``)."""

from ..errors import ConfigError
from .parse import (
    config_mapping,
    load_config,
    parse_config,
    parse_stored_config,
    range_values,
    with_changes,
)
from .schema import Axis, Catalogue, Classification, Config, Initial, Integrator, Refine, Spread

__all__ = [
    "Axis",
    "Catalogue",
    "Classification",
    "Config",
    "ConfigError",
    "Initial",
    "Integrator",
    "Refine",
    "Spread",
    "config_mapping",
    "load_config",
    "parse_config",
    "parse_stored_config",
    "range_values",
    "with_changes",
]
