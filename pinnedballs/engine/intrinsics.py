"""LLVM hints for the hot loop: they change how the code runs, never a number.

``fixed_width(arr, width)``: the same 2-D array with its row length a compile-time constant.
numba reads an array's shape from memory at run time, so ``v[i, k]`` costs a multiply
by ``v.shape[1]`` held on the stack. The loops know each row length when they are built
(``dim`` components of a velocity or unit vector, 2 balls or 2 ends of a contact);
handing them this view (same memory, same values) lets LLVM find a row with a shift or
``lea`` and keeps registers free.

``prefetch(arr, row)``: a cache prefetch hint. numba has no prefetch of its own; this emits
LLVM's ``llvm.prefetch`` for the address of ``arr[row]``: only when memory arrives changes.

Without the JIT (``NUMBA_DISABLE_JIT=1``) both are plain Python: the array itself, and nothing.
"""

from llvmlite import ir
from numba import config, types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic

__all__ = ["fixed_width", "prefetch"]


@intrinsic
def _fixed_width_intrinsic(typingctx, arr, width):
    """The view of a C-contiguous ``(n, width)`` array whose shape and strides are constants
    (but ``n``); the caller guarantees ``arr.shape[1] == width``."""
    if not (isinstance(arr, types.Array) and arr.ndim == 2 and arr.layout == "C"
            and isinstance(width, types.IntegerLiteral)):
        return None
    w = width.literal_value

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        src = context.make_array(aryty)(context, builder, args[0])
        out = context.make_array(aryty)(context, builder)
        intp = context.get_value_type(types.intp)
        itemsize = context.get_abi_sizeof(context.get_data_type(aryty.dtype))
        rows = cgutils.unpack_tuple(builder, src.shape)[0]
        context.populate_array(out, data=src.data, shape=[rows, intp(w)],
                               strides=[intp(w * itemsize), intp(itemsize)],
                               itemsize=src.itemsize, meminfo=src.meminfo, parent=src.parent)
        return impl_ret_borrowed(context, builder, aryty, out._getvalue())

    return arr(arr, width), codegen


def _fixed_width_python(arr, width):
    """Without the JIT (``NUMBA_DISABLE_JIT=1``) the array itself."""
    return arr


fixed_width = _fixed_width_python if config.DISABLE_JIT else _fixed_width_intrinsic



@intrinsic
def _prefetch_intrinsic(typingctx, arr, index):
    """Ask the CPU to bring row ``index`` of ``arr`` into cache; no effect on any value."""
    if not isinstance(arr, types.Array) or not isinstance(index, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        aryty, idxty = signature.args
        ary = context.make_array(aryty)(context, builder, args[0])
        row = builder.mul(context.cast(builder, args[1], idxty, types.intp),
                          cgutils.unpack_tuple(builder, ary.strides)[0])
        addr = builder.inttoptr(builder.add(builder.ptrtoint(ary.data, cgutils.intp_t), row), cgutils.voidptr_t)
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t, i32, i32, i32]), "llvm.prefetch.p0")
        builder.call(fn, [addr, i32(0), i32(3), i32(1)])  # read, keep in all cache levels, data
        return context.get_dummy_value()

    return types.void(arr, index), codegen


def _prefetch_python(arr, index):
    """Without the JIT (``NUMBA_DISABLE_JIT=1``) a prefetch is nothing."""


prefetch = _prefetch_python if config.DISABLE_JIT else _prefetch_intrinsic
