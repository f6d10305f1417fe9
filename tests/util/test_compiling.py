"""What numba compiles, in words (`pinnedballs.util.compiling`; issue 49, item 9): the bar names the
compile and how far it is, and a command says once how long it compiled and that the next run will not."""

from __future__ import annotations

from types import SimpleNamespace

from numba import njit

from pinnedballs.engine import harness
from pinnedballs.geometry import checks
from pinnedballs.util.compiling import CompileClock, CompileWatch, compiled_note, compiled_words, compiling_text


def dispatcher_of(module: str, qualname: str) -> SimpleNamespace:
    """A stand-in for a numba dispatcher: what `compiled_words` reads of one (its ``py_func``)."""
    return SimpleNamespace(py_func=SimpleNamespace(__module__=module, __qualname__=qualname))


def test_the_package_s_compiles_are_named_in_words_and_a_user_s_by_its_function():
    assert compiled_words(checks._first_fault) == "the contact checks"
    assert compiled_words(dispatcher_of(harness.__name__, "limits_loop.<locals>.run_to_limits")) == "the chain's loop"
    assert compiled_words(dispatcher_of("pinnedballs.engine.sequential.loops", "live_kernel.<locals>.live_flags")) \
        == "the freeze scan"
    assert compiled_words(dispatcher_of("pinnedballs.engine.threads.regions", "parallel_blocks.<locals>.blocks")) \
        == "the threaded chain"
    assert compiled_words(dispatcher_of("my_rules", "Sticky.collide")) == "collide"
    assert compiled_words(None) == "a function"


def test_the_compiling_text_says_which_compile_and_how_far_inside_it():
    assert compiling_text("the chain's loop", 1, 0) == "compiling the chain's loop (compile 1)"
    assert compiling_text("the chain's loop", 3, 1) == "compiling the chain's loop (compile 3; 1 function inside)"
    assert compiling_text("the threaded chain", 2, 14) == \
        "compiling the threaded chain (compile 2; 14 functions inside)"


def test_a_watch_counts_the_outermost_compiles_and_the_functions_inside_them():
    inner = njit(lambda x: x + 1)
    outer = njit(lambda x: inner(x) * 2)
    watch = CompileWatch(lambda: None, lambda: None)
    watch.start()
    try:
        outer(1)
        seen = (watch.compiles, watch.functions, watch.words)
        njit(lambda x: x - 1)(1)
    finally:
        watch.stop()
    assert seen == (1, 1, "<lambda>")  # outer, with inner compiled inside it
    assert (watch.compiles, watch.functions) == (2, 0)


def test_the_line_after_a_compile_says_how_long_and_whether_the_next_run_compiles():
    assert compiled_note(0.6, 0.6) is None  # under a second: nothing to say
    assert compiled_note(67.2, 67.2) == "compiled in 67 s; cached on disk: the next run will not compile"
    assert compiled_note(12.0, 0.0) == ("compiled in 12 s, none of it cached on disk (functions without a source "
                                        "file): the next run compiles again")
    assert compiled_note(12.0, 9.0) == ("compiled in 12 s, 9 s of it cached on disk; the rest (functions without a "
                                        "source file) compiles again in the next run")


def test_a_clock_adds_up_compiles_and_knows_one_numba_does_not_keep():
    with CompileClock() as clock:
        njit(lambda x: x + 3)(1)  # no cache=True: numba keeps nothing on disk
    assert clock.seconds > 0 and clock.cached_seconds == 0
    assert clock.note(least=0.0).endswith("none of it cached on disk (functions without a source file): the next "
                                          "run compiles again")
    before = clock.seconds
    njit(lambda x: x + 4)(1)  # after the block: not heard
    assert clock.seconds == before
