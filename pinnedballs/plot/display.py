"""How pinnedballs objects show themselves in a notebook: compact HTML tables (`_repr_html_`) and
pictures (`_repr_png_`), behind one-line hooks on the classes.

A `Geometry` shows its balls, contacts, dimension and view beside a picture of it; a `Simulation`
its counters, energy and whether it froze beside the picture of its state (in the geometry's own
view: `states.state_picture`, a field above `field.FIELD_BALLS` balls); a `RunSpec` its parts; a
run's `Results` its file, status and snapshots; an `EnsembleResult` its replicas and their
counts. The pictures are drawn only when matplotlib imports and the view can be drawn (else
None, and the table alone). ``import pinnedballs`` imports this module, which imports no matplotlib,
and it installs itself as how a geometry and a simulation show themselves (`geometry.pictures`: they
stand below the plots, so they are handed their pictures rather than import them).

`mimebundle` draws the picture once for both the HTML (which embeds it: notebooks show the HTML)
and the PNG (for front-ends that show no HTML).
"""

from __future__ import annotations

import base64
import html
import io
import math
import sys

import numpy as np

from ..geometry import pictures

__all__ = ["state_picture", "simulation_figure", "geometry_html", "geometry_png", "simulation_html", "simulation_png",
           "spec_html",
           "results_html", "ensemble_html", "study_spec_html", "study_html", "mimebundle", "state_png", "DISPLAY_DPI"]

#: the resolution of pictures in a notebook (an 8-inch state picture is 480 pixels wide)
DISPLAY_DPI = 60


# ---------------------------------------------------------------- tables


def _table(title: str, rows: list[tuple[str, object]], picture: bytes | None = None) -> str:
    """An HTML table of ``rows`` ``(name, value)`` under ``title``, beside ``picture`` (PNG bytes) if given."""
    cells = "".join(f"<tr><th style=\"text-align:left;padding-right:1.5em\">{html.escape(name)}</th>"
                    f"<td style=\"text-align:left\">{html.escape(str(value))}</td></tr>" for name, value in rows)
    table = (f"<table><caption style=\"text-align:left;font-weight:bold;padding-bottom:0.3em\">"
             f"{html.escape(title)}</caption>{cells}</table>")
    if picture is None:
        return f"<div>{table}</div>"
    image = base64.b64encode(picture).decode("ascii")
    return (f"<div style=\"display:flex;flex-wrap:wrap;align-items:flex-start;gap:1.5em\">{table}"
            f"<img src=\"data:image/png;base64,{image}\" style=\"max-width:480px\" alt=\"{html.escape(title)}\"></div>")


def _count(n) -> str:
    return f"{int(n):,}"


def _number(x: float) -> str:
    return f"{x:.12g}" if math.isfinite(x) else str(x)


def _geometry_rows(g) -> list[tuple[str, object]]:
    k = np.asarray(g.positions).shape[1]
    boundary = g.boundary
    rows = [("balls", _count(g.n_balls)), ("contacts", _count(g.n_contacts)),
            ("dimension", f"{g.dim} (velocity components); positions in {k}-D"), ("view", g.view)]
    if boundary is not None:
        rows.append(("boundary", f"distances {boundary.distance.min():.3g} to {boundary.distance.max():.3g}"))
    else:
        rows.append(("boundary", "none"))
    rows.append(("ball radius", f"{float(g.radius):g}"))
    return rows


def _spec_text(spec) -> str:
    """A geometry's spec in one line: ``half_plane (rows=29, cols=50)``."""
    if not spec:
        return ""
    args = ", ".join(f"{k}={v}" for k, v in spec.items() if k != "kind")
    return f"{spec.get('kind', '?')} ({args})" if args else str(spec.get("kind", "?"))


def geometry_html(g, picture: bytes | None = None) -> str:
    title = type(g).__name__ + (f": {_spec_text(g.to_spec())}" if g.to_spec() else "")
    return _table(title, _geometry_rows(g), picture)


