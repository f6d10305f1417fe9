"""A cache prefetch hint for the compiled loop: ``prefetch(arr, row)``.

numba has no prefetch of its own; this emits LLVM's ``llvm.prefetch`` for the
address of ``arr[row]``. It changes no value, only when memory arrives.
"""

from llvmlite import ir
from numba import config, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["prefetch"]


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
