"""A seed names its trajectory for good (issue 23, item 3): runs recorded with the loops of commit d0a8bbc
(tests/data/make_seed_trajectories.py, which says how) come out bit for bit the same today, on the
sequential loops and on two threads: the row pattern, the margin and the parallel chain change no bit."""

import json
import sys
from pathlib import Path

import pytest

import pinnedballs as pb

DATA = Path(__file__).resolve().parent.parent / "data"
sys.path.insert(0, str(DATA))
from make_seed_trajectories import CASES, run  # noqa: E402

RECORDED = json.loads((DATA / "seed_trajectories.json").read_text())


#: every case as recorded, and the paper's scheduler's cases on one and on two threads too
RUNS = [(name, None) for name in sorted(CASES)] + [
    (name, threads) for name in sorted(CASES) if CASES[name][3] == "uniform" for threads in (1, 2)]


@pytest.mark.slow
@pytest.mark.parametrize("name, threads", RUNS)
def test_a_recorded_run_comes_out_the_same(name, threads, monkeypatch):
    case = CASES[name]
    if threads is not None:
        original = pb.UniformRandomPair.__init__
        monkeypatch.setattr(pb.UniformRandomPair, "__init__",
                            lambda self, threads_=None: original(self, threads=threads))
    assert run(case) == RECORDED[name]
