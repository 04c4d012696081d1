"""The example configs that ship with the package (``rsf-sweep examples``).

Their one source is the repository's top-level ``configs/`` folder; ``pip
install`` copies it into the package as ``sweep/configs/`` (``pyproject.toml``:
``package-dir`` maps ``sweep.configs`` to ``configs``). An editable install or a
clone reads the repository folder itself.
"""

from pathlib import Path

_HERE = Path(__file__).resolve().parent


def folder() -> Path:
    """The folder holding the example configs.

    Returns
    -------
    pathlib.Path
        ``sweep/configs`` when installed, else the repository's ``configs/``.
    """
    installed = _HERE / "configs"
    return installed if installed.is_dir() else _HERE.parent / "configs"


def names() -> list[str]:
    """The names of the packaged example configs.

    Returns
    -------
    list of str
        The file stems (``"quick"``, ``"twoblock"``, …), sorted; each is a config
        :func:`sweep.run` and ``python -m sweep run`` accept.
    """
    return sorted(p.stem for p in folder().glob("*.yaml"))


def is_example(name: str) -> bool:
    """Whether ``name`` is a packaged example.

    Parameters
    ----------
    name : str
        A name such as ``"quick"`` or ``"quick.yaml"`` (no folder).

    Returns
    -------
    bool
        True if a packaged config of that name exists.
    """
    return Path(name).name == name and Path(name).stem in names()


def path(name: str) -> Path:
    """The path of a packaged example config.

    Parameters
    ----------
    name : str
        Its name, ``"quick"`` or ``"quick.yaml"``.

    Returns
    -------
    pathlib.Path
        The YAML file.

    Raises
    ------
    KeyError
        There is no such example (the message names the examples there are).
    """
    if not is_example(name):
        raise KeyError(f"no packaged example {name!r}; examples: {', '.join(names())}")
    return folder() / f"{Path(name).stem}.yaml"


def describe(name: str, width: int = 70) -> str:
    """The first sentence of an example's ``description``, for a listing.

    Parameters
    ----------
    name : str
        The example's name, as for :func:`path`.
    width : int, default 70
        Longest text returned, in characters (a longer sentence is cut, with "…").

    Returns
    -------
    str
        The sentence, without its full stop; empty without a description.

    Raises
    ------
    KeyError
        There is no such example.
    """
    import yaml

    raw = yaml.safe_load(path(name).read_text())
    text = " ".join(str(raw.get("description", "")).split()) if isinstance(raw, dict) else ""
    first = text.split(". ")[0].rstrip(".")
    return first if len(first) <= width else first[: width - 1].rstrip() + "…"
