"""Math typeset at build time as MathML, so that it needs no script, font or network.

Sphinx's default HTML math renderer, MathJax, loads its script from a CDN when the
page is viewed, so equations stay raw LaTeX offline. This renderer converts each
equation when the site is built, with docutils' own LaTeX-to-MathML converter
(``docutils.utils.math.latex2mathml``, already installed with Sphinx), and writes the
MathML into the page; every current browser draws MathML itself (MathML Core). An
equation the converter cannot read is a warning, which ``sphinx -W`` turns into an
error.
"""

import html

from docutils import nodes
from docutils.utils.math import MathError, latex2mathml
from sphinx.util import logging

logger = logging.getLogger(__name__)


#: Operators the converter writes with the default spacing of an infix operator, which
#: TeX does not give them: a solidus in ``K_c/W`` is set tight.
TIGHT = {
    "<mo>/</mo>": '<mo lspace="0" rspace="0">/</mo>',
    '<mo stretchy="false">/</mo>': '<mo stretchy="false" lspace="0" rspace="0">/</mo>',
}


def to_mathml(latex, node, block):
    """MathML of ``latex``; on a conversion error, a warning and the LaTeX as text."""
    try:
        mathml = latex2mathml.tex2mathml(latex, as_block=block)
    except MathError as exc:
        logger.warning("cannot typeset %r as MathML: %s", latex, exc, location=node)
        return f'<code class="math-error">{html.escape(latex)}</code>'
    for loose, tight in TIGHT.items():
        mathml = mathml.replace(loose, tight)
    return mathml


def visit_math(self, node):
    self.body.append(self.starttag(node, "span", "", CLASS="math notranslate"))
    self.body.append(to_mathml(node.astext(), node, block=False))
    self.body.append("</span>")
    raise nodes.SkipNode


def visit_displaymath(self, node):
    self.body.append(self.starttag(node, "div", CLASS="math notranslate"))
    if node.get("number"):
        self.body.append(f'<span class="eqno">({node["number"]})')
        self.add_permalink_ref(node, "Link to this equation")
        self.body.append("</span>")
    latex = node.astext()
    parts = [latex] if node.get("nowrap") else [p for p in latex.split("\n\n") if p.strip()]
    for part in parts:
        self.body.append(to_mathml(part, node, block=True))
    self.body.append("</div>\n")
    raise nodes.SkipNode


def setup(app):
    app.add_html_math_renderer("mathml", (visit_math, None), (visit_displaymath, None))
    return {"parallel_read_safe": True, "parallel_write_safe": True}
