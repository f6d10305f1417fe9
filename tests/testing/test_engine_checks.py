"""The engines' conformance battery (`pinnedballs.testing.check_engine`): every registered engine passes it
(the GPU's under numba-cuda's simulator), and deliberately broken engines fail it, the check naming the
property that broke."""

from __future__ import annotations

import numpy as np
import pytest

from pinnedballs.engine import engines
from pinnedballs.engine.backends import LoopBackend
from pinnedballs.engine.builtin import Field, Sequential
from pinnedballs.engine.chain import COLLISIONS, NO_LIMIT, STEPS
from pinnedballs.engine.protocol import Refusal
from pinnedballs.testing import (
    ENGINE_CHECKS,
    check_engine,
    check_engine_agrees_with_reference,
    check_engine_collision_target,
    check_engine_refuses,
    check_engine_resume,
    check_engine_split_runs,
    check_engine_until_frozen,
    engine_checks_for,
)
from pinnedballs.testing.engine_checks import systems_for


def _marks(engine) -> list:
    """The GPU's engines need numba-cuda and run under its simulator (seconds): ``cuda`` and ``slow``."""
    return [pytest.mark.cuda, pytest.mark.slow] if "cuda" in engine.devices else []


@pytest.mark.parametrize("engine, check", [
    pytest.param(e, c, id=f"{e.name}-{c.__name__}", marks=_marks(e))
    for e in engines() for c in engine_checks_for(e)])
def test_every_registered_engine_passes_the_battery(engine, check):
    check(engine)


@pytest.mark.slow
@pytest.mark.parametrize("engine, check", [
    pytest.param(e, c, id=f"{e.name}-{c.__name__}") for e in engines()
    if any(s.name.startswith("half_plane_large") for s in systems_for(e, large=True))
    for c in engine_checks_for(e) if c is not check_engine_refuses])
def test_the_cpus_engines_pass_it_on_large_systems_too(engine, check):
    """Past `MIN_PARALLEL_CONTACTS` the threads run and the sequential loops read prefetched rows: seconds each."""
    check(engine, large=True)


def test_every_built_in_engine_but_the_replicas_has_the_whole_battery():
    for engine in engines():
        said = [c.__name__ for c in engine_checks_for(engine)]
        if engine.replicas:
            assert said == ["check_engine_replicas"], engine
        elif engine.name in ("sequential", "field"):  # the references (tests/reference.py checks sequential)
            assert said == [c.__name__ for c in ENGINE_CHECKS if c is not check_engine_agrees_with_reference]
        else:
            assert said == [c.__name__ for c in ENGINE_CHECKS], engine
        assert systems_for(engine) or engine.replicas, f"{engine.name} runs none of the battery's systems"


def test_the_threads_engine_is_checked_where_its_threads_run():
    """The battery's large half-planes are past `MIN_PARALLEL_CONTACTS`: the threaded chains run them."""
    from pinnedballs.engine.threads.regions import MIN_PARALLEL_CONTACTS

    large = [s for s in systems_for("threads", large=True) if s.name.startswith("half_plane_large")]
    assert len(large) == 2 and all(s.build()[0].n_contacts >= MIN_PARALLEL_CONTACTS for s in large)


# ---------------------------------------------------------------- broken engines, each caught by its check


class _Broken(Sequential):
    """The sequential engine with a backend that breaks one promise."""

    backend = LoopBackend

    def __init__(self, name: str, backend: type):
        self.name, self.backend = name, backend

    def build(self, model, state, listeners, device, options):
        return self.backend(model, state, listeners, device=device)


class _Overshoots(LoopBackend):
    """Ignores the collision target: runs its steps whatever the collisions."""

    def _run(self, max_steps, max_collisions, until_frozen):
        return super()._run(max_steps, NO_LIMIT, until_frozen)


class _Reseeds(LoopBackend):
    """Moves its stream on at every call after the first: a run split into calls is not one call."""

    def _run(self, max_steps, max_collisions, until_frozen):
        if self.state.steps:
            self.state.rng[0] += np.uint64(1)
        return super()._run(max_steps, max_collisions, until_frozen)


class _StopsLate(LoopBackend):
    """Runs a few steps past the freeze."""

    def _run(self, max_steps, max_collisions, until_frozen):
        taken = super()._run(max_steps, max_collisions, until_frozen)
        if until_frozen and taken < max_steps and self.is_frozen():
            self.state.counters[STEPS] += 3
            taken += 3
        return taken


class _ForgetsMargin(LoopBackend):
    """Keeps no closing margin: a state saved and restored is not the run's."""

    def saved(self) -> dict:
        return {"margin": None}


