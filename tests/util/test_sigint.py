"""SIGINT held while a chunk runs and handed on between chunks (`pinnedballs.util.sigint`)."""

from __future__ import annotations

import signal

import pytest

from pinnedballs.util.sigint import deferred


def test_a_ctrl_c_inside_the_block_waits_for_deliver():
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with deferred() as held:
            signal.raise_signal(signal.SIGINT)  # Python would raise right here
            reached.append("after the signal")
            held.deliver()
            reached.append("after deliver")
    assert reached == ["after the signal"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_signal_noted_at_the_end_of_the_block_is_delivered_as_it_ends():
    with pytest.raises(KeyboardInterrupt):
        with deferred():
            signal.raise_signal(signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_each_signal_goes_to_the_handler_before_in_order():
    """A command line's handler that only asks the run to stop gets every Ctrl-C, at the boundary."""
    got = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: got.append(signum))
    try:
        with deferred() as held:
            signal.raise_signal(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)
            assert got == []
            held.deliver()
            assert got == [signal.SIGINT, signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_an_ignored_sigint_stays_ignored():
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred() as held:
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            signal.raise_signal(signal.SIGINT)
            held.deliver()
    finally:
        signal.signal(signal.SIGINT, previous)


def test_an_exception_leaving_the_block_drops_what_is_noted():
    with pytest.raises(RuntimeError, match="a writer failed"):
        with deferred():
            signal.raise_signal(signal.SIGINT)
            raise RuntimeError("a writer failed")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
