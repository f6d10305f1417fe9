"""The paper's chain on a GPU, with the CPU beside it in the same run: one script of at most 5 minutes.

Prints one JSON line per figure (and writes them to ``$OUT/gpu.jsonl`` when ``OUT`` is set), in this
order, each part skipped when the budget (``BENCH_BUDGET`` seconds, default 290) cannot hold it:

* ``env``: the GPU, its multiprocessors, numba and numba-cuda, the CPU cores;
* ``compile``: seconds to compile the chain's kernels and the replicas' kernel (a first run);
* ``bits``: the GPU against the CPU on the counter stream (`UniformRandomPair(stream="counter")`):
  velocities (bit patterns), steps, collisions, stream words and margin equal, for a 200x100
  half-plane from one moving ball to frozen (default batch, tiny batches, a batch above the balls
  with owner resets every few rounds), unequal masses with restitution on an FCC packing, a torus at
  equilibrium, and 2000x1000 / 1000x500 stretches;
* ``speed``: steps a second on half-planes of 1000x500, 2000x1000 and 4000x2000 from one moving ball
  (after the first wave has spread), for several batch sizes, with rounds per batch and picks tried
  per step;
* ``frozen``: 2000x1000 and, when the measured rate says it fits, 4000x2000 from one moving ball to
  frozen, through ``Simulation.run_until_frozen`` (the driver's chunks, the freeze found and ended
  at its last collision);
* ``replicas``: 16,384 replicas of 200x100 and 32,768 of 100x50 to frozen, one GPU thread each,
  two of them checked against the CPU;
* ``certified``: certified arithmetic (384 then 256 bits) on a 500x250 half-plane from one moving ball to
  frozen, on the GPU and on one CPU core: the same state bit for bit, and the seconds of each;
* ``dask``: a GPU ensemble of 4,096 replicas of 200x100 through Dask (dask-cuda's ``LocalCUDACluster`` where
  installed) against the same ensemble in this process: the same rows, and the seconds of each;
* ``cpu``: the CPU beside it: ns a step of the sequential loop (counter and xoshiro streams), and the
  threaded chains (reservations on the counter stream, regions on xoshiro) on 1..all cores.

Run it on a machine with an NVIDIA GPU and numba-cuda (``python3 -m pip install ".[cuda]"``):

    OUT=out python benchmarks/bench_gpu.py
    BENCH_SMOKE=1 NUMBA_ENABLE_CUDASIM=1 python benchmarks/bench_gpu.py   # tiny sizes on the simulator
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pinnedballs as pb  # noqa: E402

T0 = time.perf_counter()
RATE = {}  # steps a second: of the last run to frozen, of the fastest launch shape
BUDGET = float(os.environ.get("BENCH_BUDGET", "290"))
SMOKE = os.environ.get("BENCH_SMOKE") == "1"
OUT = os.environ.get("OUT")
LOG = open(os.path.join(OUT, "gpu.jsonl"), "w") if OUT else None


def left() -> float:
    return BUDGET - (time.perf_counter() - T0)


def emit(**d) -> None:
    d["t"] = round(time.perf_counter() - T0, 1)
    line = json.dumps(d, default=lambda o: o.item() if hasattr(o, "item") else str(o))
    print(line, flush=True)
    if LOG:
        LOG.write(line + "\n")
        LOG.flush()


def part(name, fn, *args, need: float = 0.0) -> None:
    if left() < need:
        emit(part=name, skipped=f"{left():.0f} s left, needs about {need:.0f}")
        return
    try:
        fn(*args)
    except Exception:  # noqa: BLE001 - a failed part is reported, the others run
        emit(part=name, error=traceback.format_exc()[-3000:])


def single(g) -> np.ndarray:
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, np.sqrt(200.0)]
    return v


def counter(threads=1):
    return pb.UniformRandomPair(stream="counter", threads=threads)


def digest(v) -> str:
    return hashlib.sha1(np.ascontiguousarray(v).tobytes()).hexdigest()[:16]


def state(sim) -> dict:
    return dict(steps=sim.steps, collisions=sim.collisions, rng=[int(x) for x in sim.engine.state.rng],
                margin=[float(x) for x in sim.engine.state.margin], v=digest(sim.velocities))


def device_chain(sim, v, **options):
    """A `DeviceChain` of ``sim``'s chain (its model and stream key) from velocities ``v``, with ``options``."""
    from pinnedballs.engine.gpu.chain import DeviceChain

    g, model = sim.geometry, sim.engine.model
    return DeviceChain(v, g.contacts, g.row_pattern, model.masses, model.params, model.collide,
                       sim.engine.state.rng[:2], **options)