class _CountsTwice(LoopBackend):
    """Counts each collision twice."""

    def _run(self, max_steps, max_collisions, until_frozen):
        before = self.state.collisions
        taken = super()._run(max_steps, max_collisions, until_frozen)
        self.state.counters[COLLISIONS] += self.state.collisions - before
        return taken


@pytest.mark.parametrize("backend, check, words", [
    (_Overshoots, check_engine_collision_target, "check_engine_collision_target: engine 'broken' on "
                                                 "half_plane/xoshiro: run(collisions=1) stopped at"),
    (_Reseeds, check_engine_split_runs, "check_engine_split_runs: engine 'broken' on half_plane/xoshiro: a run "
                                        "split into calls ends otherwise than one call: velocities"),
    (_StopsLate, check_engine_until_frozen, "check_engine_until_frozen: engine 'broken' on half_plane/xoshiro: "
                                            "frozen True at"),
    (_ForgetsMargin, check_engine_resume, "check_engine_resume: engine 'broken' on half_plane/xoshiro: a run "
                                          "resumed from a saved state ends otherwise: closing margin"),
    (_CountsTwice, check_engine_agrees_with_reference, "check_engine_agrees_with_reference: engine 'broken' on "
                                                       "half_plane/xoshiro: not the bits of 'sequential': counts"),
])
def test_a_broken_engine_fails_the_check_of_the_promise_it_breaks(backend, check, words):
    with pytest.raises(AssertionError) as info:
        check(_Broken("broken", backend))
    assert str(info.value).startswith(words), str(info.value)
    with pytest.raises(AssertionError, match=r"^check_engine_\w+: engine 'broken' on "):
        check_engine(_Broken("broken", backend))  # the whole battery stops at it, or at a check before it


class _Greedy(Field):
    """Says it runs floats too, and cannot."""

    name, arithmetics = "greedy", ("float", "exact", "certified")

    def build(self, model, state, listeners, device, options):
        if options["arithmetic"] == "float":
            raise ValueError("no float chain here")
        return super().build(model, state, listeners, device, options)


class _ClaimsAll(Sequential):
    """Says it runs exact arithmetic, and runs floats."""

    name, arithmetics = "claims_all", ("float", "exact")


def test_an_engine_that_says_it_runs_what_it_cannot_is_caught():
    with pytest.raises(ValueError, match="no float chain here"):
        check_engine(_Greedy())
    with pytest.raises(AssertionError, match=r"^check_engine_\w+: engine 'claims_all' on half_plane/xoshiro/exact: "):
        check_engine(_ClaimsAll())


class _Mumbles(Sequential):
    """Refuses what it does not run in two lines and on no field."""

    name = "mumbles"

    def supports(self, model, arithmetic, device):
        return None if arithmetic == "float" else Refusal("", "not\nthis")


def test_a_refusal_that_is_not_one_line_on_a_field_is_caught():
    check_engine_refuses("sequential")
    with pytest.raises(AssertionError, match=r"^check_engine_refuses: engine 'mumbles' on half_plane/xoshiro/exact: "
                                             r"a refusal of more than one line"):
        check_engine_refuses(_Mumbles())


def test_a_users_engine_is_checked_registered_or_not_and_left_as_it_was():
    before = [e.name for e in engines()]
    check_engine(_Broken("plain_copy", LoopBackend))
    assert [e.name for e in engines()] == before
    with pytest.raises(TypeError, match="^engine: must be a pinnedballs.engine.Engine or a registered engine's"):
        check_engine(42)
    with pytest.raises(ValueError, match="another engine is registered as 'sequential'"):
        check_engine(_Broken("sequential", LoopBackend))
    assert np.array_equal([e.name for e in engines()], before)


@pytest.mark.cuda
def test_an_engine_of_replicas_that_forgets_a_replicas_stream_is_caught():
    """Replicas as state: a replica set that leaves each simulation's stream where it was fails
    `check_engine_replicas` (the simulations would go on from another pick)."""
    from pinnedballs.engine.builtin import GPUReplicas
    from pinnedballs.engine.gpu.replicas import ReplicaSet

    class Forgetful(ReplicaSet):
        def run(self, limits, chunk):
            words = [st.rng.copy() for st in self.states]
            super().run(limits, chunk)
            for st, w in zip(self.states, words):
                st.rng[:] = w

    class Broken(GPUReplicas):
        name = "forgetful"

        def build_replicas(self, backends, device, pattern=None):
            return Forgetful(backends, pattern)

    check_engine("gpu_replicas")
    with pytest.raises(AssertionError, match=r"^check_engine_replicas: engine 'forgetful' on half_plane/counter: "
                                             r"replica 0 \(.*\) ends otherwise than alone: rng_state"):
        check_engine(Broken())
