"""Continuing undecided runs (``sweep/commands/extend.py``, ``python -m sweep extend``).

Undecided runs are made with a short end time just below Kc: the oscillation is still
growing at t_end = 50 D0/V. A continued run must settle them exactly as a run straight
to the later end time does, and leave every other run bit for bit as it was.
"""

import os
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import SUBPROCESS_TIMEOUT, make_config
from test_dataset import failing_to_netcdf

from sweep import cli
from sweep.commands.extend import extend_file, extend_result
from sweep.config import parse_config, parse_stored_config
from sweep.config.schema import STRUCTURED_FROM
from sweep.engine import runner
from sweep.errors import RunError
from sweep.io.netcdf import read_result, write_netcdf
from sweep.kernels import layout
from sweep.results.dataset import stored_config

#: Quasi-dynamic, η̂ = 0.01: Kc/W = 0.04 µm⁻¹; K/Kc = 0.85 (stick-slip, still growing at
#: 50 D0/V, settled by 200), 1.1 and 1.5 (steady well before 50).
QD = {"model": "quasi-dynamic", "parameters": {"eta_W": 0.1},
      "sweep": {"K_W": [0.034, 0.044, 0.06]}}  # fmt: skip
#: Quasi-static at K/Kc = 0.92: still growing at 50 D0/V, runs away at about 97 D0/V.
QS = {"sweep": {"K_W": [0.046, 0.06]}}
#: Inertial, M̂ = 0.01: Kc/W = 0.0667 µm⁻¹; K/Kc = 0.85 (stick-slip) and 1.2 (steady).
INERTIAL = {"model": "inertial", "parameters": {"m_W": 1.0}, "sweep": {"K_W": [0.0567, 0.08]},
            "integrator": {"method": "rosenbrock"}}  # fmt: skip
CASES = {"quasi-dynamic": QD, "quasi-static": QS, "inertial": INERTIAL}
UNDECIDED, STICK_SLIP, RUNAWAY, STEADY = (
    layout.UNDECIDED, layout.STICK_SLIP, layout.RUNAWAY, layout.STEADY,
)  # fmt: skip


def config(case, t_end, early_exit=True):
    c = CASES[case]
    return make_config(
        c, integrator={**c.get("integrator", {}), "t_end": t_end},
        classification={"early_exit": early_exit, "max_t_end": t_end},  # no continuation
    )  # fmt: skip


def compute(case, t_end, early_exit=True):
    return runner.compute(config(case, t_end, early_exit), show_progress=False)


@pytest.fixture(scope="module", params=list(CASES))
def continued(request):
    """(case, short run to 50, continued to the default 4 × 50, straight run to 200)."""
    short = compute(request.param, 50.0)
    return request.param, short, extend_result(short), compute(request.param, 200.0)


def test_undecided_runs_settle(continued):
    case, short, extended, _ = continued
    assert short["regime"].values[0] == UNDECIDED
    settled = RUNAWAY if case == "quasi-static" else STICK_SLIP
    assert list(extended["regime"].values) == [settled] + list(short["regime"].values[1:])
    assert list(short["regime"].values[1:]) == [STEADY] * (len(short["K_W"]) - 1)


def test_other_runs_are_untouched(continued):
    _, short, extended, _ = continued
    assert set(extended.data_vars) == set(short.data_vars)
    for name in short.data_vars:
        # rows 1.. were decided: the same bits, NaN included
        np.testing.assert_array_equal(extended[name][1:], short[name][1:], err_msg=name)
        assert extended[name].dtype == short[name].dtype, name


def test_same_as_a_run_straight_to_the_later_end(continued):
    """Same regime and the same limit cycle or runaway time as one run to 200 D0/V.

    The equations are autonomous and the restart state is stored exactly, so the two
    runs follow one trajectory and differ only by the integration error of their
    different step sequences after the restart (rtol 1e-8). Cycle amplitudes and
    periods (an attracting cycle, located at interpolated extrema) and runaway times
    agreed to 3e-9 relative; tested at 2e-8. The early-exit time is the end of the
    step that holds the settling cycle's last peak, so the two differ by less than
    one step (max_step = 0.5 D0/V = 5 s here; seen: 4.5e-3 s).
    """
    case, _, extended, straight = continued
    np.testing.assert_array_equal(extended["regime"], straight["regime"])
    row = {"K_W": 0}
    names = ["t_runaway"] if case == "quasi-static" else ["lnv_amplitude", "period"]
    for name in names:
        np.testing.assert_allclose(
            extended[name][row], straight[name][row], rtol=2e-8, err_msg=name
        )
    assert abs(float(extended["t_final"][row]) - float(straight["t_final"][row])) < 5.0
    assert extended["n_peaks"][row] == straight["n_peaks"][row]


