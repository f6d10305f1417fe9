"""`reproduce`: run the plan, draw the figures, check the paper's statements, write the report."""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ...engine import door
from ...engine.devices import Device, as_device
from ...results.rundir import DirLock, check_out_dir
from ...specs.run import RunSpec
from ...util.atomic import write_text_atomic
from .. import ensemble as ens
from .. import ensemble_files as ens_files
from .checks import Check, _half_plane_checks, _torus_checks, _torus_stage
from .extended.plan import EXTENDED_FULL, EXTENDED_GPU, EXTENDED_QUICK, ExtendedPlan, check_extended_plan
from .extended.report import extended_section
from .extended.run import run_extended
from .extended.scaling_study import scaling_spec
from .figures import (
    _far_share_figure,
    _figure_paper_lattice,
    _figure_sizes,
    _figures_correlations,
    _figures_half_plane,
    _figures_torus,
    _frozen_collisions_figure,
)
from .plan import (
    FULL,
    QUICK,
    REPORT_NAME,
    Plan,
    _check_plan,
    _label,
    _Run,
    _sizes,
    half_plane_spec,
    paper_lattice_row,
    paper_lattice_spec,
    torus_row,
    torus_spec,
)
from .report import _report

# ---------------------------------------------------------------- runs


def _single(spec: RunSpec) -> _Run:
    from ..execute import run_to_stop

    sim = spec.build()
    initial = sim.velocities.copy()
    counter = spec.snapshots.counter if spec.snapshots else ""
    snaps: dict[int, object] = {}
    reason = run_to_stop(spec, sim,
                         on_snapshot=lambda record: snaps.__setitem__(getattr(record.state, counter), record))
    return _Run(sim, initial, snaps, reason)



# ---------------------------------------------------------------- the whole reproduction


