"""Run specs: a whole run described as data (JSON), validated by pydantic.

Each component is chosen by its ``"kind"`` (a discriminated union), unknown keys
are errors, and every spec has a ``build()`` that returns the runtime object, so
pydantic never reaches the compiled loop. `RunSpec.build` gives a `Simulation`.

Bad input raises `SpecError`, whose message starts with the field path::

    geometry.rows: must be even for a flat torus, got 5

Relative file paths resolve against the spec file's directory (`load_spec`),
or the working directory for a spec given as a dict.
"""

from __future__ import annotations

import contextlib
import difflib
import json
import math
import os
import re
import types
from pathlib import Path
from typing import Annotated, Any, Iterator, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import (AfterValidator, BaseModel, ConfigDict, Field, ValidationError, ValidationInfo,
                      field_validator, model_validator)

from .errors import FieldError, InputError
from .geometry import FCC, HCP, FlatTorus, Geometry, GraphGeometry, HalfPlane, HyperbolicPlane, Sphere
from .limits import check_memory, check_speeds, format_bytes
from .rules import CollisionRule, Elastic, Restitution
from .colored_sweep import ColoredSweep
from .rejection_free import RejectionFree
from .schedulers import RandomSweep, Scheduler, Sweep, UniformRandomPair
from .simulation import Simulation, mass_array

__all__ = [
    "InputError", "SpecError", "RunSpec", "load_spec", "parse_spec", "describe",
    "FlatTorusSpec", "HalfPlaneSpec", "GraphPositionsSpec", "SphereSpec", "HyperbolicPlaneSpec", "FCCSpec",
    "HCPSpec", "GeometrySpec",
    "SingleBallSpec", "GaussianSpec", "FromFileSpec", "InitialSpec",
    "ElasticSpec", "RestitutionSpec", "RuleSpec",
    "UniformRandomPairSpec", "SweepSpec", "RandomSweepSpec", "RejectionFreeSpec", "ColoredSweepSpec", "SchedulerSpec",
    "StopSpec", "SnapshotsSpec", "CheckpointSpec",
]

#: spawn key of the stream that draws random initial velocities (ASCII "init");
#: far above any replica index, so it never meets an ensemble's streams
INIT_STREAM_KEY = 0x696E6974


class SpecError(FieldError):
    """A spec field is wrong. ``path`` (also ``field``) is the dotted field path (``"geometry.rows"``)."""

    def __init__(self, path: str, problem: str):
        super().__init__(path, problem)

    @property
    def path(self) -> str:
        return self.field


# ---------------------------------------------------------------- building blocks


class _Spec(BaseModel):
    """Base of every spec: strict types, no unknown keys, no NaN, immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)

    @field_validator("*", mode="after")
    @classmethod
    def _text(cls, value: Any) -> Any:
        if isinstance(value, str) and not _is_text(value):
            raise ValueError(f"{_NOT_TEXT}: {_short_text(value)}")
        return value


_NOT_TEXT = "not valid UTF-8 text (a lone surrogate, or bytes that are not UTF-8)"


def _is_text(value: str) -> bool:
    """True if ``value`` encodes as UTF-8 (no lone surrogates), so files and HDF5 can hold it."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _resolve_path(value: str, info: ValidationInfo) -> str:
    """Make a path absolute against ``context["base_dir"]`` (else the working directory)."""
    if not value:
        raise ValueError("must be a file path, got an empty string")
    base = (info.context or {}).get("base_dir") or os.getcwd()
    return os.path.abspath(os.path.join(os.fspath(base), os.path.expanduser(value)))


FilePath = Annotated[str, AfterValidator(_resolve_path)]
Count = Annotated[int, Field(ge=0, le=np.iinfo(np.int64).max)]
Positive = Annotated[float, Field(gt=0)]


def _load_npy(path: str, field: str) -> np.ndarray:
    """The array in the ``.npy`` file at ``path`` as float64; a `SpecError` on ``field`` if unreadable.

    The header is checked before any data is read: a numeric dtype, and no more data
    than the file holds or the machine's memory can take (`check_memory`).
    """
    try:
        with open(path, "rb") as f:
            shape, dtype = _npy_header(f, path, field)
            held = os.fstat(f.fileno()).st_size - f.tell()
            needed = math.prod(shape) * dtype.itemsize
            if needed > held:
                raise SpecError(field, f"{path}: the header claims shape {shape} of {dtype} "
                                       f"({format_bytes(needed)}), but the file holds {format_bytes(held)} of data")
            check_memory(needed + 8 * math.prod(shape), field, f"the array in {path}")
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise SpecError(field, f"file not found: {path}") from None
    except (SpecError, FieldError) as exc:
        raise SpecError(field, exc.problem) from None
    except (OSError, ValueError, EOFError, MemoryError) as exc:
        raise SpecError(field, f"cannot read {path} as a .npy array ({' '.join(str(exc).split())})") from None
    return array.astype(np.float64)


