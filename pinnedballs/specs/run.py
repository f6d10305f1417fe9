"""`RunSpec`: a whole run as data; reading it from JSON (`parse_spec`, `load_spec`); `describe`.

Loading this module loads no engine, numba or scipy: a spec is read, validated and its schema written with
pydantic and its models (``pinnedballs schema`` starts in about a second); building it (`RunSpec.build`)
imports what runs it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, PrivateAttr, ValidationError, field_validator, model_validator

from ..analysis.observables import DEFAULT as DEFAULT_OBSERVABLES
from ..analysis.observables import OBSERVABLES
from ..engine.devices import Device, as_device
from ..engine.jit.failures import CompileFailure
from ..util.errors import FieldError, InputError
from ..util.limits import check_memory
from .base import (
    _NOT_TEXT,
    Count,
    FilePath,
    Positive,
    _in_file,
    _is_text,
    _load_npy,
    _short_text,
    _Spec,
    draw_seed,
    engine_errors,
)
from .errors import SpecError, UserCodeError, _dot, _models_of, _short, first_error
from .geometry import GeometrySpec
from .initial import FromFileSpec, InitialSpec
from .python import ENTRY_POINT_GROUPS, IMPORT_FACTORIES, component_failed, expand_entry_points, label, not_compiled
from .rule import ElasticSpec, RuleSpec
from .scheduler import SchedulerSpec, UniformRandomPairSpec
from .stop import CheckpointSpec, SnapshotsSpec, StopSpec

if TYPE_CHECKING:
    from ..engine.protocol import Refusal
    from ..geometry.base import Geometry
    from ..simulation import Simulation

__all__ = ["RunSpec", "parse_spec", "load_spec", "stored_spec", "describe"]

#: the ``precision`` that lets certified arithmetic find its bits (`pinnedballs.engine.field.arithmetic.AUTO`, as
#: the field's ``Literal["auto"]`` states it)
AUTO = "auto"


MassesField = Positive | FilePath

#: the scheduler a GPU runs, as a spec states it (JSON)
_COUNTER_JSON = '{"kind": "uniform_random_pair", "stream": "counter"}'


def _known_observable(name: str) -> str:
    if name not in OBSERVABLES:
        raise ValueError(f"unknown observable {name!r} (known: {', '.join(OBSERVABLES)})")
    return name


class RunSpec(_Spec):
    """A whole run as data: the JSON of ``pinnedballs run SPEC.json`` (the README's run spec by example).

    Every component is chosen by its ``"kind"``; unknown keys are errors (`load_spec`, `parse_spec`).

    Parameters
    ----------
    geometry : GeometrySpec
        The geometry (``{"kind": "half_plane", "rows": ..., "cols": ...}``, ...: `pinnedballs.specs.geometry`).
    initial : InitialSpec
        The initial velocities (``{"kind": "single_ball", ...}``, ``"gaussian"``, ``"from_file"``).
    rule : RuleSpec
        The collision rule; ``{"kind": "elastic"}`` by default.
    scheduler : SchedulerSpec
        The scheduler; ``{"kind": "uniform_random_pair"}`` by default.
    masses : float or str or None
        A number > 0 for every ball, the path of a ``(n_balls,)`` .npy file, or None (all 1).
    seed : int or None
        Seeds the run's random stream; a spec without one gets one drawn from fresh entropy when
        it runs (`seeded`), which the run's own spec (``spec.json``, the results file) records, so
        ``--resume`` continues the same run and the recorded spec repeats it.
    replica : int or None
        The run is replica ``k`` of an ensemble of this spec (`pinnedballs ensemble`), seeded as it seeds it,
        ``SeedSequence(seed, spawn_key=(k,))``: one replica run alone, checkpointed and resumed, on the
        ensemble's picks (it needs a seed).
    stop : StopSpec
        When the run ends: ``{"steps": N}``, ``{"collisions": N}`` or ``{"frozen": true, "max_steps": N}``.
    snapshots : SnapshotsSpec or None
        When to store the velocities (``{"at_steps": [...]}``, ``{"every_collisions": N}``, ...); None: none.
    trajectory : SnapshotsSpec or None
        When to write a frame of ``DIR/trajectory.gsd`` (a GSD trajectory for OVITO,
        freud and MDAnalysis), in the words of ``snapshots`` (``{"every_steps": 1000}``, ...); None: none.
    checkpoint : CheckpointSpec
        How often the run checkpoints (``{"every_seconds": 60}`` by default).
    observables : list of str
        The observables a run's table records (`pinnedballs.analysis.observables`).
    arithmetic : {"float", "exact", "certified"}
        `Simulation`'s ``arithmetic``.
    precision : int or "auto" or None
        Certified arithmetic's bits per coefficient, None for its default, ``"auto"`` for the bits the run
        finds itself: it starts at the default and, where a decision cannot be proved, again from its first
        step with 1.5 times the bits (`pinnedballs.engine.field.arithmetic.next_precisions`), the results
        recording the bits it ran at.
    late_precision : int or None
        Certified arithmetic's bits once the first wave has passed, None for ``precision`` throughout.
    resolution : float or None
        The collision criterion ``e`` in (0, 1), a pick colliding when its closing speed
        exceeds ``e V`` (`Simulation`'s ``resolution``); None: the default, ``4 * 2^-53``. A model
        parameter: the run records it, and ``--resume`` continues with it.
    description : str
        Words for the reader; no effect on the run.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.specs.run import parse_spec
    >>> spec = parse_spec({"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
    ...                    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1],
    ...                                "energy": 0.5},
    ...                    "stop": {"frozen": True, "max_steps": 100000}, "seed": 1})
    >>> sim = spec.build()
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 556, 50)
    """

    geometry: GeometrySpec
    initial: InitialSpec
    rule: RuleSpec = ElasticSpec()
    scheduler: SchedulerSpec = UniformRandomPairSpec()
    masses: MassesField | None = None
    seed: Count | None = None
    replica: Count | None = None
    stop: StopSpec
    snapshots: SnapshotsSpec | None = None
    trajectory: SnapshotsSpec | None = None
    checkpoint: CheckpointSpec = CheckpointSpec()
    observables: list[Annotated[str, AfterValidator(_known_observable)]] = list(DEFAULT_OBSERVABLES[2:])
    arithmetic: Literal["float", "exact", "certified"] = "float"
    precision: Count | Literal["auto"] | None = None
    late_precision: Count | None = None
    resolution: float | None = None
    description: str = ""
    #: where `build` builds when no device is named (`on_device`): not part of the spec, nor of its JSON
    _device: Device | None = PrivateAttr(default=None)

    def _repr_html_(self) -> str:  # notebooks: a table of the parts
        from ..plot.display import spec_html

        return spec_html(self)

    @model_validator(mode="before")
    @classmethod
    def _entry_points(cls, data: Any) -> Any:
        builtin = {slot: set(_models_of(cls.model_fields[slot].annotation)[1]) for slot in ENTRY_POINT_GROUPS}
        return expand_entry_points(data, builtin)

    @field_validator("masses", mode="before")
    @classmethod
    def _masses(cls, value: Any) -> Any:
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, str))):
            raise ValueError(f"must be a number > 0 or the path of a .npy file, got {value!r}")
        return value

    @field_validator("resolution", mode="before")
    @classmethod
    def _resolution(cls, value: Any) -> Any:
        from ..rules import check_resolution

        try:
            return None if value is None else check_resolution(value)  # the engine's words
        except FieldError as exc:
            raise ValueError(exc.problem) from None

    @model_validator(mode="after")
    def _replica_needs_a_seed(self) -> RunSpec:
        if self.replica is not None and self.seed is None:
            raise ValueError("replica: is replica k of the ensemble the seed seeds; give the spec a seed")
        return self

    @model_validator(mode="after")
    def _auto_is_certified(self) -> RunSpec:
        if self.precision == AUTO and self.arithmetic != "certified":
            raise ValueError(f"precision: \"auto\" lets certified arithmetic find its bits; this run's arithmetic "
                             f"is {self.arithmetic!r}")
        from ..engine.field.arithmetic import MAX_PRECISION

        late = self.late_precision
        if self.precision == AUTO and late is not None and not 64 <= late <= MAX_PRECISION:
            raise ValueError(f"late_precision: must be whole bits in [64, {MAX_PRECISION}], got {late}")
        return self

    def at_precisions(self, precision: int, late_precision: int | None) -> RunSpec:
        """This spec at ``precision`` and ``late_precision`` bits (an ``"auto"`` one's attempt at them)."""
        return self.model_copy(update={"precision": int(precision), "late_precision": late_precision})

    def precisions(self) -> tuple[int | None, int | None]:
        """``(precision, late_precision)`` the run is built at: the spec's, or an ``"auto"`` spec's first
        attempt (`pinnedballs.engine.field.arithmetic.auto_precisions`)."""
        if self.precision == AUTO:
            from ..engine.field.arithmetic import auto_precisions

            return auto_precisions(self.late_precision)
        return self.precision, self.late_precision

    def seed_sequence(self) -> np.random.SeedSequence:
        """What seeds the run: ``SeedSequence(seed)``, or for a ``replica`` the ensemble's child
        (`pinnedballs.run.ensemble.replica_seed`)."""
        if self.replica is None:
            return np.random.SeedSequence(self.seed)
        return np.random.SeedSequence(self.seed, spawn_key=(self.replica,))

    @model_validator(mode="after")
    def _snapshots_before_stop(self) -> RunSpec:
        for field in ("snapshots", "trajectory"):
            s = getattr(self, field)
            if s is None:
                continue
            for name, listed, limit in (("at_steps", s.at_steps, self.stop.steps),
                                        ("at_collisions", s.at_collisions, self.stop.collisions),
                                        ("at_steps", s.at_steps, self.stop.max_steps)):
                if listed and limit is not None and listed[-1] > limit:
                    raise ValueError(f"{field}.{name}: {listed[-1]} is beyond the stop at {limit}")
        return self

    def seeded(self) -> RunSpec:
        """This spec, with a seed: its own, or one drawn from fresh entropy (63 bits, as a spec holds)."""
        if self.seed is not None:
            return self
        drawn = draw_seed()
        return self.model_copy(update={"seed": drawn})

    # ------------------------------------------------------------ building
    def build_masses(self, n_balls: int) -> float | np.ndarray | None:
        """The masses: None (all 1), a number, or ``(n_balls,)`` from the file."""
        if self.masses is None or isinstance(self.masses, float):
            return self.masses
        m = _load_npy(self.masses, "masses")
        if m.shape != (n_balls,):
            raise SpecError("masses", f"{self.masses} must have shape (n_balls,) = ({n_balls},), got {m.shape}")
        if not (np.isfinite(m).all() and (m > 0).all()):
            raise SpecError("masses", f"{self.masses}: must all be finite and > 0")
        return m

    def on_device(self, device: str | Device) -> RunSpec:
        """This spec, built on ``device`` when `build` names none: the same spec (equal, the same JSON and bits),
        for the replicas an ensemble runs there, whatever task builds them."""
        spec = self.model_copy()
        spec._device = as_device(device)
        return spec

    def build(self, seed: int | np.random.SeedSequence | None = None, device: str | Device | None = None,
              geometry: Geometry | None = None) -> Simulation:
        """A fresh `Simulation` of this spec.

        Parameters
        ----------
        seed : int or numpy.random.SeedSequence, optional
            Overrides ``self.seed`` (with neither, fresh entropy: see `Simulation`).
        device : str or Device, optional
            Where it runs (``"cpu"``, ``"cuda"``, `pinnedballs.CPU`, `pinnedballs.CUDA`), not part of the spec:
            the same spec gives the same bits on either (None: `on_device`'s, else the CPU).
        geometry : Geometry, optional
            This spec's geometry, built already (an ensemble's replicas share one).

        Returns
        -------
        Simulation

        Raises
        ------
        SpecError
            Naming the spec's field the engine refused (``geometry``, ``initial``, ``masses``, ``device``, ...),
            or ``seed`` for one that is neither an integer in [0, 2**63) nor a SeedSequence.
        UserCodeError
            Where a user's component the spec names failed in its own code (a `SpecError`).
        """
        device = self._device if device is None else device
        if not (seed is None or isinstance(seed, np.random.SeedSequence) or (
                isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and 0 <= seed < 2**63)):
            raise SpecError("seed", f"must be an integer in [0, 2**63) or a numpy SeedSequence, "
                                    f"got {_short(seed)}")
        if seed is None and self.seed is None:
            # its seed then fits a spec: sim.seed repeats it as the spec's "seed"
            return self.seeded().build(device=device, geometry=geometry)
        seq = seed if isinstance(seed, np.random.SeedSequence) else \
            self.seed_sequence() if seed is None else np.random.SeedSequence(seed)
        geometry = self.geometry.build() if geometry is None else geometry
        masses = self.build_masses(geometry.n_balls)
        from ..engine.state import mass_array

        with engine_errors("", {"masses": "masses"}):
            masses_all = mass_array(masses, geometry.n_balls)
        velocities = self.initial.build(geometry, masses_all, seq)
        return self.build_with(geometry, velocities, masses, seq, device)

    def build_with(self, geometry, velocities, masses, seed: np.random.SeedSequence | None = None,
                   device: str | Device | None = None) -> Simulation:
        """A `Simulation` of this spec's rule, scheduler and seed on a ``geometry``, ``velocities`` and
        ``masses`` already built (or read back from a results file), on ``device``."""
        seq = seed if seed is not None else self.seed_sequence()
        initial = "initial.path" if isinstance(self.initial, FromFileSpec) else "initial"
        if self.resolution is not None and self.arithmetic != "float":  # as the precision outside certified arithmetic
            raise SpecError("resolution", f"is the collision criterion of float arithmetic; this run's is "
                                          f"{self.arithmetic!r}")
        from ..engine.protocol import Refused
        from ..simulation import Simulation

        rule, scheduler = self.rule.build(), self.scheduler.build()
        precision, late_precision = self.precisions()
        try:
            with engine_errors("", {"velocities": initial, "masses": "masses", "geometry": "geometry",
                                    "rule": "rule", "scheduler": "scheduler", "seed": "seed",
                                    "arithmetic": "arithmetic", "resolution": "resolution", "precision": "precision",
                                    "late_precision": "late_precision", "device": "device"}):
                try:
                    return Simulation(geometry, velocities, rule=rule, scheduler=scheduler,
                                      masses=masses, seed=seq, arithmetic=self.arithmetic,
                                      resolution=self.resolution, precision=precision,
                                      late_precision=late_precision, device=device)
                except Refused as exc:
                    raise self.refused(exc.refusal) from None
                except CompileFailure as exc:  # a GPU's check compiled the rule, for the CPU too
                    raise self.not_compiled(exc) from exc.__cause__
                except InputError:
                    raise  # the engine's own words, mapped to the spec's fields
                except (Exception, SystemExit) as exc:  # a user's component failing in its own code
                    failed = component_failed(exc, {"geometry": geometry, "rule": rule, "scheduler": scheduler},
                                              {"geometry": self.geometry, "rule": self.rule,
                                               "scheduler": self.scheduler})
                    if failed is None:
                        raise
                    raise failed from exc
        except UserCodeError:
            raise
        except SpecError as exc:
            files = {"geometry": getattr(self.geometry, "positions", None),
                     "initial.path": getattr(self.initial, "path", None),
                     "masses": self.masses if isinstance(self.masses, str) else None}
            raise _in_file(exc, files[exc.path]) if files.get(exc.path) else exc from None

    def not_compiled(self, failure: CompileFailure) -> SpecError:
        """numba's refusal to compile this spec's rule or scheduler (`pinnedballs.engine.jit.failures.CompileFailure`)
        in the spec's words: a user's component named by its factory (`python.not_compiled`)."""
        return not_compiled(failure, {"rule": self.rule, "scheduler": self.scheduler})

    def refused(self, refusal: Refusal) -> SpecError:
        """The engine's `Refusal` of this spec as a `SpecError` on its field, in the spec's words: a scheduler it
        needs named as a spec's JSON states it, and this spec's beside it."""
        if ("scheduler", "counter") not in refusal.needs:
            return SpecError(refusal.field, refusal.message)
        mine = {"kind": self.scheduler.kind, **self.scheduler.model_dump(mode="json", exclude_defaults=True,
                                                                          exclude={"kind"})}
        return SpecError(refusal.field, f"'cuda' runs the scheduler {_COUNTER_JSON} (the pick of step s a function "
                                        f"of the seed and s); this spec's scheduler, {json.dumps(mine)}, runs on the "
                                        f"CPU")

    def to_json(self) -> str:
        """The spec as JSON.

        Returns
        -------
        str
            Indented JSON, defaults filled in and paths absolute.
        """
        return self.model_dump_json(indent=2)


# ---------------------------------------------------------------- reading specs


def parse_spec(data: str | bytes | dict, base_dir: str | os.PathLike | None = None, source: str = "") -> RunSpec:
    """Validate a spec given as JSON text or a dict; relative paths resolve against ``base_dir``.

    Raises `SpecError` naming the first wrong field (``source`` prefixes the message).
    """
    context = {"base_dir": os.fspath(base_dir) if base_dir is not None else None}
    try:
        if isinstance(data, dict):
            _check_tree(data, source)
            return RunSpec.model_validate(data, context=context)
        if isinstance(data, bytes):
            try:
                data = data.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise SpecError(source, f"not UTF-8 text ({exc})") from None
        try:
            parsed = json.loads(data, parse_int=_parse_int)
        except json.JSONDecodeError as exc:
            raise SpecError(source, f"not valid JSON: {exc}") from None
        except RecursionError:
            raise SpecError(source, f"not a spec: JSON nested more than {_MAX_DEPTH} levels deep") from None
        if not isinstance(parsed, dict):
            raise SpecError(source, f"a spec must be a JSON object, got {type(parsed).__name__}")
        _check_tree(parsed, source)
        return RunSpec.model_validate(parsed, context=context)
    except ValidationError as exc:
        error = first_error(exc, RunSpec)
        if isinstance(error, UserCodeError):
            # with the user's exception as its cause, set by first_error: ``from`` would replace it
            raise error  # noqa: B904
        raise SpecError(_join(source, error.path) if source else error.path, error.problem) from None


#: bytes of Python objects per character of JSON, from above (``[1,2,...]``: 36 bytes per 2 characters)
_JSON_BYTES_PER_CHAR = 32
#: deepest nesting of objects and arrays a spec may have (a spec needs 3 or 4)
_MAX_DEPTH = 32


class _LongInt(str):
    """The digits of a JSON integer too long for any spec field (kept as text, never converted)."""


def _parse_int(digits: str) -> int | _LongInt:
    return int(digits) if len(digits.lstrip("-")) <= 19 else _LongInt(digits)


def _check_tree(data: Any, source: str) -> None:
    """Refuse, naming the field, what no spec field can hold: nesting deeper than `_MAX_DEPTH`,
    integers outside int64, and strings that are not UTF-8 text (lone surrogates).

    Walks ``data`` (parsed JSON or a dict) without recursion, fields in document order.
    """
    stack = [(data, "", 0)]
    while stack:
        value, path, depth = stack.pop()
        where = path or source
        if depth > _MAX_DEPTH:
            raise SpecError(where, f"nested more than {_MAX_DEPTH} levels deep")
        if isinstance(value, dict):
            items = []
            for key, item in value.items():
                if isinstance(key, str) and not _is_text(key):
                    raise SpecError(where, f"a key is {_NOT_TEXT}: {_short_text(key)}")
                items.append((item, _dot(path, str(key)), depth + 1))
            stack.extend(reversed(items))
        elif isinstance(value, (list, tuple)):
            stack.extend(reversed([(item, f"{path}[{i}]", depth + 1) for i, item in enumerate(value)]))
        elif isinstance(value, _LongInt) or (
                isinstance(value, int) and not isinstance(value, bool) and not -2**63 <= value < 2**63):
            digits = len(str(value).lstrip("-")) if isinstance(value, str) or value.bit_length() < 10**4 else "many"
            raise SpecError(where, f"an integer of {digits} digits is out of range "
                                   f"(a spec field holds at most 2**63 - 1)")
        elif isinstance(value, str) and not _is_text(value):
            raise SpecError(where, f"{_NOT_TEXT}: {_short_text(value)}")


def load_spec(path: str | os.PathLike) -> RunSpec:
    """Read and validate the JSON spec at ``path``; relative paths in it resolve against its directory.

    Parameters
    ----------
    path : str or os.PathLike
        A run spec file.

    Returns
    -------
    RunSpec

    Raises
    ------
    SpecError
        In one line naming the file or the first wrong field, with a suggestion on a typo: no such file,
        not UTF-8 JSON, an unknown key or kind, a bad value.

    Examples
    --------
    >>> import json
    >>> import pinnedballs as pb
    >>> run = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
    ...        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 0.5},
    ...        "stop": {"frozen": True, "max_steps": 100000}, "seed": 1}
    >>> with open("run.json", "w") as f:
    ...     json.dump(run, f)
    >>> pb.load_spec("run.json").geometry
    HalfPlaneSpec(kind='half_plane', rows=4, cols=6, length=None, depth=None, radius=1.0, orientation='along')
    >>> run["geometry"]["colls"] = run["geometry"].pop("cols")
    >>> with open("bad.json", "w") as f:
    ...     json.dump(run, f)
    >>> pb.load_spec("bad.json")
    Traceback (most recent call last):
    ...
    pinnedballs.specs.errors.SpecError: geometry.colls: unknown key; did you mean 'cols'? (valid keys: ...)
    """
    path = Path(path)
    try:
        check_memory(_JSON_BYTES_PER_CHAR * path.stat().st_size, str(path), "reading this spec file")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(str(path), "no such spec file") from None
    except FieldError as exc:
        raise SpecError(str(path), exc.problem) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), f"cannot read the spec file ({exc})") from None
    try:
        return parse_spec(text, base_dir=path.resolve().parent)
    except SpecError as exc:
        if exc.path:
            raise
        raise SpecError(str(path), exc.problem) from None


