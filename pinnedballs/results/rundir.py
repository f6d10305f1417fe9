"""Output directories: can one be written, who holds it, and taking one for a new run.

`check_writable` refuses, before anything is written, an output path that cannot
become a writable directory (a dangling symlink, a regular file on the way, a read-only
file system, a directory without write permission). `DirLock` is an exclusive OS lock
(``flock``) on ``DIR/.pinnedballs.lock``: one run, ensemble or reproduction at a time
writes into a directory. The kernel drops the lock when its process dies, so a killed
run never blocks its own ``--resume``; the lock file a killed run leaves is harmless.
"""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

from ..engine.errors import InputError
from ..engine.atomic import remove, tmp_path
from .format import DATA_DIR, RESULTS_NAME

__all__ = ["LOCK_NAME", "DirLock", "holder", "check_writable", "check_resumable", "take_run_dir", "check_out_dir"]

#: the lock file in a locked directory (removed when the lock is released)
LOCK_NAME = ".pinnedballs.lock"


def _fail(option: str, path: Path, problem: str) -> InputError:
    return InputError(f"{option} {path}: {problem}")


def check_writable(out: str | os.PathLike, option: str = "--out") -> Path:
    """``out`` as a Path if it is, or can be created as, a directory we may write into;
    else an `InputError` naming ``option`` and the path at fault. Writes nothing."""
    out = Path(out)
    if out.is_symlink() and not out.exists():
        raise _fail(option, out, f"is a dangling symbolic link (to {os.readlink(out)})")
    if out.exists() and not out.is_dir():
        raise _fail(option, out, "exists and is not a directory")
    existing = out
    while not existing.is_dir():
        parent = existing.parent
        if existing.is_symlink() and not existing.exists():
            raise _fail(option, out, f"{existing} is a dangling symbolic link")
        if existing.exists() or parent == existing:
            raise _fail(option, out, f"{existing} is not a directory")
        existing = parent
    if not os.access(existing, os.W_OK | os.X_OK):
        raise _fail(option, out, f"{existing} is not writable ({_why(existing)})")
    return out


def _why(path: Path) -> str:
    """Why ``path`` cannot be written: a read-only file system, or permissions."""
    try:
        if os.statvfs(path).f_flag & os.ST_RDONLY:
            return "read-only file system"
    except OSError:
        pass
    return "permission denied"


class DirLock:
    """An exclusive lock on the directory ``out`` (created if missing), held until `release`
    or the death of the process. ``option`` names the directory in errors."""

    def __init__(self, out: str | os.PathLike, option: str = "--out"):
        self.dir, self.option = Path(out), option
        self.path = self.dir / LOCK_NAME
        self._file = None

    @property
    def held(self) -> bool:
        return self._file is not None

    def acquire(self) -> "DirLock":
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
        return self

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

    def __enter__(self) -> "DirLock":
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


def check_resumable(out: str | os.PathLike, option: str = "--out",
                    hint: str = "check the path, or start a run without --resume") -> Path:
    """``out`` as a Path if it may hold a run to continue; an `InputError` naming ``option`` if it is
    missing or empty: continuing nothing would start hours of computation somewhere unintended (a
    mistyped path) while the user believes a run goes on. A directory holding only what a run killed
    before its first checkpoint leaves (a lock file, ``results.data/``, ``spec.json``) passes: that run
    starts again from the beginning."""
    out = Path(out)
    if not out.is_dir():
        raise InputError(f"{option} {out}: no such directory, so no run to continue; {hint}")
    if not any(out.iterdir()):
        raise InputError(f"{option} {out}: an empty directory, so no run to continue; {hint}")
    return out


def take_run_dir(out: str | os.PathLike, *, force: bool = False, may_hold: frozenset[str] = frozenset(), hint: str = "use --force to overwrite or --resume to continue",
                 option: str = "--out") -> Path:
    """The run directory ``out``, made ready for a new run (the one place a run directory is taken).

    Refuses (`InputError` naming ``option``) a file, or a directory holding anything beyond
    ``may_hold`` unless ``force``; with ``force``, removes the results a run left there.
    """
    out = check_out_dir(out, force, may_hold=may_hold, hint=hint, option=option)
    out.mkdir(parents=True, exist_ok=True)
    remove(out / RESULTS_NAME)
    remove(tmp_path(out / RESULTS_NAME))
    data = out / DATA_DIR
    if data.is_dir():
        for p in data.iterdir():
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