def _npy_header(f, path: str, field: str) -> tuple[tuple[int, ...], np.dtype]:
    """``(shape, dtype)`` from the header of the open ``.npy`` file ``f``; the dtype must be numeric."""
    try:
        version = np.lib.format.read_magic(f)
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f".npy format version {version} is not supported for numeric arrays")
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(f)
    except Exception as exc:  # noqa: BLE001 - numpy parses the header with ast and tokenize: any error
        raise ValueError(f"{type(exc).__name__}: {exc}") from None
    if dtype.kind not in "iuf":
        raise SpecError(field, f"{path} must hold a numeric array, got {dtype}")
    return tuple(int(n) for n in shape), dtype


@contextlib.contextmanager
def engine_errors(path: str, fields: dict[str, str] | None = None) -> Iterator[None]:
    """Turn an error from the engine into a `SpecError`.

    ``fields`` maps the engine's argument names (a `FieldError`'s ``field``) to spec
    field paths; other errors are reported under ``path``, whole.
    """
    try:
        yield
    except SpecError:
        raise
    except FieldError as exc:
        if fields and exc.field in fields:
            raise SpecError(fields[exc.field], exc.problem) from None
        raise SpecError(path, str(exc)) from None
    except (ValueError, TypeError) as exc:
        raise SpecError(path, str(exc)) from None
    except MemoryError as exc:
        raise SpecError(path, f"needs more memory than this machine has ({' '.join(str(exc).split())})") from None


# ---------------------------------------------------------------- geometry


class FlatTorusSpec(_Spec):
    """A triangular lattice with periodic boundaries (`FlatTorus`)."""

    kind: Literal["flat_torus"] = "flat_torus"
    rows: int
    cols: int
    radius: Positive = 1.0

    def build(self) -> FlatTorus:
        with engine_errors("geometry", _fields("geometry", "rows", "cols", "radius")):
            return FlatTorus(self.rows, self.cols, self.radius)


class HalfPlaneSpec(_Spec):
    """A lattice rectangle with row 0 on the boundary: ``rows`` and ``cols``, or ``length`` and ``depth`` in radii."""

    kind: Literal["half_plane"] = "half_plane"
    rows: int | None = None
    cols: int | None = None
    length: float | None = None
    depth: float | None = None
    radius: Positive = 1.0
    orientation: Literal["along", "across"] = "along"

    @model_validator(mode="after")
    def _one_size(self) -> "HalfPlaneSpec":
        counts = self.rows is not None and self.cols is not None
        lengths = self.length is not None and self.depth is not None
        given = [k for k in ("rows", "cols", "length", "depth") if getattr(self, k) is not None]
        if counts == lengths or len(given) != 2:
            raise ValueError(f": give rows and cols, or length and depth (got {', '.join(given) or 'none'})")
        return self

    def build(self) -> HalfPlane:
        with engine_errors("geometry", _fields("geometry", "rows", "cols", "length", "depth", "radius", "orientation")):
            if self.rows is not None:
                return HalfPlane(self.rows, self.cols, self.radius, orientation=self.orientation)
            return HalfPlane.from_size(self.length, self.depth, self.radius, orientation=self.orientation)


class GraphPositionsSpec(_Spec):
    """Balls at the centres in a ``.npy`` file ``(n_balls, d)``; contacts at distance ``2 * radius``."""

    kind: Literal["graph_positions"] = "graph_positions"
    positions: FilePath
    radius: Positive = 1.0
    rtol: float = Field(1e-6, ge=0, lt=0.5)

    def build(self) -> GraphGeometry:
        try:
            return self.build_from(_load_npy(self.positions, "geometry.positions"))
        except SpecError as exc:
            raise _in_file(exc, self.positions) from None

    def build_from(self, positions: np.ndarray) -> GraphGeometry:
        """The geometry of ``positions`` ``(n_balls, d)`` (already loaded) with this spec's radius."""
        with engine_errors("geometry", _fields("geometry", "positions", "radius", "rtol")):
            return GraphGeometry.from_positions(positions, radius=self.radius, rtol=self.rtol)


