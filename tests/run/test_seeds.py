"""Seeds of spec runs and ensembles (issue 26, item 4): a spec without ``"seed"`` gets one drawn when it
runs, which the run records (``spec.json``, the results file), so that ``--resume`` continues the
same run and the recorded spec repeats it; an ensemble draws one for all its replicas."""

from __future__ import annotations

import json

import pytest
from helpers import TORUS, assert_identical, call, reference, resume, spec, write

from pinnedballs.engine import driver
from pinnedballs.results.load import load
from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec

UNSEEDED = spec(TORUS, seed=...)


def test_a_spec_without_a_seed_draws_one_and_records_it(tmp_path):
    spec_path = write(tmp_path / "s.json", UNSEEDED)
    seeds = []
    for name in ("a", "b"):
        code, _, err = call("run", spec_path, "--out", tmp_path / name, "--quiet", "--no-figures")
        assert (code, err) == (0, "")
        written = json.loads((tmp_path / name / "spec.json").read_text())["seed"]
        res = load(tmp_path / name)
        assert isinstance(written, int) and 0 <= written < 2**63 and res.spec.seed == written
        seeds.append(written)
    assert seeds[0] != seeds[1]  # two runs of the spec are independent
    a, b = load(tmp_path / "a"), load(tmp_path / "b")
    assert a.collisions != b.collisions or (a.velocities != b.velocities).any()
    # the recorded spec repeats the run bit for bit
    assert_identical(a, reference(tmp_path, json.loads((tmp_path / "a" / "spec.json").read_text())))
    code, out, _ = call("info", tmp_path / "a")
    assert f", seed {seeds[0]}\n" in out
    code, out, _ = call("validate", spec_path)
    assert code == 0 and out.endswith("; seed drawn when it runs\n")


class Crash(Exception):
    pass


def test_resume_of_a_spec_without_a_seed_continues_the_seed_the_run_drew(tmp_path, monkeypatch):
    """Every life of a requeued job runs the same spec, without a seed: the run keeps the one it drew."""
    data = spec(UNSEEDED, stop={"steps": 3_000}, snapshots={"every_steps": 500}, checkpoint={"every_seconds": 0})
    spec_path = write(tmp_path / "s.json", data)
    out = tmp_path / "out"
    monkeypatch.setattr(driver, "CHUNK_STEPS", 400)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
    advance, calls = driver.advance, []

    def crashing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise Crash
        return advance(*args, **kwargs)

    monkeypatch.setattr(driver, "advance", crashing)
    with pytest.raises(Crash):
        runner.execute(parse_spec(data), out, figures=False, progress=False)
    monkeypatch.undo()
    crashed = load(out)
    assert not crashed.complete and 0 < crashed.steps < 3_000
    drawn = crashed.spec.seed
    assert resume(spec_path, out) == 0
    done = load(out)
    assert done.spec.seed == drawn == json.loads((out / "spec.json").read_text())["seed"]
    assert_identical(done, reference(tmp_path, spec(data, seed=drawn)))


def test_an_ensemble_without_a_seed_draws_one_for_all_its_replicas(tmp_path):
    spec_path = write(tmp_path / "s.json", spec(UNSEEDED, stop={"steps": 300}, snapshots=...))
    for name in ("a", "b"):
        code, _, err = call("ensemble", spec_path, "--replicas", "3", "--workers", "1", "--out", tmp_path / name,
                            "--quiet")
        assert (code, err) == (0, "")
    summaries = [json.loads((tmp_path / name / ens.SUMMARY_NAME).read_text()) for name in ("a", "b")]
    seeds = [s["seed"] for s in summaries]
    assert all(isinstance(s, int) and 0 <= s < 2**63 for s in seeds) and seeds[0] != seeds[1]
    for name, seed, summary in zip(("a", "b"), seeds, summaries):
        assert json.loads((tmp_path / name / ens.SPEC_NAME).read_text())["seed"] == seed == summary["spec"]["seed"]
        rows = ens_files.read_table(tmp_path / name / ens.TABLE_NAME)
        assert {row["seed_entropy"] for row in rows} == {str(seed)}  # one seed, replica k its child k
    # the recorded spec repeats the ensemble bit for bit
    again = ens.run_ensemble(parse_spec(json.loads((tmp_path / "a" / ens.SPEC_NAME).read_text())), 3, workers=1)
    ens_files.write_table(again, tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "a" / ens.TABLE_NAME).read_text()


def test_a_replica_run_alone_is_the_ensembles_replica(tmp_path):
    """``"replica": k`` seeds a run as an ensemble of the spec seeds its replica k
    (``SeedSequence(seed, spawn_key=(k,))``): run alone, checkpointed like any run, it ends on the
    ensemble's replica's steps and collisions, and ``info`` names it."""
    from helpers import HALF_PLANE

    rows = ens.run_replica(parse_spec(HALF_PLANE), 2)
    path = write(tmp_path / "r2.json", spec(HALF_PLANE, replica=2))
    code, _, err = call("run", path, "--out", tmp_path / "r2", "--quiet", "--no-figures")
    assert (code, err) == (0, "")
    res = load(tmp_path / "r2")
    assert (res.steps, res.collisions) == (rows[-1]["steps"], rows[-1]["collisions"]) and res.spec.replica == 2
    plain = ens.run_replica(parse_spec(HALF_PLANE), 0)[-1]
    assert (plain["steps"], plain["collisions"]) != (res.steps, res.collisions)  # another replica, other picks
    code, out, _ = call("info", tmp_path / "r2")
    assert ", seed 3, replica 2\n" in out


def test_a_replica_without_a_seed_is_refused(tmp_path):
    path = write(tmp_path / "r.json", spec(UNSEEDED, replica=1))
    code, out, err = call("validate", path)
    assert code == 2 and "replica: is replica k of the ensemble the seed seeds; give the spec a seed" in err
