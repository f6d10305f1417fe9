"""Output directories: can one be written, who holds it, and taking one for a new run.

`check_writable` refuses, before anything is written, an output path that cannot
become a writable directory (a dangling symlink, a regular file on the way, a read-only
file system, a directory without write permission). `DirLock` is an exclusive OS lock
(``flock``) on ``DIR/.pinnedballs.lock``: one run, ensemble or reproduction at a time
writes into a directory. The kernel drops the lock when its process dies, so a killed
run never blocks its own ``--resume``; the lock file a killed run leaves is harmless. A forked child (a
pool's worker) closes its copy of the lock at once: an ``flock`` lives while any process holds its file
open, so a worker still dying after its parent's ``kill -9`` would otherwise keep the directory locked.
`made_for` removes again the directories a refused command made for its output (``a/``, ``a/b/`` of
``--out a/b/out``): nothing written means none.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import weakref
from collections.abc import Iterator
from pathlib import Path

from ..util.atomic import remove, tmp_path, unwritable
from ..util.errors import InputError
from .format import DATA_DIR, RESULTS_NAME

__all__ = ["LOCK_NAME", "BIRTH", "DirLock", "holder", "check_writable", "unwritable", "check_resumable", "take_run_dir",
           "check_out_dir", "first_missing", "remove_made", "made_for"]

#: the lock file in a locked directory (removed when the lock is released)
LOCK_NAME = ".pinnedballs.lock"


def _fail(option: str, path: Path, problem: str) -> InputError:
    return InputError(f"{option} {path}: {problem}")


def check_writable(out: str | os.PathLike, option: str = "--out") -> Path:
    """``out`` as a Path if it is, or can be created as, a directory we may write into;
    else an `InputError` naming ``option`` and the path at fault. Writes nothing."""
    out = Path(out)
    problem = unwritable(out)
    if problem is not None:
        raise _fail(option, out, problem)
    return out


def first_missing(path: str | os.PathLike) -> Path | None:
    """The outermost of ``path`` and its parents that does not exist (None if ``path`` exists), absolute."""
    missing, path = None, Path(path).absolute()
    while not path.exists() and path != path.parent:
        missing, path = path, path.parent
    return missing


def remove_made(out: str | os.PathLike, made: Path | None) -> None:
    """Remove ``out`` and its parents up to ``made`` (`first_missing` before they were made), innermost
    first, each only while it is empty: one that holds anything stays, and so do those above it."""
    if made is None:
        return
    for directory in [Path(out).absolute(), *Path(out).absolute().parents]:
        if not directory.is_relative_to(made):
            break
        try:
            directory.rmdir()
        except OSError:  # holds something (or is gone): it and those above stay
            break


@contextlib.contextmanager
def made_for(out: str | os.PathLike) -> Iterator[None]:
    """A block that may make the directory ``out`` and its missing parents: if it raises, those it made are
    removed again where they are empty (`remove_made`), so a command refused after making them leaves none."""
    made = first_missing(out)
    try:
        yield
    except BaseException:
        remove_made(out, made)
        raise


#: the locks this process holds (a forked child closes its copies: `_forked`)
_HELD: weakref.WeakSet = weakref.WeakSet()


def _forked() -> None:
    """In a forked child: close the copies of the parent's locks, which stay the parent's alone."""
    for lock in list(_HELD):
        lock.forget()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forked)


class DirLock:
    """An exclusive lock on the directory ``out`` (created if missing), held until `release`
    or the death of the process (not of a child it forks). ``option`` names the directory in errors."""

    def __init__(self, out: str | os.PathLike, option: str = "--out"):
        self.dir, self.option = Path(out), option
        self.path = self.dir / LOCK_NAME
        self._file = None

    @property
    def held(self) -> bool:
        return self._file is not None

    def acquire(self) -> DirLock:
        """Take the lock; an `InputError` naming the directory and the holder's pid if another
        process (or another lock in this one) holds it, or if the directory cannot be written."""
        if self.held:
            return self
        check_writable(self.dir, self.option)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            while True:
                f = open(self.path, "a+", encoding="ascii")
                try:
                    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    f.seek(0)
                    holder = f.read().strip() or "unknown"
                    f.close()
                    raise _fail(self.option, self.dir, f"in use by another run (pid {holder}); wait for it to "
                                                       f"end or choose another directory") from None
                except BaseException:
                    f.close()
                    raise
                if _same_file(f, self.path):  # not a file a releasing holder just removed
                    break
                f.close()
            f.seek(0)
            f.truncate()
            f.write(f"{os.getpid()}\n")
            f.flush()
        except OSError as exc:
            raise _fail(self.option, self.dir, exc.strerror or str(exc)) from None
        self._file = f
        _HELD.add(self)
        return self

    def forget(self) -> None:
        """Close this process's copy of a held lock without releasing it (a forked child's copy: an ``flock`` is
        dropped by an unlock or by its last descriptor's close, so the process that took it keeps it)."""
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()  # the pid was flushed when it was written: nothing is left to write
        self._file = None
        _HELD.discard(self)

    def release(self) -> None:
        """Remove the lock file and drop the lock (a no-op if not held)."""
        if self._file is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        except OSError:
            pass
        self._file.close()
        self._file = None
        _HELD.discard(self)

    def __enter__(self) -> DirLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def holder(out: str | os.PathLike) -> int | None:
    """The pid of the live process that holds the lock on the directory ``out``, or None (no lock file:
    released; a lock file whose process is gone: left by a kill). Reads only, and takes no lock."""
    try:
        pid = int((Path(out) / LOCK_NAME).read_text(encoding="ascii").strip())
    except (OSError, ValueError):
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:  # alive, another user's
        pass
    return pid


