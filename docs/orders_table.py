"""The table of docs/orders.md's "Small configurations" (the most collisions over velocities and
orders): run it to make the table again.

    python docs/orders_table.py [--trials N] [--seed S]

Each configuration is a piece of the triangular or the square lattice (a collinear chain's most is
known: n(n-1)/2), balls of radius 1, so the search runs in exact arithmetic (Q(sqrt 3) or Q).
Prints a Markdown table, one row per configuration with the time it took; a row not in exact
arithmetic says so after its count.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import pinnedballs as pb

R3 = 3**0.5

#: name -> ball centres (n_balls, 2), contacts at distance 2
CONFIGURATIONS = {
    "triangle": [[0, 0], [2, 0], [1, R3]],
    "4-ball star (a centre touching three)": [[0, 0], [2, 0], [-1, R3], [-1, -R3]],
    "4-ball rhombus (two triangles)": [[0, 0], [2, 0], [1, R3], [3, R3]],
    "5-ball diamond (a centre touching four, on the square lattice)": [[0, 0], [2, 0], [0, 2], [-2, 0], [0, -2]],
    "5-ball bent chain (three in a row, two at 60 degrees)": [[0, 0], [2, 0], [4, 0], [5, R3], [6, 2 * R3]],
    "7-ball hexagon (a centre and its six neighbours)": [[0, 0], [2, 0], [1, R3], [-1, R3], [-2, 0], [-1, -R3],
                                                         [1, -R3]],
    "7-ball tripod (a centre, three arms of two)": [[0, 0], [2, 0], [4, 0], [-1, R3], [-2, 2 * R3], [-1, -R3],
                                                    [-2, -2 * R3]],
    "5-ball chain (known most: 10)": [[0, 0], [2, 0], [4, 0], [6, 0], [8, 0]],
}


HEADER = ("| configuration | balls | contacts | most found | fewest–most over orders | every order | trials (best at) "
          "| time |\n|---|---|---|---|---|---|---|---|")


def geometry(name: str) -> pb.GraphGeometry:
    """The configuration ``name`` of `CONFIGURATIONS`."""
    return pb.GraphGeometry.from_positions(np.array(CONFIGURATIONS[name], dtype=float))


def row(name: str, trials: int, seed: int) -> str:
    """One row of the table: the search's result on ``name`` and the time it took."""
    g = geometry(name)
    start = time.perf_counter()
    r = pb.search_max_collisions(g, trials=trials, seed=seed)
    seconds = time.perf_counter() - start
    if r.exhaustive_orders:
        most, orders = f"{r.collisions}", f"{r.min_collisions}–{r.collisions}"
    else:
        most, orders = f"≥ {r.collisions}", f"≤ {r.min_collisions} – ≥ {r.collisions}"
    if r.arithmetic != "exact":
        most += f" ({r.arithmetic} arithmetic)"
    return (f"| {name} | {g.n_balls} | {g.n_contacts} | {most} | {orders} | "
            f"{'yes' if r.exhaustive_orders else 'no'} ({r.states:,} states) | {r.trials:,} ({r.found_at:,}) | "
            f"{seconds:.0f} s |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(HEADER)
    for name in CONFIGURATIONS:
        print(row(name, args.trials, args.seed), flush=True)


if __name__ == "__main__":
    main()