class SphereSpec(_Spec):
    """Balls on the unit sphere: the geodesic grid of ``frequency``, or the ``points`` in a ``.npy`` file ``(n, 3)``."""

    kind: Literal["sphere"] = "sphere"
    frequency: int | None = None
    points: FilePath | None = None
    radius: Positive = 1.0

    @model_validator(mode="after")
    def _one_source(self) -> "SphereSpec":
        if (self.frequency is None) == (self.points is None):
            raise ValueError(": give exactly one of frequency or points")
        return self

    def build(self) -> Sphere:
        if self.points is None:
            with engine_errors("geometry", _fields("geometry", "frequency", "radius")):
                return Sphere.geodesic(self.frequency, self.radius)
        try:
            return self.build_from(_load_npy(self.points, "geometry.points"))
        except SpecError as exc:
            raise _in_file(exc, self.points) from None

    def build_from(self, positions: np.ndarray) -> Sphere:
        """The geometry at ``positions (n, 3)`` (already loaded; the stored ones for a recorded run)."""
        if self.points is None:
            return self.build()
        with engine_errors("geometry", {"points": "geometry.points", "radius": "geometry.radius"}):
            return Sphere.from_points(positions, self.radius)


class HyperbolicPlaneSpec(_Spec):
    """The {3,q} tiling of the hyperbolic plane out to ``layers`` rings (`HyperbolicPlane`)."""

    kind: Literal["hyperbolic_plane"] = "hyperbolic_plane"
    q: int = 7
    layers: int
    radius: Positive = 1.0

    def build(self) -> HyperbolicPlane:
        with engine_errors("geometry", _fields("geometry", "q", "layers", "radius")):
            return HyperbolicPlane(self.q, self.layers, self.radius)


class _PackingSpec(_Spec):
    nx: int
    ny: int
    nz: int
    periodic: bool | list[bool] = True
    radius: Positive = 1.0

    @field_validator("periodic", mode="before")
    @classmethod
    def _periodic(cls, value: Any) -> Any:
        if not (isinstance(value, bool) or (isinstance(value, list) and len(value) == 3
                                            and all(isinstance(v, bool) for v in value))):
            raise ValueError(f"must be true, false or a list of 3 of them for [x, y, z], got {value!r}")
        return value

    def build(self) -> Geometry:
        periodic = self.periodic if isinstance(self.periodic, bool) else tuple(self.periodic)
        with engine_errors("geometry", _fields("geometry", "nx", "ny", "nz", "periodic", "radius")):
            return self._geometry(self.nx, self.ny, self.nz, periodic=periodic, radius=self.radius)


class FCCSpec(_PackingSpec):
    """Face-centred cubic packing of ``nx x ny x nz`` cells (`FCC`); ``periodic`` a bool or [x, y, z]."""

    kind: Literal["fcc"] = "fcc"
    _geometry = FCC


class HCPSpec(_PackingSpec):
    """Hexagonal close packing of ``nx x ny x nz`` cells (`HCP`); ``periodic`` a bool or [x, y, z]."""

    kind: Literal["hcp"] = "hcp"
    _geometry = HCP


GeometrySpec = Annotated[Union[FlatTorusSpec, HalfPlaneSpec, GraphPositionsSpec, SphereSpec, HyperbolicPlaneSpec,
                               FCCSpec, HCPSpec], Field(discriminator="kind")]


def _fields(path: str, *names: str) -> dict[str, str]:
    return {name: f"{path}.{name}" for name in names}


def _in_file(exc: SpecError, path: str) -> SpecError:
    """``exc`` with the data file named, if its message does not name it yet."""
    return exc if path in exc.problem else SpecError(exc.path, f"{exc.problem} (in {path})")


# ---------------------------------------------------------------- initial velocities


