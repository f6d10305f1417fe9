#!/usr/bin/env bash
# The C yardstick: the seed's chain (the paper's torus, uniform random pairs, elastic exchange) in plain C,
# the single-core limit the benchmarks compare the engine with, in the same run.
# Usage: benchmarks/c/reference.sh ROWS COLS STEPS [single|gaussian]    e.g. reference.sh 38 38 50000000
#   single (default): the paper's start, one moving ball of energy 100; gaussian: i.i.d. normal velocities
# Builds ref_kernel.c with cc -O3 -march=native (once, and again when the source is newer) into $TMPDIR.
# Prints: reference N=... steps=... collisions=... energy=... Msteps/s=...
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin="${TMPDIR:-/tmp}/pinnedballs-yardstick"
if [ ! -x "$bin" ] || [ "$here/ref_kernel.c" -nt "$bin" ]; then
  cc -O3 -march=native -o "$bin.$$" "$here/ref_kernel.c" -lm
  mv -f "$bin.$$" "$bin"
fi
exec "$bin" "$@"