def _same_file(f, path: Path) -> bool:
    try:
        a, b = os.fstat(f.fileno()), os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ENOENT:
            return False
        raise
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


#: what a run killed before its first checkpoint may leave beside its lock file
BIRTH = frozenset({"spec.json", DATA_DIR, RESULTS_NAME + ".tmp"})
#: the files a run writes in ``results.data/``: the static data, the segments, their temporary files
_OURS = re.compile(r"(static|frames_\d+)\.h5(\.tmp)?")
_SEGMENT = re.compile(r"frames_\d+\.h5(\.tmp)?")


def check_resumable(out: str | os.PathLike, option: str = "--out", *, start: bool = True,
                    hint: str = "check the path, or start a run without --resume") -> str | None:
    """What continuing the run in ``out`` finds there, before anything is written: None if ``out``
    holds a run (its index, ``results.h5``), else why it holds none yet, when the run may start there:
    "no such directory", "an empty directory", or "only what a run killed before its first checkpoint
    left" (a lock file, ``spec.json``, ``results.data/`` without segments). With ``start`` False a
    missing or empty directory is refused instead (``hint`` says what to do), as a Python writer's
    ``resume=True`` refuses one. Anything else is refused (an `InputError` naming ``option``): other
    files; segments without their index (a run whose index is lost: never started over); an index
    that is a dangling link or a loop of links; a file or folder in ``results.data/`` that no run wrote."""
    out = check_writable(out, option)
    index = out / RESULTS_NAME
    if index.is_symlink() and not index.exists():
        raise _fail(option, out, f"{RESULTS_NAME} is {_broken_link(index)}; the run's index cannot be read: "
                                 f"put {RESULTS_NAME} back, or choose another directory")
    if index.exists():
        _data_files(out, option)
        return None
    if not out.is_dir() or not any(p.name != LOCK_NAME for p in out.iterdir()):
        why = "no such directory" if not out.is_dir() else "an empty directory"
        if not start:
            raise _fail(option, out, f"{why}, so no run to continue; {hint}")
        return why
    segments = [p for p in _data_files(out, option) if _SEGMENT.fullmatch(p.name)]
    if segments:
        raise _lost_index(option, out, segments)
    others = sorted(p.name for p in out.iterdir()
                    if p.name != LOCK_NAME and (p.name not in BIRTH or (p.name == DATA_DIR and not p.is_dir())))
    if others:
        shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
        raise _fail(option, out, f"holds no run to continue, but other files ({shown}); choose another directory, "
                                 f"or write into this one with --force instead of --resume")
    return "only what a run killed before its first checkpoint left"


def _broken_link(path: Path) -> str:
    """What is wrong with the symbolic link ``path`` that leads to no file."""
    try:
        os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a loop of symbolic links"
    return f"a dangling symbolic link (to {os.readlink(path)})"


def _data_files(out: Path, option: str) -> list[Path]:
    """The files in ``out/results.data/`` (none if it is missing); an `InputError` naming the first
    entry no run wrote (a user's file or folder), which no command may remove or write beside."""
    data = out / DATA_DIR
    if not data.is_dir():
        return []
    entries = sorted(data.iterdir())
    for p in entries:
        if not _OURS.fullmatch(p.name) or p.is_symlink() or not p.is_file():
            what = "a folder" if p.is_dir() else "a file"
            raise _fail(option, out, f"{DATA_DIR}/{p.name} is {what} no run wrote; move it out of {DATA_DIR}/ "
                                     f"(a run's own data goes there)")
    return entries


def _lost_index(option: str, out: Path, segments: list[Path]) -> InputError:
    names = ", ".join(p.name for p in segments[:2]) + (", ..." if len(segments) > 2 else "")
    return _fail(option, out, f"{RESULTS_NAME} is missing, but {DATA_DIR}/ holds {len(segments)} segment(s) of a run "
                              f"({names}): its index is lost, and nothing was written over it; put {RESULTS_NAME} "
                              f"back (from a backup), or move the directory away to start anew (pinnedballs info "
                              f"{out} says what the segments hold)")


def take_run_dir(out: str | os.PathLike, *, force: bool = False, may_hold: frozenset[str] = frozenset(),
                 hint: str = "use --force to overwrite or --resume to continue", option: str = "--out") -> Path:
    """The run directory ``out``, made ready for a new run (the one place a run directory is taken).

    Refuses (`InputError` naming ``option``) a file, or a directory holding anything beyond
    ``may_hold`` unless ``force``; with ``force``, removes the results a run left there.
    """
    out = check_out_dir(out, force, may_hold=may_hold, hint=hint, option=option)
    files = _data_files(out, option)  # a user's own file there is never removed, even with force
    segments = [p for p in files if _SEGMENT.fullmatch(p.name)]
    if segments and not force and not (out / RESULTS_NAME).exists():
        raise _lost_index(option, out, segments)
    out.mkdir(parents=True, exist_ok=True)
    remove(out / RESULTS_NAME)
    remove(tmp_path(out / RESULTS_NAME))
    for p in files:
        p.unlink()
    return out


def check_out_dir(out: str | os.PathLike, force: bool, *, may_hold: frozenset[str] = frozenset(),
                  hint: str = "use --force to write into it", option: str = "--out") -> Path:
    """``out`` as a Path; an `InputError` naming ``option`` if it cannot be written (`check_writable`),
    or is a directory holding anything beyond ``may_hold`` (and a lock file) without ``force``."""
    out = check_writable(out, option)
    if out.is_dir() and not force:
        entries = sorted(p.name for p in out.iterdir() if p.name != LOCK_NAME)
        if not set(entries) <= may_hold:
            shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
            raise InputError(f"{option} {out}: directory is not empty ({shown}); {hint}")
    return out
