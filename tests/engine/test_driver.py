"""Every Python run goes in chunks (`pinnedballs.engine.driver`), writers or none (issue 26, item 1;
issue 24, item 5): Ctrl-C stops ``sim.run`` and ``sim.run_until_frozen`` at the end of a chunk with
KeyboardInterrupt, the simulation whole, so that continuing it gives the bits of a run never
interrupted; the chunks change no bit; the progress shows the steps, the collisions or, until frozen,
a count.

A real SIGINT is sent to a child Python process at random moments: in a float run, a run until
frozen, an exact run and a run logging its collisions (the last two update their state in Python
between compiled calls).
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine import driver
from pinnedballs.util.progress import DELAY

ROOT = Path(__file__).resolve().parents[2]


def torus() -> pb.Simulation:
    g = pb.FlatTorus(8, 8)
    return pb.Simulation(g, np.random.default_rng(4).standard_normal((g.n_balls, 2)), seed=9)


# ---------------------------------------------------------------- chunks


def test_chunks_grow_from_the_first_and_change_no_bit(monkeypatch):
    """The first chunk is `FIRST_CHUNK` steps (here above the per-contact floor), each next one at
    most `GROWTH` times the one before; the run ends on the bits of one call of the engine's loop."""
    sizes, advance = [], driver.advance

    def recorded(sim, steps, *args):
        sizes.append(steps)
        return advance(sim, steps, *args)

    monkeypatch.setattr(driver, "advance", recorded)
    chunked = torus()
    assert chunked.run(steps=3_000_000, progress=False) == 3_000_000
    whole = torus()
    assert whole.engine.run(3_000_000, driver.NO_LIMIT, False) == 3_000_000
    assert chunked.get_state().identical(whole.get_state())
    assert sizes[0] == driver.FIRST_CHUNK and sum(sizes) == 3_000_000 and len(sizes) > 2
    assert all(b <= driver.GROWTH * a for a, b in zip(sizes, sizes[1:-1]))  # the last is cut at the stop


def test_a_run_until_frozen_ends_on_the_freezing_collision_however_chunked(monkeypatch):
    """Chunks of 7 steps: the freeze is found whether it falls inside a chunk or on its last step."""
    g = pb.HalfPlane(4, 5)
    v = np.zeros((g.n_balls, 2))
    v[2] = [0.0, 1.0]
    whole = pb.Simulation(g, v, seed=1)
    assert whole.run_until_frozen(max_steps=10**7)
    frozen_at = whole.steps
    for chunk in (7, frozen_at, frozen_at - 1):
        monkeypatch.setattr(driver, "CHUNK_STEPS", chunk)
        monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
        sim = pb.Simulation(g, v, seed=1)
        assert sim.run_until_frozen(max_steps=10**7)
        assert sim.get_state().identical(whole.get_state())
        sim = pb.Simulation(g, v, seed=1)
        assert sim.run_until_frozen(max_steps=frozen_at)  # the freeze on the very last step allowed
        assert sim.steps == frozen_at


# ---------------------------------------------------------------- progress


def test_progress_over_steps_collisions_and_until_frozen(capfd):
    sim = torus()
    sim.run(steps=2_000_000, progress=True)
    err = capfd.readouterr().err
    assert "running: 100%" in err and "2.00M/2.00M" in err and f"collisions={sim.collisions:,}" in err
    sim.run(collisions=sim.collisions + 5_000, progress=True)
    err = capfd.readouterr().err
    assert "running: 100%" in err and " collisions" in err and f"steps={sim.steps:,}" in err
    g = pb.HalfPlane(4, 5)
    v = np.zeros((g.n_balls, 2))
    v[2] = [0.0, 1.0]
    frozen = pb.Simulation(g, v, seed=1)
    assert frozen.run_until_frozen(max_steps=10**7, progress=True)
    err = capfd.readouterr().err
    assert "until frozen:" in err and "%" not in err  # a count, not a bar: the end is unknown
    assert f"collisions={frozen.collisions:,}" in err


def test_progress_none_is_silent_off_a_terminal(capfd):
    """Under pytest stderr is no terminal and no notebook kernel runs: None shows nothing."""
    torus().run(steps=500_000)
    assert capfd.readouterr().err == ""
    assert DELAY > 0


def test_progress_must_be_a_flag_or_none():
    with pytest.raises(TypeError, match=r"^progress: must be True, False or None \(shown where it helps\), got 'yes'$"):
        torus().run(steps=10, progress="yes")


# ---------------------------------------------------------------- a real SIGINT to a Python run

CHILD = """
import sys, time
import numpy as np
import pinnedballs as pb

kind, total, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
g = pb.FlatTorus(6, 6) if kind == "exact" else pb.FlatTorus(40, 40)  # never frozen: runs to its end
sim = pb.Simulation(g, np.random.default_rng(2).standard_normal((g.n_balls, 2)), seed=5,
                    arithmetic="exact" if kind == "exact" else "float")
log = []
if kind == "log":  # a run telling a listener of every collision, in batches
    sim.collision_listeners.append(lambda steps, contacts: log.append((steps, contacts)))

def go(steps):
    if kind == "until frozen":
        sim.run_until_frozen(max_steps=steps, progress=False)
    else:
        sim.run(steps=steps, progress=False)

go(0)  # compiled
print("ready", flush=True)
interrupted = []
while sim.steps < total:  # to the same end, however often interrupted
    try:
        go(total - sim.steps)
    except KeyboardInterrupt:
        interrupted.append(sim.steps)
        print("interrupted", sim.steps, flush=True)
st = sim.get_state()
extra = {} if st.exact is None else {"exact": st.exact.astype(str)}
if kind == "log":
    extra = {"log_steps": np.concatenate([s for s, _ in log]), "log_contacts": np.concatenate([c for _, c in log])}
np.savez(out, velocities=st.velocities, counts=[st.steps, st.collisions], rng=st.rng_state,
         scheduler=st.scheduler_state, interrupted=interrupted[0] if interrupted else -1, **extra)
"""

