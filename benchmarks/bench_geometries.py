"""Build times of the large geometries and the precision of the hyperbolic tiling.

Prints, for FCC and HCP of 100 x 100 x 100 cells (4 million balls, 24 million contacts),
the seconds to place the balls and to build the contacts; for the {3,7} tiling, the
seconds per number of rings and the largest error of a contact length, measured stably
from the polar form (and, for comparison, from float64 hyperboloid coordinates).

Run it: ``python benchmarks/bench_geometries.py``.
"""

import time

import numpy as np

import pinnedballs as pb
from pinnedballs.geometry.hyperbolic import contact_length


def packings(n: int = 100) -> None:
    for cls in (pb.FCC, pb.HCP):
        t0 = time.perf_counter()
        g = cls(n, n, n)
        t1 = time.perf_counter()
        contacts = g.contacts
        t2 = time.perf_counter()
        print(f"{cls.__name__}({n}, {n}, {n}): {g.n_balls:,} balls, {len(contacts):,} contacts; "
              f"positions {t1 - t0:.2f} s, contacts {t2 - t1:.2f} s")


def hyperbolic(max_layers: int = 9) -> None:
    length = contact_length(7)
    for layers in range(4, max_layers + 1):
        t0 = time.perf_counter()
        h = pb.HyperbolicPlane(q=7, layers=layers)
        seconds = time.perf_counter() - t0
        r, phi = (a.astype(np.longdouble) for a in h.polar())
        i, j = h.contacts.pairs.astype(np.int64).T
        half_angle = np.sin((phi[i] - phi[j]) / 2)
        polar = np.arccosh(np.cosh(r[i] - r[j]) + 2 * np.sinh(r[i]) * np.sinh(r[j]) * half_angle**2)
        x = h.positions.astype(np.longdouble)
        flat = np.arccosh(x[i, 0] * x[j, 0] - x[i, 1] * x[j, 1] - x[i, 2] * x[j, 2])
        print(f"HyperbolicPlane(7, {layers}): {h.n_balls:,} balls in {seconds:.2f} s; contact length error "
              f"{float(np.abs(polar - length).max()):.1e} (polar), {float(np.abs(flat - length).max()):.1e} "
              f"(float64 hyperboloid coordinates)")


if __name__ == "__main__":
    packings()
    hyperbolic()
