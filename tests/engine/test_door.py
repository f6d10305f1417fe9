"""The engine's door (`engine.door`, `engine.builtin`, `engine.devices`): the registered engines say what they
run, one function chooses, refusals are structured, devices are objects, and a forced engine gives the bits
of the one the door would choose."""

from __future__ import annotations

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine import Engine, Refusal, Refused, choose, engines, register, unregister
from pinnedballs.engine.backends import LoopBackend
from pinnedballs.engine.devices import as_device

COUNTER = pb.UniformRandomPair(stream="counter")


def half(length=20, depth=10):
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, 10.0]
    return g, v


def model_of(**kwargs):
    g, v = half()
    return pb.Simulation(g, v, seed=1, **kwargs).engine.model


def test_the_built_in_engines_say_what_they_run():
    said = {e.name: (e.devices, e.arithmetics, e.replicas) for e in engines()}
    assert said == {"colored_sweep": (("cpu",), ("float",), False), "threads": (("cpu",), ("float",), False),
                    "sequential": (("cpu",), ("float",), False), "field": (("cpu",), ("exact", "certified"), False),
                    "gpu_certified": (("cuda",), ("certified",), False), "gpu": (("cuda",), ("float",), False),
                    "gpu_replicas": (("cuda",), ("float",), True)}


@pytest.mark.parametrize("kwargs, arithmetic, device, replicas, chosen", [
    ({}, "float", "cpu", False, "threads"),
    ({"scheduler": pb.UniformRandomPair(threads=1)}, "float", "cpu", False, "sequential"),
    ({}, "float", pb.CPU(threads=1), False, "sequential"),
    ({"scheduler": pb.ColoredSweep()}, "float", "cpu", False, "colored_sweep"),
    ({"scheduler": pb.RejectionFree()}, "float", "cpu", False, "sequential"),
    ({"scheduler": pb.Sweep()}, "float", "cpu", False, "sequential"),
    ({}, "exact", "cpu", False, "field"),
    ({}, "certified", "cpu", False, "field"),
    ({"scheduler": COUNTER}, "float", "cuda", False, "gpu"),
    ({"scheduler": COUNTER}, "certified", "cuda", False, "gpu_certified"),
    ({"scheduler": COUNTER}, "float", pb.CUDA(), True, "gpu_replicas"),
])
def test_one_function_chooses(kwargs, arithmetic, device, replicas, chosen):
    model = model_of(**kwargs)
    if device == pb.CPU(threads=1):  # the device's threads reach the model through the simulation
        g, v = half()
        model = pb.Simulation(g, v, seed=1, device=device).engine.model
    assert choose(model, arithmetic, device, replicas=replicas).name == chosen


def test_a_gpu_refuses_the_xoshiro_stream_in_a_structured_refusal():
    with pytest.raises(Refused) as info:
        choose(model_of(), "float", "cuda")
    refusal = info.value.refusal
    assert (refusal.field, refusal.needs) == ("device", (("scheduler", "counter"),))
    assert refusal.reason.startswith("'cuda' runs UniformRandomPair(stream='counter')")
    assert refusal.instead == "UniformRandomPair() runs on the CPU"
    assert str(info.value) == f"device: {refusal.reason}; {refusal.instead}"


def test_no_engine_for_an_arithmetic_on_a_device_says_where_it_runs():
    with pytest.raises(Refused, match=r"^device: 'cuda' runs float and certified arithmetic; exact arithmetic runs "
                                      r"on the CPU \(certified arithmetic proves its decisions"):
        choose(model_of(scheduler=COUNTER), "exact", "cuda")
    with pytest.raises(Refused, match=r"^device: 'cuda' runs an ensemble's replicas in float arithmetic; certified "
                                      r"arithmetic runs on the CPU, or one replica a call"):
        choose(model_of(scheduler=COUNTER), "certified", "cuda", replicas=True)


