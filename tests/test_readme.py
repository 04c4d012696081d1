"""The numbers the documentation states, read from its pages and recomputed.

The guide, physics and large-sweeps pages (``docs/**/*.md``; they were the README's
sections) state numbers; each test reads one from the page text with a regular
expression and recomputes it: with the engine the way ``make figures`` or the named
config does, and, where an independent reference is cheap, with SciPy or a closed
form. A number must agree to its last printed digit, so a change in the code that
moves it fails here until the page is updated (and an edit that no longer matches
fails too). The limit cycle numbers of "What happens below Kc" are checked in
``test_models.py``, beside the runs that produce them.

Tests marked ``drift`` compare with numbers that only this engine produced (there is
no independent reference in the test): they catch a change, not an error. The others
check against SciPy, a closed form or the config itself.
"""

import dataclasses
import math
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import (
    PAPER_A,
    PAPER_B,
    QUICK,
    ROOT,
    SUBPROCESS_TIMEOUT,
    assert_as_printed,
    config_dict,
    scipy_runaway_time,
)
from nblock_reference import Chain, start_state, window_amplitudes
from nblock_reference import run as scipy_run
from scipy.integrate import solve_ivp

from sweep import run
from sweep.commands import figures
from sweep.commands.trace import compute_trace, pin_config
from sweep.config import (
    Catalogue,
    Classification,
    Integrator,
    config_mapping,
    load_config,
    parse_config,
)
from sweep.engine.runner import compute
from sweep.model.physics import log_form_rhs
from sweep.variables import REGIMES

PAPER = load_config(ROOT / "configs" / "paper.yaml")
DOCS = ROOT / "docs"
#: Folders of docs/ that Sphinx generates (not sources).
GENERATED = {"_build", "auto_examples", "generated"}


def doc_pages():
    """The documentation's Markdown sources (docs/**/*.md, without docs/README.md)."""
    pages = sorted(DOCS.rglob("*.md"))
    return [p for p in pages if not GENERATED & set(p.relative_to(DOCS).parts)
            and p != DOCS / "README.md"]  # fmt: skip


def doc_numbers(pattern):
    """The numbers the documentation states where ``pattern`` (a regex whose groups
    capture them) matches, as the printed strings; whitespace counts as one space.
    Fails unless the pattern matches exactly once over all pages."""
    found = []
    for page in doc_pages():
        text = " ".join(page.read_text().split())
        found += [(page.name, match) for match in re.findall(pattern, text)]
    assert len(found) == 1, f"docs: {pattern!r} matched {len(found)} times: {found}"
    match = found[0][1]
    return match if isinstance(match, tuple) else (match,)


#: The paper's "stick-slip" stiffness (µm⁻¹), K/Kc = 0.92; D0/V = 10 s.
K_W = 0.046
T_UNIT = 10.0


def paper_trace(t_end=None, **changes):
    """The trace ``make figures`` draws at K/W = 0.046 for a variant of the paper config."""
    config = figures.variant(PAPER, "readme", **changes)
    return compute_trace(pin_config(config, {"K_W": K_W}, t_end), points=3000)


def test_fig1_runaway_time():
    """ "passing 10⁶ V at t = 970.5 s": the figure's trace and SciPy DOP853 (rtol 1e-10,
    conftest.scipy_runaway_time) on the log form from Φ/Φss = 1.01."""
    (printed,) = doc_numbers(r"passing 10⁶ V at t = ([\d.]+) s")
    assert_as_printed(paper_trace().attrs["t_runaway"], printed)
    tau = scipy_runaway_time(K_W / (PAPER_B - PAPER_A), 0.0, math.log(1.01))
    assert_as_printed(tau * T_UNIT, printed)


@pytest.mark.drift
def test_fig1_damped_cycle_drift():
    """Drift check: the damped row of Fig. 1 (η/W = 0.01 s/µm), its period and
    velocity range as the engine's trace gives them."""
    period, v_low, v_high = doc_numbers(
        r"stick-slip cycle \(period ([\d.]+) s, v between about ([\d.]+) and ([\d.]+) µm/s\)"
    )
    trace = paper_trace(model="quasi-dynamic", eta_W=figures.ETA_W)
    assert trace.attrs["regime"] == "stick_slip"
    assert_as_printed(trace.attrs["period"], period)
    assert_as_printed(float(trace["velocity"].min()), v_low)
    assert_as_printed(float(trace["velocity"].max()), v_high)