def simulation_html(sim, picture: bytes | None = None) -> str:
    g = sim.geometry
    approaching = sim.approaching()
    rows = [("geometry", f"{type(g).__name__}: {_count(g.n_balls)} balls, {_count(g.n_contacts)} contacts, "
                         f"dimension {g.dim}"),
            ("rule", repr(sim.rule)), ("scheduler", repr(sim.scheduler)),
            ("steps", _count(sim.steps)), ("collisions", _count(sim.collisions)),
            ("energy", _number(sim.energy())),
            ("frozen", "yes" if approaching == 0 else f"no: {approaching:,} contacts approaching")]
    if not g.curved:
        rows.insert(6, ("momentum", "(" + ", ".join(f"{x:.6g}" for x in np.asarray(sim.momentum())) + ")"))
    seed = getattr(sim, "seed", None)
    if seed is not None:
        rows.append(("seed", seed))
    return _table("Simulation", rows, picture)


def spec_html(spec) -> str:
    rows = []
    for name in ("geometry", "initial", "rule", "scheduler", "stop", "snapshots", "trajectory", "checkpoint"):
        part = getattr(spec, name)
        if part is None:
            continue
        fields = part.model_dump(exclude_none=True, mode="json")
        kind = fields.pop("kind", None)
        text = ", ".join(f"{k}={v}" for k, v in fields.items())
        rows.append((name, f"{kind} ({text})" if kind and text else kind or text or "-"))
    rows += [("observables", ", ".join(spec.observables)), ("arithmetic", spec.arithmetic), ("seed", spec.seed)]
    if spec.masses is not None:
        rows.insert(4, ("masses", "given"))
    if spec.description:
        rows.append(("description", spec.description))
    return _table("RunSpec", rows)


def results_html(res) -> str:
    snaps = res.snapshots
    steps = ", ".join(f"{s:,}" for s in snaps.steps[:5].tolist()) + (", ..." if len(snaps) > 5 else "")
    kinds = res.kinds
    n, dim = res.velocities.shape
    rows = [("file", str(res.path)),
            ("status", res.status + (f" ({res.stop_reason})" if res.stop_reason else "")),
            ("geometry", f"{kinds.get('geometry', '?')}: {_count(n)} balls, {_count(len(res.pairs))} contacts, "
                         f"dimension {dim}"),
            ("run", f"{kinds.get('initial', 'given velocities')}, {kinds.get('rule', '?')}, "
                    f"{kinds.get('scheduler', '?')}"),
            ("steps", _count(res.steps)), ("collisions", _count(res.collisions)),
            ("energy", f"{_number(res.energy)} (initially {_number(res.initial_energy)})"),
            ("frozen", _frozen(res)),
            ("snapshots", f"{len(snaps)}" + (f" at steps {steps}" if len(snaps) else "")),
            ("seed", res.spec.seed if res.spec is not None else "built in Python")]
    return _table("Results", rows)


def _frozen(res) -> str:
    """Whether a run's latest state is frozen, in words; unknown where certified arithmetic could not count
    its live contacts (a failed run's ``approaching`` -1)."""
    if res.approaching < 0:
        return "unknown: certified arithmetic could not count the live contacts at these bits"
    return "yes" if res.frozen else f"no: {res.approaching:,} contacts approaching"


def ensemble_html(result) -> str:
    failed = len(result.failures)
    rows = [("spec", f"{result.spec.geometry.kind}, {result.spec.rule.kind}, {result.spec.scheduler.kind}"),
            ("replicas", f"{result.replicas} ({result.replicas - failed} done, {failed} failed)"),
            ("seed", f"{result.spec.seed} (replica k: SeedSequence(seed).spawn(replicas)[k])"),
            ("where", result.where + (f", {result.wall_seconds:.3g} s" if math.isfinite(result.wall_seconds) else "")),
            ("stages", ", ".join(result.stages()[:5]) + (", ..." if len(result.stages()) > 5 else ""))]
    final = result.statistics().get("final", {})
    for name in ("steps", "collisions", "energy"):
        if name in final:
            s = final[name]
            spread = f" \u00b1 {s['std']:.3g}" if math.isfinite(s["std"]) else ""
            rows.append((name, f"mean {s['mean']:.6g}{spread} over {s['n']} final states"))
    frozen = result.column("frozen")
    if len(frozen):
        rows.append(("frozen", f"{int(frozen.sum())} of {len(frozen)} final states"))
    return _table("EnsembleResult", rows)


