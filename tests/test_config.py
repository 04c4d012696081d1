"""Config validation: every bad config is refused with exit status 2, a message naming
the file and the key, and no change to an existing result."""

import math

import numpy as np
import pytest
import yaml
from conftest import ROOT, config_dict, kc_w, make_config, write_config

from sweep import cli
from sweep.cli import main
from sweep.codes import METHODS
from sweep.config import ConfigError, load_config, parse_config
from sweep.config.schema import STRUCTURED_FROM, default_method
from sweep.results.dataset import settings_attrs

SENTINEL = b"an earlier result that must survive\n"

# (id, overrides of the base config, the key path the message must name)
BAD_CONFIGS = [
    ("missing blocks", {"blocks": None}, "blocks"),
    ("missing parameter", {"parameters": {"A": None}}, "parameters.A"),
    ("missing sweep", {"sweep": None}, "sweep"),
    ("unknown top-level key", {"colour": "red"}, "colour"),
    ("unknown parameter", {"parameters": {"C": 1.0}}, "parameters.C"),
    ("unknown integrator key", {"integrator": {"order": 5}}, "integrator.order"),
    ("unknown classification key", {"classification": {"v_cap": 1e6}}, "classification.v_cap"),
    (
        "unknown axis key",
        {"sweep": {"K_W": {"start": 0.04, "stop": 0.06, "step": 0.01}}},
        "sweep.K_W",
    ),
    ("unknown sweep axis", {"sweep": {"K": [0.05]}}, "sweep.K"),
    ("wrong type parameter", {"parameters": {"A": "0.03"}}, "parameters.A"),
    ("wrong type blocks", {"blocks": "one"}, "blocks"),
    ("wrong type bool", {"parameters": {"A": True}}, "parameters.A"),
    ("wrong type rtol", {"integrator": {"rtol": "tight"}}, "integrator.rtol"),
    (
        "wrong type early_exit",
        {"classification": {"early_exit": "yes"}},
        "classification.early_exit",
    ),
    ("wrong type section", {"integrator": [1, 2]}, "integrator"),
    ("A zero", {"parameters": {"A": 0.0}}, "parameters.A"),
    ("A negative", {"parameters": {"A": -0.01}}, "parameters.A"),
    ("D0 zero", {"parameters": {"D0": 0.0}}, "parameters.D0"),
    ("D0 negative", {"parameters": {"D0": -1.0}}, "parameters.D0"),
    ("V zero", {"parameters": {"V": 0.0}}, "parameters.V"),
    ("V negative", {"parameters": {"V": -0.1}}, "parameters.V"),
    ("K_W zero on axis", {"sweep": {"K_W": [0.0, 0.05]}}, "sweep.K_W"),
    (
        "K_W negative start",
        {"sweep": {"K_W": {"start": -0.01, "stop": 0.06, "num": 3}}},
        "sweep.K_W",
    ),
    (
        "K_W zero fixed",
        {"parameters": {"K_W": 0.0, "D0": None}, "sweep": {"K_W": None, "D0": [1.0, 2.0]}},
        "parameters.K_W",
    ),
    ("B negative", {"parameters": {"B": -0.08}}, "parameters.B"),
    ("empty axis list", {"sweep": {"K_W": []}}, "sweep.K_W"),
    ("empty axis values", {"sweep": {"K_W": {"values": []}}}, "sweep.K_W"),
    ("axis num zero", {"sweep": {"K_W": {"start": 0.04, "stop": 0.06, "num": 0}}}, "sweep.K_W.num"),
    ("no axis", {"sweep": {"K_W": None}}, "sweep"),
    ("nan on axis", {"sweep": {"K_W": [0.04, math.nan]}}, "sweep.K_W"),
    ("inf on axis", {"sweep": {"K_W": [0.04, math.inf]}}, "sweep.K_W"),
    (
        "inf axis stop",
        {"sweep": {"K_W": {"start": 0.04, "stop": math.inf, "num": 3}}},
        "sweep.K_W.stop",
    ),
    ("nan parameter", {"parameters": {"B": math.nan}}, "parameters.B"),
    ("initial wrong length", {"initial": {"v_over_V": [1.0, 1.0]}}, "initial.v_over_V"),
    ("initial not positive", {"initial": {"phi_over_phi_ss": 0.0}}, "initial.phi_over_phi_ss"),
    ("rtol out of range", {"integrator": {"rtol": 1.0}}, "integrator.rtol"),
    ("method unknown", {"integrator": {"method": "euler"}}, "integrator.method"),
    ("cap below one", {"classification": {"v_cap_over_V": 0.5}}, "classification.v_cap_over_V"),
    ("mass on quasi-static", {"parameters": {"m_W": 1.0}}, "parameters.m_W"),
    ("coupling on one block", {"parameters": {"k2_W": 0.05}}, "parameters.k2_W"),
    ("output not netcdf", {"output": "out.txt"}, "output"),
    ("refine not a mapping", {"refine": [4]}, "refine"),
    ("refine unknown key", {"refine": {"level": 4}}, "refine.level"),
    ("refine levels above 20", {"refine": {"levels": 21}}, "refine.levels"),
    ("refine levels not an integer", {"refine": {"levels": 2.5}}, "refine.levels"),
    ("refine max_runs below the grid", {"refine": {"max_runs": 1}}, "refine.max_runs"),
    ("refine unknown output", {"refine": {"outputs": ["regim"]}}, "refine.outputs[0]"),
    ("refine outputs not a list", {"refine": {"outputs": "regime"}}, "refine.outputs"),
    ("refine fraction without ensemble", {"refine": {"outputs": ["regime_fraction"]}},
     "refine.outputs[0]"),
    ("refine rtol zero", {"refine": {"rtol": 0}}, "refine.rtol"),
    ("refine to zarr", {"refine": {}, "output": "results/test.zarr"}, "output"),
    ("refine one value per axis", {"refine": {}, "sweep": {"K_W": [0.05]}}, "refine"),
    ("method as a list", {"integrator": {"method": ["dop853"]}}, "integrator.method"),
    ("method as a mapping", {"integrator": {"method": {"dop853": 1}}}, "integrator.method"),
    ("confirm_cycles past 32 bits", {"classification": {"confirm_cycles": 3_000_000_000}},
     "classification.confirm_cycles"),
    ("seed past 32 bits", {"initial": {"ensemble": 2, "seed": 2**32 - 1}}, "initial.seed"),
    ("blocks past the limit", {"blocks": 10**12}, "blocks"),
    ("axis of 1e12 points", {"sweep": {"K_W": {"start": 0.04, "stop": 0.06, "num": 10**12}}},
     "sweep.K_W.num"),
    ("ensemble of 1e12", {"initial": {"ensemble": 10**12}}, "initial.ensemble"),
    ("1e10 runs", {"sweep": {"K_W": {"start": 0.04, "stop": 0.06, "num": 100_000}},
                   "initial": {"ensemble": 100_000}}, "the sweep has 1e+10 runs"),
]  # fmt: skip