def half(length, depth):
    return pb.HalfPlane.from_size(length / 10, depth / 10) if SMOKE else pb.HalfPlane.from_size(length, depth)


# ---------------------------------------------------------------- parts


def env() -> None:
    import numba
    from numba import cuda

    info = dict(part="env", numba=numba.__version__, numpy=np.__version__, cpus=os.cpu_count(), smoke=SMOKE)
    try:
        import importlib.metadata as md
        info["numba_cuda"] = md.version("numba-cuda")
    except Exception:  # noqa: BLE001
        pass
    if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":
        d = cuda.get_current_device()
        info.update(gpu=d.name.decode() if isinstance(d.name, bytes) else d.name, sms=d.MULTIPROCESSOR_COUNT,
                    cc=list(d.compute_capability))
    emit(**info)


def compile_times() -> None:
    g = half(200, 100)
    t = time.perf_counter()
    try:
        sim = pb.Simulation(g, single(g), scheduler=counter(), seed=1, device="cuda")
        sim.run(steps=1000, progress=False)
    except Exception:  # noqa: BLE001 - no cooperative launch here: the blocks meet on an atomic counter
        emit(part="compile", barrier="grid", error=traceback.format_exc()[-2000:])
        os.environ["PINNEDBALLS_GPU_BARRIER"] = "atomic"
        sim = pb.Simulation(g, single(g), scheduler=counter(), seed=1, device="cuda")
        sim.run(steps=1000, progress=False)
    chain = time.perf_counter() - t
    from pinnedballs.engine.gpu.replicas import ReplicaChains
    t = time.perf_counter()
    model, state = sim.engine.model, sim.engine.state
    rc = ReplicaChains(sim.velocities[None], model.params[None], state.rng[None, :2], g.contacts, None, model.masses,
                       model.collide)
    rc.run(np.array([[10, 2**62, 0]]), 4096)
    emit(part="compile", chain_s=round(chain, 2), replicas_s=round(time.perf_counter() - t, 2),
         grid_blocks=sim.engine.chain.grid(), barrier=sim.engine.chain.barrier,
         resources=kernel_resources({"chain": sim.engine.chain._kernel, "live": sim.engine.chain._live,
                              "replicas": rc._kernel}))


def kernel_resources(kernels: dict) -> dict:
    """Registers a thread, local (spilled) bytes a thread and shared bytes a block of each compiled kernel (none
    under the simulator)."""
    out = {}
    for name, kernel in kernels.items():
        try:
            out[name] = {sig: dict(registers=kernel.get_regs_per_thread(sig),
                                   local=kernel.get_local_mem_per_thread(sig),
                                   shared=kernel.get_shared_mem_per_block(sig)) for sig in kernel.overloads}
            out[name] = {str(k): v for k, v in out[name].items()}
        except Exception as exc:  # noqa: BLE001 - the simulator keeps no machine code
            out[name] = f"not known here ({type(exc).__name__})"
    return out


def compare(name, geometry, v, run, masses=None, rule=None, batch=None, top=None) -> None:
    """The same run on the CPU (sequential loop, counter stream) and on the GPU."""
    out = {}
    for device in ("cpu", "cuda"):
        sim = pb.Simulation(geometry, v, scheduler=counter(), seed=11, masses=masses, rule=rule, device=device)
        if device == "cuda" and (batch or top):
            from pinnedballs.engine.backends import DeviceBackend
            sim.engine.chain = device_chain(sim, sim.velocities, batch=batch, **({"top": top} if top else {}))
            assert isinstance(sim.engine, DeviceBackend)
        t = time.perf_counter()
        run(sim)
        out[device] = (state(sim), time.perf_counter() - t, sim)
    same = out["cpu"][0] == out["cuda"][0]
    gpu = out["cuda"][2]
    emit(part="bits", case=name, balls=geometry.n_balls, equal=same, **out["cuda"][0],
         cpu_s=round(out["cpu"][1], 3), gpu_s=round(out["cuda"][1], 3),
         **({} if same else {"cpu": out["cpu"][0]}), stats=gpu.engine.chain.stats)