def stored_spec(text: str) -> RunSpec:
    """The spec stored with a run (JSON), validated without importing the user's factories it names:
    reading a run needs no user code. A ValueError if it is not a valid spec."""
    return RunSpec.model_validate_json(text, context={IMPORT_FACTORIES: False})


def _join(a: str, b: str) -> str:
    return f"{a}: {b}" if a and b else a or b



# ---------------------------------------------------------------- summaries


def describe(spec: RunSpec, sim: Simulation) -> str:
    """One line saying what ``spec`` runs: geometry, sizes, rule, scheduler, stop, snapshots, seed."""
    g = spec.geometry
    shape = _shape(g, sim.geometry)
    stop = spec.stop
    until = {"steps": lambda: f"{stop.steps:,} steps", "collisions": lambda: f"{stop.collisions:,} collisions",
             "frozen": lambda: f"frozen (max {stop.max_steps:,} steps)"}[stop.kind]()
    snapshots = _how_many(spec.snapshots, spec.stop, "snapshot")
    if spec.trajectory is not None:
        snapshots += f", trajectory.gsd: {_how_many(spec.trajectory, spec.stop, 'frame')}"
    rule = label(spec.rule) + (f"(r={spec.rule.r})" if spec.rule.kind == "restitution" else "")
    arithmetic = _arithmetic(spec, sim)
    return (f"{g.kind} {shape}: {sim.geometry.n_balls} balls, {sim.geometry.n_contacts} contacts, dim "
            f"{sim.geometry.dim}; {label(spec.initial)}, energy {sim.energy():.6g}; {rule}, {label(spec.scheduler)}; "
            + (f"{arithmetic}; " if arithmetic else "")
            + f"stop at {until}; {snapshots}; "
            + ("seed drawn when it runs" if spec.seed is None else f"seed {spec.seed}"
               + ("" if spec.replica is None else f", replica {spec.replica}"))
            + ("" if spec.resolution is None else f"; resolution {spec.resolution:.3g}"))