def reproduce(out, plan: Plan | None = None, *, quick: bool = False, force: bool = False, workers: int | None = None,
              progress: bool | None = False, log: Callable[[str], None] | None = None,
              extended: bool | ExtendedPlan = False, device: str | Device = "cpu", **overrides) -> Path:
    """Run ``plan`` (default `QUICK` if ``quick`` else `FULL`, with ``overrides`` of its fields) into ``out``.

    Writes the PNGs of `expected_figures`, ``report.md``, ``results.json``, the specs
    (``specs/``) and every ensemble's table (``ensembles/<name>/``). Returns the report's path.
    ``extended``: then the studies beyond the paper (`extended`), ``EXTENDED_QUICK`` if
    ``quick`` else ``EXTENDED_FULL`` for True, or the `ExtendedPlan` given: their figures, a
    table each in the report and ``results.json["extended"]``.
    ``workers``: local processes for the ensembles (default all cores). Refuses a
    non-empty ``out`` without ``force`` (`InputError`).
    ``device="cuda"``: every ensemble whose spec a GPU runs (float arithmetic on the counter stream: the
    extended scaling study, whose plan is then ``EXTENDED_GPU``, or the plan given, on the counter stream)
    runs on the GPU; the rest, the paper's figures with their published seeds on the xoshiro stream among
    them, on the CPU as with ``device="cpu"``. The log says so once.
    """
    from ...analysis import observables as obs

    t0 = time.perf_counter()
    plan = dataclasses.replace(plan or (QUICK if quick else FULL), **overrides)
    _check_plan(plan)
    device = as_device(device)
    xplan = _extended_plan(extended, quick, device)
    if xplan is not None:
        check_extended_plan(xplan)
    out = check_out_dir(out, force)
    say = log or (lambda message: None)
    say_t = lambda message: say(f"[{time.perf_counter() - t0:6.1f} s] {message}")  # noqa: E731
    if device.gpu:
        _check_gpu(xplan, device)  # numba-cuda and a GPU, before anything runs
        say(_device_note(xplan))
    # every spec is built (and so validated) before anything is written
    detail_steps = half_plane_spec(plan.detail, plan, {"at_steps": list(plan.steps)})
    detail_collisions = half_plane_spec(plan.detail, plan, {"at_collisions": [plan.collisions]})
    size_specs = {size: half_plane_spec(size, plan) for size in _sizes(plan)}
    torus = torus_spec(plan)
    torus_long = torus_spec(plan, max(plan.long_steps, plan.steps[-1]))
    for spec in (detail_steps, *size_specs.values(), torus, torus_long):
        spec.build()
    with DirLock(out, "--out"):  # one reproduction at a time writes into a directory
        out.mkdir(parents=True, exist_ok=True)
        for sub in ("specs", "data", "ensembles"):
            (out / sub).mkdir(exist_ok=True)
        lattice = paper_lattice_spec(plan)
        specs = {"half_plane_detail_steps": detail_steps, "half_plane_detail_collisions": detail_collisions,
                 "torus": torus, "torus_ensemble": torus_long, "paper_lattice": lattice,
                 **{f"half_plane_{_label(s)}": spec for s, spec in size_specs.items()}}
        for name, spec in specs.items():
            write_text_atomic(out / "specs" / f"{name}.json", spec.to_json() + "\n")

        checks: list[Check] = []
        results: dict = {"plan": dataclasses.asdict(plan), "device": device.kind}
        failures: list[dict] = []

        def ensemble(name: str, spec: RunSpec, replicas: int, **kwargs) -> ens.EnsembleResult:
            on_gpu = device.gpu and _runs_on_gpu(spec, xplan)
            say_t(f"ensemble {name}: {replicas} replicas{' on the GPU' if on_gpu else ''}")
            where = {"device": device} if on_gpu else {"workers": workers}
            result = ens.run_ensemble(spec, replicas, progress=progress, **where, **kwargs)
            ens_files.write_outputs(result, out / "ensembles" / name, figures=False)
            failures.extend({"ensemble": name, **row} for row in result.failures)
            return result

        # ---------------------------------------------------------- half-plane: Figures 1-3
        say_t(f"half-plane {_label(plan.detail)}: single runs (seed {plan.seed})")
        by_steps, by_collisions = _single(detail_steps), _single(detail_collisions)
        if not np.array_equal(by_steps.sim.velocities, by_collisions.sim.velocities):
            raise RuntimeError("the same half-plane spec and seed gave two different final states")
        sim = by_steps.sim
        geom = sim.geometry
        dist = geom.boundary_distance()
        _figures_half_plane(out, plan, geom, by_steps, by_collisions)
        final_row = ens.state_row(geom, sim.velocities)
        at_c = by_collisions.snapshots.get(plan.collisions)
        results["detail"] = {"rows": geom.rows, "cols": geom.cols, "balls": geom.n_balls, "steps": sim.steps,
                             "collisions": sim.collisions, "frozen": sim.is_frozen(), "final": final_row,
                             "boundary_share_at_collisions": (obs.boundary_share(dist, at_c.state.velocities)
                                                              if at_c is not None else None)}

        # ---------------------------------------------------------- half-plane: sizes (Figure 4) and ensembles
        profiles, size_rows, size_results = {}, [], {}
        for size, spec in size_specs.items():
            say_t(f"half-plane {_label(size)}: single run")
            run = by_steps if size == tuple(plan.detail) else _single(spec)
            g = run.sim.geometry
            profiles[f"{_label(size)} ({g.rows}x{g.cols}, {g.n_balls:,} balls)"] = obs.energy_profile(
                g.boundary_distance(), run.sim.velocities)
            replicas = plan.replicas if size == tuple(plan.detail) else plan.size_replicas
            res = ensemble(f"half_plane_{_label(size)}", spec, replicas)
            size_results[size] = (g, res)
            size_rows.append((_label(size), g.n_balls, res.column("far_half_share"), res.column("far_row_share")))
        _figure_sizes(out, profiles)
        _far_share_figure(size_rows, out / "extra_far_share_by_size.png")
        lattice_res = ensemble("paper_lattice", lattice, plan.replicas,
                               task=functools.partial(ens.run_replica, observe=paper_lattice_row))
        say_t("paper-orientation lattice: single run")
        lattice_run = _single(lattice)
        _figure_paper_lattice(out, lattice_run)
        detail_geom, detail_res = size_results[tuple(plan.detail)]
        _frozen_collisions_figure(detail_res.column("collisions"), lattice_res.column("collisions"),
                                  (f"HalfPlane {detail_geom.rows}x{detail_geom.cols}",
                                   f"paper orientation ({lattice_run.sim.geometry.n_balls:,} balls)"),
                                  out / "extra_collisions_until_frozen.png")
        checks += _half_plane_checks(plan, results["detail"], size_results, lattice_res, lattice_run)

        # ---------------------------------------------------------- torus: Figures 5-8
        say_t(f"torus {plan.torus[0]}x{plan.torus[1]}: single run (seed {plan.seed})")
        trun = _single(torus)
        _figures_torus(out, plan, trun)
        tres = ensemble("torus", torus_long, plan.replicas, task=functools.partial(ens.run_replica, observe=torus_row))
        _figures_correlations(out, plan, tres, _torus_stage(plan, plan.steps[-1]))
        checks += _torus_checks(plan, trun, tres, results)

        if xplan is not None:
            say_t("paper's sections done; extended studies")
            results["extended"] = run_extended(xplan, out, ensemble, say_t)

        wall = time.perf_counter() - t0
        results["wall_seconds"] = wall
        results["failures"] = failures
        results["checks"] = [dataclasses.asdict(c) for c in checks]
        write_text_atomic(out / "results.json", json.dumps(ens_files.json_safe(_plain(results)), indent=2) + "\n")
        report = out / REPORT_NAME
        text = _report(plan, quick, checks, results, geom, trun.sim.geometry, lattice_run.sim.geometry, failures, wall)
        if xplan is not None:
            text += "\n" + "\n".join(extended_section(results["extended"]))
        write_text_atomic(report, text)  # a full disk leaves the old report or none, never half of one
        say_t(f"wrote {report}")
        return report