@pytest.fixture
def sentinel_output(in_tmp):
    """An earlier result at the path the configs write to."""
    out = in_tmp / "results" / "test.nc"
    out.parent.mkdir()
    out.write_bytes(SENTINEL)
    return out


def run_cli(argv, capsys):
    status = cli.main(argv)
    return status, capsys.readouterr()


@pytest.mark.parametrize(
    "overrides, key", [c[1:] for c in BAD_CONFIGS], ids=[c[0] for c in BAD_CONFIGS]
)
def test_bad_config_exits_2_and_names_file_and_key(in_tmp, sentinel_output, capsys, overrides, key):
    path = write_config(in_tmp / "bad.yaml", overrides)
    status, captured = run_cli(["run", str(path), "--quiet"], capsys)
    assert status == 2
    assert str(path) in captured.err
    assert key in captured.err, captured.err
    assert captured.out == ""
    assert sentinel_output.read_bytes() == SENTINEL
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert any(key in problem for problem in info.value.problems)


REFERENCE = "parameters must give exactly one of V0 (um/s) or Phi0 (s), the reference point"


@pytest.mark.parametrize(
    "overrides, message",
    [
        (
            {"parameters": {"K_W": 0.05}},  # K_W is swept by the base config
            "parameters.K_W is also a sweep axis; give it in one place only",
        ),
        (
            {"parameters": {"V0": 1.0}},  # beside the base config's Phi0
            f"{REFERENCE} of the friction law; got ['V0', 'Phi0']",
        ),
        ({"parameters": {"Phi0": None}}, f"{REFERENCE} of the friction law; got neither"),
        (
            {"parameters": {"Phi0": None}, "sweep": {"Phi0": [1.0, 2.0], "V0": [1.0]}},
            f"{REFERENCE} of the friction law; got ['V0', 'Phi0']",
        ),
    ],
    ids=["fixed and swept", "V0 and Phi0", "neither V0 nor Phi0", "V0 and Phi0 swept"],
)
def test_fixed_or_swept_and_one_reference_point(in_tmp, sentinel_output, capsys, overrides,
                                                message):  # fmt: skip
    """The README's "a parameter is either fixed or swept, not both" and "exactly one of
    Phi0 / V0", through the CLI: exit status 2, the file and the message."""
    path = write_config(in_tmp / "bad.yaml", overrides)
    status, captured = run_cli(["run", str(path), "--quiet"], capsys)
    assert status == 2
    assert f"{path}: {message}" in captured.err, captured.err
    assert sentinel_output.read_bytes() == SENTINEL