def test_fig1_critical_stiffnesses():
    """The closed-form Kc/W = (B − A − η̂)/D0 for η̂ = 0.001 and 0.01."""
    (kc_small,) = doc_numbers(r"Kc/W = \(B − A − η̂\)/D0 = ([\d.]+) µm⁻¹\)")
    (kc_large,) = doc_numbers(r"η̂ = 0.01 would move Kc/W to ([\d.]+) µm⁻¹")
    assert_as_printed(PAPER_B - PAPER_A - 0.001, kc_small)
    assert_as_printed(PAPER_B - PAPER_A - 0.01, kc_large)


def fig2_trace():
    """Fig. 2's out-of-phase quasi-static run (k2/W = 0.05 µm⁻¹, Φ/Φss = 1.01 and 0.99)
    as ``make figures`` traces it, and its end time (s)."""
    t_end = figures.TWO_BLOCK_SPAN * PAPER.integrator.t_end
    return paper_trace(t_end, k2_W=figures.K2_W, phi=figures.OUT_OF_PHASE), t_end


def test_fig2_out_of_phase_runaway():
    """Fig. 2's out-of-phase quasi-static run: runaway time from the figure's trace and
    from SciPy DOP853 (rtol 1e-10) on the two-block log form."""
    (printed,) = doc_numbers(r"the quasi-static run runs away at t = ([\d.]+) s")
    trace, t_end = fig2_trace()
    assert_as_printed(trace.attrs["t_runaway"], printed)

    def cap(t, y, *args):
        return np.max(y[:2]) - math.log(PAPER.classification.v_cap_over_V)

    cap.terminal = True
    kappa2 = figures.K2_W  # κ = k D0/W with D0 = 1 µm
    phi = figures.OUT_OF_PHASE
    reference = solve_ivp(
        log_form_rhs, (0.0, t_end / T_UNIT), [0.0, 0.0, *np.log(phi)], method="DOP853",
        rtol=1e-10, atol=1e-12, events=cap, args=(PAPER_A, PAPER_B, K_W, kappa2, 2),
    )  # fmt: skip
    assert_as_printed(reference.t_events[0][0] * T_UNIT, printed)


@pytest.mark.drift
def test_fig2_synchronisation_drift():
    """Drift check: in the engine's trace of Fig. 2's out-of-phase run the blocks agree
    to rounding error from "about 300 s" on, and not at half that time."""
    (sync,) = doc_numbers(r"synchronise to rounding error within about ([\d.]+) s")
    trace, _ = fig2_trace()
    # rounding error of ℓ: a few ulps of |ℓ| ≤ ln 1e6 ≈ 14, i.e. ≲ 1e-14; at half the
    # stated time the blocks must still differ by more, or "about" would be wrong
    t = trace["time"].values
    gap = np.abs(trace["lnv"].isel(block=0).values - trace["lnv"].isel(block=1).values)
    assert gap[t >= float(sync)].max() <= 1e-14
    assert gap[t >= 0.5 * float(sync)].max() > 1e-14


def config_at(path, **values):
    """The config at ``path`` with each named axis reduced to one value (physical units)."""
    raw = config_mapping(load_config(path))
    for name, value in values.items():
        raw["sweep"][name] = [value]
    return parse_config(raw, f"{path} at {values}")


@pytest.mark.slow
@pytest.mark.drift
def test_slip_law_events_are_smaller_drift():
    """Drift check: "v_max/V 12.3 vs 15.4 at K/Kc ≈ 0.48, η̂ = 0.01": the grid point of
    configs/slip_law.yaml and configs/quasidynamic.yaml nearest to that K/Kc."""
    slip, aging, ratio = doc_numbers(r"v_max/V ([\d.]+) vs ([\d.]+) at K/Kc ≈ ([\d.]+), η̂ = 0.01\)")
    eta_w = 0.1  # η̂ = η V/W = 0.01 with V = 0.1 µm/s
    kc_w = (PAPER_B - PAPER_A - 0.01) / 1.0
    k_axis = np.array(load_config(ROOT / "configs" / "slip_law.yaml").axes[0].values)
    k_w = float(k_axis[np.argmin(np.abs(k_axis / kc_w - float(ratio)))])
    assert_as_printed(k_w / kc_w, ratio)
    for name, printed in (("slip_law", slip), ("quasidynamic", aging)):
        ds = compute(config_at(ROOT / "configs" / f"{name}.yaml", K_W=k_w, eta_W=eta_w),
                     show_progress=False)  # fmt: skip
        assert int(ds["regime"].item()) == REGIMES.index("stick_slip")
        assert_as_printed(float(ds["v_max"].item()) / 0.1, printed)