def bits_small() -> None:
    g = half(200, 100)
    frozen = lambda s: s.run_until_frozen(max_steps=10**8, progress=False)  # noqa: E731
    compare("200x100 single to frozen", g, single(g), frozen)
    compare("200x100 single to frozen, batch 64", g, single(g), frozen, batch=64)
    compare("200x100 single to frozen, batch above the balls, resets every 3 rounds", g, single(g), frozen,
            batch=256 if SMOKE else 1 << 15, top=3)
    n = 100 if SMOKE else 100_000
    compare(f"200x100 single, collisions={n} then 1234 steps", g, single(g),
            lambda s: (s.run(collisions=n, progress=False), s.run(steps=1234, progress=False)))
    fcc = pb.FCC(3, 3, 3, periodic=False) if SMOKE else pb.FCC(8, 8, 8, periodic=False)
    if fcc is not None:
        rng = np.random.default_rng(3)
        compare("FCC 8^3 unequal masses, Restitution(0.9), to frozen", fcc, rng.normal(size=(fcc.n_balls, 3)),
                frozen, masses=rng.uniform(0.5, 2.0, fcc.n_balls), rule=pb.Restitution(0.9))
    torus = pb.FlatTorus(8, 8) if SMOKE else pb.FlatTorus(64, 64)
    n = 2000 if SMOKE else 2 * 10**6
    compare(f"torus {torus.n_balls} balls Gaussian {n:.0e} steps", torus,
            np.random.default_rng(4).normal(size=(torus.n_balls, 2)), lambda s: s.run(steps=n, progress=False))


def bits_large() -> None:
    g = half(2000, 1000)
    n = 3000 if SMOKE else 3 * 10**7
    compare(f"2000x1000 Gaussian {n:.0e} steps", g, np.random.default_rng(1).normal(size=(g.n_balls, 2)),
            lambda s: s.run(steps=n, progress=False))
    g = half(1000, 500)
    n = 3000 if SMOKE else 2 * 10**8
    compare(f"1000x500 single {n:.0e} steps", g, single(g), lambda s: s.run(steps=n, progress=False))


def speed() -> None:
    sizes = [(1000, 500), (2000, 1000), (4000, 2000)]
    for length, depth in sizes:
        g = half(length, depth)
        base = pb.Simulation(g, single(g), scheduler=counter(), seed=1, device="cuda")
        warm = 2000 if SMOKE else 50 * g.n_contacts
        base.run(steps=warm, progress=False)  # the first wave spreads: the speed of the bulk of a run
        v = base.velocities
        for k in ((64, 256) if SMOKE else (1 << 18, 1 << 19, 1 << 20, 1 << 21)):
            if left() < 60:
                return
            chain = device_chain(base, v, batch=k)
            counters, rng, margin = (x.copy() for x in (base.engine.state.counters, base.engine.state.rng,
                                                        base.engine.state.margin))
            chain.run(counters, rng, margin, 1000 if SMOKE else 10 ** 8, 2**63 - 1, False)
            steps = int(min(5e9, 2e9 * g.n_balls / 577_000)) if not SMOKE else 2000
            t = time.perf_counter()
            chain.run(counters, rng, margin, steps, 2**63 - 1, False)
            wall = time.perf_counter() - t
            st = chain.stats
            emit(part="speed", size=f"{length}x{depth}", balls=g.n_balls, contacts=g.n_contacts, batch=k,
                 batch_over_balls=round(k / g.n_balls, 3), steps=steps, wall=round(wall, 3),
                 gsteps_per_s=round(steps / wall / 1e9, 3), rounds_per_batch=round(st["rounds"] / st["batches"], 2),
                 picks_tried_per_step=round(st["pick_rounds"] / (steps + (1000 if SMOKE else 10**8)), 3))


VARIANTS = [("grid", 256, None), ("atomic", 256, None), ("atomic", 128, None), ("atomic", 256, 128),
            ("atomic", 512, 64), ("atomic", 256, 96)]


