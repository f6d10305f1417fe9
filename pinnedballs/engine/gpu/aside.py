"""Under numba-cuda's simulator, a rule checked as a GPU checks it: compiled for one in a process of its own.

The simulator runs a rule's plain-Python twin, which any Python runs (``math.exp`` there has the CPU's
rounding): numba-cuda never compiles it, so it cannot say what a GPU would refuse (`compile.check_rule`). `verdict`
hands the rule's functions (pickled by numba's serializer: a module's by reference, a notebook's by value) to a
child process without the simulator (``NUMBA_ENABLE_CUDASIM=0``), which compiles them for sm_90 as a GPU's
machine does (`compile._refusal`: NVVM alone, no GPU needed) and answers with the verdict. It is kept in this
process, and on disk beside numba's cache (``NUMBA_CACHE_DIR``, else `cache_root`), under a digest of the source
of every function the rule reaches, of numba-cuda's version and of this package's (`verdict_key`), so the next
process, or the next ``pinnedballs run --device cuda``, asks none (a child takes seconds).

The built-in rules are not asked: their code is the package's, which the tests compile for a GPU
(tests/engine/gpu/test_gpu.py: no fused multiply-add), and no GPU refuses them. Where no child can compile for
a GPU (numba-cuda's NVVM missing, the ``cu13`` extra), a user's rule is refused on ``device``, saying so: the
simulator cannot show a run a GPU would not make.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from ..._version import __version__
from ...util.atomic import write_text_atomic
from ...util.errors import FieldError
from ..closing import impulse_of
from ..jit.cache import cache_root, reachable_functions, source_key

__all__ = ["verdict", "builtin", "verdict_key", "CHILD"]

#: what the child runs: the rule's impulse (or its whole ``collide``), dim and flat pickled on stdin; on stdout
#: ``{"verdict": [kind, said, where] or null}``, or ``{"unchecked": why}`` where it cannot compile for a GPU
CHILD = r"""
import json, pickle, sys
from pinnedballs.engine.closing import impulse_rule
from pinnedballs.engine.gpu.compile import SIMULATED, _refusal
from numba.cuda.cudadrv import nvvm

impulse, collide, dim, flat = pickle.loads(sys.stdin.buffer.read())
if SIMULATED or not nvvm.is_available():
    print(json.dumps({"unchecked": "numba-cuda's NVVM is not installed "
                                   "(python3 -m pip install \".[cuda]\" in the checkout)"}))
else:
    collide = impulse_rule(impulse) if impulse is not None else collide
    print(json.dumps({"verdict": _refusal(collide, dim, flat)}))
"""

#: seconds the child may take (a compile for a GPU takes seconds; minutes on a loaded machine)
_TIMEOUT = 600
#: this package's files whose code a verdict depends on beside the rule's (the probe and its trial)
_HERE = Path(__file__).resolve().parent
KEY_FILES = (_HERE / "compile.py", _HERE / "aside.py")


def builtin(collide: Callable) -> bool:
    """Whether every function of the rule's ``collide`` (its impulse too) is this package's: a built-in rule."""
    own = [getattr(f, "py_func", f) for f in (collide, impulse_of(collide)) if f is not None]
    functions = [*own, *(g for f in own for g in reachable_functions(f))]
    return all((f.__module__ or "").startswith("pinnedballs.") for f in functions)


def verdict_key(collide: Callable, dim: int, flat: bool) -> str | None:
    """The digest a verdict is kept under on disk: the rule's sources (`jit.cache.source_key`), ``dim``, ``flat``,
    numba-cuda's version, this package's and `KEY_FILES`; None where the rule's source cannot be keyed."""
    from importlib.metadata import version

    rule = source_key(getattr(collide, "py_func", collide))
    if rule is None:
        return None
    h = hashlib.sha256(f"{rule} {dim} {bool(flat)} {version('numba-cuda')} {__version__}".encode())
    for path in KEY_FILES:
        h.update(path.read_bytes())
    return h.hexdigest()


@functools.cache
def verdict(collide: Callable, dim: int, flat: bool) -> tuple[str, str, str] | None:
    """What `compile._refusal` says of the rule's ``collide`` on a GPU's machine (None: it runs there with the
    CPU's bits), asked of a child process once (module docstring); a `FieldError` on ``device`` where the child
    cannot compile for a GPU."""
    if builtin(collide):
        return None
    key = verdict_key(collide, dim, flat)
    path = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_root()) / "gpu_rules" / f"{key}.json" if key else None
    try:
        return _found(json.loads(path.read_text(encoding="utf-8")))
    except (AttributeError, OSError, ValueError, KeyError, TypeError):  # none kept (or unreadable): ask
        pass
    answer = _ask(collide, dim, flat)
    if path is not None and "verdict" in answer:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomic(path, json.dumps(answer) + "\n")
        except OSError:  # a cache that cannot be written: the next process asks again
            pass
    return _found(answer)


def _found(answer: dict) -> tuple[str, str, str] | None:
    if "unchecked" in answer:
        raise FieldError("device", f"under numba-cuda's simulator a user's rule is checked as a GPU would check it, "
                                   f"and here it cannot be: {answer['unchecked']}")
    found = answer["verdict"]
    return None if found is None else tuple(found)


def _ask(collide: Callable, dim: int, flat: bool) -> dict:
    """The child's answer (`CHILD`) for the rule's ``collide``; a `FieldError` on ``device`` saying why there is
    none (its functions cannot be pickled, or the child failed)."""
    from numba.core import serialize

    impulse = impulse_of(collide)
    try:
        data = serialize.dumps((impulse, None if impulse is not None else collide, int(dim), bool(flat)))
    except Exception as exc:  # noqa: BLE001 - pickle's errors have no common base
        raise FieldError("device", f"under numba-cuda's simulator a user's rule is checked as a GPU would check "
                                   f"it, in a process of its own, and this one cannot be handed to one ({exc})") \
            from None
    path = os.pathsep.join(p or os.getcwd() for p in sys.path)  # the rule's module is found as it is here
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "0", "PYTHONPATH": path}
    try:
        out = subprocess.run([sys.executable, "-c", CHILD], input=data, capture_output=True, env=env,
                             timeout=_TIMEOUT)
    except subprocess.TimeoutExpired:
        out = subprocess.CompletedProcess(CHILD, -1, b"", f"no answer in {_TIMEOUT} s".encode())
    lines = out.stdout.decode(errors="replace").splitlines()
    if out.returncode != 0 or not lines:
        said = (out.stderr.decode(errors="replace").strip().splitlines() or ["no output"])[-1]
        raise FieldError("device", f"under numba-cuda's simulator a user's rule is checked as a GPU would check it, "
                                   f"and the check failed: {said}")
    return json.loads(lines[-1])
