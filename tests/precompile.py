"""The kernel variants a tier of the test suite runs, compiled once before its tests
(``make test``, ``make test-all``).

A variant (model, state law, method, coupling, equal or unequal blocks, with or without
the tangent, with or without a catalogue, state size: ``dispatch.variant``) compiles in
6-10 s; the suite uses about ninety. Left to the tests, two pytest workers and the
processes that tests start compile them as each first needs one, often the same one at
once. Here they are compiled side by side in one fresh process per core, each variant
once, into numba's cache (``dispatch.load_kernels``), and the tests then load them. A
variant missing from the list is still compiled by the first test that needs it: the
list makes the suite faster, never different.

    python tests/precompile.py [--tier fast]            # compile a tier's variants
    python tests/precompile.py [--tier fast] --write    # list what the cache holds

Each tier has its list (:data:`VARIANTS`): ``fast`` the variants of ``make test`` (the
tests not marked ``slow``), ``all`` those of ``make test-all``. ``--write`` reads the
names of the grid kernels' files in numba's cache folder of ``sweep/kernels``
(``NUMBA_CACHE_DIR`` if set): run it in a fresh clone after ``make test`` (``--tier
fast``) or ``make test-all``, whose cache then holds exactly what the tier compiled.
"""

import argparse
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sweep import codes  # noqa: E402
from sweep.engine import dispatch  # noqa: E402
from sweep.kernels import layout  # noqa: E402

#: Per tier, the list of its variants, one per line: model, state law, method, coupling,
#: blocks (equal, unequal), tangent (plain, tangent), catalogue (plain, catalogue) and
#: the state size its kernel is compiled for (0: any).
VARIANTS = {
    "fast": Path(__file__).parent / "data" / "kernel_variants_fast.txt",
    "all": Path(__file__).parent / "data" / "kernel_variants.txt",
}
BLOCKS, TANGENT, CATALOGUE = ("equal", "unequal"), ("plain", "tangent"), ("plain", "catalogue")
TABLES = (codes.MODELS, codes.STATE_LAWS, tuple(codes.METHODS), codes.COUPLINGS, BLOCKS,
          TANGENT, CATALOGUE)  # fmt: skip


def variant_names(variant):
    """A variant tuple of ``dispatch.variant`` as the words of one line of the list."""
    *coded, n_fixed = variant
    return [table[int(c)] for table, c in zip(TABLES, coded, strict=True)] + [str(n_fixed)]


def job(words):
    """The (params, settings, tangent) job of ``dispatch.load_kernels`` for one line."""
    *named, n_fixed = words
    model, law, method, coupling, unequal, tangent, catalogue = (
        codes.code(table, name) for table, name in zip(TABLES, named, strict=True)
    )
    per_block = layout.values_per_block(model)
    n_blocks = int(n_fixed) // per_block or dispatch.STACK_STATE_MAX // per_block + 1
    settings = np.zeros(layout.N_SETTINGS)
    for column, value in ((layout.S_MODEL, model), (layout.S_LAW, law),
                          (layout.S_METHOD, method), (layout.S_COUPLING, coupling),
                          (layout.S_NBLOCKS, n_blocks),
                          (layout.S_CATALOGUE, catalogue)):  # fmt: skip
        settings[column] = value
    width = layout.N_PARAMS + (layout.N_BLOCK_PARAMS * n_blocks if unequal else 0)
    out = (np.empty((0, width)), settings, bool(tangent))
    assert variant_names(dispatch.variant(*out)) == list(words), words
    return out


def listed(tier="all"):
    """The variants of ``tier``'s list (:data:`VARIANTS`), as lists of words."""
    lines = VARIANTS[tier].read_text().splitlines()
    return [line.split() for line in lines if line.strip() and not line.startswith("#")]


def cached_variants():
    """The variants whose grid kernels numba's cache folder of ``sweep/kernels`` holds."""
    pattern, elsewhere = "integrate.*integrate_grid_*.nbi", os.environ.get("NUMBA_CACHE_DIR")
    if elsewhere:
        matches = Path(elsewhere).rglob(pattern)
    else:
        matches = (ROOT / "sweep" / "kernels" / "__pycache__").glob(pattern)
    found = set()
    for path in matches:
        # of 8 codes: not the older kernels of the bit-identity reference in the same cache
        codes_ = re.search(r"integrate_grid((?:_\d+){8})-", path.name)
        if codes_ is not None:
            found.add(tuple(int(c) for c in codes_.group(1).split("_")[1:]))
    return [variant_names(v) for v in sorted(found)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tier", choices=sorted(VARIANTS), default="all",
                        help="the tests of make test (fast) or of make test-all (all)")  # fmt: skip
    parser.add_argument("--write", action="store_true", help="list the cached variants")
    args = parser.parse_args(argv)
    if args.write:
        rows = cached_variants()
        header = ("# model law method coupling blocks tangent catalogue state_size "
                  "(tests/precompile.py)\n")  # fmt: skip
        VARIANTS[args.tier].write_text(header + "".join(" ".join(r) + "\n" for r in rows))
        print(f"wrote {len(rows)} variants to {VARIANTS[args.tier]}")
        return 0
    import numba

    from sweep.accelerate import CACHE

    if numba.config.DISABLE_JIT or not CACHE:
        print("precompile: no JIT or no cache (NUMBA_DISABLE_JIT, SWEEP_NUMBA_CACHE): skipped")
        return 0
    jobs = [job(words) for words in listed(args.tier)]
    start = time.perf_counter()
    print(f"compiling (or loading) the {len(jobs)} kernel variants of the tier {args.tier} ...",
          flush=True)  # fmt: skip
    dispatch.load_kernels(jobs, here=False)
    print(f"... in {time.perf_counter() - start:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
