"""Dense linear algebra of the implicit method (RODAS4) and its tangent: an LU
factorisation with partial pivoting and the solve with its factors."""

from ..accelerate import jit


@jit
def lu_factor(a, perm):
    """In-place LU factorisation of ``a`` with partial pivoting; ``perm[i]`` is the
    original index of the i-th pivot row.

    A zero pivot is not trapped: it yields non-finite values, which the caller's
    error estimate turns into a rejected step.
    """
    n = a.shape[0]
    for k in range(n):
        perm[k] = k
    for k in range(n):
        pk = k
        for i in range(k + 1, n):
            if abs(a[i, k]) > abs(a[pk, k]):
                pk = i
        if pk != k:
            tmp_row = perm[k]
            perm[k] = perm[pk]
            perm[pk] = tmp_row
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[pk, j]
                a[pk, j] = tmp
        for i in range(k + 1, n):
            a[i, k] /= a[k, k]
            if a[i, k] != 0.0:  # coupling Jacobians are sparse: skip rows with nothing to do
                for j in range(k + 1, n):
                    a[i, j] -= a[i, k] * a[k, j]


@jit
def lu_solve(a, perm, b, x):
    """Solve ``a x = b`` into ``x`` (≠ ``b``) from the factors of :func:`lu_factor`."""
    n = a.shape[0]
    for i in range(n):
        acc = b[perm[i]]
        for j in range(i):
            if a[i, j] != 0.0:
                acc -= a[i, j] * x[j]
        x[i] = acc
    for ii in range(n):
        i = n - 1 - ii
        acc = x[i]
        for j in range(i + 1, n):
            if a[i, j] != 0.0:
                acc -= a[i, j] * x[j]
        x[i] = acc / a[i, i]
