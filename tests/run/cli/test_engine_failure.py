"""An engine that fails (issue 49, item 6): a loop that stops short of its chunk, neither frozen nor at its
collision target, breaks the chunk protocol. The run ends with one line saying what failed and exit status 1
(an internal failure, not bad input; ``--traceback`` shows where), its results saved at the state the loop
left, marked "failed" with those words, which ``info`` shows and ``--resume`` refuses. Before, a traceback,
and the results "interrupted" as if a Ctrl-C had stopped them."""

from __future__ import annotations

import pytest
from helpers import TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs.engine import find, register
from pinnedballs.engine.backends import LoopBackend
from pinnedballs.engine.builtin import Sequential

#: a 4x4 torus (it never freezes) to frozen, on the sequential engine: no threads run a sweep
FROZEN = spec(TORUS, scheduler={"kind": "sweep"}, stop={"frozen": True, "max_steps": 10**6}, snapshots=...)
#: the steps the first chunk takes (`engine.driver.FIRST_CHUNK` asked, one short)
SHORT_AT = (1 << 12) - 1
LINE = (f"pinnedballs: error: the loop of engine 'sequential' stopped at step {SHORT_AT:,}, 1 step short of its "
        f"chunk, neither frozen nor at its collision target (an internal failure)\n")


class OneShort(LoopBackend):
    """A deliberately broken loop: until frozen, it takes one step fewer than asked (its state is whole)."""

    def _run(self, max_steps, max_collisions, until_frozen):
        return super()._run(max_steps - 1 if until_frozen and max_steps > 1 else max_steps, max_collisions,
                            until_frozen)


class ShortSequential(Sequential):
    def build(self, model, state, listeners, device, options):
        return OneShort(model, state, listeners, device=device)


@pytest.fixture
def broken():
    """The door's sequential engine replaced by `ShortSequential` while the test runs."""
    sound = find("sequential")
    register(ShortSequential(), replace=True)
    try:
        yield
    finally:
        register(sound, replace=True)


def test_a_loop_short_of_its_chunk_is_one_line_and_a_failed_run(tmp_path, broken):
    spec_path, out = write(tmp_path / "s.json", FROZEN), tmp_path / "out"
    assert call("run", spec_path, "--out", out, "--quiet", "--no-figures") == (1, "", LINE)
    res = pb.load(out)
    assert (res.status, res.steps, res.failure["error"]) == ("failed", SHORT_AT, "InternalError")
    sound = pb.load_spec(spec_path).build()
    sound.run(steps=SHORT_AT)
    assert res.state().identical(sound.get_state())  # the state the loop left: the chain's, whole
    code, said, _ = call("info", out)
    assert code == 0 and (f"status:      failed at step {SHORT_AT:,}: the loop of engine 'sequential' stopped at "
                          f"step {SHORT_AT:,}, 1 step short of its chunk") in said
    assert "it cannot go on: run it again (--force); one that fails the same way is a fault of pinnedballs" in said
    code, _, err = call("run", spec_path, "--out", out, "--quiet", "--no-figures", "--resume")
    assert code == 2 and err.startswith(f"pinnedballs: error: --resume: the run in {out} failed at step "
                                        f"{SHORT_AT:,}: the loop of engine 'sequential'")


def test_traceback_shows_where_the_engine_failed(tmp_path, broken):
    spec_path = write(tmp_path / "s.json", FROZEN)
    code, _, err = call("run", spec_path, "--out", tmp_path / "out", "--quiet", "--no-figures", "--traceback")
    assert code == 1 and err.startswith("Traceback (most recent call last):\n") and err.endswith(f"\n{LINE}")
    assert 'engine/driver.py", line' in err and "in advance\n" in err
