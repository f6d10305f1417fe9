"""pinnedballs: simulation of pinned billiard balls.

Balls sit at fixed centres; their pseudo-velocities change when two touching
balls approach and collide. See ``docs/`` and the README for a tour.
"""

from .geometry import Contacts, FlatTorus, Geometry, GraphGeometry, HalfPlane
from .rules import CollisionRule, Elastic, Restitution
from .schedulers import RandomSweep, Scheduler, Sweep, UniformRandomPair
from .simulation import Simulation
from .io import load
from .triggers import AtCollisions, AtSteps, EveryCollisions, EverySteps, Trigger
from .writers import ResultsWriter
from .specs import RunSpec
from .ensemble import run_ensemble

__version__ = "0.1.0"

__all__ = [
    "Contacts", "Geometry", "FlatTorus", "HalfPlane", "GraphGeometry",
    "CollisionRule", "Elastic", "Restitution",
    "Scheduler", "UniformRandomPair", "Sweep", "RandomSweep",
    "Simulation", "__version__",
    "load", "RunSpec", "run_ensemble",
    "ResultsWriter", "Trigger", "AtSteps", "EverySteps", "AtCollisions", "EveryCollisions",
]
