"""Hostile input, one test per class of failure: each is refused up front with one line naming
the field or the file (exit status 2 on the command line, nothing written), never a traceback,
a hang, a memory blow-up or a run that stores NaN."""

from __future__ import annotations

import io
import json
import os
import pickle
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from helpers import TORUS, assert_input_error, call, spec, write  # exit 2, one line, no traceback

import pinnedballs as pb
from pinnedballs.specs import SpecError, engine_errors, parse_spec
from pinnedballs.util import limits
from pinnedballs.util.errors import FieldError, FieldTypeError, InputError

ROOT = Path(__file__).resolve().parents[3]


def run_refused(tmp_path: Path, spec_path: Path, *words: str) -> None:
    """``run`` and ``validate`` both refuse ``spec_path``; ``run`` leaves no --out behind."""
    out = tmp_path / "out"
    for argv in (["run", spec_path, "--out", out], ["validate", spec_path]):
        code, stdout, err = call(*argv)
        assert_input_error(code, err, *words)
        assert stdout == ""
        assert not out.exists()


def npy_header(shape: tuple, descr: str = "<f8") -> bytes:
    """The bytes of a version 1.0 ``.npy`` header announcing ``shape`` of ``descr``."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    return buffer.getvalue()


# ---------------------------------------------------------------- item 1: malformed specs


def test_json_nested_100000_deep_names_the_file(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text('{"geometry": ' + "[" * 100_000 + "]" * 100_000 + "}")
    run_refused(tmp_path, path, "deep.json: not a spec: JSON nested more than 32 levels deep")


def test_nesting_that_json_accepts_but_no_field_can_hold_names_the_field(tmp_path):
    data = json.dumps(spec(description=None)).replace("null", "[" * 500 + "]" * 500)
    path = tmp_path / "s.json"
    path.write_text(data)
    run_refused(tmp_path, path, "description" + "[0]" * 32 + ": nested more than 32 levels deep")


@pytest.mark.parametrize("field, digits", [("rows", 5000), ("rows", 300), ("cols", 20)])
def test_huge_integers_name_the_field(tmp_path, field, digits):
    """5,000 digits is past Python's int-string limit; 20 digits is just past int64."""
    text = json.dumps(spec()).replace(f'"{field}": 4', f'"{field}": ' + "9" * digits)
    path = tmp_path / "s.json"
    path.write_text(text)
    run_refused(tmp_path, path, f"geometry.{field}: an integer of {digits} digits is out of range")


def test_huge_integer_in_a_dict_spec_names_the_field():
    with pytest.raises(SpecError, match=r"^seed: an integer of 22 digits is out of range") as info:
        parse_spec(spec(seed=2**70))
    assert info.value.field == "seed"


@pytest.mark.parametrize("where, text, words", [
    ("description", '"description": "\\ud800"', ["description: not valid UTF-8 text", "'\\ud800'"]),
    ("a key", '"\\udcff": 1', ["s.json: a key is not valid UTF-8 text"]),
    ("a file path", '"masses": "m\\ud800.npy"', ["masses: not valid UTF-8 text"]),
])
def test_lone_surrogates_name_the_field_and_write_nothing(tmp_path, where, text, words):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(spec())[:-1] + ", " + text + "}")
    run_refused(tmp_path, path, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]  # no results.h5.tmp anywhere


def test_lone_surrogate_in_a_spec_built_in_python_is_refused():
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match=r"description\n  Value error, not valid UTF-8 text"):
        pb.RunSpec.model_validate({**spec(), "description": "caf\udce9"})


# ---------------------------------------------------------------- item 1: data files and memory


def _lying_header(d: Path, name: str) -> Path:
    """A .npy whose header claims shape (10**12, 2) float64 (16 TB) over 64 bytes of data."""
    path = d / name
    path.write_bytes(npy_header((10**12, 2)) + b"\0" * 64)
    return path


