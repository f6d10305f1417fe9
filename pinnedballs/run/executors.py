"""Where an ensemble's jobs run: in this process, on local processes, or on a Dask cluster.

A job is ``(fn, *args)``; each executor returns ``{index: fn(*args)}`` for the jobs given as
``{index: job}``, calling ``tick()`` as each ends. A job whose worker failed (a process that died,
a Dask worker lost) gives ``on_error(index, exc)`` instead of its result, and the others go on.

A worker that dies (killed, out of memory) takes no other job down with it. Dask reschedules
the jobs of a lost worker itself, and gives up (``KilledWorker``) on one that was on workers that
died more often than its scheduler allows (``distributed.scheduler.allowed-failures``): `on_dask`
runs each of those again alone, so that a death there is its own. A local pool breaks as a whole
when one of its processes dies, failing every job still in it: `on_processes` kills the other
processes at once (each job running there is lost too) and runs every job left in a fresh pool, the
lost ones first, in parallel as before; a job lost `LOST_BESIDE_OTHERS` times in pools beside others
then runs alone (the process that kills its pool each time is told apart from those beside it), and
one whose process dies alone `MAX_DEATHS` times is reported (`WorkerDied`), and so is every job left
when pools break `MAX_DEATHS` times in a row before any job ends. Jobs are deterministic, so a job run
again gives the same bits.

A Ctrl-C in the main process stops the ensemble at once: local processes are killed (they ignore
SIGINT themselves, so a terminal's Ctrl-C, which reaches them too, is handled in one place), the
jobs a Dask cluster has not finished are cancelled. A local process also ends when the process that
started it dies (`watch_parent`): a ``kill -9`` of the main process leaves no orphan at work.

Before Dask connects to a ``tcp://`` address, `check_scheduler` reads the server's greeting itself.
A Dask listener speaks first: on every new connection it sends its handshake, one
message framed as ``8 bytes (native uint64) n`` + ``n bytes`` of frames, holding a
dict with ``"pickle-protocol"`` (``distributed.comm.core.Listener.on_connection``).
`distributed.comm.connect` reads that handshake without a timeout and trusts its
length: a server that sends nothing (an HTTP server, a dashboard port) makes it wait
for ever, and one that sends garbage makes it allocate what the first 8 bytes say
(exabytes). `check_scheduler` reads the greeting within the timeout and refuses the
address unless it is a Dask handshake of sane size. The probe closes its connection after
the greeting; a real scheduler logs that at info level ("closed before handshake completed").
Only plain ``tcp://`` addresses are probed (TLS and other transports are left to Dask).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import socket
import struct
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from ..util.errors import InputError
from ..util.extras import need

__all__ = ["in_process", "on_processes", "on_dask", "dask_client", "check_scheduler", "watch_parent", "WorkerDied",
           "MAX_DEATHS", "LOST_BESIDE_OTHERS", "MAX_GREETING", "CONNECT_TIMEOUT", "PARENT_POLL", "ORPHANED"]

#: deaths of the process running a job, alone, after which the job is reported instead of run again (and
#: pools broken in a row before any job ended, after which every job left is)
MAX_DEATHS = 3
#: times a job may be lost in broken pools beside other jobs (running when the pool broke) before it runs
#: alone: once, a worker killed from outside, costs one run again in parallel with the others
LOST_BESIDE_OTHERS = 2
#: seconds between a pool process's checks that the process that started it is alive
PARENT_POLL = 0.5
#: the exit status of a pool process whose parent died
ORPHANED = 70
_PR_SET_PDEATHSIG = 1  # <sys/prctl.h>

#: largest handshake accepted, in bytes (a real one is about 100)
MAX_GREETING = 1 << 16
#: seconds to reach a Dask scheduler: its handshake, then `Client`'s connect
CONNECT_TIMEOUT = 10.0

#: ``on_error(index, exc) -> result`` of a job whose worker failed
OnError = Callable[[int, BaseException], object]


# ---------------------------------------------------------------- executors


def in_process(jobs: dict, tick: Callable[[], None]) -> dict:
    """Run each job here, in order."""
    results = {}
    for k, (fn, *args) in jobs.items():
        results[k] = fn(*args)
        tick()
    return results


class WorkerDied(RuntimeError):
    """The process running a job died (killed, or out of memory?) each time the job ran, alone."""


def on_processes(jobs: dict, workers: int, tick: Callable[[], None], on_error: OnError) -> dict:
    """Run the jobs on ``workers`` local processes; a process that dies costs only its own job (see
    the module's docstring)."""
    results: dict = {}
    with tempfile.TemporaryDirectory(prefix="pinnedballs-jobs-") as marks:
        todo, barren, lost = dict(jobs), 0, {}  # lost: index -> pools broken beside others while it ran
        while todo:
            before = len(results)
            for k in [k for k in todo if lost.get(k, 0) >= LOST_BESIDE_OTHERS]:  # alone: a death is then its own
                _alone(k, todo[k], Path(marks), results, tick, on_error)
            left = {k: job for k, job in todo.items() if k not in results}  # the lost ones first: they ran first
            if left:
                for k in _pool(left, min(workers, len(left)), Path(marks), results, tick, on_error):
                    lost[k] = lost.get(k, 0) + 1
            todo = {k: job for k, job in todo.items() if k not in results}
            barren = barren + 1 if len(results) == before else 0  # the pool broke before any job ended
            if todo and barren == MAX_DEATHS:
                for k in todo:
                    results[k] = on_error(k, WorkerDied(f"the pool's processes died {MAX_DEATHS} times before any "
                                                        f"job ended (killed, or out of memory?)"))
                    tick()
                break
    return results


def _alone(k: int, job, marks: Path, results: dict, tick, on_error: OnError) -> None:
    """Run the job ``k`` alone on a process, again each time that process dies, until it ends or has died
    `MAX_DEATHS` times (then reported); a pool that broke before the job began leaves it to run again."""
    for _ in range(MAX_DEATHS):
        if not _pool({k: job}, 1, marks, results, tick, on_error):
            return
    results[k] = on_error(k, WorkerDied(f"the process running it died {MAX_DEATHS} times (killed, or out of "
                                        f"memory?)"))
    tick()


def _pool(jobs: dict, workers: int, marks: Path, results: dict, tick, on_error: OnError) -> list:
    """Run ``jobs`` on a pool of ``workers`` processes, adding to ``results``; if a process died, the
    jobs that were running then (each marks the file ``<index>`` in ``marks`` while it runs), else []."""
    context = _start_method()
    parent = os.getpid() if context is None else None  # forkserver: the server is the parent
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_starts,
                               initargs=(parent,))
    futures: dict = {}
    try:
        for k, job in jobs.items():
            futures[pool.submit(_marked, marks / str(k), *job)] = k
        for future in as_completed(futures):
            k = futures[future]
            try:
                results[k] = future.result()
            except BrokenProcessPool:
                raise
            except Exception as exc:  # noqa: BLE001 - reported by on_error, the others kept
                results[k] = on_error(k, exc)
            tick()
        return []
    except BrokenProcessPool:  # a process died: the pool fails every job left in it
        # Its survivors are killed here, not left to the pool: on Python 3.11 it only sends them SIGTERM
        # and waits for them, and one may wait for ever on a lock of the call queue that the dead
        # process held (or take SIGTERM as the KeyboardInterrupt of a handler it inherited).
        _kill_workers(pool)
        pool.shutdown(wait=True, cancel_futures=True)
        return _after_break(futures, marks, results, tick)
    except BaseException:  # Ctrl-C (or any failure here): the workers stop now, not after their jobs
        _kill_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _kill_workers(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's processes at once (``shutdown`` alone would wait for the jobs they run)."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(OSError, ValueError, AttributeError):
            process.kill()


def _start_method():
    """How a pool starts its processes: None (the platform's default, fork on Linux: fast, the children
    inherit what this process loaded) unless this process has started numba's GNU OpenMP threads, which
    a forked child cannot use again (numba ends it: "fork() called from a process already using GNU
    OpenMP"; a run on >= 65,536 contacts uses threads). Then the forkserver context: children forked from
    a server process that never started them (preloading pinnedballs, so each starts fast). As with
    spawn, each child imports the main script: a script must keep its top level under
    ``if __name__ == "__main__":``, and a job must be picklable by name or by value."""
    import multiprocessing

    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:  # not started in this process
        return None
    if layer != "omp":
        return None
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["pinnedballs"])
    return context


