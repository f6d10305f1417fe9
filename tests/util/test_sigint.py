"""SIGINT held while a chunk runs and handed on between chunks (`pinnedballs.util.sigint`); a call aside
(the driver's compiling call) left at once by a Ctrl-C."""

from __future__ import annotations

import os
import signal
import threading
import time

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


# ---------------------------------------------------------------- a call aside (the driver's compiling call)


def test_a_call_aside_gives_its_value_and_its_exception():
    with deferred() as held:
        assert held.aside(lambda a, b: a + b, 2, 3) == 5
        with pytest.raises(ZeroDivisionError):
            held.aside(lambda: 1 / 0)


@pytest.mark.parametrize("to_thread", [False, True], ids=["to the process", "to the call's thread"])
def test_a_ctrl_c_while_a_call_aside_runs_is_raised_at_once_and_the_next_call_waits_for_it(to_thread):
    """As a compile aside: KeyboardInterrupt while the call goes on on its thread; the next call aside
    starts only once it has ended. A process's SIGINT may reach any of its threads, and Python runs the
    handler on the main thread at its next instruction: the wait comes to one every few hundredths of a
    second (before, a signal the system handed to the call's thread waited for the call to end: 3.3 s of a
    compile in one CI run)."""
    finished, order = threading.Event(), []

    def slow_call():
        if to_thread:
            time.sleep(0.2)  # the main thread waits by now
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)
        else:  # at once: perhaps before the wait begins
            os.kill(os.getpid(), signal.SIGINT)
        time.sleep(2.0)
        order.append("first call ended")
        finished.set()

    with pytest.raises(KeyboardInterrupt):
        with deferred() as held:
            held.aside(slow_call)
    assert not finished.is_set()  # not waited for
    with deferred() as held:
        held.aside(lambda: order.append("second call"))
    assert order == ["first call ended", "second call"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_handler_that_only_notes_a_ctrl_c_still_stops_a_call_aside():
    """A command line's handler asks the run to stop between chunks: during a compile nothing has run yet,
    so the run stops there."""
    got = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: got.append(signum))
    try:
        with pytest.raises(KeyboardInterrupt):
            with deferred() as held:
                held.aside(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.3)))
        assert got == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)
        with deferred() as held:
            held.aside(lambda: None)  # the first call's end


def test_a_call_aside_runs_here_where_nothing_is_deferred():
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred() as held:
            assert held.aside(threading.current_thread) is threading.main_thread()
    finally:
        signal.signal(signal.SIGINT, previous)
