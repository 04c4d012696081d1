"""Progress: a widget bar in a notebook, a bar on a terminal, plain periodic lines in
pipes and logs, nothing when quiet."""

import fcntl
import io
import json
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
from pathlib import Path
from types import SimpleNamespace

import nbformat
import pytest
from conftest import SUBPROCESS_TIMEOUT
from nbclient import NotebookClient

from sweep import progress as progress_module
from sweep.engine import runner
from sweep.engine.backends import Resources
from sweep.progress import Progress

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "configs" / "quick.yaml"
#: The MIME type of a Jupyter widget's view in a notebook's outputs.
WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


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


def test_default_interval_is_ten_seconds(clock):
    """The README's "a plain line every 10 s": by default nothing at 9.75 s after the
    last line, a line at 10 s (times exact in binary)."""
    stream = io.StringIO()
    p = Progress(100, desc="demo", stream=stream)
    for _ in range(2):
        clock.now += 9.75
        p.update(1)
        before = stream.getvalue().count("\n")
        clock.now += 0.25
        p.update(1)
        assert stream.getvalue().count("\n") == before + 1
    assert stream.getvalue().count("\n") == 2


def test_a_sweep_prints_every_ten_seconds(quick, tmp_path, monkeypatch, capsys):
    """run_sweep's progress (what the CLI shows in a pipe) with a clock that advances
    4 s each time progress reads it: lines after 12 s and 24 s, and the last one."""
    ticks = iter(range(0, 1000, 4))
    monkeypatch.setattr(progress_module, "time", SimpleNamespace(monotonic=lambda: next(ticks)))
    runner.run_sweep(quick, out=tmp_path / "r.nc", chunk_size=1, resources=Resources(threads=1))
    err = capsys.readouterr().err
    lines = re.findall(r"^quick: \d+/9 runs.*$", err, re.M)
    assert [line.split()[1] for line in lines] == ["3/9", "6/9", "9/9"], err
    assert [line.split("elapsed ")[1].split(",")[0] for line in lines] == ["12.0 s", "24.0 s",
                                                                             "36.0 s"]  # fmt: skip


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


@pytest.mark.slow
def test_cli_shows_a_bar_on_a_terminal(tmp_path):
    leader, follower = pty.openpty()
    # a terminal window of 24 rows x 100 columns (a fresh pty reports 0 x 0)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = run_quick(tmp_path, stderr=follower)
    os.close(follower)
    output = b""
    while True:
        ready, _, _ = select.select([leader], [], [], SUBPROCESS_TIMEOUT)
        assert ready, f"the sweep printed nothing for {SUBPROCESS_TIMEOUT} s"
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # EIO: the sweep closed the terminal
            break
        if not chunk:
            break
        output += chunk
    os.close(leader)
    assert proc.wait(timeout=SUBPROCESS_TIMEOUT) == 0
    text = output.decode(errors="replace")
    assert "\r" in text  # the bar redraws itself in place
    assert re.search(r"quick: 100%.*\| 9/9 \[\d\d:\d\d<\d\d:\d\d, +[\d.]+run/s\]", text), text


@pytest.mark.slow
@pytest.mark.parametrize("to", ["pipe", "log file"])
def test_cli_writes_plain_lines_to_a_pipe_or_a_log_file(tmp_path, to):
    if to == "pipe":
        proc = run_quick(tmp_path, stderr=subprocess.PIPE)
        _, err = proc.communicate(timeout=SUBPROCESS_TIMEOUT)
        text = err.decode()
    else:
        with open(tmp_path / "sweep.log", "wb") as log:
            proc = run_quick(tmp_path, stderr=log)
            proc.wait(timeout=SUBPROCESS_TIMEOUT)
        text = (tmp_path / "sweep.log").read_text()
    assert proc.returncode == 0, text
    assert "\r" not in text
    assert re.search(r"^quick: 9/9 runs \(100%\), [\d.]+ runs/s, elapsed [\d.]+ s, ETA 0 s$",
                     text, re.M), text  # fmt: skip


def run_notebook(tmp_path, monkeypatch, *cells):
    """Execute a notebook of these code cells in a Jupyter kernel of this Python (a
    kernel spec of its own, whatever kernels the machine has) → its outputs, in order."""
    spec = tmp_path / "jupyter" / "kernels" / "rsf-sweep-test"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(json.dumps({"argv": argv, "language": "python",
                                                  "display_name": "rsf-sweep test"}))  # fmt: skip
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    NotebookClient(nb, kernel_name="rsf-sweep-test", timeout=SUBPROCESS_TIMEOUT,
                   resources={"metadata": {"path": str(tmp_path)}}).execute()  # fmt: skip
    return [out for cell in nb.cells for out in cell.outputs]


RUN_QUICK = f"import sweep\nds = sweep.run({str(QUICK)!r}, threads=1)\nint(ds.regime.size)"


def stream_text(outputs):
    return "".join(out.text for out in outputs if out.output_type == "stream")


@pytest.mark.slow
def test_a_notebook_shows_a_widget_bar(tmp_path, monkeypatch):
    """``sweep.run`` in a Jupyter kernel: a tqdm.auto widget, no plain lines."""
    outputs = run_notebook(tmp_path, monkeypatch, RUN_QUICK)
    widgets = [out for out in outputs if WIDGET_VIEW in out.get("data", {})]
    assert len(widgets) == 1, outputs
    assert outputs[-1].data["text/plain"] == "9", outputs
    assert "quick: 9/9 runs" not in stream_text(outputs), outputs


@pytest.mark.slow
def test_a_notebook_without_ipywidgets_shows_plain_lines(tmp_path, monkeypatch):
    """The ``notebook`` extra missing: tqdm's hint to install ipywidgets, then the
    plain lines of a log."""
    no_ipywidgets = "import sys\nsys.modules['ipywidgets'] = None  # import fails"
    outputs = run_notebook(tmp_path, monkeypatch, no_ipywidgets, RUN_QUICK)
    assert not [out for out in outputs if WIDGET_VIEW in out.get("data", {})], outputs
    text = stream_text(outputs)
    assert "ipywidgets" in text and "\r" not in text, text
    assert re.search(r"^quick: 9/9 runs \(100%\)", text, re.M), text