@pytest.mark.parametrize("field, make_spec", [
    ("initial.path", lambda: spec(initial={"kind": "from_file", "path": "big.npy"})),
    ("masses", lambda: spec(masses="big.npy")),
    ("geometry.positions", lambda: spec(geometry={"kind": "graph_positions", "positions": "big.npy"})),
])
def test_npy_header_claiming_more_than_the_file_holds(tmp_path, field, make_spec):
    _lying_header(tmp_path, "big.npy")
    run_refused(tmp_path, write(tmp_path / "s.json", make_spec()),
                f"{field}: {tmp_path / 'big.npy'}: the header claims shape (1000000000000, 2) of float64 "
                f"(16.0 TB), but the file holds 64 bytes of data")


def test_npy_with_a_garbage_header_names_the_file(tmp_path):
    (tmp_path / "v.npy").write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': [[[[[[" + b" " * 10)
    run_refused(tmp_path, write(tmp_path / "s.json", spec(initial={"kind": "from_file", "path": "v.npy"})),
                "initial.path: cannot read", "v.npy as a .npy array")


def test_npy_needing_more_memory_than_available_is_refused_with_the_size(tmp_path, monkeypatch):
    """A chain of 2,000 balls 2 apart as float32: 16 kB on disk, 48 kB once read and made float64."""
    positions = np.column_stack([2.0 * np.arange(2000), np.zeros(2000)]).astype(np.float32)
    np.save(tmp_path / "p.npy", positions)
    s = spec(geometry={"kind": "graph_positions", "positions": "p.npy"}, snapshots=...)
    monkeypatch.setattr(limits, "available_memory", lambda: 40_000)
    run_refused(tmp_path, write(tmp_path / "s.json", s), "geometry.positions: the array in",
                "p.npy needs about 48.0 kB of memory, more than the 40.0 kB this machine has available")
    monkeypatch.setattr(limits, "available_memory", lambda: 48_000)
    assert call("validate", tmp_path / "s.json")[0] == 0


def test_spec_file_too_large_to_parse_is_refused_before_reading(tmp_path, monkeypatch):
    """32 bytes of Python objects per character of JSON, from above."""
    path = write(tmp_path / "s.json", spec(snapshots__at_steps=list(range(1000))))
    size = path.stat().st_size
    monkeypatch.setattr(limits, "available_memory", lambda: 32 * size - 1)
    run_refused(tmp_path, path, "s.json: reading this spec file needs about")
    monkeypatch.setattr(limits, "available_memory", lambda: 32 * size)
    assert call("validate", path)[0] == 0


def test_check_memory_refuses_one_byte_over_what_is_available(monkeypatch):
    monkeypatch.setattr(limits, "available_memory", lambda: 10**9)
    limits.check_memory(10**9, "rows", "it")
    with pytest.raises(FieldError, match=r"^rows: it needs about 1.0 GB of memory, more than the 1.0 GB") as info:
        limits.check_memory(10**9 + 1, "rows", "it")
    assert info.value.field == "rows"


def test_available_memory_is_positive_and_at_most_the_machine():
    total = None
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemTotal:"):
                total = int(line.split()[1]) * 1024
    available = limits.available_memory()
    assert available is not None and 0 < available <= total


def test_a_million_by_a_million_torus_is_refused_with_its_size_from_python_and_from_a_spec(tmp_path):
    """run_bytes: (2 * (104 bytes a ball + 73 a contact * 3 contacts a ball)) * 10**12 balls = 646 TB."""
    with pytest.raises(FieldError, match="needs about 646.0 TB of memory") as info:
        pb.FlatTorus(rows=10**6, cols=10**6)
    assert info.value.field == "rows*cols"
    with pytest.raises(FieldError, match="needs about 646.0 TB of memory"):
        pb.HalfPlane(rows=10**6, cols=10**6)
    run_refused(tmp_path, write(tmp_path / "s.json", spec(geometry__rows=10**6, geometry__cols=10**6)),
                "geometry: rows*cols: a 1000000 x 1000000 flat torus needs about 646.0 TB of memory")