class SingleBallSpec(_Spec):
    """One ball moves, all others rest: a ``velocity``, or a ``direction`` and a total ``energy``."""

    kind: Literal["single_ball"] = "single_ball"
    ball: int | Literal["boundary_center"] = 0
    velocity: list[float] | None = None
    direction: list[float] | None = None
    energy: Annotated[float, Field(ge=0)] | None = None

    @field_validator("ball", mode="before")
    @classmethod
    def _ball(cls, value: Any) -> Any:
        ok = (isinstance(value, int) and not isinstance(value, bool) and value >= 0) or value == "boundary_center"
        if not ok:
            raise ValueError(f'must be a ball index (an integer >= 0) or "boundary_center", got {value!r}')
        return value

    @model_validator(mode="after")
    def _one_way(self) -> "SingleBallSpec":
        if self.velocity is not None:
            if self.direction is not None or self.energy is not None:
                raise ValueError(": give velocity, or direction and energy, not both")
        elif self.direction is None or self.energy is None:
            missing = "direction" if self.direction is None else "energy"
            raise ValueError(f"{missing}: required (give velocity, or direction and energy)")
        return self

    def build(self, geometry: Geometry, masses: np.ndarray, seed: np.random.SeedSequence) -> np.ndarray:
        ball = self._index(geometry)
        v = np.zeros((geometry.n_balls, geometry.dim))
        if self.velocity is not None:
            v[ball] = self._vector("velocity", self.velocity, geometry.dim)
            return v
        d = self._vector("direction", self.direction, geometry.dim)
        norm = float(np.linalg.norm(d))
        if norm == 0:
            raise SpecError("initial.direction", "must not be the zero vector")
        with np.errstate(all="ignore"):
            v[ball] = np.sqrt(2.0 * self.energy / masses[ball]) * (d / norm)
        return _finite_speeds(v, masses)

    def _index(self, geometry: Geometry) -> int:
        if self.ball == "boundary_center":
            if geometry.boundary is None:
                raise SpecError("initial.ball",
                                f'"boundary_center" needs a geometry with a boundary, got {type(geometry).__name__}')
            return int(geometry.boundary_center())
        if self.ball >= geometry.n_balls:
            raise SpecError("initial.ball", f"must be < n_balls = {geometry.n_balls}, got {self.ball}")
        return self.ball

    @staticmethod
    def _vector(name: str, values: list[float], dim: int) -> np.ndarray:
        if len(values) != dim:
            raise SpecError(f"initial.{name}", f"must have dim = {dim} components, got {len(values)}")
        return np.array(values, dtype=np.float64)


class GaussianSpec(_Spec):
    """I.i.d. standard normal components from the seed, scaled to total ``energy``."""

    kind: Literal["gaussian"] = "gaussian"
    energy: Annotated[float, Field(ge=0)]
    zero_momentum: bool = False

    def build(self, geometry: Geometry, masses: np.ndarray, seed: np.random.SeedSequence) -> np.ndarray:
        stream = np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, INIT_STREAM_KEY))
        v = np.random.default_rng(stream).standard_normal((geometry.n_balls, geometry.dim))
        if self.zero_momentum:
            v -= (masses @ v) / masses.sum()
        energy = 0.5 * float(masses @ np.einsum("ij,ij->i", v, v))
        if energy == 0:
            raise SpecError("initial.zero_momentum", "leaves no velocity to scale (a single ball?)")
        with np.errstate(all="ignore"):
            return _finite_speeds(v * np.sqrt(self.energy / energy), masses)


def _finite_speeds(v: np.ndarray, masses: np.ndarray) -> np.ndarray:
    """``v``, or a `SpecError` on ``initial.energy`` when the speeds or the total energy
    ``sum m |v|^2 / 2`` overflow float64, now or in a collision (`check_speeds`)."""
    try:
        if not np.isfinite(v).all():
            raise FieldError("", "a speed is not finite")
        check_speeds(v, masses)
    except FieldError as exc:
        raise SpecError("initial.energy", f"too large for these masses: the speeds or the total energy "
                                          f"overflow float64 ({exc.problem})") from None
    return v


class FromFileSpec(_Spec):
    """Velocities read from a ``.npy`` file of shape ``(n_balls, dim)``."""

    kind: Literal["from_file"] = "from_file"
    path: FilePath

    def build(self, geometry: Geometry, masses: np.ndarray, seed: np.random.SeedSequence) -> np.ndarray:
        v = _load_npy(self.path, "initial.path")
        if v.shape != (geometry.n_balls, geometry.dim):
            raise SpecError("initial.path", f"{self.path} must have shape (n_balls, dim) = "
                                            f"{(geometry.n_balls, geometry.dim)}, got {v.shape}")
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if len(bad):
            raise SpecError("initial.path", f"{self.path}: ball {bad[0]} has a NaN or infinite component "
                                            f"({len(bad)} ball(s) in all)")
        return v


InitialSpec = Annotated[Union[SingleBallSpec, GaussianSpec, FromFileSpec], Field(discriminator="kind")]


# ---------------------------------------------------------------- rules and schedulers


class ElasticSpec(_Spec):
    """Totally elastic collisions (`Elastic`)."""

    kind: Literal["elastic"] = "elastic"

    def build(self) -> CollisionRule:
        return Elastic()


class RestitutionSpec(_Spec):
    """Inelastic collisions with coefficient of restitution ``r`` (`Restitution`)."""

    kind: Literal["restitution"] = "restitution"
    r: float

    def build(self) -> CollisionRule:
        with engine_errors("rule", {"r": "rule.r"}):
            return Restitution(self.r)


