"""The chain on a GPU (`engine.gpu`), run under numba-cuda's simulator: the CPU loop's bits on the counter
stream for every batch size, rule, geometry and stop, and one clear line where a GPU run cannot go."""

import subprocess
import sys

import numpy as np
import pytest
import user_rules
from helpers import ROOT, fcc_cluster

import pinnedballs as pb
from pinnedballs.engine.chain import COUNTERS, NO_LIMIT
from pinnedballs.engine.gpu.chain import DeviceChain
from pinnedballs.engine.gpu.replicas import S_COLLISIONS, S_FROZEN, S_STEPS, ReplicaChains
from pinnedballs.engine.margin import new_margin
from pinnedballs.engine.rows import row_pattern
from pinnedballs.util.errors import FieldError

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)

COUNTER = pb.UniformRandomPair(stream="counter", threads=1)


def single(g):
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, np.sqrt(200.0)]
    return v


def state(sim) -> tuple:
    """Everything a run leaves: velocities (bit patterns), counters, stream words, margin."""
    s = sim.get_state()
    return (s.velocities.view(np.uint64).tobytes(), s.steps, s.collisions, s.rng_state.tobytes(), s.margin.tobytes(),
            int(sim.engine.state.counters[3]))


def both(geometry, v, run, **kwargs):
    """``run(sim)`` on the CPU and on the GPU: their states."""
    out = []
    for device in ("cpu", "cuda"):
        sim = pb.Simulation(geometry, v, scheduler=COUNTER, seed=5, device=device, **kwargs)
        run(sim)
        out.append((state(sim), sim))
    return out


def test_a_half_plane_runs_to_frozen_with_the_cpu_bits():
    g = pb.HalfPlane.from_size(20, 10)
    (cpu, c), (gpu, s) = both(g, single(g), lambda sim: sim.run_until_frozen(max_steps=10**6, progress=False))
    assert gpu == cpu
    assert s.is_frozen() and s.approaching() == 0 and c.steps == s.steps
    assert s.energy() == pytest.approx(100.0, rel=1e-12)


def _chain_run(geometry, v, steps, masses=None, rule=None, pattern=None, **chain):
    """The CPU's run of ``steps`` and a `DeviceChain`'s (``chain`` options), as states."""
    cpu = pb.Simulation(geometry, v, scheduler=COUNTER, seed=8, masses=masses, rule=rule)
    cpu.run(steps=steps, progress=False)
    sim = pb.Simulation(geometry, v, scheduler=COUNTER, seed=8, masses=masses, rule=rule)
    dc = DeviceChain(sim.velocities, geometry.contacts, pattern, sim.engine.model.masses, sim.engine.model.params,
                     sim.engine.model.collide, sim.engine.state.rng[:2], **chain)
    counters, rng, margin = np.zeros(COUNTERS, dtype=np.int64), sim.engine.state.rng.copy(), new_margin()
    assert dc.run(counters, rng, margin, steps, NO_LIMIT, False) == steps
    assert (counters[0], counters[1], counters[3]) == (cpu.steps, cpu.collisions, cpu.engine.state.counters[3])
    np.testing.assert_array_equal(rng, cpu.engine.state.rng)
    np.testing.assert_array_equal(margin, cpu.engine.state.margin)
    np.testing.assert_array_equal(dc.velocities().view(np.uint64), cpu.velocities.view(np.uint64))
    return dc


