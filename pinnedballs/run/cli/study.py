"""``pinnedballs study``: a study spec run into a signac project, an ensemble a point (`run.study.run_study`)."""

from __future__ import annotations

import sys
from pathlib import Path

from .commands import DEVICE, EXIT_INTERRUPTED, PROG, TRACEBACK, _progress, arg, subcommand

__all__ = ["study_command"]


@subcommand("study", "run a study: a base spec over a grid of points, an ensemble a point, into a signac project "
                     "(a job a point); --resume runs the points not done yet",
            arg("spec", metavar="STUDY.json", help="the study spec (pinnedballs schema --study)"),
            arg("--out", required=True, metavar="DIR", help="the study directory (created; a signac project)"),
            arg("--workers", type=int, metavar="K", help="local processes for each point's replicas (default: all "
                                                         "cores; 1 runs in-process)"),
            arg("--dask", metavar="ADDRESS", help="run the replicas on the Dask scheduler at ADDRESS"),
            arg("--resume", action="store_true", help="continue the study in DIR: run the points that have no "
                                                      "ensemble yet (after a kill, or added to the study since)"),
            arg("--quiet", action="store_true", help="no progress bars, no summary line"), DEVICE, TRACEBACK)
def study_command(args) -> int:
    """Exit 0, 1 if a replica failed (its point's ensemble is written with its error row), 2 on bad input (nothing
    written), 130 when interrupted (the points done are kept: ``--resume`` goes on)."""
    from ...util.errors import InputError
    from ..ensemble import check_count
    from .status import Status

    if args.workers is not None:
        check_count("--workers", args.workers)
        if args.dask is not None:
            raise InputError("--workers, --dask: give one of them, not both")
    if args.device == "cuda" and args.workers is not None:
        raise InputError("--device cuda runs the replicas on a GPU (this machine's, or each Dask worker's with "
                         "--dask): give no --workers")
    try:
        with Status(show=False if args.quiet else None) as status:
            status("reading the study")
            result = _study(args, status)
    except KeyboardInterrupt:
        print(f"{PROG}: {_interrupted(Path(args.out))}", file=sys.stderr)
        return EXIT_INTERRUPTED
    failed = 0
    for k in range(len(result.points)):
        res = result.ensemble(k)
        if res.failures:
            failed += len(res.failures)
            row = res.failures[0]
            print(f"{PROG}: point {k} {result.points[k]['overrides']}: {len(res.failures)} of {res.replicas} replicas "
                  f"failed, the first (replica {row['replica']}): {row['error']}", file=sys.stderr)
    if not args.quiet:
        replicas = sum(p["replicas"] for p in result.points)
        print(f"{len(result.points)} points done ({len(result.ran)} run now), {replicas - failed} of {replicas} "
              f"replicas; wrote {result.path}")
    return 1 if failed else 0


def _study(args, status):
    from ...specs.study import load_study_spec
    from ..executors import dask_client
    from ..study import run_study

    study = load_study_spec(args.spec)
    client = None
    if args.dask is not None:
        client, _ = dask_client(args.dask, None, "--dask")
    try:
        return run_study(study, args.out, workers=args.workers, cluster=client, device=args.device,
                         resume=args.resume, progress=_progress(args), status=status)
    finally:
        if client is not None:
            client.close()


def _interrupted(out: Path) -> str:
    """What an interrupted study leaves in ``out``, in one line."""
    from ..study_dir import is_study_dir, load_study

    if not is_study_dir(out):
        return f"interrupted before the study wrote anything in {out}"
    done = load_study(out).done()
    return f"interrupted; {sum(done)} of {len(done)} points done, kept in {out}: continue with --resume"

