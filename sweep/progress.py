"""Progress reporting for long sweeps: a bar on a terminal, log lines elsewhere."""

import sys
import time


class Progress:
    """Counts finished runs; shows runs done, runs/s and ETA.

    On a terminal a tqdm bar on stderr; otherwise (CI, batch logs) a plain line
    at most every ``interval`` seconds (s) and one at the end. ``enabled=False``
    prints nothing. ``initial``: runs already done before this session (e.g.
    read back from parts on resume); the rate counts only runs done now.
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
        if enabled and getattr(self.stream, "isatty", lambda: False)():
            from tqdm import tqdm

            self._bar = tqdm(
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
        """Finish the bar (a terminal line is left showing the final state)."""
        if self._bar is not None:
            self._bar.close()
