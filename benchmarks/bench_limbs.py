"""What a certified collision's limb work costs: ns for its closing speeds and its exchanges (issue 51, item 3).

The fixed-point chain's two limb loops on the paper's lattice (Q(sqrt 3), two coefficients a component), as a
collision along one of the tilted lines makes them: ``limbs.diff_combination`` for the closing speed's two
coefficients (two terms each), ``limbs.exchange`` for the four components (one term each), on the numbers of
1,000 balls in turn (in the cache), compiled as the chain's kernels are (no reference counting). The best of 5
rounds of a million collisions; the CPU's model, L2 cache and vector extensions first.

    python benchmarks/bench_limbs.py                # 12 limbs (768 bits, certified's default)
    python benchmarks/bench_limbs.py --limbs 6 65   # 384 bits, and the exact policy's width at 500x250
    (cd /tmp/old && python /path/to/benchmarks/bench_limbs.py)   # the package in the working directory
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path.cwd() if (Path.cwd() / "pinnedballs").is_dir() else Path(__file__).resolve().parents[1]))
from pinnedballs.engine.field import limbs  # noqa: E402
from pinnedballs.util.provenance import cpu_line  # noqa: E402

#: the closing speed along u = (1/2, sqrt 3 / 2), at scale S + 1: (d, s, f) terms of each coefficient
WTERMS = np.array([[[0, 0, 1], [1, 1, 3]], [[0, 1, 1], [1, 0, 1]]], dtype=np.int64)
WCOUNT = np.array([2, 2], dtype=np.int64)
#: omega u's coefficients, component by component: (s, f) terms
KTERMS = np.array([[[[0, 1]], [[1, 1]]], [[[1, 3]], [[0, 1]]]], dtype=np.int64)
KCOUNT = np.array([[1, 1], [1, 1]], dtype=np.int64)
BALLS = 1000


@numba.njit(_nrt=False)
def closing(X, W, n, terms, count):
    """``n`` collisions' closing speeds (the terms handed in as arrays, as the chain's tables are)."""
    for r in range(n):
        i, j = (r * 7) % X.shape[0], (r * 13 + 1) % X.shape[0]
        for c in range(2):
            limbs.diff_combination(W[c], X[i], X[j], terms[c], count[c])
    return W[0, 0]


@numba.njit(_nrt=False)
def exchanges(X, W, n, terms, count):
    """``n`` collisions' exchanges."""
    for r in range(n):
        i, j = (r * 7) % X.shape[0], (r * 13 + 1) % X.shape[0]
        for d in range(2):
            for c in range(2):
                limbs.exchange(X[i, d, c], X[j, d, c], W, terms[d, c], count[d, c])
    return X[0, 0, 0, 0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limbs", nargs="+", type=int, default=[12], help="widths, in 64-bit limbs")
    parser.add_argument("--collisions", type=int, default=1_000_000, help="collisions a round")
    args = parser.parse_args()
    print(cpu_line())
    rng = np.random.default_rng(1)
    for P in args.limbs:
        X = rng.integers(0, 2**63, size=(BALLS, 2, 2, P), dtype=np.uint64)
        W = rng.integers(0, 2**63, size=(2, P), dtype=np.uint64)
        for f, tables in ((closing, (WTERMS, WCOUNT)), (exchanges, (KTERMS, KCOUNT))):
            f(X, W, 10, *tables)  # compile
            best = min(_timed(f, X, W, args.collisions, tables) for _ in range(5))
            print(f"{P:>3} limbs  {f.__name__:>9}: {best / args.collisions * 1e9:7.1f} ns a collision", flush=True)


def _timed(f, X, W, n, tables) -> float:
    start = time.perf_counter()
    f(X, W, n, *tables)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
