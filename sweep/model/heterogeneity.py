"""Per-block parameter values: lists, seeded relative spreads, the reference scale.

Each of A, B, D0 and K_W may differ between blocks. A config gives either a list of
``blocks`` values, or a relative spread ``s`` of a common value ``x``::

    x_i = x (1 + s ξ_i),    ξ_i ~ U(−1, 1) (uniform) or N(0, 1) (normal)

The pattern ξ is drawn once from the seed, one row per parameter in the order of
:data:`PER_BLOCK` (a spread on one parameter leaves the others' patterns alone), and
is the same at every grid point of that seed: a swept spread size (axis
``spread_<name>``) scales one realisation. The seed is ``spread.seed``, or swept as the
axis ``spread_seed`` (:data:`SEED_AXIS`): each of its values is one realisation of the
disorder, the pattern :func:`spread_pattern` draws from it (a one-value axis gives the
numbers of ``spread.seed`` with that value, bit for bit). A row's pattern depends on its
seed only, so no result depends on chunking, threads or resuming. Seeds are categories,
not points of a range: refinement does not split them (a config with ``refine`` and a
seed axis is refused), and a seed axis needs a spread size above 0 (else every seed runs
the same systems). ``x`` is the
parameter's scalar or swept value; for a list it is the list's mean (the common
value stored as the parameter's coordinate). A swept K_W with a K_W spread: the
spread multiplies the swept value, so ``critical_K_W`` is that common K_W at onset.

Plain numpy; the kernels see the results as per-block parameter columns
(``grid.build_grid``).
"""

import numpy as np

#: Parameters that may differ between blocks, in the order the spread rows are drawn.
PER_BLOCK = ("A", "B", "D0", "K_W")
DISTRIBUTIONS = ("uniform", "normal")
#: A sweep axis ``spread_<name>`` sweeps the relative spread of parameter ``name``.
SPREAD_PREFIX = "spread_"
#: The sweep axes of relative spreads: spread_A, spread_B, spread_D0, spread_K_W.
SPREAD_AXES = tuple(SPREAD_PREFIX + name for name in PER_BLOCK)
#: The sweep axis of seeds of the pattern ξ: one realisation of the disorder per value.
SEED_AXIS = SPREAD_PREFIX + "seed"


def spread_pattern(n_blocks, distribution="uniform", seed=0):
    """The relative pattern ξ (name → array of ``n_blocks``), drawn once from ``seed``."""
    rng = np.random.default_rng(seed)
    shape = (len(PER_BLOCK), n_blocks)
    if distribution == "uniform":
        xi = rng.uniform(-1.0, 1.0, shape)
    elif distribution == "normal":
        xi = rng.standard_normal(shape)
    else:
        raise ValueError(f"distribution must be one of {DISTRIBUTIONS}, got {distribution!r}")
    return dict(zip(PER_BLOCK, xi, strict=True))


def spread_sizes(config, phys, n):
    """Relative spread size per parameter at each of ``n`` systems (name → array)."""
    sizes = {}
    for name in PER_BLOCK:
        axis = SPREAD_PREFIX + name
        if axis in phys:
            sizes[name] = phys[axis]
        else:
            sizes[name] = np.full(n, config.spread.sizes_dict.get(name, 0.0))
    return sizes


def spread_seeds(config, phys, n):
    """Seed of the pattern ξ at each of ``n`` systems (int64 array): the swept
    ``spread_seed`` where there is one, else ``spread.seed`` everywhere."""
    if SEED_AXIS in phys:
        return np.asarray(phys[SEED_AXIS]).astype(np.int64)
    return np.full(n, config.spread.seed, np.int64)


def block_factors(config, phys):
    """Per-block values relative to the common value: name → (n, blocks) array.

    1 + s ξ_i for a spread (exactly 1 without one), ξ the pattern of the row's seed;
    list / mean for a list. They do not depend on the common value, so rows that differ
    only in it (a swept K_W) share them bit for bit.
    """
    nb = config.blocks
    n = phys["A"].size
    lists = dict(config.block_parameters)
    sizes = spread_sizes(config, phys, n)
    seeds, row_seed = np.unique(spread_seeds(config, phys, n), return_inverse=True)
    out = {}
    for name in PER_BLOCK:
        if name in lists:
            values = np.asarray(lists[name], float)
            out[name] = np.broadcast_to(values / config.fixed[name], (n, nb)).copy()
        else:
            out[name] = np.empty((n, nb))
    for k, seed in enumerate(seeds.tolist()):
        rows = row_seed == k
        xi = spread_pattern(nb, config.spread.distribution, seed)
        for name in PER_BLOCK:
            if name not in lists:
                out[name][rows] = 1.0 + sizes[name][rows, None] * xi[name][None, :]
    return out


def block_values(config, phys):
    """Per-block values of A, B, D0 and K_W at every system: name → (n, blocks) array.

    ``phys``: the common values (``grid.physical_parameters``), including the swept
    spread sizes ``spread_<name>``. A list's values as given; with a spread, the
    common value × :func:`block_factors` (without one: exactly the common value).
    """
    n = phys["A"].size
    lists = dict(config.block_parameters)
    factors = block_factors(config, phys)
    out = {}
    for name in PER_BLOCK:
        if name in lists:
            out[name] = np.broadcast_to(np.asarray(lists[name], float), (n, config.blocks)).copy()
        else:
            out[name] = phys[name][:, None] * factors[name]
    return out


def identical_blocks(values):
    """Per system: whether every block has the same A, B, D0 and K_W (bool array)."""
    same = np.ones(next(iter(values.values())).shape[0], bool)
    for v in values.values():
        same &= (v == v[:, :1]).all(axis=1)
    return same
