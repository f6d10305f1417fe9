"""Geometries: where the balls sit and which of them touch.

One module per idea: `base` (`Contacts`, `Geometry`, the `Boundary` capability), `graph`
(`GraphGeometry` and the `StoredGeometry` a results file holds), `lattices` (the flat torus and
half-plane), `sphere`, `hyperbolic` (the {3,q} tiling) and `packings` (FCC and HCP in 3-D).
Every geometry knows its spec (`Geometry.to_spec`), its boundary and how it is drawn (`Geometry.view`;
`pictures`: the drawings `pinnedballs.plot` hands down). `simulation`: the `Simulation` of balls on a
geometry, run by a scheduler under a rule, below the specs, results and analysis that use it.
"""

from .base import VIEWS, Boundary, Contacts, Geometry
from .graph import GraphGeometry, StoredGeometry
from .hyperbolic import HyperbolicPlane
from .lattices import FlatTorus, HalfPlane
from .packings import FCC, HCP
from .sphere import Sphere

__all__ = ["Contacts", "Geometry", "Boundary", "VIEWS", "FlatTorus", "HalfPlane", "GraphGeometry", "StoredGeometry",
           "Sphere", "HyperbolicPlane", "FCC", "HCP"]
