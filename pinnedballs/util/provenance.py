"""Provenance: how an output was made, written into the output itself (as GROMACS and LAMMPS log it, and as
HOOMD-blue's users asked for in hoomd-blue#1439).

An *entry* is a plain JSON-able dict: one per life of a run (a resumed run appends one, `results.format`), one
per ensemble (``summary.json``). `entry` gives what this process knows of itself; the run adds what it used::

    versions  {"pinnedballs", "python", "numpy", "numba", "llvmlite", "h5py": their versions; "numba-cuda": a GPU
              run's}: read from the installed packages' metadata, so reading one imports nothing
    command   the command line (``"pinnedballs run spec.json --out DIR"``, `command_line`), or the Python call
              (``"python script.py: pinnedballs.run_spec"``, `python_call`); argv: the process's ``sys.argv``
    host      the host name; platform: ``platform.platform()``
    cpu       {"model": the CPU's name, "cores": logical CPUs, "usable": those this process may run on,
              "l2_cache": bytes (absent where unreadable), "flags": its vector extensions (avx2, avx512f, ...)}
    device    what ran it, from the run (`engine.protocol.Backend.resources`): {"kind": "cpu", "threads": k,
              "tuned": {count: share of the work}, where a `ThreadTuner` chose the count}, or {"kind": "cuda",
              "gpu": its name, "compute_capability": "9.0"} ({"gpu": "simulated"} under numba-cuda's simulator)
    started, ended  UTC, ISO 8601 (``"2026-12-01T23:30:53Z"``); ended None until the life's first checkpoint

`problem` checks an entry read back; `lines` says a list of them in a few lines (``pinnedballs info``).
Nothing here changes a bit of a run: provenance is metadata only.
"""

from __future__ import annotations

import contextlib
import contextvars
import datetime
import importlib.metadata
import os
import platform
import shlex
import socket
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

__all__ = ["PACKAGES", "entry", "versions", "cpu", "cpu_line", "now", "command", "command_line", "python_call",
           "script", "problem", "lines"]

#: the packages whose versions every entry records (where installed)
PACKAGES = ("numpy", "numba", "llvmlite", "h5py")
#: the vector extensions of a CPU an entry names (x86's, then Arm's)
VECTOR_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512vl", "asimd", "sve", "sve2")
#: the keys every entry has, and their types (`problem`)
REQUIRED = {"versions": dict, "command": str, "host": str, "device": dict, "started": str}

_COMMAND: contextvars.ContextVar[str | None] = contextvars.ContextVar("pinnedballs_command", default=None)