@pytest.mark.slow
def test_a_result_is_read_with_the_method_its_runs_used():
    """A config that names no method is stored as written (``config_text``), the method
    its runs got in ``integrator_method``: for an inertial chain of ``STRUCTURED_FROM``
    blocks, ``rosenbrock-structured``. A file written before that default, whose runs
    used ``rosenbrock``, is read (extended, audited) with ``rosenbrock``, which the
    extended file's config then names; a text that names its method is read as it stands."""
    blocks = STRUCTURED_FROM["chain"]
    config = make_config({"blocks": blocks, **INERTIAL, "integrator": None},
                         parameters={"k2_W": 0.02}, integrator={"t_end": 50.0},
                         classification={"max_t_end": 50.0})  # fmt: skip
    ds = runner.compute(config, show_progress=False)
    assert "method" not in ds.attrs["config_text"]
    assert ds.attrs["integrator_method"] == "rosenbrock-structured"
    assert stored_config(ds, "new.nc").integrator.method == "rosenbrock-structured"
    assert ds["regime"].values[0] == UNDECIDED  # still growing at 50 D0/V
    old = ds.copy()
    old.attrs["integrator_method"] = "rosenbrock"  # as the version before the default wrote it
    assert stored_config(old, "old.nc").integrator.method == "rosenbrock"
    extended = extend_result(old)
    assert parse_config(extended.attrs["config_text"]).integrator.method == "rosenbrock"
    assert extended["regime"].values[0] == STICK_SLIP
    named = ds.attrs["config_text"].replace("integrator:\n", "integrator:\n  method: dopri5\n")
    assert parse_stored_config(named, "named", "rosenbrock").integrator.method == "dopri5"


@pytest.mark.parametrize("case", ["quasi-dynamic", "inertial"])
def test_final_state_equals_a_straight_run(case):
    """Without early exit both runs stop at exactly 100 D0/V: the final state (ℓ, ψ and,
    for inertia, z) agrees within the integration error (seen: 5e-10 relative; tested at
    1e-8). A restart from a wrong state, e.g. z = 0, misses by orders of magnitude more."""
    short = compute(case, 50.0, early_exit=False)
    assert short["regime"].values[0] == UNDECIDED
    extended = extend_result(short, 100.0)
    straight = compute(case, 100.0, early_exit=False)
    names = ["lnv_final", "ln_state_final"] + (
        ["inertial_force_final"] if case == "inertial" else []
    )
    for name in names:
        np.testing.assert_allclose(extended[name][0], straight[name][0], rtol=1e-8, err_msg=name)
    # 500 s + 50 D0/V × 10 s: the old t_final plus the time of the continued run
    np.testing.assert_allclose(extended["t_final"][0], straight["t_final"][0], rtol=1e-14)
    assert extended["t_final"][0] == pytest.approx(1000.0, rel=1e-14)


def test_times_and_counts_add_up(continued):
    """t_final, t_runaway count from the original start (s); steps and peaks add up."""
    case, short, extended, _ = continued
    row = {"K_W": 0}
    old_end = float(short["t_final"][row])
    assert old_end == pytest.approx(500.0)  # 50 D0/V, D0/V = 10 s
    assert old_end < float(extended["t_final"][row]) <= 2000.0
    if case == "quasi-static":
        # the cap is crossed inside the last step, which ends the run
        assert old_end < float(extended["t_runaway"][row]) <= float(extended["t_final"][row])
    for name in ("n_steps", "n_rejected", "n_peaks"):
        assert extended[name][row] >= short[name][row], name
    assert extended["n_steps"][row] > short["n_steps"][row]


def test_provenance_records_the_extension(continued):
    _, short, extended, _ = continued
    assert extended.attrs["integrator_t_end"] == 200.0
    stored = stored_config(extended, "x.nc")
    assert stored.integrator.t_end == 200.0
    assert stored.integrator.rtol == 1e-8 and stored.classification.early_exit
    history = extended.attrs["history"].splitlines()
    assert history[0] == short.attrs["history"]
    assert (
        "python -m sweep extend: 1 undecided runs continued from t_end = 50 to 200 D0/V"
        in (history[1])
    )


@pytest.fixture
def short_file(tmp_path):
    """The quasi-dynamic run to 50 D0/V as a file in a fresh folder."""
    path = tmp_path / "r.nc"
    write_netcdf(compute("quasi-dynamic", 50.0), path)
    return path


