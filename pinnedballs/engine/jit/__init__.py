"""numba below the loops: its on-disk cache for loops that are closures over jitted functions (`cache`) and
the LLVM hints the hot loops use (`intrinsics`: fixed row widths, prefetches, atomics, a select)."""
