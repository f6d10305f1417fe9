"""What numba-cuda's simulator gets wrong, mended for this engine's kernels, under the simulator only.

The simulator runs a block's threads as Python threads and gives each ``cuda.shared.array`` call the array
its line allocated first (``FakeCUDAShared.array``: a dict keyed by the calling file and line). It looks the
line up and stores a new array without a lock, so two threads that reach a line together can each allocate
one: the later store wins, and the thread holding the other writes and reads an array no other thread sees
(numba-cuda 0.30.4, unchanged upstream in July 2026). A kernel's block sum then loses a thread's part, or
reads an uninitialised count: an 8x8 torus's live contacts counted 76, 19 or 78 times in 1,500 instead of
91, and now and then a chunk ending short or an index of 9e18. `mend` makes the lookup and the store one
step under a lock; the arrays, their keys and the aliasing the simulator documents are as before.

On a GPU a shared array is one per block by construction: nothing here runs there.
"""

from __future__ import annotations

import sys
import threading
import traceback

import numpy as np

__all__ = ["mend", "mended", "locked_shared_array", "upstream_shared_array"]

_LOCK = threading.Lock()

#: numba-cuda's own ``FakeCUDAShared.array``, as `mend` found it (None before): the tests show its race
upstream_shared_array = None


def locked_shared_array(self, shape, dtype, alignment=None):
    """``FakeCUDAShared.array`` with the lookup and the allocation under one lock (numba-cuda 0.30.4's own
    body otherwise, line for line: a static array per calling line, dynamic shared memory for ``shape == 0``)."""
    from numba.cuda.simulator import kernelapi

    if alignment is not None:
        raise RuntimeError("Array alignment is not supported in cudasim")
    if isinstance(dtype, kernelapi.types.Type):
        dtype = kernelapi.numpy_support.as_dtype(dtype)
    if shape == 0:
        count = self._dynshared_size // dtype.itemsize
        return np.frombuffer(self._dynshared.data, dtype=dtype, count=count)
    caller = tuple(traceback.extract_stack(sys._getframe())[-2][0:2])
    with _LOCK:
        array = self._allocations.get(caller)
        if array is None:
            array = self._allocations[caller] = np.empty(shape, dtype)
    return array


def mend() -> None:
    """Install `locked_shared_array` in numba-cuda's simulator (idempotent; call only under the simulator)."""
    global upstream_shared_array
    from numba.cuda.simulator import kernelapi

    if kernelapi.FakeCUDAShared.array is not locked_shared_array:
        upstream_shared_array = kernelapi.FakeCUDAShared.array
        kernelapi.FakeCUDAShared.array = locked_shared_array


def mended() -> bool:
    """True once `mend` has run in this process."""
    from numba.cuda.simulator import kernelapi

    return kernelapi.FakeCUDAShared.array is locked_shared_array
