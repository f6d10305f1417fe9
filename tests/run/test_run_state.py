"""`RunState`, the record `Simulation.get_state` gives, still reads as the dict it was until 2026-11
(issue 26, item 9): old code keeps working for a release, each use warned as deprecated."""

from __future__ import annotations

import dataclasses

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


def test_a_state_reads_as_the_dict_it_was_with_a_deprecation_warning():
    st = run_sim().get_state()
    with pytest.warns(DeprecationWarning, match=r"^RunState is a record, no longer a dict: state\['velocities'\] is "
                                                r"deprecated and will be removed; use state.velocities$"):
        v = st["velocities"]
    assert v is st.velocities
    with pytest.warns(DeprecationWarning):
        assert list(st.keys()) == FLOAT_KEYS
    with pytest.warns(DeprecationWarning):
        assert list(st) == FLOAT_KEYS and len(st) == 6 and "steps" in st and "exact" not in st
    with pytest.warns(DeprecationWarning):
        old = dict(st, steps=99)
    assert sorted(old) == sorted(FLOAT_KEYS) and old["steps"] == 99 and old["collisions"] == st.collisions
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


def test_the_record_lives_below_the_simulation_and_keeps_its_old_names():
    """`RunState` and `mass_array` moved to `engine.state`; ``pb.RunState``, the simulation's module and
    the import scripts used (``from pinnedballs.run.simulation import RunState``, which the simulation
    left for `geometry.simulation`: a DeprecationWarning) name the same objects."""
    from pinnedballs.engine import state
    from pinnedballs.geometry import simulation

    with pytest.warns(DeprecationWarning, match="moved to pinnedballs.geometry.simulation"):
        from pinnedballs.run.simulation import RunState, mass_array
    assert pb.RunState is RunState is state.RunState is simulation.RunState and mass_array is state.mass_array
    with pytest.warns(DeprecationWarning):
        from pinnedballs.run.simulation import FreezeWarning, Simulation
    assert Simulation is pb.Simulation and FreezeWarning is simulation.FreezeWarning


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
