"""The structure of a results file, checked before anything uses it (`pb.load`, ``info``,
``plot``, ``--resume``): a file edited or damaged by hand or by another program is refused
with one message naming the file and the dataset, never read as a run.

First what the index says of itself (`index`: format and version, attributes, the segment list and the links
to the data files; an older format's as `legacy` says), then the data. What is checked (``n`` balls, ``d``
velocity components, ``E`` contacts, ``F`` snapshots): shapes and dtypes of the geometry, the initial and
latest velocities, the snapshots and their observables; the contacts against the geometry the stored spec
builds; finite numbers (the snapshots' of format 3 as each is read, `frames`: their digests are verified here;
those of older formats all at once, `legacy.scan_frames`); the counters (``0 <= collisions <= steps``,
snapshots in order and not past the state); the random state (4 words, not all zero) and the scheduler state
(as its scheduler would check it); the closing margin where the file keeps one (as `Simulation.set_state`
would check it, with its criterion); and every segment and the static file behind the index (virtual
datasets read missing or truncated sources as zeros, so each one is opened and measured).
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
from pydantic import ValidationError

from ..engine.field.fixed_state import bound_rule_problem, precisions_problem
from ..engine.field.fixed_state import margin_problem as certified_margin_problem
from ..engine.state import margin_problem
from ..specs.errors import first_error
from ..specs.geometry import geometry_from_stored, parse_geometry
from ..specs.run import RunSpec, stored_spec
from ..util.errors import FieldError
from . import legacy
from .format import STATIC_NAME, ResultsError
from .index import (
    Damage,
    check_attributes,
    check_digests,
    check_format,
    check_initial,
    check_links,
    check_provenance,
    check_sources,
    data_files,
)

__all__ = ["check_results"]


def check_results(p: Path, f: h5py.File, sealed: bool) -> int:
    """The format version of the open results file ``f`` (at ``p``); a `ResultsError` naming ``p`` and
    the dataset unless it is a sound results file this version reads. ``sealed``: the index carried
    a digest, which its bytes matched (`digest.unseal`): format 3 must, earlier formats cannot."""
    try:
        version = check_format(p, f)
        if legacy.older(version):
            legacy.check_index(p, f, version, sealed)
        else:
            _check_index(p, f, version, sealed)
        check_initial(f)
        _check(f)
        if legacy.older(version):  # no digest vouches for their frames
            legacy.scan_frames(f)
    except ResultsError:
        raise
    except Damage as exc:
        raise ResultsError(f"{p}: damaged results file: {exc}") from None
    except (KeyError, OSError, ValueError, TypeError) as exc:
        raise ResultsError(f"{p}: damaged results file ({' '.join(str(exc).split())})") from None
    return version


def _check_index(p: Path, f: h5py.File, version: int, sealed: bool) -> None:
    """The index of format 3: its digest (``sealed``), attributes, provenance, and the static file and
    segments it lists, each with its digest and the rows the index says, under its virtual datasets."""
    if not sealed:
        raise Damage("/ (attribute format_version)", f"is {version}, but the index lacks the digest of format 3")
    check_attributes(f)
    check_provenance(f)
    data, segments = data_files(p, f)
    check_digests(f, data, [STATIC_NAME, *(s[0] for s in segments)])
    check_sources(segments, data)
    check_links(f, data, segments, json.loads(f.attrs["observables"]))


def _dataset(f: h5py.File, name: str) -> h5py.Dataset:
    try:
        obj = f[name]
    except (KeyError, OSError) as exc:
        raise Damage(name, f"missing or unreadable ({' '.join(str(exc).split())})") from None
    if not isinstance(obj, h5py.Dataset):
        raise Damage(name, "is not a dataset")
    return obj


def _array(f: h5py.File, name: str, kind: str, shape: tuple) -> np.ndarray:
    """The dataset ``name``, checked: dtype kind ``kind`` ("f" float, "i" integer, "u" unsigned),
    ``shape`` (None: any length on that axis); floats finite."""
    ds = _dataset(f, name)
    if not _kind_ok(ds.dtype, kind):
        raise Damage(name, f"must be {_KINDS[kind]}, got {ds.dtype}")
    if len(ds.shape) != len(shape) or any(s is not None and s != t for s, t in zip(shape, ds.shape)):
        want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
        raise Damage(name, f"must have shape {want}, got {ds.shape}")
    value = ds[()]
    if kind == "f" and not np.isfinite(value).all():
        raise Damage(name, f"holds {np.count_nonzero(~np.isfinite(value))} non-finite values (NaN or inf)")
    return value


_KINDS = {"f": "floating point", "i": "integer", "u": "unsigned integers (uint64)"}


def _kind_ok(dtype: np.dtype, kind: str) -> bool:
    if kind == "i":
        return dtype.kind in "iu"
    if kind == "u":
        return dtype == np.uint64
    return dtype.kind == "f"


def _check(f: h5py.File) -> None:
    positions = _array(f, "geometry/positions", "f", (None, None))
    n = len(positions)
    pairs = _array(f, "geometry/pairs", "i", (None, 2))
    e = len(pairs)
    if e and (pairs.min() < 0 or pairs.max() >= n or (pairs[:, 0] == pairs[:, 1]).any()):
        raise Damage("geometry/pairs", f"must be pairs of distinct balls in [0, {n})")
    d = _array(f, "geometry/t_i", "f", (e, None)).shape[1]
    _array(f, "geometry/t_j", "f", (e, d))
    if "masses" in f["geometry"]:
        masses = _array(f, "geometry/masses", "f", (n,))
        if not (masses > 0).all():
            raise Damage("geometry/masses", "must be > 0")
    rigid = f["geometry"].attrs.get("rigid")  # absent: a file written before it was kept (False)
    if rigid is not None and not isinstance(rigid, (bool, np.bool_)):
        raise Damage("geometry (attribute rigid)", f"must be true or false, got {rigid!r}")
    _array(f, "initial/velocities", "f", (n, d))
    _array(f, "state/velocities", "f", (n, d))
    _check_against_spec(f, n, d, pairs)
    steps, collisions = int(f["state"].attrs["steps"]), int(f["state"].attrs["collisions"])
    if collisions > steps:
        raise Damage("state/collisions", f"{collisions} is more than the {steps} steps taken")
    rng = _array(f, "state/rng_state", "u", (4,))
    if not rng.any():
        raise Damage("state/rng_state", "is all zero (not a state of the random generator)")
    sched = _array(f, "state/scheduler_state", "i", (None,))
    if sched.dtype != np.int64:
        raise Damage("state/scheduler_state", f"must be int64, got {sched.dtype}")
    _check_scheduler_state(f, sched, e)
    if "exact" in f["state"]:
        _check_exact(f, n, d)
    if "margin" in f["state"]:
        _check_margin(f)
    if "certified" in f["state"]:
        _check_certified(f, n, d)
    _check_snapshots(f, n, d, steps, collisions)


def _stored_spec(f: h5py.File) -> RunSpec | None:
    """The run's stored spec (None for a run built in Python), validated without importing user code."""
    text = f.attrs.get("spec", "")
    if not text:
        return None
    try:
        return stored_spec(text)
    except ValidationError as exc:
        raise Damage("/ (attribute spec)", f"not a valid spec for this version of pinnedballs "
                                            f"({first_error(exc, RunSpec)})") from None


