"""The public API's docstrings follow numpydoc, so that the API reference renders them.

The API reference (docs/api.md) is generated from the docstrings by autodoc and
napoleon, which read numpydoc sections. A sentence such as "Raises ``ValueError`` for
…" written inside a Parameters or Returns section is rendered as a parameter or a
return value of that name, and ``sphinx -W`` cannot see it. These tests read every
documented name's docstring section by section, as numpydoc defines them (a section
title underlined with dashes; in Parameters, Returns and Raises an unindented line
starts an entry, ``name : type``, and its description is indented), and check:

- every public function has a summary, a Parameters section naming exactly the
  parameters of its signature (when it has any), a Returns section (unless it is
  annotated ``-> None``) and type annotations on every parameter and its return;
- no Returns entry is a sentence about errors, every Raises entry names an exception
  class, and no "Raises …" sentence stands outside a Raises section;
- a default stated in a parameter's type (``int, default 20``) is the signature's;
- every field of a documented dataclass is described (a ``#:`` comment, or an entry of
  its Parameters or Attributes section), and no property's docstring opens as
  napoleon would read as "type: description";
- every name of ``sweep.__all__`` and every public function of a documented module is
  on the API page, with ``read_result``, which the guide uses.
"""

import builtins
import dataclasses
import importlib
import inspect
import re
from pathlib import Path

import pytest
from sphinx.ext.napoleon import Config as NapoleonConfig
from sphinx.ext.napoleon.docstring import NumpyDocstring
from sphinx.pycode import ModuleAnalyzer
from test_docs_site import autosummary_names

import sweep
from sweep import errors

ROOT = Path(__file__).resolve().parents[1]
API_PAGE = ROOT / "docs" / "api.md"
#: Sections whose unindented lines are entries (numpydoc: "name : type").
ENTRY_SECTIONS = {"Parameters", "Returns", "Yields", "Raises", "Warns", "Attributes",
                  "Other Parameters", "Receives"}  # fmt: skip
#: Names the guide and examples use that must be on the API page as well.
REQUIRED_ON_PAGE = {"read_result", "write_netcdf", "compute_trace"}


def resolve(name):
    """The object ``sweep.<name>`` (``name`` may be dotted: ``examples.names``)."""
    obj = sweep
    for part in name.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            obj = importlib.import_module(f"{obj.__name__}.{part}")
    return obj


def documented_names():
    """The names the API page lists (``currentmodule`` sweep)."""
    return sorted(autosummary_names(API_PAGE.read_text()))


def documented_objects():
    """``[(name, object)]``: the API page's names, and the public functions of the
    modules among them (e.g. ``examples.names``)."""
    found = []
    for name in documented_names():
        obj = resolve(name)
        found.append((name, obj))
        if inspect.ismodule(obj):
            for attr, value in vars(obj).items():
                if inspect.isfunction(value) and not attr.startswith("_"):
                    if value.__module__ == obj.__name__:
                        found.append((f"{name}.{attr}", value))
    return found


def sections(doc):
    """``{title: [lines]}`` of a docstring (cleaned with inspect.cleandoc); the text
    before the first section is under ``""``."""
    lines = inspect.cleandoc(doc).splitlines()
    out, title, k = {"": []}, "", 0
    while k < len(lines):
        line = lines[k]
        underline = lines[k + 1] if k + 1 < len(lines) else ""
        if line.strip() and re.fullmatch(r"-{3,}", underline.strip()) and not line[0].isspace():
            title = line.strip()
            assert title not in out, f"section {title} twice"
            out[title] = []
            k += 2
            continue
        out[title].append(line)
        k += 1
    return out


def entries(lines):
    """``[(head, description)]`` of an entry section: an unindented line is a head
    (``name : type``, or a type alone in Returns), the indented lines below it its
    description."""
    found = []
    for line in lines:
        if not line.strip():
            continue
        if not line[0].isspace():
            found.append([line.strip(), ""])
        elif found:
            found[-1][1] += " " + line.strip()
        else:
            found.append(["", line.strip()])  # indented text before any head
    return [(head, text.strip()) for head, text in found]


def split_head(head):
    """``(name, type)`` of ``name : type``; ``(head, "")`` without a colon."""
    name, colon, kind = head.partition(" : ")
    return (name.strip(), kind.strip()) if colon else (head.strip(), "")


def signature_parameters(func):
    """``{name: Parameter}`` of a function's signature, ``*args`` as ``*args``."""
    params = {}
    for p in inspect.signature(func).parameters.values():
        if p.name in ("self", "cls"):
            continue
        star = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
        params[star + p.name] = p
    return params


