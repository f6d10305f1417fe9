"""pinnedballs: simulation of pinned billiard balls.

Balls sit at fixed centres; their pseudo-velocities change when two touching
balls approach and collide. See ``docs/`` and the README for a tour.
"""

import sys as _sys
from typing import TYPE_CHECKING as _TYPE_CHECKING

from .util.startup import from_the_first_instant as _from_the_first_instant

_from_the_first_instant(only_if_starting=True)  # the command line: a Ctrl-C while numpy, numba... import is one line
from .util.moved import install as _install_moved  # noqa: E402

_install_moved()  # module paths that moved still import, with a DeprecationWarning (`util.moved`)

from ._version import __version__  # noqa: E402 - after the finder: a moved path may be imported below
from .analysis.maxima import MaxCollisionsResult, search_max_collisions
from .analysis.observables import register as register_observable
from .analysis.orders import OrdersResult, explore_orders
from .engine.driver import Writer
from .engine.margin import MarginWarning
from .engine.stop import Stop
from .engine.triggers import AtCollisions, AtSteps, EveryCollisions, EverySteps, Trigger
from .geometry import (
    FCC,
    HCP,
    Boundary,
    Contacts,
    FlatTorus,
    Geometry,
    GraphGeometry,
    HalfPlane,
    HyperbolicPlane,
    Sphere,
)
from .geometry.simulation import FreezeWarning, RunState, Simulation
from .plot import display as _display  # noqa: F401 - how a geometry and a simulation show themselves
from .results.format import ResultsError
from .results.load import Results, load
from .rules import CollisionRule, Elastic, Restitution
from .run.collision_log import CollisionLog
from .run.ensemble import EnsembleResult, run_ensemble
from .run.ensemble_dir import load_ensemble
from .run.execute import run_spec
from .run.gsd_writer import GSDWriter
from .run.writers import ResultsWriter
from .schedulers import ColoredSweep, RandomSweep, RejectionFree, Replay, Scheduler, Sweep, UniformRandomPair
from .specs.errors import SpecError
from .specs.run import RunSpec, load_spec
from .util.errors import FieldError, FieldTypeError, InputError

__all__ = [
    "Contacts", "Geometry", "Boundary", "FlatTorus", "HalfPlane", "GraphGeometry",
    "Sphere", "HyperbolicPlane", "FCC", "HCP",
    "CollisionRule", "Elastic", "Restitution",
    "Scheduler", "UniformRandomPair", "Sweep", "RandomSweep", "RejectionFree", "ColoredSweep", "Replay",
    "Simulation", "RunState", "__version__",
    "load", "Results", "ResultsError", "RunSpec", "run_ensemble", "load_spec", "run_spec",
    "load_ensemble", "EnsembleResult",
    "search_max_collisions", "MaxCollisionsResult",
    "explore_orders", "OrdersResult",
    "ResultsWriter", "GSDWriter", "CollisionLog", "Writer", "Stop", "Trigger", "AtSteps", "EverySteps", "AtCollisions", "EveryCollisions",
    "register_observable", "InputError", "FieldError", "FieldTypeError", "SpecError",
    "MarginWarning", "FreezeWarning", "GPUUnavailable",
]

if _TYPE_CHECKING:  # for readers of the source (type checkers, the API page): `__getattr__` imports it when asked
    from .engine.gpu import GPUUnavailable


def __getattr__(name: str):
    """``pb.GPUUnavailable``, imported when first asked for: ``import pinnedballs`` leaves the GPU engine's
    package (and numba-cuda, which it never imports before a GPU run) alone."""
    if name == "GPUUnavailable":
        from .engine.gpu import GPUUnavailable

        globals()[name] = GPUUnavailable
        return GPUUnavailable
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

# hypothesis came first: st.from_type(pb.Geometry) and the others draw from the kit's strategies, which
# register themselves as they are imported (_pinnedballs_hypothesis.py says why here)
if _sys.modules.get("hypothesis") is not None:
    from .testing import strategies as _strategies  # noqa: F401 - registers them
