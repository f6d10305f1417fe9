"""The extended reproduction's scaling and torus-law tables on a tiny plan, which must stay the same to the digit
when these studies are run from study specs (issue 48: ``reproduce --extended`` keeps its tables). Made once,
with the studies of commit 7dac6a9 (before study specs), by

    python3 tests/data/make_extended_tables.py tests/data/extended_tables.json

The file holds each study's numbers (its rows, fits, profiles and verdicts; not the seconds it took, nor where it
ran) and the SHA-256 of each ensemble's ``replicas.csv`` and ``spec.json``. tests/run/reproduction/
test_extended_tables.py runs the same plan with the current code and compares.
"""

from __future__ import annotations

import hashlib
import json
import sys
import tempfile
from pathlib import Path

from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
from pinnedballs.run import reproduction as rp
from pinnedballs.run.reproduction import extended as ext

#: the tiny plan of tests/run/reproduction/test_extended.py: three half-planes, two tori
PLAN = rp.ExtendedPlan(scaling=((10, 5, 3), (20, 10, 3), (30, 15, 2)), torus_sides=(6, 8), torus_times=(50, 200),
                       torus_replicas=4)
FILES = ("replicas.csv", "spec.json")


def tables(out: Path) -> dict:
    """The scaling and torus-law studies of `PLAN` run in ``out``, one process: their numbers and files' digests."""
    digests: dict = {}

    def ensemble(name, spec, replicas, **kwargs):
        res = ens.run_ensemble(spec, replicas, workers=1, **kwargs)
        ens_files.write_outputs(res, out / name, figures=False)
        digests[name] = {f: hashlib.sha256((out / name / f).read_bytes()).hexdigest() for f in FILES}
        return res

    scaling = ext.scaling(PLAN, out, ensemble)
    torus = ext.torus_law(PLAN, out, ensemble)
    return json.loads(json.dumps(rp.run._plain({"scaling": numbers(scaling), "torus_law": numbers(torus),
                                                "files": digests})))


def numbers(value):
    """``value`` without what changes from run to run (seconds, where it ran) or names files (figures)."""
    if isinstance(value, dict):
        return {k: numbers(v) for k, v in value.items()
                if not k.endswith("seconds") and k not in ("figures", "ran_on")}
    if isinstance(value, list):
        return [numbers(v) for v in value]
    return value


if __name__ == "__main__":
    Path(sys.argv[1]).write_text(json.dumps(tables(Path(tempfile.mkdtemp())), indent=1, sort_keys=True) + "\n")