def test_config_sizes_and_inertial_kc_range():
    """Run counts of the regularised configs, and the inertial Kc/W range from the
    closed form Kc/W = ((B − A)/D0)(1 + M̂/A) over the config's m/W axis."""
    for name in ("quasidynamic", "inertial"):
        (runs,) = doc_numbers(rf"`configs/{name}.yaml`: [^`]*?(\d+) runs")
        assert math.prod(load_config(ROOT / "configs" / f"{name}.yaml").shape) == int(runs)
    low, high = doc_numbers(r"Kc ∝ 1 \+ M̂/A from ([\d.]+) to ([\d.]+) µm⁻¹")
    m_w = np.array(load_config(ROOT / "configs" / "inertial.yaml").axes[1].values)
    mass_hat = m_w * 0.1**2 / 1.0  # M̂ = m V²/(W D0)
    kc_w = (PAPER_B - PAPER_A) * (1 + mass_hat / PAPER_A)
    assert_as_printed(kc_w.min(), low)
    assert_as_printed(kc_w.max(), high)


#: ``python -m sweep ARGS`` that reports its own peak resident memory (KiB) on stderr.
# The peak resident memory of this process's own address space (VmHWM, KiB). Not
# getrusage's ru_maxrss: Linux carries the parent's high-water mark over fork and exec,
# so under a pytest process that has grown to 1.7 GB it reported 1.7 GB.
MEASURED_RUN = """
import sys
from sweep.cli import main
status = main(sys.argv[1:])
status_lines = open("/proc/self/status").read().splitlines()
print(next(line for line in status_lines if line.startswith("VmHWM:")), file=sys.stderr)
sys.exit(status)
"""


