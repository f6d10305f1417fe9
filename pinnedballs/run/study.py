"""Parameter studies: every point of a study spec (`specs.study`) an ensemble, run into a signac project.

`run_study` validates the whole study first: every point's run spec, built once (its geometry and start), so that
a bad point is refused, naming it and its field, before anything is written. Then the study directory is a signac
project (Adorf et al., Comput. Mater. Sci. 146, 220, 2018)::

    DIR/
      study.json           the study as run: its base inline, its seed (a file that repeats the study)
      points.json          its points in order: job id, overrides, replicas, seed, balls (`study_dir` reads it)
      .signac/             signac's configuration
      workspace/<job id>/  one job a point, its id the hash of its state point (`StudyPoint.state_point`: the
        signac_statepoint.json   point's overrides, nested by path, and the base spec's digest); its document
        signac_job_document.json holds its replicas, seed and number of balls
        ensemble/          the point's ensemble directory (`run.ensemble_files.write_outputs`: replicas.csv, ...)

so that ``signac find geometry.length 20``, ``signac view`` and ``signac.get_project(DIR).to_dataframe()`` work on
it, and signac-flow, row or signac-dashboard can take it on. The points run one after another, each one's replicas
through `run.ensemble.run_ensemble` (local processes, a Dask cluster, the GPU), so a point's table is the one
``pinnedballs ensemble`` gives its spec; a point's ensemble is written into ``ensemble.partial`` and renamed
``ensemble`` when whole: a point is done exactly when its job holds ``ensemble``.

Ctrl-C and kills: a point interrupted loses its replicas (as an ensemble does) and nothing else; the points done
stay. ``resume=True`` runs what is missing: the points without an ensemble, so a killed study continues to the
table it would have had, and a point added to the study file later runs alone (its seeds are its own,
`specs.study.point_seed`). A done point whose recorded spec or replicas differ from the study's now is refused,
naming it (its rows would not be the study's).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from .._version import __version__
from ..engine.devices import Device, as_device
from ..results.rundir import DirLock, check_out_dir
from ..specs.base import engine_errors
from ..specs.errors import SpecError
from ..specs.study import PointError, StudyPoint, StudySpec, load_study_spec, parse_study
from ..util.atomic import write_text_atomic
from ..util.errors import InputError
from ..util.progress import Progress
from . import ensemble as ens
from . import ensemble_files as ens_files
from . import executors
from .ensemble_dir import is_ensemble_dir, load_ensemble
from .study_dir import ENSEMBLE_DIR, PARTIAL_DIR, POINTS_NAME, STUDY_NAME, StudyResult, is_study_dir, load_study

__all__ = ["run_study", "read_study", "STARTED"]

#: what a study directory holds before its first point runs (the signac project, the study's record)
STARTED = frozenset({".signac", "workspace", STUDY_NAME, POINTS_NAME})


def read_study(study, option: str = "study") -> StudySpec:
    """``study`` as a `StudySpec`: one already, a dict (paths relative to the working directory) or a file's path."""
    if isinstance(study, StudySpec):
        return study
    if isinstance(study, dict):
        return parse_study(study, base_dir=os.getcwd())
    if isinstance(study, (str, os.PathLike)):
        return load_study_spec(study)
    raise InputError(f"{option}: must be a StudySpec, a dict or the path of a study file, got {type(study).__name__}")


