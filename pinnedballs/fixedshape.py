"""``fixed_width(arr, width)``: the same 2-D array with its row length a compile-time constant.

numba reads an array's shape from memory at run time, so ``v[i, k]`` costs a multiply
by ``v.shape[1]`` held on the stack. The loops know each row length when they are built
(``dim`` components of a velocity or unit vector, 2 balls or 2 ends of a contact);
handing them this view (same memory, same values) lets LLVM find a row with a shift or
``lea`` and keeps registers free. Only the code changes, never a number.
"""

from numba import config, types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic

__all__ = ["fixed_width"]


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