def peak_memory(config, points, t_end, cwd):
    """Peak resident memory (bytes) of ``python -m sweep run`` on ``config`` (a path to
    configs/quick.yaml's text) with ``points`` K/W values and runs cut at ``t_end``
    (D0/V), its kernel already cached."""
    text = QUICK.read_text().replace("t_end: 2000.0", f"t_end: {t_end}")
    config.write_text(text.replace("num: 9}", f"num: {points}}}"))
    proc = subprocess.run(
        [sys.executable, "-c", MEASURED_RUN, "run", str(config), "--out", "m.nc", "--quiet"],
        cwd=cwd, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert f"wrote m.nc ({points} runs" in proc.stdout
    return int(proc.stderr.split()[-2]) * 1024  # "VmHWM:  1009076 kB"


@pytest.mark.slow
def test_memory_grows_with_the_result_arrays_only(tmp_path):
    """ "Memory grows only with the result arrays … whatever the run length": the peak
    resident memory of ``python -m sweep run`` (configs/quick.yaml, one block) does not
    change with the run length (2·10⁵ runs cut at 1 and at 20 D0/V, within 5 %: the
    allocator's rounding), and grows with the number of runs by between 1 and 3 times
    the bytes per run of the result's variables (a run's result row and its Dataset
    are held at once while the file is written; 3: one more copy for the write). The
    docs' figure for 10⁶ runs lies within the same bounds (it is a measurement, which
    the allocator and library versions move)."""
    config = tmp_path / "many.yaml"
    config.write_text(QUICK.read_text().replace("t_end: 2000.0", "t_end: 1.0"))
    small = run(str(config), progress=False)  # compiles and caches the kernel
    per_run = sum(v.nbytes for v in small.data_vars.values() if "K_W" in v.dims) / small.K_W.size
    short, longer = (peak_memory(config, 200_000, t, tmp_path) for t in (1.0, 20.0))
    assert longer == pytest.approx(short, rel=0.05)
    slope = (peak_memory(config, 1_000_000, 1.0, tmp_path) - short) / 800_000
    assert per_run <= slope <= 3 * per_run, (slope, per_run)
    base = short - 200_000 * slope  # the interpreter, numba, xarray and the kernel
    (gb,) = doc_numbers(r"a one-block sweep of 10⁶ grid points peaks at about ([\d.]+) GB")
    assert base + per_run * 1e6 <= float(gb) * 1e9 <= base + 3 * per_run * 1e6, (base, per_run)


def setting_comments(section):
    """``{key: comment}`` of the config reference's annotated config under ``section:``
    (a key's comment and the comment lines that continue it)."""
    lines = (DOCS / "guide" / "configs.md").read_text().splitlines()
    start = lines.index(f"{section}:")
    comments, key = {}, None
    for line in lines[start + 1 :]:
        if not line.startswith("  "):
            break
        head, _, comment = line.partition("#")
        if head.strip():
            key = head.split(":")[0].strip()
            comments[key] = comment
        else:
            comments[key] += " " + comment
    return comments


@pytest.mark.parametrize("section, cls", [("integrator", Integrator),
                                          ("classification", Classification),
                                          ("catalogue", Catalogue)])  # fmt: skip
def test_config_reference_states_each_setting_as_declared(section, cls):
    """The annotated config names every integrator and classification setting with the
    interval or choices and the unit declared once in ``sweep.config.schema`` (its field's
    ``Setting``), so the reference and the validation cannot drift apart."""
    comments = setting_comments(section)
    for field in dataclasses.fields(cls):
        spec = field.metadata["setting"]
        assert field.name in comments, f"docs/guide/configs.md lacks {section}.{field.name}"
        comment = comments[field.name]
        if isinstance(spec.allowed, str):
            assert spec.allowed in comment, f"{section}.{field.name}: no {spec.allowed}"
        elif all(isinstance(choice, str) for choice in spec.allowed):
            words = re.split(r"[\s|]+", comment)
            assert set(spec.allowed) <= set(words), f"{section}.{field.name}: {spec.allowed}"
        if spec.units != "1":
            assert spec.units in comment, f"{section}.{field.name}: no unit {spec.units}"


# --- Many contact points (issue 14) ------------------------------------------------------


@pytest.mark.slow
def test_unequal_chain_critical_stiffness():
    """ "Kc/W = 0.0470 µm⁻¹ (identical blocks with their mean D0: 0.0484 µm⁻¹)": the
    engine's critical_K_W of the D0 = 1.0/1.3/0.8 µm chain, the independent reference's
    bisection, and (B − A)/⟨D0⟩."""
    kc, kc_mean = doc_numbers(
        r"k2/W = 0.02 µm⁻¹ have Kc/W = ([\d.]+) µm⁻¹ \(identical blocks with their mean D0: "
        r"([\d.]+) µm⁻¹\)"
    )
    d0 = [1.0, 1.3, 0.8]
    ds = sweep_chain(d0, [0.05])
    assert_as_printed(float(ds.critical_K_W[0]), kc)
    assert_as_printed(Chain(PAPER_A, PAPER_B, d0, 0.05, 0.02).critical_K_W(), kc)
    assert_as_printed((PAPER_B - PAPER_A) / np.mean(d0), kc_mean)


def sweep_chain(d0, k_w, **sections):
    """The engine on three quasi-static blocks in a chain (k2/W = 0.02 µm⁻¹) with D0
    ``d0`` (µm, list or scalar), K/W values ``k_w``, start Φ/Φss = 1.01, t_end 3000 D0/V."""
    cfg = config_dict(
        {"blocks": 3, "coupling": "chain", "parameters": {"D0": d0, "k2_W": 0.02},
         "sweep": {"K_W": list(k_w)}, "integrator": {"t_end": 3000.0}}, **sections
    )  # fmt: skip
    return run(cfg, progress=False)


@pytest.mark.slow
@pytest.mark.drift
def test_unequal_chain_cycle_at_0_97_kc_drift():
    """Drift check, but for max |ln Φ/Φss| (SciPy; the engine's cycle is checked against
    SciPy in test_nblock_findings.py): "ln(v/V) between −1.810 and 1.692 (max
    |ln Φ/Φss| 1.22), period 53.2 s, sync_order 0.959; … run away (at 2586 s in phase
    …)": the engine at 0.97 of the chain's critical_K_W, and the identical blocks with
    the mean D0 at 0.97 of theirs; max |ln Φ/Φss| (not an engine output) from the SciPy
    reference (DOP853 rtol 1e-10, τ 300–400)."""
    low, high, psi, period, order, t_run = doc_numbers(
        r"a cycle with ln\(v/V\) between −([\d.]+) and ([\d.]+) \(max \|ln Φ/Φss\| ([\d.]+)\), "
        r"period ([\d.]+) s, `sync_order` ([\d.]+); identical blocks with the mean D0 at 0.97 "
        r"of their Kc run away \(at (\d+) s in phase"
    )
    d0 = [1.0, 1.3, 0.8]
    kc = float(sweep_chain(d0, [0.05]).critical_K_W[0])
    row = sweep_chain(d0, [0.97 * kc]).isel(K_W=0)
    assert REGIMES[int(row.regime)] == "stick_slip"
    assert_as_printed(-float(row.lnv_min), low)
    assert_as_printed(float(row.lnv_max), high)
    assert_as_printed(float(row.period), period)
    assert_as_printed(float(row.sync_order), order)
    chain = Chain(PAPER_A, PAPER_B, d0, 0.97 * kc, 0.02)
    sol, _ = scipy_run(chain, start_state(3), 400.0)
    assert_as_printed(window_amplitudes(chain, sol, 300.0)[0], psi)
    mean_d0 = float(np.mean(d0))
    same = sweep_chain(mean_d0, [0.97 * (PAPER_B - PAPER_A) / mean_d0]).isel(K_W=0)
    assert REGIMES[int(same.regime)] == "runaway"
    assert_as_printed(float(same.t_runaway), t_run)


@pytest.mark.drift
def test_two_weakly_coupled_blocks_sync_order_drift(anti_phase_cycle):
    """Drift check: "(`sync_order` 0.919, one block per slip)": the engine on the
    anti-phase start of test_classification (K/Kc = 0.99, k2/W = 0.001 µm⁻¹, t_end 8000
    D0/V; conftest's ``anti_phase_cycle``)."""
    (order,) = doc_numbers(r"out-of-phase cycle \(`sync_order` ([\d.]+), one block per slip\)")
    _, row = anti_phase_cycle
    assert REGIMES[int(row.regime)] == "stick_slip"
    assert_as_printed(float(row.sync_order), order)
    assert float(row.slip_participation) == 0.5


@pytest.mark.slow
@pytest.mark.drift
def test_critical_stiffness_against_n_and_coupling_drift():
    """Drift check (the engine's linear stability; test_nblock_reference.py checks it
    against an independent Jacobian): "within 1.2 % of the mean-D0 value … from 0.946 to
    1.082 times it": the left panel's numbers (``figures.critical_ratios`` of
    configs/heterogeneous.yaml, as make figures)."""
    (all_pct,) = doc_numbers(r"all-to-all coupling it stays within ([\d.]+) % of the mean-D0")
    low, high = doc_numbers(r"along a chain it ranges from ([\d.]+) to ([\d.]+) times it")
    sizes, n_low, n_high = doc_numbers(
        r"D0 spread by (\d+) %, k2/W = 0.02 µm⁻¹, ten seeds.*?every N from (\d+) to (\d+);"
    )
    ratios = figures.critical_ratios(load_config(ROOT / "configs" / "heterogeneous.yaml"))
    assert (int(sizes), len(ratios.seed)) == (round(100 * figures.NBLOCK_SPREAD), 10)
    assert (int(n_low), int(n_high)) == (min(ratios.blocks), max(ratios.blocks))
    everyone = 100 * float(abs(ratios.sel(coupling="all") - 1).max())
    assert everyone <= float(all_pct) and everyone > float(all_pct) - 0.1
    chain = ratios.sel(coupling="chain")
    assert_as_printed(float(chain.min()), low)
    assert_as_printed(float(chain.max()), high)


@pytest.mark.slow
@pytest.mark.drift
def test_nblock_configs_counts_drift():
    """Drift check (run counts excepted): run and regime counts of
    configs/heterogeneous.yaml and configs/nblock.yaml as the physics page states them
    (the figure's middle and right panels)."""
    n_het, n_nb = doc_numbers(
        r"K/W × k2/W, (\d+) runs\) and `configs/heterogeneous.yaml` .*?K/W × spread, (\d+) runs\)"
    )[::-1]
    cells, mixed, stick, away, undecided = doc_numbers(
        r"of the (\d+) grid points of `configs/heterogeneous.yaml`, the four starts disagree at "
        r"(\d+) .*?; (\d+) runs stick-slip, (\d+) run away, (\d+) stay undecided"
    )
    (nb_undecided,) = doc_numbers(r"(\d+) of its \d+ runs stay undecided at `max_t_end`")
    het = compute(load_config(ROOT / "configs" / "heterogeneous.yaml"), show_progress=False)
    nb = compute(load_config(ROOT / "configs" / "nblock.yaml"), show_progress=False)
    assert (het.regime.size, nb.regime.size) == (int(n_het), int(n_nb))
    frac = het.regime_fraction
    assert frac.isel(regime_name=0).size == int(cells)
    assert int((frac.max("regime_name") < 1).sum()) == int(mixed)
    counts = [int((het.regime == REGIMES.index(r)).sum()) for r in REGIMES[1:]]
    assert counts == [int(stick), int(away), int(undecided)]
    assert int((nb.regime == REGIMES.index("undecided")).sum()) == int(nb_undecided)


def test_layout_names_every_module():
    """The Layout section of docs/internals.md lists every module and subpackage of
    ``sweep/``, and none that is gone: the top-level modules under a heading of their own
    (ground floor, faces), each subpackage as ``name/`` with its modules and
    subpackages indented under it."""
    text = (DOCS / "internals.md").read_text()
    layout = text[text.index("## Layout") :]
    layout = layout[: layout.index("\n## ", 1)] if "\n## " in layout[1:] else layout
    block = layout[layout.index("```text") : layout.index("```", layout.index("```text") + 3)]
    groups, group = {}, None
    for line in block.splitlines()[1:]:
        if line and not line.startswith(" "):  # a heading; outside sweep/ (benchmarks/...): none
            heading = re.match(r"(\w+/|[a-z][a-z ]*?)(?:\s{2,}|$)", line)
            group = groups.setdefault(heading[1], set()) if heading else None
        elif group is not None and (entry := re.match(r"  (\w+\.py|\w+/) ", line)):
            group.add(entry[1])
    package = ROOT / "sweep"
    top = {name for name, entries in groups.items() if not name.endswith("/")}
    listed_top = set().union(*(groups[name] for name in top))
    listed_top |= set(re.findall(r"sweep/(\w+\.py)", block))  # named in a description
    assert listed_top == {p.name for p in package.glob("*.py")}
    folders = {name for name in groups if name.endswith("/") and (package / name).is_dir()}
    assert folders == {p.parent.name + "/" for p in package.glob("*/__init__.py")}
    for name in folders:
        present = {p.name for p in (package / name).glob("*.py")} - {"__init__.py"}
        present |= {p.parent.name + "/" for p in (package / name).glob("*/__init__.py")}
        assert groups[name] == present, name


# --- the README as the landing page ------------------------------------------------------


def test_readme_is_a_landing_page():
    """README.md stays short (≤ 250 lines) and points to the documentation."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    assert "make docs" in text and "docs/_build/html/index.html" in text


#: Sentences with numbers that tests/test_models.py reads from README.md (through
#: conftest.readme_numbers); the models page states them too.
SHARED_WITH_MODELS_PAGE = [
    r"η̂ = ηV/W = 0.04: [\d.]+ / [\d.]+ / [\d.]+ at K/Kc = 0.999 / 0.99 / 0.98",
    r"With η̂ = 0.01, v_max/V = [\d.]+ / [\d.]+ / [\d.]+ at K/Kc = 0.5 / 0.9 / 0.99",
]


@pytest.mark.parametrize("pattern", SHARED_WITH_MODELS_PAGE)
def test_readme_and_models_page_state_the_same_numbers(pattern):
    """The limit-cycle numbers test_models.py checks in the README are the ones the
    models page states, so the page cannot drift from the tested README."""
    readme = " ".join((ROOT / "README.md").read_text().split())
    page = " ".join((DOCS / "guide" / "models.md").read_text().split())
    (in_readme,) = re.findall(pattern, readme)
    (in_page,) = re.findall(pattern, page)
    assert in_readme == in_page


# --- defaults and counts the pages state, against the code (issue 40 §6) -----------------


def default_method(model, blocks=1, coupling="chain"):
    """``integrator.method`` of a config that does not set it, for ``model`` and
    ``blocks`` blocks coupled as ``coupling``."""
    from sweep.config.schema import required_parameters

    values = {"A": 0.03, "B": 0.08, "mu0": 0.4, "V": 0.1, "D0": 1.0, "eta_W": 0.01, "m_W": 1.0,
              "k2_W": 0.05}  # fmt: skip
    fixed = {k: values[k] for k in required_parameters(blocks, model) if k != "K_W"}
    raw = {"blocks": blocks, "model": model, "parameters": {**fixed, "Phi0": 1.0},
           "sweep": {"K_W": [0.05]}, **({"coupling": coupling} if blocks > 1 else {})}  # fmt: skip
    return parse_config(raw).integrator.method


def assert_structured_from(sizes, structured):
    """An inertial config that names no method gets ``structured`` from ``sizes`` (chain,
    ring, all-to-all: the numbers a page states) blocks on, the dense method one below."""
    for coupling, n in zip(("chain", "ring", "all"), map(int, sizes), strict=True):
        assert default_method("inertial", n, coupling) == structured, coupling
        assert default_method("inertial", n - 1, coupling) == default_method("inertial"), coupling


def test_readme_names_each_models_default_method():
    """The README's "by default `dop853` …; `rosenbrock` (RODAS4 …) for the stiff
    inertial model" is what a config that names no method gets, model by model, and the
    sentence names every method the parser accepts (the method's own name: its module's
    ``NAME``)."""
    from sweep.codes import METHODS
    from sweep.kernels.methods import MODULES
    from sweep.model.physics import MODELS

    readme = " ".join((ROOT / "README.md").read_text().split())
    sentence = (r"by default `(\w+)`[^;]*; `(\w+)` \((\w+),[^)]*\) for the stiff inertial "
                r"model, and from (\d+) inertial blocks in a chain \((\d+) in a ring, (\d+) all "
                r"to all\) `([\w-]+)`[^;]*; ([^)]*) on request\)")  # fmt: skip
    match = re.search(sentence, readme)
    assert match, "README: the sentence naming the default methods is gone"
    default, inertial, inertial_name, *sizes, structured, others = match.groups()
    for model in MODELS:
        assert default_method(model) == (inertial if model == "inertial" else default), model
    assert_structured_from(sizes, structured)
    assert dict(zip(METHODS, (m.NAME for m in MODULES), strict=True))[inertial] == inertial_name
    assert {default, inertial, structured, *re.findall(r"`([\w-]+)`", others)} == set(METHODS)


def test_models_page_names_each_models_default_method():
    """docs/guide/models.md: the inertial model "defaults to `integrator.method:
    rosenbrock`", to `rosenbrock-structured` "from 10 blocks in a chain, 12 in a ring and
    6 all to all", "the other models default to `integrator.method: dop853`"."""
    (inertial,) = doc_numbers(r"It therefore defaults to `integrator.method: (\w+)`")
    (others,) = doc_numbers(r"The other models default to `integrator.method: (\w+)`")
    *sizes, structured = doc_numbers(
        r"It is the default from (\d+) blocks in a chain, (\d+) in a ring and (\d+) all to "
        r"all \(`integrator.method: ([\w-]+)`\)"
    )
    assert default_method("inertial") == inertial
    assert_structured_from(sizes, structured)
    assert {default_method(m) for m in ("quasi-static", "quasi-dynamic")} == {others}


def test_stated_event_counts_are_the_codes():
    """Counts of events the pages state: the default ``classification.events`` kept per
    run (large sweeps), the longest cycle the classifier recognises (internals), and
    the events a chaotic run's amplitude spans (outputs), against the code."""
    from sweep.config.schema import MAX_EVENTS
    from sweep.kernels.classify import state

    (kept,) = doc_numbers(r"half of it the (\d+) event maxima and intervals kept per run")
    assert int(kept) == Classification().events
    (longest,) = doc_numbers(r"return-map verdicts for cycles of 1 to (\d+) events")
    assert int(longest) == state.MAX_CYCLE_EVENTS
    (spanned,) = doc_numbers(r"the last kept events \(up to (\d+)\) of chaotic")
    assert int(spanned) == state.HISTORY == MAX_EVENTS
