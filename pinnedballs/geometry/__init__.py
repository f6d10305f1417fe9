"""Geometries: where the balls sit and which of them touch.

One module per idea: `base` (`Contacts`, `Geometry`, the `Boundary` capability,
`GraphGeometry`), `lattices` (the flat torus and half-plane), `sphere`,
`hyperbolic` (the {3,q} tiling) and `packings` (FCC and HCP in 3-D).
"""

from .base import Boundary, Contacts, Geometry, GraphGeometry
from .hyperbolic import HyperbolicPlane
from .lattices import FlatTorus, HalfPlane
from .packings import FCC, HCP
from .sphere import Sphere

__all__ = ["Contacts", "Geometry", "Boundary", "FlatTorus", "HalfPlane", "GraphGeometry",
           "Sphere", "HyperbolicPlane", "FCC", "HCP"]
