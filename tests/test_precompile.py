"""The list of kernel variants that ``make test`` compiles before the tests
(``tests/precompile.py``): every line names a variant the way ``dispatch.variant`` reads
it from the kernels' arrays, and the shipped configs' kernels (without the tangent, which the
suite compiles only where a test needs it) are on it."""

from pathlib import Path

import precompile
import pytest

from sweep import codes
from sweep.config import load_config
from sweep.engine import dispatch
from sweep.engine.grid import build_grid

CONFIGS = sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.yaml"))


@pytest.mark.parametrize("tier", sorted(precompile.VARIANTS))
def test_every_line_is_one_variant_read_back_from_its_arrays(tier):
    lines = precompile.listed(tier)
    assert lines, "no variants listed"
    # precompile.job asserts that dispatch.variant reads the line back from the arrays
    variants = [dispatch.variant(*precompile.job(words)) for words in lines]
    assert len(set(variants)) == len(variants), "a variant listed twice"


def test_the_fast_tier_compiles_every_method_model_and_coupling():
    """``make test`` compiles every method, model and coupling, unequal blocks, the
    tangent and the catalogue at least once (issue 51), and nothing the full tier does
    not. The slip law's grid kernels are on the full tier's list only: a group of
    kernels of their own (about 15 s of CPU once the shared helpers are cached) and
    its monodromy kernel (about 10 s more) in a fresh ``make test``."""
    fast = precompile.listed("fast")
    for column, table in enumerate(precompile.TABLES):
        if table is not codes.STATE_LAWS:
            assert {words[column] for words in fast} == set(table), table
    assert {tuple(w) for w in fast} <= {tuple(w) for w in precompile.listed("all")}


@pytest.mark.slow
def test_the_shipped_configs_variants_are_listed():
    listed = {tuple(words) for words in precompile.listed()}
    missing = set()
    for path in CONFIGS:
        g = build_grid(load_config(path))
        for params, settings, tangent in dispatch.kernel_jobs(g.params, g.settings):
            words = tuple(precompile.variant_names(dispatch.variant(params, settings, tangent)))
            if words not in listed:
                missing.add((path.name, words))
    assert not missing, sorted(missing)