def _check_against_spec(f: h5py.File, n: int, d: int, pairs: np.ndarray) -> None:
    """The stored contacts are those of the geometry the stored spec (or Python description) builds;
    a user's own geometry (``"kind": "python"``) is not built: reading a run runs no user code."""
    run = _stored_spec(f)
    if run is not None:
        spec = run.geometry
    else:
        described = json.loads(f.attrs.get("run", "") or "{}").get("geometry", {})
        if "kind" not in described:
            return
        spec = parse_geometry(described)
    if spec.kind == "python":
        return
    geometry = geometry_from_stored(spec, f["geometry/positions"][()])
    if geometry.n_balls != n:
        raise Damage("geometry/positions", f"must hold the spec's {geometry.n_balls} balls, got {n}")
    if geometry.dim != d:
        raise Damage("initial/velocities", f"must have the spec's {geometry.dim} components, got {d}")
    if not np.array_equal(np.asarray(geometry.contacts.pairs), pairs):
        raise Damage("geometry/pairs", f"differ from the {geometry.n_contacts} contacts of the spec's geometry")


def _check_scheduler_state(f: h5py.File, sched: np.ndarray, e: int) -> None:
    """``sched`` as the run's scheduler would check it before resuming (when it has a spec)."""
    run = _stored_spec(f)
    if run is None or run.scheduler.kind == "python":
        return
    scheduler = run.scheduler.build()
    try:
        scheduler.check_state(sched, e)
    except FieldError as exc:
        raise Damage("state/scheduler_state", exc.problem) from None


