"""Where a chain runs, as an object (HOOMD-blue's ``hoomd.device.CPU`` / ``GPU``): `CPU` and `CUDA` carry what
belongs to the device (the CPU's threads; the GPU's index, and whether numba-cuda's simulator stands in for it).

A device is information about a run, not part of its model: the same spec and seed give the same bits on
either. The strings ``"cpu"`` and ``"cuda"`` are taken wherever a device is (`as_device`), in Python, specs'
runs and on the command line. Devices are plain data: which engine runs a chain on one, and whether one is
here at all, is the door's to say (`engine.door.choose`, `engine.door.ready`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..util import checks
from ..util.errors import FieldTypeError

__all__ = ["Device", "CPU", "CUDA", "as_device", "DEVICE_NAMES"]


@dataclass(frozen=True)
class Device:
    """A device a chain runs on; `CPU` or `CUDA`.

    Attributes
    ----------
    kind : str
        Its name, as a string names it (``"cpu"``).
    gpu : bool
        Whether it is a GPU: its state lives in the GPU's memory, its chains run by reservations there.
    """

    kind: ClassVar[str] = ""
    #: whether it is a GPU: its state lives in the GPU's memory, its chains run by reservations there
    gpu: ClassVar[bool] = False

    def __str__(self) -> str:
        return self.kind


@dataclass(frozen=True)
class CPU(Device):
    """This machine's CPU.

    Parameters
    ----------
    threads : int or None
        The threads a chain may use (None: as many as pay, up to numba's ``NUMBA_NUM_THREADS``); a scheduler's
        own ``threads=`` wins where it names one. The bits never depend on it.

    Raises
    ------
    FieldError
        On ``threads`` outside [1, 65536].

    Examples
    --------
    >>> import pinnedballs as pb
    >>> pb.CPU(threads=1)
    CPU(threads=1)
    >>> str(pb.CPU())
    'cpu'
    """

    kind: ClassVar[str] = "cpu"
    threads: int | None = None

    def __post_init__(self):
        if self.threads is not None:
            checks.integer("threads", self.threads, 1, 1 << 16)


@dataclass(frozen=True)
class CUDA(Device):
    """An NVIDIA GPU, through numba-cuda (``python3 -m pip install ".[cuda]"``); numba-cuda's simulator
    (``NUMBA_ENABLE_CUDASIM=1``) stands in for one, with the same bits, on the CPU.

    Parameters
    ----------
    device : int
        The GPU's index among those numba-cuda sees (0: the first). The bits never depend on it.

    Raises
    ------
    FieldError
        On ``device`` outside [0, 1024].

    Examples
    --------
    >>> import pinnedballs as pb
    >>> pb.CUDA()
    CUDA(device=0)
    >>> pb.CUDA().gpu
    True
    """

    kind: ClassVar[str] = "cuda"
    gpu: ClassVar[bool] = True
    device: int = 0

    def __post_init__(self):
        checks.integer("device", self.device, 0, 1 << 10)


#: a device by its name, as specs and the command line give it
DEVICE_NAMES: dict[str, type[Device]] = {"cpu": CPU, "cuda": CUDA}


def as_device(device) -> Device:
    """``device`` as a `Device`: the strings ``"cpu"`` and ``"cuda"`` are taken wherever a device is.

    Parameters
    ----------
    device : Device or str or None
        A `Device` already, or its name (``"cpu"``, ``"cuda"``); None is the CPU.

    Returns
    -------
    Device

    Raises
    ------
    FieldError
        On ``device``, for another name (a `FieldTypeError` for what is neither a device nor a name).

    Examples
    --------
    >>> from pinnedballs.engine import as_device
    >>> as_device("cuda"), as_device(None)
    (CUDA(device=0), CPU(threads=None))
    """
    if device is None:
        return CPU()
    if isinstance(device, Device):
        return device
    if isinstance(device, str):
        return DEVICE_NAMES[checks.choice("device", device, tuple(DEVICE_NAMES))]()
    raise FieldTypeError("device", f"must be a device such as pb.CPU() or pb.CUDA(), or its name 'cpu' or 'cuda', "
                                   f"got {type(device).__name__}")
