"""Running: the triggers and writers the run driver (`pinnedballs.engine.driver`) fires, a spec run
into a directory (`execute`), and ensembles of replicas (`ensemble`) on local processes or Dask
(`executors`)."""