RuleSpec = Annotated[Union[ElasticSpec, RestitutionSpec], Field(discriminator="kind")]


class UniformRandomPairSpec(_Spec):
    """The paper's scheduler: one contact uniformly at random per step."""

    kind: Literal["uniform_random_pair"] = "uniform_random_pair"

    def build(self) -> Scheduler:
        return UniformRandomPair()


class SweepSpec(_Spec):
    """Every contact once per sweep, in a fixed order."""

    kind: Literal["sweep"] = "sweep"

    def build(self) -> Scheduler:
        return Sweep()


class RandomSweepSpec(_Spec):
    """Every contact once per sweep, in a fresh random order."""

    kind: Literal["random_sweep"] = "random_sweep"

    def build(self) -> Scheduler:
        return RandomSweep()


class RejectionFreeSpec(_Spec):
    """The paper's chain without its rejected picks (`RejectionFree`): same law, far fewer loop turns."""

    kind: Literal["rejection_free"] = "rejection_free"

    def build(self) -> Scheduler:
        return RejectionFree()


class ColoredSweepSpec(_Spec):
    """Colour classes of contacts sharing no ball in turn, each in parallel (`ColoredSweep`)."""

    kind: Literal["colored_sweep"] = "colored_sweep"
    shuffle: bool = False

    def build(self) -> Scheduler:
        return ColoredSweep(shuffle=self.shuffle)


SchedulerSpec = Annotated[Union[UniformRandomPairSpec, SweepSpec, RandomSweepSpec, RejectionFreeSpec, ColoredSweepSpec],
                          Field(discriminator="kind")]


# ---------------------------------------------------------------- running and output


def _only_one(model: BaseModel, names: tuple[str, ...], what: str) -> list[str]:
    given = [n for n in names if getattr(model, n) not in (None, False)]
    if len(given) != 1:
        raise ValueError(f": give exactly one of {what} (got {', '.join(given) or 'none'})")
    return given


class StopSpec(_Spec):
    """When the run ends: after ``steps``, at ``collisions`` in total, or when ``frozen`` (within ``max_steps``).

    A ``collisions`` target the system cannot reach because it froze first ends the
    run at the freeze.
    """

    steps: Count | None = None
    collisions: Count | None = None
    frozen: bool = False
    max_steps: Count | None = None

    @model_validator(mode="after")
    def _one_stop(self) -> "StopSpec":
        _only_one(self, ("steps", "collisions", "frozen"), "steps, collisions or frozen")
        if self.frozen and self.max_steps is None:
            raise ValueError("max_steps: required with frozen (a flat torus never freezes)")
        if not self.frozen and self.max_steps is not None:
            raise ValueError("max_steps: only allowed with frozen")
        return self

    @property
    def kind(self) -> str:
        """``"steps"``, ``"collisions"`` or ``"frozen"``."""
        return "steps" if self.steps is not None else "collisions" if self.collisions is not None else "frozen"


def _sorted_unique(values: list[int] | None) -> list[int] | None:
    return None if values is None else sorted(set(values))


class SnapshotsSpec(_Spec):
    """When to store the velocities: at listed step or collision counts, or every N of them."""

    at_steps: Annotated[list[Count], AfterValidator(_sorted_unique)] | None = None
    at_collisions: Annotated[list[Count], AfterValidator(_sorted_unique)] | None = None
    every_steps: Annotated[int, Field(ge=1)] | None = None
    every_collisions: Annotated[int, Field(ge=1)] | None = None

    @model_validator(mode="after")
    def _one_rule(self) -> "SnapshotsSpec":
        _only_one(self, ("at_steps", "at_collisions", "every_steps", "every_collisions"),
                  "at_steps, at_collisions, every_steps or every_collisions")
        return self

    @property
    def counter(self) -> str:
        """``"steps"`` or ``"collisions"``: the counter the snapshots are placed on."""
        return "steps" if self.at_steps is not None or self.every_steps is not None else "collisions"

    def target(self, n: int) -> int | None:
        """The count at which snapshot ``n`` (from 0) is taken, or None if there are fewer."""
        listed = self.at_steps if self.at_steps is not None else self.at_collisions
        if listed is not None:
            return listed[n] if n < len(listed) else None
        return (n + 1) * (self.every_steps or self.every_collisions)


class CheckpointSpec(_Spec):
    """How often a running simulation saves its state (also at every snapshot); 0 means after every chunk."""

    every_seconds: Annotated[float, Field(ge=0)] = 60.0