def run_study(study, out, *, workers: int | None = None, dask_address: str | None = None, cluster=None,
              device: str | Device | None = None, resume: bool = False, progress: bool | None = None,
              task: ens.Task | None = None, status=None) -> StudyResult:
    """Run every point of ``study`` (a `StudySpec`, a dict or a study file's path) into the directory ``out``, a
    signac project with a job a point (the module's docstring); return the study read back (`load_study`).

    Parameters
    ----------
    study : StudySpec, dict or path
        The study spec (`pinnedballs.specs.study`). Without a seed it gets one drawn, recorded in ``out``.
    out : path
        The study directory: created, or empty; with ``resume``, one this function wrote before (or none yet).
    workers, dask_address, cluster, device, task
        Where each point's ensemble runs, as `run_ensemble`'s (``device``: a `pinnedballs.CPU` or
        `pinnedballs.CUDA`, or its name; None: the CPU). The points run one after another, each on all the workers
        its replicas can use.
    resume : bool
        Continue the study in ``out``: run the points that have no ensemble yet (a study killed, or points added
        to the study since), none of those done; a study without a seed keeps the one ``out`` records.
    progress : bool or None
        A bar over the points, and each point's bar over its replicas (`run_ensemble`'s ``progress``).
    status : callable, optional
        Told each stage before the bars: a command's status line (``status(message)``, ``status.clear()``; None:
        `run.execute.SILENT`).

    Returns
    -------
    StudyResult
        The study directory read back (`StudyResult.to_pandas`, `StudyResult.summary`, `StudyResult.fit`, ...);
        its ``ran``: the points this call ran, by place in the study.

    Raises
    ------
    PointError
        A point is not a valid run spec (or does not build), naming the point and the field; nothing is written.
    InputError
        Bad arguments, ``out`` not empty (without ``resume``), or a done point that no longer matches the study.
    KeyboardInterrupt
        Ctrl-C: the points done are kept; ``resume=True`` goes on from them.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> base = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
    ...         "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 0.5},
    ...         "stop": {"frozen": True, "max_steps": 100000}}
    >>> study = {"base": base, "grid": {"geometry.cols": [6, 8]}, "replicas": 2, "seed": 0}
    >>> st = pb.run_study(study, "study", workers=1)
    >>> st, st.ran
    (StudyResult(study: 2 of 2 points done, varying geometry.cols), [0, 1])
    >>> st.to_pandas()[["geometry.cols", "replica", "collisions"]]
       geometry.cols  replica  collisions
    0              6        0          40
    1              6        1          53
    2              8        0          89
    3              8        1          80
    >>> pb.run_study(study, "study", workers=1, resume=True).ran   # nothing is missing
    []
    """
    if status is None:
        from .execute import SILENT as status
    study = read_study(study)
    device = as_device(device)
    _check_where(workers, dask_address, cluster)
    out = Path(out)
    if resume and is_study_dir(out):
        study = _with_recorded_seed(study, out)
    elif resume:  # nothing, or what a study killed as it started left
        check_out_dir(out, False, may_hold=STARTED, hint="it holds no study to resume")
    else:
        check_out_dir(out, False, hint="resume=True (--resume) continues a study there")
    study = study.seeded()
    points = study.expand()
    status(f"building the {len(points)} points' systems")
    balls = [_built(point, device, on_cluster=dask_address is not None or cluster is not None) for point in points]
    digest = study.digest()
    client, own = (None, False) if dask_address is None and cluster is None else \
        executors.dask_client(dask_address, cluster)  # one client for every point (an address refused here)
    try:
        with DirLock(out, "--out"):  # one study at a time writes into a directory
            done = _done_points(out, points, digest)  # read only: a conflict writes nothing
            jobs = _jobs(out, study, points, balls, digest)
            todo = [k for k in range(len(points)) if not done[k]]
            status.clear()
            with Progress(progress, len(todo), "points", "study points", scale=False) as bar:
                for n, k in enumerate(todo):
                    bar.update(n, postfix=points[k].label)
                    _run_point(points[k], Path(jobs[k].path), workers=workers, cluster=client, device=device,
                               progress=progress, task=task)
                    bar.update(n + 1)
    finally:
        if own:
            client.close()
    result = load_study(out)
    result.ran = todo
    return result


def _check_where(workers, dask_address, cluster) -> None:
    if (dask_address is not None) + (cluster is not None) + (workers is not None) > 1:
        raise InputError("workers, dask_address, cluster: give at most one")
    if workers is not None:
        ens.check_count("workers", workers)


