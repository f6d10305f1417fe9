"""The warnings and the GPU's error the guides name are top-level names (issue 42): a user catches
`pb.MarginWarning`, `pb.FreezeWarning` and `pb.GPUUnavailable` without knowing the module each lives in,
each has its entry on the API page, and ``import pinnedballs`` still loads neither the GPU engine nor
numba-cuda."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import THIN, thin_spec

import pinnedballs as pb
from pinnedballs.specs import parse_spec

ROOT = Path(__file__).resolve().parents[2]
NAMES = ("MarginWarning", "FreezeWarning", "GPUUnavailable")


def test_the_warnings_and_the_gpus_error_are_public_and_documented():
    api = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    for name in NAMES:
        assert name in pb.__all__ and f"::: pinnedballs.{name}\n" in api


def test_a_thin_run_until_frozen_warns_with_pb_margin_warning(tmp_path):
    sim = parse_spec(thin_spec(tmp_path)).build()
    with pytest.warns(pb.MarginWarning, match=THIN.replace("(", r"\(")):
        assert sim.run_until_frozen(max_steps=10)


def test_a_torus_run_until_frozen_warns_with_pb_freeze_warning():
    g = pb.FlatTorus(4, 4)
    v = np.random.default_rng(0).standard_normal((g.n_balls, 2))
    sim = pb.Simulation(g, v, seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert not sim.run_until_frozen(max_steps=1000)
    assert [type(w.message) for w in caught] == [pb.FreezeWarning]
    assert "not frozen after 1,000 steps, and never will be" in str(caught[0].message)


#: numba-cuda missing: a GPU run raises pb.GPUUnavailable, and importing pinnedballs loaded no GPU code
WITHOUT_NUMBA_CUDA = """
import sys
sys.modules["numba_cuda"] = None  # as if not installed
import warnings
warnings.simplefilter("ignore")  # numba's redirector says it cannot find numba_cuda
import numpy as np
import pinnedballs as pb
assert "pinnedballs.engine.gpu" not in sys.modules
g = pb.FlatTorus(4, 4)
try:
    pb.Simulation(g, np.ones((g.n_balls, 2)), scheduler=pb.UniformRandomPair(stream="counter"), device="cuda")
except pb.GPUUnavailable as exc:
    print(exc.field, "|", exc.problem.split(",")[0])
"""


def test_a_gpu_run_without_numba_cuda_raises_pb_gpu_unavailable():
    out = subprocess.run([sys.executable, "-c", WITHOUT_NUMBA_CUDA], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout == "device | 'cuda' needs numba-cuda\n"
