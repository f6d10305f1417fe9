"""Certified arithmetic on a GPU (`engine.gpu.certified`), under numba-cuda's simulator: the CPU's certified run
bit for bit (steps, collisions, the fixed-point state, its bounds and margin), exact arithmetic's counts, the same
one-line failure at the same step, and one clear line where a GPU run cannot go."""

import dataclasses

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.field.fixed import UncertifiedDecision
from pinnedballs.engine.gpu.certified import DevicePicks
from pinnedballs.util.errors import FieldError

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)

COUNTER = pb.UniformRandomPair(stream="counter", threads=1)


def grid_velocities(g, seed: int) -> np.ndarray:
    """Gaussian velocities on a grid of ``2^-45``: 64 bits hold them, and collisions soon round."""
    rng = np.random.default_rng(seed)
    return np.round(rng.normal(size=(g.n_balls, 2)) * 2**45) / 2**45


def single(g) -> np.ndarray:
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, np.sqrt(200.0)]
    return v


def both(g, v, run, **kwargs) -> list:
    """``run(sim)`` for a certified simulation on the CPU and on the GPU."""
    out = []
    for device in ("cpu", "cuda"):
        sim = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="certified", device=device, **kwargs)
        run(sim)
        out.append(sim)
    return out


def pieces(sim) -> None:
    sim.run(steps=150)
    sim.run(collisions=sim.collisions + 40)
    assert sim.run_until_frozen(max_steps=10**5)


def test_certified_on_a_gpu_is_the_cpus_run_bit_for_bit_and_exact_arithmetics_count():
    """Split into a run of steps, a collision target and a run to frozen: the GPU's state is the CPU's, bounds,
    rounding, the batched rule's pending sums and margin included, though it made the collisions in rounds; the
    count is exact arithmetic's."""
    g = pb.HalfPlane(8, 8)
    v = grid_velocities(g, 3)
    cpu, gpu = both(g, v, pieces, seed=4, precision=64)
    c = gpu.get_state().certified
    assert gpu.get_state().identical(cpu.get_state()) and c.identical(cpu.get_state().certified)
    assert c.rounding > 0 and any(c.pending) and c.bounds.any() and c.bound_batch > 0  # it rounded
    stats = gpu.engine.state.field_chain.picks.stats
    assert stats["rounds"] > 10 * stats["segments"] and stats["again"] >= 1  # in rounds; the target made again
    assert stats["uploads"] == 1 and stats["drawn"] == stats["segments"]  # the state stays there; picks drawn there
    exact = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="exact", seed=4)
    exact.run_until_frozen(max_steps=10**5)
    assert (gpu.steps, gpu.collisions) == (exact.steps, exact.collisions) == (1781, 323)
    assert gpu.closing_margin().smallest_collision == cpu.closing_margin().smallest_collision


def test_checkpoints_read_the_state_mid_run_and_a_results_file_resumes_on_either_device(tmp_path):
    """A run written with snapshots and checkpoints on the GPU (the state read back between its chunks, its
    velocities read from the changed balls alone) writes the CPU's file; resumed on the GPU it ends on the
    CPU's state."""
    g = pb.HalfPlane(8, 8)
    v = grid_velocities(g, 3)
    whole = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="certified", seed=4, precision=64)
    whole.run_until_frozen(max_steps=10**5)
    for device in ("cpu", "cuda"):
        sim = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="certified", seed=4, precision=64, device=device)
        sim.run(steps=400, writers=[pb.ResultsWriter(tmp_path / device, snapshots={"every_steps": 100})])
        assert np.array_equal(sim.velocities, pb.load(tmp_path / device).velocities)
    cpu, gpu = pb.load(tmp_path / "cpu"), pb.load(tmp_path / "cuda")
    assert np.array_equal(cpu.velocities, gpu.velocities) and cpu.steps == gpu.steps == 400
    assert [s.velocities.tobytes() for s in cpu.snapshots] == [s.velocities.tobytes() for s in gpu.snapshots]
    resumed = gpu.simulation(device="cuda")
    resumed.run_until_frozen(max_steps=10**5)
    assert resumed.get_state().identical(whole.get_state())


def test_a_pick_it_cannot_decide_stops_both_devices_at_the_same_step_with_the_same_line():
    g = pb.HalfPlane.from_size(16, 8)
    failures = []

    def run(sim):
        with pytest.raises(UncertifiedDecision) as info:
            sim.run_until_frozen(max_steps=10**5)
        failures.append(str(info.value))

    cpu, gpu = both(g, single(g), run, seed=1, precision=64)
    assert failures[0] == failures[1] and "\n" not in failures[0]
    assert "cannot decide contact 80 (balls 28, 37) at step 330: its closing speed" in failures[0]
    assert gpu.steps == cpu.steps == 329 and gpu.get_state().identical(cpu.get_state())


