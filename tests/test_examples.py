"""The gallery (examples/gallery.py) runs end to end at quick sizes, as a user would run
it, and writes every file it promises."""

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import SUBPROCESS_TIMEOUT

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_gallery_runs_and_writes_its_figures(tmp_path):
    out = tmp_path / "gallery"
    proc = subprocess.run(
        [sys.executable, "-W", "error::FutureWarning", str(ROOT / "examples" / "gallery.py"),
         str(out), "--quick"],
        cwd=tmp_path, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    names = ["bifurcation.pdf", "oneblock.nc", "phase.png", "t_final.svg", "v_max.png"]
    assert sorted(p.name for p in out.iterdir()) == names
    assert all((out / name).stat().st_size > 5_000 for name in names)
    assert "stick-slip runs:" in proc.stdout
