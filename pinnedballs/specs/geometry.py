"""Geometry specs: one per kind, each with a ``build()`` that returns the `Geometry` (imported there: a spec is
validated, and its schema written, without the geometries' modules)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from .base import FilePath, Positive, _fields, _in_file, _load_npy, _Spec, engine_errors
from .errors import SpecError
from .python import IMPORT_FACTORIES, PythonGeometrySpec

if TYPE_CHECKING:
    from ..geometry import FlatTorus, Geometry, GraphGeometry, HalfPlane, HyperbolicPlane, Sphere

__all__ = ["FlatTorusSpec", "HalfPlaneSpec", "GraphPositionsSpec", "SphereSpec", "HyperbolicPlaneSpec", "FCCSpec",
           "HCPSpec", "GeometrySpec", "geometry_from_stored", "parse_geometry"]



class FlatTorusSpec(_Spec):
    """A triangular lattice with periodic boundaries (`FlatTorus`)."""

    kind: Literal["flat_torus"] = "flat_torus"
    rows: int
    cols: int
    radius: Positive = 1.0

    def build(self) -> FlatTorus:
        from ..geometry.lattices import FlatTorus

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
    def _one_size(self) -> HalfPlaneSpec:
        counts = self.rows is not None and self.cols is not None
        lengths = self.length is not None and self.depth is not None
        given = [k for k in ("rows", "cols", "length", "depth") if getattr(self, k) is not None]
        if counts == lengths or len(given) != 2:
            raise ValueError(f": give rows and cols, or length and depth (got {', '.join(given) or 'none'})")
        return self

    def build(self) -> HalfPlane:
        from ..geometry.lattices import HalfPlane

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
        from ..geometry.graph import GraphGeometry

        with engine_errors("geometry", _fields("geometry", "positions", "radius", "rtol")):
            return GraphGeometry.from_positions(positions, radius=self.radius, rtol=self.rtol)


class SphereSpec(_Spec):
    """Balls on the unit sphere: the geodesic grid of ``frequency``, or the ``points`` in a ``.npy`` file ``(n, 3)``."""

    kind: Literal["sphere"] = "sphere"
    frequency: int | None = None
    points: FilePath | None = None
    radius: Positive = 1.0

    @model_validator(mode="after")
    def _one_source(self) -> SphereSpec:
        if (self.frequency is None) == (self.points is None):
            raise ValueError(": give exactly one of frequency or points")
        return self

    def build(self) -> Sphere:
        from ..geometry.sphere import Sphere

        if self.points is None:
            with engine_errors("geometry", _fields("geometry", "frequency", "radius")):
                return Sphere.geodesic(self.frequency, self.radius)
        try:
            return self.build_from(_load_npy(self.points, "geometry.points"))
        except SpecError as exc:
            raise _in_file(exc, self.points) from None

    def build_from(self, positions: np.ndarray) -> Sphere:
        """The geometry at ``positions (n, 3)`` (already loaded; the stored ones for a recorded run)."""
        from ..geometry.sphere import Sphere

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
        from ..geometry.hyperbolic import HyperbolicPlane

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
        from ..geometry import packings

        periodic = self.periodic if isinstance(self.periodic, bool) else tuple(self.periodic)
        with engine_errors("geometry", _fields("geometry", "nx", "ny", "nz", "periodic", "radius")):
            return getattr(packings, self._geometry)(self.nx, self.ny, self.nz, periodic=periodic, radius=self.radius)


class FCCSpec(_PackingSpec):
    """Face-centred cubic packing of ``nx x ny x nz`` cells (`FCC`); ``periodic`` a bool or [x, y, z]."""

    kind: Literal["fcc"] = "fcc"
    _geometry = "FCC"  # of `geometry.packings`


class HCPSpec(_PackingSpec):
    """Hexagonal close packing of ``nx x ny x nz`` cells (`HCP`); ``periodic`` a bool or [x, y, z]."""

    kind: Literal["hcp"] = "hcp"
    _geometry = "HCP"


GeometrySpec = Annotated[FlatTorusSpec | HalfPlaneSpec | GraphPositionsSpec | SphereSpec | HyperbolicPlaneSpec | FCCSpec
                         | HCPSpec | PythonGeometrySpec, Field(discriminator="kind")]


def geometry_from_stored(spec, positions: np.ndarray):
    """The geometry of ``spec`` for a results file that stores ``positions (n, k)``: a spec that reads
    its positions from a file takes the stored ones instead (the file may be gone)."""
    return spec.build_from(positions) if hasattr(spec, "build_from") else spec.build()


def parse_geometry(described: dict):
    """The `GeometrySpec` of a dict with a ``"kind"`` (a geometry's own `Geometry.to_spec`, as a run
    built in Python stores it), or None for a dict without one (a geometry that has no spec).
    A user's factory it names is not imported (`IMPORT_FACTORIES`)."""
    from pydantic import TypeAdapter

    if "kind" not in described:
        return None
    return TypeAdapter(GeometrySpec).validate_python(described, context={IMPORT_FACTORIES: False})
