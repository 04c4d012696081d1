"""RODAS4-structured: the steps of ``rodas4.py`` (the same stage loop and tangent,
``rodas4.rosenbrock``) with their matrix I/(γh) − J built, factorised and solved in O(N)
operations for N blocks instead of the dense O(N³) (issue 39).

The matrix is ordered block by block: position q = vpb·pos(i) + c holds component c (ℓ,
ψ, z) of block i, vpb values per block. Block i couples to others only in its row
``row_i`` (z_i inertial, else ℓ_i), in their ℓ_j:

- chain: pos(i) = i, neighbours one block apart: a band of half-width kl = 2vpb − 1;
- ring: the folded order 0, nb − 1, 1, nb − 2, … (pos(i) = 2i for i < (nb + 1)//2,
  else 2(nb − 1 − i) + 1) puts every neighbour at most two blocks apart: a band of
  half-width 3vpb − 1, no corner terms (chosen over Sherman–Morrison–Woodbury for the
  corners: as O(N), one factorisation and no correction);
- all: block-diagonal (half-width vpb − 1) minus the rank-one a wᵀ (a_i = 1/denom_i at
  row_i, w_j = κ2 e^ℓ_j at ℓ_j; each block's own term stays in its diagonal block),
  solved by Sherman–Morrison: M⁻¹b = x + z (w·x)/(1 − w·z), x = B⁻¹b, z = B⁻¹a.

The band is factorised with partial pivoting as LAPACK's dgbtf2 does (upper half-width
kl + ku after the interchanges, the multipliers of each column kept in place, the
interchanges applied in order by the solve). ``mat`` row q holds the entry of column c at
``mat[q, c − q + kl]`` (kl = ku), in 3kl + 1 columns; for all-to-all three more columns
hold a, w and z in band order. The solve gathers its right-hand side into band order
and scatters the solution back.
"""

import numpy as np

from ...accelerate import jit, jit_inline
from ..equations import block_jacobian, coupling_entry
from ..layout import ALL, CHAIN, INERTIAL, RING, values_per_block
from . import rodas4

NAME = "RODAS4-structured"
ADAPTIVE, EXPONENT, STAGE_ROWS, MATRIX = True, rodas4.EXPONENT, rodas4.STAGE_ROWS, True
DENSE_ROWS, DENSE_STAGES, EXCURSION = rodas4.DENSE_ROWS, rodas4.DENSE_STAGES, rodas4.EXCURSION
TANGENT_ROWS, TANGENT_CAP = rodas4.TANGENT_ROWS, rodas4.TANGENT_CAP
dense = rodas4.dense

#: Columns after the band of an all-to-all matrix: a, w and z = B⁻¹a (Sherman–Morrison).
RANK_ONE_COLUMNS = 3
#: Blocks between a block and its farthest coupled block in the band order.
_REACH = {CHAIN: 1, RING: 2, ALL: 0}


def matrix_columns(model, coupling):
    """Columns of the method's matrix for ``model`` and ``coupling`` (codes): the band,
    3kl + 1 with kl = vpb·(reach + 1) − 1, and the rank-one columns of all-to-all."""
    vpb = values_per_block(model)
    kl = vpb * (_REACH[coupling] + 1) - 1
    return 3 * kl + 1 + (RANK_ONE_COLUMNS if coupling == ALL else 0)


@jit_inline
def position(coupling, nb, i):
    """Block ``i``'s place in the band order (the ring folded, else ``i``)."""
    if coupling != RING:
        return i
    return 2 * i if i < (nb + 1) // 2 else 2 * (nb - 1 - i) + 1


@jit_inline
def state_index(coupling, nb, vpb, q):
    """The state index of band position ``q`` (the inverse of :func:`position`)."""
    pos = q // vpb
    if coupling == RING and pos % 2 == 1:
        pos = nb - 1 - pos // 2
    elif coupling == RING:
        pos = pos // 2
    return (q % vpb) * nb + pos


@jit
def band_factor(mat, perm, kl, n):
    """In-place LU factorisation with partial pivoting of the band matrix of half-widths
    ``kl`` (both) in ``mat`` (module docstring); ``perm[k]``: the row swapped with row k
    at step k. A zero pivot is not trapped: the caller's error estimate rejects the
    step its non-finite values give."""
    right = 0  # the last column rows below k may hold (LAPACK's JU)
    for k in range(n):
        last = min(k + kl, n - 1)
        pk = k
        for i in range(k + 1, last + 1):
            if abs(mat[i, k - i + kl]) > abs(mat[pk, k - pk + kl]):
                pk = i
        perm[k] = pk
        right = max(right, min(pk + kl, n - 1))
        if pk != k:
            for c in range(k, right + 1):
                tmp = mat[k, c - k + kl]
                mat[k, c - k + kl] = mat[pk, c - pk + kl]
                mat[pk, c - pk + kl] = tmp
        pivot = mat[k, kl]
        for i in range(k + 1, last + 1):
            lik = mat[i, k - i + kl] / pivot
            mat[i, k - i + kl] = lik
            if lik != 0.0:
                for c in range(k + 1, right + 1):
                    mat[i, c - i + kl] -= lik * mat[k, c - k + kl]


