"""Digests of runs that the engine's loops must reproduce bit for bit, whatever they become (issue 23,
item 3: a seed names its trajectory for good). Made once, with the loops of commit d0a8bbc (before
the row pattern, the margin and the parallel chain), by

    PYTHONPATH=/path/to/checkout-at-d0a8bbc python tests/data/make_seed_trajectories.py \\
        > tests/data/seed_trajectories.json

Each case is a small program over the public API (`run` below); the digest covers the final
velocities, the random stream's state and the counters. tests/engine/test_seed_trajectories.py runs
the same programs with the current engine (1 and 2 threads) and compares.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

import pinnedballs as pb

#: name -> (geometry, start, rule, scheduler, seed, calls): calls are ("steps", n) or ("collisions", more)
CASES = {
    "half-plane 300x310, Gaussian, steps then a collision target": (
        ("half_plane", 300, 310), "gaussian", "elastic", "uniform", 1, [("steps", 2_000_000), ("collisions", 10_000)]),
    "torus 300x300, one ball, steps": (
        ("flat_torus", 300, 300), "one ball", "elastic", "uniform", 2, [("steps", 3_000_000)]),
    "half-plane 300x310 across, unequal masses, restitution 0.9": (
        ("half_plane_across", 300, 310), "gaussian", "restitution", "uniform", 3, [("steps", 1_500_000)]),
    "half-plane 29x50, one ball, until frozen": (
        ("half_plane", 29, 50), "one ball", "elastic", "uniform", 4, [("frozen", 10**8)]),
    "half-plane 60x80, Gaussian, sweep": (
        ("half_plane", 60, 80), "gaussian", "elastic", "sweep", 5, [("steps", 400_000)]),
    "torus 38x38, one ball, rejection-free": (
        ("flat_torus", 38, 38), "one ball", "elastic", "rejection_free", 6, [("steps", 200_000)]),
}


def geometry(kind, rows, cols):
    if kind == "flat_torus":
        return pb.FlatTorus(rows, cols)
    return pb.HalfPlane(rows, cols, orientation="across" if kind.endswith("across") else "along")


def run(case) -> dict:
    (kind, rows, cols), start, rule, scheduler, seed, calls = case
    g = geometry(kind, rows, cols)
    rng = np.random.default_rng(seed)
    if start == "gaussian":
        v = rng.normal(size=(g.n_balls, 2))
    else:
        v = np.zeros((g.n_balls, 2))
        v[g.boundary_center() if g.boundary is not None else 0] = [0.3, np.sqrt(200.0)]
    masses = rng.uniform(0.5, 2.0, g.n_balls) if rule == "restitution" else None
    sched = {"uniform": pb.UniformRandomPair(), "sweep": pb.Sweep(), "rejection_free": pb.RejectionFree()}[scheduler]
    sim = pb.Simulation(g, v, rule=pb.Restitution(0.9) if rule == "restitution" else pb.Elastic(), scheduler=sched,
                        masses=masses, seed=seed)
    for call, n in calls:
        if call == "steps":
            sim.run(steps=n)
        elif call == "collisions":
            sim.run(collisions=sim.collisions + n)
        else:
            sim.run_until_frozen(max_steps=n)
    state = sim.get_state()
    h = hashlib.sha256()
    for array in (np.ascontiguousarray(sim.velocities), np.ascontiguousarray(state.rng_state)):
        h.update(array.tobytes())
    return {"steps": sim.steps, "collisions": sim.collisions, "digest": h.hexdigest()}


if __name__ == "__main__":
    print(json.dumps({name: run(case) for name, case in CASES.items()}, indent=1))