def _with_recorded_seed(study: StudySpec, out: Path) -> StudySpec:
    """``study``, seeded as the study recorded in ``out`` was when it states no seed itself."""
    if study.seed is not None or study.seeds == "as_spec":
        return study
    try:
        seed = json.loads((out / STUDY_NAME).read_text(encoding="utf-8")).get("seed")
    except (OSError, ValueError) as exc:
        raise InputError(f"{out / STUDY_NAME}: not readable ({' '.join(str(exc).split())})") from None
    if seed is None:
        return study
    return study.model_copy(update={"seed": seed})


def _built(point: StudyPoint, device, *, on_cluster: bool) -> int:
    """The number of balls of ``point``, built once as its replica 0 is (and, on a GPU, asked how its ensemble runs
    there: `run.ensemble.ensemble_plan`): a point that does not build or run there is a `PointError` before
    anything runs."""
    try:
        with engine_errors(""):
            sim = point.spec.build(seed=ens.replica_seed(point.spec, 0))
            if device.gpu:
                ens.ensemble_plan(point.spec, sim, device, on_cluster=on_cluster)
    except PointError:
        raise
    except SpecError as exc:
        raise PointError(point.overrides, exc.path, exc.problem) from None
    return int(sim.geometry.n_balls)


def _jobs(out: Path, study: StudySpec, points: list[StudyPoint], balls: list[int], digest: str) -> list:
    """The signac project in ``out`` (made if new), the study's record (`STUDY_NAME`, `POINTS_NAME`), then a job
    initialised for each point (in order): a study killed on its way here resumes (`STARTED`)."""
    import signac

    project = signac.init_project(out)
    jobs = [project.open_job(point.state_point(digest)) for point in points]
    documents = [{"replicas": p.replicas, "seed": p.spec.seed, "n_balls": n} for p, n in zip(points, balls)]
    records = [{"job": job.id, "overrides": p.overrides, **d} for job, p, d in zip(jobs, points, documents)]
    write_text_atomic(out / STUDY_NAME, study.to_json() + "\n")
    write_text_atomic(out / POINTS_NAME, json.dumps({"version": __version__, "base": digest, "points": records},
                                                     indent=1, ensure_ascii=False) + "\n")
    for job, document in zip(jobs, documents):
        job.init(force=True)  # (again) its state point file, whole
        if dict(job.document) != document:  # its replicas, seed and balls (signac's documents take no dotted keys)
            job.document.update(document)
    return jobs


def _done_points(out: Path, points: list[StudyPoint], digest: str) -> list[bool]:
    """For each point, whether the project in ``out`` (if any) holds its whole ensemble; an `InputError` naming
    the first that holds an ensemble of another run spec or number of replicas."""
    if not is_study_dir(out):
        return [False] * len(points)
    import signac

    project = signac.get_project(out, search=False)
    done = []
    for point in points:
        ensemble = Path(project.open_job(point.state_point(digest)).path) / ENSEMBLE_DIR
        done.append(is_ensemble_dir(ensemble))
        if not done[-1]:
            continue
        held = load_ensemble(ensemble)
        if held.replicas != point.replicas or json.loads(held.spec.to_json()) != json.loads(point.spec.to_json()):
            raise InputError(f"point {point.label}: {ensemble} holds {held.replicas} replicas of another run spec "
                             f"(seed {held.spec.seed}); the study gives it {point.replicas} replicas of seed "
                             f"{point.spec.seed}: run the study into another directory")
    return done


def _run_point(point: StudyPoint, job_dir: Path, *, progress, **where) -> None:
    """Run ``point``'s ensemble and write it into ``job_dir/ensemble``, whole or not at all."""
    partial, final = job_dir / PARTIAL_DIR, job_dir / ENSEMBLE_DIR
    if partial.exists():  # what a kill left as it wrote
        shutil.rmtree(partial)
    result = ens.run_ensemble(point.spec, point.replicas, progress=progress, **where)
    ens_files.write_outputs(result, partial, figures=False)
    os.replace(partial, final)
