"""The command line's Ctrl-C handler (`pinnedballs.util.startup`) is the program's: ``python -m pinnedballs``
and the ``pinnedballs`` script set it up in ``__main__``; importing the library leaves Python's handler
(tests/run/cli/test_ctrl_c.py sends the Ctrl-Cs)."""

from __future__ import annotations

import signal
import subprocess
import sys

from pinnedballs.util import startup


def handler_after(code: str) -> str:
    """The SIGINT handler's name in a fresh process after ``code``."""
    probe = f"{code}\nimport signal; print(getattr(signal.getsignal(signal.SIGINT), '__name__', '?'))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                          check=True).stdout.strip()


def test_importing_the_library_keeps_pythons_handler():
    assert handler_after("import pinnedballs as pb; pb.HalfPlane") == "default_int_handler"


def test_the_programs_main_sets_its_handler_before_the_command_line_imports():
    assert handler_after("import pinnedballs.__main__; import sys; assert 'numpy' not in sys.modules") == \
        "_at_once_outside_main"


def test_a_handler_of_its_own_stands():
    """The command line's handler replaces Python's default only, never one the caller chose."""
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        startup.from_the_first_instant()
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)