def test_all_problems_are_reported_together():
    overrides = {"parameters": {"A": -1.0, "D0": 0.0}, "integrator": {"method": "euler"}}
    with pytest.raises(ConfigError) as info:
        make_config(overrides, source="many.yaml")
    text = str(info.value)
    for key in ("parameters.A", "parameters.D0", "integrator.method"):
        assert f"many.yaml: {key}" in text
    assert "must be in (0, inf), got -1" in text  # what is allowed and what was found


def test_bad_axis_is_reported_once():
    """A swept parameter with a bad value is not also reported as missing."""
    with pytest.raises(ConfigError) as info:
        make_config(sweep={"K_W": [0.04, math.nan]})
    assert info.value.problems == ["sweep.K_W[1] must be a finite number in (0, inf), got nan"]


def test_bad_axis_range_names_what_was_written():
    """A range with a bad end is reported with that end, not with a value inside the grid
    (it used to say ``sweep.K_W must be in (0, inf), got -0.00875``)."""
    with pytest.raises(ConfigError) as info:
        make_config(sweep={"K_W": {"start": -0.05, "stop": 0.06, "num": 9}})
    assert info.value.problems == ["sweep.K_W.start must be in (0, inf), got -0.05"]


def test_b_zero_is_allowed():
    """B may be zero (no evolution effect); only B < 0 is refused."""
    assert make_config(parameters={"B": 0.0}).fixed["B"] == 0.0


def test_yaml_exponent_floats_are_numbers():
    """1e6 and 1.0e-8 are floats (YAML 1.2 style), not strings."""
    text = yaml.safe_dump(config_dict(classification=None, integrator=None)) + (
        "classification:\n  v_cap_over_V: 1e6\nintegrator:\n  rtol: 1.0e-8\n  atol: 1e-10\n"
    )
    config = parse_config(text)
    assert config.classification.v_cap_over_V == 1e6
    assert config.integrator.rtol == 1e-8 and config.integrator.atol == 1e-10


@pytest.mark.parametrize("where", ["config", "--out"])
@pytest.mark.parametrize("target", ["under a file", "proc"])
def test_unwritable_output_exits_2(in_tmp, sentinel_output, capsys, where, target):
    """An output under a regular file, or in /proc, is refused before any run; the
    blocking file and an earlier result stay byte-identical."""
    blocker = in_tmp / "blocker"
    blocker.write_bytes(SENTINEL)
    out = str(blocker / "out.nc") if target == "under a file" else "/proc/rsf-sweep-test/out.nc"
    if where == "config":
        path = write_config(in_tmp / "c.yaml", output=out)
        argv, key = ["run", str(path), "--quiet"], "output"
    else:
        path = write_config(in_tmp / "c.yaml")
        argv, key = ["run", str(path), "--quiet", "--out", out], "--out"
    status, captured = run_cli(argv, capsys)
    assert status == 2
    assert str(path) in captured.err and key in captured.err and out in captured.err
    assert blocker.read_bytes() == SENTINEL
    assert sentinel_output.read_bytes() == SENTINEL


