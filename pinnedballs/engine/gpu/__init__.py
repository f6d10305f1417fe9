"""The chain on an NVIDIA GPU (numba-cuda), with the bits of the CPU loop on the counter stream.

`load` imports numba-cuda (the optional ``[cuda]`` extra) and says in one line what is missing: the
package, or a GPU its driver can see. Nothing here imports numba-cuda before a GPU run asks for it.
Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernels run on the CPU, one block of
Python threads: the tests run them so.

Any rule runs: the kernels call the rule's own functions, the ones the CPU's loops call, compiled for the
device with the CPU's rounding (`compile`). Modules: `compile` (a rule's functions on the device, their
simulator twins, the one-line refusal of a rule that would not give the CPU's bits), `device` (the counter
stream and the contact readers as device functions), `kernels` (a chain by deterministic reservations; the
freeze scan), `chain` (`DeviceChain`: one simulation's chain on the GPU), `replicas` (many small systems,
one GPU thread each), `certified` (certified arithmetic's picks on the GPU, by the same reservations).
"""

from __future__ import annotations

import numpy as _np

from ...util.errors import FieldError

if not hasattr(_np, "row_stack"):  # numba-cuda 0.30 overloads np.row_stack, which numpy 2.5 removed:
    _np.row_stack = _np.vstack     # without it, its first compile fails (AttributeError: row_stack)

__all__ = ["load", "importable", "describe", "GPUUnavailable", "INSTALL"]

#: how to install what a GPU run needs
INSTALL = 'python3 -m pip install ".[cuda]" (from the checkout)'

class GPUUnavailable(FieldError):
    """A GPU run was asked for where none can run: numba-cuda missing, or no GPU its driver sees.

    A `FieldError` on ``device``: the command line says it in one line and exits with status 2.

    Parameters
    ----------
    problem : str
        What is missing.
    """

    def __init__(self, problem: str):
        super().__init__("device", problem)

    def __reduce__(self):
        return type(self), (self.problem,)


def importable():
    """numba-cuda's ``cuda`` module (no GPU needed); else `GPUUnavailable` saying it is not installed, in one line."""
    try:
        import numba_cuda  # noqa: F401 - numba itself still ships an older numba.cuda, which this engine cannot use
        from numba import cuda
    except ImportError as exc:
        raise GPUUnavailable(f"'cuda' needs numba-cuda, which is not installed ({INSTALL}): {exc}") from None
    return cuda


def load():
    """numba-cuda's ``cuda`` module, ready to launch kernels; else `GPUUnavailable` saying why, in one line."""
    cuda = importable()
    from .compile import SIMULATED

    if not SIMULATED and not cuda.is_available():
        raise GPUUnavailable("'cuda' found no GPU: numba-cuda sees no CUDA driver or device here (nvidia-smi "
                             "should list one); device 'cpu' gives the same bits on the counter stream")
    return cuda


def describe() -> dict:
    """The GPU this process's kernels run on, as a run's provenance records it (`util.provenance`): ``{"gpu": its
    name, "compute_capability": "9.0"}``, or ``{"gpu": "simulated"}`` under numba-cuda's simulator (`compile.SIMULATED`:
    the kernels as Python threads on the CPU). Asked once a GPU run has loaded numba-cuda (`load`)."""
    from .compile import SIMULATED

    if SIMULATED:
        return {"gpu": "simulated"}
    from numba import cuda

    gpu = cuda.get_current_device()
    name = gpu.name.decode() if isinstance(gpu.name, bytes) else str(gpu.name)
    major, minor = gpu.compute_capability
    return {"gpu": name, "compute_capability": f"{major}.{minor}"}