def test_a_forced_engine_refuses_what_it_does_not_run_naming_what_does():
    with pytest.raises(Refused, match=r"^engine: 'colored_sweep' runs a scheduler's own loop, and "
                                      r"UniformRandomPair\(\) has none; engine 'sequential' runs it$"):
        choose(model_of(), "float", "cpu", engine="colored_sweep")
    with pytest.raises(Refused, match=r"^engine: 'threads' runs UniformRandomPair's picks; Sweep\(\) picks "):
        choose(model_of(scheduler=pb.Sweep()), "float", "cpu", engine="threads")
    with pytest.raises(Refused, match=r"^arithmetic: engine 'sequential' runs float arithmetic, not exact$"):
        choose(model_of(), "exact", "cpu", engine="sequential")
    with pytest.raises(pb.FieldError, match=r"^engine: no engine 'warp' is registered \(registered: colored_sweep, "):
        choose(model_of(), "float", "cpu", engine="warp")
    with pytest.raises(pb.FieldError, match=r"^engine: 'gpu_replicas' runs replicas together, not one chain$"):
        choose(model_of(scheduler=COUNTER), "float", "cuda", engine="gpu_replicas")


def test_the_field_engine_refuses_a_rule_without_an_exact_form_in_the_arithmetics_words():
    class Sticky(pb.Restitution):
        def exact_restitution(self):
            return None

    with pytest.raises(Refused, match=r"^arithmetic: exact arithmetic runs the built-in rules \(Elastic, "
                                      r"Restitution\); Sticky\(0.5\) has no exact form$"):
        choose(model_of(rule=Sticky(0.5)), "exact", "cpu")


@pytest.mark.parametrize("scheduler, chosen", [(pb.UniformRandomPair(), "threads"),
                                                (pb.ColoredSweep(), "colored_sweep"), (pb.RandomSweep(), "sequential")])
def test_the_engine_the_door_chooses_gives_the_sequential_bits(scheduler, chosen):
    g, v = half(30, 15)
    runs = []
    for engine in (None, "sequential"):
        sim = pb.Simulation(g, v, scheduler=scheduler, seed=5, engine=engine)
        sim.run(steps=3000)
        sim.run_until_frozen(max_steps=10**6)
        runs.append(sim)
    door, sequential = runs
    assert (door.engine_name, sequential.engine_name) == (chosen, "sequential")
    assert (door.steps, door.collisions) == (sequential.steps, sequential.collisions)
    assert np.array_equal(door.velocities, sequential.velocities)


def test_devices_are_objects_and_their_names_still_work():
    assert as_device("cpu") == pb.CPU() and as_device("cuda") == pb.CUDA() and as_device(None) == pb.CPU()
    assert (str(pb.CPU(threads=4)), pb.CPU(threads=4).threads, pb.CUDA(device=1).device) == ("cpu", 4, 1)
    assert (pb.CPU().gpu, pb.CUDA().gpu) == (False, True)
    with pytest.raises(pb.FieldError, match=r"^device: must be 'cpu' or 'cuda', got 'tpu'$"):
        as_device("tpu")
    with pytest.raises(pb.FieldError, match=r"^threads: must be an integer in \[1, 65536\], got 0$"):
        pb.CPU(threads=0)
    g, v = half()
    sim = pb.Simulation(g, v, seed=1, device=pb.CPU(threads=1))
    assert sim.device == pb.CPU(threads=1) and sim.engine_name == "sequential" and sim.engine.model.threads == 1


class OneAtATime(Engine):
    """A user's engine: the sequential loops, under another name."""

    name, devices, arithmetics = "one_at_a_time", ("cpu",), ("float",)

    def build(self, model, state, listeners, device, options):
        return LoopBackend(model, state, listeners, device=device)


def test_a_users_engine_comes_in_through_the_door():
    engine = register(OneAtATime())
    try:
        assert engines()[-1] is engine
        with pytest.raises(ValueError, match="'one_at_a_time' is registered already"):
            register(OneAtATime())
        g, v = half()
        sim = pb.Simulation(g, v, seed=2, engine="one_at_a_time")
        sim.run_until_frozen(max_steps=10**6)
        ref = pb.Simulation(g, v, seed=2)
        ref.run_until_frozen(max_steps=10**6)
        assert sim.engine_name == "one_at_a_time" and np.array_equal(sim.velocities, ref.velocities)
    finally:
        unregister("one_at_a_time")
    assert "one_at_a_time" not in [e.name for e in engines()]
    with pytest.raises(TypeError, match="^engine: must be a pinnedballs.engine.Engine, got str$"):
        register("sequential")


def test_a_refusal_is_plain_data():
    r = Refusal("device", "no GPU here", "device 'cpu' runs it")
    assert r.message == "no GPU here; device 'cpu' runs it" and Refusal("engine", "no").message == "no"
    error = r.error()
    assert isinstance(error, pb.FieldError) and (error.field, error.refusal) == ("device", r)