@pytest.mark.parametrize("batch, top", [(1, 5), (3, 2), (256, 2), (4096, 1022)])
def test_any_batch_size_gives_the_same_bits(batch, top):
    """Batches of 1 pick up to many times the balls; owner words reset every ``top`` rounds or so."""
    torus = pb.FlatTorus(6, 6)
    dc = _chain_run(torus, np.random.default_rng(2).normal(size=(torus.n_balls, 2)), 400, batch=batch, top=top)
    assert dc.stats["batches"] == -(-400 // batch)
    assert dc.stats["resets"] >= (1 if top <= 5 else 0)


def test_unequal_masses_and_restitution_in_three_dimensions():
    fcc = fcc_cluster(2)
    rng = np.random.default_rng(3)
    _chain_run(fcc, rng.normal(size=(fcc.n_balls, 3)), 300, masses=rng.uniform(0.5, 2.0, fcc.n_balls),
               rule=pb.Restitution(0.5), batch=16)


def test_a_lattice_read_by_index_and_a_curved_surface():
    """The row pattern's decoding (`engine.rows`, here forced on a small half-plane) and tangent frames on a
    sphere (``t_j`` read from its own row, not ``-t_i``)."""
    g = pb.HalfPlane.from_size(20, 10)
    rows, cols = g.row_shape()
    pattern = row_pattern(g.contacts.pairs, g.contacts.ends, rows, cols, min_balls=0)
    assert pattern is not None
    _chain_run(g, single(g), 300, pattern=pattern, batch=32)
    sphere = pb.Sphere.geodesic(2)
    assert not sphere.contacts.flat
    v = np.random.default_rng(4).normal(size=(sphere.n_balls, sphere.dim))
    _chain_run(sphere, v, 300, batch=16)


def test_a_state_resumed_on_the_gpu_goes_on_bit_for_bit():
    g = pb.HalfPlane.from_size(20, 10)
    whole = pb.Simulation(g, single(g), scheduler=COUNTER, seed=6, device="cuda")
    whole.run(steps=900, progress=False)
    first = pb.Simulation(g, single(g), scheduler=COUNTER, seed=6, device="cuda")
    first.run(steps=400, progress=False)
    later = pb.Simulation(g, single(g), scheduler=COUNTER, seed=1, device="cuda")
    later.set_state(first.get_state())
    later.run(steps=500, progress=False)
    assert state(later) == state(whole)


@pytest.mark.parametrize("layout, rows", [("block", False), ("block", True), ("thread", False), ("thread", True)])
def test_replicas_are_the_cpus_simulations(layout, rows, monkeypatch):
    """Each replica runs to its own limits (frozen, a step count, a collision target) and ends as the CPU's
    simulation with its seed: velocities, counters, margin; one a block (its lanes running batches of steps)
    or one a thread, its contacts read from the tables or decoded from the lattice's row pattern."""
    monkeypatch.setenv("PINNEDBALLS_GPU_REPLICAS", layout)
    g = pb.HalfPlane.from_size(20, 10)
    seeds = np.random.SeedSequence(3).spawn(4)
    sims = [pb.Simulation(g, single(g), scheduler=COUNTER, seed=s) for s in seeds]
    pattern = row_pattern(g.contacts.pairs, g.contacts.ends, *g.row_shape(), min_balls=0) if rows else None
    assert (pattern is not None) == rows
    chains = ReplicaChains(np.stack([s.velocities for s in sims]), np.stack([s.engine.model.params for s in sims]),
                           np.stack([s.engine.state.rng[:2] for s in sims]), g.contacts, pattern,
                           sims[0].engine.model.masses, sims[0].engine.model.collide)
    limits = np.array([[10**6, NO_LIMIT, 1], [700, NO_LIMIT, 0], [10**6, 60, 1], [10**6, NO_LIMIT, 1]])
    chains.run(limits, 512)
    sims[0].run_until_frozen(max_steps=10**6, progress=False)
    sims[1].run(steps=700, progress=False)
    sims[2].run(collisions=60, progress=False)
    sims[3].run_until_frozen(max_steps=10**6, progress=False)
    for r, sim in enumerate(sims):
        assert (chains.state[r, S_STEPS], chains.state[r, S_COLLISIONS]) == (sim.steps, sim.collisions)
        assert chains.state[r, S_FROZEN] == (r in (0, 3))
        np.testing.assert_array_equal(chains.velocities(r).view(np.uint64), sim.velocities.view(np.uint64))
        np.testing.assert_array_equal(chains.margin[r], sim.engine.state.margin)


def test_what_the_gpu_does_not_run_is_said_in_one_line():
    g = pb.HalfPlane.from_size(20, 10)
    v = single(g)
    cases = [({"scheduler": pb.UniformRandomPair()}, "runs UniformRandomPair\\(stream='counter'\\)"),
             ({"scheduler": pb.Sweep()}, "Sweep\\(\\) runs on the CPU"),
             ({"scheduler": COUNTER, "arithmetic": "exact"}, "exact arithmetic runs on the CPU"),
             ({"scheduler": COUNTER, "device": "gpu"}, "device: must be 'cpu' or 'cuda'")]
    for kwargs, message in cases:
        with pytest.raises(FieldError, match=message):
            pb.Simulation(g, v, seed=1, **{"device": "cuda", **kwargs})
    sim = pb.Simulation(g, v, scheduler=COUNTER, seed=1, device="cuda")
    sim.collision_listeners.append(lambda steps, contacts: None)
    with pytest.raises(FieldError, match="device: the collision log runs on the CPU"):
        sim.run(steps=10, progress=False)


_CHILD = r"""
import numpy as np, sys, pinnedballs as pb
{block}
g = pb.HalfPlane.from_size(20, 10)
try:
    pb.Simulation(g, np.zeros((g.n_balls, 2)), scheduler=pb.UniformRandomPair(stream="counter"), device="cuda")
except ValueError as exc:
    print(exc)
"""


@pytest.mark.slow
@pytest.mark.parametrize("block, message", [
    ("", "device: 'cuda' found no GPU: numba-cuda sees no CUDA driver or device here"),
    ("sys.modules['numba.cuda'] = None", 'device: \'cuda\' needs numba-cuda, which is not installed '
                                          '(python3 -m pip install ".[cuda]" (from the checkout))')])
def test_without_a_gpu_or_numba_cuda_one_line_says_so(block, message):
    env = {"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", _CHILD.format(block=block)], capture_output=True, text=True,
                         env=env, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(message) and out.stdout.count("\n") == 1, out.stdout


_PTX = r"""
import re, sys, types
import numpy as np
from numba import cuda, njit
from numba.cuda import types as T
from pinnedballs.engine.gpu.compile import ptx
from pinnedballs.engine.gpu.kernels import chain_kernel, live_kernel
from pinnedballs.engine.gpu.replicas import lanes_kernel, replicas_kernel
from pinnedballs.rules import collide_elastic, collide_equal, collide_masses
sys.path.insert(0, "tests")
from user_rules import collide_sticky, collide_spring
A = lambda dt, nd: T.Array(dt, nd, "C")
f64, i64, u64, u32 = T.float64, T.int64, T.uint64, T.uint32
tables = (A(u32, 2), A(T.uint8, 2), A(i64, 1), A(i64, 1), f64, A(f64, 2), A(f64, 1))
chain = (A(f64, 2), *tables, A(f64, 1), A(u64, 1), A(i64, 1), A(u32, 1), A(u32, 1), A(T.int32, 2), A(T.int32, 1),
         A(T.int32, 1), A(T.uint8, 1), A(f64, 1), A(i64, 1))
for name, rule in (("elastic", collide_elastic), ("equal", collide_equal), ("masses", collide_masses),
                   ("sticky", collide_sticky), ("spring", collide_spring)):
    for kernel, sig in ((chain_kernel(rule, 2, True, True, "atomic"), chain),
                        (chain_kernel(rule, 3, False, False, "grid"), chain),
                        (live_kernel(rule, 2, True, False), (A(f64, 2), *tables, A(f64, 1), i64, A(i64, 1))),
                        (replicas_kernel(rule, 2, True, False), (A(f64, 3), *tables, A(f64, 2), A(u64, 2), A(i64, 2),
                                                                 A(f64, 2), A(i64, 2), i64)),
                        (lanes_kernel(rule, 3, False, True), (A(f64, 3), *tables, A(f64, 2), A(u64, 2), A(i64, 2),
                                                              A(f64, 2), A(i64, 2), i64))):
        code = ptx(kernel.py_func, sig)
        print(name, len(re.findall(r"\bfma\.[a-z.]*f64", code)), len(re.findall(r"\bmul\.rn\.f64", code)),
              len(re.findall(r"^\\s*(?:mul|add|sub)\\.f64", code, re.M)))
"""


@pytest.mark.slow
def test_the_kernels_round_every_operation_as_the_cpu_does():
    """Compiled for sm_90 (no GPU needed: NVVM from numba-cuda's cu13 extra), the kernels' PTX, for the
    built-in rules and for two users' rules (one written whole, one by its impulse), has no fused
    multiply-add on doubles, which would round once where the CPU rounds twice, and only round-to-nearest
    products and sums (``mul.rn.f64``: a product without ``.rn`` ptxas may still fuse)."""
    out = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, cwd=ROOT, timeout=900,
                         env={"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
    assert out.returncode == 0, out.stderr[-3000:]
    lines = [line.split() for line in out.stdout.splitlines()]
    assert len(lines) == 25
    assert all(fma == "0" and int(mul) > 0 and loose == "0" for _, fma, mul, loose in lines), out.stdout


_REFUSED = r"""
import numpy as np, sys, pinnedballs as pb
sys.path.insert(0, "tests")
import user_rules
g = pb.HalfPlane.from_size(20, 10)
v = np.zeros((g.n_balls, 2))
v[g.boundary_center()] = [0.0, 10.0]
for rule in (user_rules.Sticky(0.5), user_rules.Spring(0.25), user_rules.Exponential(), user_rules.Allocating()):
    try:
        pb.Simulation(g, v, rule=rule, scheduler=pb.UniformRandomPair(stream="counter"), device="cuda", seed=1)
    except ValueError as exc:
        print(exc)
"""


@pytest.mark.slow
def test_a_rule_that_would_not_give_the_cpus_bits_is_refused_in_one_line():
    """Without a GPU (and without the simulator) a rule is compiled for one all the same: a user's rule that
    compiles with the CPU's rounding gets as far as the missing GPU; one calling ``exp`` (libdevice's, not
    libm's, and fused on purpose) or one that numba-cuda cannot compile is refused naming the rule and why."""
    out = subprocess.run([sys.executable, "-c", _REFUSED], capture_output=True, text=True, cwd=ROOT, timeout=900,
                         env={"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
    assert out.returncode == 0, out.stderr[-3000:]
    lines = out.stdout.splitlines()
    assert len(lines) == 4, out.stdout
    assert lines[0].startswith("device: 'cuda' found no GPU") and lines[1].startswith("device: 'cuda' found no GPU")
    assert lines[2].startswith("rule: Exponential cannot run on a GPU: it calls a function (exp, log, sin, pow")
    assert lines[3].startswith("rule: Allocating cannot run on a GPU: numba-cuda cannot compile it: "
                               "No implementation of function Function(norm)")
    assert "user_rules.py:" in lines[3] and lines[3].endswith("; device='cpu' runs it")


@pytest.mark.slow
def test_the_simulator_refuses_what_a_gpu_refuses_in_its_words(tmp_path, monkeypatch):
    """Issue 49, item 7: under the simulator a user's rule is compiled for a GPU aside (`engine.gpu.aside`: a process
    without the simulator), so one calling ``exp``, and one numba-cuda cannot compile, are refused with the very line
    a GPU's machine says (the child above, without the simulator); before, the simulator ran both. The verdicts
    are kept on disk, and the next process asks for none."""
    from pinnedballs.engine.gpu.aside import verdict

    gpu = subprocess.run([sys.executable, "-c", _REFUSED], capture_output=True, text=True, cwd=ROOT, timeout=900,
                         env={"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
    assert gpu.returncode == 0, gpu.stderr[-3000:]
    said = gpu.stdout.splitlines()[2:]
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # a cold cache of verdicts: each rule asks a child
    verdict.cache_clear()
    g = pb.HalfPlane.from_size(20, 10)
    for _ in range(2):  # asked, then read back
        for rule, line in zip((user_rules.Exponential(), user_rules.Allocating()), said, strict=True):
            with pytest.raises(FieldError) as refused:
                pb.Simulation(g, single(g), rule=rule, scheduler=COUNTER, device="cuda", seed=1)
            assert str(refused.value) == line
        assert len(list((tmp_path / "gpu_rules").glob("*.json"))) == 2
        verdict.cache_clear()


@pytest.mark.parametrize("rule", [user_rules.Sticky(0.5), user_rules.Spring(0.25)])
def test_a_users_rule_runs_on_the_gpu_with_the_cpus_bits(rule):
    """A rule written as docs/extending.md shows (whole, or by its impulse) on ``device="cuda"``: the kernels
    call its own functions, so the run to frozen and a split run give the CPU's bits."""
    g = pb.HalfPlane.from_size(20, 10)

    def run(sim):
        sim.run(steps=300, progress=False)
        sim.run_until_frozen(max_steps=10**6, progress=False)

    (cpu, c), (gpu, _) = both(g, single(g), run, rule=rule)
    assert gpu == cpu and c.collisions > 100
    fcc = fcc_cluster(2)
    v = np.random.default_rng(7).normal(size=(fcc.n_balls, 3))
    _chain_run(fcc, v, 300, rule=rule, batch=16)


def test_a_device_chain_refuses_what_its_kernels_cannot_run():
    g = pb.HalfPlane.from_size(20, 10)
    sim = pb.Simulation(g, single(g), scheduler=COUNTER, seed=1)
    args = (sim.velocities, g.contacts, None, sim.engine.model.masses, sim.engine.model.params)
    for options, message in (({"batch": 0}, r"^batch must be in \[1, 4194304\] and top in \[1, 1022\]$"),
                             ({"top": 1023}, r"^batch must be in \[1, 4194304\]")):
        with pytest.raises(ValueError, match=message):
            DeviceChain(*args, sim.engine.model.collide, sim.engine.state.rng[:2], **options)
