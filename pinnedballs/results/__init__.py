"""Results: the file format (`format`), writing a run directory append-only (`store`), reading it
back (`load`), checking a file before use (`check`), atomic files (`files`) and output directories
and their locks (`rundir`)."""
