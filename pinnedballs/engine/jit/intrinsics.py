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

import platform

from llvmlite import ir
from numba import config, types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic

__all__ = ["fixed_width", "prefetch", "atomic_load", "atomic_store", "atomic_add", "atomic_cas", "pause", "give_way",
           "ticks", "TICKS"]


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


# ---------------------------------------------------------------- atomics: threads that meet without a lock
#
# The parallel chain (`engine.threads.regions`) coordinates its threads through a few int64 counters: a
# thread claims a piece of work with a compare-and-swap, counts what it finished with an atomic add,
# and publishes ("release") or waits to see ("acquire") that the velocities another thread wrote are
# complete. numba has no atomics of its own; these emit LLVM's. Without the JIT (one thread) they are
# the plain operations.


def _element_pointer(context, builder, aryty, ary, index, idxty):
    ary = context.make_array(aryty)(context, builder, ary)
    index = context.cast(builder, index, idxty, types.intp)
    return cgutils.get_item_pointer(context, builder, aryty, ary, [index])


def _int64_array(arr) -> bool:
    return isinstance(arr, types.Array) and arr.dtype == types.int64 and arr.ndim == 1


@intrinsic
def _atomic_load_intrinsic(typingctx, arr, index):
    if not (_int64_array(arr) and isinstance(index, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        ptr = _element_pointer(context, builder, signature.args[0], args[0], args[1], signature.args[1])
        return builder.load_atomic(ptr, "acquire", 8)

    return types.int64(arr, index), codegen


@intrinsic
def _atomic_store_intrinsic(typingctx, arr, index, value):
    if not (_int64_array(arr) and isinstance(index, types.Integer) and isinstance(value, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        ptr = _element_pointer(context, builder, signature.args[0], args[0], args[1], signature.args[1])
        builder.store_atomic(context.cast(builder, args[2], signature.args[2], types.int64), ptr, "release", 8)
        return context.get_dummy_value()

    return types.void(arr, index, value), codegen


@intrinsic
def _atomic_add_intrinsic(typingctx, arr, index, value):
    if not (_int64_array(arr) and isinstance(index, types.Integer) and isinstance(value, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        ptr = _element_pointer(context, builder, signature.args[0], args[0], args[1], signature.args[1])
        return builder.atomic_rmw("add", ptr, context.cast(builder, args[2], signature.args[2], types.int64), "acq_rel")

    return types.int64(arr, index, value), codegen


@intrinsic
def _atomic_cas_intrinsic(typingctx, arr, index, expected, new):
    if not (_int64_array(arr) and isinstance(index, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        ptr = _element_pointer(context, builder, signature.args[0], args[0], args[1], signature.args[1])
        old = context.cast(builder, args[2], signature.args[2], types.int64)
        pair = builder.cmpxchg(ptr, old, context.cast(builder, args[3], signature.args[3], types.int64),
                               "acq_rel", "acquire")
        return builder.extract_value(pair, 0)

    return types.int64(arr, index, expected, new), codegen


@intrinsic
def _pause_intrinsic(typingctx):
    def codegen(context, builder, signature, args):
        if platform.machine().lower() in ("x86_64", "amd64", "i386", "i686"):
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []),
                                                "llvm.x86.sse2.pause")
            builder.call(fn, [])
        return context.get_dummy_value()

    return types.void(), codegen


@intrinsic
def _give_way_intrinsic(typingctx):
    def codegen(context, builder, signature, args):
        if platform.system() in ("Linux", "Darwin"):  # POSIX sched_yield, found by name in the C library
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(32), []), "sched_yield")
            builder.call(fn, [])
        return context.get_dummy_value()

    return types.void(), codegen


def _atomic_load_python(arr, index):
    return arr[index]


def _atomic_store_python(arr, index, value):
    arr[index] = value


def _atomic_add_python(arr, index, value):
    old = arr[index]
    arr[index] = old + value
    return old


def _atomic_cas_python(arr, index, expected, new):
    old = arr[index]
    if old == expected:
        arr[index] = new
    return old


def _pause_python():
    """Without the JIT there is one thread: nothing to wait for."""


#: ``atomic_load(arr, i)``: ``arr[i]`` (int64), seeing every write released before the value was stored
atomic_load = _atomic_load_python if config.DISABLE_JIT else _atomic_load_intrinsic
#: ``atomic_store(arr, i, x)``: ``arr[i] = x``, after every write before it is visible
atomic_store = _atomic_store_python if config.DISABLE_JIT else _atomic_store_intrinsic
#: ``atomic_add(arr, i, x) -> old``: ``arr[i] += x`` as one step
atomic_add = _atomic_add_python if config.DISABLE_JIT else _atomic_add_intrinsic
#: ``atomic_cas(arr, i, expected, new) -> old``: ``arr[i] = new`` if it held ``expected``, as one step
atomic_cas = _atomic_cas_python if config.DISABLE_JIT else _atomic_cas_intrinsic
#: ``pause()``: a spinning thread's hint to the core (x86's ``pause``)
pause = _pause_python if config.DISABLE_JIT else _pause_intrinsic
#: ``give_way()``: the operating system may run another thread on this core now (``sched_yield``)
give_way = _pause_python if config.DISABLE_JIT else _give_way_intrinsic


# ---------------------------------------------------------------- the clock a loop reads
#
# A loop that chooses between two ways of running its blocks (`engine.sequential.choice`) times them on the
# CPU that runs it: x86's time-stamp counter (``rdtsc``, LLVM's ``llvm.readcyclecounter``: tens of cycles,
# no system call). Elsewhere LLVM may read a counter the operating system forbids (Arm's PMCCNTR_EL0 traps),
# so there `ticks` is 0 and `TICKS` False: a loop then does not time itself.

#: whether `ticks` counts (x86-64: the time-stamp counter)
TICKS = platform.machine().lower() in ("x86_64", "amd64")


@intrinsic
def _ticks_intrinsic(typingctx):
    def codegen(context, builder, signature, args):
        if not TICKS:
            return ir.Constant(ir.IntType(64), 0)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                            "llvm.readcyclecounter")
        return builder.call(fn, [])

    return types.int64(), codegen


def _ticks_python():
    """Without the JIT: nanoseconds of `time.perf_counter_ns` (a clock, as the counter is)."""
    import time

    return time.perf_counter_ns()


#: ``ticks() -> int64``: the time-stamp counter (cycles at a constant rate) where `TICKS`, else 0
ticks = _ticks_python if config.DISABLE_JIT else _ticks_intrinsic