def study_spec_html(study) -> str:
    """A `StudySpec`: its base, what it varies, its replicas and seeds."""
    base = study.base
    rows = [("base", f"{base.geometry.kind}, {base.rule.kind}, {base.scheduler.kind}, stop at {base.stop.kind}")]
    for part in ("zip", "grid"):
        for path, values in getattr(study, part).items():
            rows.append((f"{part} {path}", ", ".join(map(str, values[:8])) + (", ..." if len(values) > 8 else "")))
    if study.points:
        rows.append(("points", f"{len(study.points)} given"))
    rows += [("points in all", _count(len(study.overrides()))),
             ("replicas", study.replicas if isinstance(study.replicas, int) else f"{len(study.replicas)} rules"),
             ("seeds", f"by point, from seed {study.seed}" if study.seeds == "by_point" else "each point's spec's own")]
    if study.description:
        rows.append(("description", study.description))
    return _table("StudySpec", rows)


def study_html(result) -> str:
    """A `StudyResult`: its directory, its points done, what they vary, and each done point's mean collisions."""
    done = result.done()
    rows = [("directory", str(result.path)), ("points", f"{sum(done)} of {len(done)} done"),
            ("varied", ", ".join(result.varied) or "nothing")]
    for k, point in enumerate(result.points[:12]):
        values = ", ".join(f"{p}={v}" for p, v in point["overrides"].items()) or "the base"
        if done[k]:
            x = result.ensemble(k).column("collisions")
            state = f"collisions {x.mean():.6g} over {len(x)} replicas" if len(x) else "no replica finished"
        else:
            state = "to do"
        rows.append((f"point {k}", f"{values} ({_count(point['n_balls'])} balls): {state}"))
    if len(result.points) > 12:
        rows.append(("...", f"{len(result.points) - 12} more points"))
    return _table("StudyResult", rows)


# ---------------------------------------------------------------- pictures


def state_picture(geometry):
    """`states.state_picture` (imported when first drawn: matplotlib)."""
    from .states import state_picture as draw

    return draw(geometry)


def simulation_figure(sim, what: str, ax=None, title: str | None = None):
    """`run.plot_simulation` (imported when first drawn: matplotlib): ``sim.plot(what)``."""
    from .run import plot_simulation

    return plot_simulation(sim, what, ax=ax, title=title)


def state_png(geometry, velocities, title: str, dpi: int = DISPLAY_DPI) -> bytes | None:
    """The state picture of ``velocities (n_balls, dim)`` on ``geometry`` as PNG bytes, or None when
    matplotlib is missing or the geometry's view cannot draw it."""
    try:
        from .states import state_picture
    except ImportError:
        return None
    try:
        fig = state_picture(geometry)(np.asarray(velocities, dtype=np.float64), title)
    except (ValueError, TypeError, KeyError):  # a view this state does not fit (FieldError is a ValueError)
        return None
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=dpi)
    return out.getvalue()


def geometry_png(g) -> bytes | None:
    """The balls of ``g`` at rest, in its view."""
    return state_png(g, np.zeros((g.n_balls, g.dim)), f"{type(g).__name__}: {g.n_balls:,} balls at rest")


def simulation_png(sim) -> bytes | None:
    return state_png(sim.geometry, sim.velocities, f"after {sim.steps:,} steps, {sim.collisions:,} collisions")


def mimebundle(obj, table, picture, include=None, exclude=None) -> dict:
    """``{"text/html": table(obj, png), "image/png": png}`` with ``png = picture(obj)`` drawn once
    (left out when None); ``include`` / ``exclude``: the MIME types IPython asks for or not."""
    wanted = [m for m in ("text/html", "image/png") if (include is None or m in include)
              and (exclude is None or m not in exclude)]
    png = picture(obj) if wanted else None
    out = {}
    if "text/html" in wanted:
        out["text/html"] = table(obj, png)
    if "image/png" in wanted and png is not None:
        out["image/png"] = png
    return out


pictures.install(sys.modules[__name__])  # how a geometry and a simulation show themselves
