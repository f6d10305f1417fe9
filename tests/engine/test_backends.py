"""What a chain's backend says it ran on (`Backend.resources`, which a run's provenance records): the threads of the
loop that ran, the share of the work a `ThreadTuner` gave each count, the GPU; and the bits never depend on it."""

from __future__ import annotations

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.chain import NO_LIMIT
from pinnedballs.engine.jit.intrinsics import TICKS
from pinnedballs.engine.threads.tuning import most_threads
from pinnedballs.schedulers import colored_sweep


def _sim(scheduler, **options) -> pb.Simulation:
    g = pb.FlatTorus(6, 6)
    return pb.Simulation(g, np.random.default_rng(1).standard_normal((g.n_balls, 2)), scheduler=scheduler, seed=4,
                         **options)


def test_the_sequential_loop_runs_on_one_thread_and_says_which_loop():
    """A small torus: the table loop, chosen by its size, its blocks with a branch or without as their costs (or,
    where the CPU cannot time them, the share of collisions) chose (`engine.sequential.choice`)."""
    sim = _sim(pb.UniformRandomPair())
    sim.run(steps=2000)
    said = sim.engine.resources()
    loop = said.pop("loop")
    assert said == {"kind": "cpu", "threads": 1}
    assert loop["name"] == "tables" and loop["by"] == "size"
    assert loop["blocks"] == ("measured" if TICKS else "threshold")
    assert 0.0 <= loop["branch_free"] <= 1.0


@pytest.mark.slow  # compiles the sweep's threaded loop (seconds on an empty cache)
def test_a_sweep_of_plain_steps_runs_on_its_threads_and_one_until_frozen_on_one():
    sim = _sim(pb.ColoredSweep(threads=most_threads()))
    assert sim.engine.resources() == {"kind": "cpu", "threads": 1}  # nothing run yet
    sim.run(steps=2000)  # plain steps: the sweep's own parallel loop
    assert sim.engine.resources() == {"kind": "cpu", "threads": most_threads()}
    frozen = _sim(pb.ColoredSweep(threads=most_threads()))
    frozen.run(steps=2000, until_frozen=True)  # the engine's sequential loop, which watches for the freeze
    said = frozen.engine.resources()
    assert {k: said[k] for k in ("kind", "threads")} == {"kind": "cpu", "threads": 1}
    assert said["loop"]["name"] == "tables"


@pytest.mark.slow  # compiles the sweep's threaded loop (seconds on an empty cache)
@pytest.mark.skipif(most_threads() < 2, reason="the tuner chooses between several thread counts")
def test_a_tuned_sweep_says_what_its_tuner_chose_and_keeps_the_bits(monkeypatch):
    monkeypatch.setattr(colored_sweep, "TUNED_SEGMENT", 256)  # segments of 256 steps: a short run is tuned
    tuned, fixed = _sim(pb.ColoredSweep()), _sim(pb.ColoredSweep(threads=1))
    assert tuned.engine.run(64 * 256, NO_LIMIT, False) == fixed.engine.run(64 * 256, NO_LIMIT, False) == 64 * 256
    said = tuned.engine.resources()
    shares = tuned.engine.own_steps.tuner.shares()
    assert said == {"kind": "cpu", "threads": max(shares, key=shares.get),
                    "tuned": {str(k): s for k, s in shares.items()}}
    assert set(said["tuned"]) <= {str(most_threads()), "1"} and sum(said["tuned"].values()) == pytest.approx(1.0)
    assert np.array_equal(tuned.velocities, fixed.velocities)  # whatever it chose: the bits of one thread


@pytest.mark.cuda
def test_a_gpu_backend_names_its_gpu_or_the_simulator():
    pytest.importorskip("numba_cuda")
    from pinnedballs.engine.gpu.compile import SIMULATED

    sim = _sim(pb.UniformRandomPair(stream="counter"), device="cuda")
    said = sim.engine.resources()
    assert said["kind"] == "cuda"
    if SIMULATED:
        assert said == {"kind": "cuda", "gpu": "simulated"}
    else:  # on a GPU: its name and a compute capability "major.minor"
        major, minor = said["compute_capability"].split(".")
        assert said["gpu"] and major.isdigit() and minor.isdigit()