#: the steps of each run: 1.5 to 2.5 s on a quiet machine (a signal within 0.5 s finds it running). The exact run
#: widens as it goes (810 limbs at a million steps), so its time grows faster than its steps: 1.2 million took
#: 2.0 s on the 2-core machine in 2026-12 (500,000 took 0.44 s once its limb loops were tuned: too short)
RUNS = {"torus": 150_000_000, "until frozen": 150_000_000, "exact": 1_200_000, "log": 40_000_000}


def child_run(tmp_path: Path, kind: str, signals: list[float] | None):
    """Run CHILD for ``kind``; after it says ready, SIGINT at each delay of ``signals``. Its saved
    arrays, and the seconds from the first signal to its "interrupted" line (None if none)."""
    out = tmp_path / f"{kind.replace(' ', '_')}_{len(signals or ())}.npz"
    child = subprocess.Popen([sys.executable, "-c", CHILD, kind, str(RUNS[kind]), str(out)],
                             env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    assert child.stdout.readline() == "ready\n"
    latency = None
    if signals:
        time.sleep(signals[0])
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        for delay in signals[1:]:
            time.sleep(delay)
            child.send_signal(signal.SIGINT)
        line = child.stdout.readline()
        if line.startswith("interrupted"):
            latency = time.monotonic() - sent
    _, err = child.communicate(timeout=600)
    assert child.returncode == 0, err
    return dict(np.load(out)), latency


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory):
    cache = {}

    def get(kind: str):
        if kind not in cache:
            cache[kind] = child_run(tmp_path_factory.mktemp("undisturbed"), kind, None)[0]
        return cache[kind]
    return get


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(RUNS))
@pytest.mark.parametrize("seed", range(3))
def test_sigint_stops_a_python_run_at_a_chunk_and_it_continues_to_the_same_bits(tmp_path, undisturbed, kind, seed):
    """Before: a run without writers ignored Ctrl-C to its end (minutes, hours). Now the child's
    KeyboardInterrupt comes within a chunk or so of the signal, and the run, continued, ends on the
    bits of the undisturbed run (the collision log too: no batch lost or told twice)."""
    rng = random.Random(f"{kind}{seed}")
    signals = [rng.uniform(0.0, 0.5)] + ([rng.uniform(0.0, 0.05)] if seed == 2 else [])  # seed 2: Ctrl-C twice
    got, latency = child_run(tmp_path, kind, signals)
    whole = undisturbed(kind)
    assert 0 < got["interrupted"] < RUNS[kind]
    assert latency is not None and latency < 10  # chunks of 0.2 s; generous for a loaded machine
    for name in whole:
        if name != "interrupted":
            assert np.array_equal(got[name], whole[name]), name


# ---------------------------------------------------------------- a Ctrl-C while the loop compiles

COMPILING = """
import json, os, signal, sys, tempfile, time
import numpy as np
from numba.core import event
import pinnedballs as pb

def system():
    g = pb.FlatTorus(12, 12)
    return pb.Simulation(g, np.random.default_rng(3).standard_normal((g.n_balls, 2)), seed=8)

sent = []

class CtrlC(event.Listener):  # Ctrl-C as numba begins to compile the loop (seconds with an empty cache)
    def on_start(self, ev):
        if getattr(ev.data["dispatcher"].py_func, "__name__", "") == "run_to_limits" and not sent:
            sent.append(time.monotonic())
            os.kill(os.getpid(), signal.SIGINT)

    def on_end(self, ev):
        pass

event.register("numba:compile", CtrlC())
sim, start = system(), system().get_state()
try:
    sim.run(steps=5000, progress=False)
    waited = None
except KeyboardInterrupt:
    waited = time.monotonic() - sent[0]
untouched = sim.get_state().identical(start)
sim.run(steps=5000, progress=False)  # waits for the compile left running, then runs
whole = system()
whole.run(steps=5000, progress=False)
print(json.dumps({"waited": waited, "untouched": untouched, "same": sim.get_state().identical(whole.get_state())}))
"""


@pytest.mark.slow
def test_a_ctrl_c_while_the_loop_compiles_stops_the_run_at_once_untouched(tmp_path):
    """The driver's compiling call runs aside (`sigint.Deferred.aside`): a Ctrl-C as the loop's first compile
    begins raises KeyboardInterrupt at once, the simulation as it was (before: after the compile, seconds, and
    the first chunk). The compile goes on alone; the next run waits for it and ends on the unbroken bits."""
    done = subprocess.run([sys.executable, "-c", COMPILING], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp_path / "cache")})
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout.splitlines()[-1])
    assert got["waited"] is not None and got["waited"] < 1.0  # the compile takes 2 s or more
    assert got["untouched"] and got["same"]