def test_an_ensemble_of_a_trillion_replicas_is_refused_with_its_size(tmp_path):
    """4096 bytes a replica (seed, job, row) times 10**12: 4.1 PB, before any seed is drawn."""
    code, out, err = call("ensemble", write(tmp_path / "s.json", TORUS), "--replicas", 10**12, "--workers", 1,
                          "--out", tmp_path / "out")
    assert_input_error(code, err, "--replicas: an ensemble of 1,000,000,000,000 replicas needs about 4.1 PB of memory")
    assert not (tmp_path / "out").exists()
    with pytest.raises(FieldError, match="^replicas: an ensemble of 1,000,000,000,000 replicas needs about 4.1 PB") \
            as info:
        pb.run_ensemble(parse_spec(TORUS), 10**12, workers=1)
    assert info.value.field == "replicas"


@pytest.mark.parametrize("make, words", [
    (lambda: pb.HalfPlane.from_size(1e300, 1e300),
     r"^rows\*cols: a ~10\^299 x ~10\^299 half-plane lattice needs about 10\^602 bytes of memory"),
    (lambda: pb.FlatTorus(10**400, 4), r"^rows\*cols: a ~10\^400 x 4 flat torus needs about 10\^403 bytes of memory"),
])
def test_astronomical_sizes_from_python_are_refused_with_their_size(make, words):
    with pytest.raises(FieldError, match=words) as info:
        make()
    assert info.value.field == "rows*cols"


def test_run_bytes_bounds_what_a_torus_holds():
    """The estimate is above the arrays a 40x40 torus and its simulation really hold."""
    g = pb.FlatTorus(40, 40)
    sim = pb.Simulation(g, np.ones((g.n_balls, 2)))
    c = g.contacts
    held = (g.positions.nbytes + 3 * sim.velocities.nbytes + c.pairs.nbytes + c.ends.nbytes + c.units.nbytes
            + 8 * (g.n_balls + 1) + 4 * 2 * g.n_contacts + g.n_contacts)
    assert held < limits.run_bytes(g.n_balls, g.n_contacts) < 20 * held


# ---------------------------------------------------------------- item 2: velocities that could overflow


def _two_touching(speed: float) -> np.ndarray:
    """4x4 torus velocities: balls 0 and 1 touch along x and fly at each other at ``speed``."""
    v = np.zeros((16, 2))
    v[0], v[1] = [speed, 0.0], [-speed, 0.0]
    return v


def test_the_issues_overflowing_pair_is_refused_in_python():
    with pytest.raises(ValueError, match="^velocities: the total energy sum m |v|^2 / 2 overflows float64") as info:
        pb.Simulation(pb.FlatTorus(4, 4), _two_touching(1.7e308))
    assert info.value.field == "velocities"


def test_speed_bound_sits_where_the_docstring_derives_it():
    """Equal masses: E = s^2 (two balls at speed s), so the reachable speed is sqrt(2E) = sqrt(2) s."""
    g = pb.FlatTorus(4, 4)
    inside = limits.SPEED_LIMIT / np.sqrt(2) * 0.999
    sim = pb.Simulation(g, _two_touching(inside), seed=1)
    e0 = sim.energy()
    sim.run(steps=20_000)
    assert np.isfinite(sim.velocities).all()
    assert sim.collisions > 1000
    assert abs(sim.energy() - e0) <= 1e-12 * e0
    assert np.abs(sim.velocities).max() <= np.sqrt(2 * e0) * (1 + 1e-12)
    with pytest.raises(ValueError, match=r"^velocities: with energy .* a ball could reach speed sqrt\(2E/m_min\)"):
        pb.Simulation(g, _two_touching(inside * 1.002))