def test_output_directory_is_refused(in_tmp, capsys):
    path = write_config(in_tmp / "c.yaml")
    (in_tmp / "dir.nc").mkdir()
    status, captured = run_cli(["run", str(path), "--quiet", "--out", "dir.nc"], capsys)
    assert status == 2 and "is a directory" in captured.err


def test_bad_axis_names_its_real_interval_and_each_bad_value():
    """A range end that is not a number is named with the parameter's interval, and
    listed values that are not numbers each with their index (not as "not distinct")."""
    with pytest.raises(ConfigError) as info:
        make_config(sweep={"K_W": {"start": "abc", "stop": 0.06, "num": 3}})
    assert info.value.problems == ["sweep.K_W.start must be a number in (0, inf), got 'abc'"]
    with pytest.raises(ConfigError) as info:
        make_config(sweep={"K_W": ["a", 0.05, True]})
    assert info.value.problems == [
        "sweep.K_W[0] must be a number in (0, inf), got 'a'",
        "sweep.K_W[2] must be a number in (0, inf), got True",
    ]
    with pytest.raises(ConfigError, match=r"sweep.K_W.values must be distinct, got \[0.05, 0.05\]"):
        make_config(sweep={"K_W": [0.05, 0.05]})


@pytest.mark.parametrize("where", ["top", "parameters", "sweep"])
def test_a_key_given_twice_is_refused(in_tmp, sentinel_output, capsys, where):
    """YAML keeps the last of a repeated key silently; a config names it and its lines
    instead, and nothing is run or overwritten."""
    text = write_config(in_tmp / "c.yaml").read_text()
    repeated = {"top": ("blocks: 1\n", "blocks: 1\nblocks: 2\n", "'blocks'"),
                "parameters": ("  A: ", "  A: 0.5\n  A: ", "'A'"),
                "sweep": ("sweep:\n", "sweep:\n  K_W: [0.04]\n", "'K_W'")}[where]  # fmt: skip
    assert text.count(repeated[0]) == 1
    path = in_tmp / "twice.yaml"
    path.write_text(text.replace(repeated[0], repeated[1]))
    status, captured = run_cli(["run", str(path), "--quiet"], capsys)
    assert status == 2 and str(path) in captured.err
    assert f"key {repeated[2]} is given twice" in captured.err, captured.err
    assert sentinel_output.read_bytes() == SENTINEL


@pytest.mark.parametrize("given", [None, 123, [1, 2], b"blocks: 1", ""])
def test_load_config_of_something_else_says_what_a_config_is(given):
    with pytest.raises(ConfigError, match="a config must be a YAML file's path, a packaged"):
        load_config(given)


def test_a_result_file_given_as_config_exits_2(in_tmp, capsys):
    path = in_tmp / "result.nc"
    path.write_bytes(b"\x89HDF\r\n\x1a\n\xff\xfe binary")
    status, captured = run_cli(["run", str(path)], capsys)
    assert status == 2 and f"{path}: cannot read config: not UTF-8 text" in captured.err


def test_missing_config_file_exits_2(in_tmp, capsys):
    status, captured = run_cli(["run", "nowhere.yaml"], capsys)
    assert status == 2
    assert "nowhere.yaml" in captured.err and "cannot read config" in captured.err


def test_not_yaml_exits_2(in_tmp, capsys):
    path = in_tmp / "broken.yaml"
    path.write_text("blocks: [1,\n")
    status, captured = run_cli(["run", str(path)], capsys)
    assert status == 2 and str(path) in captured.err and "not valid YAML" in captured.err


def test_config_is_frozen_and_keeps_its_text():
    config = make_config()
    with pytest.raises(AttributeError):
        config.blocks = 2
    assert "K_W" in config.text
    assert config.shape == (2,)
    assert config.fixed["D0"] == 1.0


