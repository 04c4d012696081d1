"""The package's exceptions: one base class, and one subclass per kind of trouble.

``InputError`` (and its ``ConfigError``) means the user can fix the call: the CLI
exits with status 2. ``RunError`` means the surroundings failed (disk, cluster,
another process): status 1. Both are importable as ``sweep.ConfigError`` and
``sweep.RunError``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable


class SweepError(Exception):
    """Base class of every error rsf-sweep raises on purpose.

    Catch it to handle any of them: :class:`InputError` (and its
    :class:`ConfigError`) for input the caller can fix, :class:`RunError` for
    trouble in the surroundings.
    """


class InputError(SweepError, ValueError):
    """Input that cannot be used: a path, a file, an argument.

    The message is one line per problem, each ``"<source>: <problem>"``; the CLI
    prints it and exits with status 2.

    Parameters
    ----------
    source : str or os.PathLike
        The file or argument the problems are about (kept as ``str``).
    problems : iterable of str
        Every reason, kept as a list.

    Attributes
    ----------
    source : str
        As given.
    problems : list of str
        As given.
    """

    def __init__(self, source: str | os.PathLike, problems: Iterable[str]) -> None:
        self.source = str(source)
        self.problems = list(problems)
        super().__init__("\n".join(f"{self.source}: {p}" for p in self.problems))


class ConfigError(InputError):
    """A config that cannot be run; ``problems`` lists every reason.

    Each problem names the key path, what is allowed and what was found, e.g.
    ``parameters.A must be in (0, inf), got -0.01``.

    Parameters
    ----------
    source : str or os.PathLike
        The config's file, ``"<mapping>"`` or ``"<config>"``.
    problems : iterable of str
        Every problem of the config.
    """


class RunError(SweepError, RuntimeError):
    """A sweep stopped by its surroundings (disk, cluster), not by its input.

    The CLI prints the message and exits with status 1; an earlier result file is
    left as it was.

    Parameters
    ----------
    message : str
        What failed, and where.
    """


class Interrupted(RunError):
    """A sweep stopped by a signal; the finished chunks are kept as parts."""

    def __init__(self, signum, message):
        self.signum = int(signum)
        super().__init__(message)


class OutputBusy(RunError):
    """Another process holds the lock of the output; the message names it."""


class PartError(SweepError, ValueError):
    """A part file that cannot be used; the message says why."""
