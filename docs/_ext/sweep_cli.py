"""The command-line reference, generated from the argument parser (``sweep.cli.build_parser``).

The directive ``{sweep-cli}`` writes one section per subcommand: what it does, its
usage line as argparse prints it, and every argument as a ``std:option`` entry
(``{option}`` directives under ``{program}``), so the search box and the index find
each option and ``{option}`` roles link to it. Nothing is written by hand, so a new
subcommand or option appears here as soon as the parser has it.
"""

import argparse
import re

from sphinx.util.docutils import SphinxDirective

#: What the reference calls the program (``rsf-sweep`` is the installed name).
PROG = "python -m sweep"


def subcommands(parser):
    """``[(name, help, subparser)]`` in the order the parser declares them."""
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    helps = {choice.dest: choice.help for choice in action._choices_actions}
    return [(name, helps.get(name, ""), sub) for name, sub in action.choices.items()]


def option_name(action):
    """What ``{option}`` declares: ``--out PATH``, ``--quiet``, or a positional's name."""
    if not action.option_strings:
        return action.metavar or action.dest
    if action.nargs == 0:
        return ", ".join(action.option_strings)
    metavar = action.metavar or action.dest.upper()
    if action.nargs == "?":
        metavar = f"[{metavar}]"
    return ", ".join(f"{flag} {metavar}" for flag in action.option_strings)


#: Pieces of help text that are code: a command (``python -m sweep run``,
#: ``rsf-sweep[zarr]``), an option (``--refine``), a file name with placeholders
#: (``results/<name>_trace_<at>.nc``), a name with an underscore or a dot
#: (``t_unit``, ``catalogue.capacity``), a file extension or ``./results``, and
#: ``NAME=VALUE``, and the tolerances ``rtol`` and ``atol``. Written as code spans, they
#: keep their ``--``, ``<…>`` and ``_``.
CODE = (
    r"python -m sweep(?: [a-z]+)?"
    r"|rsf-sweep(?:\[\w+\]| [a-z]+\b)?"
    r"|(?P<option>--[a-z][a-z-]*)"
    r"|[\w./-]*(?:<[a-z][a-z ]*>[\w./-]*)+"
    r"|\b[a-z]\w*_\w+\b|\b[a-z]{2,}(?:\.[a-z]{2,})+\b"
    r"|(?<![\w.])\.(?:nc|zarr|png|pdf|svg)\b|\./\w+"
    r"|\b\w+=[A-Z]+\b|\b[ar]tol\b"
)
#: Characters that Markdown or HTML would read as markup.
SPECIAL = re.compile(r"([\\`*_\[\]{}<>#+!|~$&])")


def escape(text):
    """Markdown (MyST) for plain text: each markup character backslash-escaped."""
    return SPECIAL.sub(r"\\\1", text)


def code(text):
    """A Markdown code span of ``text`` (its own backticks allowed)."""
    ticks = "`" * (max((len(m) for m in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{ticks}{pad}{text}{pad}{ticks}"


def output_variables():
    """The names of the output variables (``sweep.variables``), each an ``{outvar}`` entry."""
    from sweep.variables import VARIABLES

    return sorted((var.name for var in VARIABLES), key=len, reverse=True)


def markdown(text, options=()):
    """Help text as MyST Markdown that shows exactly that text: commands, options,
    file names and identifiers as code (an option of ``options``, the flags of the
    same subcommand, and an output variable as links to their entries), everything
    else escaped, so ``<name>`` is not an HTML tag and ``--refine`` not a dash."""
    variables = "|".join(output_variables())
    pattern = re.compile(rf"(?P<variable>\b(?:{variables})\b)|{CODE}")
    out, last = [], 0
    for match in pattern.finditer(text):
        out.append(escape(text[last : match.start()]))
        piece = match.group()
        if match.group("option") and piece in options:
            out.append("{option}" + code(piece))
        elif match.group("variable"):
            out.append("{outvar}" + code(piece))
        else:
            out.append(code(piece))
        last = match.end()
    out.append(escape(text[last:]))
    return "".join(out)


def sentence(text):
    """``text`` with a capital first letter and one full stop at the end."""
    text = text.strip().rstrip(".")
    return f"{text[:1].upper()}{text[1:]}."


def option_text(action, options=()):
    """The help of an argument, as Markdown, then its choices, how often it may be given,
    whether it is required and its default when the help does not state it."""
    help_text = (action.help or "").replace("%(default)s", str(action.default))
    text = markdown(sentence(help_text), options)
    extra = []
    if action.choices and not isinstance(action, argparse._SubParsersAction):
        extra.append("one of " + ", ".join(code(str(c)) for c in action.choices))
    if action.nargs in ("+", "*"):
        extra.append("one or more" if action.nargs == "+" else "any number")
    if isinstance(action, argparse._AppendAction):
        extra.append("may be repeated")
    if action.required and action.option_strings:
        extra.append("required")
    stated = "default" in help_text
    if action.option_strings and action.default not in (None, False, [], "") and not stated:
        extra.append(f"default {code(str(action.default))}")
    return f"{text} {sentence('; '.join(extra))}" if extra else text


def flags(parser):
    """Every option string of ``parser`` (what ``{option}`` can link to)."""
    return {flag for action in parser._actions for flag in action.option_strings}


def exclusive_note(parser):
    """A sentence naming options that exclude each other, if any."""
    notes = []
    for group in parser._mutually_exclusive_groups:
        first = [a.option_strings[0] for a in group._group_actions]
        notes.append(" and ".join("{option}" + code(f) for f in first) + " exclude each other.")
    return " ".join(notes)


def usage(parser):
    """The usage line argparse prints, wrapped at 88 characters."""
    parser.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=88)
    return parser.format_usage().strip().removeprefix("usage: ")


class CommandLine(SphinxDirective):
    """One section per subcommand of ``python -m sweep``, from the argument parser."""

    def run(self):
        from sweep.cli import build_parser

        parser = build_parser()
        parser.prog = PROG
        lines = []
        for name, help_text, sub in subcommands(parser):
            sub.prog = f"{PROG} {name}"
            options = flags(sub)
            lines += [f"## `{name}`", "", markdown(sentence(help_text), options), ""]
            if sub.description:
                lines += [markdown(sub.description, options), ""]
            lines += ["```text", usage(sub), "```", ""]
            lines += ["```{program} " + f"{PROG} {name}", "```", ""]
            for action in sub._actions:
                if isinstance(action, argparse._HelpAction):
                    continue
                entry = option_text(action, options)
                lines += ["```{option} " + option_name(action), entry, "```", ""]
            if exclusive_note(sub):
                lines += [exclusive_note(sub), ""]
        return self.parse_text_to_nodes("\n".join(lines), allow_section_headings=True)


def setup(app):
    app.add_directive("sweep-cli", CommandLine)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