MassesField = Union[Positive, FilePath]


class RunSpec(_Spec):
    """A whole run: geometry, initial velocities, rule, scheduler, masses, seed, stop, snapshots."""

    geometry: GeometrySpec
    initial: InitialSpec
    rule: RuleSpec = ElasticSpec()
    scheduler: SchedulerSpec = UniformRandomPairSpec()
    masses: MassesField | None = None
    seed: Count = 0
    stop: StopSpec
    snapshots: SnapshotsSpec | None = None
    checkpoint: CheckpointSpec = CheckpointSpec()
    description: str = ""

    @field_validator("masses", mode="before")
    @classmethod
    def _masses(cls, value: Any) -> Any:
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, str))):
            raise ValueError(f"must be a number > 0 or the path of a .npy file, got {value!r}")
        return value

    @model_validator(mode="after")
    def _snapshots_before_stop(self) -> "RunSpec":
        s = self.snapshots
        if s is None:
            return self
        for name, listed, limit in (("at_steps", s.at_steps, self.stop.steps),
                                    ("at_collisions", s.at_collisions, self.stop.collisions),
                                    ("at_steps", s.at_steps, self.stop.max_steps)):
            if listed and limit is not None and listed[-1] > limit:
                raise ValueError(f"snapshots.{name}: {listed[-1]} is beyond the stop at {limit}")
        return self

    # ------------------------------------------------------------ building
    def build_masses(self, n_balls: int) -> float | np.ndarray | None:
        """The masses: None (all 1), a number, or ``(n_balls,)`` from the file."""
        if self.masses is None or isinstance(self.masses, float):
            return self.masses
        m = _load_npy(self.masses, "masses")
        if m.shape != (n_balls,):
            raise SpecError("masses", f"{self.masses} must have shape (n_balls,) = ({n_balls},), got {m.shape}")
        if not (np.isfinite(m).all() and (m > 0).all()):
            raise SpecError("masses", f"{self.masses}: must all be finite and > 0")
        return m

    def build(self, seed: int | np.random.SeedSequence | None = None) -> Simulation:
        """A fresh `Simulation` of this spec; ``seed`` (int or SeedSequence) overrides ``self.seed``."""
        if not (seed is None or isinstance(seed, np.random.SeedSequence) or (
                isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and 0 <= seed < 2**63)):
            raise SpecError("seed", f"must be an integer in [0, 2**63) or a numpy SeedSequence, "
                                    f"got {_short(seed)}")
        seq = seed if isinstance(seed, np.random.SeedSequence) else \
            np.random.SeedSequence(self.seed if seed is None else seed)
        geometry = self.geometry.build()
        masses = self.build_masses(geometry.n_balls)
        with engine_errors("", {"masses": "masses"}):
            masses_all = mass_array(masses, geometry.n_balls)
        velocities = self.initial.build(geometry, masses_all, seq)
        initial = "initial.path" if isinstance(self.initial, FromFileSpec) else "initial"
        try:
            with engine_errors("", {"velocities": initial, "masses": "masses", "geometry": "geometry",
                                    "rule": "rule", "scheduler": "scheduler", "seed": "seed"}):
                return Simulation(geometry, velocities, rule=self.rule.build(), scheduler=self.scheduler.build(),
                                  masses=masses, seed=seq)
        except SpecError as exc:
            files = {"geometry": getattr(self.geometry, "positions", None),
                     "initial.path": getattr(self.initial, "path", None),
                     "masses": self.masses if isinstance(self.masses, str) else None}
            raise _in_file(exc, files[exc.path]) if files.get(exc.path) else exc from None

    def to_json(self) -> str:
        """The spec as indented JSON, defaults filled in and paths absolute."""
        return self.model_dump_json(indent=2)


# ---------------------------------------------------------------- reading specs


def parse_spec(data: str | bytes | dict, base_dir: str | os.PathLike | None = None, source: str = "") -> RunSpec:
    """Validate a spec given as JSON text or a dict; relative paths resolve against ``base_dir``.

    Raises `SpecError` naming the first wrong field (``source`` prefixes the message).
    """
    context = {"base_dir": os.fspath(base_dir) if base_dir is not None else None}
    try:
        if isinstance(data, dict):
            _check_tree(data, source)
            return RunSpec.model_validate(data, context=context)
        if isinstance(data, bytes):
            try:
                data = data.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise SpecError(source, f"not UTF-8 text ({exc})") from None
        try:
            parsed = json.loads(data, parse_int=_parse_int)
        except json.JSONDecodeError as exc:
            raise SpecError(source, f"not valid JSON: {exc}") from None
        except RecursionError:
            raise SpecError(source, f"not a spec: JSON nested more than {_MAX_DEPTH} levels deep") from None
        if not isinstance(parsed, dict):
            raise SpecError(source, f"a spec must be a JSON object, got {type(parsed).__name__}")
        _check_tree(parsed, source)
        return RunSpec.model_validate(parsed, context=context)
    except ValidationError as exc:
        error = _first_error(exc)
        raise SpecError(_join(source, error.path) if source else error.path, error.problem) from None


