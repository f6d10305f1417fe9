"""Which process is the command line starting (`pinnedballs.util.startup`): only ``python -m pinnedballs``
and the ``pinnedballs`` program get its Ctrl-C handler while the package imports; a program that imports the
package, or runs another of its modules, keeps Python's (tests/cli/test_ctrl_c.py sends the Ctrl-Cs)."""

from __future__ import annotations

import signal
import sys

import pytest

from pinnedballs.util import startup


@pytest.mark.parametrize("argv, orig_argv, starting", [
    (["-m"], ["python3", "-m", "pinnedballs", "run"], True),
    (["-m"], ["python3", "-u", "-mpinnedballs", "run"], True),
    (["-m"], ["python3", "-m", "pinnedballs.__main__"], True),
    (["-m"], ["python3", "-m", "pinnedballs.run.ensemble"], False),   # another module's program
    (["-m"], ["python3", "-m", "pytest"], False),
    (["/usr/local/bin/pinnedballs", "run"], ["python3", "/usr/local/bin/pinnedballs", "run"], True),
    (["analysis.py"], ["python3", "analysis.py"], False),
    (["-c"], ["python3", "-c", "import pinnedballs"], False),
])
def test_only_the_command_line_is_starting(monkeypatch, argv, orig_argv, starting):
    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(sys, "orig_argv", orig_argv)
    assert startup.starts_the_command_line() is starting


def test_a_program_importing_the_package_keeps_its_handler(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["analysis.py"])
    before = signal.getsignal(signal.SIGINT)
    startup.from_the_first_instant(only_if_starting=True)
    assert signal.getsignal(signal.SIGINT) is before


def test_a_handler_of_its_own_stands(monkeypatch):
    """The command line's handler replaces Python's default only, never one the caller chose."""
    monkeypatch.setattr(sys, "argv", ["/usr/bin/pinnedballs"])
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        startup.from_the_first_instant(only_if_starting=True)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)