def tune(length=4000, depth=2000) -> None:
    """Steps a second of each launch shape (barrier, threads a block, registers a thread) at one size, from one
    shared state; the fastest is kept (``PINNEDBALLS_GPU_*``) for the parts after."""
    g = half(length, depth)
    base = pb.Simulation(g, single(g), scheduler=counter(), seed=1, device="cuda")
    base.run(steps=2000 if SMOKE else 50 * g.n_contacts, progress=False)
    v, best = base.velocities, (0.0, None)
    for barrier, block, registers in VARIANTS:
        if left() < 40:
            break
        os.environ.update(PINNEDBALLS_GPU_BARRIER=barrier, PINNEDBALLS_GPU_BLOCK=str(block),
                          PINNEDBALLS_GPU_MAXREG=str(registers or ""))
        for k in ((256,) if SMOKE else (1 << 19,)):
            try:
                t = time.perf_counter()
                chain = device_chain(base, v, batch=k)
                counters, rng, margin = (x.copy() for x in (base.engine.state.counters, base.engine.state.rng,
                                                            base.engine.state.margin))
                chain.run(counters, rng, margin, 1000 if SMOKE else 10**8, 2**63 - 1, False)
                compile_s = time.perf_counter() - t
                steps = 2000 if SMOKE else 2 * 10**9
                t = time.perf_counter()
                chain.run(counters, rng, margin, steps, 2**63 - 1, False)
                rate = steps / (time.perf_counter() - t)
                emit(part="tune", size=f"{length}x{depth}", barrier=barrier, block=block, registers=registers, batch=k,
                     grid_blocks=chain.grid(), gsteps_per_s=round(rate / 1e9, 3), first_s=round(compile_s, 2),
                     v=digest(chain.velocities()))
                if rate > best[0]:
                    best = (rate, (barrier, block, registers, k))
            except Exception:  # noqa: BLE001
                emit(part="tune", barrier=barrier, block=block, registers=registers,
                     error=traceback.format_exc()[-1500:])
    if best[1] is not None:
        barrier, block, registers, k = best[1]
        os.environ.update(PINNEDBALLS_GPU_BARRIER=barrier, PINNEDBALLS_GPU_BLOCK=str(block),
                          PINNEDBALLS_GPU_MAXREG=str(registers or ""))
        RATE["tuned"] = best[0]
        BEST["batch"] = k
        emit(part="tune", best=dict(barrier=barrier, block=block, registers=registers, batch=k,
                                    gsteps_per_s=round(best[0] / 1e9, 3)))


BEST = {}


def frozen(length, depth) -> None:
    g = pb.HalfPlane.from_size(length / 100, depth / 100) if SMOKE else half(length, depth)
    sim = pb.Simulation(g, single(g), scheduler=counter(), seed=1, device="cuda")
    if BEST.get("batch") and length >= 4000:  # the batch the tuning found fastest at this size
        sim.engine.chain = device_chain(sim, sim.velocities, batch=BEST["batch"])
    t = time.perf_counter()
    done = sim.run_until_frozen(max_steps=2 * 10**12, progress=False)
    wall = time.perf_counter() - t
    RATE["frozen"] = sim.steps / wall
    emit(part="frozen", size=f"{length}x{depth}", balls=g.n_balls, frozen=done, steps=sim.steps,
         collisions=sim.collisions, wall=round(wall, 2), gsteps_per_s=round(sim.steps / wall / 1e9, 3),
         energy=sim.energy(), margin=sim.closing_margin().describe(), v=digest(sim.velocities),
         batch=sim.engine.chain.batch, stats=sim.engine.chain.stats)


def replicas(length, depth, count, rows: bool = True) -> None:
    """``count`` replicas to frozen, one a thread, their picks decoded from the lattice's row pattern (``rows``,
    what `run_ensemble(device="cuda")` runs) or read from the contact tables."""
    from pinnedballs.engine.gpu.replicas import ReplicaChains
    from pinnedballs.engine.streams.philox import counter_stream
    from pinnedballs.engine.streams.xoshiro import seed_state
    from pinnedballs.run.ensemble_gpu import replica_pattern
    g = half(length, depth)
    t = time.perf_counter()
    v0 = single(g)
    probe = pb.Simulation(g, v0, scheduler=counter(), seed=0)
    seeds = np.random.SeedSequence(2026).spawn(count)
    keys = np.stack([counter_stream(seed_state(s))[:2] for s in seeds])
    V = np.broadcast_to(probe.velocities, (count, *probe.velocities.shape))
    P = np.broadcast_to(probe.engine.model.params, (count, len(probe.engine.model.params)))
    pattern = replica_pattern(g) if rows else None
    rc = ReplicaChains(V, P, keys, g.contacts, pattern, probe.engine.model.masses, probe.engine.model.collide)
    setup = time.perf_counter() - t
    t = time.perf_counter()
    rc.run(np.tile(np.array([10**9, 2**62, 1]), (count, 1)), max(4096, 4 * g.n_contacts))
    wall = time.perf_counter() - t
    st = rc.state
    checks = []
    for r in (0, count - 1):
        sim = pb.Simulation(g, v0, scheduler=counter(), seed=seeds[r])
        sim.run_until_frozen(max_steps=10**9, progress=False)
        checks.append(bool(np.array_equal(sim.velocities, rc.velocities(r)) and sim.steps == st[r, 0]
                           and sim.collisions == st[r, 1] and np.array_equal(sim.engine.state.margin, rc.margin[r])))
    emit(part="replicas", layout=rc.layout, contacts="rows" if pattern is not None else "tables",
         size=f"{length}x{depth}", replicas=count, frozen=int(st[:, 3].sum()), wall=round(wall, 3),
         setup_s=round(setup, 2), steps=int(st[:, 0].sum()), gsteps_per_s=round(st[:, 0].sum() / wall / 1e9, 2),
         mean_collisions=float(st[:, 1].mean()), sd_collisions=float(st[:, 1].std(ddof=1)),
         checked_against_cpu=checks)