def _extended_plan(extended: bool | ExtendedPlan, quick: bool, device: Device) -> ExtendedPlan | None:
    """The extended studies' plan: for True ``EXTENDED_QUICK`` if ``quick`` else the full plan of ``device``
    (``EXTENDED_GPU`` on a GPU), or the plan given; on a GPU its scaling study on the counter stream. None: none."""
    if extended is False or extended is None:
        return None
    if extended is True:
        extended = EXTENDED_QUICK if quick else (EXTENDED_GPU if device.gpu else EXTENDED_FULL)
    return dataclasses.replace(extended, stream="counter") if device.gpu else extended


def _runs_on_gpu(spec: RunSpec, xplan: ExtendedPlan | None) -> bool:
    """Whether ``device="cuda"`` runs ``spec``'s ensemble on the GPU: float arithmetic (its replicas together) or
    certified (one at a time, sizes of at least ``xplan.exact_gpu_min_balls``) on the counter stream
    (the engine's door, `engine.door`; anything else it asks of a spec, it refuses in `run_ensemble` itself)."""
    if getattr(spec.scheduler, "stream", None) != "counter":
        return False
    if spec.arithmetic == "certified":
        return xplan is not None and spec.geometry.build().n_balls >= xplan.exact_gpu_min_balls
    return spec.arithmetic == "float"


def _check_gpu(xplan: ExtendedPlan | None, device: Device) -> None:
    """A `FieldError` on ``device`` now, not after the paper's sections, when no GPU can run the scaling study."""
    if xplan is not None:
        length, depth, _ = xplan.scaling[0]
        sim = scaling_spec(length, depth, xplan).build()
        door.check(sim.engine.model, sim.arithmetic, device)


def _device_note(xplan: ExtendedPlan | None) -> str:
    """The log's one line on what runs where with ``device="cuda"``."""
    paper = "device cuda: the paper's figures keep their published seeds on the xoshiro stream and run on the CPU"
    if xplan is None:
        return paper + "; nothing else runs here (the GPU runs the extended scaling study: extended=True, --extended)"
    return (paper + "; the scaling study runs on the GPU on the counter stream (its exact counts too, certified "
            f"arithmetic, one replica at a time, from {xplan.exact_gpu_min_balls:,} balls), the other extended "
            "studies on the CPU")


def _plain(value):
    """``value`` with numpy scalars and arrays made JSON-friendly."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value