def _check_snapshots(f: h5py.File, n: int, d: int, steps: int, collisions: int) -> None:
    """Snapshot velocities ``(F, n, d)``; counters ``(F,)`` in order, within the state's. The frames are not
    read: a run of format 3 had its digests verified, and `frames.Snapshots` checks each frame as it reads it,
    so a large run opens at once (`legacy.scan_frames` reads those of older formats)."""
    frames = _dataset(f, "snapshots/velocities")
    if frames.ndim != 3 or frames.shape[1:] != (n, d) or frames.dtype.kind != "f":
        raise Damage("snapshots/velocities", f"must be floating point of shape (F, {n}, {d}), got "
                                              f"{frames.dtype} {frames.shape}")
    count = frames.shape[0]
    at = {}
    for name, last in (("steps", steps), ("collisions", collisions)):
        x = _array(f, f"observables/{name}", "i", (count,))
        if count and (x.min() < 0 or (np.diff(x) < 0).any() or x.max() > last):
            raise Damage(f"observables/{name}", f"must be >= 0, in order and at most the state's {last:,}")
        at[name] = x
    if (np.diff(at["steps"]) == 0).any():  # a snapshot is taken once at a state: these are copies
        raise Damage("observables/steps", "lists the same step twice (duplicated snapshots)")
    if count and (at["collisions"] > at["steps"]).any():
        raise Damage("observables/collisions", "more collisions than steps in a snapshot")
    for name in f["observables"]:
        ds = _dataset(f, f"observables/{name}")
        if ds.shape[:1] != (count,):
            raise Damage(f"observables/{name}", f"must have {count} rows, got shape {ds.shape}")


