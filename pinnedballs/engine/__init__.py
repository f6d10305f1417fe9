"""The engine: the plain data of a chain, its compiled loops, the driver that runs them in chunks,
the random stream, numba's disk cache for the loops, and the checks that keep every input inside
what the machine can hold.

One module per idea: `errors` (errors naming the argument at fault), `checks` (the one helper
that validates arguments), `limits` (memory and the float64 range), `random` (xoshiro256**),
`jitcache` (the loops' disk cache), `threads` (how the parallel sweep's threads wait, and how
many), `intrinsics` (LLVM hints for the hot loop), `chain` (the
data every loop reads) and `loops` (the compiled loops); `driver` (a run in chunks to its stop, with
writers), `sigint` (Ctrl-C between chunks) and `progress` (the bar every long call shows, drawn by `bars`,
saying so while numba compiles: `compiling`); `stop` and
`triggers` (when a run ends and when its writers record: predicates of the counters, built by specs
and read by the driver); `atomic` (files written whole or not at all); `margin` (how near the
collision criterion a run's picks came) and `state` (`RunState`: all of a run that changes, as one record).
"""
