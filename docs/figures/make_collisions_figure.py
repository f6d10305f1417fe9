"""Evidence for the remnant threshold: closing speeds of genuine collisions against rounding remnants.

For each run, the same picks are followed twice: by the float64 chain that counts every pick that
changes a bit (the criterion before the threshold) and by the exact chain (`pinnedballs.engine.field.rational`).
A float collision the exact chain also makes is *genuine*; one it refuses (exact closing speed zero
or negative) is a *remnant*. Each is plotted by its float closing speed in units of ``2^-53 V``
(``V = sqrt(2 E / m)``, the system's speed scale), and by its float closing speed relative to the
two balls' own speeds, with the engine's threshold drawn. Writes ``collisions_closing_speeds.png``
and ``collisions_closing_speeds.json`` beside this script (about two minutes on 2 cores).

    python docs/figures/make_collisions_figure.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import pinnedballs as pb
from pinnedballs.engine.field.rational import RationalChain
from pinnedballs.plot.base import new_figure, save
from pinnedballs.rules import THRESHOLD_ULPS

HERE = Path(__file__).resolve().parent
U = 2.0**-53


def lockstep(geometry, v: np.ndarray, seed: int, steps: int) -> dict[str, list[tuple[float, float]]]:
    """``{"genuine": [...], "remnant": [...]}`` of ``(w, w / (|v_i|_1 + |v_j|_1))`` for every pick the
    bit-changing float criterion collides, classified by the exact chain on the same picks."""
    sim = pb.Simulation(geometry, v, seed=seed)
    picks = np.empty(steps, dtype=np.int64)
    sim.engine.loops.picks(sim.engine.state.scheduler, sim.engine.model.selector.aux, sim.engine.state.rng,
                           geometry.n_contacts, picks)
    exact = RationalChain(geometry, v, np.ones(geometry.n_balls), pb.Elastic().exact_kick)
    c = geometry.contacts
    pairs, t_i, t_j = c.pairs.astype(int).tolist(), c.t_i.tolist(), c.t_j.tolist()
    vf = np.array(v, dtype=np.float64).tolist()
    out = {"genuine": [], "remnant": []}
    for k in picks.tolist():
        i, j = pairs[k]
        a, b = t_i[k], t_j[k]
        w = vf[i][0] * a[0] + vf[j][0] * b[0]
        for d in range(1, len(a)):
            w += vf[i][d] * a[d] + vf[j][d] * b[d]
        scale = sum(map(abs, vf[i])) + sum(map(abs, vf[j]))
        genuine = exact.collide(k)
        if w > 0.0:
            new_i = [vf[i][d] - w * a[d] for d in range(len(a))]
            new_j = [vf[j][d] - w * b[d] for d in range(len(a))]
            if new_i != vf[i] or new_j != vf[j]:  # the float criterion before the threshold: a bit changed
                out["genuine" if genuine else "remnant"].append((w, w / scale))
            vf[i], vf[j] = new_i, new_j
    return out


def runs():
    """``(label, geometry, velocities, seed, steps)``: half-planes until frozen, tori for a fixed time."""
    def half(length, depth, direction=(0.0, 1.0), balls=1, seed=0):
        g = pb.HalfPlane.from_size(length, depth)
        v = np.zeros((g.n_balls, 2))
        rng = np.random.default_rng(seed)
        for b in [g.boundary_center()] if balls == 1 else rng.choice(g.n_balls, balls, replace=False):
            d = np.array(direction, dtype=float) if balls == 1 else rng.normal(size=2)
            v[b] = np.sqrt(200.0 / balls) * d / np.linalg.norm(d)
        return g, v

    cases = [("20x10", *half(20, 10), 1), ("40x20 oblique", *half(40, 20, (0.3, 1.7)), 2),
             ("60x30 diagonal", *half(60, 30, (1.0, 1.0)), 1), ("40x20 five balls", *half(40, 20, balls=5), 1),
             ("100x50", *half(100, 50), 1), ("200x100", *half(200, 100), 1)]
    out = []
    for label, g, v, seed in cases:
        sim = pb.Simulation(g, v, seed=seed)
        sim.run_until_frozen(max_steps=10**10)
        out.append((f"half-plane {label}", g, v, seed, sim.steps))
    torus = pb.FlatTorus(38, 38)
    one = np.zeros((torus.n_balls, 2))
    one[0] = [np.sqrt(200.0), 0.0]
    out.append(("torus 38x38, one ball, 2e6 steps", torus, one, 1, 2_000_000))
    out.append(("torus 38x38, Gaussian, 2e6 steps", torus, np.random.default_rng(3).normal(size=(torus.n_balls, 2)),
                1, 2_000_000))
    return out


def main() -> None:
    table, genuine, remnant = [], [], []
    for label, g, v, seed, steps in runs():
        V = float(np.sqrt((v**2).sum()))  # sqrt(2E/m), unit masses
        found = lockstep(g, v, seed, steps)
        G = np.array(found["genuine"]).reshape(-1, 2)
        R = np.array(found["remnant"]).reshape(-1, 2)
        genuine.append(np.column_stack([G[:, 0] / (U * V), G[:, 1]]))
        remnant.append(np.column_stack([R[:, 0] / (U * V), R[:, 1]]))
        table.append({"run": label, "steps": steps, "genuine": len(G), "remnants": len(R),
                      "smallest genuine / (2^-53 V)": float(G[:, 0].min() / (U * V)),
                      "largest remnant / (2^-53 V)": float(R[:, 0].max() / (U * V)) if len(R) else None})
        print(table[-1], flush=True)
    G, R = np.concatenate(genuine), np.concatenate(remnant)
    fig = new_figure((11.0, 4.6))
    left, right = fig.subplots(1, 2)
    bins = np.logspace(-6, 17, 93)
    left.hist(G[:, 0], bins=bins, color="tab:blue", label=f"genuine collisions ({len(G):,})")
    left.hist(R[:, 0], bins=bins, color="tab:red", label=f"rounding remnants ({len(R):,})")
    left.axvline(THRESHOLD_ULPS, color="k", linestyle="--", label=f"threshold: {THRESHOLD_ULPS:g} x 2^-53 V")
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("float closing speed w, in units of 2^-53 V (V = sqrt(2E/m))")
    left.set_ylabel("picks the old float criterion collided")
    left.set_title("against the system's speed scale: apart")
    left.legend(fontsize="small", loc="upper right")
    rel = np.logspace(-12, 0.5, 61)
    right.hist(G[:, 1], bins=rel, color="tab:blue", label="genuine")
    right.hist(R[:, 1], bins=rel, color="tab:red", label="remnants")
    right.set_xscale("log")
    right.set_yscale("log")
    right.set_xlabel("w / (|v_i|_1 + |v_j|_1): against the two balls' own speeds")
    right.set_title("against the balls' own speeds: mixed")
    right.legend(fontsize="small", loc="upper left")
    fig.suptitle("Float collisions, classified by exact arithmetic on the same picks: "
                 "half-planes 20x10 to 200x100 until frozen, tori for 2e6 steps")
    save(fig, HERE / "collisions_closing_speeds.png")
    (HERE / "collisions_closing_speeds.json").write_text(json.dumps(table, indent=2) + "\n")


if __name__ == "__main__":
    main()
