"""The documentation site covers the public API and every config key.

The output variables, parameters and integrator and classification settings are
listed on the site from their declarations in the code (docs/_ext/sweep_reference.py);
these tests catch what is written by hand: the API reference's list of names and the
entries of the config keys that have no declaration of their own.
"""

import dataclasses
import importlib
import re
import types
from pathlib import Path

import sweep
from sweep.config import Initial
from sweep.config.schema import TOP_LEVEL_KEYS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Config sections whose keys the site lists from the code (``{sweep-config-keys}``).
GENERATED_SECTIONS = {"parameters", "integrator", "classification", "catalogue", "refine"}


def autosummary_names(text):
    """Names listed in the autosummary blocks of a page (``currentmodule`` sweep)."""
    names = set()
    for block in re.findall(r".. autosummary::\n(?:   :.*\n)*\n((?:   \S.*\n)+)", text):
        names.update(line.strip() for line in block.splitlines())
    return names


def resolve(name):
    """The object ``sweep.<name>`` names (importing submodules on the way), or None if
    there is none."""
    obj = sweep
    for part in name.split("."):
        if hasattr(obj, part):
            obj = getattr(obj, part)
            continue
        if not isinstance(obj, types.ModuleType):
            return None
        try:
            obj = importlib.import_module(f"{obj.__name__}.{part}")
        except ImportError:
            return None
    return obj


def test_api_reference_lists_every_public_name():
    """docs/api.md documents every name of ``sweep.__all__`` and only names that exist
    (a name whose object was renamed or removed is reported)."""
    names = autosummary_names((DOCS / "api.md").read_text())
    assert set(sweep.__all__) <= names, set(sweep.__all__) - names
    assert [name for name in sorted(names) if resolve(name) is None] == []
    # the check finds a missing name, at the top level and in a submodule
    assert resolve("no_such_function") is None and resolve("dataset.no_such_function") is None


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


def float_literals(text):
    """Every number written in ``text`` (``2e-3``, ``0.002``, ``1e5``), as floats."""
    return {float(x) for x in re.findall(r"(?<![\w.])\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])", text)}


def stated_tolerances(bullet):
    """The tolerances a bullet says a test uses: "tested at 1e-4 and 1e-6", "tested at
    2 %" (as 0.02)."""
    found = []
    for phrase in re.findall(r"tested at ((?:[\d.]+(?:e-\d+)?(?: %)?(?:,| and| or)? ?)+)", bullet):
        for number, percent in re.findall(r"([\d.]+(?:e-\d+)?)( %)?", phrase):
            found.append(float(number) / 100 if percent else float(number))
    return found


def test_internals_tolerances_are_the_tests():
    """Each "tested at …" tolerance of docs/internals.md's test list is written in one of
    the test modules its bullet names, so a tolerance changed in a test cannot leave
    the page behind (the page quoted tolerances that had moved, issue 40)."""
    text = (DOCS / "internals.md").read_text()
    tests = text[text.index("## Tests") : text.index("## Numerical choices")]
    bullets = re.split(r"\n- ", tests)[1:]
    checked = 0
    for bullet in bullets:
        bullet = " ".join(bullet.split())
        files = set(re.findall(r"tests/(\w+\.py)", bullet))
        literals = set()
        for name in files:
            literals |= float_literals((ROOT / "tests" / name).read_text())
        for value in stated_tolerances(bullet):
            assert any(abs(value - x) <= 1e-12 * value for x in literals), (
                f"internals.md says a test in {sorted(files)} uses {value:g}: not in the tests"
            )
            checked += 1
    assert checked >= 10  # the page still states them


# --- the site as a reader finds it (issue 40) --------------------------------------------


def prose(page):
    """A page's text outside fenced code blocks."""
    out, fence = [], False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            fence = not fence
        elif not fence:
            out.append(line)
    return "\n".join(out)


def guide_pages():
    return [DOCS / "getting-started.md", *sorted((DOCS / "guide").glob("*.md")),
            DOCS / "physics.md"]  # fmt: skip


def test_the_guide_links_every_api_name_it_mentions():
    """A documented ``sweep.*`` name in the guide's prose is a link (``{func}`` or
    ``{class}`` role), not plain code, and every guide page links to the API."""
    documented = {f"sweep.{name}" for name in autosummary_names((DOCS / "api.md").read_text())}
    for page in guide_pages():
        text = prose(page)
        plain = re.findall(r"(?<![}\w])`(sweep\.[\w.]+)", text)
        named = [n for n in plain if n in documented or n.rsplit(".", 1)[0] in documented]
        assert not named, f"{page.name}: plain code, not a link: {named}"
        if page.parent.name == "guide":
            assert re.search(r"\{(func|class)\}`~?sweep\.", text), f"{page.name}: no API link"


def test_the_site_loads_nothing_from_a_cdn():
    """Math is MathML written at build time (no MathJax), sphinx-gallery writes no
    execution-time pages (they load DataTables and Bootstrap from CDNs), and every
    style sheet is served from the site."""
    conf = {"__file__": str(DOCS / "conf.py")}
    exec(compile((DOCS / "conf.py").read_text(), "conf.py", "exec"), conf)
    assert "sphinx.ext.mathjax" not in conf["extensions"]
    assert conf["html_math_renderer"] == "mathml" and "sweep_mathml" in conf["extensions"]
    assert conf["sphinx_gallery_conf"]["write_computation_times"] is False
    for css in conf["html_css_files"]:
        assert (DOCS / "_static" / css).is_file() and "//" not in css


def test_citing_page_is_linked_and_every_reference_is_complete():
    """The landing page, the physics page and its errata link the citing page; each
    reference of CITATION.cff but the seed paper has authors, a year and a DOI."""
    import yaml

    assert "citing.md" in (DOCS / "index.md").read_text()
    physics = (DOCS / "physics.md").read_text()
    errata = physics[physics.index("## Errata in the seed paper") :]
    assert "citing.md" in physics[: physics.index("## Errata")] and "citing.md" in errata
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    seed, *others = cff["references"]
    assert seed["authors"][0]["family-names"] == "Szkutnik"
    for ref in others:
        assert ref["authors"] and ref["year"] and ref["doi"].startswith("10."), ref["title"]


def test_cli_reference_lists_the_refine_options():
    """The command-line reference (docs/cli.md, generated by docs/_ext/sweep_cli.py from
    the parser) has ``run``'s refinement options as option entries, with their help."""
    import sys

    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        import sweep_cli
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    from sweep.cli import build_parser

    subs = {name: sub for name, _, sub in sweep_cli.subcommands(build_parser())}
    entries = {sweep_cli.option_name(a): sweep_cli.option_text(a) for a in subs["run"]._actions}
    assert "Refine where the labels change" in entries["--refine LEVELS"]
    assert "at most N runs" in entries["--max-runs N"]
    assert "guide/refinement.md" in (DOCS / "cli.md").read_text()
