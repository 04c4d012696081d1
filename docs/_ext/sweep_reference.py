"""Every config key and output variable as a searchable, indexed entry, read from the code.

``{confkey}`` and ``{outvar}`` are object types (each entry is found by the search box
and listed in the index); the directives ``{sweep-config-keys}`` and
``{sweep-output-variables}`` write one entry per model parameter, per integrator,
classification, catalogue and refine setting (the ``Setting``s of ``sweep.config.schema``)
and per output variable (``sweep.variables.VARIABLES``), so the reference cannot drift
from the code.
"""

import dataclasses
import math

from sphinx.util.docutils import SphinxDirective


def _yaml_value(value):
    """A default as a config would write it: ``1e-8``, ``1.0e+6``, ``3000``, ``.inf``,
    ``true``, ``D0/V`` (not Python's ``1e-08``, ``3000.0``, ``inf``, ``True``, ``'D0/V'``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        if value.is_integer() and abs(value) < 1e6:
            return str(int(value))
        mantissa, _, exponent = f"{value:g}".partition("e")
        if not exponent:
            return mantissa
        if exponent.startswith("+") and "." not in mantissa:
            mantissa += ".0"  # PyYAML reads 1e+6 as text, 1.0e+6 as a number
        return f"{mantissa}e{exponent[0]}{exponent[1:].lstrip('0')}"
    return str(value)


def _allowed_text(allowed):
    if allowed is None:
        return ""
    if isinstance(allowed, str):
        return f"allowed `{allowed}`"
    return "one of " + ", ".join(f"`{_yaml_value(choice)}`" for choice in allowed)


def _units_text(units):
    return "" if units in ("1", "") else f"in `{units}`"


def _entry(kind, name, parts, text):
    """One entry as a MyST directive (the pages that use these directives are Markdown)."""
    detail = "; ".join(p for p in parts if p)
    body = f"{text} ({detail})." if detail else f"{text}."
    return [f"```{{{kind}}} {name}", body, "```", ""]


class _Generated(SphinxDirective):
    """A directive whose Markdown is generated: :meth:`lines` gives it."""

    def run(self):
        return self.parse_text_to_nodes("\n".join(self.lines()))


class ConfigKeys(_Generated):
    """One ``confkey`` per model parameter and per integrator, classification, catalogue
    and refine setting."""

    def lines(self):
        from sweep.config.schema import Catalogue, Classification, Integrator, Refine
        from sweep.model import physics

        out = []
        for name, info in physics.PARAMETERS.items():
            parts = [_units_text(info.units), f"allowed `{physics.interval_text(name)}`"]
            text = f"{info.long_name[:1].upper()}{info.long_name[1:]}: fixed under "
            text += f"`parameters`, or swept under `sweep.{name}`"
            out += _entry("confkey", f"parameters.{name}", parts, text)
        sections = (("integrator", Integrator), ("classification", Classification),
                    ("catalogue", Catalogue), ("refine", Refine))  # fmt: skip
        for section, cls in sections:
            for field in dataclasses.fields(cls):
                spec = field.metadata["setting"]
                default = spec.default_text or f"`{_yaml_value(field.default)}`"
                parts = [_units_text(spec.units), _allowed_text(spec.allowed), f"default {default}"]
                text = spec.doc[:1].upper() + spec.doc[1:]
                out += _entry("confkey", f"{section}.{field.name}", parts, text)
        return out


class OutputVariables(_Generated):
    """One ``outvar`` per variable of the output schema."""

    def lines(self):
        from sweep.variables import VARIABLES

        out = []
        for var in VARIABLES:
            where = []
            if var.per_block:
                where.append("per block")
            if var.per_event:
                where.append("per event")
            if var.per_regime:
                where.append("per regime")
            if var.min_blocks > 1:
                where.append(f"with at least {var.min_blocks} blocks")
            if var.models:
                where.append("models " + ", ".join(var.models))
            if var.feature:
                where.append(f"{var.feature} results")
            parts = [_units_text(var.units), f"`{var.dtype}`", *where]
            text = f"*{var.long_name}*: {var.description}"
            out += _entry("outvar", var.name, parts, text)
        return out


def setup(app):
    app.add_object_type(
        "confkey", "confkey", objname="config key", indextemplate="pair: %s; config key"
    )
    app.add_object_type(
        "outvar", "outvar", objname="output variable", indextemplate="pair: %s; output variable"
    )
    app.add_directive("sweep-config-keys", ConfigKeys)
    app.add_directive("sweep-output-variables", OutputVariables)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