def test_classification_settings_and_retired_keys():
    """max_t_end left out follows t_end (None: ten times it); below t_end it is refused;
    retired keys name their replacement; max_step .inf means no cap."""
    config = make_config(integrator={"max_step": math.inf})
    assert config.classification.max_t_end is None and config.integrator.max_step == math.inf
    assert make_config(classification={"max_t_end": 5000.0}).classification.max_t_end == 5000.0
    with pytest.raises(ConfigError) as err:
        make_config(
            integrator={"t_end": 100.0},
            classification={"max_t_end": 50.0, "envelope_tolerance": 1e-4, "trend_cycles": 3},
        )
    text = str(err.value)
    assert "classification.max_t_end must be at least integrator.t_end (100), got 50" in text
    for old, new in (("envelope_tolerance", "accuracy"), ("trend_cycles", "confirm_cycles")):
        assert f"classification.{old} is no longer used; use classification.{new}" in text
    with pytest.raises(ConfigError, match=r"classification.accuracy must be in \(0, 0.5\]"):
        make_config(classification={"accuracy": 0.0})


# --- the models' configs (issue 3) ---------------------------------------------------


def test_inertial_model_defaults_to_rosenbrock():
    def method(model, extra, **integrator):
        overrides = {"model": model, "parameters": extra, "integrator": None}
        return make_config(overrides, integrator=integrator).integrator.method

    assert method("inertial", {"m_W": 1.0}) == "rosenbrock"
    assert method("quasi-dynamic", {"eta_W": 0.1}) == "dop853"
    assert method("inertial", {"m_W": 1.0}, method="dopri5") == "dopri5"


def blocks_config(blocks, coupling=None, model="inertial", **integrator):
    """A config of ``blocks`` blocks of ``model`` coupled as ``coupling`` (None: the key
    left out, an open chain) with the ``integrator`` settings given (no others)."""
    extra = {"inertial": {"m_W": 1.0}, "quasi-dynamic": {"eta_W": 0.1}}.get(model, {})
    overrides = {"blocks": blocks, "model": model, "integrator": None,
                 "parameters": {**extra, **({"k2_W": 0.05} if blocks > 1 else {})}}  # fmt: skip
    if coupling is not None:
        overrides["coupling"] = coupling
    return make_config(overrides, integrator=integrator)


@pytest.mark.parametrize("coupling", sorted(STRUCTURED_FROM))
def test_inertial_default_is_structured_from_the_crossing(coupling):
    """An inertial config that names no method gets the dense ``rosenbrock`` below
    ``STRUCTURED_FROM`` blocks of its coupling and ``rosenbrock-structured`` from there on
    (cheaper per step there: ``bench_structured_crossing``), with the same step cap; the
    parsed config and the result's attributes hold the method chosen; a named method is
    kept at any size; the other models keep ``dop853``."""
    n = STRUCTURED_FROM[coupling]
    assert n > 2  # systems of one or two inertial blocks (the stack kernel) stay dense
    below, at = blocks_config(n - 1, coupling).integrator, blocks_config(n, coupling).integrator
    assert (below.method, at.method) == ("rosenbrock", "rosenbrock-structured")
    assert below.max_step == at.max_step == 0.5
    assert blocks_config(4 * n, coupling).integrator.method == "rosenbrock-structured"
    for method in ("rosenbrock", "dopri5"):
        assert blocks_config(4 * n, coupling, method=method).integrator.method == method
    assert blocks_config(n - 1, coupling, method="rosenbrock-structured").integrator.method == (
        "rosenbrock-structured"
    )
    assert blocks_config(4 * n, coupling, "quasi-dynamic").integrator.method == "dop853"
    if coupling == "chain":  # no coupling key: an open chain
        assert blocks_config(n - 1).integrator.method == "rosenbrock"
        assert blocks_config(n).integrator.method == "rosenbrock-structured"
    assert settings_attrs("integrator", at)["integrator_method"] == "rosenbrock-structured"
    assert default_method("inertial", n, coupling) == "rosenbrock-structured"
    assert default_method("inertial", 1) == "rosenbrock"


