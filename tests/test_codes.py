"""The code tables of ``sweep/codes.py``: one table per choice serves the config parser,
the grid builder, the kernels' codes and the result files' flag values."""

import dataclasses

import numpy as np
import pytest
from conftest import make_config

from sweep import codes, variables
from sweep.config import parse, schema
from sweep.engine.grid import build_grid
from sweep.kernels import layout
from sweep.model import physics
from sweep.results.dataset import build_dataset

TABLES = {
    "MODELS": codes.MODELS,
    "STATE_LAWS": codes.STATE_LAWS,
    "COUPLINGS": codes.COUPLINGS,
    "LYAPUNOV_MODES": codes.LYAPUNOV_MODES,
    "METHODS": codes.METHODS,
    "REGIMES": codes.REGIMES,
    "ATTRACTORS": codes.ATTRACTORS,
}


@pytest.mark.parametrize("table", TABLES)
def test_each_name_has_one_code(table):
    names = list(TABLES[table])
    assert len(set(names)) == len(names)
    assert [codes.code(TABLES[table], name) for name in names] == list(range(len(names)))


def test_the_layout_names_the_codes_of_the_tables():
    named = {
        "MODELS": (layout.QUASI_STATIC, layout.QUASI_DYNAMIC, layout.INERTIAL),
        "STATE_LAWS": (layout.AGING, layout.SLIP),
        "COUPLINGS": (layout.CHAIN, layout.RING, layout.ALL),
        "LYAPUNOV_MODES": (layout.LYAP_NEVER, layout.LYAP_UNSETTLED, layout.LYAP_ALWAYS),
        "REGIMES": (layout.STEADY, layout.STICK_SLIP, layout.RUNAWAY, layout.UNDECIDED),
        "ATTRACTORS": (layout.FIXED_POINT, layout.PERIODIC, layout.QUASI_PERIODIC,
                       layout.CHAOTIC, layout.UNRESOLVED, layout.UNBOUNDED),
    }  # fmt: skip
    for table, values in named.items():
        assert sorted(values) == list(range(len(TABLES[table]))), table


def test_the_config_accepts_the_names_of_the_tables():
    """The parser checks each choice against its table, no copy of it."""
    assert physics.MODELS is codes.MODELS and physics.STATE_LAWS is codes.STATE_LAWS
    assert parse.COUPLINGS is codes.COUPLINGS and schema.LYAPUNOV_MODES is codes.LYAPUNOV_MODES
    assert set(schema.METHODS) == set(codes.METHODS)
    allowed = {f.name: f.metadata["setting"].allowed
               for cls in (schema.Integrator, schema.Classification)
               for f in dataclasses.fields(cls)}  # fmt: skip
    assert set(allowed["method"]) == set(codes.METHODS)
    assert set(allowed["lyapunov"]) == set(codes.LYAPUNOV_MODES)


def test_the_grid_passes_the_codes_and_files_flag_them():
    cfg = make_config({"coupling": "ring", "blocks": 3, "sweep": {"K_W": [0.04], "k2_W": [0.01]}},
                      integrator={"method": "rk4", "t_end": 5.0},
                      classification={"lyapunov": "never"})  # fmt: skip
    g = build_grid(cfg)
    assert g.settings[layout.S_COUPLING] == codes.code(codes.COUPLINGS, "ring")
    assert g.settings[layout.S_METHOD] == codes.code(codes.METHODS, "rk4")
    assert g.settings[layout.S_LYAPUNOV] == codes.code(codes.LYAPUNOV_MODES, "never")
    results = np.zeros((g.n, layout.result_width(g.settings)))
    ds = build_dataset(g, results, np.zeros_like(g.y0))
    for name, table in (("regime", variables.REGIMES), ("attractor", variables.ATTRACTORS)):
        assert table is getattr(codes, f"{name.upper()}S")
        assert ds[name].attrs["flag_meanings"].split() == list(table)
        assert list(ds[name].attrs["flag_values"]) == list(range(len(table)))
