"""Geometry specs: one per kind, each with a ``build()`` that returns the `Geometry`."""

from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, model_validator

from ..errors import SpecError
from ..geometry import FlatTorus, GraphGeometry, HalfPlane
from .base import FilePath, Positive, _fields, _in_file, _load_npy, _Spec, engine_errors
from .python import PythonGeometrySpec

__all__ = ["FlatTorusSpec", "HalfPlaneSpec", "GraphPositionsSpec", "GeometrySpec", "geometry_from_stored"]



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

    @model_validator(mode="after")
    def _one_size(self) -> "HalfPlaneSpec":
        counts = self.rows is not None and self.cols is not None
        lengths = self.length is not None and self.depth is not None
        given = [k for k in ("rows", "cols", "length", "depth") if getattr(self, k) is not None]
        if counts == lengths or len(given) != 2:
            raise ValueError(f": give rows and cols, or length and depth (got {', '.join(given) or 'none'})")
        return self

    def build(self) -> HalfPlane:
        with engine_errors("geometry", _fields("geometry", "rows", "cols", "length", "depth", "radius")):
            if self.rows is not None:
                return HalfPlane(self.rows, self.cols, self.radius)
            return HalfPlane.from_size(self.length, self.depth, self.radius)


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


GeometrySpec = Annotated[Union[FlatTorusSpec, HalfPlaneSpec, GraphPositionsSpec, PythonGeometrySpec],
                         Field(discriminator="kind")]


def geometry_from_stored(spec, positions: np.ndarray):
    """The geometry of ``spec`` for a results file that stores ``positions (n, k)``: a spec that reads
    its positions from a file takes the stored ones instead (the file may be gone)."""
    return spec.build_from(positions) if hasattr(spec, "build_from") else spec.build()