def problems_of_function(name, func):
    """What is wrong with a function's docstring (a list of messages)."""
    doc = func.__doc__
    if not doc or not doc.strip():
        return [f"{name}: no docstring"]
    found = []
    parts = sections(doc)
    params = signature_parameters(func)
    unknown = set(parts) - ENTRY_SECTIONS - {"", "Notes", "Examples", "See Also", "References"}
    if unknown:
        found.append(f"{name}: unknown sections {sorted(unknown)}")
    summary = [line for line in parts[""] if line.strip()]
    if not summary:
        found.append(f"{name}: no summary line")
    found += free_raises(name, parts)

    documented = {}
    for head, text in entries(parts.get("Parameters", [])):
        for each in split_head(head)[0].split(","):
            documented[each.strip()] = (split_head(head)[1], text)
    fake = sorted(set(documented) - set(params))
    if fake:
        found.append(f"{name}: Parameters names what is not in the signature: {fake}")
    missing = sorted(set(params) - set(documented))
    if missing:
        found.append(f"{name}: parameters not documented: {missing}")
    for pname, (kind, _) in documented.items():
        stated = re.search(r"\bdefault:? (.+)$", kind)
        if stated and pname in params:
            default = params[pname].default
            if stated.group(1).strip() not in {repr(default), str(default)}:
                found.append(f"{name}: {pname} says default {stated.group(1)!r}, the "
                             f"signature has {default!r}")  # fmt: skip

    for pname, p in params.items():
        if p.annotation is inspect.Parameter.empty:
            found.append(f"{name}: parameter {pname} has no type annotation")
    returns = inspect.signature(func).return_annotation
    if returns is inspect.Signature.empty:
        found.append(f"{name}: no return annotation")
    if "Returns" not in parts and returns not in (None, "None"):
        found.append(f"{name}: no Returns section")
    for head, text in entries(parts.get("Returns", [])):
        for part in (head, text):
            if re.match(r"(Raises|Raise|Raised)\b", part):
                found.append(f"{name}: a Returns entry is about errors: {part[:60]!r}")
    found += raises_problems(name, parts)
    return found


def free_raises(name, parts):
    """'Raises …' sentences outside a Raises section (rendered as prose, or worse)."""
    found = []
    for title, lines in parts.items():
        if title == "Raises":
            continue
        text = " ".join(lines)
        if re.search(r"(^|[.;:]\s+|\s)Raises\s", " " + text):
            found.append(f"{name}: 'Raises …' written in the {title or 'summary'} text")
    return found


def raises_problems(name, parts):
    """Every Raises entry names an exception class (builtins or ``sweep.errors``)."""
    found = []
    for head, _ in entries(parts.get("Raises", [])):
        exc = getattr(errors, head, None) or getattr(builtins, head, None)
        if not (inspect.isclass(exc) and issubclass(exc, BaseException)):
            found.append(f"{name}: Raises entry is not an exception class: {head[:60]!r}")
    return found


def documented_fields(cls):
    """``{name: text}`` of a class's attributes with a ``#:`` doc comment (as autodoc
    reads them)."""
    analyzer = ModuleAnalyzer.for_module(cls.__module__)
    docs = analyzer.find_attr_docs()
    return {attr: "\n".join(lines) for (scope, attr), lines in docs.items()
            if scope == cls.__qualname__ and "".join(lines).strip()}  # fmt: skip


def napoleon_reads_a_type(doc):
    """Whether napoleon renders a property's docstring as "Type: …" (its first line
    split at a colon)."""
    text = str(NumpyDocstring(inspect.cleandoc(doc), NapoleonConfig(), what="property", name="p"))
    return ":type:" in text


def problems_of_class(name, cls):
    found = []
    if not cls.__doc__ or not cls.__doc__.strip():
        return [f"{name}: no docstring"]
    parts = sections(cls.__doc__)
    found += free_raises(name, parts)
    described = set()
    for title in ("Parameters", "Attributes"):
        for head, _ in entries(parts.get(title, [])):
            described.update(n.strip() for n in split_head(head)[0].split(","))
    if dataclasses.is_dataclass(cls):
        fields = {f.name for f in dataclasses.fields(cls)}
        comments = documented_fields(cls)
        missing = sorted(fields - described - set(comments))
        if missing:
            found.append(f"{name}: fields without a description: {missing}")
        for field, text in comments.items():
            if napoleon_reads_a_type(text):
                found.append(f"{name}.{field}: its #: comment opens as 'type: text' (napoleon "
                             "renders it as a type)")  # fmt: skip
        for f in dataclasses.fields(cls):
            if f.type in (object, "object") and f.name not in described:
                found.append(f"{name}: field {f.name} has neither a type nor an entry")
    elif "__init__" in vars(cls):
        params = signature_parameters(cls.__init__)
        fake = sorted(described - set(params) - set(vars(cls)))
        attrs = {split_head(h)[0] for h, _ in entries(parts.get("Attributes", []))}
        fake = [f for f in fake if f not in attrs]
        if fake:
            found.append(f"{name}: Parameters names what is not in the signature: {fake}")
        if set(params) - described:
            found.append(f"{name}: parameters not documented: {sorted(set(params) - described)}")
    for attr, value in vars(cls).items():
        if isinstance(value, property) and not attr.startswith("_"):
            if not value.__doc__:
                found.append(f"{name}.{attr}: property without a docstring")
            elif napoleon_reads_a_type(value.__doc__):
                found.append(f"{name}.{attr}: its docstring opens as 'type: text' (napoleon "
                             "renders it as a type)")  # fmt: skip
    return found


