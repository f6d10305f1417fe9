"""Carry out a run spec: simulate in chunks, take snapshots, checkpoint, resume, draw figures.

The loop (`run_to_stop`) runs the simulation in chunks of at most
``max(CHUNK_STEPS, CHUNK_PER_CONTACT * n_contacts)`` steps, each chunk also cut
short at the next snapshot or stop, so snapshots land on *exactly* the requested
step or collision count. The engine carries all state, so the result is
bit-identical however the run is split; wall time only decides when a
checkpoint is written (between chunks). The final state equals that of the
plain calls ``sim.run(steps=S)``, ``sim.run(collisions=C)`` (which also stops
at a freeze) or ``sim.run_until_frozen(max_steps=M)``.

`execute` adds the run directory: ``spec.json``, ``results.h5`` (see
`pinnedballs.io`) and the figures (``*.png``, `pinnedballs.plots`), with
checkpoints, a progress bar and resuming.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Iterator

from .io import RESULTS_NAME, Record, Results, check_out_dir, checkpoint, create, load, write_text_atomic
from .simulation import Simulation
from .errors import InputError
from .specs import RunSpec

__all__ = ["CHUNK_STEPS", "CHUNK_PER_CONTACT", "Interrupted", "advance", "run_to_stop", "execute", "write_figures"]

#: a chunk is at least this many steps ...
CHUNK_STEPS = 1 << 20
#: ... and at least this many per contact (so per-chunk O(contacts) work stays small)
CHUNK_PER_CONTACT = 2
#: a snapshot's checkpoint is skipped (kept for the next one) if the last write was
#: more recent than this many times its own duration: checkpoints stay under ~10 % of the time
_WRITE_COST_RATIO = 10.0


class Interrupted(RuntimeError):
    """The run was stopped by SIGINT/SIGTERM after writing a complete checkpoint."""


# ---------------------------------------------------------------- the loop


def advance(sim: Simulation, steps: int, collisions: int | None = None, until_frozen: bool = False) -> bool:
    """Run at most ``steps`` more steps, stopping at ``collisions`` in total if given, and
    at the exact freeze if ``until_frozen``. Returns True if it stopped because the system froze.
    """
    sim.run(steps=steps, collisions=collisions, until_frozen=until_frozen)
    return until_frozen and sim.is_frozen()


def _counter(sim: Simulation, name: str) -> int:
    return sim.steps if name == "steps" else sim.collisions


def _stop_reason(spec: RunSpec, sim: Simulation, frozen: bool) -> str:
    """Why the run is over (``"steps"``, ``"collisions"``, ``"frozen"``, ``"max_steps"``), or ``""``."""
    stop = spec.stop
    if stop.kind == "steps":
        return "steps" if sim.steps >= stop.steps else ""
    if stop.kind == "collisions" and sim.collisions >= stop.collisions:
        return "collisions"
    if frozen:
        return "frozen"
    if stop.kind == "frozen" and sim.steps >= stop.max_steps:
        return "max_steps"
    return ""


def _next_chunk(spec: RunSpec, sim: Simulation, chunk: int, target: int | None) -> tuple[int, int | None]:
    """``(steps, collisions)`` limits of the next chunk: never past the stop or the next snapshot."""
    stop, counter = spec.stop, spec.snapshots.counter if spec.snapshots else None
    steps, collisions = chunk, stop.collisions
    limit = stop.steps if stop.kind == "steps" else stop.max_steps
    if limit is not None:
        steps = min(steps, limit - sim.steps)
    if target is not None and counter == "steps":
        steps = min(steps, target - sim.steps)
    if target is not None and counter == "collisions":
        collisions = target if collisions is None else min(collisions, target)
    return steps, collisions


def run_to_stop(spec: RunSpec, sim: Simulation, *, snapshots_taken: int = 0,
                on_snapshot: Callable[[Record], None] | None = None,
                after_chunk: Callable[[Simulation], None] | None = None) -> str:
    """Run ``sim`` (built from ``spec``) to ``spec.stop``, calling ``on_snapshot`` at each snapshot.

    ``snapshots_taken`` skips the first snapshots (when resuming). ``after_chunk`` is
    called between chunks (progress, checkpoints). Returns the stop reason.
    """
    snaps = spec.snapshots
    chunk = max(CHUNK_STEPS, CHUNK_PER_CONTACT * sim.geometry.n_contacts)
    until_frozen = spec.stop.kind != "steps"
    n, frozen = snapshots_taken, False
    while True:
        target = snaps.target(n) if snaps else None
        if target is not None and _counter(sim, snaps.counter) == target:
            if on_snapshot is not None:
                on_snapshot(Record.of(sim))
            n += 1
            continue
        if target is not None and _counter(sim, snaps.counter) > target:
            raise RuntimeError(f"snapshot {n} at {snaps.counter} = {target} was missed")
        reason = _stop_reason(spec, sim, frozen)
        if reason:
            return reason
        steps, collisions = _next_chunk(spec, sim, chunk, target)
        frozen = advance(sim, steps, collisions, until_frozen)
        if after_chunk is not None:
            after_chunk(sim)


# ---------------------------------------------------------------- run directories


def execute(spec: RunSpec, out_dir: str | os.PathLike, *, force: bool = False, resume: bool = False,
            progress: bool | None = None, figures: bool = True) -> Path:
    """Run ``spec`` into the directory ``out_dir``; return the path of its ``results.h5``.

    Everything is validated and the simulation built before anything is written.
    A non-empty ``out_dir`` is refused (`InputError`) unless ``force`` (which
    replaces our files) or ``resume`` (which continues from the last checkpoint
    of the same spec; a finished run is left as it is). ``progress``: a tqdm bar
    on stderr; None means only if stderr is a terminal. SIGINT/SIGTERM write a
    checkpoint and raise `Interrupted`.
    """
    out = Path(out_dir)
    path = out / RESULTS_NAME
    if resume and path.exists():
        res = load(path)
        _check_same_run(res, spec)
        if not (out / "spec.json").exists():
            write_text_atomic(out / "spec.json", res.spec.to_json() + "\n")
        if res.complete:
            if figures:
                write_figures(out)
            return path
        _remove(out / _TMP_NAME)
        sim, taken, elapsed = res.simulation(), len(res.snapshots), res.elapsed_seconds
    else:
        sim = spec.build()
        # what a run killed at birth leaves may be resumed over
        check_out_dir(out, force, may_hold=frozenset({"spec.json", _TMP_NAME}) if resume else frozenset(),
                      hint="use --force to overwrite or --resume to continue")
        out.mkdir(parents=True, exist_ok=True)
        _remove(out / _TMP_NAME)
        _remove_figures(out)  # a replaced run's pictures would pass for this one's
        from . import __version__
        create(path, spec, sim.geometry, sim.masses, Record.of(sim), __version__)
        write_text_atomic(out / "spec.json", spec.to_json() + "\n")
        taken, elapsed = 0, 0.0
    _run_with_checkpoints(spec, sim, path, taken, elapsed, progress)
    if figures:
        write_figures(out)
    return path


_TMP_NAME = RESULTS_NAME + ".tmp"


def _check_same_run(res: Results, spec: RunSpec) -> None:
    """Refuse to resume ``res`` with a different spec (checkpoint settings and description may differ)."""
    ignore = {"checkpoint", "description"}
    old, new = res.spec.model_dump(exclude=ignore), spec.model_dump(exclude=ignore)
    where = _first_difference(old, new)
    if where is not None:
        path, a, b = where
        raise InputError(f"{path}: differs from the run in {res.path.parent} ({a!r} there, {b!r} here); "
                         f"run without --resume, and with --force to overwrite it")


def _first_difference(a, b, path: str = "") -> tuple[str, object, object] | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in list(a) + [k for k in b if k not in a]:
            found = _first_difference(a.get(key), b.get(key), f"{path}.{key}" if path else key)
            if found:
                return found
        return None
    return None if a == b else (path, a, b)


def _remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        path.unlink()


class _Checkpointer:
    """Writes checkpoints: every ``every_seconds`` between chunks, and after snapshots."""

    def __init__(self, path: Path, every_seconds: float, elapsed: float):
        self.path, self.every = path, every_seconds
        self.pending: list[Record] = []
        self.start, self.elapsed0 = time.monotonic(), elapsed
        self.last, self.cost = self.start, 0.0

    def elapsed(self) -> float:
        return self.elapsed0 + time.monotonic() - self.start

    def snapshot(self, record: Record, sim: Simulation) -> None:
        self.pending.append(record)
        if time.monotonic() - self.last >= min(self.every, _WRITE_COST_RATIO * self.cost):
            self.write(record)

    def maybe(self, sim: Simulation) -> None:
        if time.monotonic() - self.last >= self.every:
            self.write(Record.of(sim))

    def write(self, state: Record, done: bool = False, reason: str = "") -> None:
        t = time.monotonic()
        checkpoint(self.path, self.pending, state, done=done, stop_reason=reason, elapsed_seconds=self.elapsed())
        self.pending = []
        self.last = time.monotonic()
        self.cost = self.last - t


def _run_with_checkpoints(spec: RunSpec, sim: Simulation, path: Path, taken: int, elapsed: float,
                          progress: bool | None) -> None:
    saver = _Checkpointer(path, spec.checkpoint.every_seconds, elapsed)
    with _progress_bar(spec, sim, progress) as bar, _deferred_signals() as stop_requested:
        def after_chunk(s: Simulation) -> None:
            bar(s)
            if stop_requested():
                saver.write(Record.of(s))
                raise Interrupted(f"interrupted at step {s.steps:,}; the checkpoint in {path.parent} is complete: "
                                  f"continue with --resume")
            saver.maybe(s)

        reason = run_to_stop(spec, sim, snapshots_taken=taken, after_chunk=after_chunk,
                             on_snapshot=lambda record: saver.snapshot(record, sim))
        saver.write(Record.of(sim), done=True, reason=reason)
        bar(sim)


@contextlib.contextmanager
def _deferred_signals() -> Iterator[Callable[[], bool]]:
    """Turn SIGINT/SIGTERM into a request the loop honours between chunks (main thread only).

    A second SIGINT interrupts at once.
    """
    requested = []
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return

    def handler(signum, frame):
        if requested and signum == signal.SIGINT:
            raise KeyboardInterrupt
        requested.append(signum)

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: bool(requested)
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def _progress_bar(spec: RunSpec, sim: Simulation, show: bool | None) -> Iterator[Callable[[Simulation], None]]:
    """A callable updating a tqdm bar on stderr (steps, collisions, rate, ETA); a no-op when not shown."""
    if show is None:
        show = sys.stderr.isatty()
    if not show:
        yield lambda s: None
        return
    from tqdm import tqdm

    stop = spec.stop
    unit, total = ("collisions", stop.collisions) if stop.kind == "collisions" else \
        ("steps", stop.steps if stop.kind == "steps" else stop.max_steps)
    other = "steps" if unit == "collisions" else "collisions"
    with tqdm(total=total, initial=_counter(sim, unit), unit=f" {unit}", unit_scale=True, file=sys.stderr,
              dynamic_ncols=True, delay=0.5, smoothing=0.1) as bar:
        def update(s: Simulation) -> None:
            bar.update(_counter(s, unit) - bar.n)
            bar.set_postfix_str(f"{other}={_counter(s, other):,}", refresh=False)
        yield update


# ---------------------------------------------------------------- figures


def write_figures(run_dir: str | os.PathLike) -> list[Path]:
    """Draw the figures of the run in ``run_dir`` (PNG files beside its results), first removing
    any figures an earlier run left there; the paths written."""
    from .plots import write_figures as draw

    res = load(run_dir)
    _remove_figures(Path(run_dir))
    return list(draw(res, Path(run_dir)))


def _remove_figures(run_dir: Path) -> None:
    from .plots import figure_files

    for old in figure_files(run_dir):
        old.unlink()
