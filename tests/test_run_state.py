"""`RunState`, the record `Simulation.get_state` gives, still reads as the dict it was until 2026-11
(issue 26, item 9): old code keeps working for a release, each use warned as deprecated."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pinnedballs as pb

OLD_KEYS = ["velocities", "steps", "collisions", "rng_state", "scheduler_state"]


def run_sim(seed: int = 4) -> pb.Simulation:
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.5)
    sim = pb.Simulation(g, v, seed=seed)
    sim.run(steps=37)
    return sim


def test_a_state_reads_as_the_dict_it_was_with_a_deprecation_warning():
    st = run_sim().get_state()
    with pytest.warns(DeprecationWarning, match=r"^RunState is a record, no longer a dict: state\['velocities'\] is "
                                                r"deprecated and will be removed; use state.velocities$"):
        v = st["velocities"]
    assert v is st.velocities
    with pytest.warns(DeprecationWarning):
        assert list(st.keys()) == OLD_KEYS
    with pytest.warns(DeprecationWarning):
        assert list(st) == OLD_KEYS and len(st) == 5 and "steps" in st and "exact" not in st
    with pytest.warns(DeprecationWarning):
        old = dict(st, steps=99)
    assert sorted(old) == sorted(OLD_KEYS) and old["steps"] == 99 and old["collisions"] == st.collisions
    assert old["rng_state"] is st.rng_state
    with pytest.warns(DeprecationWarning), pytest.raises(KeyError):
        st["energy"]


def test_set_state_still_takes_a_dict_and_continues_bit_for_bit():
    a, b = run_sim(), run_sim()
    with pytest.warns(DeprecationWarning):
        saved = dict(a.get_state())  # what old code kept
    a.run(steps=50)
    with pytest.warns(DeprecationWarning, match=r"^Simulation.set_state: a dict is deprecated"):
        a.set_state(saved)
    assert a.get_state().identical(b.get_state())
    a.run(steps=50)
    b.run(steps=50)
    assert a.get_state().identical(b.get_state())


def test_a_dict_missing_a_field_or_with_a_stray_key_is_refused_by_name():
    sim = run_sim()
    st = sim.get_state()
    fields = {f.name: getattr(st, f.name) for f in dataclasses.fields(st)}
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match=r"^state: the dict lacks rng_state$"):
        sim.set_state({k: v for k, v in fields.items() if k != "rng_state"})
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match=r"^state: unknown key\(s\) energy "):
        sim.set_state({**fields, "energy": 1.0})
    assert sim.get_state().identical(st)


def test_a_state_stays_a_frozen_record():
    st = run_sim().get_state()
    assert dataclasses.is_dataclass(st)
    with pytest.raises(dataclasses.FrozenInstanceError):
        st.steps = 0
    assert st.replace(steps=5).steps == 5 and st.steps == 37


def test_an_exact_state_lists_its_exact_velocities():
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.0)
    sim = pb.Simulation(g, v, seed=2, arithmetic="exact")
    sim.run(steps=20)
    with pytest.warns(DeprecationWarning):
        old = dict(sim.get_state())
    assert list(old) == [*OLD_KEYS, "exact"]
    other = pb.Simulation(g, v, seed=2, arithmetic="exact")
    with pytest.warns(DeprecationWarning):
        other.set_state(old)
    assert other.get_state().identical(sim.get_state())
