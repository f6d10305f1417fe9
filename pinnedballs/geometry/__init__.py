"""Geometries: where the balls sit and which of them touch.

One module per idea: `base` (`Contacts`, `Geometry`, the `Boundary` capability), `graph`
(`GraphGeometry` and the `StoredGeometry` a results file holds), `lattices` (the flat torus and
half-plane), `sphere`, `hyperbolic` (the {3,q} tiling) and `packings` (FCC and HCP in 3-D).
Every geometry knows its spec (`Geometry.to_spec`), its boundary and how it is drawn (`Geometry.view`;
`pictures`: the drawings `pinnedballs.plot` hands down). `simulation`: the `Simulation` of balls on a
geometry, run by a scheduler under a rule, below the specs, results and analysis that use it.

Each name is imported from its module when first used (`lazy_loader` over ``__init__.pyi``, as the package's own
front door): a
module that needs one module of the room (`rows`, the rows of a lattice by distance) loads that one alone.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)  # the names: __init__.pyi
