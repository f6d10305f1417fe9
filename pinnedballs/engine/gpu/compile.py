"""A rule's arithmetic on a GPU: the CPU's own functions, compiled by numba-cuda with the CPU's rounding.

The kernels call the functions the CPU's loops call (`engine.closing.trial_form`, `engine.margin.track`,
a rule's ``collide`` or impulse, a user's included); numba-cuda compiles a CPU-jitted function called from a
kernel for the device. Two things keep the GPU's bits the CPU's:

* **No contraction.** NVVM contracts ``a * b + c`` into ``fma.rn.f64`` by default, which rounds once where
  the CPU rounds twice. numba-cuda 0.30 has no option for NVVM's ``-fma=0`` (NVIDIA/numba-cuda#118; the
  ``fma=`` of ``cuda.jit`` proposed in its pull request #839 is used where present), so `contraction_off`
  adds ``fma=False`` to the NVVM options of the compiles made inside it: the kernels' own, never anyone
  else's. Products and sums then compile to ``mul.rn.f64`` and ``add.rn.f64``.
* **No other roundings.** Division and square roots are correctly rounded on both; libdevice's other
  functions (``exp``, ``log``, ``sin``, ``pow`` with a fractional exponent, ``hypot``, ...) are not libm's,
  and their code fuses products on purpose. So a rule whose device code, compiled without contraction,
  still holds a fused multiply-add would not give the CPU's bits: `check_rule` refuses it in one line,
  as it refuses a rule numba-cuda cannot compile (saying so where numba cannot compile it for the CPU
  either), before anything runs; under the simulator too, compiled aside for a GPU (`aside`).

Under numba-cuda's simulator (the tests' CPU stand-in for a GPU) kernels are Python: `device_function` gives
a jitted function's plain-Python *twin* (`python_twin`), every jitted function it reaches replaced by its own
twin, so the same source runs there too, with the CPU's rounding (Python's floats are IEEE doubles).
"""

from __future__ import annotations

import contextlib
import functools
import re
import threading
import types
from collections.abc import Callable

import numpy as np
from numba.core.dispatcher import Dispatcher

from ...util.errors import FieldError, described
from ..closing import choose, choose_python, impulse_of, trial_form
from ..field import limbs
from ..jit.cache import code_names
from ..jit.failures import CompileFailure, numba_errors, place, said

__all__ = ["SIMULATED", "contraction_off", "device_function", "device_trial", "python_twin", "check_rule", "ptx",
           "ROUNDING"]

try:  # numba-cuda >= 0.2x keeps its own configuration
    from numba.cuda.core import config as _cuda_config
except ImportError:  # pragma: no cover - older numba-cuda reads numba's
    from numba.core import config as _cuda_config

#: True under numba-cuda's simulator: kernels run as Python threads on the CPU
SIMULATED = bool(getattr(_cuda_config, "ENABLE_CUDASIM", 0))
if SIMULATED:  # its shared arrays allocated under a lock (`simulator`): else a thread may get one of its own
    from .simulator import mend

    mend()

_OFF = threading.local()  # how deep the calling thread is inside `contraction_off`


def _without_fma(compile_ir: Callable) -> Callable:
    @functools.wraps(compile_ir)
    def compile_ir_without_fma(llvmir, **options):
        if getattr(_OFF, "depth", 0) > 0:
            options["fma"] = False
        return compile_ir(llvmir, **options)

    compile_ir_without_fma.contraction_off = True
    return compile_ir_without_fma


@contextlib.contextmanager
def contraction_off():
    """NVVM told not to contract products and sums (``-fma=0``) in the compiles made inside (this thread's)."""
    if SIMULATED:
        yield
        return
    from numba.cuda.cudadrv import nvvm

    if not getattr(nvvm.compile_ir, "contraction_off", False):
        nvvm.compile_ir = _without_fma(nvvm.compile_ir)
    _OFF.depth = getattr(_OFF, "depth", 0) + 1
    try:
        yield
    finally:
        _OFF.depth -= 1


# ---------------------------------------------------------------- the simulator's twins

#: jitted callables that are no Python functions (numba intrinsics, and functions built on them), and what their
#: twins call instead
_INTRINSICS = {choose: choose_python, limbs._mac_intrinsic: limbs._mac_python,
               limbs._mac_top_intrinsic: limbs._mac_top_python, limbs._mac_diff_intrinsic: limbs._mac_diff_python,
               limbs._next_limb_jit: limbs._next_limb_python}


def device_function(f: Callable) -> Callable:
    """``f`` as a kernel calls it: the jitted function itself on a GPU (numba-cuda compiles it for the device),
    its plain-Python twin under the simulator."""
    return python_twin(f) if SIMULATED else f


@functools.cache
def device_trial(collide: Callable, dim: int, flat: bool) -> Callable:
    """The rule's trial (`engine.closing.trial_form`: ``(hit, w)`` of a contact) as the kernels call it."""
    return device_function(trial_form(collide, dim, flat))


def python_twin(f: Callable) -> Callable:
    """The plain-Python function behind the jitted ``f``, with each jitted function it reaches through its
    globals or its closure replaced by its own twin (``f`` itself when it is not jitted)."""
    return _twin(f, {})


