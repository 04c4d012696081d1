"""Progress: a bar on a terminal, plain periodic lines in logs, nothing when quiet."""

import fcntl
import io
import os
import pty
import re
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from sweep import progress as progress_module
from sweep.progress import Progress

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "configs" / "quick.yaml"


class Clock:
    """A stand-in for ``time.monotonic`` that moves only when told to (s)."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


@pytest.fixture
def clock(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_module.time, "monotonic", clock)
    return clock


def test_plain_lines_show_runs_rate_and_eta(clock):
    stream = io.StringIO()  # not a terminal
    p = Progress(10, desc="demo", stream=stream, interval=5.0)
    clock.now += 2.0
    p.update(2)  # before the interval: nothing printed
    clock.now += 3.0
    p.update(3)  # 5 runs in 5 s: 1 run/s, 5 left
    clock.now += 1.0
    p.update(5)  # the end is always printed
    p.close()
    assert stream.getvalue().splitlines() == [
        "demo: 5/10 runs (50%), 1.0 runs/s, elapsed 5.0 s, ETA 5 s",
        "demo: 10/10 runs (100%), 1.7 runs/s, elapsed 6.0 s, ETA 0 s",
    ]


def test_resumed_runs_count_as_done_but_not_in_the_rate(clock):
    stream = io.StringIO()
    p = Progress(10, desc="demo", stream=stream, interval=0.0, initial=6)
    clock.now += 2.0
    p.update(2)  # 2 runs in 2 s (the 6 resumed ones took no time now); 2 left
    assert stream.getvalue() == "demo: 8/10 runs (80%), 1.0 runs/s, elapsed 2.0 s, ETA 2 s\n"


def test_disabled_progress_prints_nothing():
    stream = io.StringIO()
    p = Progress(3, stream=stream, enabled=False, interval=0.0)
    p.update(3)
    p.close()
    assert stream.getvalue() == ""


def run_quick(tmp_path, stderr):
    return subprocess.Popen(
        [sys.executable, "-m", "sweep", "run", str(QUICK), "--out", str(tmp_path / "q.nc")],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=stderr,
    )


def test_cli_shows_a_bar_on_a_terminal(tmp_path):
    leader, follower = pty.openpty()
    # a terminal window of 24 rows x 100 columns (a fresh pty reports 0 x 0)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = run_quick(tmp_path, stderr=follower)
    os.close(follower)
    output = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # EIO: the sweep closed the terminal
            break
        if not chunk:
            break
        output += chunk
    os.close(leader)
    assert proc.wait(timeout=60) == 0
    text = output.decode(errors="replace")
    assert "\r" in text  # the bar redraws itself in place
    assert re.search(r"quick: 100%.*\| 9/9 \[\d\d:\d\d<\d\d:\d\d, +[\d.]+run/s\]", text), text


def test_cli_writes_plain_lines_to_a_pipe(tmp_path):
    proc = run_quick(tmp_path, stderr=subprocess.PIPE)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0
    text = err.decode()
    assert "\r" not in text
    assert re.search(r"^quick: 9/9 runs \(100%\), [\d.]+ runs/s, elapsed [\d.]+ s, ETA 0 s$",
                     text, re.M), text  # fmt: skip
