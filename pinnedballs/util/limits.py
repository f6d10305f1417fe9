"""What the machine can hold: memory for a run's arrays, and the float64 range for its velocities.

`check_memory` refuses an allocation larger than the memory available now;
`run_bytes` estimates what a geometry of ``n_balls`` and ``n_contacts`` costs, so
any geometry (or its spec) can call ``check_memory(run_bytes(...), ...)`` before
allocating. `check_speeds` refuses velocities whose collisions could overflow.
"""

from __future__ import annotations

import math
import os

import numpy as np

from .errors import FieldError
from .sums import kinetic_energy

__all__ = ["available_memory", "check_memory", "run_bytes", "format_bytes", "format_count",
           "check_speeds", "ENERGY_LIMIT", "SPEED_LIMIT"]

_FLOAT_MAX = float(np.finfo(np.float64).max)
#: margin against rounding drift: the energy and every squared speed stay 2**10 below overflow
_MARGIN = 2.0 ** 10
ENERGY_LIMIT = _FLOAT_MAX / _MARGIN  #: largest total energy accepted (about 1.8e305)
SPEED_LIMIT = math.sqrt(_FLOAT_MAX / _MARGIN)  #: largest speed any ball may reach (about 4.2e152)


# ---------------------------------------------------------------- memory


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            text = f.read().split()[0]
        return int(text)
    except (OSError, ValueError, IndexError):
        return None


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_available() -> int | None:
    """Bytes left under this process's cgroup memory limit (v2, then v1), or None if unlimited."""
    for limit, usage in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                         ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                          "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        cap, used = _read_int(limit), _read_int(usage)
        if cap is not None and used is not None and cap < 1 << 60:
            return max(cap - used, 0)
    return None


def available_memory() -> int | None:
    """Bytes of memory this process can still allocate (the smaller of the system's available
    memory and the cgroup's remaining limit), or None if this system does not say."""
    known = [b for b in (_meminfo_available(), _cgroup_available()) if b is not None]
    return min(known) if known else None


def format_bytes(n: float) -> str:
    """``n`` bytes in a readable unit: ``"1.5 GB"``; ``"10^21 bytes"`` from 1000 PB on (any int)."""
    if n >= 10**18:
        return f"10^{math.floor(math.log10(n))} bytes"
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} PB"


def format_count(n: int) -> str:
    """``n`` in full up to 15 digits, else ``"~10^k"`` (keeps messages one short line)."""
    return str(n) if abs(n) < 10**15 else f"~10^{math.floor(math.log10(abs(n)))}"


def check_memory(nbytes: int, field: str, what: str) -> None:
    """Raise a `FieldError` on ``field`` if ``what`` needs more than the `available_memory`.

    ``nbytes`` is the estimate (see `run_bytes`); ``what`` names it in the message,
    e.g. ``"a 1000000 x 1000000 flat torus"``.
    """
    available = available_memory()
    if available is not None and nbytes > available:
        raise FieldError(field, f"{what} needs about {format_bytes(nbytes)} of memory, more than the "
                                f"{format_bytes(available)} this machine has available")


def run_bytes(n_balls: int, n_contacts: int, dim: int = 2, embed: int | None = None) -> int:
    """An estimate, from above, of the bytes a run of this size holds at once.

    Per ball: its centre ``(embed,)``, three copies of its velocity ``(dim,)`` (the
    simulation's, a checkpoint's and a snapshot's), its frame ``(dim, embed)`` and the
    incidence pointer. Per contact: ``pairs`` and ``ends`` (int64 while built), a unit
    vector at each end ``(2, dim)``, two incidence entries and a live flag. Times 2 for
    the temporaries of building the tables.
    """
    embed = dim if embed is None else embed
    per_ball = 8 * (embed + 3 * dim + dim * embed + 1)
    per_contact = 8 * 2 + 8 * 2 + 8 * 2 * dim + 4 * 2 + 1
    return 2 * (int(n_balls) * per_ball + int(n_contacts) * per_contact)


# ---------------------------------------------------------------- float64 range


def check_speeds(v: np.ndarray, masses: np.ndarray, field: str = "velocities") -> None:
    """Raise a `FieldError` on ``field`` unless no collision from velocities ``v`` ``(n_balls, dim)``
    with ``masses`` ``(n_balls,)`` can overflow float64.

    The bound. Let ``F`` be the largest float64 (1.8e308) and ``E = sum m_i |v_i|^2 / 2``
    the energy, computed as `Simulation.energy` does (``|v_i|^2`` first). A collision
    never raises the exact energy (``r <= 1``); rounding moves it by a relative 1e-16 or
    so per collision. Since ``m_i |v_i|^2 / 2 <= E`` at all times, no ball ever moves
    faster than ``S = sqrt(2 E / m_min)`` (the lightest ball may end up with all the
    energy). In a collision of ``i`` and ``j``, with unit vectors ``t_i, t_j``:

    - closing speed: ``|w| = |v_i . t_i + v_j . t_j| <= |v_i| + |v_j| <= 2 S``, and by
      Cauchy-Schwarz every partial sum of the component-wise products is bounded so too;
    - impulse: ``(1 + r) m_j / (m_i + m_j) |w| <= 2 |w| <= 4 S``, computed as
      ``((1 + r) w / (m_i + m_j)) * m_j``, whose factors are no larger;
    - new components: ``|v_ik - impulse t_ik| <= S + 4 S = 5 S``;
    - energy: each ``|v_i|^2 <= S^2``, and the mass-weighted sum is about ``2 E``.

    So all is finite when ``E`` and ``S^2`` are finite; we ask for a margin of ``2**10``
    against rounding drift: ``E <= F / 2**10`` (`ENERGY_LIMIT`) and ``S <= sqrt(F / 2**10)``
    (`SPEED_LIMIT`, 4.2e152), far above any physical use.
    """
    with np.errstate(all="ignore"):
        energy = kinetic_energy(masses, v)
        speed = math.sqrt(2.0 * energy / float(masses.min())) if np.isfinite(energy) else math.inf
    if not np.isfinite(energy):
        raise FieldError(field, "the total energy sum m |v|^2 / 2 overflows float64")
    if energy > ENERGY_LIMIT:
        raise FieldError(field, f"the total energy {energy:.3g} is above {ENERGY_LIMIT:.3g}, so collisions "
                                f"could overflow float64")
    if not speed <= SPEED_LIMIT:
        raise FieldError(field, f"with energy {energy:.3g} and lightest mass {float(masses.min()):.3g} a ball "
                                f"could reach speed sqrt(2E/m_min) = {speed:.3g}, above {SPEED_LIMIT:.3g}, so "
                                f"collisions could overflow float64")