def now() -> str:
    """The time now, UTC, ISO 8601 to the second: ``"2026-12-01T23:30:53Z"``."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def versions(pinnedballs: str, extra: Sequence[str] = ()) -> dict[str, str]:
    """``{"pinnedballs": pinnedballs, "python": ..., package: version}`` of `PACKAGES` and ``extra`` (e.g.
    ``("numba-cuda",)``), those installed; read from their metadata (nothing is imported)."""
    out = {"pinnedballs": str(pinnedballs), "python": platform.python_version()}
    for name in (*PACKAGES, *extra):
        with contextlib.suppress(importlib.metadata.PackageNotFoundError):
            out[name] = importlib.metadata.version(name)
    return out


def cpu() -> dict:
    """The CPU: ``{"model", "cores", "usable", "l2_cache" (bytes, where readable), "flags"}`` (module docstring)."""
    info = _cpuinfo()
    cores = os.cpu_count() or 1
    out = {"model": info.get("model name") or info.get("Model") or platform.processor() or platform.machine(),
           "cores": cores}
    with contextlib.suppress(AttributeError, OSError):
        out["usable"] = len(os.sched_getaffinity(0))
    l2 = _l2_cache()
    if l2 is not None:
        out["l2_cache"] = l2
    flags = set((info.get("flags") or info.get("Features") or "").split())
    out["flags"] = [f for f in VECTOR_FLAGS if f in flags]
    return out


def cpu_line(info: dict | None = None) -> str:
    """The CPU in one line, as a benchmark prints it beside its figures: ``"CPU: AMD EPYC (family 26 model 2), 2
    cores, L2 2 MiB a core, sse4_2 avx avx2 fma avx512f avx512vl"`` (``info``: `cpu`'s dict; None: this one)."""
    c = cpu() if info is None else info
    raw = _cpuinfo() if info is None else {}
    model = c.get("model", "unknown")
    if raw.get("cpu family") and raw.get("model"):
        model += f" (family {raw['cpu family']} model {raw['model']})"
    l2 = c.get("l2_cache")
    size = "L2 unknown" if l2 is None else f"L2 {l2 >> 20} MiB a core" if l2 >= 1 << 20 else f"L2 {l2 >> 10} KiB a core"
    return f"CPU: {model}, {c.get('cores')} cores, {size}, {' '.join(c.get('flags') or ['no vector flags read'])}"


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields in ``/proc/cpuinfo`` (empty where there is none)."""
    out: dict[str, str] = {}
    with contextlib.suppress(OSError, UnicodeDecodeError):
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            key, sep, value = line.partition(":")
            if not sep:
                if out:
                    break  # the first processor's block ends at its blank line
                continue
            out.setdefault(key.strip(), value.strip())
    return out


def _l2_cache() -> int | None:
    """The bytes of the first CPU's level-2 cache (Linux's ``/sys``), or None where unreadable."""
    units = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
    for index in sorted(Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")):
        with contextlib.suppress(OSError, ValueError):
            if (index / "level").read_text().strip() == "2":
                size = (index / "size").read_text().strip()
                return int(size[:-1]) * units[size[-1]] if size[-1] in units else int(size)
    return None


# ---------------------------------------------------------------- the command


@contextlib.contextmanager
def command_line(argv: Sequence[str]) -> Iterator[None]:
    """Within the block, outputs record the command line ``pinnedballs ARGV`` (`cli.main`)."""
    token = _COMMAND.set(shlex.join(["pinnedballs", *map(str, argv)]))
    try:
        yield
    finally:
        _COMMAND.reset(token)


@contextlib.contextmanager
def python_call(name: str) -> Iterator[None]:
    """Within the block, outputs record the Python call ``name`` (``"pinnedballs.run_spec"``), unless an outer
    command line or call is recorded already (a command line's run goes through `run_spec`'s code too)."""
    if _COMMAND.get() is not None:
        yield
        return
    token = _COMMAND.set(f"python {script()}: {name}")
    try:
        yield
    finally:
        _COMMAND.reset(token)


def command(call: str) -> str:
    """The command line or Python call recorded (`command_line`, `python_call`), else the Python call ``call``."""
    return _COMMAND.get() or f"python {script()}: {call}"


def script() -> str:
    """The script this process runs, as a reader names it: its file's name, ``-m package`` (its ``__main__``),
    ``-c``, or ``(interactive)``."""
    first = sys.argv[0] if sys.argv else ""
    if first in ("", "-", "-c"):
        return "-c" if first == "-c" else "(interactive)"
    path = Path(first)
    return f"-m {path.parent.name}" if path.name == "__main__.py" else path.name


def entry(pinnedballs: str, call: str, device: dict, extra: Sequence[str] = ()) -> dict:
    """An entry (module docstring) begun now: this process's versions (with ``extra`` packages), its command
    (``call``: the Python call it is, where no command line or call is recorded), host, platform and CPU, and
    ``device``: what the run used; ``ended`` None."""
    return {"versions": versions(pinnedballs, extra), "command": command(call), "argv": list(map(str, sys.argv)),
            "host": socket.gethostname(), "platform": platform.platform(), "cpu": cpu(), "device": dict(device),
            "started": now(), "ended": None}


# ---------------------------------------------------------------- reading back


def _time(value) -> datetime.datetime | None:
    """The time ``value`` says, if it is ISO 8601 text with its offset from UTC (`now`); else None."""
    if not isinstance(value, str):
        return None
    try:
        t = datetime.datetime.fromisoformat(value)
    except ValueError:
        return None
    return t if t.tzinfo is not None else None


def problem(item) -> str | None:
    """What is wrong with ``item`` as an entry (module docstring), in words; None if it is one."""
    if not isinstance(item, dict):
        return f"must be a JSON object, got {type(item).__name__}"
    for key, kind in REQUIRED.items():
        if not isinstance(item.get(key), kind):
            return f"{key}: must be {'text' if kind is str else 'a JSON object'}, got {_short(item.get(key))}"
    named = item["versions"]
    if not {"pinnedballs", "python"} <= set(named) or not all(isinstance(v, str) for v in named.values()):
        return f"versions: must give pinnedballs's and python's (text), got {_short(named)}"
    if not isinstance(item["device"].get("kind"), str):
        return f"device: must say its kind (text), got {_short(item['device'])}"
    threads = item["device"].get("threads")
    if threads is not None and not (isinstance(threads, int) and not isinstance(threads, bool) and threads >= 1):
        return f"device: threads must be a count >= 1, got {_short(threads)}"
    started, ended = _time(item["started"]), item.get("ended")
    if started is None:
        return f"started: must be a time (ISO 8601, UTC), got {_short(item['started'])}"
    if ended is not None and (_time(ended) is None or _time(ended) < started):
        return f"ended: must be a time (ISO 8601, UTC) not before started, got {_short(ended)}"
    steps = item.get("steps")
    if steps is not None and not (isinstance(steps, list) and len(steps) == 2 and all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in steps) and steps[0] <= steps[1]):
        return f"steps: must be [first, last] step counts, got {_short(steps)}"
    return None


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# ---------------------------------------------------------------- in words


def lines(entries: Sequence[dict], label: int = 13) -> list[str]:
    """A few lines on ``entries`` (a run's lives, or an ensemble's one), the latest said in full, each
    beginning with its label padded to ``label`` characters; none recorded: one line saying so."""
    if not entries:
        return ["made by:".ljust(label) + "not recorded (written before outputs kept their provenance)"]
    last = entries[-1]
    v = last["versions"]
    made = f"pinnedballs {v['pinnedballs']} on Python {v['python']}" + "".join(
        f", {name} {v[name]}" for name in ("numpy", "numba", "numba-cuda") if name in v)
    when = f"started {_when(last['started'])}, " + (
        f"ended {_when(last['ended'])}" if last.get("ended") else "not ended (no checkpoint yet)")
    if len(entries) > 1:
        when += f"; resumed {len(entries) - 1} time{'s' if len(entries) > 2 else ''}, first started " \
                f"{_when(entries[0]['started'])}"
    first = (entries[0].get("steps") or [0])[0]
    if first:  # a run begun by a pinnedballs that kept no provenance, resumed by one that does
        when += f"; its lives before step {first:,} not recorded"
    return ["made by:".ljust(label) + made,
            "ran on:".ljust(label) + _device(last),
            "command:".ljust(label) + last["command"],
            "host:".ljust(label) + f"{last['host']}; {when}"]


def _when(stamp: str) -> str:
    return stamp.replace("T", " ").replace("Z", " UTC")


#: the limited loops in words, and what chose them (`engine.sequential.sizes`, `engine.sequential.choice`)
_LOOPS = {"tables": "the table loop", "prefetched": "the prefetched table loop", "rows": "the row-pattern loop"}
_CHOSEN = {"size": "by its size", "measured": "timed on this CPU", "threshold": "by the share of collisions",
           "forced": "forced"}


def _loop(loop: dict) -> str:
    """``"the table loop (by its size), 87% of its picks without a branch (timed on this CPU)"``."""
    name = loop.get("name")
    said = _LOOPS.get(name, f"the {name} loop") if isinstance(name, str) else "the table loop"
    if isinstance(loop.get("by"), str):
        said += f" ({_CHOSEN.get(loop['by'], loop['by'])})"
    if isinstance(loop.get("branch_free"), (int, float)):
        said += f", {float(loop['branch_free']):.0%} of its picks without a branch"
        if isinstance(loop.get("blocks"), str):
            said += f" ({_CHOSEN.get(loop['blocks'], loop['blocks'])})"
    return said


def _device(item: dict) -> str:
    """``"CPU: AMD EPYC (2 cores, AVX2), 2 threads"``, or the GPU's name and compute capability."""
    c, d = item.get("cpu") or {}, item["device"]
    flags = [f.upper() for f in ("avx512f", "avx2", "sve", "asimd") if f in (c.get("flags") or ())][:1]
    cores = c.get("cores")
    said = f"CPU: {c.get('model', 'unknown')}" + (f" ({', '.join([f'{cores} cores', *flags])})" if cores else "")
    if "gpu" in d:  # a GPU's entry names it
        gpu = d["gpu"]
        return (f"GPU: simulated (numba-cuda's simulator on the {said})" if gpu == "simulated" else
                f"GPU: {gpu}" + (f" (compute capability {d['compute_capability']})" if "compute_capability" in d
                                 else "") + f"; {said}")
    if "threads" in d:
        threads = d["threads"]
        said += f", {threads} thread{'s' if threads != 1 else ''}"
        tuned = d.get("tuned")
        if isinstance(tuned, dict) and len(tuned) > 1:
            said += " (chosen by the tuner: " + ", ".join(f"{k} on {float(s):.0%}" for k, s in tuned.items()) + ")"
    if isinstance(d.get("loop"), dict) and d["loop"]:
        said += "; " + _loop(d["loop"])
    if isinstance(d.get("setting"), str) and d["setting"] not in said:
        said += f" ({d['setting']})"
    for key in ("workers", "dask"):
        if key in d:
            said += f"; {key} {d[key]}"
    return said