def _check_certified(f: h5py.File, n: int, d: int) -> None:
    """The fixed point and bounds of a run in certified arithmetic (`CertifiedState`): limbs
    ``(n, d, m, P) uint64``, bounds ``(n, 2, L)`` floats >= 0, an integer scale, a rounding >= 0, an
    integer bound_scale where there is one, and a margin a certified state can hold where there is one."""
    limbs, bounds = _dataset(f, "state/certified/limbs"), _dataset(f, "state/certified/bounds")
    if limbs.ndim != 4 or limbs.shape[:2] != (n, d) or limbs.dtype != np.uint64:
        raise Damage("state/certified/limbs",
                     f"must be uint64 of shape ({n}, {d}, m, P), got {limbs.dtype} {limbs.shape}")
    if bounds.ndim != 3 or bounds.shape[:2] != (n, 2) or bounds.dtype.kind != "f":
        raise Damage("state/certified/bounds",
                     f"must be floats of shape ({n}, 2, L), got {bounds.dtype} {bounds.shape}")
    b = bounds[()]
    if not (np.isfinite(b).all() and (b >= 0).all()):
        raise Damage("state/certified/bounds", "must be finite and >= 0")
    attrs = f["state/certified"].attrs
    for name in ("scale", "rounding"):
        if name not in attrs:
            raise Damage("state/certified", f"has no {name}")
    scale, rounding = attrs["scale"], attrs["rounding"]
    if not (np.issubdtype(np.asarray(scale).dtype, np.integer) and 0 <= scale < 64 * limbs.shape[3]):
        raise Damage("state/certified", f"scale must be an integer in [0, {64 * limbs.shape[3]}), got {scale!r}")
    if not (np.isfinite(rounding) and rounding >= 0):
        raise Damage("state/certified", f"rounding must be a finite number >= 0, got {rounding!r}")
    bound_scale = attrs.get("bound_scale", 0)  # bounds in units of 2^-bound_scale (absent: 0, absolute)
    if not (np.issubdtype(np.asarray(bound_scale).dtype, np.integer) and 0 <= bound_scale < 64 * limbs.shape[3]):
        raise Damage("state/certified", f"bound_scale must be an integer in [0, {64 * limbs.shape[3]}), "
                                        f"got {bound_scale!r}")
    # absent: not kept (files written before)
    problem = precisions_problem(attrs.get("precision", 0), attrs.get("late_precision", 0), limbs.shape[3])
    if problem:
        raise Damage("state/certified", problem)
    if "bound_batch" in attrs:  # absent: the bound rule in step order (files of pinnedballs < 1.0: they load)
        pending = np.asarray(attrs.get("pending", np.zeros(0)))
        plain = lambda x: x.item() if isinstance(x, np.generic) else x  # noqa: E731 (numpy's scalars, said plainly)
        problem = bound_rule_problem(plain(attrs["bound_batch"]), plain(attrs.get("bound_at")),
                                     tuple(pending.tolist()) if pending.dtype.kind == "u" else (None,),
                                     plain(attrs.get("unfolded", np.nan)))
        if problem:
            raise Damage("state/certified", problem)
    if "margin" in attrs:  # absent: not kept (files written before), unknown
        problem = certified_margin_problem(np.asarray(attrs["margin"]))
        if problem:
            raise Damage("state/certified (attribute margin)", problem.removeprefix("margin").lstrip(": "))


def _check_exact(f: h5py.File, n: int, d: int) -> None:
    """The exact velocities of a run in exact arithmetic: ``(n, d, m)`` texts of rational numbers."""
    ds = _dataset(f, "state/exact")
    if ds.ndim != 3 or ds.shape[:2] != (n, d) or ds.dtype.kind != "O":
        raise Damage("state/exact", f"must be text of shape ({n}, {d}, m), got {ds.dtype} {ds.shape}")
    from gmpy2 import mpq

    for text in ds.asstr()[()].ravel():
        try:
            mpq(text)
        except (ValueError, TypeError, ZeroDivisionError):
            raise Damage("state/exact", f"holds {text[:40]!r}, not a rational number") from None


def _check_margin(f: h5py.File) -> None:
    """The closing margin of the latest state (`engine.margin`): ``(4,)`` floats a margin can hold,
    and its criterion: the threshold a finite number >= 0 (0 where the speed scale times the resolution
    is below the smallest float: every velocity 0, or all subnormal or tiny), the resolution in (0, 1)."""
    ds = _dataset(f, "state/margin")
    problem = margin_problem(ds[()]) if ds.shape == (4,) and ds.dtype.kind == "f" else \
        f"must be 4 floating-point numbers, got {ds.dtype} {ds.shape}"
    if problem is not None:
        raise Damage("state/margin", problem)
    for name, low, high, bracket in (("threshold", 0.0, np.inf, "["), ("resolution", 0.0, 1.0, "(")):
        value = ds.attrs.get(name)
        if not (isinstance(value, (float, np.floating)) and (low <= value if bracket == "[" else low < value)
                and value < high):
            shown = value.item() if isinstance(value, np.generic) else value
            raise Damage(f"state/margin (attribute {name})", f"must be a number in {bracket}{low:g}, {high:g}), got "
                                                              f"{shown!r}")
