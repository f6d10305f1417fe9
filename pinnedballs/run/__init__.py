"""Running: the one run driver (`driver`) with its triggers and writers, a spec run into a directory
(`execute`), and ensembles of replicas (`ensemble`) on local processes or Dask (`executors`)."""
