"""Reading a results file: `load` gives the `Results` of a run, finished or at its last checkpoint,
after `check.check_results` has found the file sound."""

from __future__ import annotations

import functools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ..engine.field.arithmetic import AUTO
from ..engine.field.fixed_state import SMALLEST, STEP_ORDER_RULE, CertifiedState
from ..engine.margin import ClosingMargin
from ..engine.state import RunState, mass_array
from ..geometry.base import Boundary, Geometry
from ..geometry.graph import StoredGeometry
from ..rules import check_resolution, threshold
from ..simulation import Simulation
from ..specs.errors import SpecError, UserCodeError
from ..specs.geometry import geometry_from_stored, parse_geometry
from ..specs.python import IMPORT_FACTORIES, label
from ..specs.run import RunSpec, stored_spec
from ..util.errors import InputError
from . import legacy
from .check import check_results
from .digest import unseal
from .format import FORMAT_VERSION, RESULTS_NAME, ResultsError, data_dir, results_path
from .frames import FrameFile, Snapshots
from .index import segment_list

__all__ = ["Results", "load", "open_checked", "read"]


@dataclass(eq=False)
class Results:
    """A run read back from its results file (finished, or the last checkpoint of an unfinished one).

    `load` makes it from what the file holds (`pinnedballs.results.format`). ``velocities``, ``steps``,
    ``collisions``, ``rng_state`` and ``scheduler_state`` are the latest state's fields, as properties here
    too; ``positions``, ``pairs``, ``t_i``, ``t_j`` and ``radius`` the stored geometry's.

    Parameters
    ----------
    path : pathlib.Path
        The results file.
    spec : RunSpec or None
        The run's spec, or None for a run built in Python, which ``run`` describes.
    version : str
        The pinnedballs version that wrote the file.
    status : {"running", "done", "interrupted", "failed"}
        Where the run stands (`complete`).
    stop_reason : str
        Why it stopped, as `Stop.reason` says it.
    energy, momentum, approaching, frozen
        The latest state's energy, ``(d,)`` momentum, live contacts (-1 where a failed run's live contacts
        could not be counted) and whether it is frozen.
    stored : StoredGeometry
        The geometry the file holds (``positions (n, k)``, ``pairs (E, 2)``, ``t_i, t_j (E, d)`` are its arrays).
    masses : numpy.ndarray or None
        ``(n,)``; None for all equal.
    initial_velocities, initial_energy
        ``(n, d)`` and their energy.
    snapshots : Snapshots
        The `Snapshot` ``(steps, collisions, velocities (n, d))`` of each snapshot, as a sequence
        (`frames.Snapshots`) that reads a snapshot's velocities when it is taken (the run opens at once,
        whatever its size).
    observables : dict of numpy.ndarray
        Per-snapshot columns (``steps, collisions (F,)`` and the recorded observables).
    elapsed_seconds : float
        The run's time, over its lives.
    checkpoints : int
        The checkpoints written.
    created, updated : str
        When the file was made and last written.
    latest : RunState
        The latest state.
    run : dict
        What a run built in Python was built from (``geometry``, ``rule``, ``scheduler``: each component's own
        spec, else ``{"class": ...}``).
    format_version : int
        Of the results format.
    closing_margin : ClosingMargin or None
        How near its collision criterion the run's picks came, at the latest state
        (`pinnedballs.engine.margin.ClosingMargin`); None where the file keeps none (a run in exact or
        certified arithmetic, or one begun before runs kept their margin). A certified run's margin is that
        of its decisions (`smallest_exact_collision`).
    device : {"cpu", "cuda"}
        Where its last stretch ran (information: not part of the spec, and no number depends on it).
    simulated : bool
        Whether numba-cuda's simulator stood in for the GPU there.
    failure : dict or None
        Why a failed run (``status`` "failed") cannot go on, as the file keeps it (`format`: ``message``,
        ``steps``, ``precision``, ``late_precision``, ``narrowed``, ``remedy``); None otherwise.
    provenance : list of dict
        How the run was made, one entry per life (the first run, then each resumed one, in order;
        `pinnedballs.util.provenance`): ``versions`` (pinnedballs, Python, numpy, numba, ...), ``command`` (the
        command line or the Python call), ``argv``, ``host``, ``platform``, ``cpu`` (model, cores, L2 cache,
        vector flags), ``device`` (``kind`` "cpu" with the ``threads`` used, or "cuda" with the ``gpu``'s name
        and compute capability, ``"simulated"`` under numba-cuda's simulator), ``steps`` (``[first, last]`` of
        the life), ``started`` and ``ended`` (UTC, ISO 8601; ``ended`` at its last checkpoint). Empty for a file
        written before runs kept their provenance.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run_until_frozen(100_000, writers=[pb.ResultsWriter("run", snapshots={"every_collisions": 10})])
    True
    >>> res = pb.load("run")
    >>> res
    Results('run/results.h5', done, steps=556, collisions=50, snapshots=5, frozen=True)
    >>> [(s.steps, s.collisions) for s in res.snapshots][:2], res.kinds["geometry"]
    ([(120, 10), (147, 20)], 'half_plane')
    >>> res.simulation().is_frozen()
    True
    """

    path: Path
    spec: RunSpec | None
    version: str
    status: str
    stop_reason: str
    energy: float
    momentum: np.ndarray
    approaching: int
    frozen: bool
    stored: StoredGeometry
    masses: np.ndarray | None
    initial_velocities: np.ndarray
    initial_energy: float
    snapshots: Snapshots
    observables: dict[str, np.ndarray]
    elapsed_seconds: float
    checkpoints: int
    created: str
    updated: str
    latest: RunState
    run: dict = field(default_factory=dict, repr=False)
    format_version: int = FORMAT_VERSION
    closing_margin: ClosingMargin | None = None
    device: str = "cpu"
    simulated: bool = False
    failure: dict | None = None
    provenance: list[dict] = field(default_factory=list, repr=False)

    @property
    def velocities(self) -> np.ndarray:
        return self.latest.velocities

    @property
    def steps(self) -> int:
        return self.latest.steps

    @property
    def collisions(self) -> int:
        return self.latest.collisions

    @property
    def rng_state(self) -> np.ndarray:
        return self.latest.rng_state

    @property
    def scheduler_state(self) -> np.ndarray:
        return self.latest.scheduler_state

    @property
    def positions(self) -> np.ndarray:
        return self.stored.positions

    @property
    def pairs(self) -> np.ndarray:
        return self.stored.contacts.pairs

    @property
    def t_i(self) -> np.ndarray:
        return self.stored.contacts.t_i

    @property
    def t_j(self) -> np.ndarray:
        return self.stored.contacts.t_j

    @property
    def radius(self) -> float:
        return self.stored.radius

    @property
    def smallest_exact_collision(self) -> float | None:
        """A run in certified arithmetic: the smallest closing speed it counted as a collision, up to the latest
        state, in thresholds (as `Simulation.smallest_exact_collision`: the float criterion's threshold, which
        does not decide here); None before its first collision, in other arithmetics, and where the file keeps
        none (a run begun before certified states kept their margin: unknown)."""
        certified = self.latest.certified
        if certified is None or certified.margin is None or not np.isfinite(certified.margin[SMALLEST]):
            return None
        resolution = self.spec.resolution if self.spec is not None else self.run.get("resolution")
        criterion = threshold(self.initial_velocities, mass_array(self.masses, len(self.initial_velocities)),
                              check_resolution(resolution))
        return float(certified.margin[SMALLEST] / criterion)

    @property
    def complete(self) -> bool:
        """True once the run reached its stop (``status`` "done"); False for a checkpoint of a run still
        going ("running"), killed ("running" too: its last checkpoint), stopped by an exception or a
        signal ("interrupted": the state it stopped in) or where it cannot go on ("failed": `failure`)."""
        return self.status == "done"

    @property
    def run_dir(self) -> Path:
        """The run's directory (the results file's)."""
        return self.path.parent

    @property
    def kinds(self) -> dict[str, str]:
        """``geometry``, ``initial``, ``rule``, ``scheduler``: what each component is: its kind, the
        factory (``module:callable``) of a user's own, or the class of one built in Python without a spec."""
        if self.spec is not None:
            return {k: label(getattr(self.spec, k)) for k in ("geometry", "initial", "rule", "scheduler")}
        return {k: (v.get("factory") if v.get("kind") == "python" else v.get("kind")) or v.get("class", "?")
                for k in ("geometry", "rule", "scheduler") if isinstance(v := self.run.get(k), dict)}

    @functools.cached_property
    def geometry(self) -> Geometry:
        """The run's geometry: rebuilt from its spec (the stored positions stand in for a file of
        positions), or the stored one (`stored`) for a geometry that has no spec."""
        spec = self.spec.geometry if self.spec is not None else parse_geometry(self.run.get("geometry", {}))
        if spec is None or (spec.kind == "python" and self.stored.complete):
            return self.stored
        return geometry_from_stored(spec, self.positions)

    @property
    def cannot_resume(self) -> str:
        """Why this run cannot be continued from its file, or "": a certified run written under the step-order
        bound rule of pinnedballs < 1.0 (no ``bound_batch``: its states, counts and figures load, but the chain
        keeps the batched rule alone)."""
        certified = self.latest.certified
        if certified is None or certified.bound_batch:
            return ""
        again = "its spec" if self.spec is not None else "the start"
        return f"{STEP_ORDER_RULE}; run it again from {again}"

    def state(self) -> RunState:
        """A copy of the latest state, for `Simulation.set_state`.

        Returns
        -------
        RunState
        """
        return self.latest.copy()

    def simulation(self, *, rule=None, scheduler=None, device: str = "cpu") -> Simulation:
        """A `Simulation` at the latest state, ready to go on exactly where this run stopped.

        Parameters
        ----------
        rule, scheduler : optional
            A run built in Python with a rule or scheduler that has no spec needs them given.
        device : Device or {"cpu", "cuda"}
            Where it goes on: the same bits on the counter stream, whatever device wrote the file.

        Returns
        -------
        Simulation

        Raises
        ------
        InputError
            Naming the module and how otherwise, where the spec names a user's factory (``"kind":
            "python"``) whose module cannot be imported; naming its directory and why, for a run that cannot
            go on (`cannot_resume`).
        ValueError
            Naming ``rule`` or ``scheduler``, for a run built in Python with one that has no spec, not given.
        """
        if self.cannot_resume:
            raise InputError(f"{self.run_dir}: {self.cannot_resume}")
        try:
            sim = self._build(rule, scheduler, device)
        except SpecError as exc:
            if not exc.path.endswith(".factory") or isinstance(exc, UserCodeError):  # that one names the factory
                raise
            raise InputError(f"{self.run_dir}: continuing this run needs the code its spec names: {exc}") from None
        sim.set_state(self.state())
        return sim

    def _build(self, rule, scheduler, device: str = "cpu") -> Simulation:
        if self.spec is not None:
            return self._attempt().build_with(self.geometry, self.initial_velocities, self.masses, device=device)
        from ..specs import RuleSpec, SchedulerSpec

        rule = rule if rule is not None else _component(self.run.get("rule", {}), RuleSpec, "rule")
        scheduler = scheduler if scheduler is not None else \
            _component(self.run.get("scheduler", {}), SchedulerSpec, "scheduler")
        certified = self.latest.certified  # a certified run's bits, as its state records them (0: not kept)
        bits = {} if certified is None or not certified.precision else \
            {"precision": certified.precision, "late_precision": certified.late_precision or None}
        return Simulation(self.geometry, self.initial_velocities, rule=rule, scheduler=scheduler,
                          masses=self.masses, seed=0, arithmetic=self.run.get("arithmetic", "float"),
                          resolution=self.run.get("resolution"), device=device, **bits)

    def _attempt(self) -> RunSpec:
        """The spec of this run at the bits it ran at: a spec whose ``precision`` is ``"auto"`` at those its
        latest state records (`CertifiedState.precision`), any other as it is."""
        certified = self.latest.certified
        if self.spec.precision != AUTO or certified is None or not certified.precision:
            return self.spec
        return self.spec.at_precisions(certified.precision, certified.late_precision or None)

    def animate(self, out=None, fps: float = 4, max_frames: int | None = None) -> Path:
        """A movie of this run's snapshots (`pinnedballs.plot.animation.animate`).

        Parameters
        ----------
        out : str or os.PathLike, optional
            The movie's file (default ``<run dir>/movie.gif``).
        fps : float
            Frames a second.
        max_frames : int, optional
            At most this many frames (300 by default).

        Returns
        -------
        pathlib.Path
            The movie's path, which shows the movie when a notebook displays it.
        """
        from ..plot.animation import animate

        return animate(self, out, fps, max_frames)

    def plot(self, what: str = "final", *, snapshot: int | None = None, ax=None):
        """A figure of this run as ``pinnedballs plot`` draws it (`pinnedballs.plot.run.plot_results`).

        Parameters
        ----------
        what : str
            ``"final"`` (the final state), ``"initial"``, ``"snapshot"`` (number ``snapshot``), ``"snapshots"``
            (the contact sheet), ``"energy"`` (by distance from the boundary), ``"height"`` (flat 3-D),
            ``"histograms"`` (velocity components) or ``"all"`` (a dict of every figure).
        snapshot : int, optional
            The snapshot ``"snapshot"`` draws.
        ax : matplotlib.axes.Axes, optional
            Draw into these axes; else a new figure.

        Returns
        -------
        matplotlib.figure.Figure or dict
            A dict of every figure for ``"all"``.
        """
        from ..plot.run import plot_results

        return plot_results(self, what, snapshot=snapshot, ax=ax)

    def _repr_html_(self) -> str:  # notebooks: file, status, counters and snapshots as a table
        from ..plot.display import results_html

        return results_html(self)

    def to_pandas(self):
        """The snapshots as a table (`pinnedballs.results.tables.to_pandas`).

        Returns
        -------
        pandas.DataFrame
            One row per snapshot, the final state last, scalar columns (``momentum_x``, ``momentum_y``, ...).
        """
        from .tables import to_pandas

        return to_pandas(self)

    def to_xarray(self):
        """The snapshots as labelled arrays (`pinnedballs.results.tables.to_xarray`).

        Returns
        -------
        xarray.Dataset
            ``velocities (snapshot, ball, component)`` read lazily, the observables over ``snapshot``, the
            final state last.
        """
        from .tables import to_xarray

        return to_xarray(self)

    def __repr__(self) -> str:
        return (f"Results({str(self.path)!r}, {self.status}, steps={self.steps}, collisions={self.collisions}, "
                f"snapshots={len(self.snapshots)}, frozen={self.frozen})")


