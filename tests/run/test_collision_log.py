"""The collision log: every collision's step and contact, exactly the chain's, surviving resume with
nothing lost or doubled, and replaying to the run's velocities bit for bit."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from reference import ReferenceSimulation

import pinnedballs as pb
from pinnedballs.engine import backends


def half_plane(rows=5, cols=7):
    g = pb.HalfPlane(rows, cols)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.4, 3.0]
    return g, v


@pytest.mark.parametrize("scheduler", ["uniform", "sweep", "random_sweep", "colored_sweep_shuffle"])
def test_the_log_is_the_twin_s_record_of_every_collision(tmp_path, scheduler, monkeypatch):
    """A log of 7 collisions at a time (so many flushes) holds the plain-Python twin's collision
    steps and picked contacts, one for one."""
    monkeypatch.setattr(backends, "LOG_CAPACITY", 7)
    g, v = half_plane()
    cls = {"uniform": pb.UniformRandomPair, "sweep": pb.Sweep, "random_sweep": pb.RandomSweep,
           "colored_sweep_shuffle": lambda: pb.ColoredSweep(shuffle=True)}[scheduler]
    sim = pb.Simulation(g, v, scheduler=cls(), seed=3)
    sim.run(steps=2_000, writers=[pb.CollisionLog(tmp_path / "events.h5")])
    twin = ReferenceSimulation.from_geometry(g, v, scheduler=scheduler, seed=3)
    twin.run(steps=2_000)
    ev = pb.CollisionLog.read(tmp_path / "events.h5")
    assert ev["step"].tolist() == twin.collision_steps
    assert ev["contact"].tolist() == [twin.picks[s - 1] for s in twin.collision_steps]
    assert ev["complete_to"] == 2_000 and len(ev["step"]) == sim.collisions


@pytest.mark.parametrize("kind", ["uniform until frozen", "rejection free", "colored sweep", "exact"])
def test_a_logged_run_is_the_unlogged_run_and_its_contacts_replay_it(tmp_path, kind):
    g, v = half_plane(8, 10)
    scheduler = {"rejection free": pb.RejectionFree(), "colored sweep": pb.ColoredSweep()}.get(kind)
    arithmetic = "exact" if kind == "exact" else "float"
    logged = pb.Simulation(g, v, scheduler=scheduler, seed=5, arithmetic=arithmetic)
    plain = pb.Simulation(g, v, scheduler=scheduler, seed=5, arithmetic=arithmetic)
    if kind == "colored sweep":  # plain steps: the logged run goes one contact at a time, the same bits
        logged.run(steps=50_000, writers=[pb.CollisionLog(tmp_path / "e.h5")])
        plain.run(steps=50_000)
    else:
        logged.run_until_frozen(10**7, writers=[pb.CollisionLog(tmp_path / "e.h5")])
        assert plain.run_until_frozen(10**7)
    assert logged.get_state().identical(plain.get_state())
    ev = pb.CollisionLog.read(tmp_path / "e.h5")
    assert len(ev["contact"]) == plain.collisions > 100
    replay = pb.Simulation(g, v, scheduler=pb.Replay(ev["contact"]), arithmetic=arithmetic)
    replay.run(steps=len(ev["contact"]))
    assert replay.collisions == len(ev["contact"])
    assert np.array_equal(replay.velocities, plain.velocities)


def test_resuming_from_a_checkpoint_behind_the_log_drops_what_came_after_it(tmp_path):
    """The log ran on past the last checkpoint (as when a run is killed between checkpoints):
    resumed from that checkpoint, it drops the later events and records them again, once."""
    g, v = half_plane(8, 10)
    whole = pb.Simulation(g, v, seed=9)
    whole.run(steps=9_000, writers=[pb.CollisionLog(tmp_path / "whole.h5")])
    sim = pb.Simulation(g, v, seed=9)
    log = pb.CollisionLog(tmp_path / "e.h5")
    sim.run(steps=4_000, writers=[log, pb.ResultsWriter(tmp_path / "run", checkpoint_seconds=0)])
    sim.run(steps=2_500, writers=[log])  # logged, never checkpointed
    assert pb.CollisionLog.read(tmp_path / "e.h5")["complete_to"] == 6_500
    resumed = pb.load(tmp_path / "run").simulation()
    assert resumed.steps == 4_000
    resumed.run(steps=5_000, writers=[pb.CollisionLog(tmp_path / "e.h5", resume=True)])
    got, expected = pb.CollisionLog.read(tmp_path / "e.h5"), pb.CollisionLog.read(tmp_path / "whole.h5")
    assert got["step"].tolist() == expected["step"].tolist() and got["contact"].tolist() == expected["contact"].tolist()
    with h5py.File(tmp_path / "e.h5") as f:  # no segment left over that the index does not list
        listed = sorted(name for name, _, _ in json.loads(f.attrs["segments"]))
    assert sorted(p.name for p in (tmp_path / "e.data").iterdir()) == listed


def test_a_log_refuses_what_would_lose_or_double_events(tmp_path):
    g, v = half_plane()
    sim = pb.Simulation(g, v, seed=1)
    sim.run(steps=500, writers=[pb.CollisionLog(tmp_path / "e.h5")])
    with pytest.raises(ValueError, match=r"e.h5: a collision log is already there; pass force=True"):
        pb.Simulation(g, v, seed=1).run(steps=10, writers=[pb.CollisionLog(tmp_path / "e.h5")])
    ahead = pb.Simulation(g, v, seed=1)
    ahead.run(steps=900)
    with pytest.raises(ValueError, match=r"the log is complete to step 500 but the simulation is at step 900"):
        ahead.run(steps=10, writers=[pb.CollisionLog(tmp_path / "e.h5", resume=True)])
    with pytest.raises(ValueError, match=r"the simulation is at step 900, not at its start"):
        ahead.run(steps=10, writers=[pb.CollisionLog(tmp_path / "new.h5")])
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(ValueError, match=r"junk.h5: not a readable collision log"):
        pb.CollisionLog.read(tmp_path / "junk.h5")
