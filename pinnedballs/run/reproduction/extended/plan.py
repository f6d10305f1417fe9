"""What the extended studies run: `ExtendedPlan` (sizes, replicas, seed), its full and quick
scales, the order of the studies and the figures they write."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from ....engine.field.fixed import PRECISION
from ....schedulers.simple import UniformRandomPair
from ....util.errors import InputError
from ... import ensemble as ens

#: the streams the scaling study's `UniformRandomPair` may draw from (`ExtendedPlan.stream`)
STREAMS = UniformRandomPair.STREAMS

#: the studies in the order they run; keys of ``results.json["extended"]``
STUDIES = ("scaling", "torus_law", "sphere", "hyperbolic", "fcc_half_space", "orders")


@dataclass(frozen=True)
class ExtendedPlan:
    """What the extended studies run. Sizes are chosen for the time budget (2 cores)."""

    #: half-plane ``(length, depth, replicas)``, by size
    scaling: tuple[tuple[float, float, int], ...] = (
        (10, 5, 16), (30, 15, 16), (60, 30, 16), (100, 50, 16), (200, 100, 8), (300, 150, 8), (500, 250, 8),
        (1000, 500, 8), (2000, 1000, 2))
    #: sizes up to this many balls are also counted exactly (certified arithmetic on the same seeds: every
    #: decision proven, docs/collisions.md) and, unless `resolution_max_balls` says otherwise, by the float
    #: chain at each of `resolutions` (the model N_e)
    exact_max_balls: int = 150_000
    #: sizes up to this many balls are counted by the float chain at each of `resolutions` (N_e); None: up to
    #: `exact_max_balls`, like the exact count
    resolution_max_balls: int | None = None
    #: the exact count's certified arithmetic narrows to this many bits once the first wave has passed
    #: (`Simulation`'s ``late_precision``; None: the default precision throughout)
    exact_late_precision: int | None = 256
    #: with ``device="cuda"``, sizes of at least this many balls are counted exactly on the GPU, one replica at a
    #: time (`engine.gpu.certified`); smaller ones on the CPU's workers, in parallel (a small system's picks leave
    #: a GPU idle: its rounds hold few picks each)
    exact_gpu_min_balls: int = 100_000
    resolutions: tuple[float, ...] = (1e-6, 1e-9, 1e-12)   #: criteria e of the N_e counts
    torus_sides: tuple[int, ...] = (16, 38, 76, 128)   #: square tori ``side x side``
    torus_times: tuple[int, ...] = (100, 300, 1000, 3000, 10000, 30000)   #: steps per ball
    torus_replicas: int = 24
    sphere_frequency: int = 12   #: 10 f^2 + 2 balls (12: 1,442, next to the 38x38 torus's 1,444)
    hyperbolic_layers: tuple[int, ...] = (2, 3, 4, 5, 6)
    hyperbolic_replicas: int = 16
    fcc: tuple[tuple[int, int, int], ...] = ((6, 6, 3), (10, 10, 5), (14, 14, 7))   #: open FCC blocks
    fcc_replicas: int = 8
    orders_replicas: int = 1000   #: random orders per configuration
    orders_max_states: int = 10**6
    energy: float = 100.0
    seed: int = 0
    max_steps: int = 10**11
    #: the scaling study's `UniformRandomPair` stream: "xoshiro" (every published seed's bits, the CPU) or
    #: "counter" (Philox: the same law, other picks; what a GPU runs, with the CPU's bits)
    stream: str = "xoshiro"

    def resolution_limit(self) -> int:
        """The most balls a size may have to be counted at each of `resolutions` (N_e)."""
        return self.exact_max_balls if self.resolution_max_balls is None else self.resolution_max_balls


EXTENDED_FULL = ExtendedPlan()
EXTENDED_QUICK = ExtendedPlan(
    scaling=((10, 5, 8), (20, 10, 8), (30, 15, 8), (60, 30, 8), (100, 50, 8), (200, 100, 8), (300, 150, 4)),
    torus_sides=(16, 38, 76), torus_times=(100, 300, 1000, 3000, 10000), torus_replicas=16,
    hyperbolic_layers=(2, 3, 4, 5, 6), hyperbolic_replicas=8, fcc=((6, 6, 3), (8, 8, 4), (10, 10, 5)),
    fcc_replicas=4, orders_replicas=400, orders_max_states=10**5)
#: the full plan on a GPU (``reproduce --extended --device cuda``): the scaling study on the counter stream, up to
#: 4000x2000 (2,310,000 balls, float and N_e; the exact count, certified arithmetic on the CPU, stops where the
#: full plan's does)
EXTENDED_GPU = replace(
    EXTENDED_FULL, scaling=(*EXTENDED_FULL.scaling[:-1], (2000, 1000, 8), (4000, 2000, 4)),
    resolution_max_balls=2_400_000, stream="counter")

Ensemble = Callable[..., ens.EnsembleResult]


def check_extended_plan(plan: ExtendedPlan) -> None:
    """`InputError` naming the field of a plan that cannot run."""
    if not _whole(plan.exact_max_balls):
        raise InputError(f"exact_max_balls: must be a whole number of balls >= 0, got {plan.exact_max_balls!r}")
    if not _whole(plan.exact_gpu_min_balls):
        raise InputError(f"exact_gpu_min_balls: must be a whole number of balls >= 0, got {plan.exact_gpu_min_balls!r}")
    if plan.resolution_max_balls is not None and not _whole(plan.resolution_max_balls):
        raise InputError(f"resolution_max_balls: must be a whole number of balls >= 0 or None (up to exact_max_balls), "
                         f"got {plan.resolution_max_balls!r}")
    if plan.stream not in STREAMS:
        raise InputError(f"stream: the scaling study's UniformRandomPair stream must be "
                         f"{' or '.join(map(repr, STREAMS))}, got {plan.stream!r}")
    late = plan.exact_late_precision
    if late is not None and (isinstance(late, bool) or not isinstance(late, int) or not 64 <= late <= PRECISION):
        raise InputError(f"exact_late_precision: must be a whole number of bits in [64, {PRECISION}] or None, "
                         f"got {late!r}")
    for e in plan.resolutions:
        if isinstance(e, bool) or not isinstance(e, (int, float)) or not 0.0 < e < 1.0:
            raise InputError(f"resolutions: each must be a criterion e in (0, 1), got {e!r}")
    for name in ("torus_replicas", "hyperbolic_replicas", "fcc_replicas", "orders_replicas", "orders_max_states"):
        ens.check_count(name, getattr(plan, name))
    if len(plan.scaling) < 2 or any(len(s) != 3 or s[2] < 2 for s in plan.scaling):
        raise InputError(f"scaling: give at least two (length, depth, replicas >= 2), got {plan.scaling}")
    if not plan.torus_sides or not plan.torus_times or list(plan.torus_times) != sorted(set(plan.torus_times)):
        raise InputError(f"torus_times: must be increasing steps per ball, got {plan.torus_times}")
    for name in ("hyperbolic_layers", "fcc"):
        if not getattr(plan, name):
            raise InputError(f"{name}: give at least one size")


def _whole(value) -> bool:
    """Whether ``value`` is an int >= 0 (not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def expected_extended_figures() -> list[str]:
    """The PNG names the extended studies write."""
    return ["extended_scaling.png", "extended_scaling_profiles.png", "extended_torus_law.png",
            "extended_sphere_vs_torus.png", "extended_hyperbolic.png", "extended_fcc_half_space.png",
            "extended_orders.png"]


def _plan_dict(plan: ExtendedPlan) -> dict:
    import dataclasses

    return dataclasses.asdict(plan)
