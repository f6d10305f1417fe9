"""`RunState`, the record `Simulation.get_state` gives and `set_state` takes: all of a run that changes, so that
a run split at a saved state ends on the bits of the unbroken one (its margin too); a bad part is refused by
name, changing nothing."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
import pytest

import pinnedballs as pb

OLD_KEYS = ["velocities", "steps", "collisions", "rng_state", "scheduler_state"]
#: a float run's state also holds its closing margin (after the old keys: the dict it gave had none)
FLOAT_KEYS = [*OLD_KEYS, "margin"]


def run_sim(seed: int = 4) -> pb.Simulation:
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.5)
    sim = pb.Simulation(g, v, seed=seed)
    sim.run(steps=37)
    return sim


def test_a_state_is_a_record_and_set_state_refuses_a_dict_in_one_line():
    """1.0: the dict a state was until 2026-11 is gone (CHANGELOG): ``set_state`` names what it takes."""
    sim = run_sim()
    st = sim.get_state()
    assert not isinstance(st, Mapping) and [f.name for f in dataclasses.fields(st)][:5] == OLD_KEYS
    fields = {f.name: getattr(st, f.name) for f in dataclasses.fields(st)}
    with pytest.raises(TypeError, match=r"^state: must be a RunState \(what get_state gives\), got dict$"):
        sim.set_state(fields)
    sim.set_state(pb.RunState(**fields))  # a dict of its fields makes one
    assert sim.get_state().identical(st)


def test_a_state_stays_a_frozen_record():
    st = run_sim().get_state()
    assert dataclasses.is_dataclass(st)
    with pytest.raises(dataclasses.FrozenInstanceError):
        st.steps = 0
    assert st.replace(steps=5).steps == 5 and st.steps == 37


def test_an_exact_state_holds_its_exact_velocities_and_continues_bit_for_bit():
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.0)
    sim = pb.Simulation(g, v, seed=2, arithmetic="exact")
    sim.run(steps=20)
    saved = sim.get_state()
    assert saved.exact.shape == (16, 2, 2) and saved.margin is None and saved.certified is None
    other = pb.Simulation(g, v, seed=2, arithmetic="exact")
    other.set_state(saved)
    assert other.get_state().identical(saved)
    other.run(steps=30)
    sim.run(steps=30)
    assert other.get_state().identical(sim.get_state())


def test_the_margin_travels_with_the_state():
    """A run split at a saved state and continued elsewhere ends with the margin of the unbroken run."""
    unbroken, first = run_sim(), run_sim()
    unbroken.run(steps=400)
    saved = first.get_state()
    assert saved.margin.shape == (4,) and saved.margin.dtype == np.float64
    second = pb.Simulation(pb.FlatTorus(4, 4), first.velocities, seed=99)  # another stream, restored below
    second.set_state(saved)
    second.run(steps=400)
    assert second.get_state().identical(unbroken.get_state())
    assert second.closing_margin() == unbroken.closing_margin() and unbroken.closing_margin().smallest_collision > 0
    assert not saved.identical(saved.replace(margin=saved.margin + [0.0, 0.0, 1.0, 0.0]))


def test_a_state_without_a_margin_starts_it_afresh():
    """A state written before runs kept a margin: the margin then covers the picks from there on."""
    sim = run_sim()
    st = sim.get_state().replace(margin=None)
    sim.run(steps=100)
    sim.set_state(st)
    m = sim.closing_margin()
    assert (m.smallest_collision, m.largest_remnant, m.near_collisions, m.near_remnants) == (None, None, 0, 0)


def test_an_exact_state_has_no_margin():
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.0)
    sim = pb.Simulation(g, v, seed=2, arithmetic="exact")
    sim.run(steps=20)
    assert sim.get_state().margin is None


@pytest.mark.parametrize("margin, problem", [
    (np.zeros(3), "must be 4 floating-point numbers, got float64 (3,)"),
    (np.array([1, 0, 0, 0]), "must be 4 floating-point numbers, got int64 (4,)"),
    ([0.0, 0.0, 0.0, 0.0], "the smallest collision's closing speed must be > 0 (inf: none yet), got 0.0"),
    ([np.nan, 0.0, 0.0, 0.0], "the smallest collision's closing speed must be > 0 (inf: none yet), got nan"),
    ([1.0, -1.0, 0.0, 0.0], "the largest remnant's closing speed must be finite and >= 0 (0: none), got -1.0"),
    ([1.0, np.inf, 0.0, 0.0], "the largest remnant's closing speed must be finite and >= 0 (0: none), got inf"),
    ([1.0, 0.0, 0.5, 0.0], "the counts near the threshold must be whole numbers >= 0, got [0.5, 0.0]"),
    ([1.0, 0.0, 0.0, -2.0], "the counts near the threshold must be whole numbers >= 0, got [0.0, -2.0]"),
    ([np.inf, 0.0, 3.0, 0.0], "counts 3 collisions near the threshold but no collision"),
])
def test_a_bad_margin_is_refused_by_name_and_changes_nothing(margin, problem):
    sim = run_sim()
    before = sim.get_state()
    with pytest.raises(ValueError) as error:
        sim.set_state(before.replace(margin=np.asarray(margin), steps=before.steps + 5))
    assert str(error.value) == f"margin: {problem}"
    assert sim.get_state().identical(before)