def _component(described: dict, slot, name: str):
    """The rule or scheduler a Python run described as a spec dict; a ValueError naming ``name`` if it has none."""
    from pydantic import TypeAdapter

    if "kind" not in described:
        raise ValueError(f"{name}: this run used {described.get('class', 'a component')}, which has no spec; "
                         f"pass {name}= to simulation()")
    return TypeAdapter(slot).validate_python(described, context={IMPORT_FACTORIES: False}).build()


def load(path: str | os.PathLike) -> Results:
    """Read a results file, or ``DIR/results.h5`` given a run directory.

    Opening a run reads its index, not its arrays: a snapshot's velocities are read when asked for.

    Parameters
    ----------
    path : str or os.PathLike
        A results file or a run directory (``pinnedballs run``'s ``--out``, a `ResultsWriter`'s).

    Returns
    -------
    Results

    Raises
    ------
    FileNotFoundError
        If there is none, naming the path.
    ResultsError
        If the file is not a pinnedballs results file or is damaged (a ValueError), naming the path.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run_until_frozen(100_000, writers=[pb.ResultsWriter("run", snapshots={"every_collisions": 10})])
    True
    >>> res = pb.load("run")
    >>> res
    Results('run/results.h5', done, steps=556, collisions=50, snapshots=5, frozen=True)
    >>> [(s.steps, s.collisions) for s in res.snapshots][:2], res.kinds["geometry"]
    ([(120, 10), (147, 20)], 'half_plane')
    >>> res.simulation().is_frozen()
    True
    """
    p = results_path(path)
    if not p.exists():
        where = f"{path}: no {RESULTS_NAME} in this directory" if Path(path).is_dir() else f"{p}: no such file"
        raise FileNotFoundError(where)
    with open_checked(p) as f:
        try:
            return read(p, f)
        except (KeyError, OSError, ValueError, TypeError) as exc:  # what the checks cannot foresee
            raise ResultsError(f"{p}: damaged results file ({' '.join(str(exc).split())})") from None