def _twin(f, memo: dict):
    if _hashable(f) and f in _INTRINSICS:
        return _INTRINSICS[f]
    if not isinstance(f, Dispatcher):
        return f
    if id(f) in memo:
        return memo[id(f)]
    py = f.py_func
    closure = tuple(types.CellType(_twin(cell.cell_contents, memo)) for cell in py.__closure__ or ())
    scope = dict(py.__globals__)
    twin = types.FunctionType(py.__code__, scope, py.__name__, py.__defaults__, closure or None)
    memo[id(f)] = twin
    for name in code_names(py.__code__):
        if name in scope:
            scope[name] = _twin(scope[name], memo)
    return twin


def _hashable(value) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


# ---------------------------------------------------------------- a rule that would not give the CPU's bits

_FMA = re.compile(r"\bfma\.[a-z.]*f64")


def ptx(kernel: Callable, signature, cc: tuple[int, int] = (9, 0)) -> str:
    """The PTX of ``kernel`` (a Python function, compiled as a kernel) for ``signature`` and compute capability
    ``cc``, without contraction; no GPU needed (NVVM alone)."""
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda

    with contraction_off(), _device_of(cc, dispatcher):
        return cuda.compile_ptx(kernel, signature, cc=cc)[0]


@contextlib.contextmanager
def _device_of(cc: tuple[int, int], dispatcher):
    """Without a GPU, numba-cuda still asks the current device's compute capability when it compiles a called
    function on its own: answer ``cc`` meanwhile."""
    from numba import cuda

    if cuda.is_available():
        yield
        return
    asked = dispatcher.get_current_device
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=cc)
    try:
        yield
    finally:
        dispatcher.get_current_device = asked


#: a rule that calls a function a GPU rounds otherwise, in the words of a refusal
ROUNDING = ("it calls a function (exp, log, sin, pow, hypot, ...) that a GPU computes with other roundings than "
            "the CPU, so its bits would differ")


@functools.cache
def _refusal(collide: Callable, dim: int, flat: bool) -> tuple[str, str, str] | None:
    """Why the rule's trial cannot run on a GPU with the CPU's bits, or None: ``("rounding", "", "")`` (`ROUNDING`),
    ``("gpu", said, where)`` (numba-cuda cannot compile it: numba's words and the place, `jit.failures`) or
    ``("cpu", said, where)`` (numba cannot compile it for the CPU either)."""
    trial = trial_form(collide, dim, flat)

    def probe(v, units, masses, params, out):
        hit, w = trial(v, units, masses, params, np.int64(0), np.int64(1), np.int64(0), np.int64(1), True)
        out[0] = w if hit else 0.0

    from numba import cuda

    a2, a1 = cuda.types.Array(cuda.types.float64, 2, "C"), cuda.types.Array(cuda.types.float64, 1, "C")
    try:
        code = ptx(probe, (a2, a2, a1, a1, a1))
    except Exception as exc:  # noqa: BLE001 - numba's errors have no common base; all are said in one line
        own = impulse_of(collide) or collide  # a rule by its impulse: the impulse is the user's code
        return _on_the_cpu(trial, own) or ("gpu", said(exc), place(exc, own))
    if _FMA.search(code):
        return "rounding", "", ""
    return None


def _on_the_cpu(trial: Callable, own: Callable) -> tuple[str, str, str] | None:
    """``("cpu", said, where)`` when numba cannot compile the rule's ``trial`` for the CPU either (``own``: the
    user's function, named where numba names no place), else None."""
    from numba import njit
    from numba import types as nt

    @njit
    def probe(v, units, masses, params, write, out):
        hit, w = trial(v, units, masses, params, np.int64(0), np.int64(1), np.int64(0), np.int64(1), write)
        out[0] = w if hit else 0.0

    a2, a1 = nt.Array(nt.float64, 2, "C"), nt.Array(nt.float64, 1, "C")
    try:
        probe.compile((a2, a2, a1, a1, nt.boolean, a1))
    except numba_errors() as exc:
        return "cpu", said(exc), place(exc, own)
    return None


def check_rule(rule, collide: Callable, dim: int, flat: bool) -> None:
    """A `FieldError` on ``rule`` when ``collide`` (of ``rule``) cannot run on a GPU with the CPU's bits: numba-cuda
    cannot compile it, or it calls a function the GPU rounds otherwise (module docstring); a
    `jit.failures.CompileFailure` when numba cannot compile it for the CPU either. Compiles it for the GPU once (no
    GPU needed); under the simulator in a process of its own that compiles for a GPU (`aside.verdict`), so the
    simulator refuses what a GPU refuses, in the same words."""
    if SIMULATED:
        from .aside import verdict

        found = verdict(collide, dim, flat)
    else:
        found = _refusal(collide, dim, flat)
    if found is None:
        return
    kind, numba_said, where = found
    if kind == "cpu":
        raise CompileFailure("rule", rule, numba_said, where, gpu=True)
    why = ROUNDING if kind == "rounding" else f"numba-cuda cannot compile it: {numba_said} ({where})"
    raise FieldError("rule", f"{described(rule)} cannot run on a GPU: {why}; device='cpu' runs it")
