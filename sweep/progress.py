"""Progress reporting for long sweeps: a widget bar in a notebook, a bar on a terminal,
log lines elsewhere."""

import sys
import time
import warnings


class Progress:
    """Counts finished runs; shows runs done, runs/s and ETA.

    In a Jupyter kernel a ``tqdm.auto`` widget bar (needs ipywidgets: the ``notebook``
    extra); on a terminal a tqdm bar on stderr; otherwise (pipes, CI, batch logs, a
    kernel without ipywidgets) a plain line at most every ``interval`` seconds (s) and
    one at the end. A given ``stream`` is never replaced by a widget. ``enabled=False``
    prints nothing. ``initial``: runs already done before this session (e.g. read back
    from parts on resume); the rate counts only runs done now.
    """

    def __init__(self, total, desc="sweep", enabled=True, stream=None, interval=10.0, initial=0):
        self.total = int(total)
        self.initial = int(initial)
        self.done = self.initial
        self.desc = desc
        self.stream = stream if stream is not None else sys.stderr
        self.interval = interval
        self.enabled = enabled
        self._start = time.monotonic()
        self._last = self._start
        self._bar = None
        bar = None
        if enabled and stream is None and _jupyter_kernel():
            bar = _widget_bar()
        if bar is None and enabled and getattr(self.stream, "isatty", lambda: False)():
            from tqdm import tqdm as bar
        if bar is not None:
            self._bar = bar(
                total=self.total, desc=desc, unit="run", file=self.stream, initial=self.initial
            )

    def update(self, n):
        """Record ``n`` more finished runs."""
        self.done += n
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(n)
            return
        now = time.monotonic()
        if now - self._last >= self.interval or self.done >= self.total:
            self._last = now
            print(self.line(now), file=self.stream, flush=True)

    def line(self, now=None):
        """One plain progress line: done/total, percent, runs/s, ETA."""
        now = time.monotonic() if now is None else now
        elapsed = max(now - self._start, 1e-9)
        rate = (self.done - self.initial) / elapsed
        left = (self.total - self.done) / rate if rate > 0 else float("inf")
        pct = 100.0 * self.done / self.total if self.total else 100.0
        return (
            f"{self.desc}: {self.done}/{self.total} runs ({pct:.0f}%), "
            f"{rate:.1f} runs/s, elapsed {elapsed:.1f} s, ETA {left:.0f} s"
        )

    def close(self):
        """Finish the bar (it is left showing the final state)."""
        if self._bar is not None:
            self._bar.close()


def _jupyter_kernel():
    """Whether this process is a Jupyter kernel (ipykernel's shell is running)."""
    zmqshell = sys.modules.get("ipykernel.zmqshell")
    return zmqshell is not None and zmqshell.ZMQInteractiveShell.initialized()


def _widget_bar():
    """``tqdm.auto``'s bar class if it is the widget one, else None (no ipywidgets, for
    which tqdm warns once, or a Qt console or Spyder)."""
    from tqdm import TqdmExperimentalWarning
    from tqdm.notebook import tqdm as widget

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TqdmExperimentalWarning)
        from tqdm.auto import tqdm as auto
    return auto if issubclass(auto, widget) else None