def problems_of(name, obj):
    if inspect.isclass(obj):
        return problems_of_class(name, obj)
    if inspect.ismodule(obj):
        doc = obj.__doc__ or ""
        return [] if doc.strip() else [f"{name}: module without a docstring"]
    return problems_of_function(name, obj)


@pytest.mark.parametrize(
    "name, obj", documented_objects(), ids=[n for n, _ in documented_objects()]
)
def test_docstring_follows_numpydoc(name, obj):
    """Each documented function and class: sections as numpydoc defines them, nothing
    that napoleon would render as a fake parameter, return value or type."""
    assert problems_of(name, obj) == []


def test_every_public_name_is_on_the_api_page():
    """``sweep.__all__``, and what the guide uses, are documented on the API page."""
    names = set(documented_names())
    assert set(sweep.__all__) <= names, set(sweep.__all__) - names
    assert REQUIRED_ON_PAGE <= names, REQUIRED_ON_PAGE - names


# --- the checks themselves -----------------------------------------------------------------


def _old_run(config, *, threads=None):
    """Run a sweep.

    Parameters
    ----------
    config : Config
        The config.
    threads : int, optional
        Threads.

    Returns
    -------
    xarray.Dataset
        The result.

    Raises ``ConfigError`` for a bad config and ``RunError`` when Dask is missing.
    """


def _old_with_changes(config: object, changes: dict) -> object:
    """A changed config.

    Parameters
    ----------
    config : Config
        The config.
    changes : Mapping
        The changes.

    Returns
    -------
    Config
        Raises :class:`ConfigError` naming every changed key that is not valid.
    """


def _old_plot_variable(ds: object, name: str) -> object:
    """Any variable.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep result.
    name : str
        The variable.

    Raises ``ValueError`` listing the valid names for an unknown ``name``.
    """


def _prose_only(ds: object, caption: str = "") -> object:
    """Phase diagram of a sweep result; returns the Figure. ``caption``: a title."""


def _wrong_default(ds: object, dpi: int = 150) -> object:
    """Save.

    Parameters
    ----------
    ds : object
        Anything.
    dpi : int, default 100
        Dots per inch.

    Returns
    -------
    object
        The path.
    """


class _Properties:
    """A class with a property."""

    @property
    def shape(self):
        """Grid shape: the length of each sweep axis, in order."""


@pytest.mark.parametrize(
    "func, expected",
    [
        (_old_run, "a Returns entry is about errors"),
        (_old_run, "no type annotation"),
        (_old_with_changes, "a Returns entry is about errors"),
        (_old_plot_variable, "Parameters names what is not in the signature"),
        (_old_plot_variable, "'Raises …' written in the Parameters text"),
        (_prose_only, "parameters not documented"),
        (_prose_only, "no Returns section"),
        (_wrong_default, "says default '100'"),
    ],
)
def test_the_checks_catch_what_the_site_garbled(func, expected):
    """The checks fail on the docstrings that were rendered wrongly (issue 40): a
    "Raises" sentence in Returns or Parameters, prose without sections."""
    assert any(expected in p for p in problems_of_function(func.__name__, func)), (
        problems_of_function(func.__name__, func)
    )


def test_the_checks_catch_a_property_read_as_a_type():
    assert napoleon_reads_a_type(_Properties.shape.__doc__)
    assert any("opens as 'type: text'" in p for p in problems_of_class("P", _Properties))


# --- statements beside the code, against the code (issue 40 §6) ---------------------------


def test_kernels_package_docstring_names_every_module_and_method():
    """sweep/kernels/__init__.py lists each module and subpackage of the package (it
    once listed three methods of four: the methods are now the registry's, and each
    method's module names its method first)."""
    from sweep import kernels
    from sweep.kernels.methods import MODULES

    doc = kernels.__doc__
    here = Path(kernels.__file__).parent
    modules = {p.stem for p in here.glob("*.py")} - {"__init__"}
    modules |= {p.parent.name for p in here.glob("*/__init__.py")}
    assert {m for m in modules if f"``{m}``" not in doc} == set()
    assert [m.__name__ for m in MODULES if not m.__doc__.startswith(f"{m.NAME}: ")] == []


def test_output_descriptions_state_the_classifiers_limits():
    """The numbers in the output schema's descriptions (written into every file) are the
    classifier's: the longest cycle it recognises and the events it keeps."""
    from sweep.config.schema import MAX_EVENTS
    from sweep.kernels.classify import state
    from sweep.variables import BY_NAME

    (longest,) = re.findall(r"no cycle of up to (\d+) events", BY_NAME["attractor"].description)
    assert int(longest) == state.MAX_CYCLE_EVENTS
    (kept,) = re.findall(r"the last events kept \(up to (\d+)\)",
                         BY_NAME["lnv_amplitude"].description)  # fmt: skip
    assert int(kept) == state.HISTORY == MAX_EVENTS