def test_file_in_place_keeps_other_runs_bit_identical(short_file):
    before = read_result(short_file)
    ds, n = extend_file(short_file)
    assert n == 1
    after = read_result(short_file)
    xr.testing.assert_identical(after, ds)
    for name in before.data_vars:
        np.testing.assert_array_equal(after[name][1:], before[name][1:], err_msg=name)
    assert after["regime"].values[0] == STICK_SLIP
    assert sorted(os.listdir(short_file.parent)) == ["r.nc"]


def test_nothing_undecided_leaves_the_file_alone(short_file, capsys):
    extend_file(short_file, 400.0)
    before = short_file.read_bytes(), os.stat(short_file).st_mtime_ns
    assert cli.main(["extend", str(short_file)]) == 0
    assert "no undecided runs" in capsys.readouterr().out
    assert (short_file.read_bytes(), os.stat(short_file).st_mtime_ns) == before


def test_failed_write_keeps_the_file(short_file, monkeypatch, capsys):
    before = short_file.read_bytes()
    monkeypatch.setattr(xr.Dataset, "to_netcdf", failing_to_netcdf)
    assert cli.main(["extend", str(short_file)]) == 1
    err = capsys.readouterr().err
    assert "No space left on device" in err and f"{short_file} is unchanged" in err
    assert short_file.read_bytes() == before
    assert sorted(os.listdir(short_file.parent)) == ["r.nc"]


def test_bad_input_exits_2(short_file, capsys):
    folder = short_file.parent
    (folder / "notes.nc").write_text("not netCDF")
    xr.Dataset({"x": ("i", [1.0])}).to_netcdf(folder / "other.nc")
    inertial = compute("inertial", 50.0).drop_vars("inertial_force_final")
    write_netcdf(inertial, folder / "old_inertial.nc")
    cases = [
        (["missing.nc"], "missing.nc: cannot read result file"),
        (["notes.nc"], "notes.nc: cannot read result file"),
        (["other.nc"], "other.nc: not a sweep result (no regime"),
        (
            ["r.nc", "--t-end", "50"],
            "must be later than the time its undecided runs already reached (50 D0/V",
        ),
        (["r.nc", "--t-end", "20"], "got 20"),
        (["old_inertial.nc"], "not a complete sweep result: no inertial_force_final"),
    ]
    before = short_file.read_bytes()
    for args, message in cases:
        code = cli.main(["extend", str(folder / args[0]), *args[1:]])
        err = capsys.readouterr().err
        assert code == 2, args
        assert message in err, (args, err)
    assert short_file.read_bytes() == before


@pytest.mark.slow
def test_cli_end_to_end(short_file):
    """``python -m sweep extend r.nc --out longer.nc`` in a fresh folder: the regime
    summary, the file written, the input untouched."""
    before = short_file.read_bytes()
    proc = subprocess.run(
        [sys.executable, "-m", "sweep", "extend", "r.nc", "--t-end", "200", "--out", "longer.nc"],
        cwd=short_file.parent, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [line.split()[:2] for line in lines[:-1]] == [
        ["steady", "2"], ["stick_slip", "1"], ["runaway", "0"], ["undecided", "0"],
    ]  # fmt: skip
    assert lines[-1] == "wrote longer.nc (1 undecided runs continued to 200 D0/V)"
    assert "extend: 1/1 runs (100%)" in proc.stderr  # progress, off with --quiet
    assert short_file.read_bytes() == before
    quiet = subprocess.run(
        [sys.executable, "-m", "sweep", "extend", "r.nc", "--out", "q.nc", "--quiet"],
        cwd=short_file.parent, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT,
    )  # fmt: skip
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr
    with xr.open_dataset(short_file.parent / "longer.nc") as ds:
        assert ds["regime"].values.tolist() == [STICK_SLIP, STEADY, STEADY]


def test_extend_in_place_refuses_while_a_run_holds_the_file(short_file, lock_holder):
    """An extend of a result another process is writing (a run, or another extend)
    refuses naming that process and leaves the file as it was."""
    before = short_file.read_bytes()
    holder = lock_holder(short_file)
    with pytest.raises(RunError, match=rf"r.nc is in use .* pid {holder.pid} "):
        extend_file(short_file, t_end=100.0)
    with pytest.raises(RunError, match=f"pid {holder.pid}"):
        extend_file(short_file.with_name("elsewhere.nc"), t_end=100.0, out=short_file)
    assert short_file.read_bytes() == before
