"""The results format under random damage (issue 20): hypothesis flips bits, truncates, deletes and
duplicates datasets, attributes and whole files of a run's ``results.h5``, ``static.h5`` and
segments; loading then either returns exactly the run that was written or raises `ResultsError`,
never another exception and never a hang; ``info``, ``plot`` and ``run --resume`` say the same with
their exit status (0 with the undamaged output, or 2 and one line).

HDF5 changes are made first, on the sound files (h5py must not parse damaged bytes itself), then
the byte-level ones.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import TORUS, call, spec, write
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs import ResultsError

RUN = spec(TORUS, initial={"kind": "gaussian", "energy": 100.0}, snapshots={"every_steps": 250},
           checkpoint={"every_seconds": 0})

#: each example gets a fresh copy; a deadline catches a hang (a load takes milliseconds: the deadline
#: leaves room for a machine shared by several test runs)
FUZZ = settings(max_examples=150, deadline=30_000, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
FUZZ_CLI = settings(max_examples=30, deadline=120_000, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def _files(run: Path) -> list[Path]:
    return [run / "results.h5", *sorted((run / "results.data").iterdir())]


def _objects(path: Path) -> tuple[list[str], list[tuple[str, str]]]:
    """The datasets and groups of an HDF5 file (external links not followed), and ``(object, attribute)`` pairs."""
    names, attrs = [], [("/", a) for a in h5py.File(path, "r").attrs]
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            names.append(name)
            attrs.extend((name, a) for a in obj.attrs)
        f.visititems(visit)
    return names, attrs


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """``(spec path, run directory, what load gives, the structure of each file)``: a run of 1,000 steps
    in 4 segments."""
    base = tmp_path_factory.mktemp("fuzz")
    s = write(base / "s.json", RUN)
    run = base / "run"
    assert call("run", s, "--out", run, "--quiet", "--no-figures")[0] == 0
    assert len(_files(run)) == 6
    return s, run, pb.load(run), {p.relative_to(run): _objects(p) for p in _files(run)}


def same(a, b) -> bool:
    """Two loaded runs are the same run, bit for bit, in every field ``Results`` has."""

    def arrays(r):
        return [r.velocities, r.rng_state, r.scheduler_state, r.momentum, r.positions, r.pairs, r.t_i, r.t_j,
                r.initial_velocities, *(s.velocities for s in r.snapshots), *r.observables.values()]

    def geometry(r):
        return r.stored.view, r.stored.radius, r.stored.boundary, r.masses

    def fields(r):
        return (r.spec, r.version, r.status, r.stop_reason, r.energy, r.approaching, r.frozen, r.initial_energy,
                [s[:2] for s in r.snapshots], list(r.observables), r.elapsed_seconds, r.checkpoints, r.created,
                r.updated, r.steps, r.collisions, r.run, r.format_version, geometry(r))

    return fields(a) == fields(b) and all(x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
                                          for x, y in zip(arrays(a), arrays(b), strict=True))


# ---------------------------------------------------------------- damage


@st.composite
def damages(draw, structure: dict) -> list[tuple]:
    """1 to 3 damages: ``("delete" | "duplicate" | "delete attr" | "duplicate attr" | "overwrite attr", file, ...)``
    on the HDF5 structure, ``("flip", file, offset, mask)``, ``("truncate", file, fraction)`` and
    ``("copy file", source, target)`` on the bytes."""
    files = sorted(structure)
    out = []
    for _ in range(draw(st.integers(1, 3))):
        file = draw(st.sampled_from(files))
        names, attrs = structure[file]
        kind = draw(st.sampled_from(["flip", "flip", "flip", "truncate", "copy file", "delete", "duplicate",
                                     "delete attr", "duplicate attr", "overwrite attr"]))
        if kind == "flip":
            out.append((kind, file, draw(st.floats(0, 1, exclude_max=True)), draw(st.integers(1, 255))))
        elif kind == "truncate":
            out.append((kind, file, draw(st.floats(0, 1, exclude_max=True))))
        elif kind == "copy file":
            out.append((kind, file, draw(st.sampled_from(files))))
        elif kind in ("delete", "duplicate"):
            out.append((kind, file, draw(st.sampled_from(names))))
        elif kind == "overwrite attr" and len(attrs) > 1:
            out.append((kind, file, draw(st.sampled_from(attrs)), draw(st.sampled_from(attrs))))
        elif attrs:
            out.append((kind, file, draw(st.sampled_from(attrs))))
    return sorted(out, key=lambda d: d[0] in ("flip", "truncate", "copy file"))  # HDF5 changes first


def damage(run: Path, changes: list[tuple]) -> None:
    for kind, file, *args in changes:
        path = run / file
        if kind in ("flip", "truncate", "copy file"):
            data = bytearray(path.read_bytes())
            if kind == "flip":
                if data:  # (a file truncated to nothing has no byte to flip)
                    data[int(args[0] * len(data))] ^= args[1]
            elif kind == "truncate":
                data = data[:int(args[0] * len(data))]
            else:
                data = bytearray((run / args[0]).read_bytes())
            path.write_bytes(bytes(data))
            continue
        try:
            with h5py.File(path, "r+") as f:
                if kind == "delete":
                    del f[args[0]]
                elif kind == "duplicate":
                    f.copy(f[args[0]], f"{args[0]}_copy")
                elif kind == "delete attr":
                    del f[args[0][0]].attrs[args[0][1]]
                elif kind == "duplicate attr":
                    f[args[0][0]].attrs[args[0][1] + "_copy"] = f[args[0][0]].attrs[args[0][1]]
                else:
                    (g, a), (h, b) = args
                    f[h].attrs[b] = f[g].attrs[a]
        except (KeyError, ValueError, OSError, TypeError, RuntimeError):
            pass  # already gone with its parent, or not copyable: that change is not made


# ---------------------------------------------------------------- the properties


def _damaged_copy(written, tmp_path_factory, data) -> Path:
    """A copy of the written run with one drawn set of damages applied."""
    _, source, _, structure = written
    run = tmp_path_factory.mktemp("damaged") / "run"
    shutil.copytree(source, run)
    damage(run, data.draw(damages(structure)))
    return run


@FUZZ
@given(data=st.data())
def test_load_gives_the_run_written_or_results_error(written, tmp_path_factory, data):
    _, _, expected, _ = written
    run = _damaged_copy(written, tmp_path_factory, data)
    try:
        got = pb.load(run)
    except ResultsError as exc:
        event(f"refused: {_why(str(exc))}")
        return
    event("loads")
    assert same(got, expected)


@pytest.mark.slow
@FUZZ_CLI
@given(data=st.data())
def test_info_plot_and_resume_say_it_with_their_exit_status(written, tmp_path_factory, data):
    s, _, expected, _ = written
    run = _damaged_copy(written, tmp_path_factory, data)
    sound = _loads(run)
    event("loads" if sound else "refused")
    for argv in (["info", run], ["plot", run], ["run", s, "--out", run, "--resume", "--quiet", "--no-figures"]):
        code, out, err = call(*argv)
        if sound:
            assert (code, err) == (0, ""), (argv, err)
        else:
            assert code == 2 and "Traceback" not in err and len(err.splitlines()) == 1, (argv, err)
            assert err.startswith(f"pinnedballs: error: {run / 'results.h5'}: ") and out == "", (argv, err)
    if sound:
        assert same(pb.load(run), expected)


def _why(message: str) -> str:
    """The class of a refusal, for hypothesis's statistics (``--hypothesis-show-statistics``)."""
    for words, why in (("digest written with them", "the index's digest"),
                       ("digest the index holds", "a file's digest"), ("is missing", "a file missing"),
                       ("not a readable HDF5 file", "not readable")):
        if words in message:
            return why
    return "other: " + message[message.index(": ") + 2:][:60]


def _loads(run: Path) -> bool:
    try:
        pb.load(run)
    except ResultsError:
        return False
    return True


def test_the_fuzzed_run_is_a_real_one(written):
    """The control: 4 snapshots in 4 segments, loaded the same twice; the same with a no-op damage."""
    _, run, expected, structure = written
    assert len(expected.snapshots) == 4 and same(pb.load(run), expected) and expected.format_version == 3
    assert {str(p) for p in structure} == {"results.h5", "results.data/static.h5"} | {
        f"results.data/frames_{k:09d}.h5" for k in (0, 1, 2, 3)}
    assert not same(pb.load(run), _shifted(expected))


def _shifted(res):
    """``res`` with one bit of its latest velocities changed: `same` must see it."""
    import dataclasses

    v = res.velocities.copy()
    v.view(np.uint64)[0, 0] ^= 1
    return dataclasses.replace(res, latest=res.latest.replace(velocities=v))