def test_a_narrowed_run_and_a_run_to_frozen_from_one_ball():
    """``late_precision``: the checks for narrowing cut the GPU's segments where the CPU checks, the state narrowed
    on the GPU at the CPU's step (896), or taken back with the picks a freeze takes back; a single moving ball's
    run to frozen at the default bits."""
    g = pb.HalfPlane(5, 5)
    for run, narrowed in ((lambda s: s.run(steps=1000), 896), (lambda s: s.run_until_frozen(max_steps=10**5), None)):
        cpu, gpu = both(g, grid_velocities(g, 0), run, seed=0, precision=128, late_precision=64)
        assert gpu.get_state().identical(cpu.get_state()) and gpu.engine.state.field_chain.narrowed == narrowed
    g = pb.HalfPlane.from_size(16, 8)
    cpu, gpu = both(g, single(g), lambda s: s.run_until_frozen(max_steps=10**5), seed=0)
    assert gpu.get_state().identical(cpu.get_state()) and gpu.steps == 1184 and gpu.is_frozen()


def test_fcc_in_q_sqrt_2_on_a_gpu_is_the_cpus():
    g = pb.FCC(2, 2, 2)
    rng = np.random.default_rng(1)
    v = np.round(rng.normal(size=(g.n_balls, 3)) * 2**45) / 2**45
    cpu, gpu = both(g, v, lambda s: s.run(steps=400), seed=2, precision=64)
    assert gpu.get_state().identical(cpu.get_state()) and gpu.collisions > 100
    assert any(gpu.get_state().certified.pending) and gpu.get_state().certified.bounds.any()  # it rounded


def test_what_a_gpu_cannot_run_in_certified_arithmetic_is_refused_in_one_line():
    g = pb.HalfPlane(4, 4)
    v = single(g)
    with pytest.raises(FieldError, match="^device: 'cuda' runs float and certified arithmetic; exact arithmetic runs "
                                         "on the CPU"):
        pb.Simulation(g, v, scheduler=COUNTER, arithmetic="exact", device="cuda")
    cpu = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="certified", seed=1)
    state = cpu.get_state()
    old = state.replace(certified=dataclasses.replace(state.certified, bound_batch=0))
    gpu = pb.Simulation(g, v, scheduler=COUNTER, arithmetic="certified", seed=1, device="cuda")
    with pytest.raises(FieldError, match=r"^certified: a state written under the step-order bound rule of "
                                         r"pinnedballs < 1\.0 does not resume; run it again from its start$"):
        gpu.set_state(old)
    assert gpu.get_state().identical(state)
    assert isinstance(gpu.engine.state.field_chain.picks, DevicePicks)


_PTX = r"""
import re
import numpy as np
from numba import typeof
from numba.cuda import types as T
import pinnedballs as pb
from pinnedballs.engine.gpu import certified
from pinnedballs.engine.gpu.compile import ptx
_, attempt, live = certified._kernels()[:3]
made = {}
for g in (pb.HalfPlane(3, 3), pb.FCC(2, 2, 2)):  # Q(sqrt 3) and Q(sqrt 2)
    f = pb.Simulation(g, np.ones((g.n_balls, g.dim)), arithmetic="certified").engine.state.field_chain
    A = lambda a, more=0: T.Array(typeof(a).dtype, a.ndim + more, "C")
    tables = [A(a) if isinstance(a, np.ndarray) else typeof(a) for a in f.tables]
    state = [A(a) for a in f._state()]
    scratch = [A(a, 1) for a in f.scratch]
    a1 = lambda t: T.Array(t, 1, "C")
    shared = (*tables, *state[:7], T.Array(T.uint64, 2, "C"), state[8], *scratch, T.Array(T.float64, 2, "C"))
    for name, kernel, sig in (
            ("attempt", attempt, (a1(T.int64), a1(T.int32), T.int64, a1(T.uint32), a1(T.uint32), T.uint32, T.uint32,
                                  a1(T.int32), a1(T.int32), T.int64, T.int64, T.boolean, *shared, a1(T.int8),
                                  a1(T.float64), a1(T.uint8))),
            ("live", live, (T.int64, T.int64, T.boolean, *tables, *state, *scratch, T.Array(T.float64, 2, "C"),
                            a1(T.int64)))):
        if (name, sig) not in made:  # a field whose arrays have the other's types compiles to the same PTX
            made[name, sig] = ptx(kernel.py_func, sig)
        code = made[name, sig]
        print(name, len(re.findall(r"\bfma\.[a-z.]*f64", code)), len(re.findall(r"\bmul\.rn\.f64", code)),
              len(re.findall(r"^\s*(?:mul|add|sub)\.f64", code, re.M)))
print("compiled", len(made))
"""


@pytest.mark.slow
def test_the_certified_kernels_round_every_operation_as_the_cpu_does():
    """Compiled for sm_90 (no GPU needed), the certified kernels' PTX, in Q(sqrt 3) and Q(sqrt 2): no fused
    multiply-add on doubles (the bounds and the float filter round as the CPU's) and only round-to-nearest
    products and sums. A kernel is compiled once for the two fields while their arrays have the same types (the
    same PTX: the field is in the tables' values)."""
    import subprocess
    import sys

    from helpers import ROOT

    out = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, cwd=ROOT, timeout=900,
                         env={"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
    assert out.returncode == 0, out.stderr[-3000:]
    *lines, made = [line.split() for line in out.stdout.splitlines()]
    assert len(lines) == 4 and made[0] == "compiled" and int(made[1]) in (2, 4), out.stdout
    assert all(fma == "0" and int(mul) > 0 and loose == "0" for _, fma, mul, loose in lines), out.stdout
