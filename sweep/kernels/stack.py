"""Fixed-size work arrays on the stack, for kernels compiled for one state size.

numba's arrays live on the heap behind a reference-counted pointer, which LLVM cannot
keep in registers; an array of a compile-time size on the stack (``alloca``) it can:
the integration loop of a small system then runs at the speed of code written with
scalars (``docs/performance.md``). The arrays are valid while the function that
creates them runs, so only the grid kernel's loop uses them, never returns them.
"""

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array


def _stack_array(context, builder, shape):
    """An uninitialised float64 C array of the int ``shape`` on the function's stack
    (allocated once, in its entry block), with no reference-counted owner."""
    arrty = types.Array(types.float64, len(shape), "C")
    size = 1
    for extent in shape:
        size *= extent
    data = cgutils.alloca_once(builder, context.get_value_type(types.float64), size=max(size, 1))
    array = make_array(arrty)(context, builder)
    itemsize = context.get_constant(types.intp, 8)
    strides = [8 * _prod(shape[i + 1 :]) for i in range(len(shape))]
    context.populate_array(
        array,
        data=data,
        shape=[context.get_constant(types.intp, e) for e in shape],
        strides=[context.get_constant(types.intp, s) for s in strides],
        itemsize=itemsize,
        meminfo=None,
    )
    return array._getvalue()


def _prod(values):
    out = 1
    for v in values:
        out *= v
    return out


@intrinsic
def stack_vector(typingctx, n):
    """A float64 array of the literal length ``n`` on the caller's stack."""
    if not isinstance(n, types.IntegerLiteral):
        return None

    def codegen(context, builder, signature, args):
        return _stack_array(context, builder, (n.literal_value,))

    return types.Array(types.float64, 1, "C")(n), codegen


@intrinsic
def stack_matrix(typingctx, rows, n):
    """A float64 (rows, n) C array of literal extents on the caller's stack."""
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(n, types.IntegerLiteral)):
        return None

    def codegen(context, builder, signature, args):
        return _stack_array(context, builder, (rows.literal_value, n.literal_value))

    return types.Array(types.float64, 2, "C")(rows, n), codegen
