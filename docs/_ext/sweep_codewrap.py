"""Code blocks whose long lines wrap with a hanging indent.

Code blocks wrap long lines (``_static/sweep.css``: a comment beside a command, a long
YAML value) rather than hide their ends off the side of the box. A wrapped line of a
single ``<pre>`` would restart at the box's left edge, whatever the line's indentation,
so the HTML highlighter here writes each line of a block as its own ``<span
class="line">`` with the column its continuation starts at as ``--hang``, which the
style sheet makes a hanging indent: under the comment of a line with code and a
comment beside it (the comment is what wraps), under the value of a ``key = value``
or ``key: value`` line (a BibTeX field, a YAML entry), otherwise two characters right
of the line's indentation. A word with a hyphen (``--resume``, ``rosenbrock-structured``)
is kept whole in a ``<span class="nobr">``: a browser would break it after the hyphen.
An unwrapped line looks as before, and copying a block still copies its text, line by
line.
"""

import html
import re

from pygments.formatters.html import HtmlFormatter

TAG = re.compile(r"<[^>]*>")
#: Where Pygments starts a comment (classes ``c``, ``c1``, ``cm``: any language's).
COMMENT = re.compile(r'<span class="c[1m]?">')
#: A line ``key = value`` or ``key: value``: the value's column.
KEY_VALUE = re.compile(r"\s*[\w.-]+\s*[=:]\s+(?=\S)")
#: A value further right than this does not set the hang (it would leave no room).
MAX_VALUE_COLUMN = 24
#: The tags of a piece of HTML, and a word (no space) with a hyphen in its text.
TAGS = re.compile(r"(<[^>]*>)")
HYPHENATED = re.compile(r"[^\s-]*(?:-+[^\s-]*)+")


def text(line_html):
    """The characters a piece of highlighted HTML shows."""
    return html.unescape(TAG.sub("", line_html))


def hang(line_html):
    """The column where a wrapped line of highlighted HTML continues: its comment's, if
    code comes before the comment; its value's, if it is ``key = value`` or ``key:
    value``; else its indentation's plus 2 (tabs count as one)."""
    comment = COMMENT.search(line_html)
    if comment:
        before = text(line_html[: comment.start()])
        if before.strip():
            return len(before)
    line = text(line_html)
    key = KEY_VALUE.match(line)
    if key and key.end() <= MAX_VALUE_COLUMN:
        return key.end()
    return len(line) - len(line.lstrip(" \t")) + 2


def keep_hyphenated_words(line_html):
    """Each word with a hyphen in the text of ``line_html`` wrapped in ``span.nobr``."""
    pieces = TAGS.split(line_html)
    for k in range(0, len(pieces), 2):  # the text between the tags
        pieces[k] = HYPHENATED.sub(
            lambda m: f'<span class="nobr">{m[0]}</span>' if m[0].strip("-") else m[0],
            pieces[k],
        )  # fmt: skip
    return "".join(pieces)


class HangingIndentFormatter(HtmlFormatter):
    """Pygments' HTML formatter with each source line in a ``<span class="line">``."""

    def wrap(self, source):
        return super().wrap(self._lines(source))

    @staticmethod
    def _lines(source):
        for is_line, piece in source:
            if is_line:
                words = keep_hyphenated_words(piece)
                piece = f'<span class="line" style="--hang: {hang(piece)}">{words}</span>'
            yield is_line, piece


def use_hanging_indent(app):
    for name in ("highlighter", "dark_highlighter"):
        highlighter = getattr(app.builder, name, None)
        if highlighter is not None and highlighter.dest == "html":
            highlighter.formatter = HangingIndentFormatter


def setup(app):
    app.connect("builder-inited", use_hanging_indent)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