def cpu() -> None:
    import subprocess
    code = r"""
import json, os, sys, time, numpy as np, numba, pinnedballs as pb
L, D, stream, steps = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
g = pb.HalfPlane.from_size(L, D)
v = np.zeros((g.n_balls, 2)); v[g.boundary_center()] = [0, np.sqrt(200.0)]
threads = numba.config.NUMBA_NUM_THREADS
sim = pb.Simulation(g, v, seed=1, scheduler=pb.UniformRandomPair(stream=stream, threads=threads))
sim.run(steps=5 * g.n_contacts, progress=False)
t = time.perf_counter(); sim.run(steps=steps, progress=False); w = time.perf_counter() - t
print(json.dumps(dict(size=f"{L}x{D}", stream=stream, threads=threads, ns_per_step=w / steps * 1e9,
                      v=__import__('hashlib').sha1(sim.velocities.tobytes()).hexdigest()[:16])))
"""
    cores = os.cpu_count() or 1
    plan = [(2000, 1000, "counter", sorted({1, 2, 4, 8, cores})), (2000, 1000, "xoshiro", sorted({1, cores})),
            (4000, 2000, "counter", sorted({1, cores}))]
    one = {}
    for length, depth, stream, counts in plan:
        if SMOKE:
            length, depth = length // 10, depth // 10
        for threads in counts:
            if threads <= cores and left() >= 25:
                env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
                steps = 10**6 if SMOKE else 10**8
                r = subprocess.run([sys.executable, "-c", code, str(length), str(depth), stream, str(steps)],
                                   capture_output=True, text=True, env=env, timeout=max(5, left() - 5))
                if r.returncode != 0:
                    emit(part="cpu", size=f"{length}x{depth}", stream=stream, threads=threads, error=r.stderr[-1500:])
                    continue
                d = json.loads(r.stdout.strip().splitlines()[-1])
                one.setdefault((length, stream), d["ns_per_step"])
                emit(part="cpu", **d, speedup=round(one[(length, stream)] / d["ns_per_step"], 2))


def certified(length, depth, precision, late) -> None:
    """Certified arithmetic from one moving ball to frozen on the GPU and on the CPU (one core): the same state,
    bit for bit, and the seconds each took; the GPU's segments, rounds and segments run again."""
    length, depth = (16, 8) if SMOKE else (length, depth)  # the simulator is slow
    g = pb.HalfPlane.from_size(length, depth)
    out, states = dict(part="certified", size=f"{length}x{depth}", balls=g.n_balls, bits=[precision, late]), {}
    for device in ("cuda", "cpu"):
        sim = pb.Simulation(g, single(g), scheduler=counter(), seed=1, arithmetic="certified", precision=precision,
                            late_precision=late, device=device)
        t = time.perf_counter()
        sim.run_until_frozen(max_steps=10**11, progress=False)
        seconds = time.perf_counter() - t
        states[device] = sim.get_state()
        out[device] = dict(seconds=round(seconds, 2), steps=sim.steps, collisions=sim.collisions,
                           msteps_s=round(sim.steps / seconds / 1e6, 2))
        if device == "cuda":
            picks = sim.engine.state.field_chain.picks
            out["gpu_stats"] = dict(picks.stats)
            out["resources"] = kernel_resources(dict(zip(("reserve", "attempt", "live", "draw", "settled", "gather"),
                                                         picks.kernels)))
    out["identical"] = states["cuda"].identical(states["cpu"])
    emit(**out)


