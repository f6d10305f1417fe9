"""``--device cuda`` refused before anything is written (issue 42, item 3): ``reproduce`` (with ``--extended`` or
without) and ``ensemble`` on a machine without a GPU, and ``ensemble`` of a spec on the xoshiro stream: one line,
exit status 2, no directory made; the counter stream named as a spec states it. Without a GPU is numba-cuda
with its simulator off (``NUMBA_ENABLE_CUDASIM=0``), in a child process (the tests' own process runs the
simulator, as `tests.engine.gpu.test_gpu.test_without_a_gpu_or_numba_cuda_one_line_says_so` does)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from helpers import ROOT, TORUS, assert_input_error, call, spec, write

COUNTER = '{"kind": "uniform_random_pair", "stream": "counter"}'
NO_GPU = "device: 'cuda' found no GPU: numba-cuda sees no CUDA driver or device here"


def without_a_gpu(*argv) -> subprocess.CompletedProcess:
    """``pinnedballs ARGV`` in a child process where numba-cuda sees no GPU and its simulator is off."""
    env = {"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "pinnedballs", *map(str, argv)], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=300)


pytestmark = pytest.mark.cuda  # the refusals of numba-cuda without a GPU: skipped without numba-cuda (conftest)


@pytest.fixture(scope="module")
def no_gpu():
    env = {"NUMBA_ENABLE_CUDASIM": "0", "PATH": "/usr/bin:/bin", "HOME": str(ROOT)}
    seen = subprocess.run([sys.executable, "-c", "from numba import cuda; print(cuda.is_available())"],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    if seen.stdout.strip() != "False":
        pytest.skip("a GPU is here: nothing to refuse")


@pytest.mark.slow
@pytest.mark.parametrize("extended", [[], ["--extended"]])
def test_reproduce_on_cuda_without_a_gpu_refuses_and_writes_nothing(tmp_path, no_gpu, extended):
    out = tmp_path / "new" / "repro"
    done = without_a_gpu("reproduce", "--quick", *extended, "--device", "cuda", "--out", out)
    assert_input_error(done.returncode, done.stderr, NO_GPU)
    assert done.stdout == "" and not (tmp_path / "new").exists()


@pytest.mark.slow
def test_an_ensemble_on_cuda_without_a_gpu_refuses_and_makes_no_directory(tmp_path, no_gpu):
    path = write(tmp_path / "s.json", spec(TORUS, scheduler={"kind": "uniform_random_pair", "stream": "counter"}))
    done = without_a_gpu("ensemble", path, "--replicas", 3, "--device", "cuda", "--out", tmp_path / "new" / "a" / "b")
    assert_input_error(done.returncode, done.stderr, NO_GPU)
    assert done.stdout == "" and not (tmp_path / "new").exists()


def test_an_ensemble_on_the_xoshiro_stream_is_refused_in_the_specs_words(tmp_path):
    path = write(tmp_path / "s.json", TORUS)
    for out in (tmp_path / "new" / "a" / "b", tmp_path / "empty"):
        code, stdout, err = call("ensemble", path, "--replicas", 3, "--device", "cuda", "--out", out, "--quiet")
        assert_input_error(code, err, f"device: 'cuda' runs the scheduler {COUNTER} (the pick of step s a function of "
                                      f"the seed and s); this spec's scheduler, {{\"kind\": \"uniform_random_pair\"}}, "
                                      f"runs on the CPU")
        assert stdout == "" and "UniformRandomPair(" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]


def test_a_run_on_the_xoshiro_stream_is_refused_in_the_specs_words(tmp_path):
    code, stdout, err = call("run", write(tmp_path / "s.json", TORUS), "--device", "cuda", "--out", tmp_path / "r")
    assert_input_error(code, err, f"device: 'cuda' runs the scheduler {COUNTER}")
    assert stdout == "" and "UniformRandomPair(" not in err and not (tmp_path / "r").exists()


def test_an_ensemble_on_the_counter_stream_runs_on_the_simulated_gpu(tmp_path):
    """What the refusals stand in front of still runs: the tests' simulator is a GPU to the command line."""
    path = write(tmp_path / "s.json", spec(TORUS, scheduler={"kind": "uniform_random_pair", "stream": "counter"},
                                           snapshots=...))
    code, stdout, err = call("ensemble", path, "--replicas", 2, "--device", "cuda", "--out", tmp_path / "e")
    assert (code, err) == (0, "") and stdout.startswith("2 of 2 replicas done in ") and "(GPU)" in stdout


def test_a_certified_ensemble_on_a_clusters_gpus_is_refused_and_makes_no_parents(tmp_path):
    """A certified spec runs its replicas one at a time on this process's GPU, never on a Dask cluster's
    (docs/gpu.md); refused before the scheduler is asked (none listens here), a/ and a/b/ not made."""
    path = write(tmp_path / "s.json", spec(TORUS, arithmetic="certified", stop={"frozen": True, "max_steps": 10**5},
                                           geometry={"kind": "half_plane", "rows": 3, "cols": 4},
                                           initial={"kind": "single_ball", "ball": "boundary_center",
                                                    "direction": [0, 1], "energy": 100},
                                           scheduler={"kind": "uniform_random_pair", "stream": "counter"},
                                           snapshots=...))
    code, stdout, err = call("ensemble", path, "--replicas", 2, "--device", "cuda", "--dask", "tcp://127.0.0.1:9",
                             "--out", tmp_path / "a" / "b" / "out", "--quiet")
    assert_input_error(code, err, "device: 'cuda' runs a certified ensemble's replicas one at a time on this "
                                  "process's GPU; on a Dask cluster, certified replicas run on its CPUs "
                                  "(device='cpu')")
    assert stdout == "" and sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]


@pytest.mark.slow
def test_an_ensemble_on_a_cluster_without_gpus_is_refused_and_leaves_no_parents(tmp_path, no_gpu, monkeypatch):
    """The issue's case: workers that see no GPU refuse the replicas after --out's lock made a/, a/b/ and
    a/b/out: all go again; a directory that held something before stays, and what it held."""
    distributed = pytest.importorskip("dask.distributed")
    path = write(tmp_path / "s.json", spec(TORUS, scheduler={"kind": "uniform_random_pair", "stream": "counter"},
                                           snapshots=...))
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "mine.txt").write_text("mine")
    monkeypatch.setenv("NUMBA_ENABLE_CUDASIM", "0")  # the workers (spawned now) see no simulated GPU
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        for out in (tmp_path / "a" / "b" / "out", tmp_path / "kept" / "b" / "out"):
            code, stdout, err = call("ensemble", path, "--replicas", 2, "--device", "cuda", "--dask",
                                     cluster.scheduler_address, "--out", out, "--quiet")
            assert_input_error(code, err, "device: 'cuda' on Dask needs a GPU on every worker; 1 of 1 have none")
            assert stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept", "s.json"]
    assert [p.name for p in (tmp_path / "kept").iterdir()] == ["mine.txt"]
