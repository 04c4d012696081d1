"""The example configs that ship with the package (``rsf-sweep examples``).

Their one source is the repository's top-level ``configs/`` folder; ``pip
install`` copies it into the package as ``sweep/configs/`` (``pyproject.toml``:
``package-dir`` maps ``sweep.configs`` to ``configs``). An editable install or a
clone reads the repository folder itself.
"""

from pathlib import Path

_HERE = Path(__file__).resolve().parent


def folder():
    """The folder holding the example configs: ``sweep/configs`` when installed, else
    the repository's ``configs/``."""
    installed = _HERE / "configs"
    return installed if installed.is_dir() else _HERE.parent / "configs"


def names():
    """Names of the packaged example configs (file stems), sorted."""
    return sorted(p.stem for p in folder().glob("*.yaml"))


def is_example(name):
    """Whether ``name`` (e.g. ``"quick"`` or ``"quick.yaml"``) is a packaged example."""
    return Path(name).name == name and Path(name).stem in names()


def path(name):
    """Path of the packaged example ``name`` (``"quick"`` or ``"quick.yaml"``).

    Raises ``KeyError`` naming the examples there are.
    """
    if not is_example(name):
        raise KeyError(f"no packaged example {name!r}; examples: {', '.join(names())}")
    return folder() / f"{Path(name).stem}.yaml"


def describe(name, width=70):
    """First sentence of an example's ``description``, cut to ``width`` characters."""
    import yaml

    raw = yaml.safe_load(path(name).read_text())
    text = " ".join(str(raw.get("description", "")).split()) if isinstance(raw, dict) else ""
    first = text.split(". ")[0].rstrip(".")
    return first if len(first) <= width else first[: width - 1].rstrip() + "…"
