"""Write the gallery's examples as Jupyter notebooks, without outputs.

    python examples/sync_notebooks.py          # examples/plot_*.py → examples/notebooks/*.ipynb

The notebooks are converted by sphinx-gallery's own converter, so they are the ones
the documentation offers for download. ``tests/test_notebooks.py`` checks that the
committed notebooks equal a fresh conversion and runs each in a Jupyter kernel.
"""

import copy
import json
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent
NOTEBOOKS = EXAMPLES / "notebooks"
#: The first cell of every notebook (docs/conf.py gives sphinx-gallery the same):
#: draws the Figures the package returns, which are made without pyplot.
FIRST_CELL = "%matplotlib inline"


def sources():
    """The gallery's example scripts, in order."""
    return sorted(EXAMPLES.glob("plot_*.py"))


def notebook_text(source):
    """The notebook of the example script ``source`` as JSON text (no outputs)."""
    from sphinx_gallery import gen_gallery
    from sphinx_gallery.notebook import jupyter_notebook
    from sphinx_gallery.py_source_parser import split_code_and_text_blocks

    conf = copy.deepcopy(gen_gallery.DEFAULT_GALLERY_CONF)
    conf["first_notebook_cell"] = FIRST_CELL
    _, blocks = split_code_and_text_blocks(str(source))
    notebook = jupyter_notebook(blocks, conf, source.parent)
    return json.dumps(notebook, indent=1, ensure_ascii=False, sort_keys=True) + "\n"


def main():
    NOTEBOOKS.mkdir(exist_ok=True)
    for source in sources():
        target = NOTEBOOKS / f"{source.stem}.ipynb"
        target.write_text(notebook_text(source))
        print("wrote", target.relative_to(EXAMPLES.parent))


if __name__ == "__main__":
    sys.exit(main())