def test_a_light_ball_lowers_the_speed_bound():
    """Ball 0 moves at 1000 (E = 5e5); a ball of mass m could take all of it: speed sqrt(1e6 / m)."""
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = [1000.0, 0.0]
    m = np.ones(16)
    m[5] = 1e-300  # sqrt(1e306) = 1e153 > 4.2e152
    with pytest.raises(ValueError, match=r"lightest mass 1e-300 a ball could reach speed sqrt\(2E/m_min\) = 1e\+153"):
        pb.Simulation(g, v, masses=m)
    m[5] = 1e-290  # 1e148: accepted, and runs without NaN
    sim = pb.Simulation(g, v, masses=m, seed=2)
    sim.run(steps=5000)
    assert np.isfinite(sim.velocities).all() and sim.collisions > 100


def test_set_state_refuses_overflowing_velocities_and_changes_nothing():
    sim = pb.Simulation(pb.FlatTorus(4, 4), _two_touching(1.0))
    sim.run(steps=100)
    before = sim.get_state()
    state = before.replace(velocities=_two_touching(1e200))
    with pytest.raises(ValueError, match="^velocities: the total energy"):
        sim.set_state(state)
    assert np.array_equal(sim.velocities, before.velocities) and sim.steps == 100


@pytest.mark.parametrize("initial, words", [
    ({"kind": "from_file", "path": "v.npy"}, ["initial.path: the total energy sum m |v|^2 / 2 overflows float64",
                                             "v.npy"]),
    ({"kind": "single_ball", "velocity": [1e160, 0]}, ["initial: the total energy sum m |v|^2 / 2 overflows"]),
    ({"kind": "single_ball", "direction": [1, 0], "energy": 1e306},
     ["initial.energy: too large for these masses: the speeds or the total energy overflow float64",
      "above 1.76e+305"]),
])
def test_overflowing_velocities_from_a_spec_exit_2(tmp_path, initial, words):
    np.save(tmp_path / "v.npy", _two_touching(1.7e308))
    run_refused(tmp_path, write(tmp_path / "s.json", spec(initial=initial)), *words)


# ---------------------------------------------------------------- item 8: errors name the argument


def test_build_with_a_bad_seed_names_seed():
    s = parse_spec(TORUS)
    for seed, shown in ((-1, "-1"), (2**64, str(2**64)), (1.5, "1.5"), (True, "True")):
        with pytest.raises(SpecError, match=rf"^seed: must be an integer in \[0, 2\*\*63\) .*got {shown}$") as info:
            s.build(seed=seed)
        assert info.value.field == "seed"


@pytest.mark.parametrize("make, field, kind", [
    (lambda: pb.FlatTorus(rows=5, cols=4), "rows", FieldError),
    (lambda: pb.HalfPlane(rows="3", cols=4), "rows", FieldTypeError),
    (lambda: pb.FlatTorus(4, 4, radius=-1.0), "radius", FieldError),
    (lambda: pb.Restitution(1.5), "r", FieldError),
    (lambda: pb.Simulation(pb.FlatTorus(4, 4), np.zeros((16, 2)), seed=-3), "seed", FieldError),
    (lambda: pb.Simulation(pb.FlatTorus(4, 4), np.zeros((16, 2)), masses=np.ones(3)), "masses", FieldError),
    (lambda: pb.Simulation(pb.FlatTorus(4, 4), "fast"), "velocities", FieldTypeError),
])
def test_engine_errors_carry_their_field_as_data(make, field, kind):
    with pytest.raises(kind) as info:
        make()
    assert info.value.field == field and isinstance(info.value, (ValueError, InputError))
    assert str(info.value) == f"{field}: {info.value.problem}"
    copy = pickle.loads(pickle.dumps(info.value))  # crosses process pools and Dask intact
    assert (type(copy), copy.field, copy.problem) == (kind, field, info.value.problem)


