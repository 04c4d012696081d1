"""The package's exceptions: one base class, and one subclass per kind of trouble.

``InputError`` (and its ``ConfigError``) means the user can fix the call: the CLI
exits with status 2. ``RunError`` means the surroundings failed (disk, cluster,
another process): status 1. Both are importable as ``sweep.ConfigError`` and
``sweep.RunError``.
"""


class SweepError(Exception):
    """Base class of every error rsf-sweep raises on purpose."""


class InputError(SweepError, ValueError):
    """Input that cannot be used: a path, a file, an argument; ``problems`` lists every
    reason, each printed after ``source`` (the file or argument it is about)."""

    def __init__(self, source, problems):
        self.source = str(source)
        self.problems = list(problems)
        super().__init__("\n".join(f"{self.source}: {p}" for p in self.problems))


class ConfigError(InputError):
    """A config that cannot be run; ``problems`` lists every reason."""


class RunError(SweepError, RuntimeError):
    """A sweep stopped by its surroundings (disk, cluster), not by its input."""


class Interrupted(RunError):
    """A sweep stopped by a signal; the finished chunks are kept as parts."""

    def __init__(self, signum, message):
        self.signum = int(signum)
        super().__init__(message)


class OutputBusy(RunError):
    """Another process holds the lock of the output; the message names it."""


class PartError(SweepError, ValueError):
    """A part file that cannot be used; the message says why."""
