"""A geometry written by a user: balls in a ring, each touching its two neighbours.

A `pinnedballs.Geometry` subclass sets ``positions`` and builds its `Contacts`
with ``Contacts.build(pairs, ends, units)``: the two balls ``(i, j)`` of each
contact, and the rows of ``units`` holding the unit vector at ``i`` pointing to
``j`` and the one at ``j`` pointing to ``i``. Everything else (simulation,
observables, the contact graph) comes for free.

Run it: ``python examples/custom_geometry.py``.
"""

import numpy as np

import pinnedballs as pb


class Ring(pb.Geometry):
    """``n`` balls of ``radius`` on a circle, each touching its neighbours (a polygon of contacts).

    positions ``(n, 2)``; contact ``k`` joins balls ``k`` and ``k + 1 (mod n)``.
    """

    def __init__(self, n: int, radius: float = 1.0):
        if n < 3:
            raise ValueError(f"n: a ring needs at least 3 balls, got {n}")
        self.radius = float(radius)
        # neighbouring centres are 2 * radius apart: the chord of angle 2 pi / n
        big = radius / np.sin(np.pi / n)
        angle = 2 * np.pi * np.arange(n) / n
        self.positions = big * np.column_stack([np.cos(angle), np.sin(angle)])

    def _build_contacts(self) -> pb.Contacts:
        n = len(self.positions)
        i = np.arange(n)
        j = (i + 1) % n
        t_i = self.positions[j] - self.positions[i]
        t_i /= np.linalg.norm(t_i, axis=1, keepdims=True)
        units = np.empty((2 * n, 2))
        units[0::2], units[1::2] = t_i, -t_i  # flat space: t_j = -t_i
        return pb.Contacts.build(pairs=np.column_stack([i, j]), ends=np.column_stack([2 * i, 2 * i + 1]),
                                 units=units)


def main() -> None:
    ring = Ring(24)
    print(ring)
    velocities = np.zeros((ring.n_balls, ring.dim))
    velocities[0] = [0.0, 10.0]  # ball 0 sits at angle 0: this is along the ring
    sim = pb.Simulation(ring, velocities, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=1)
    energy, momentum = sim.energy(), sim.momentum()
    frozen = sim.run_until_frozen(max_steps=10**7)
    print(f"frozen={frozen} after {sim.steps:,} steps and {sim.collisions:,} collisions")
    print(f"energy {energy:.12g} -> {sim.energy():.12g}; momentum {momentum} -> {sim.momentum()}")

    # the same contacts through the generic graph geometry give the same run, bit for bit
    twin = pb.Simulation(pb.GraphGeometry(ring.contact_graph()), velocities, seed=1)
    twin.run_until_frozen(max_steps=10**7)
    print("GraphGeometry twin identical:", np.array_equal(twin.velocities, sim.velocities))


if __name__ == "__main__":
    main()
