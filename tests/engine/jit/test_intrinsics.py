"""`fixed_width` views are the same memory as the array they come from, and the loops refuse
tables whose row lengths are not those they were built for."""

import numpy as np
import pytest
from helpers import pick_loops
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.chain import NO_LIMIT
from pinnedballs.engine.jit.intrinsics import fixed_width
from pinnedballs.engine.margin import new_margin
from pinnedballs.engine.sequential.choice import new_tune
from pinnedballs.engine.sequential.loops import NO_AUX, NO_PATTERN
from pinnedballs.rules import collide_elastic
from pinnedballs.schedulers.simple import pick_uniform


def _copy_and_bump(width):
    """A compiled function that reads every element through the view into a new array, then
    adds 1 through the view (``width`` a compile-time constant, as in the loops)."""
    W = width

    @njit
    def run(a):
        view = fixed_width(a, W)
        out = np.empty_like(a)
        for i in range(view.shape[0]):
            for k in range(view.shape[1]):
                out[i, k] = view[i, k]
                view[i, k] += 1
        return out

    return run


@pytest.mark.parametrize("dtype, width", [(np.float64, 3), (np.uint32, 2), (np.uint8, 2)])
def test_view_reads_and_writes_the_same_elements(dtype, width):
    a = np.arange(7 * width).astype(dtype).reshape(7, width)
    before = a.copy()
    assert np.array_equal(_copy_and_bump(width)(a), before)
    assert np.array_equal(a, before + 1)


def test_loop_refuses_tables_of_another_row_length():
    geom = pb.FlatTorus(rows=4, cols=4)
    c = geom.contacts
    loops = pick_loops(collide_elastic, pick_uniform, 2, True)
    v3 = np.zeros((geom.n_balls, 3))  # three components for a loop built for two
    rng, counters = np.array([1, 2, 3, 4], dtype=np.uint64), np.zeros(4, dtype=np.int64)
    with pytest.raises(ValueError, match="^the loop's tables do not have the row lengths it was built for$"):
        loops.limited(v3, c.pairs, c.ends, c.units, np.ones(geom.n_balls), np.array([1.0]), NO_PATTERN,
                      np.zeros(1, dtype=np.int64), NO_AUX, rng, counters, new_margin(), 10, NO_LIMIT, False, 10,
                      np.zeros(1, dtype=np.int64), np.empty((0, 2), dtype=np.int64), new_tune())
    assert counters.tolist() == [0, 0, 0, 0]
