"""Which bits an ``"auto"`` certified run starts at and starts again at (`engine.field.arithmetic`)."""

from __future__ import annotations

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.field.arithmetic import MAX_PRECISION, auto_failure, auto_precisions, next_precisions
from pinnedballs.engine.field.fixed import PRECISION, UncertifiedDecision
from pinnedballs.util.errors import FieldError


def inward(g) -> np.ndarray:
    """The paper's start: the boundary-centre ball moving inward, energy 100."""
    v = np.zeros((g.n_balls, g.dim))
    b = g.boundary_center()
    v[b] = -np.sqrt(200.0) * g.boundary.outward[b]
    return v


def failure(precision: int, late: int = 0, narrowed: bool = False) -> UncertifiedDecision:
    """An `UncertifiedDecision` of a chain that ran at ``precision`` bits (``late`` behind the first wave)."""
    f = UncertifiedDecision("arithmetic", "certified arithmetic cannot decide contact 3 (balls 1, 2) at step 7: "
                                          "its closing speed 0 is within the error bound 1e-30; use more bits")
    f.decision = f.problem.split(";")[0]
    f.precision, f.late_precision, f.narrowed = precision, late, narrowed
    return f


def test_an_auto_run_starts_at_the_default_narrowing_only_to_fewer_bits():
    assert auto_precisions(None) == (PRECISION, None)
    assert auto_precisions(256) == (PRECISION, 256)
    assert auto_precisions(PRECISION) == (PRECISION, None)  # not fewer: nothing to narrow to
    assert auto_precisions(2048) == (PRECISION, None)


@pytest.mark.parametrize("ran, late, narrowed, spec_late, then", [
    (768, 0, False, None, (1152, None)),        # the front needed more: 1.5 times, whole limbs
    (64, 0, False, None, (128, None)),          # 96 rounded up to 2 limbs
    (768, 256, False, 256, (1152, 256)),        # the late bits stay
    (768, 0, False, 1024, (1152, 1024)),        # the spec's late bits, once fewer than the precision
    (768, 0, False, 2048, (1152, None)),
    (1152, 256, True, 256, (1152, 384)),        # failed behind the front: more bits there
    (1152, 768, True, 256, (1152, None)),       # late bits reaching the precision: the precision throughout
    (3072, 0, False, None, (MAX_PRECISION, None)),  # capped
])
def test_the_next_attempt_grows_the_bits_where_the_decision_failed(ran, late, narrowed, spec_late, then):
    assert next_precisions(failure(ran, late, narrowed), spec_late) == then


def test_no_next_attempt_where_more_bits_cannot_help():
    assert next_precisions(failure(MAX_PRECISION)) is None
    assert next_precisions(failure(0)) is None  # not a certified chain's failure (bits unknown)


def test_the_line_an_auto_run_says_names_the_bits_before_and_after():
    line = auto_failure(failure(1152, 256, True), (1152, 384))
    assert line == ("at 256 bits behind the first wave, certified arithmetic cannot decide contact 3 (balls 1, 2) at "
                    "step 7: its closing speed 0 is within the error bound 1e-30; starting again at 1152 bits "
                    "(384 behind the first wave)")
    assert auto_failure(failure(64), (128, None)).startswith("at 64 bits, certified arithmetic")


def test_a_failing_chain_reports_the_bits_it_ran_at(monkeypatch):
    """The paper's 30x15 half-plane at 64 bits cannot decide a pick at the front; its failure says so."""
    g = pb.HalfPlane.from_size(30, 15)
    sim = pb.Simulation(g, inward(g), seed=1, arithmetic="certified", precision=64)
    with pytest.raises(UncertifiedDecision) as info:
        sim.run_until_frozen(max_steps=10**6)
    assert (info.value.precision, info.value.late_precision, info.value.narrowed) == (64, 0, False)
    assert str(info.value) == (f"arithmetic: {info.value.decision}; use arithmetic=\"exact\" or a larger precision "
                               "(now 64 bits)")
    assert next_precisions(info.value) == (128, None)


def test_a_simulation_takes_bits_not_auto():
    g = pb.HalfPlane.from_size(10, 5)
    with pytest.raises(FieldError, match=r'^precision: "auto" is a spec\'s \(pinnedballs run, run_spec, run_ensemble'):
        pb.Simulation(g, inward(g), seed=1, arithmetic="certified", precision="auto")

