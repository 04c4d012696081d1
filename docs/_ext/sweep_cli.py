"""The command-line reference, generated from the argument parser (``sweep.cli.build_parser``).

The directive ``{sweep-cli}`` writes one section per subcommand: what it does, its
usage line as argparse prints it, and every argument as a ``std:option`` entry
(``{option}`` directives under ``{program}``), so the search box and the index find
each option and ``{option}`` roles link to it. Nothing is written by hand, so a new
subcommand or option appears here as soon as the parser has it.
"""

import argparse

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


def option_text(action):
    """The help of an argument, with its choices, how often it may be given and its default."""
    text = (action.help or "").replace("%(default)s", str(action.default))
    text = text[:1].upper() + text[1:]
    extra = []
    if action.choices and not isinstance(action, argparse._SubParsersAction):
        extra.append("one of " + ", ".join(f"`{c}`" for c in action.choices))
    if action.nargs in ("+", "*"):
        extra.append("one or more" if action.nargs == "+" else "any number")
    if isinstance(action, argparse._AppendAction):
        extra.append("may be repeated")
    if action.required and action.option_strings:
        extra.append("required")
    stated = "default" in text
    if action.option_strings and action.default not in (None, False, [], "") and not stated:
        extra.append(f"default `{action.default}`")
    text = text.rstrip(".")
    return f"{text} ({'; '.join(extra)})." if extra else f"{text}."


def exclusive_note(parser):
    """A sentence naming options that exclude each other, if any."""
    notes = []
    for group in parser._mutually_exclusive_groups:
        flags = [a.option_strings[0] for a in group._group_actions]
        notes.append(" and ".join(f"`{f}`" for f in flags) + " exclude each other.")
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
            lines += [f"## `{name}`", "", f"{help_text[:1].upper()}{help_text[1:]}.", ""]
            if sub.description:
                lines += [sub.description, ""]
            lines += ["```text", usage(sub), "```", ""]
            lines += ["```{program} " + f"{PROG} {name}", "```", ""]
            for action in sub._actions:
                if isinstance(action, argparse._HelpAction):
                    continue
                lines += ["```{option} " + option_name(action), option_text(action), "```", ""]
            if exclusive_note(sub):
                lines += [exclusive_note(sub), ""]
        return self.parse_text_to_nodes("\n".join(lines), allow_section_headings=True)


def setup(app):
    app.add_directive("sweep-cli", CommandLine)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
