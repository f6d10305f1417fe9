"""The engine: a chain as plain data, run to its limits by one of several engines, in chunks, by one driver.

The map, a room per concern (package-wide helpers, errors and argument checks among them, are `pinnedballs.util`):

* the chain as plain data: `chain` (`chain.Model`, what a chain is; `chain.ChainState`, what changes; the
  loops' arrays and counters), `state` (`state.RunState`, what a checkpoint keeps), `margin` (how near the
  collision criterion its picks came), `rows` (a lattice's contacts read from their index);
* what components give the engine: `closing` (a rule's arithmetic, written once and compiled for every
  engine: the closing speed, the kick, the forms each engine runs), `selector` (a scheduler's
  `selector.Selector`);
* the door: `protocol` (what an engine is: `protocol.Engine`, whose ``supports`` answers with None or a
  `protocol.Refusal`), `door` (the registered engines: `engines()`, `register()`, and `door.choose`, the one
  place an engine is chosen), `builtin` (the built-in engines, one per room), `devices` (`devices.CPU`,
  `devices.CUDA`: where a chain runs, as objects);
* running: `harness` (the limits of a run, written once: chunks, the collision target, the freeze),
  `backends` (what the engines build: the chunk protocol), `driver` (a run in chunks to its
  `stop.Stop`, its writers fired on their `triggers`);
* the engines, each a room: `sequential` (the compiled loops on one core), `threads` (the paper's chain on
  every core with the bits of one), `field` (exact and certified arithmetic in the number field of the
  contact normals), `gpu` (the counter stream's chain on an NVIDIA GPU, in float or certified arithmetic);
* below them: `streams` (the random streams: xoshiro256**, its jumps, the counter stream Philox) and `jit`
  (numba's disk cache for closures, LLVM hints).

The door's names are this package's (``from pinnedballs.engine import engines, register``), each imported
when first used.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)  # the names: __init__.pyi