def test_specs_map_fields_from_the_attribute_not_the_message():
    with pytest.raises(SpecError) as info:
        with engine_errors("geometry", {"rows": "geometry.rows"}):
            raise FieldError("rows", "must be even")
    assert (info.value.field, info.value.problem) == ("geometry.rows", "must be even")
    with pytest.raises(SpecError) as info:  # text that looks like a field is not parsed
        with engine_errors("geometry", {"rows": "geometry.rows"}):
            raise ValueError("rows: must be even")
    assert (info.value.field, info.value.problem) == ("geometry", "rows: must be even")


# ---------------------------------------------------------------- item 7: --dask at something else


class _Server:
    """A TCP server on 127.0.0.1 in a thread: ``greeting`` is sent on connect (then it reads
    until the peer closes, or hangs up with ``hang_up``), or with ``http`` it answers a request
    only after reading one."""

    def __init__(self, greeting: bytes = b"", http: bool = False, hang_up: bool = False):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.greeting, self.http, self.hang_up = greeting, http, hang_up
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._talk, args=(conn,), daemon=True).start()

    def _talk(self, conn):
        with conn:
            try:
                if self.http:
                    conn.recv(65536)
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
                elif self.greeting:
                    conn.sendall(self.greeting)
                while not self.hang_up and conn.recv(65536):
                    pass
            except OSError:
                pass

    def close(self):
        self.sock.close()


def _ensemble_cli(tmp_path: Path, address: str, timeout: float) -> tuple[int, str]:
    """``pinnedballs ensemble --dask ADDRESS`` in a subprocess with a connect timeout of ``timeout`` s;
    the subprocess itself is killed after 60 s, so a hang fails the test instead of stalling it."""
    spec_path = write(tmp_path / "s.json", TORUS)
    code = ("import sys; from pinnedballs.run.cli.main import main; from pinnedballs.run import executors; "
            f"executors.CONNECT_TIMEOUT = {timeout}; sys.exit(main(sys.argv[1:]))")
    proc = subprocess.run([sys.executable, "-c", code, "ensemble", str(spec_path), "--replicas", "2",
                           "--out", str(tmp_path / "out"), "--dask", address],
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    return proc.returncode, proc.stderr


@pytest.mark.parametrize("server, words", [
    (lambda: _Server(b"\xff" * 64), "not a Dask scheduler (its greeting announces 18446744073709551615 bytes)"),
    (lambda: _Server(http=True), "not a Dask scheduler (no Dask handshake within 2 s; a dashboard"),
    (lambda: _Server(b"\x10\x00\x00\x00\x00\x00\x00\x00" + b"garbage!" * 2),
     "not a Dask scheduler (its greeting does not decode as a Dask message"),
    (lambda: _Server(b"\x40\x00\x00\x00\x00\x00\x00\x00abc", hang_up=True),
     "not a Dask scheduler (it closed the connection after 3 of 64 bytes of its greeting)"),
    (lambda: _Server(hang_up=True), "not a Dask scheduler (it closed the connection without a greeting)"),
])
@pytest.mark.slow
def test_dask_address_of_a_server_that_is_not_dask_exits_2(tmp_path, server, words):
    s = server()
    try:
        code, err = _ensemble_cli(tmp_path, f"tcp://127.0.0.1:{s.port}", timeout=2)
    finally:
        s.close()
    assert_input_error(code, err, f"--dask tcp://127.0.0.1:{s.port}: " + words)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_real_scheduler_passes_the_probe(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    from pinnedballs.run import ensemble
    from pinnedballs.run import executors as daskprobe

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as c:
        daskprobe.check_scheduler(c.scheduler_address, 10)
        result = ensemble.run_ensemble(parse_spec(TORUS), 2, dask_address=c.scheduler_address)
    alone = ensemble.run_ensemble(parse_spec(TORUS), 2, workers=1)
    assert repr(result.rows) == repr(alone.rows)  # bit-identical (repr: some columns are NaN)
