"""Files written whole or not at all: through a temporary file beside the target, flushed and
renamed over it, so that a kill, a Ctrl-C or a full disk never leaves half of one. Results files,
specs, reports and figures are all written this way; `unwritable` says, before anything is written,
why a directory could not be."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

__all__ = ["write_text_atomic", "write_bytes_atomic", "written_atomically", "tmp_path", "remove", "unwritable"]


@contextlib.contextmanager
def written_atomically(path: str | os.PathLike):
    """A temporary path beside ``path`` for a library to write a whole file into; flushed and renamed
    over ``path`` if the block succeeds, removed if it fails (so ``path`` is never half written)."""
    path = Path(path)
    tmp = tmp_path(path)
    try:
        yield tmp
        _commit(tmp, path)
    except BaseException:
        remove(tmp)
        raise


def tmp_path(path: Path) -> Path:
    return path.with_name(path.name + ".tmp")


def remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        path.unlink()


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: a kill leaves the
    old file or the new one, never half of one."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename; if writing fails
    (a full disk), the temporary file is removed and ``path`` is as it was."""
    path = Path(path)
    tmp = tmp_path(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
        _commit(tmp, path)
    except BaseException:
        remove(tmp)
        raise


def _commit(tmp: Path, path: Path) -> None:
    """Flush ``tmp`` to disk and rename it over ``path`` (atomic on POSIX)."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def unwritable(out: Path) -> str | None:
    """Why ``out`` cannot be, or be created as, a directory we may write into (None if it can):
    ``"is a dangling symbolic link (to X)"``, ``"X is not a directory"``, ``"X is not writable
    (read-only file system)"``, ... Writes nothing."""
    if out.is_symlink() and not out.exists():
        return f"is a dangling symbolic link (to {os.readlink(out)})"
    if out.exists() and not out.is_dir():
        return "exists and is not a directory"
    existing = out
    while not existing.is_dir():
        parent = existing.parent
        if existing.is_symlink() and not existing.exists():
            return f"{existing} is a dangling symbolic link"
        if existing.exists() or parent == existing:
            return f"{existing} is not a directory"
        existing = parent
    if not os.access(existing, os.W_OK | os.X_OK) or _read_only(existing):
        return f"{existing} is not writable ({_why(existing)})"
    return None


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def _why(path: Path) -> str:
    """Why ``path`` cannot be written: a read-only file system, or permissions."""
    return "read-only file system" if _read_only(path) else "permission denied"
