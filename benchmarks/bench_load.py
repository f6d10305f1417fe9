"""Opening a large run: `pb.load` of a 250,000-ball half-plane with 120 snapshots (about 480 MB of
snapshot velocities), its time and the memory it takes, then a few snapshots read after it.

Writes the run once (``--dir``, default a folder under the system's temporary directory, kept for
the next call), then measures in a fresh child process: the wall time of ``pb.load(DIR)`` and its
peak memory above what the process held before (``VmHWM`` reset through ``/proc/self/clear_refs``,
Linux), then the time of reading snapshots 0, 60 and 119 and of ``res.to_xarray()`` and
``res.to_pandas()`` (their libraries' imports timed apart). Target (issue 24): open in under 2 s with under 150 MB extra
memory, any snapshot still readable.

    python benchmarks/bench_load.py                # write the run if needed, then measure (3 times)
    python benchmarks/bench_load.py --repeat 5 --dir /tmp/big_run
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = COLS = 500          # 250,000 balls
SNAPSHOTS = 120
EVERY = 1000               # steps between snapshots

SPEC = {
    "geometry": {"kind": "half_plane", "rows": ROWS, "cols": COLS},
    "initial": {"kind": "gaussian", "energy": 100.0},
    "stop": {"steps": EVERY * SNAPSHOTS},
    "snapshots": {"every_steps": EVERY},
    "checkpoint": {"every_seconds": 60},
    "seed": 1,
}

_CHILD = r"""
import json, sys, time
from pathlib import Path
import numpy as np
import pinnedballs as pb

def memory(field):
    return int(dict(l.split(":", 1) for l in open("/proc/self/status").read().splitlines())[field].split()[0]) * 1024

out = Path(sys.argv[1])
open("/proc/self/clear_refs", "w").write("5")   # the peak (VmHWM) starts again from here
before = memory("VmRSS")
t0 = time.perf_counter()
res = pb.load(out)
opened = time.perf_counter() - t0
peak = memory("VmHWM") - before
reads = {}
for i in (0, 60, 119):
    t0 = time.perf_counter()
    v = res.snapshots[i].velocities
    reads[i] = time.perf_counter() - t0
    assert v.shape == (250_000, 2) and np.isfinite(v).all()
t0 = time.perf_counter()
import dask.array, pandas, xarray  # the first call's imports, timed apart
imports = time.perf_counter() - t0
t0 = time.perf_counter()
xr = res.to_xarray() if hasattr(res, "to_xarray") else None
to_xarray = time.perf_counter() - t0
t0 = time.perf_counter()
table = res.to_pandas() if hasattr(res, "to_pandas") else None
to_pandas = time.perf_counter() - t0
print(json.dumps({"open_s": opened, "open_extra_mb": peak / 2**20, "reads_s": reads, "imports_s": imports,
                  "to_xarray_s": to_xarray,
                  "to_pandas_s": to_pandas, "snapshots": len(res.snapshots), "rss_after_mb": memory("VmRSS") / 2**20}))
"""


def write_run(out: Path) -> None:
    """The run, written as ``pinnedballs run`` writes it (no figures), unless ``out`` holds it already."""
    if (out / "results.h5").exists():
        return
    sys.path.insert(0, str(ROOT))
    import pinnedballs as pb
    from pinnedballs.specs.run import parse_spec

    t0 = time.perf_counter()
    res = pb.run_spec(parse_spec(json.dumps(SPEC)), out, force=True, figures=False, progress=False)
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"wrote {out}: {res.positions.shape[0]:,} balls, {len(res.snapshots)} snapshots, {size / 2**20:,.0f} MB "
          f"in {time.perf_counter() - t0:.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()) / "pinnedballs_bench_load")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    write_run(args.dir)
    for _ in range(args.repeat):
        child = subprocess.run([sys.executable, "-c", _CHILD, str(args.dir)], capture_output=True, text=True,
                               cwd=ROOT)
        if child.returncode:
            sys.exit(f"the measuring process failed:\n{child.stderr}")
        out = child.stdout
        r = json.loads(out.strip().splitlines()[-1])
        reads = ", ".join(f"{k}: {v * 1000:.0f} ms" for k, v in r["reads_s"].items())
        print(f"open {r['open_s']:.2f} s, {r['open_extra_mb']:.0f} MB extra at the peak; snapshots read ({reads}); "
              f"to_xarray {r['to_xarray_s'] * 1000:.0f} ms, to_pandas {r['to_pandas_s'] * 1000:.0f} ms (after "
              f"importing xarray, pandas and dask: {r['imports_s']:.1f} s)")


if __name__ == "__main__":
    main()
