"""Fixed-size work arrays on the stack, for kernels compiled for one state size.

numba's arrays live on the heap behind a reference-counted pointer, which LLVM cannot
keep in registers; an array of a compile-time size on the stack (``alloca``) it can.
In a micro-benchmark of RK4 on one block that reaches the speed of code written with
scalars (76 vs 96 ns per step); the grid kernels of one and two blocks run 1.1–1.4×
faster per step (``docs/internals.md``). The arrays live as long as the function
that creates them, so only the grid kernel's loop uses them and never returns them.
"""

import math

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array


def _stack_array(context, builder, shape):
    """An uninitialised float64 C array of the int ``shape`` on the function's stack
    (allocated once, in its entry block), with no reference-counted owner."""
    data = cgutils.alloca_once(
        builder, context.get_value_type(types.float64), size=max(math.prod(shape), 1)
    )
    array = make_array(types.Array(types.float64, len(shape), "C"))(context, builder)
    strides = [8 * math.prod(shape[i + 1 :]) for i in range(len(shape))]
    context.populate_array(
        array,
        data=data,
        shape=[context.get_constant(types.intp, extent) for extent in shape],
        strides=[context.get_constant(types.intp, stride) for stride in strides],
        itemsize=context.get_constant(types.intp, 8),
        meminfo=None,
    )
    return array._getvalue()


@intrinsic
def _stack_vector(typingctx, n):
    if not isinstance(n, types.IntegerLiteral):
        return None

    def codegen(context, builder, signature, args):
        return _stack_array(context, builder, (n.literal_value,))

    return types.Array(types.float64, 1, "C")(n), codegen


@intrinsic
def _stack_matrix(typingctx, rows, n):
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(n, types.IntegerLiteral)):
        return None

    def codegen(context, builder, signature, args):
        return _stack_array(context, builder, (rows.literal_value, n.literal_value))

    return types.Array(types.float64, 2, "C")(rows, n), codegen


def _heap_vector(n):
    return np.empty(n)


def _heap_matrix(rows, n):
    return np.empty((rows, n))


#: ``stack_vector(n)``: a float64 array of the literal length ``n`` on the caller's
#: stack; ``stack_matrix(rows, n)``: a (rows, n) C array. With ``NUMBA_DISABLE_JIT=1``
#: (the kernels as plain Python) they are numpy arrays.
if numba.config.DISABLE_JIT:
    stack_vector, stack_matrix = _heap_vector, _heap_matrix
else:
    stack_vector, stack_matrix = _stack_vector, _stack_matrix