def open_checked(p: Path) -> h5py.File:
    """The results file ``p`` opened for reading, after checking it is one this version reads:
    its digests (format 3, `digest`) before HDF5 parses anything, then its structure
    (`check_results`). The one place results files are opened."""
    for _ in range(_ATTEMPTS):
        try:
            with open(p, "rb") as raw:
                sealed, inode = unseal(p, raw), _inode(os.fstat(raw.fileno()))
            f = h5py.File(p, "r")
        except OSError as exc:
            raise ResultsError(f"{p}: not a readable HDF5 file (truncated or not HDF5): {exc}") from None
        if _inode(os.stat(p)) == inode:  # the file checked is the one opened (a run replaces its index)
            break
        f.close()
    else:
        raise ResultsError(f"{p}: replaced by its run faster than it could be read; try again")
    try:
        check_results(p, f, sealed)
    except BaseException:
        f.close()
        raise
    return f


#: times `open_checked` reads an index that its run keeps replacing
_ATTEMPTS = 5


def _inode(st: os.stat_result) -> tuple[int, int]:
    return st.st_dev, st.st_ino


def read(p: Path, f: h5py.File) -> Results:
    """The `Results` in the open results file ``f`` (at ``p``), already checked."""
    spec = stored_spec(f.attrs["spec"]) if f.attrs["spec"] else None  # checked by check_results
    version = int(f.attrs["format_version"])
    s, o = f["state"], f["observables"]
    exact = s["exact"].asstr()[()] if "exact" in s else None
    margin = s["margin"][()] if "margin" in s else None  # checked by check_results
    certified = None
    if "certified" in s:
        c = s["certified"]
        decided = c.attrs.get("margin")  # its decisions' margin; absent: not kept (files before it was), unknown
        certified = CertifiedState(c["limbs"][()], int(c.attrs["scale"]), c["bounds"][()], float(c.attrs["rounding"]),
                                   int(c.attrs.get("bound_scale", 0)),  # 0: absolute (files before it was kept)
                                   int(c.attrs.get("precision", 0)), int(c.attrs.get("late_precision", 0)),
                                   None if decided is None else np.array(decided, dtype=np.float64),
                                   # absent: the bound rule in step order (pinnedballs < 1.0: no resume)
                                   int(c.attrs.get("bound_batch", 0)), int(c.attrs.get("bound_at", -1)),
                                   tuple(int(x) for x in c.attrs.get("pending", (0, 0))),
                                   float(c.attrs.get("unfolded", 0.0)))
    latest = RunState(s["velocities"][()], int(s.attrs["steps"]), int(s.attrs["collisions"]), s["rng_state"][()],
                      s["scheduler_state"][()], exact, margin, certified)
    names = legacy.observable_names(f, version) if legacy.older(version) else json.loads(f.attrs["observables"])
    observables = {name: o[name][()] for name in names}
    steps, collisions = observables["steps"], observables["collisions"]
    g = f["geometry"]
    return Results(
        path=p, spec=spec, version=str(f.attrs["version"]), status=str(f.attrs["status"]),
        stop_reason=str(f.attrs["stop_reason"]),
        energy=float(s.attrs["energy"]), momentum=s["momentum"][()], approaching=int(s.attrs["approaching"]),
        frozen=bool(s.attrs["frozen"]), stored=stored_geometry(g), masses=g["masses"][()] if "masses" in g else None,
        initial_velocities=f["initial/velocities"][()], initial_energy=float(f["initial"].attrs["energy"]),
        snapshots=Snapshots(p, steps, collisions, _frame_files(p, f, version), latest.velocities.shape),
        observables=observables,
        elapsed_seconds=float(f.attrs["elapsed_seconds"]), checkpoints=int(f.attrs["checkpoints"]),
        created=str(f.attrs["created"]), updated=str(f.attrs["updated"]),
        latest=latest, run=json.loads(f.attrs.get("run", "") or "{}"), format_version=version,
        closing_margin=None if margin is None else ClosingMargin.of(
            margin, float(s["margin"].attrs["threshold"]), float(s["margin"].attrs["resolution"])),
        device=str(f.attrs.get("device", "cpu")), simulated=bool(f.attrs.get("simulated", False)),
        failure=json.loads(f.attrs["failure"]) if f.attrs["status"] == "failed" else None,  # checked
        provenance=[json.loads(x) for x in f["provenance"].asstr()[()]] if "provenance" in f else [],  # checked
    )


def _frame_files(p: Path, f: h5py.File, version: int) -> list[FrameFile]:
    """Where each snapshot's velocities are: the segments (`legacy.frame_files` for older formats)."""
    if legacy.older(version):
        return legacy.frame_files(p, f, version)
    data = data_dir(p)
    return [FrameFile.at(data / name, "velocities", first, count) for name, first, count in segment_list(f)]


def stored_geometry(g: h5py.Group) -> StoredGeometry:
    """The geometry in the group ``/geometry`` of a results file: its contacts and, in files that
    store them, its boundary, frames and view (``complete``: all that reading the run needs), and
    whether it is `Geometry.rigid` (False in files written before it was kept)."""
    boundary = None
    if "boundary_distance" in g:
        boundary = Boundary(g["boundary_distance"][()], g["boundary_outward"][()])
    view = g.attrs.get("view")
    stored = StoredGeometry(g["positions"][()], g["pairs"][()], g["t_i"][()], g["t_j"][()],
                            float(g.attrs.get("radius", 1.0)), boundary=boundary,
                            frames=g["frames"][()] if "frames" in g else None, view=None if view is None else str(view))
    stored.rigid = bool(g.attrs.get("rigid", False))
    return stored