#: bytes of Python objects per character of JSON, from above (``[1,2,...]``: 36 bytes per 2 characters)
_JSON_BYTES_PER_CHAR = 32
#: deepest nesting of objects and arrays a spec may have (a spec needs 3 or 4)
_MAX_DEPTH = 32


class _LongInt(str):
    """The digits of a JSON integer too long for any spec field (kept as text, never converted)."""


def _parse_int(digits: str) -> int | _LongInt:
    return int(digits) if len(digits.lstrip("-")) <= 19 else _LongInt(digits)


def _check_tree(data: Any, source: str) -> None:
    """Refuse, naming the field, what no spec field can hold: nesting deeper than `_MAX_DEPTH`,
    integers outside int64, and strings that are not UTF-8 text (lone surrogates).

    Walks ``data`` (parsed JSON or a dict) without recursion, fields in document order.
    """
    stack = [(data, "", 0)]
    while stack:
        value, path, depth = stack.pop()
        where = path or source
        if depth > _MAX_DEPTH:
            raise SpecError(where, f"nested more than {_MAX_DEPTH} levels deep")
        if isinstance(value, dict):
            items = []
            for key, item in value.items():
                if isinstance(key, str) and not _is_text(key):
                    raise SpecError(where, f"a key is {_NOT_TEXT}: {_short_text(key)}")
                items.append((item, _dot(path, str(key)), depth + 1))
            stack.extend(reversed(items))
        elif isinstance(value, (list, tuple)):
            stack.extend(reversed([(item, f"{path}[{i}]", depth + 1) for i, item in enumerate(value)]))
        elif isinstance(value, _LongInt) or (
                isinstance(value, int) and not isinstance(value, bool) and not -2**63 <= value < 2**63):
            digits = len(str(value).lstrip("-")) if isinstance(value, str) or value.bit_length() < 10**4 else "many"
            raise SpecError(where, f"an integer of {digits} digits is out of range "
                                   f"(a spec field holds at most 2**63 - 1)")
        elif isinstance(value, str) and not _is_text(value):
            raise SpecError(where, f"{_NOT_TEXT}: {_short_text(value)}")


def load_spec(path: str | os.PathLike) -> RunSpec:
    """Read and validate the JSON spec at ``path``; relative paths in it resolve against its directory."""
    path = Path(path)
    try:
        check_memory(_JSON_BYTES_PER_CHAR * path.stat().st_size, str(path), "reading this spec file")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(str(path), "no such spec file") from None
    except FieldError as exc:
        raise SpecError(str(path), exc.problem) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), f"cannot read the spec file ({exc})") from None
    try:
        return parse_spec(text, base_dir=path.resolve().parent)
    except SpecError as exc:
        if exc.path:
            raise
        raise SpecError(str(path), exc.problem) from None


def _join(a: str, b: str) -> str:
    return f"{a}: {b}" if a and b else a or b


# ---------------------------------------------------------------- error messages

_PRIORITY = {"extra_forbidden": 0, "union_tag_invalid": 1, "union_tag_not_found": 1}


