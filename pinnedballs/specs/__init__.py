"""Run specs: a whole run described as data (JSON), validated by pydantic.

Each component is chosen by its ``"kind"`` (a discriminated union), unknown keys
are errors, and every spec has a ``build()`` that returns the runtime object, so
pydantic never reaches the compiled loop. `RunSpec.build` gives a `Simulation`.

Bad input raises `SpecError`, whose message starts with the field path::

    geometry.rows: must be even for a flat torus, got 5

Relative file paths resolve against the spec file's directory (`load_spec`),
or the working directory for a spec given as a dict.

One module per idea: `base` (the model base, field types, engine errors), `geometry`,
`initial`, `rule`, `scheduler` (the components by kind), `stop` (stop, snapshot and
checkpoint specs), `python` (a user's components and entry-point kinds), `run` (`RunSpec`,
reading specs) and `errors` (`SpecError` and the messages of pydantic's errors).
"""

from ..util.errors import InputError
from .base import Count, FilePath, Positive, engine_errors
from .errors import SpecError
from .geometry import (
                       FCCSpec,
                       FlatTorusSpec,
                       GeometrySpec,
                       GraphPositionsSpec,
                       HalfPlaneSpec,
                       HCPSpec,
                       HyperbolicPlaneSpec,
                       SphereSpec,
)
from .initial import INIT_STREAM_KEY, FromFileSpec, GaussianSpec, InitialSpec, SingleBallSpec
from .python import PythonGeometrySpec, PythonInitialSpec, PythonRuleSpec, PythonSchedulerSpec
from .rule import ElasticSpec, RestitutionSpec, RuleSpec
from .run import RunSpec, describe, load_spec, parse_spec
from .scheduler import (
                       ColoredSweepSpec,
                       RandomSweepSpec,
                       RejectionFreeSpec,
                       SchedulerSpec,
                       SweepSpec,
                       UniformRandomPairSpec,
)
from .stop import CheckpointSpec, SnapshotsSpec, StopSpec

__all__ = [
    "InputError", "SpecError", "RunSpec", "load_spec", "parse_spec", "describe",
    "FlatTorusSpec", "HalfPlaneSpec", "GraphPositionsSpec", "SphereSpec", "HyperbolicPlaneSpec", "FCCSpec",
    "HCPSpec", "GeometrySpec",
    "SingleBallSpec", "GaussianSpec", "FromFileSpec", "InitialSpec",
    "ElasticSpec", "RestitutionSpec", "RuleSpec",
    "UniformRandomPairSpec", "SweepSpec", "RandomSweepSpec", "RejectionFreeSpec", "ColoredSweepSpec", "SchedulerSpec",
    "StopSpec", "SnapshotsSpec", "CheckpointSpec",
    "PythonGeometrySpec", "PythonInitialSpec", "PythonRuleSpec", "PythonSchedulerSpec",
    "Count", "FilePath", "Positive", "engine_errors", "INIT_STREAM_KEY",
]
