"""Self-audit (``sweep/commands/audit.py``, ``python -m sweep audit``): long reruns without early
exit and reruns with tighter tolerances agree with clearly classified points, catch a
regime that is wrong in the file, and catch a chaotic transient whose runaway the
default tolerance misses (checked against SciPy)."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_A, PAPER_B, SUBPROCESS_TIMEOUT, make_config
from nblock_reference import Chain, run, start_state

import sweep
from sweep import cli
from sweep.codes import ATTRACTORS, code
from sweep.commands.audit import audit_config, audit_points, audit_result, tight_config
from sweep.engine import runner
from sweep.io.netcdf import write_netcdf
from sweep.kernels import layout

#: Quasi-dynamic, one block, two axes. Kc/W = (B − A − η̂)/D0 = 0.05 (η = 0) and 0.045 µm⁻¹
#: (η/W = 0.05 s/µm): K/Kc from 0.6 to 1.56, none within 10 % of Kc, so every point is
#: clearly runaway (η = 0, below Kc), stick-slip (η > 0, below Kc) or steady (above).
CLEAR = {"model": "quasi-dynamic", "sweep": {"K_W": [0.03, 0.04, 0.07], "eta_W": [0.0, 0.05]},
         "integrator": {"t_end": 300.0}}  # fmt: skip


@pytest.fixture(scope="module")
def clear():
    return runner.compute(make_config(CLEAR), show_progress=False)


def test_clear_points_agree(clear):
    regimes = clear["regime"].values
    assert regimes.tolist() == [[layout.RUNAWAY, layout.STICK_SLIP]] * 2 + [[layout.STEADY] * 2]
    audit = audit_result(clear)
    assert audit.sizes["point"] == 6  # a sample of 20 takes the whole grid of 6
    assert audit["agree"].all() and audit["agree_tight"].all()
    np.testing.assert_array_equal(audit["regime_audit"], regimes.ravel())
    np.testing.assert_array_equal(audit["regime_tight"], regimes.ravel())
    for name in ("attractor", "cycle_events"):
        np.testing.assert_array_equal(audit[f"{name}_file"], clear[name].values.ravel())
        np.testing.assert_array_equal(audit[f"{name}_tight"], clear[name].values.ravel())
    assert audit.attrs["audit_tighten"] == 100.0
    assert "regime_tight" not in audit_result(clear, tighten=None)
    np.testing.assert_array_equal(audit["K_W"], [0.03, 0.03, 0.04, 0.04, 0.07, 0.07])
    np.testing.assert_array_equal(audit["eta_W"], [0.0, 0.05] * 3)
    np.testing.assert_array_equal(audit["K_over_Kc"], clear["K_over_Kc"].values.ravel())
    assert audit.attrs["audit_t_end"] == 3000.0  # 10 × the file's 300 D0/V
    assert not audit["near_kc"].any()


def test_audit_config_turns_early_exit_off():
    config = make_config(CLEAR)
    longer = audit_config(config, 3000.0)
    assert config.classification.early_exit and not longer.classification.early_exit
    assert longer.integrator.t_end == 3000.0
    assert longer.integrator == dataclasses.replace(config.integrator, t_end=3000.0)
    assert (longer.axes, longer.parameters, longer.initial) == (
        config.axes, config.parameters, config.initial,
    )  # fmt: skip


def test_tight_config_divides_the_tolerances_only():
    config = make_config(CLEAR, integrator={"method": "rk4", "dt": 0.01})
    tight = tight_config(config, 100.0)
    assert (tight.integrator.rtol, tight.integrator.atol) == (1e-10, 1e-12)
    assert tight.integrator.dt == pytest.approx(0.01 / 100**0.25)
    assert tight.integrator.t_end == config.integrator.t_end
    assert (tight.classification, tight.axes, tight.parameters, tight.initial) == (
        config.classification, config.axes, config.parameters, config.initial,
    )  # fmt: skip


@pytest.mark.slow
def test_a_chaotic_transient_is_caught_by_the_tighter_rerun():
    """Three unequal quasi-static blocks (D0 1.0/1.3/0.8 µm, chain, k2/W 0.02 µm⁻¹) at
    0.9 of the reference's Kc, from Φ/Φss = [1.01, 1, 1]: SciPy (DOP853, rtol 1e-10) runs
    away after a chaotic transient; so does the engine at rtol 1e-10, to 2e-3 of its
    time. At the default rtol 1e-8 the engine's trajectory has left the true one by the
    escape (λ1 ≈ 0.0011 s⁻¹ grows the error about 1e5-fold by then) and stays chaotic to
    max_t_end: the file's label is of another trajectory, and the tighter rerun says
    so."""
    chain = Chain(PAPER_A, PAPER_B, [1.0, 1.3, 0.8], 0.05, 0.02)
    k_w = 0.9 * chain.critical_K_W()
    start = {"phi_over_phi_ss": [1.01, 1.0, 1.0], "v_over_V": 1.0, "ensemble": 0}
    config = sweep.with_changes(
        "unequal_chain", {"sweep": {"K_W": [k_w], "k2_W": [0.02]}, "initial": start}
    )
    ds = runner.compute(config, show_progress=False)
    audit = audit_result(ds, sample=1, near_kc=0.0)
    tight = runner.compute(tight_config(config, 100.0), show_progress=False)
    _, t_scipy = run(chain.with_K(k_w), start_state(3, 1.0, [1.01, 1.0, 1.0]), 2000.0)
    assert t_scipy is not None  # in the reference's unit 1 µm / V = 10 s
    assert int(tight["regime"].item()) == layout.RUNAWAY
    assert tight["t_runaway"].item() == pytest.approx(10.0 * t_scipy, rel=2e-3)
    assert int(audit["regime_tight"].item()) == layout.RUNAWAY
    assert int(ds["regime"].item()) == layout.STICK_SLIP
    assert int(ds["attractor"].item()) == code(ATTRACTORS, "chaotic")
    assert not audit["agree_tight"].item()


@pytest.mark.slow
def test_blocks_merged_by_round_off_are_named(tmp_path, capsys):
    """Three identical quasi-static blocks in a ring (k2/W 0.002 µm⁻¹) at 0.99 Kc from
    Φ/Φss = [1.02, 1, 0.98]: the engine ends on a cycle with blocks 1 and 2 equal bit for
    bit. SciPy, from that state with ln v_1 moved by 1e-10, leaves the cycle (|ln v_1 −
    ln v_2| > 0.1 within 15 000 s): it is unstable across the two blocks, and the audit
    names the point."""
    start = {"phi_over_phi_ss": [1.02, 1.0, 0.98], "v_over_V": 1.0, "ensemble": 0}
    changes = {"sweep": {"K_W": [0.0495, 0.0485], "k2_W": [0.002]}, "coupling": "ring",
               "parameters": {"D0": 1.0}, "initial": start}  # fmt: skip
    ds = runner.compute(sweep.with_changes("unequal_chain", changes), show_progress=False)
    audit = audit_result(ds, sample=2, near_kc=0.0, tighten=None)
    np.testing.assert_array_equal(audit["merged_blocks"], [2, 0])  # 0.0485 runs away
    on_cycle = ds.isel(K_W=0, k2_W=0)
    assert int(on_cycle["attractor"]) == code(ATTRACTORS, "periodic")
    end = np.concatenate([on_cycle["lnv_final"].values, on_cycle["ln_state_final"].values])
    assert end[1] == end[2] and end[4] == end[5]
    end[1] += 1e-10
    sol, _ = run(Chain(PAPER_A, PAPER_B, 1.0, 0.0495, 0.002, "ring", n_blocks=3), end, 1500.0)
    lnv = sol.sol(np.linspace(0.0, 1500.0, 300_001))  # time unit 1 µm / V = 10 s
    assert np.abs(lnv[1] - lnv[2]).max() > 0.1
    write_netcdf(ds, tmp_path / "ring.nc")
    cli.main(["audit", str(tmp_path / "ring.nc"), "--quiet"])
    out = capsys.readouterr().out
    assert "K_W=0.0495 k2_W=0.002  K/Kc=0.99  2 blocks equal bit for bit" in out


def test_points_sample_and_near_kc():
    """Seeded draw: the same seed draws the same points; every point near Kc is added."""
    k_over_kc = np.linspace(0.5, 1.5, 101)  # 0.01 apart: 0.99, 1.0 and 1.01 within 1.5 %
    ds = xr.Dataset({"K_over_Kc": ("K_W", k_over_kc)})
    rows, near = audit_points(ds, sample=10, near_kc=0.015, seed=0)
    again, _ = audit_points(ds, sample=10, near_kc=0.015, seed=0)
    other, _ = audit_points(ds, sample=10, near_kc=0.015, seed=1)
    np.testing.assert_array_equal(rows, again)
    assert not np.array_equal(rows, other)
    assert {49, 50, 51} <= set(rows) and np.all(np.diff(rows) > 0)
    assert 10 <= rows.size <= 13
    np.testing.assert_array_equal(rows[near], [49, 50, 51])
    only_near, _ = audit_points(ds, sample=0, near_kc=0.015, seed=0)
    np.testing.assert_array_equal(only_near, [49, 50, 51])


@pytest.fixture
def planted(clear, tmp_path):
    """The clear sweep as a file, with the steady point K/W = 0.07, η/W = 0.05 relabelled
    stick-slip."""
    wrong = clear.copy(deep=True)
    wrong["regime"].loc[{"K_W": 0.07, "eta_W": 0.05}] = layout.STICK_SLIP
    write_netcdf(wrong, tmp_path / "r.nc")
    return tmp_path


@pytest.mark.slow
def test_planted_disagreement_is_found(planted):
    """``python -m sweep audit r.nc`` in a fresh folder: exit 1, the table, the point."""
    proc = subprocess.run(
        [sys.executable, "-m", "sweep", "audit", "r.nc"],
        cwd=planted, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == (
        "audited 6 points of r.nc (0 within 0.01 of Kc): runs to 3000 D0/V without early exit, "
        "and to 300 D0/V with rtol and atol / 100"
    )
    regimes = ["steady", "stick_slip", "runaway", "undecided"]
    expected = {"steady": [1, 0, 0, 0], "stick_slip": [1, 2, 0, 0],
                "runaway": [0, 0, 2, 0], "undecided": [0, 0, 0, 0]}  # fmt: skip
    reruns = (
        (1, ["long", "run"], "regime"),
        (7, ["tighter", "tolerance"], "regime, attractor and events per cycle"),
    )
    for first, rerun, compared in reruns:
        assert lines[first].split() == ["file", "\\", *rerun, *regimes]
        rows = lines[first + 1 : first + 5]
        assert {line.split()[0]: [int(c) for c in line.split()[1:]] for line in rows} == expected
        assert lines[first + 5] == f"agreement: 5 of 6 points (83.3 %; {compared})"
    assert lines[13:] == [
        "points where a rerun disagrees:",
        "  K_W=0.07 eta_W=0.05  K/Kc=1.556  file: stick_slip (fixed_point)  long run: steady  "
        "tighter tolerance: steady",
    ]


def test_all_agree_exits_0(clear, tmp_path, capsys):
    write_netcdf(clear, tmp_path / "r.nc")
    assert cli.main(["audit", str(tmp_path / "r.nc"), "--sample", "3", "--seed", "5"]) == 0
    out, err = capsys.readouterr()
    for rerun in ("long run", "tighter tolerance"):  # progress, on stderr
        assert f"audit: {rerun}: 3/3 runs (100%)" in err
    assert cli.main(["audit", str(tmp_path / "r.nc"), "--sample", "3", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert out.count("agreement: 3 of 3 points (100.0 %;") == 2
    assert "disagrees" not in out


def test_bad_input_exits_2(clear, tmp_path, capsys):
    assert cli.main(["audit", str(tmp_path / "missing.nc")]) == 2
    assert "missing.nc: cannot read result file" in capsys.readouterr().err
    write_netcdf(clear, tmp_path / "r.nc")
    for factor in ("1", "1e6"):  # no tighter, or rtol 1e-14
        assert cli.main(["audit", str(tmp_path / "r.nc"), "--tighten", factor]) == 2
        assert (
            "--tighten must be finite, above 1 and keep rtol / FACTOR >= 1e-13 (the file's rtol "
            f"is 1e-08), got {float(factor):g}"
        ) in capsys.readouterr().err
    bad = (["--t-end", "0"], ["--near-kc", "-0.1"], ["--sample", "-1"], ["--seed", "x"],
           ["--tighten", "0"], ["--tighten", "nan"])  # fmt: skip
    for option in bad:
        with pytest.raises(SystemExit) as info:
            cli.main(["audit", "r.nc", *option])
        assert info.value.code == 2, option


def test_ensemble_members_are_audited_as_runs(tmp_path, capsys):
    """With an ensemble each drawn grid point is audited once per member, each member
    from its own start: the file's labels and the long runs' are those of a direct
    sweep of every run (the audit once took grid-point rows for run rows)."""
    ensemble = {"sweep": {"K_W": [0.03, 0.045, 0.07]}, "integrator": {"t_end": 200.0},
                "initial": {"ensemble": 3, "seed": 2, "amplitude": 0.5}}  # fmt: skip
    config = make_config(ensemble)
    ds = runner.compute(config, show_progress=False)
    audit = audit_result(ds, sample=2, near_kc=0.0, seed=1)
    points = np.unique(audit["index"].values)
    assert points.size == 2 and audit.sizes["point"] == 2 * 3
    np.testing.assert_array_equal(audit["member"], [0, 1, 2, 0, 1, 2])
    np.testing.assert_array_equal(audit["regime_file"], ds["regime"].values[points].ravel())
    long = runner.compute(audit_config(config, audit.attrs["audit_t_end"]), show_progress=False)
    np.testing.assert_array_equal(audit["regime_audit"], long["regime"].values[points].ravel())
    tight = runner.compute(tight_config(config, 100.0), show_progress=False)
    for name in ("regime", "attractor", "cycle_events"):
        np.testing.assert_array_equal(audit[f"{name}_tight"], tight[name].values[points].ravel())
    np.testing.assert_array_equal(audit["K_W"], np.repeat(ds["K_W"].values[points], 3))
    write_netcdf(ds, tmp_path / "e.nc")
    cli.main(["audit", str(tmp_path / "e.nc"), "--sample", "2", "--near-kc", "0", "--seed", "1"])
    assert "audited 6 runs of" in capsys.readouterr().out
