"""Damaged results files (issue 10, item 5; issue 20, item 4): each class of damage, made by editing
a good run with h5py, is refused by `pb.load` (`ResultsError` naming the file and the dataset) and
by ``info``, ``plot``, ``animate`` and ``run --resume`` (exit 2, one line), and ``--resume`` leaves the
damaged files exactly as they were instead of finishing them as "done".

Each damage is made on a run of format 2 (written by pinnedballs before format 3, kept in
``tests/data/format2``), which only its structure protects: so every structural check is tested
with its own message. A run of format 3 refuses the same damages earlier, by its digests, naming
the file that changed (`test_any_change_to_a_format_3_run_is_refused_by_a_digest`).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import ROOT, TORUS, assert_input_error, call, spec, write

import pinnedballs as pb
from pinnedballs import ResultsError

#: 16 balls, 48 contacts, 2 components; a sweep in random order, so a scheduler state with a range
#: (the spec of tests/data/format2)
RUN = spec(TORUS, scheduler={"kind": "random_sweep"}, initial={"kind": "gaussian", "energy": 100.0})
N, E = 16, 48
FORMAT_2 = ROOT / "tests" / "data" / "format2"


def _as_running(run: Path) -> None:
    """A finished run marked as a checkpoint still running (its --resume has nothing left to do but
    to mark it done)."""
    with h5py.File(run / "results.h5", "r+") as f:
        f.attrs["status"], f.attrs["stop_reason"] = "running", ""


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> tuple[Path, Path]:
    """``(spec path, run directory)``: the format-2 run, as a checkpoint still running."""
    base = tmp_path_factory.mktemp("good")
    out = base / "run"
    shutil.copytree(FORMAT_2, out)
    _as_running(out)
    return out / "spec.json", out


@pytest.fixture(scope="module")
def good3(tmp_path_factory) -> tuple[Path, Path]:
    """``(spec path, run directory)``: the same run, written now (format 3)."""
    base = tmp_path_factory.mktemp("good3")
    s = write(base / "s.json", RUN)
    out = base / "run"
    assert call("run", s, "--out", out, "--quiet", "--no-figures")[0] == 0
    return s, out


def _index(run: Path) -> Path:
    return run / "results.h5"


def _static(run: Path) -> Path:
    return run / "results.data" / "static.h5"


def _segment(run: Path) -> Path:
    return sorted((run / "results.data").glob("frames_*.h5"))[0]


def _last_segment(run: Path) -> Path:
    return sorted((run / "results.data").glob("frames_*.h5"))[-1]


def _replace(path: Path, name: str, value) -> None:
    with h5py.File(path, "r+") as f:
        del f[name]
        f[name] = value


def _set(path: Path, name: str, change) -> None:
    with h5py.File(path, "r+") as f:
        x = f[name][()]
        change(x)
        f[name][...] = x


def _attr(path: Path, group: str, **attrs) -> None:
    with h5py.File(path, "r+") as f:
        f[group].attrs.update(attrs)


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def _nan_at_0(x):
    x[0, 0] = np.nan


def _nan_in_frame(x):
    x[-1, 3, 1] = np.nan


def _roll_pairs(r: Path) -> None:
    """The same contacts, listed in another order (so every t_i / t_j is attached to the wrong pair)."""
    _set(_static(r), "geometry/pairs", lambda x: x.__setitem__(slice(None), np.roll(x, 1, axis=0)))


def _segments(run: Path, change) -> None:
    with h5py.File(_index(run), "r+") as f:
        listed = json.loads(f.attrs["segments"])
        f.attrs["segments"] = json.dumps(change(listed))


def _map_first_segment_twice(run: Path) -> None:
    """The snapshots' virtual dataset reads the first segment's frame twice (the index's list is intact)."""
    with h5py.File(_index(run), "r+") as f:
        first = f"results.data/{_segment(run).name}"
        rows = f["snapshots/velocities"].shape[0]
        layout = h5py.VirtualLayout(shape=(rows, N, 2), dtype=np.float64)
        for row in range(rows):
            layout[row:row + 1] = h5py.VirtualSource(first, "velocities", shape=(1, N, 2))
        del f["snapshots/velocities"]
        f.create_virtual_dataset("snapshots/velocities", layout)


def _repeat_a_step(x):
    x[-1] = x[-2]


def _margin(margin, **attrs):
    """A damage: ``/state/margin`` in the index replaced by ``margin`` (written where there was none, as in
    format 2), with the threshold and resolution of the run but for those in ``attrs``."""
    def damage(run: Path) -> None:
        with h5py.File(_index(run), "r+") as f:
            if "margin" in f["state"]:
                del f["state/margin"]
            f["state/margin"] = np.asarray(margin)
            f["state/margin"].attrs.update({"threshold": 4 * 2.0**-53 * np.sqrt(200.0), "resolution": 4 * 2.0**-53,
                                            **attrs})
    return damage


#: name: (damage done to the run directory, the file named, words of the message)
DAMAGE = {
    "format": (lambda r: _attr(_index(r), "/", format="something-else"), _index, "not a pinnedballs results file"),
    "version": (lambda r: _attr(_index(r), "/", format_version=-3), _index, "format_version"),
    "status": (lambda r: _attr(_index(r), "/", status="finished?"), _index, "status"),
    "velocities shape": (lambda r: _replace(_index(r), "state/velocities", np.zeros((3, 3))), _index,
                         f"state/velocities: must have shape ({N}, 2), got (3, 3)"),
    "velocities strings": (lambda r: _replace(_index(r), "state/velocities", np.full((N, 2), b"fast")), _index,
                           "state/velocities: must be floating point, got |S4"),
    "initial velocities shape": (lambda r: _replace(_static(r), "initial/velocities", np.zeros((N, 3))), _index,
                                 f"initial/velocities: must have shape ({N}, 2), got ({N}, 3)"),
    "pairs out of range": (lambda r: _set(_static(r), "geometry/pairs", lambda x: x.__setitem__((0, 0), 99)),
                           _index, f"geometry/pairs: must be pairs of distinct balls in [0, {N})"),
    "pairs replaced": (_roll_pairs, _index, "geometry/pairs: differ from the 48 contacts of the spec's geometry"),
    "negative steps": (lambda r: _attr(_index(r), "state", steps=-5), _index, "state/steps: must be >= 0, got -5"),
    "collisions > steps": (lambda r: _attr(_index(r), "state", collisions=10**6), _index,
                           "state/collisions: 1000000 is more than the 1000 steps taken"),
    "NaN velocities": (lambda r: _set(_index(r), "state/velocities", _nan_at_0), _index,
                       "state/velocities: holds 1 non-finite values"),
    "NaN in a snapshot": (lambda r: _set(_segment(r), "velocities", _nan_in_frame), _index,
                          "snapshots/velocities: holds non-finite values"),
    "snapshot past the state": (lambda r: _set(_segment(r), "observables/steps",
                                               lambda x: x.__setitem__(-1, 5_000)), _index,
                                "observables/steps: must be >= 0, in order and at most the state's 1,000"),
    "zero rng state": (lambda r: _replace(_index(r), "state/rng_state", np.zeros(4, np.uint64)), _index,
                       "state/rng_state: is all zero"),
    "rng state dtype": (lambda r: _replace(_index(r), "state/rng_state", np.ones(4)), _index,
                        "state/rng_state: must be unsigned integers (uint64), got float64"),
    "scheduler state out of range": (lambda r: _set(_index(r), "state/scheduler_state",
                                                    lambda x: x.__setitem__(0, E + 7)), _index,
                                     f"state/scheduler_state: the position in the sweep must be in [0, {E}], got 55"),
    "scheduler state not a permutation": (lambda r: _set(_index(r), "state/scheduler_state",
                                                         lambda x: x.__setitem__(1, x[2])), _index,
                                          "state/scheduler_state: the sweep order must be a permutation"),
    "missing segment": (lambda r: _segment(r).unlink(), _index, "frames_000000000.h5 is missing"),
    "truncated index": (lambda r: _truncate(_index(r)), _index, "not a readable HDF5 file"),
    "truncated static": (lambda r: _truncate(_static(r)), _static, "not a readable HDF5 file (truncated?)"),
    "truncated segment": (lambda r: _truncate(_segment(r)), _segment, "not a readable HDF5 file (truncated?)"),
    "short segment": (lambda r: _replace(_last_segment(r), "velocities", np.zeros((1, N, 2))), _index,
                      "frames_000000001.h5: velocities: must have 2 rows"),
    # issue 20, item 4: attributes that are not what they say, and frames passed off twice
    "format_version text": (lambda r: _attr(_index(r), "/", format_version="abc"), _index,
                            "/ (attribute format_version): must be an integer from 1 to"),
    "state keys not JSON": (lambda r: _attr(_index(r), "state", keys="[velocities"), _index,
                            "state/keys: must be a JSON list (text), got '[velocities'"),
    "state keys other": (lambda r: _attr(_index(r), "state", keys='["velocities"]'), _index,
                         "state/keys: must list ['velocities', 'steps', 'collisions', 'rng_state', "
                         "'scheduler_state']"),
    "elapsed time text": (lambda r: _attr(_index(r), "/", elapsed_seconds="fast"), _index,
                          "/ (attribute elapsed_seconds): must be a number, got 'fast'"),
    "checkpoints fraction": (lambda r: _attr(_index(r), "/", checkpoints=2.5), _index,
                             "/ (attribute checkpoints): must be an integer, got 2.5"),
    "observables not JSON": (lambda r: _attr(_index(r), "/", observables="steps, collisions"), _index,
                             "/ (attribute observables): must be a JSON list (text)"),
    "frozen but approaching": (lambda r: _attr(_index(r), "state", frozen=True), _index,
                               "state/frozen: is True with"),
    "segment listed twice": (lambda r: _segments(r, lambda s: [s[0], s[0], *s[1:]]), _index,
                             "/ (attribute segments): ['frames_000000000.h5', 0, 1] does not follow the 1 frames "
                             "before it (a segment listed twice"),
    "segment listed out of order": (lambda r: _segments(r, lambda s: s[::-1]), _index,
                                    "/ (attribute segments): ['frames_000000001.h5', 1, 2] does not follow the 0"),
    "a segment mapped twice": (_map_first_segment_twice, _index,
                               "snapshots/velocities: does not map the segments the index lists, each once and in "
                               "order"),
    "a step listed twice": (lambda r: _set(_last_segment(r), "observables/steps", _repeat_a_step), _index,
                            "observables/steps: lists the same step twice (duplicated snapshots)"),
    # issue 27: the closing margin of the latest state, and its criterion
    "margin NaN": (_margin([np.nan, 0.0, 0.0, 0.0]), _index, "state/margin: the smallest collision's closing speed "
                                                             "must be > 0 (inf: none yet), got nan"),
    "margin shape": (_margin(np.ones(3)), _index, "state/margin: must be 4 floating-point numbers, got float64 (3,)"),
    "margin text": (_margin(np.array([b"wide"] * 4)), _index, "state/margin: must be 4 floating-point numbers, "
                                                              "got |S4 (4,)"),
    "margin counts a fraction": (_margin([1.0, 0.0, 0.5, 0.0]), _index,
                                 "state/margin: the counts near the threshold must be whole numbers >= 0, "
                                 "got [0.5, 0.0]"),
    "margin threshold text": (_margin(np.full(4, 1.0), threshold="x"), _index,
                              "state/margin (attribute threshold): must be a number in [0, inf), got 'x'"),
    "margin resolution 2": (_margin(np.full(4, 1.0), resolution=2.0), _index,
                            "state/margin (attribute resolution): must be a number in (0, 1), got 2.0"),
}


def _digest(run: Path) -> dict[str, str]:
    return {str(p.relative_to(run)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(run.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("name", list(DAMAGE))
def test_damage_is_named_and_never_resumed(good, tmp_path, name):
    s, source = good
    run = tmp_path / "run"
    shutil.copytree(source, run)
    damage, named, words = DAMAGE[name]
    named = named(run)  # before the damage: a segment may be removed
    damage(run)
    before = _digest(run)
    with pytest.raises(ResultsError) as caught:
        pb.load(run)
    message = str(caught.value)
    assert message.startswith(f"{_index(run)}: ") and str(named) in message and words in message, message
    for argv in (["info", run], ["plot", run], ["animate", run],
                 ["run", s, "--out", run, "--resume", "--quiet", "--no-figures"]):
        code, stdout, err = call(*argv)
        assert_input_error(code, err, str(named), words)
        assert stdout == ""
    assert _digest(run) == before  # --resume wrote nothing, and did not mark the run done


def test_the_undamaged_copy_loads_and_resumes_to_done(good, good3, tmp_path):
    """The control: the same file, undamaged, passes every check and --resume finishes it (as format 3),
    ending on the bits of the run written now."""
    s, source = good
    run = tmp_path / "run"
    shutil.copytree(source, run)
    res = pb.load(run)
    assert (res.format_version, res.status, res.steps, len(res.snapshots)) == (2, "running", 1000, 3)
    assert call("info", run)[0] == 0
    assert call("run", s, "--out", run, "--resume", "--quiet", "--no-figures")[0] == 0
    res, now = pb.load(run), pb.load(good3[1])
    assert (res.format_version, res.complete, res.steps) == (3, True, 1000)
    assert res.latest.identical(now.latest.replace(margin=None)) and res.checkpoints == now.checkpoints + 1
    assert res.closing_margin is None and now.closing_margin is not None  # format 2 kept none: unknown
    assert all(np.array_equal(a.velocities, b.velocities) for a, b in zip(res.snapshots, now.snapshots))


@pytest.mark.parametrize("name", list(DAMAGE))
def test_any_change_to_a_format_3_run_is_refused_by_a_digest(good3, tmp_path, name):
    """The same damage to a run written now: refused before anything parses the changed file, naming it."""
    s, source = good3
    run = tmp_path / "run"
    shutil.copytree(source, run)
    before = _digest(run)
    DAMAGE[name][0](run)
    after = _digest(run)
    changed = sorted(set(before) - set(after)) or [f for f in sorted(after) if after[f] != before[f]][-1:]
    assert changed  # a damage changes or removes a file
    where = run / changed[0]
    if changed[0] not in after:
        words = f"damaged results file ({where} is missing)"
    elif where.name == "results.h5":
        words = f"{where}: damaged results file: its bytes differ from the digest written with them"
    else:
        words = f"damaged results file: {where}: its bytes differ from the digest the index holds for it"
    with pytest.raises(ResultsError) as caught:
        pb.load(run)
    assert str(caught.value).startswith(f"{_index(run)}: ") and words in str(caught.value), str(caught.value)
    for argv in (["info", run], ["plot", run], ["animate", run],
                 ["run", s, "--out", run, "--resume", "--quiet", "--no-figures"]):
        code, stdout, err = call(*argv)
        assert_input_error(code, err, words)
        assert stdout == ""
    assert _digest(run) == after


def test_a_python_writer_will_not_resume_a_damaged_file(good, tmp_path):
    s, source = good
    run = tmp_path / "run"
    shutil.copytree(source, run)
    sim = pb.load(run).simulation()
    _attr(_index(run), "state", collisions=10**6)
    with pytest.raises(ResultsError, match="state/collisions: 1000000 is more than the 1000 steps"):
        sim.run(steps=10, writers=[pb.ResultsWriter(run, resume=True)])
    assert sim.steps == 1000
