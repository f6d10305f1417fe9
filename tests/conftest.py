"""Shared test setup: the helpers (`helpers.py`), the plain-Python twin (`reference.py`) and a
user's module (`user_components.py`) are importable from every test folder."""

import importlib.util
import os
import pathlib
import sys

import pytest

# The GPU engine's kernels run under numba-cuda's simulator (Python threads on the CPU): CI has no GPU,
# and the simulator runs the same kernel source. numba-cuda reads this when it is first imported.
os.environ.setdefault("NUMBA_ENABLE_CUDASIM", "1")

sys.path.insert(0, str(pathlib.Path(__file__).parent))

import signal

# The tests send SIGINT to themselves and to the processes they start. A suite started as a
# background job (`cmd &` in a script, nohup) inherits SIGINT ignored, which Python then leaves
# ignored and every child inherits: the interrupt tests would test nothing. Python's own handler
# here (in the main process and in each xdist worker) gives every child the default again.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: numba-cuda installed (the cuda extra): the GPU engine's tests run under its simulator; without it they skip
HAS_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
NO_NUMBA_CUDA = ("numba-cuda is not installed: the GPU engine's tests need it (python3 -m pip install \".[cuda]\", "
                 "then python3 -m pytest -q -m cuda)")


def pytest_collection_modifyitems(config, items):
    """Tests marked ``cuda`` skip, saying why, where numba-cuda is missing (the README's test line installs the
    test extra alone)."""
    if HAS_NUMBA_CUDA:
        return
    for item in items:
        if item.get_closest_marker("cuda") is not None:
            item.add_marker(pytest.mark.skip(reason=NO_NUMBA_CUDA))