@jit
def band_substitute(mat, perm, kl, x):
    """x ← B⁻¹ x in place (``x`` in band order) from the factors of :func:`band_factor`."""
    n = x.size
    for k in range(n):
        pk = perm[k]
        if pk != k:
            tmp = x[k]
            x[k] = x[pk]
            x[pk] = tmp
        xk = x[k]
        if xk != 0.0:
            for i in range(k + 1, min(k + kl, n - 1) + 1):
                x[i] -= mat[i, k - i + kl] * xk
    for ii in range(n):
        i = n - 1 - ii
        acc = x[i]
        for c in range(i + 1, min(i + 2 * kl, n - 1) + 1):
            acc -= mat[i, c - i + kl] * x[c]
        x[i] = acc / mat[i, kl]


@jit
def structured_factorise(y, f, diag, p, model, law, coupling, het, nb, ev, mat, perm):
    """The matrix I/(γh) − J at ``y`` (``diag`` = 1/(γh), V/D0) in band form into ``mat``
    (module docstring; entries from ``equations.block_jacobian``), factorised in place
    (pivots ``perm``); for all-to-all also a, w and z = B⁻¹a."""
    n = y.size
    vpb = 3 if model == INERTIAL else 2
    width = mat.shape[1] - (RANK_ONE_COLUMNS if coupling == ALL else 0)
    kl = (width - 1) // 3
    mat[:, :] = 0.0
    for i in range(nb):
        ev[i] = np.exp(y[i])
    for i in range(nb):
        psi_l, psi_psi, l_l, l_z, row_l, row_z, row_psi, denom = block_jacobian(
            y, f, p, model, law, coupling, het, nb, ev, i)  # fmt: skip
        q = vpb * position(coupling, nb, i)  # ℓ_i; ψ_i at q + 1, z_i at q + 2
        mat[q + 1, kl - 1] = -psi_l
        mat[q + 1, kl] = -psi_psi + diag
        r = q
        if model == INERTIAL:
            r = q + 2
            mat[q, kl] = -l_l + diag
            mat[q, kl + 2] = -l_z
            mat[r, kl] = -row_z + diag
            mat[r, kl - 2] = -row_l
        else:
            mat[q, kl] = -row_l + diag
        mat[r, q + 1 - r + kl] = -row_psi
        if coupling == CHAIN:
            if i > 0:
                mat[r, vpb * (i - 1) - r + kl] -= coupling_entry(p, ev, i - 1, denom)
            if i < nb - 1:
                mat[r, vpb * (i + 1) - r + kl] -= coupling_entry(p, ev, i + 1, denom)
        elif coupling == RING:
            left, right = i - 1 if i > 0 else nb - 1, i + 1 if i < nb - 1 else 0
            mat[r, vpb * position(coupling, nb, left) - r + kl] -= coupling_entry(
                p, ev, left, denom)  # fmt: skip
            mat[r, vpb * position(coupling, nb, right) - r + kl] -= coupling_entry(
                p, ev, right, denom)  # fmt: skip
        else:  # M = B − a wᵀ: B keeps the block's own coupling term
            mat[r, q - r + kl] += coupling_entry(p, ev, i, denom)
            mat[r, width] = 1.0 / denom
            mat[q, width + 1] = coupling_entry(p, ev, i, 1.0)
    band_factor(mat, perm, kl, n)
    if coupling == ALL:
        for j in range(n):
            mat[j, width + 2] = mat[j, width]
        band_substitute(mat, perm, kl, mat[:, width + 2])


@jit
def structured_solve(mat, perm, b, x, nb, model, coupling):
    """x = (I/(γh) − J)⁻¹ b from the factors of :func:`structured_factorise`, solved in
    band order in ``x``; ``b`` is overwritten (with the solution)."""
    n = b.size
    vpb = 3 if model == INERTIAL else 2
    width = mat.shape[1] - (RANK_ONE_COLUMNS if coupling == ALL else 0)
    for q in range(n):
        x[q] = b[state_index(coupling, nb, vpb, q)]
    band_substitute(mat, perm, (width - 1) // 3, x)
    if coupling == ALL:  # Sherman–Morrison; w is nonzero at the ℓ_j only
        wx, wz = 0.0, 0.0
        for q in range(0, n, vpb):
            wx += mat[q, width + 1] * x[q]
            wz += mat[q, width + 1] * mat[q, width + 2]
        scale = wx / (1.0 - wz)
        for q in range(n):
            x[q] += mat[q, width + 2] * scale
    for q in range(n):
        b[state_index(coupling, nb, vpb, q)] = x[q]
    for j in range(n):
        x[j] = b[j]


step, tangent_step = rodas4.rosenbrock("rodas4_structured", structured_factorise,
                                       structured_solve)  # fmt: skip