def _arithmetic(spec: RunSpec, sim: Simulation) -> str:
    """The run's arithmetic and bits in words (nothing for floats, the default): ``"exact arithmetic"``,
    ``"certified arithmetic, 768 bits through the first wave, 256 behind it"``, ``"certified arithmetic, 768
    bits"``, or an ``"auto"`` run's ``"certified arithmetic, precision auto: 768 bits to start, more where ..."``."""
    if spec.arithmetic != "certified":
        return "" if spec.arithmetic == "float" else f"{spec.arithmetic} arithmetic"
    top, late = getattr(sim.engine.state.field_chain, "bits", (0, 0))
    bits = f"{top} bits through the first wave, {late} behind it" if late else f"{top} bits"
    if spec.precision == AUTO:
        return f"certified arithmetic, precision auto: {bits} to start, more where a decision cannot be proved"
    return f"certified arithmetic, {bits}"


def _shape(g: BaseModel, geometry: Geometry) -> str:
    """``rows x cols`` or ``nx x ny x nz`` when the geometry has them, else the spec's own arguments."""
    if hasattr(geometry, "rows") and hasattr(geometry, "cols"):
        return f"{geometry.rows}x{geometry.cols}"
    if isinstance(getattr(geometry, "shape", None), tuple):
        return "x".join(str(n) for n in geometry.shape)
    fields = g.model_dump(exclude={"kind", "radius", "rtol", "args"}, exclude_none=True)
    if "factory" in fields:  # a user's component
        return fields["factory"]
    return " ".join(Path(v).name if isinstance(v, str) and os.sep in v else f"{k}={v}" for k, v in fields.items())


def _how_many(s: SnapshotsSpec | None, stop: StopSpec, noun: str) -> str:
    """``"3 snapshots"``, ``"1 snapshot"``, ``"no snapshots"`` or ``"a snapshot every 100 collisions"``."""
    if s is None:
        return f"no {noun}s"
    listed = s.at_steps if s.at_steps is not None else s.at_collisions
    every = s.every_steps or s.every_collisions
    limit = stop.steps if s.every_steps else stop.collisions
    if listed is None and limit is None:
        return f"a {noun} every {every:,} {s.counter}"
    count = len(listed) if listed is not None else limit // every
    return f"{count:,} {noun}{'' if count == 1 else 's'}"
