# The engine's door, `from pinnedballs.engine import engines, register, ...`: each name imported from its module
# when first used (`lazy_loader.attach_stub` reads this file; type checkers and the API page read it too).
from .devices import CPU as CPU
from .devices import CUDA as CUDA
from .devices import Device as Device
from .devices import as_device as as_device
from .door import check as check
from .door import choose as choose
from .door import engines as engines
from .door import find as find
from .door import register as register
from .door import unregister as unregister
from .protocol import Backend as Backend
from .protocol import Engine as Engine
from .protocol import Refusal as Refusal
from .protocol import Refused as Refused