def _first_error(exc: ValidationError) -> SpecError:
    """The most telling error of a pydantic `ValidationError`, as a `SpecError` with a dotted path."""
    e = sorted(exc.errors(), key=lambda e: _PRIORITY.get(e["type"], 2))[0]
    loc = tuple(e["loc"])
    if e["type"] == "extra_forbidden":
        path, model, _ = _walk(loc[:-1])
        key, valid = str(loc[-1]), list(model.model_fields) if model else []
        return SpecError(_dot(path, key), f"unknown key{_suggest(key, valid)} (valid keys: {', '.join(valid)})")
    path, _, tags = _walk(loc)
    if e["type"] == "union_tag_not_found":
        return SpecError(_dot(path, "kind"), f"missing; one of: {', '.join(tags)}")
    if e["type"] == "union_tag_invalid":
        tag = str(e["ctx"]["tag"])
        return SpecError(_dot(path, "kind"), f"unknown kind {tag!r}{_suggest(tag, list(tags))} "
                                             f"(valid kinds: {', '.join(tags)})")
    message = e["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
        head, sep, rest = message.partition(": ")
        if sep and re.fullmatch(r"[\w.]*", head):  # a model validator naming its own field
            return SpecError(_dot(path, head), rest)
        return SpecError(path, message)
    if e["type"] == "missing":
        return SpecError(path, "missing (required)")
    return SpecError(path, f"{message[0].lower()}{message[1:]}, got {_short(e.get('input'))}")


def _walk(loc: tuple) -> tuple[str, type[BaseModel] | None, dict[str, type[BaseModel]]]:
    """Follow ``loc`` from `RunSpec`: the dotted path (union tags and member labels dropped),
    the model reached, and the ``kind``-tagged models if a union was reached."""
    parts: list[str] = []
    model: type[BaseModel] | None = RunSpec
    tags: dict[str, type[BaseModel]] = {}
    for element in loc:
        if isinstance(element, int):
            if parts:
                parts[-1] += f"[{element}]"
        elif model is not None and element in model.model_fields:
            parts.append(element)
            model, tags = _models_of(model.model_fields[element].annotation)
        elif element in tags:
            model, tags = tags[element], {}
    return ".".join(parts), model, tags


def _models_of(annotation: Any) -> tuple[type[BaseModel] | None, dict[str, type[BaseModel]]]:
    """The single model behind ``annotation``, or its ``kind``-tagged members."""
    members = [a for a in _flatten(annotation) if isinstance(a, type) and issubclass(a, BaseModel)]
    tags = {m.model_fields["kind"].default: m for m in members if "kind" in m.model_fields}
    if len(members) == 1 and not tags:
        return members[0], {}
    return None, tags


def _flatten(annotation: Any) -> list[Any]:
    """The members of a (possibly Annotated or Optional) union annotation."""
    if get_origin(annotation) is Annotated:
        return _flatten(get_args(annotation)[0])
    if get_origin(annotation) in (Union, types.UnionType):
        return [m for a in get_args(annotation) for m in _flatten(a)]
    return [annotation]


def _suggest(word: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else ""


def _dot(path: str, name: str) -> str:
    return f"{path}.{name}" if path and name else path or name


def _short_text(value: Any) -> str:
    """``ascii(value)``, cut to 60 characters: shows lone surrogates as escapes."""
    text = ascii(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# ---------------------------------------------------------------- summaries


def describe(spec: RunSpec, sim: Simulation) -> str:
    """One line saying what ``spec`` runs: geometry, sizes, rule, scheduler, stop, snapshots, seed."""
    g = spec.geometry
    shape = _shape(g, sim.geometry)
    stop = spec.stop
    until = {"steps": lambda: f"{stop.steps:,} steps", "collisions": lambda: f"{stop.collisions:,} collisions",
             "frozen": lambda: f"frozen (max {stop.max_steps:,} steps)"}[stop.kind]()
    n_snap = _count_snapshots(spec)
    rule = spec.rule.kind + (f"(r={spec.rule.r})" if spec.rule.kind == "restitution" else "")
    return (f"{g.kind} {shape}: {sim.geometry.n_balls} balls, {sim.geometry.n_contacts} contacts, dim "
            f"{sim.geometry.dim}; {spec.initial.kind}, energy {sim.energy():.6g}; {rule}, {spec.scheduler.kind}; "
            f"stop at {until}; {n_snap} snapshot(s); seed {spec.seed}")


def _shape(g: BaseModel, geometry: Geometry) -> str:
    """``rows x cols`` or ``nx x ny x nz`` when the geometry has them, else the spec's own arguments."""
    if hasattr(geometry, "rows") and hasattr(geometry, "cols"):
        return f"{geometry.rows}x{geometry.cols}"
    if isinstance(getattr(geometry, "shape", None), tuple):
        return "x".join(str(n) for n in geometry.shape)
    fields = g.model_dump(exclude={"kind", "radius", "rtol"}, exclude_none=True)
    return " ".join(Path(v).name if isinstance(v, str) else f"{k}={v}" for k, v in fields.items())


def _count_snapshots(spec: RunSpec) -> str:
    s = spec.snapshots
    if s is None:
        return "no"
    listed = s.at_steps if s.at_steps is not None else s.at_collisions
    if listed is not None:
        return str(len(listed))
    every = s.every_steps or s.every_collisions
    limit = spec.stop.steps if s.every_steps else spec.stop.collisions
    return str(limit // every) if limit is not None else f"every {every:,} {s.counter}"
