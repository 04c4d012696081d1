"""What a running sweep is told and what it gives back: a stop request set by a signal
(:class:`StopRequest`, :func:`stop_on_signals`) and the finished sweep
(:class:`SweepResult`)."""

import logging
import signal
from contextlib import contextmanager
from dataclasses import dataclass

log = logging.getLogger(__name__)


class StopRequest:
    """Set by a signal handler; the runner stops after the chunk that is running.

    ``signum`` is the signal received (``None`` until then); a second signal
    raises ``KeyboardInterrupt`` at once.
    """

    def __init__(self):
        self.signum = None

    def __bool__(self):
        return self.signum is not None

    def __call__(self, signum, frame):
        if self:
            raise KeyboardInterrupt
        self.signum = signum
        log.warning(
            "received %s: stopping after the chunks in progress (again to stop at once)",
            signal.Signals(signum).name,
        )


@contextmanager
def stop_on_signals(signums=(signal.SIGINT, signal.SIGTERM)):
    """Within the block, SIGINT/SIGTERM set the yielded :class:`StopRequest`.

    For command-line use: nothing is installed on import.
    """
    stop = StopRequest()
    old = {s: signal.signal(s, stop) for s in signums}
    try:
        yield stop
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


@dataclass
class SweepResult:
    """A finished sweep or shard.

    ``dataset``: the result (``None`` for a shard); ``path``: the NetCDF file
    written, or for a shard its parts folder; ``elapsed``: wall time (s);
    ``computed`` / ``reused``: runs integrated now / read back from parts;
    ``timings``: for a refinement, wall time (s) by activity (``sweep/engine/refined.py``).
    """

    dataset: object
    path: object
    elapsed: float
    computed: int = 0
    reused: int = 0
    timings: dict = None
