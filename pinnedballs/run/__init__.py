"""Running: the writers the run driver (`pinnedballs.engine.driver`) fires as it runs a `Simulation`
(`pinnedballs.simulation`), a spec run into a directory (`execute`), and ensembles of replicas
(`ensemble`) on local processes or Dask (`executors`). What a run stops at and when its writers
record (`engine.stop`, `engine.triggers`) live in the engine, so that specs build them."""
