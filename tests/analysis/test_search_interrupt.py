"""Ctrl-C stops `explore_orders` and `search_max_collisions` (issue 26, item 1): a real SIGINT to a
child Python process at a random moment raises KeyboardInterrupt within a second or two, the partial
search is discarded, and the same call made again in that process gives the undisturbed result (no
cache or compiled kernel left half made); the progress bars say what they count."""

from __future__ import annotations

import json
import os
import random
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb

ROOT = Path(__file__).resolve().parents[2]

CHILD = """
import json, math, sys
import numpy as np
import pinnedballs as pb

pb.HalfPlane, pb.explore_orders, pb.search_max_collisions  # imported before "ready": the signal is for the search

def call():
    if sys.argv[1] == "orders":
        geom = pb.HalfPlane(rows=3, cols=4)
        v = np.zeros((geom.n_balls, 2))
        v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
        r = pb.explore_orders(geom, v, arithmetic="float", max_states=150_000, progress=False)
        return [r.min_collisions, r.max_collisions, r.states, list(r.min_order), list(r.max_order)]
    r = pb.search_max_collisions(pb.HalfPlane(2, 3), trials=150, seed=4, max_states=2_000, final_states=2_000,
                                 progress=False)
    return [r.collisions, r.velocities.tolist(), list(r.order), r.found_at, r.climbs]

print("ready", flush=True)
while True:
    try:
        result = call()
        break
    except KeyboardInterrupt:
        print("interrupted", flush=True)
print(json.dumps(result), flush=True)
"""


def line_within(child: subprocess.Popen, seconds: float) -> str:
    ready, _, _ = select.select([child.stdout], [], [], seconds)
    return child.stdout.readline() if ready else ""


def run_child(which: str, delay: float | None) -> tuple[list, bool]:
    """CHILD's result for ``which``, with a SIGINT ``delay`` seconds after it is ready (None: none), and
    whether it was interrupted; a KeyboardInterrupt must come within 10 s of the signal."""
    child = subprocess.Popen([sys.executable, "-c", CHILD, which], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert line_within(child, 120) == "ready\n"
        interrupted = False
        if delay is not None:
            time.sleep(delay)
            child.send_signal(signal.SIGINT)
            line = line_within(child, 10)  # a second or two; the margin is for a loaded machine
            interrupted = line == "interrupted\n"
            if not interrupted:  # it had finished before the signal came
                assert line.startswith("["), f"no KeyboardInterrupt within 10 s of the signal: {line!r}"
                child.communicate(timeout=60)
                return json.loads(line), False
        out, err = child.communicate(timeout=600)
        assert child.returncode == 0, err
        return json.loads(out.splitlines()[-1]), interrupted
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()


@pytest.fixture(scope="module")
def undisturbed():
    cache = {}

    def get(which: str) -> list:
        if which not in cache:
            cache[which] = run_child(which, None)[0]
        return cache[which]
    return get


@pytest.mark.slow
@pytest.mark.parametrize("which", ["orders", "maxima"])
@pytest.mark.parametrize("seed", range(2))
def test_sigint_stops_the_search_and_the_same_call_then_gives_the_undisturbed_result(undisturbed, which, seed):
    delay = random.Random(f"{which}{seed}").uniform(0.1, 1.5)
    got, interrupted = run_child(which, delay)
    assert got == undisturbed(which)
    assert interrupted  # each call takes 2-3 s on an idle core: a signal within 1.5 s finds it running


def test_search_max_collisions_shows_its_trials_and_the_best_so_far(capfd):
    r = pb.search_max_collisions(pb.HalfPlane(2, 2), trials=12, seed=2, max_states=500, final_states=500,
                                 progress=True)
    err = capfd.readouterr().err
    assert "most collisions: 100%" in err and "| 12/12 [" in err and f"best={r.collisions}" in err
    pb.search_max_collisions(pb.HalfPlane(2, 2), trials=3, seed=2, max_states=100, final_states=100)
    assert capfd.readouterr().err == ""  # None: not on a terminal, not in a notebook


def test_progress_must_be_a_flag_or_none():
    with pytest.raises(TypeError, match=r"^progress: must be True, False or None \(shown where it helps\), got 1$"):
        pb.explore_orders(pb.HalfPlane(2, 2), np.ones((4, 2)), progress=1)