def _worker_starts(parent: int | None) -> None:
    """A pool process's start: Ctrl-C is the main process's to handle (it stops the workers), SIGTERM
    ends the process, and it dies with its parent (`watch_parent`; None: the process that forked it, a
    forkserver, which ends with the main process), so a ``kill -9`` of the main process leaves no orphan."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the handler of a command line it was forked from
    watch_parent(os.getppid() if parent is None else parent)


def watch_parent(parent: int, every: float = PARENT_POLL) -> None:
    """End this process (exit status `ORPHANED`) as soon as the process ``parent`` that started it is gone.

    Two guards: on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` has the kernel kill this process when
    the thread that forked it ends (which holds for our pools: they live inside one call of the thread
    that made them), even while it runs compiled code that holds the GIL; everywhere, a daemon thread
    checks every ``every`` seconds that this process's parent is still ``parent`` (an orphan is
    re-parented to init or a subreaper)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # it died before the guards were up
        os._exit(ORPHANED)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(every)
        os._exit(ORPHANED)

    threading.Thread(target=watch, name="pinnedballs-watch-parent", daemon=True).start()


def _after_break(futures: dict, marks: Path, results: dict, tick) -> list:
    """The results of the jobs that ended before the pool broke, added to ``results``; the jobs that
    were running when it broke (their marks are removed)."""
    for future, k in futures.items():
        if k not in results and future.done() and not future.cancelled() and future.exception() is None:
            results[k] = future.result()
            tick()
    running = [k for k in futures.values() if k not in results and (marks / str(k)).exists()]
    for k in running:
        (marks / str(k)).unlink()
    return running


def _marked(mark: Path, fn, *args):
    """``fn(*args)``, with the file ``mark`` there while it runs (run on the worker)."""
    mark.touch()
    try:
        return fn(*args)
    finally:
        os.unlink(mark)


def on_dask(client, jobs: dict, tick: Callable[[], None], on_error: OnError) -> dict:
    """Run the jobs on the Dask cluster of ``client``.

    Dask gives up on a job (``KilledWorker``) whose workers died while it was on them, whether it
    killed them or only waited beside the job that did; each such job is run again alone, one after
    the other, so that a death is then its own (a job is deterministic: run again, it gives the same
    bits), and only one whose worker dies when it runs alone is reported. A Ctrl-C cancels every job
    not yet done (Dask cannot stop one already running on a worker)."""
    from distributed import KilledWorker

    results: dict = {}
    suspects: list[int] = []

    def settle(k: int, future) -> None:
        try:
            results[k] = future.result()
        except KilledWorker as exc:
            if k not in suspects:  # the first time: run it again alone
                suspects.append(k)
                return
            results[k] = on_error(k, exc)
        except Exception as exc:  # noqa: BLE001 - reported by on_error, the others kept
            results[k] = on_error(k, exc)
        tick()

    _submitted(client, jobs, settle)
    for k in suspects:
        _submitted(client, {k: jobs[k]}, settle)
    return results


def _submitted(client, jobs: dict, settle: Callable) -> None:
    """Submit the jobs to the cluster of ``client``, calling ``settle(index, future)`` as each ends;
    the jobs not done are cancelled if this stops early (a Ctrl-C)."""
    from dask.distributed import as_completed as dask_completed

    futures = {client.submit(*job, pure=False): k for k, job in jobs.items()}
    try:
        for future in dask_completed(list(futures), loop=client.loop):
            settle(futures[future], future)
    finally:
        client.cancel([f for f in futures if not f.done()])


def dask_client(address: str | None, cluster, option: str = "dask_address"):
    """``(client, owned)``: a Dask client for ``address`` or ``cluster`` (an `InputError` naming ``option``
    if unreachable; a `MissingExtra` naming the ``dask`` extra without Dask)."""
    Client = need("dask.distributed", "a Dask cluster", "dask").Client
    from distributed.comm.addressing import get_address_host_port

    if cluster is not None and isinstance(cluster, Client):
        return cluster, False
    if cluster is None:
        try:  # before Client(): a half-built one prints a traceback when collected
            get_address_host_port(address)
        except (ValueError, TypeError) as exc:
            raise InputError(f"{option} {address}: not a Dask scheduler address such as tcp://host:8786 "
                             f"({' '.join(str(exc).split())})") from None
        check_scheduler(address, CONNECT_TIMEOUT, option)  # Dask itself hangs or crashes on a non-Dask server
    try:
        return Client(cluster if cluster is not None else address, timeout=f"{CONNECT_TIMEOUT}s",
                      set_as_default=False), True
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        what = f"{option} {address}" if address is not None else "cluster"
        raise InputError(f"{what}: cannot connect to a Dask scheduler ({' '.join(str(exc).split())})") from None


# ---------------------------------------------------------------- is a Dask scheduler listening?


def check_scheduler(address: str, timeout: float, option: str = "dask_address") -> None:
    """Raise an `InputError` naming ``option`` unless the ``tcp://`` server at ``address`` greets
    like a Dask scheduler within ``timeout`` seconds. A refused or unreachable address passes:
    `distributed.Client` retries it until its own timeout and reports it."""
    need("distributed", "a Dask cluster", "dask")
    from distributed.comm.addressing import get_address_host_port, parse_address

    if parse_address(address)[0] != "tcp":
        return
    host, port = get_address_host_port(address)
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError:
        return
    try:
        header = _read(sock, 8, deadline)
        (size,) = struct.unpack("Q", header)
        if not 0 < size <= MAX_GREETING:
            raise _NotDask(f"its greeting announces {size} bytes")
        greeting = _decode(_read(sock, size, deadline))
        if not (isinstance(greeting, dict) and "pickle-protocol" in greeting):
            raise _NotDask("its greeting is not a Dask handshake")
    except TimeoutError:
        raise InputError(f"{option} {address}: not a Dask scheduler (no Dask handshake within {timeout:g} s; "
                         f"a dashboard or another server?)") from None
    except _NotDask as exc:
        raise InputError(f"{option} {address}: not a Dask scheduler ({exc})") from None
    except OSError as exc:
        raise InputError(f"{option} {address}: not a Dask scheduler (the connection failed during the "
                         f"handshake: {' '.join(str(exc).split())})") from None
    finally:
        sock.close()


class _NotDask(Exception):
    """The server answered, but not as a Dask scheduler."""


def _read(sock: socket.socket, n: int, deadline: float) -> bytes:
    """Exactly ``n`` bytes from ``sock`` before ``deadline`` (``time.monotonic``)."""
    chunks, got = [], 0
    while got < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        chunk = sock.recv(n - got)
        if not chunk:
            raise _NotDask(f"it closed the connection after {got} of {n} bytes of its greeting"
                           if got or n != 8 else "it closed the connection without a greeting")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _decode(data: bytes):
    """The message in a Dask frame block, or `_NotDask` if it is not one."""
    from distributed.protocol import loads
    from distributed.protocol.utils import unpack_frames

    try:
        if len(data) < 8 or struct.unpack_from("Q", data)[0] > len(data) // 8:
            raise ValueError("frame count beyond the data")
        frames, buffers = unpack_frames(data, partial=True)
        if buffers:
            raise ValueError("unexpected buffers")
        return loads(frames, deserialize=False)
    except Exception as exc:  # noqa: BLE001 - any failure to decode untrusted bytes means "not Dask"
        raise _NotDask(f"its greeting does not decode as a Dask message: {type(exc).__name__}") from None
