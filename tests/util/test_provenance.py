"""What a process says of itself in an output's provenance (`util.provenance`): the installed versions, the
CPU as the OS describes it, the command line or Python call, UTC times; an entry read back is checked field by
field; and reading versions imports nothing heavy."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pinnedballs.util import provenance

MODULE = Path(provenance.__file__)


def _entry(**changes) -> dict:
    """A sound entry (a CPU run of two threads), with ``changes``."""
    e = {"versions": {"pinnedballs": "1.0.0", "python": "3.11.7", "numpy": "2.4.6", "numba": "0.68.1"},
         "command": "pinnedballs run s.json --out r", "argv": ["pinnedballs", "run"], "host": "node7",
         "platform": "Linux", "cpu": {"model": "AMD EPYC", "cores": 2, "flags": ["avx2", "fma"]},
         "device": {"kind": "cpu", "threads": 2}, "started": "2026-12-01T10:00:00Z", "ended": "2026-12-01T10:05:00Z",
         "steps": [0, 1000]}
    e.update(changes)
    return e


def test_versions_are_those_installed_and_python_s_own():
    v = provenance.versions("1.2.3", extra=("no-such-package-here",))
    assert v["pinnedballs"] == "1.2.3" and v["python"] == platform.python_version()
    assert v["numpy"] == np.__version__
    for name in ("numba", "llvmlite", "h5py"):
        assert v[name] == importlib.metadata.version(name)
    assert "no-such-package-here" not in v  # not installed: left out, not guessed


def test_reading_versions_and_the_cpu_imports_nothing_heavy():
    """The module alone (by its path: it uses only the standard library) answers without importing numba,
    numba-cuda, h5py or numpy."""
    code = (f"import importlib.util, sys\n"
            f"spec = importlib.util.spec_from_file_location('p', {str(MODULE)!r})\n"
            f"m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
            f"m.entry('1.0.0', 'pinnedballs.run_spec', {{'kind': 'cpu'}}, ('numba-cuda',))\n"
            f"print(sorted(k for k in sys.modules if k.split('.')[0] in ('numba', 'numba_cuda', 'h5py', 'numpy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_cpu_is_the_one_the_os_describes():
    c = provenance.cpu()
    assert c["cores"] == os.cpu_count()
    assert c["usable"] == len(os.sched_getaffinity(0))
    info = Path("/proc/cpuinfo")
    if info.exists():  # Linux: the first processor's model name and flags
        text = info.read_text()
        model = next(line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("model name"))
        flags = set(next(line.split(":", 1)[1] for line in text.splitlines() if line.startswith("flags")).split())
        assert c["model"] == model
        assert c["flags"] == [f for f in provenance.VECTOR_FLAGS if f in flags]
    level2 = [d for d in Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")
              if (d / "level").read_text().strip() == "2"]
    if level2:
        size = (level2[0] / "size").read_text().strip()
        assert c["l2_cache"] == int(size[:-1]) * {"K": 1 << 10, "M": 1 << 20}[size[-1]]


def test_now_is_utc_to_the_second():
    before = datetime.datetime.now(datetime.UTC).replace(microsecond=0)
    stamp = provenance.now()
    after = datetime.datetime.now(datetime.UTC)
    assert stamp.endswith("Z") and len(stamp) == len("2026-12-01T23:30:53Z")
    assert before <= datetime.datetime.fromisoformat(stamp) <= after


def test_the_script_is_named_as_its_reader_would_run_it(monkeypatch):
    for argv0, said in [("/home/me/study.py", "study.py"), ("/usr/lib/python3/site-packages/pytest/__main__.py",
                                                             "-m pytest"), ("-c", "-c"), ("", "(interactive)")]:
        monkeypatch.setattr(sys, "argv", [argv0, "--out", "r"])
        assert provenance.script() == said
        assert provenance.command("pinnedballs.run_spec") == f"python {said}: pinnedballs.run_spec"


def test_the_command_line_is_recorded_over_any_python_call_inside_it():
    script = provenance.script()
    assert provenance.command("pinnedballs.ResultsWriter") == f"python {script}: pinnedballs.ResultsWriter"
    with provenance.python_call("pinnedballs.run_spec"):
        assert provenance.command("pinnedballs.ResultsWriter") == f"python {script}: pinnedballs.run_spec"
    with provenance.command_line(["run", "my spec.json", "--out", "r"]):
        with provenance.python_call("pinnedballs.run_spec"):  # the command line's run goes through it too
            assert provenance.command("pinnedballs.ResultsWriter") == "pinnedballs run 'my spec.json' --out r"
    assert provenance.command("x") == f"python {script}: x"  # both contexts undone


def test_an_entry_holds_this_process_s_facts_and_is_json():
    e = provenance.entry("1.0.0", "pinnedballs.run_spec", {"kind": "cpu", "threads": 1})
    assert json.loads(json.dumps(e)) == e
    assert e["host"] == socket.gethostname() and e["argv"] == sys.argv and e["ended"] is None
    assert e["versions"]["pinnedballs"] == "1.0.0" and e["device"] == {"kind": "cpu", "threads": 1}
    assert provenance.problem(e) is None


@pytest.mark.parametrize("changes,said", [
    ({"versions": "1.0"}, "versions: must be a JSON object, got '1.0'"),
    ({"versions": {"pinnedballs": "1.0.0"}}, "versions: must give pinnedballs's and python's (text)"),
    ({"versions": {"pinnedballs": "1.0.0", "python": 3.11}}, "versions: must give pinnedballs's and python's"),
    ({"command": None}, "command: must be text, got None"),
    ({"device": {"threads": 2}}, "device: must say its kind (text)"),
    ({"device": {"kind": "cpu", "threads": 0}}, "device: threads must be a count >= 1, got 0"),
    ({"started": "yesterday"}, "started: must be a time (ISO 8601, UTC), got 'yesterday'"),
    ({"started": "2026-12-01T10:00:00"}, "started: must be a time (ISO 8601, UTC)"),  # no offset: not UTC
    ({"ended": "2026-12-01T09:59:59Z"}, "ended: must be a time (ISO 8601, UTC) not before started"),
    ({"steps": [1000, 10]}, "steps: must be [first, last] step counts, got [1000, 10]"),
])
def test_a_damaged_entry_is_named_field_by_field(changes, said):
    assert provenance.problem(_entry()) is None
    assert provenance.problem(_entry(**changes)).startswith(said)
    assert provenance.problem(["not", "an", "object"]) == "must be a JSON object, got list"


def test_lines_say_the_latest_life_and_how_many_came_before():
    first = _entry()
    second = _entry(started="2026-12-02T08:00:00Z", ended="2026-12-02T09:30:00Z", steps=[1000, 5000],
                    command="pinnedballs run s.json --out r --resume",
                    device={"kind": "cpu", "threads": 2, "tuned": {"2": 0.75, "1": 0.25}})
    assert provenance.lines([first, second]) == [
        "made by:     pinnedballs 1.0.0 on Python 3.11.7, numpy 2.4.6, numba 0.68.1",
        "ran on:      CPU: AMD EPYC (2 cores, AVX2), 2 threads (chosen by the tuner: 2 on 75%, 1 on 25%)",
        "command:     pinnedballs run s.json --out r --resume",
        "host:        node7; started 2026-12-02 08:00:00 UTC, ended 2026-12-02 09:30:00 UTC; resumed 1 time, first "
        "started 2026-12-01 10:00:00 UTC"]
    gpu = _entry(device={"kind": "cuda", "gpu": "NVIDIA H200", "compute_capability": "9.0"}, ended=None,
                 steps=[250, 250])
    assert provenance.lines([gpu])[1:] == [
        "ran on:      GPU: NVIDIA H200 (compute capability 9.0); CPU: AMD EPYC (2 cores, AVX2)",
        "command:     pinnedballs run s.json --out r",
        "host:        node7; started 2026-12-01 10:00:00 UTC, not ended (no checkpoint yet); its lives before step "
        "250 not recorded"]
    assert provenance.lines([_entry(device={"kind": "cuda", "gpu": "simulated"})])[1] == \
        "ran on:      GPU: simulated (numba-cuda's simulator on the CPU: AMD EPYC (2 cores, AVX2))"
    assert provenance.lines([]) == ["made by:     not recorded (written before outputs kept their provenance)"]


def test_lines_say_which_loop_ran_and_what_chose_it():
    """What `engine.backends.LoopBackend.resources` records of the loop (`engine.sequential.sizes`, `.choice`)."""
    timed = _entry(device={"kind": "cpu", "threads": 1, "loop": {"name": "tables", "by": "measured",
                                                                  "shares": {"tables": 0.9, "rows": 0.1},
                                                                  "blocks": "measured", "branch_free": 0.8704}})
    assert provenance.lines([timed])[1] == ("ran on:      CPU: AMD EPYC (2 cores, AVX2), 1 thread; the table loop "
                                            "(timed on this CPU), 87% of its picks without a branch (timed on this "
                                            "CPU)")
    forced = _entry(device={"kind": "cpu", "threads": 1, "loop": {"name": "rows", "by": "PINNEDBALLS_LOOP=rows"},
                            "setting": "PINNEDBALLS_LOOP=rows"})
    assert provenance.lines([forced])[1] == ("ran on:      CPU: AMD EPYC (2 cores, AVX2), 1 thread; the row-pattern "
                                             "loop (PINNEDBALLS_LOOP=rows)")
