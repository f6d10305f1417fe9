"""A certified run that cannot decide a pick (issue 42, item 1): its error names the step and the bits on every
path, the first failure winning over any that saving the run meets; the directory keeps the state the run
stopped in, marked failed with the step, the bits and what to do instead; ``info`` says so, and ``--resume``
refuses in one line rather than running into the same failure. At 64 bits the 30x15 half-plane (seed 1) cannot
decide contact 117 at step 1,099, and its live contacts cannot be counted after step 1,098."""

from __future__ import annotations

import json

import pytest
from helpers import assert_input_error, call, spec, write

import pinnedballs as pb
from pinnedballs.engine.field import arithmetic
from pinnedballs.engine.field.fixed import UncertifiedDecision
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec

AT_64_BITS = {
    "geometry": {"kind": "half_plane", "length": 30, "depth": 15},
    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": "inward", "energy": 100},
    "stop": {"frozen": True, "max_steps": 10**7},
    "arithmetic": "certified", "precision": 64, "checkpoint": {"every_seconds": 60}, "seed": 1,
}
#: what the run cannot decide, as it says it without a writer
UNDECIDED = "certified arithmetic cannot decide contact 117 (balls 40, 55) at step 1,099: its closing speed 0"


def test_a_failed_run_names_its_step_and_is_marked_failed_and_info_says_so(tmp_path):
    out = tmp_path / "r"
    code, _, err = call("run", write(tmp_path / "s.json", AT_64_BITS), "--out", out, "--quiet", "--no-figures")
    assert_input_error(code, err, f"arithmetic: {UNDECIDED}", "(now 64 bits)")
    res = pb.load(out)
    assert res.status == "failed" and not res.complete
    assert res.steps == 1098  # the last state the chain passed through, not the state it started from
    assert (res.approaching, res.frozen) == (-1, False)  # its live contacts cannot be counted at 64 bits
    failure = res.failure
    assert (failure["steps"], failure["precision"], failure["late_precision"]) == (1098, 64, 0)
    assert failure["decision"].startswith(UNDECIDED)
    assert '"precision": "auto"' in failure["remedy"] and "more than 64 bits" in failure["remedy"]
    code, text, err = call("info", out)
    assert (code, err) == (0, "")
    status = next(line for line in text.splitlines() if line.startswith("status:"))
    assert status.startswith(f"status:      failed at step 1,098 at 64 bits: {UNDECIDED}")
    assert "it cannot go on: run it again (--force) with \"precision\": \"auto\"" in status
    assert "--resume" not in text and "killed" not in text
    assert "approaching: unknown (certified arithmetic could not count the live contacts at these bits)\n" in text


def test_resuming_a_failed_run_refuses_in_one_line_and_changes_nothing(tmp_path):
    spec_path, out = write(tmp_path / "s.json", AT_64_BITS), tmp_path / "r"
    assert call("run", spec_path, "--out", out, "--quiet", "--no-figures")[0] == 2
    before = (out / "results.h5").read_bytes()
    code, stdout, err = call("run", spec_path, "--out", out, "--quiet", "--no-figures", "--resume")
    assert stdout == ""
    assert_input_error(code, err, f"--resume: the run in {out} failed at step 1,098 at 64 bits: {UNDECIDED}",
                       "continuing it would fail the same way: run it again (--force) with")
    assert "cannot decide contact 117 (balls 40, 55) at step 1,099" in err and err.count("cannot decide") == 1
    assert (out / "results.h5").read_bytes() == before
    assert call("run", spec_path, "--out", out, "--quiet", "--no-figures", "--force")[0] == 2  # --force starts over


def test_a_python_run_with_a_writer_fails_as_one_without(tmp_path):
    """The writer saves the state the run stopped in; the error that goes on is the run's own, word for word."""
    with pytest.raises(UncertifiedDecision) as plain:
        parse_spec(AT_64_BITS).build().run_until_frozen(max_steps=10**7, progress=False)
    sim = parse_spec(AT_64_BITS).build()
    with pytest.raises(UncertifiedDecision) as written:
        sim.run_until_frozen(max_steps=10**7, writers=[pb.ResultsWriter(tmp_path / "py")], progress=False)
    assert str(written.value) == str(plain.value) and UNDECIDED in str(plain.value)
    res = pb.load(tmp_path / "py")
    assert (res.status, res.steps, res.collisions) == ("failed", 1098, sim.collisions) and sim.steps == 1098
    assert "precision above 64 bits" in res.failure["remedy"] and 'arithmetic="exact"' in res.failure["remedy"]
    again = res.simulation()
    with pytest.raises(pb.InputError, match=r"^resume: the run in .* failed at step 1,098 at 64 bits: certified"):
        again.run(steps=10, writers=[pb.ResultsWriter(tmp_path / "py", resume=True)], progress=False)
    assert pb.load(tmp_path / "py").status == "failed"


def test_a_count_of_the_live_contacts_that_fails_names_the_step_it_follows():
    sim = parse_spec(AT_64_BITS).build()
    with pytest.raises(UncertifiedDecision):
        sim.run_until_frozen(max_steps=10**7, progress=False)
    with pytest.raises(UncertifiedDecision, match="at a count of the live contacts after step 1,098: "):
        sim.approaching()


def test_an_auto_run_starting_again_says_the_first_failures_words(tmp_path, monkeypatch):
    monkeypatch.setattr(arithmetic, "AUTO_START", 64)
    lines: list[str] = []
    runner.execute(parse_spec(spec(AT_64_BITS, precision="auto")), tmp_path / "auto", figures=False, progress=False,
                   log=lines.append)
    assert lines[0] == (f"precision auto: at 64 bits, {UNDECIDED} is within the error bound 2.88444e-16; starting "
                        f"again at 128 bits")
    res = pb.load(tmp_path / "auto")
    assert res.complete and res.failure is None and json.loads((tmp_path / "auto" / "spec.json").read_text())[
        "precision"] == "auto"


def test_a_failed_run_keeps_the_snapshots_before_it(tmp_path):
    data = spec(AT_64_BITS, snapshots={"every_steps": 250})
    code, _, err = call("run", write(tmp_path / "s.json", data), "--out", tmp_path / "r", "--quiet", "--no-figures")
    assert_input_error(code, err, UNDECIDED)
    res = pb.load(tmp_path / "r")
    assert (res.status, res.steps) == ("failed", 1098) and res.snapshots.steps.tolist() == [250, 500, 750, 1000]
