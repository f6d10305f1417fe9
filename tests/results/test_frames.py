"""Lazy snapshots (issue 24, item 6): `pb.load` reads a run's index, and each snapshot's velocities
when it is taken; the values are those stored, bit for bit, and a file damaged or replaced after
loading is refused with one line when read."""

from __future__ import annotations

import json
import shutil

import h5py
import numpy as np
import pytest
from helpers import TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs import ResultsError
from pinnedballs.results.digest import HEADER_SIZE, file_digest, seal
from pinnedballs.results.format import Snapshot

#: 9 snapshots (steps 0, 100, ..., 800) in several segments (a checkpoint after every chunk)
RUN = spec(TORUS, initial={"kind": "gaussian", "energy": 100.0}, snapshots={"every_steps": 100},
           stop={"steps": 800}, checkpoint={"every_seconds": 0})


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    base = tmp_path_factory.mktemp("frames")
    run = base / "run"
    assert call("run", write(base / "s.json", RUN), "--out", run, "--quiet", "--no-figures")[0] == 0
    return run


@pytest.fixture
def run(written, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(written, copy)
    return copy


def stored(run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(velocities (F, n, d), steps (F,), collisions (F,))`` read eagerly through the index."""
    with h5py.File(run / "results.h5", "r") as f:
        return f["snapshots/velocities"][()], f["observables/steps"][()], f["observables/collisions"][()]


def test_each_snapshot_read_lazily_is_the_one_stored(written):
    res = pb.load(written)
    velocities, steps, collisions = stored(written)
    assert len(res.snapshots) == 8
    assert res.snapshots.steps.tolist() == steps.tolist() == list(range(100, 801, 100))
    assert res.snapshots.collisions.tolist() == collisions.tolist()
    for k, snap in enumerate(res.snapshots):
        assert (snap.steps, snap.collisions) == (steps[k], collisions[k])
        assert snap.velocities.dtype == np.float64 and snap.velocities.tobytes() == velocities[k].tobytes()
    assert res.snapshots[-1].velocities.tobytes() == velocities[-1].tobytes()
    assert [s.steps for s in res.snapshots[2:5]] == [300, 400, 500]
    assert res.snapshots == [Snapshot(int(a), int(b), v) for a, b, v in zip(steps, collisions, velocities)]
    assert res.snapshots != res.snapshots[:-1]
    with pytest.raises(IndexError, match="snapshot 8 out of range: the run has 8"):
        res.snapshots[8]


def test_the_snapshots_are_in_several_segments_and_read_from_each(written):
    res = pb.load(written)
    files = {f.path.name for f in res.snapshots.files}
    assert len(files) >= 4 and all(name.startswith("frames_") for name in files)


def test_a_segment_replaced_after_loading_is_refused_when_read(run):
    res = pb.load(run)
    last = res.snapshots.files[-1]
    shutil.copy(res.snapshots.files[0].path, last.path)   # another run's bytes under the same name
    with pytest.raises(ResultsError) as caught:
        res.snapshots[last.first]
    assert str(caught.value) == (f"{run / 'results.h5'}: snapshot {last.first} ({last.path.name}): the file changed "
                                 f"since the run was loaded (a run written there again?): load the run again")
    assert res.snapshots[0].velocities.shape == (16, 2)   # the others still read
    last.path.unlink()
    with pytest.raises(ResultsError, match=r"the file is gone since the run was loaded: load the run again$"):
        res.snapshots[-1]


def test_a_frame_forged_with_matching_digests_loads_but_is_refused_when_read(run):
    """Format 3 verifies digests at open and each frame's values when read: a NaN written by another
    program that also rewrote every digest opens, and its snapshot is refused by name when taken."""
    res = pb.load(run)
    target = res.snapshots.files[1]
    with h5py.File(target.path, "r+") as f:
        f["velocities"][0, 3, 1] = np.nan
    index = run / "results.h5"
    with h5py.File(index, "r+") as f:
        digests = json.loads(f.attrs["digests"])
        digests[target.path.name] = file_digest(target.path)
        f.attrs["digests"] = json.dumps(digests)
    index.write_bytes(seal(index.read_bytes()[HEADER_SIZE:]))
    forged = pb.load(run)
    assert forged.snapshots[0].velocities.tobytes() == res.snapshots[0].velocities.tobytes()
    with pytest.raises(ResultsError) as caught:
        forged.snapshots[target.first]
    assert str(caught.value) == (f"{index}: snapshot {target.first} ({target.path.name}): damaged results file: "
                                 f"snapshots/velocities: holds non-finite values (NaN or inf)")
