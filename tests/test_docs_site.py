"""The documentation site covers the public API and every config key.

The output variables, parameters and integrator and classification settings are
listed on the site from their declarations in the code (docs/_ext/sweep_reference.py);
these tests catch what is written by hand: the API reference's list of names and the
entries of the config keys that have no declaration of their own.
"""

import dataclasses
import re
from pathlib import Path

import sweep
from sweep.config import TOP_LEVEL_KEYS, Initial

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Config sections whose keys the site lists from the code (``{sweep-config-keys}``).
GENERATED_SECTIONS = {"parameters", "integrator", "classification", "refine"}


def autosummary_names(text):
    """Names listed in the autosummary blocks of a page (``currentmodule`` sweep)."""
    names = set()
    for block in re.findall(r".. autosummary::\n(?:   :.*\n)*\n((?:   \S.*\n)+)", text):
        names.update(line.strip() for line in block.splitlines())
    return names


def test_api_reference_lists_every_public_name():
    """docs/api.md documents every name of ``sweep.__all__`` (and only real names)."""
    names = autosummary_names((DOCS / "api.md").read_text())
    assert set(sweep.__all__) <= names, set(sweep.__all__) - names
    for name in names:
        obj = sweep
        for part in name.split("."):
            obj = getattr(obj, part, None) or __import__(f"{obj.__name__}.{part}", fromlist=["_"])
        assert obj is not None, name


def test_every_config_key_has_an_entry():
    """Each key the config parser accepts is a ``{confkey}`` entry of the configs page,
    or is listed there from the code (``{sweep-config-keys}``)."""
    text = (DOCS / "guide" / "configs.md").read_text()
    assert "```{sweep-config-keys}" in text
    entries = set(re.findall(r"^```\{confkey\} (\S+)", text, re.M))
    for key in TOP_LEVEL_KEYS:
        listed = key in entries or any(e.startswith(f"{key}.") for e in entries)
        assert listed or key in GENERATED_SECTIONS, f"no entry for config key {key}"
    for field in dataclasses.fields(Initial):
        assert f"initial.{field.name}" in entries, f"no entry for initial.{field.name}"