def test_shipped_configs_keep_their_methods():
    """Every shipped config names its method, so none changes with the default; the
    inertial ones name the method they would get without it (one or two blocks: the
    dense ``rosenbrock``; the 100-block chain: ``rosenbrock-structured``)."""
    for path in sorted((ROOT / "configs").glob("*.yaml")):
        raw = yaml.safe_load(path.read_text())
        config = load_config(path)
        assert raw["integrator"]["method"] == config.integrator.method, path.name
        if config.model == "inertial":
            want = default_method("inertial", config.blocks, config.coupling)
            assert config.integrator.method == want, path.name


def test_only_rosenbrock_caps_its_steps_by_default():
    """DOPRI5 and DOP853 take the steps their controller asks for; RODAS4, which reads
    extrema from a cubic Hermite interpolant, keeps 0.5 D0/V unless told otherwise."""

    def max_step(model, extra, **integrator):
        overrides = {"model": model, "parameters": extra, "integrator": None}
        return make_config(overrides, integrator=integrator).integrator.max_step

    assert max_step("quasi-static", {}) == math.inf
    assert max_step("quasi-static", {}, method="dopri5") == math.inf
    assert max_step("inertial", {"m_W": 1.0}) == 0.5
    assert max_step("quasi-static", {}, method="rosenbrock") == 0.5
    assert max_step("inertial", {"m_W": 1.0}, max_step=2.0) == 2.0
    assert max_step("inertial", {"m_W": 1.0}, max_step=math.inf) == math.inf
    assert max_step("inertial", {"m_W": 1.0}, method="dop853") == math.inf


def raw_config(model_name="quasi-dynamic", law="aging", parameters=None, sweep=None, **other):
    """``conftest.config_dict`` for ``model_name`` (with the parameter it needs), ``law``
    and ``sweep`` (replacing the base axes), then the changes ``other``."""
    params = {"quasi-dynamic": {"eta_W": 0.1}, "inertial": {"m_W": 1.0}}.get(model_name, {})
    params |= parameters or {}
    sweep = sweep or {"K_W": [0.04]}
    params |= {name: None for name in sweep if name in params}  # swept, so not fixed
    base = {"model": model_name, "state_law": law, "sweep": None, "integrator": None}
    return config_dict(base, parameters=params, sweep=sweep, **other)


BAD_MODEL_CONFIGS = [
    (raw_config(parameters={"eta_W": -0.1}), "parameters.eta_W must be in [0, inf), got -0.1"),
    (
        raw_config(sweep={"K_W": [0.04], "eta_W": [0.1, -0.2]}),
        "sweep.eta_W[1] must be in [0, inf), got -0.2",
    ),
    (
        raw_config("inertial", parameters={"m_W": -1.0}),
        "parameters.m_W must be in [0, inf), got -1",
    ),
    (
        raw_config("inertial", parameters={"m_W": 0.0}),
        "parameters.m_W must be in (0, inf) for model inertial, got 0",
    ),
    (
        raw_config("inertial", sweep={"K_W": [0.04], "m_W": [0.0, 1.0]}),
        "sweep.m_W must be in (0, inf) for model inertial, got 0",
    ),
    (
        raw_config("dynamic"),
        "model must be one of quasi-static, quasi-dynamic, inertial; got 'dynamic'",
    ),
    (raw_config(law="ruina"), "state_law must be one of aging, slip; got 'ruina'"),
    (
        raw_config(integrator={"method": "radau"}),
        f"integrator.method must be one of {', '.join(METHODS)}; got 'radau'",
    ),
    (
        raw_config("quasi-static", parameters={"eta_W": 0.1}),
        "parameters.eta_W only applies to model quasi-dynamic",
    ),
]


@pytest.mark.parametrize("raw, message", BAD_MODEL_CONFIGS)
def test_bad_model_values_are_rejected(tmp_path, capsys, raw, message):
    """Exit status 2, the file and the offending key in the message, nothing written."""
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    out = tmp_path / "out.nc"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert str(path) in err
    assert not out.exists()


