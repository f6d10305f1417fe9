"""Every output says how it was made (issue 47, item 6): a run's results and an ensemble's directory record the
versions, the command line or the Python call, the host, the CPU, what the run used (threads, or the GPU) and
when it started and ended; a resumed run keeps one entry a life; ``info`` says it in a few lines; a damaged
entry is refused in one line naming it; files written before load and resume; and no bit of a run changes."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import platform
import shlex
import shutil
import socket
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import ROOT, TORUS, assert_input_error, call, spec, write

import pinnedballs as pb
from pinnedballs import ResultsError
from pinnedballs.results.digest import HEADER_SIZE, seal
from pinnedballs.run import ensemble as ens
from pinnedballs.specs import parse_spec
from pinnedballs.util.provenance import lines, script

DATA = ROOT / "tests" / "data"
SCRIPT = script()  # what a Python call records as its script: pytest's own here (``-m pytest``, or its file)


def _time(stamp: str) -> datetime.datetime:
    assert stamp.endswith("Z")
    return datetime.datetime.fromisoformat(stamp)


def _assert_this_process(entry: dict) -> None:
    """The facts every entry of this process holds: its versions, host, argv and CPU, times in order."""
    v = entry["versions"]
    assert v["pinnedballs"] == pb.__version__ and v["python"] == platform.python_version()
    assert v["numpy"] == np.__version__ and v["numba"] == importlib.metadata.version("numba")
    assert entry["host"] == socket.gethostname() and entry["argv"] == sys.argv
    assert entry["cpu"]["cores"] >= 1 and isinstance(entry["cpu"]["model"], str)
    assert _time(entry["started"]) <= _time(entry["ended"]) <= datetime.datetime.now(datetime.UTC)


def test_a_command_line_run_records_its_command_and_info_says_it(tmp_path):
    s = write(tmp_path / "s.json", TORUS)
    out = tmp_path / "run"
    argv = ["run", str(s), "--out", str(out), "--quiet", "--no-figures"]
    assert call(*argv)[0] == 0
    (entry,) = pb.load(out).provenance
    _assert_this_process(entry)
    assert entry["command"] == shlex.join(["pinnedballs", *argv])
    device = entry["device"]  # 48 contacts: the sequential table loop, chosen by its size
    assert (device["kind"], device["threads"]) == ("cpu", 1) and set(device) == {"kind", "threads", "loop"}
    assert (device["loop"]["name"], device["loop"]["by"]) == ("tables", "size")
    assert 0 <= device["loop"]["branch_free"] <= 1 and device["loop"]["blocks"] == "measured"
    assert entry["steps"] == [0, 1000]
    code, stdout, _ = call("info", out)
    assert code == 0
    v = entry["versions"]
    assert stdout.splitlines()[-4:] == [
        f"made by:     pinnedballs {pb.__version__} on Python {v['python']}, numpy {v['numpy']}, numba {v['numba']}",
        lines([entry])[1], f"command:     {entry['command']}",
        f"host:        {entry['host']}; started {entry['started'].replace('T', ' ').replace('Z', ' UTC')}, ended "
        f"{entry['ended'].replace('T', ' ').replace('Z', ' UTC')}"]
    assert lines([entry])[1].startswith(f"ran on:      CPU: {entry['cpu']['model']} ({entry['cpu']['cores']} cores")
    assert lines([entry])[1].endswith(f", 1 thread; the table loop (by its size), {device['loop']['branch_free']:.0%} "
                                      "of its picks without a branch (timed on this CPU)")


def test_run_spec_records_the_python_call(tmp_path):
    res = pb.run_spec(parse_spec(TORUS), tmp_path / "run", figures=False, progress=False)
    (entry,) = res.provenance
    _assert_this_process(entry)
    assert entry["command"] == f"python {SCRIPT}: pinnedballs.run_spec"
    assert res.provenance == pb.load(tmp_path / "run").provenance


def test_a_resumed_run_keeps_a_list_one_entry_a_life_and_the_same_bits(tmp_path):
    g = pb.FlatTorus(4, 4)
    v = np.random.default_rng(3).standard_normal((g.n_balls, 2))
    plain = pb.Simulation(g, v, seed=7)
    plain.run(steps=1000)
    sim = pb.Simulation(g, v, seed=7)
    sim.run(steps=500, writers=[pb.ResultsWriter(tmp_path / "r", snapshots={"every_steps": 100})])
    (first,) = pb.load(tmp_path / "r").provenance
    again = pb.load(tmp_path / "r").simulation()
    again.run(steps=500, writers=[pb.ResultsWriter(tmp_path / "r", snapshots={"every_steps": 100}, resume=True)])
    res = pb.load(tmp_path / "r")
    assert len(res.provenance) == 2 and res.provenance[0] == first  # the first life as it was written
    second = res.provenance[1]
    _assert_this_process(second)
    assert (first["steps"], second["steps"]) == ([0, 500], [500, 1000])
    assert first["command"] == second["command"] == f"python {SCRIPT}: pinnedballs.ResultsWriter"
    assert _time(first["ended"]) <= _time(second["started"])
    assert res.steps == plain.steps == 1000 and res.collisions == plain.collisions
    assert np.array_equal(res.velocities, plain.velocities)  # metadata only: the bits of a plain run
    assert np.array_equal(res.rng_state, plain.get_state().rng_state)
    assert call("info", tmp_path / "r")[1].splitlines()[-1].endswith(
        f"; resumed 1 time, first started {first['started'].replace('T', ' ').replace('Z', ' UTC')}")


def test_a_format_1_run_without_provenance_loads_and_its_resume_records_the_new_life(tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    shutil.copy(DATA / "results_v1_running.h5", out / "results.h5")
    old = pb.load(out)
    assert (old.format_version, old.steps, old.provenance) == (1, 250, [])
    assert call("info", out)[1].splitlines()[-1] == \
        "made by:     not recorded (written before outputs kept their provenance)"
    s = write(tmp_path / "s.json", spec(TORUS, checkpoint={"every_seconds": 0}))
    argv = ["run", str(s), "--out", str(out), "--resume", "--quiet", "--no-figures"]
    assert call(*argv)[0] == 0
    res = pb.load(out)
    (entry,) = res.provenance
    assert res.format_version == 3 and res.complete and entry["steps"] == [250, 1000]
    assert entry["command"] == shlex.join(["pinnedballs", *argv])
    assert call("info", out)[1].splitlines()[-1].endswith("; its lives before step 250 not recorded")
    reference = pb.run_spec(parse_spec(TORUS), tmp_path / "ref", figures=False, progress=False)
    assert np.array_equal(res.velocities, reference.velocities) and res.collisions == reference.collisions


def test_a_format_2_run_loads_without_provenance(tmp_path):
    shutil.copytree(DATA / "format2", tmp_path / "f2")
    assert pb.load(tmp_path / "f2").provenance == []


# ---------------------------------------------------------------- damaged


def _rewrite_provenance(index: Path, texts) -> None:
    """``/provenance`` of the index replaced by ``texts``, and the index sealed again (a damage its digest cannot
    see: written by a program that knows the format)."""
    with h5py.File(index, "r+") as f:
        del f["provenance"]
        f.create_dataset("provenance", data=texts, dtype=h5py.string_dtype() if isinstance(texts, list) else None)
    index.write_bytes(seal(index.read_bytes()[HEADER_SIZE:]))


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("good") / "run"
    assert call("run", write(out.parent / "s.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    return out


@pytest.mark.parametrize("damage, words", [
    (lambda e: [json.dumps({**e, "started": "soon"})], "provenance[0]: started: must be a time (ISO 8601, UTC), "
                                                       "got 'soon'"),
    (lambda e: [json.dumps(e), json.dumps({**e, "versions": {}})], "provenance[1]: versions: must give "
                                                                    "pinnedballs's and python's (text), got {}"),
    (lambda e: ["{not json"], "provenance[0]: must be a JSON object (text), got '{not json'"),
    (lambda e: np.arange(3), 'provenance: must be a list of texts (one JSON object a life), got <HDF5 dataset '
                             '"provenance": shape (3,), type "<i8">'),
], ids=["a time", "a second life's versions", "not JSON", "not texts"])
def test_a_damaged_provenance_is_refused_in_one_line_naming_it(good, tmp_path, damage, words):
    run = tmp_path / "run"
    shutil.copytree(good, run)
    index = run / "results.h5"
    _rewrite_provenance(index, damage(pb.load(run).provenance[0]))
    with pytest.raises(ResultsError) as caught:
        pb.load(run)
    assert str(caught.value) == f"{index}: damaged results file: {words}"
    code, _, err = call("info", run)
    assert_input_error(code, err, str(index), words)


# ---------------------------------------------------------------- ensembles

HALF_PLANE = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
              "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0], "energy": 100.0},
              "stop": {"frozen": True, "max_steps": 10**6}, "seed": 11}


def test_an_ensemble_directory_records_its_call_and_loads_it_back(tmp_path):
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 3, workers=1)
    entry = result.provenance
    _assert_this_process(entry)
    assert entry["command"] == f"python {SCRIPT}: pinnedballs.run_ensemble"
    assert entry["device"] == {"kind": "cpu", "where": "in-process", "workers": 1}
    result.save(tmp_path / "e", figures=False)
    assert pb.load_ensemble(tmp_path / "e").provenance == entry
    assert call("info", tmp_path / "e")[1].splitlines()[-4:] == lines([entry])
    assert lines([entry])[1].endswith("; workers 1")


def test_the_ensemble_command_records_its_command_line(tmp_path):
    s = write(tmp_path / "s.json", HALF_PLANE)
    argv = ["ensemble", str(s), "--replicas", "2", "--workers", "1", "--out", str(tmp_path / "e"), "--quiet"]
    assert call(*argv)[0] == 0
    entry = json.loads((tmp_path / "e" / "summary.json").read_text())["provenance"]
    assert entry["command"] == shlex.join(["pinnedballs", *argv]) and entry["device"]["workers"] == 1
    assert pb.load_ensemble(tmp_path / "e").provenance == entry


def test_an_ensemble_directory_without_provenance_loads_and_a_damaged_one_is_one_line(tmp_path):
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 2, workers=1)
    out = tmp_path / "e"
    result.save(out, figures=False)
    summary = out / "summary.json"
    data = json.loads(summary.read_text())
    summary.write_text(json.dumps({k: v for k, v in data.items() if k != "provenance"}))  # as written before
    assert pb.load_ensemble(out).provenance is None
    assert call("info", out)[1].splitlines()[-1] == \
        "made by:     not recorded (written before outputs kept their provenance)"
    summary.write_text(json.dumps({**data, "provenance": {**data["provenance"], "ended": "2001-01-01T00:00:00Z"}}))
    words = f"{summary}: provenance: ended: must be a time (ISO 8601, UTC) not before started"
    with pytest.raises(pb.InputError, match=r"^" + words.replace("(", r"\(").replace(")", r"\)")):
        pb.load_ensemble(out)
    code, _, err = call("info", out)
    assert_input_error(code, err, words)


# ---------------------------------------------------------------- on a GPU (numba-cuda's simulator)


@pytest.mark.cuda
def test_a_gpu_run_under_the_simulator_records_simulated_and_numba_cuda(tmp_path):
    pytest.importorskip("numba_cuda")
    g = pb.FlatTorus(4, 4)
    v = np.random.default_rng(5).standard_normal((g.n_balls, 2))
    counter = pb.UniformRandomPair(stream="counter")
    cpu = pb.Simulation(g, v, scheduler=counter, seed=2)
    cpu.run(steps=200)
    gpu = pb.Simulation(g, v, scheduler=counter, seed=2, device="cuda")
    gpu.run(steps=200, writers=[pb.ResultsWriter(tmp_path / "g")])
    res = pb.load(tmp_path / "g")
    (entry,) = res.provenance
    _assert_this_process(entry)
    assert entry["device"] == {"kind": "cuda", "gpu": "simulated"}
    assert entry["versions"]["numba-cuda"] == importlib.metadata.version("numba-cuda")
    assert np.array_equal(res.velocities, cpu.velocities)  # the CPU's bits
    assert lines([entry])[1].startswith("ran on:      GPU: simulated (numba-cuda's simulator on the CPU: ")


@pytest.mark.slow  # starts a Dask cluster
def test_an_ensemble_on_dask_records_the_scheduler_its_workers_and_their_hosts():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        result = ens.run_ensemble(parse_spec(HALF_PLANE), 2, cluster=client)
        hosts = sorted({w["host"] for w in client.scheduler_info()["workers"].values()})
    device = result.provenance["device"]
    assert device == {"kind": "cpu", "where": result.where, "dask": c.scheduler_address, "workers": 2, "hosts": hosts}
    assert result.where == f"dask {c.scheduler_address}"
