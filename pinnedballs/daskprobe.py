"""Is a Dask scheduler listening at an address? A raw TCP probe of its greeting, before Dask connects.

A Dask listener speaks first: on every new connection it sends its handshake, one
message framed as ``8 bytes (native uint64) n`` + ``n bytes`` of frames, holding a
dict with ``"pickle-protocol"`` (``distributed.comm.core.Listener.on_connection``).
`distributed.comm.connect` reads that handshake without a timeout and trusts its
length: a server that sends nothing (an HTTP server, a dashboard port) makes it wait
for ever, and one that sends garbage makes it allocate what the first 8 bytes say
(exabytes). `check_scheduler` reads the greeting itself, within the timeout, and
refuses the address unless it is a Dask handshake of sane size. The probe closes
its connection after the greeting; a real scheduler logs that at info level
("closed before handshake completed").
Only plain ``tcp://`` addresses are probed (TLS and other transports are left to Dask).
"""

from __future__ import annotations

import socket
import struct
import time

from .errors import InputError

__all__ = ["check_scheduler", "MAX_GREETING"]

#: largest handshake accepted, in bytes (a real one is about 100)
MAX_GREETING = 1 << 16


def check_scheduler(address: str, timeout: float, option: str = "dask_address") -> None:
    """Raise an `InputError` naming ``option`` unless the ``tcp://`` server at ``address`` greets
    like a Dask scheduler within ``timeout`` seconds. A refused or unreachable address passes:
    `distributed.Client` retries it until its own timeout and reports it."""
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
    except (socket.timeout, TimeoutError):
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
