"""pinnedballs: simulation of pinned billiard balls.

Balls sit at fixed centres; their pseudo-velocities change when two touching
balls approach and collide. See ``docs/`` and the README for a tour.
"""

from .geometry import (FCC, HCP, Boundary, Contacts, FlatTorus, Geometry, GraphGeometry, HalfPlane, HyperbolicPlane,
                       Sphere)
from .rules import CollisionRule, Elastic, Restitution
from .schedulers import RandomSweep, Scheduler, Sweep, UniformRandomPair
from .rejection_free import RejectionFree
from .colored_sweep import ColoredSweep
from .simulation import Simulation
from .io import ResultsError, load
from .triggers import AtCollisions, AtSteps, EveryCollisions, EverySteps, Trigger
from .writers import ResultsWriter
from .specs import RunSpec
from .ensemble import run_ensemble
from .orders import OrdersResult, Replay, explore_orders

__version__ = "0.1.0"

__all__ = [
    "Contacts", "Geometry", "Boundary", "FlatTorus", "HalfPlane", "GraphGeometry",
    "Sphere", "HyperbolicPlane", "FCC", "HCP",
    "CollisionRule", "Elastic", "Restitution",
    "Scheduler", "UniformRandomPair", "Sweep", "RandomSweep", "RejectionFree", "ColoredSweep",
    "Simulation", "__version__",
    "load", "ResultsError", "RunSpec", "run_ensemble",
    "explore_orders", "OrdersResult", "Replay",
    "ResultsWriter", "Trigger", "AtSteps", "EverySteps", "AtCollisions", "EveryCollisions",
]