@pytest.mark.parametrize(
    "name, model_name, law, second",
    [
        ("quasidynamic", "quasi-dynamic", "aging", "eta_W"),
        ("inertial", "inertial", "aging", "m_W"),
        ("slip_law", "quasi-dynamic", "slip", "eta_W"),
    ],
)
def test_shipped_model_configs(name, model_name, law, second):
    """The new configs: model and law as named, a K/W × (η/W or m/W) grid whose
    K/W axis brackets Kc for every value of the second axis, with no grid point on
    Kc; m/W spans at least two decades."""
    config = load_config(f"configs/{name}.yaml")
    assert (config.model, config.state_law) == (model_name, law)
    axes = {a.name: np.array(a.values) for a in config.axes}
    assert set(axes) == {"K_W", second}
    for value in axes[second]:
        kc = kc_w(model_name, **{second.lower(): value})
        assert axes["K_W"].min() < kc < axes["K_W"].max()
        assert np.abs(axes["K_W"] / kc - 1).min() > 1e-3
    if second == "m_W":
        assert axes["m_W"].max() / axes["m_W"].min() >= 100.0


def test_refine_errors_say_what_is_allowed():
    """Each bad refine value is named with its key, what is allowed and what was given,
    all in one error."""
    with pytest.raises(ConfigError) as info:
        make_config(refine={"levels": -1, "max_runs": 1, "outputs": ["period", "colour"],
                            "rtol": -0.1})  # fmt: skip
    problems = info.value.problems
    assert "refine.levels must be an integer in [0, 20], got -1" in problems
    assert (
        "refine.max_runs must be an integer in [2, 2147483647], got 1 (the 2 runs of the grid come "
        "first)" in problems
    )
    assert "refine.rtol must be in (0, inf), got -0.1" in problems
    (unknown,) = [p for p in problems if p.startswith("refine.outputs[1]")]
    assert "must be an output variable of this sweep, one of regime, attractor" in unknown
    assert unknown.endswith("got 'colour'")
    assert len(problems) == 4


def test_refine_defaults_and_round_trip():
    """An empty section takes the defaults (an ensemble refines on regime_fraction);
    config_mapping writes the section and the ranges back, so with_changes keeps them."""
    from sweep.config import config_mapping, with_changes

    config = make_config(refine={})
    assert (config.refine.levels, config.refine.max_runs, config.refine.outputs) == (
        6, None, ("regime", "attractor", "cycle_events"),
    )  # fmt: skip
    ensemble = make_config(refine={}, initial={"ensemble": 2})
    assert ensemble.refine.outputs == ("regime_fraction",)
    ranged = make_config(sweep={"K_W": {"start": 0.04, "stop": 0.06, "num": 5, "scale": "log"}},
                         refine={"levels": 3})  # fmt: skip
    again = parse_config(config_mapping(ranged))
    assert (again.refine, again.axes) == (ranged.refine, ranged.axes)
    assert again.axes[0].span == ("log", 0.04, 0.06)
    assert with_changes(ranged, {"refine": {"levels": 5}}).axes == ranged.axes


@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "configs").glob("*.yaml")))
def test_shipped_configs_round_trip_and_take_another_number_of_blocks(name):
    """Every shipped config reads back as itself from config_mapping; with_changes of
    ``blocks`` alone starts each block where the file starts them all, and where the
    file gives the blocks different starts it says which key needs one per block."""
    from sweep.config import config_mapping, with_changes

    config = load_config(ROOT / "configs" / f"{name}.yaml")
    again = parse_config(config_mapping(config), config.source)
    assert again.initial == config.initial and again.blocks == config.blocks
    if config.block_parameters:  # per-block values, one per block: the user gives them
        return
    changed, starts = config.blocks + 3, config.initial
    if len(set(starts.v_over_V)) == 1 and len(set(starts.phi_over_phi_ss)) == 1:
        extra = {} if config.blocks > 1 else {"parameters": {"k2_W": 0.5}}
        more = with_changes(config, {"blocks": changed, **extra})
        assert more.initial.v_over_V == (starts.v_over_V[0],) * changed
        assert more.initial.phi_over_phi_ss == (starts.phi_over_phi_ss[0],) * changed
    else:
        with pytest.raises(ConfigError, match=f"list of {changed} \\(one per block\\)"):
            with_changes(config, {"blocks": changed})
