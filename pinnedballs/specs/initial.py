"""Initial-velocity specs: ``build(geometry, masses (n,), seed) -> velocities (n, dim)``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..util.errors import FieldError
from ..util.limits import check_speeds
from ..util.sums import kinetic_energy, momentum
from .base import FilePath, _load_npy, _Spec
from .errors import SpecError
from .python import PythonInitialSpec

if TYPE_CHECKING:
    from ..geometry.base import Geometry

__all__ = ["SingleBallSpec", "GaussianSpec", "FromFileSpec", "InitialSpec", "INIT_STREAM_KEY"]

#: spawn key of the stream that draws random initial velocities (ASCII "init");
#: far above any replica index, so it never meets an ensemble's streams
INIT_STREAM_KEY = 0x696E6974




class SingleBallSpec(_Spec):
    """One ball moves, all others rest: a ``velocity``, or a ``direction`` and a total ``energy``.

    ``direction: "inward"`` is minus the geometry's ``boundary.outward`` at the ball (in its own
    frame), for a geometry with a boundary.
    """

    kind: Literal["single_ball"] = "single_ball"
    ball: int | Literal["boundary_center"] = 0
    velocity: list[float] | None = None
    direction: list[float] | Literal["inward"] | None = None
    energy: Annotated[float, Field(ge=0)] | None = None

    @field_validator("ball", mode="before")
    @classmethod
    def _ball(cls, value: Any) -> Any:
        ok = (isinstance(value, int) and not isinstance(value, bool) and value >= 0) or value == "boundary_center"
        if not ok:
            raise ValueError(f'must be a ball index (an integer >= 0) or "boundary_center", got {value!r}')
        return value

    @model_validator(mode="after")
    def _one_way(self) -> SingleBallSpec:
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
        d = self._inward(geometry, ball) if self.direction == "inward" else \
            self._vector("direction", self.direction, geometry.dim)
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
    def _inward(geometry: Geometry, ball: int) -> np.ndarray:
        """``(dim,)`` minus ``boundary.outward[ball]``."""
        if geometry.boundary is None:
            raise SpecError("initial.direction",
                            f'"inward" needs a geometry with a boundary, got {type(geometry).__name__}')
        return -np.asarray(geometry.boundary.outward[ball], dtype=np.float64)

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
            v -= momentum(masses, v) / masses.sum()
        energy = kinetic_energy(masses, v)
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


InitialSpec = Annotated[SingleBallSpec | GaussianSpec | FromFileSpec | PythonInitialSpec, Field(discriminator="kind")]