def dask_gpus() -> None:
    """A GPU ensemble through Dask (dask-cuda's `LocalCUDACluster` where installed, else one `LocalCluster` worker
    seeing the GPU): its rows against the same ensemble in this process, and the seconds each took."""
    from distributed import LocalCluster

    from pinnedballs.specs.run import parse_spec

    spec = parse_spec({"geometry": {"kind": "half_plane", "length": 20 if SMOKE else 200,
                                    "depth": 10 if SMOKE else 100},
                       "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1],
                                   "energy": 100},
                       "scheduler": {"kind": "uniform_random_pair", "stream": "counter"},
                       "stop": {"frozen": True, "max_steps": 10**9}, "seed": 3})
    count = 8 if SMOKE else 4096
    try:
        from dask_cuda import LocalCUDACluster
        cluster, kind = LocalCUDACluster(), "LocalCUDACluster"
    except ImportError:
        cluster, kind = LocalCluster(n_workers=1, threads_per_worker=1, processes=True), "LocalCluster"
    with cluster:
        t = time.perf_counter()
        there = pb.run_ensemble(spec, count, device="cuda", cluster=cluster, progress=False)
        dask_s = time.perf_counter() - t
    t = time.perf_counter()
    here = pb.run_ensemble(spec, count, device="cuda", progress=False)
    emit(part="dask", cluster=kind, replicas=count, dask_s=round(dask_s, 2), here_s=round(time.perf_counter() - t, 2),
         same_rows=json.dumps(there.rows, sort_keys=True) == json.dumps(here.rows, sort_keys=True), where=there.where)


def bits_quick() -> None:
    g = half(200, 100)
    compare("200x100 single to frozen", g, single(g), lambda s: s.run_until_frozen(max_steps=10**8, progress=False))
    g = half(2000, 1000)
    n = 3000 if SMOKE else 3 * 10**7
    compare(f"2000x1000 Gaussian {n:.0e} steps", g, np.random.default_rng(1).normal(size=(g.n_balls, 2)),
            lambda s: s.run(steps=n, progress=False))


def replicas_layouts() -> None:
    """16,384 replicas of 200x100 laid out one a block (a batch of 32 steps run by the block's lanes) and one
    a thread; the faster is kept for the parts after."""
    times = {}
    for layout in ("block", "thread"):
        if left() < 30:
            break
        os.environ["PINNEDBALLS_GPU_REPLICAS"] = layout
        t = time.perf_counter()
        for rows in (False, True):
            replicas(200, 100, 8 if SMOKE else 16384, rows)
        times[layout] = time.perf_counter() - t
    if times:
        os.environ["PINNEDBALLS_GPU_REPLICAS"] = min(times, key=times.get)


PARTS = {
    "env": lambda: part("env", env),
    "compile": lambda: part("compile", compile_times),
    "tune": lambda: part("tune", tune, need=60),
    "bits": lambda: part("bits", bits_small, need=30),
    "bits_quick": lambda: part("bits", bits_quick, need=20),
    "speed": lambda: part("speed", speed, need=60),
    "frozen2000": lambda: part("frozen", frozen, 2000, 1000, need=40),
    "replicas": lambda: [part("replicas", replicas, 200, 100, 8 if SMOKE else 16384, rows, need=25)
                         for rows in (False, True)],  # the tables, then the row pattern (what ensembles run)
    "replicas_layouts": lambda: part("replicas", replicas_layouts, need=25),
    # 4000x2000 takes about 457e9 steps (the probe's run): only when a measured rate says it fits
    "frozen4000": lambda: part("frozen", frozen, 4000, 2000, need=min(BUDGET, 20 + (1.5e4 if SMOKE else 4.6e11) / max(
        RATE.get("frozen", 1.0), 0.9 * RATE.get("tuned", 1.0)))),
    "bits_large": lambda: part("bits", bits_large, need=40),
    "replicas_small": lambda: part("replicas", replicas, 100, 50, 8 if SMOKE else 32768, need=15),
    "cpu": lambda: part("cpu", cpu, need=40),
    # the CPU takes 5-6 s at 500x250 (384/256 bits) on a 2-core VM: docs/collisions.md
    "certified": lambda: part("certified", certified, 500, 250, 384, 256, need=40),
    "dask": lambda: part("dask", dask_gpus, need=40),
}
DEFAULT = "env,compile,bits,certified,speed,frozen2000,replicas,frozen4000,bits_large,replicas_small,dask,cpu"

if __name__ == "__main__":
    for name in os.environ.get("BENCH_PARTS", DEFAULT).split(","):
        PARTS[name]()
    emit(part="end", wall=round(time.perf_counter() - T0, 1))
