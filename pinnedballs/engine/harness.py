"""Running a chain to its limits, written once for every engine.

A call of an engine's ``run(max_steps, max_collisions, until_frozen)`` takes at most ``max_steps`` steps,
stops at a total of ``max_collisions`` collisions and, with ``until_frozen``, right after the collision
that leaves no live contact, however the run is split into calls. Every engine keeps these limits the
same way, `limits_loop`'s:

1. with ``until_frozen``, a system with no live contact takes no step;
2. the steps go in *chunks* of at most ``chunk`` steps; the engine *advances* through a chunk (its own
   inner loop: a compiled loop, threads, exact arithmetic, a GPU's kernels), stopping right after the
   collision that reaches ``max_collisions``;
3. after a chunk with a collision, a run until frozen scans for a live contact. A contact live at a
   chunk's start stays live until a collision touches one of its balls, so a chunk without a collision
   cannot freeze the system; a chunk whose scan finds it frozen ends at its last collision: the engine
   *settles* it there (its stream, the scheduler's state and the margin as right after that collision),
   from what it *marked* at the chunk's start;
4. the steps taken are counted, and the step right after the call's last collision.

The state is then bit for bit the one a loop re-testing every contact after every collision reaches.

`limits_loop` returns this loop as a plain function of four others: ``mark(data, carry, count, left) ->
start``, ``advance(data, carry, count, left, taken, collisions) -> (used, made, last, carry)``, ``live(data,
carry) -> bool`` and ``settle(data, start, carry, used, count, frozen) -> carry``, where ``data`` is what the
engine reads, ``carry`` what a chunk changes (returned, so that the loop is a function of plain values),
``left`` the collisions still allowed, ``used``/``made`` the chunk's steps and collisions and ``last`` the
chunk's step index of its last collision (-1: none). The compiled sequential loops compile it with numba
(`engine.sequential.loops`: ``data`` and ``carry`` tuples, every function inlined); the threaded, exact and
GPU chains call it as Python (`engine.backends`, `engine.gpu.chain`); a GPU's replicas compile it for the
device (`engine.gpu.replicas`).
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["limits_loop", "given", "taken"]


def given(data, carry, collisions, max_steps, max_collisions, until_frozen, chunk):
    """`limits_loop`'s ``prepare`` by default: the loop's own arguments, as they are."""
    return data, carry, collisions, max_steps, max_collisions, until_frozen, chunk


def taken(data, carry, steps, collisions, frozen, last):
    """`limits_loop`'s ``finish`` by default: ``(taken, collisions, frozen, last, carry)``."""
    return steps, collisions, frozen, last, carry


def limits_loop(mark: Callable, advance: Callable, live: Callable, settle: Callable, prepare: Callable = given,
                finish: Callable = taken) -> Callable:
    """``run(*args)``: ``prepare(*args) -> (data, carry, collisions, max_steps, max_collisions, until_frozen,
    chunk)``, the chain run to its limits from ``collisions`` so far (module docstring), then ``finish(data,
    carry, taken, collisions, frozen, last)``, ``last`` the steps taken up to the call's last collision (-1:
    none). By default
    ``run(data, carry, collisions, max_steps, max_collisions, until_frozen, chunk) -> (taken, collisions, frozen,
    last, carry)``; a compiled loop gives its own ``prepare`` and ``finish`` (its arguments in, its counters out),
    so that numba compiles the loop as that loop itself, its chunk inlined one level deep."""

    def run_to_limits(*args):
        data, carry, collisions, max_steps, max_collisions, until_frozen, chunk = prepare(*args)
        taken_, frozen, last_at = 0, False, -1
        if until_frozen and not live(data, carry):
            frozen = True
        while not frozen and taken_ < max_steps and collisions < max_collisions:
            count = min(chunk, max_steps - taken_)
            left = max_collisions - collisions
            start = mark(data, carry, count, left)
            used, made, last, carry = advance(data, carry, count, left, taken_, collisions)
            collisions += made
            if last >= 0:
                last_at = taken_ + last + 1
            if until_frozen and last >= 0 and not live(data, carry):
                frozen, used = True, last + 1  # the run ends right after its last collision
            carry = settle(data, start, carry, used, count, frozen)
            taken_ += used
        return finish(data, carry, taken_, collisions, frozen, last_at)

    return run_to_limits
