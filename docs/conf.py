"""Sphinx configuration of the rsf-sweep documentation (``make docs``)."""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT))

import sweep  # noqa: E402

project = "rsf-sweep"
author = "rsf-sweep authors"
copyright = "rsf-sweep authors, MIT licence"
release = sweep.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx_gallery.gen_gallery",
    "sweep_reference",
    "sweep_cli",
    "sweep_citation",
    "sweep_mathml",
    "sweep_landing",
    "sweep_scraper",
    "sweep_codewrap",
    "sweep_figures",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "README.md", "auto_examples/*.ipynb", "**/*.codeobj.json"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# The API reference: one page per public name of sweep/__init__.py (sweep.__all__).
# Types are in the signatures (annotations; one parameter a line when long) and in
# the numpydoc Parameters sections; tests/test_docstrings.py checks both.
autosummary_generate = True
templates_path = ["_templates"]
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "signature"
autodoc_typehints_format = "short"
python_maximum_signature_line_length = 88
autodoc_member_order = "bysource"
# {func} links name the function only: the guide writes the arguments after them
add_function_parentheses = False
napoleon_numpy_docstring = True
napoleon_google_docstring = False

# Math as MathML written at build time (docs/_ext/sweep_mathml.py): no MathJax script
# from a CDN, so equations render offline
html_math_renderer = "mathml"

# The gallery: examples/plot_*.py run at build time; their figures are captured by
# docs/_ext/sweep_scraper.py (the package draws without pyplot, so matplotlib's own
# scraper would see nothing)
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"gallery\.py|sync_notebooks\.py|__init__\.py",
    # the notebooks' first cell, as in examples/sync_notebooks.py (the committed ones)
    "first_notebook_cell": "%matplotlib inline",
    # a Figure as a cell's last line draws it in a notebook; here the scraper does
    "capture_repr": (),
    "image_scrapers": ("sweep_scraper",),
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "plot_gallery": "True",
    "within_subsection_order": "FileNameSortKey",
    # the execution-time pages load DataTables and Bootstrap from CDNs (unstyled
    # offline) and tell a reader nothing: not written
    "write_computation_times": False,
}

# Offline: no intersphinx, no remote images, no script or style from a CDN
html_theme = "furo"
html_title = f"rsf-sweep {release}"
html_static_path = ["_static"]
html_css_files = ["sweep.css"]
os.environ.setdefault("SWEEP_DOCS_BUILD", "1")
