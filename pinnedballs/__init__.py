"""pinnedballs: simulation of pinned billiard balls.

Balls sit at fixed centres; their pseudo-velocities change when two touching balls approach and
collide. See ``docs/`` and the README for a tour.

``import pinnedballs`` loads nothing but this face: each public name (``__init__.pyi`` lists them) is
imported from its module when first used (Scientific Python's SPEC 1, `lazy_loader`), so a script that
asks for ``pb.HalfPlane`` loads the geometry, and ``pinnedballs validate`` no numba kernel.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
