"""What a results file's index says of itself, checked before its data is read (`check.check_results`
runs these first): its format and version, the type of every attribute, the list of segments and their
files, and the links to the static file and the virtual datasets over the segments. Format 3's, and the
pieces `legacy` checks formats 1 and 2 with.

A damaged attribute must never be read as a number it is not (``int("abc")``, a checkpoint
count of 2.7), and an index that lists a segment twice must never pass its frames off as new
ones: each segment is ``frames_<first>.h5`` holding rows ``[first, first + count)``, one after
another, and every virtual dataset maps exactly those rows from exactly those files.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import h5py
import numpy as np

from ..util import provenance
from .digest import file_digest
from .format import FORMAT, FORMAT_VERSION, STATE_KEYS, STATIC_NAME, ResultsError
from .format import data_dir as data_dir_of

__all__ = ["Damage", "check_format", "check_attributes", "check_initial", "check_provenance", "segment_list",
           "data_files", "check_sources", "check_digests", "check_links", "ROOT", "STATUSES", "UNKNOWN"]

#: what ``status`` may say (format 3)
STATUSES = ("running", "done", "interrupted", "failed")
#: ``/state``'s ``approaching`` of a failed run whose live contacts could not be counted (certified arithmetic)
UNKNOWN = -1
_SEGMENT = re.compile(r"frames_(\d{9})\.h5")


class Damage(Exception):
    """One fault: ``dataset`` and what is wrong with it."""

    def __init__(self, dataset: str, problem: str):
        super().__init__(f"{dataset}: {problem}")


def check_format(p: Path, f: h5py.File) -> int:
    """The format version of the results file ``f``, an integer this version reads; a `ResultsError`
    if it is not a results file or a newer one, `Damage` if the version is not a version."""
    if not _is(f.attrs.get("format"), str) or f.attrs["format"] != FORMAT:
        raise ResultsError(f"{p}: not a pinnedballs results file (no format={FORMAT!r} attribute)")
    version = f.attrs.get("format_version")
    if not _is(version, int) or version < 1:
        raise Damage("/ (attribute format_version)", f"must be an integer from 1 to {FORMAT_VERSION}, got "
                                                     f"{_short(version)}")
    if version > FORMAT_VERSION:
        raise ResultsError(f"{p}: written by a newer pinnedballs (format {version}; this one reads up to "
                           f"{FORMAT_VERSION}): upgrade pinnedballs")
    return int(version)


# ---------------------------------------------------------------- attributes

#: attribute -> type, of the root (format 3), of /state and of /initial; "json-list" and "json-object": text
#: holding one
ROOT = {"version": str, "spec": str, "status": str, "stop_reason": str, "created": str, "updated": str,
        "elapsed_seconds": float, "checkpoints": int, "run": "json-object", "checked": bool,
        "observables": "json-list", "segments": "json-list", "digests": "json-object"}
_STATE = {"steps": int, "collisions": int, "energy": float, "approaching": int, "frozen": bool, "keys": "json-list"}
_INITIAL = {"energy": float, "approaching": int}


def check_attributes(f: h5py.File, root: dict = ROOT, statuses: tuple[str, ...] = STATUSES) -> None:
    """Every attribute of the index the reader uses is there, of its type, and sane (counts >= 0,
    finite numbers, a known status, ``frozen`` exactly when nothing approaches, the state's ``keys``;
    a failed run's ``failure``, and its ``approaching`` `UNKNOWN` where it could not be counted);
    those of ``/initial`` (in the static file) are `check_initial`'s. ``root``: the root's attributes and
    their types, ``statuses``: what ``status`` may say (format 3's; an older format's from `legacy`)."""
    where = "/ (attribute status)"
    _attribute("/", "status", f.attrs.get("status"), str)
    if f.attrs["status"] not in statuses:
        raise Damage(where, f"must be {' or '.join(map(repr, statuses))}, got {_short(f.attrs['status'])}")
    failed = f.attrs["status"] == "failed"
    if failed:
        _attribute("/", "failure", f.attrs.get("failure"), "json-object")
    for group, table in (("/", root), ("state", _STATE)):
        for name, kind in table.items():
            value = f[group].attrs.get(name)
            if not (failed and group == "state" and name == "approaching" and _is(value, int) and value == UNKNOWN):
                _attribute(group, name, value, kind)
    state = f["state"].attrs
    if bool(state["frozen"]) != (state["approaching"] == 0):
        raise Damage("state/frozen", f"is {bool(state['frozen'])} with {state['approaching']} contacts "
                                                 f"approaching")
    if json.loads(state["keys"]) != list(STATE_KEYS):
        raise Damage("state/keys", f"must list {list(STATE_KEYS)}, got {_short(state['keys'])}")
    if "observables" in root:  # formats 2 and 3 list them
        names = json.loads(f.attrs["observables"])
        if not all(isinstance(n, str) for n in names) or not {"steps", "collisions"} <= set(names) \
                or len(set(names)) != len(names):
            raise Damage("/ (attribute observables)", f"must list distinct names with steps and collisions, got "
                                                      f"{_short(names)}")


def check_provenance(f: h5py.File) -> None:
    """``/provenance``, where there is one (files written before runs kept it have none): a JSON text for each
    life of the run, each an entry `util.provenance.problem` finds sound."""
    if "provenance" not in f:
        return
    ds = f["provenance"]
    if not isinstance(ds, h5py.Dataset) or ds.ndim != 1 or h5py.check_string_dtype(ds.dtype) is None:
        raise Damage("provenance", f"must be a list of texts (one JSON object a life), got {_short(ds)}")
    for i, text in enumerate(ds.asstr()[()]):
        try:
            said = provenance.problem(json.loads(text))
        except (ValueError, UnicodeDecodeError):
            said = f"must be a JSON object (text), got {_short(text)}"
        if said is not None:
            raise Damage(f"provenance[{i}]", said)


def check_initial(f: h5py.File) -> None:
    """The attributes of ``/initial``: its energy and the number of contacts approaching."""
    for name, kind in _INITIAL.items():
        _attribute("initial", name, f["initial"].attrs.get(name), kind)


def _attribute(group: str, name: str, value, kind) -> None:
    where = f"/ (attribute {name})" if group == "/" else f"{group}/{name}"
    if kind in ("json-list", "json-object"):
        want = list if kind == "json-list" else dict
        try:
            ok = _is(value, str) and isinstance(json.loads(value) if value or want is list else {}, want)
        except ValueError:
            ok = False
        if not ok:
            raise Damage(where, f"must be a JSON {want.__name__} (text), got {_short(value)}")
        return
    if not _is(value, kind):
        raise Damage(where, f"must be {_NAMES[kind]}, got {_short(value)}")
    if kind in (int, float) and not math.isfinite(value):
        raise Damage(where, f"must be finite, got {_short(value)}")
    if kind in (int, float) and value < 0:
        raise Damage(where, f"must be >= 0, got {_short(value)}")


_NAMES = {str: "text", int: "an integer", float: "a number", bool: "true or false"}


def _is(value, kind) -> bool:
    """``value`` (as h5py gives an attribute) is a scalar of ``kind``."""
    if kind is bool:
        return isinstance(value, (bool, np.bool_))
    if kind is int:
        return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if kind is float:
        return isinstance(value, (float, int, np.floating, np.integer)) and not isinstance(value, (bool, np.bool_))
    return isinstance(value, kind)


def _short(value) -> str:
    text = repr(value.item() if isinstance(value, np.generic) else value)
    return text if len(text) <= 60 else text[:57] + "..."


# ---------------------------------------------------------------- segments and links


def segment_list(f: h5py.File) -> list[tuple[str, int, int]]:
    """The index's segments ``(file, first, count)``: ``frames_<first>.h5`` each, contiguous from frame 0,
    none listed twice, none empty."""
    where, total = "/ (attribute segments)", 0
    out = []
    for entry in json.loads(f.attrs["segments"]):
        if not (isinstance(entry, list) and len(entry) == 3 and isinstance(entry[0], str)
                and all(_is(x, int) for x in entry[1:])):
            raise Damage(where, f"entries must be [file, first, count], got {_short(entry)}")
        name, first, count = entry
        match = _SEGMENT.fullmatch(name)
        if match is None or int(match.group(1)) != first or first != total or count < 1:
            raise Damage(where, f"{_short(entry)} does not follow the {total:,} frames before it "
                                f"(a segment listed twice, out of order or misnamed)")
        out.append((name, first, count))
        total += count
    return out


def data_files(p: Path, f: h5py.File) -> tuple[Path, list[tuple[str, int, int]]]:
    """The data directory of the results file ``f`` (at ``p``) and its segments (`segment_list`), once the
    static file and every segment are there (a `ResultsError` naming the first missing)."""
    data, segments = data_dir_of(p), segment_list(f)
    missing = [name for name in [STATIC_NAME, *(s[0] for s in segments)] if not (data / name).is_file()]
    if missing:
        raise ResultsError(f"{p}: damaged results file ({data / missing[0]} is missing)")
    return data, segments


def check_sources(segments: list, data_dir: Path) -> None:
    """The static file and each segment open, and hold the rows the index says (virtual datasets read a missing
    or truncated source as zeros)."""
    _open_source(data_dir / STATIC_NAME, lambda g: None)
    for name, _, count in segments:
        def measure(g, name=name, count=count):
            try:
                ds = g["velocities"]
            except (KeyError, OSError) as exc:
                raise Damage("velocities", f"missing or unreadable ({' '.join(str(exc).split())})") from None
            if not isinstance(ds, h5py.Dataset):
                raise Damage("velocities", "is not a dataset")
            rows = ds.shape[:1]
            if rows != (count,):
                raise Damage(f"{data_dir.name}/{name}: velocities", f"must have {count} rows, got {rows}")
        _open_source(data_dir / name, measure)


def _open_source(path: Path, check) -> None:
    try:
        with h5py.File(path, "r") as g:
            check(g)
    except OSError as exc:
        raise Damage(str(path), f"not a readable HDF5 file (truncated?): {' '.join(str(exc).split())}") from None


def check_digests(f: h5py.File, data_dir: Path, names: list[str]) -> None:
    """Each of the files ``names`` in ``data_dir`` (the static file and the segments) has the digest the
    index lists for it, before anything opens it (format 3)."""
    digests = json.loads(f.attrs["digests"])
    if sorted(digests) != sorted(names):
        raise Damage("/ (attribute digests)", f"must list the digests of {', '.join(names)}, got {_short(digests)}")
    for name in names:
        if file_digest(data_dir / name) != digests[name]:
            raise Damage(f"{data_dir / name}", "its bytes differ from the digest the index holds for it (changed "
                                               "or cut short since pinnedballs wrote it)")


def check_links(f: h5py.File, data_dir: Path, segments: list, observables: list[str]) -> None:
    """``/geometry`` and ``/initial`` link to the static file; ``/snapshots/velocities`` and each
    ``/observables/<name>`` map the rows of exactly the listed segments, in order."""
    rel = f"{data_dir.name}/"
    for name in ("geometry", "initial"):
        link = f.get(name, getlink=True)
        if not isinstance(link, h5py.ExternalLink) or (link.filename, link.path) != (rel + STATIC_NAME, f"/{name}"):
            raise Damage(name, f"must link to /{name} in {rel + STATIC_NAME}")
    expected = [(rel + name, first, first + count - 1) for name, first, count in segments]
    for where, source in [("snapshots/velocities", "velocities"),
                          *((f"observables/{n}", f"observables/{n}") for n in observables)]:
        if where not in f or not isinstance(f[where], h5py.Dataset):
            raise Damage(where, "missing")
        if _mapping(f[where], source) != expected:
            raise Damage(where, "does not map the segments the index lists, each once and in order")


def _mapping(ds: h5py.Dataset, source: str) -> list[tuple[str, int, int]]:
    """``(file, first row, last row)`` of each source of the virtual dataset ``ds`` reading ``source``
    (an empty dataset: none)."""
    if not ds.is_virtual:
        return [] if ds.shape[:1] == (0,) else [("not virtual", 0, 0)]
    plist = ds.id.get_create_plist()
    out = []
    for k in range(plist.get_virtual_count()):
        if plist.get_virtual_dsetname(k) != source:
            return [("another dataset", 0, 0)]
        start, end = plist.get_virtual_vspace(k).get_select_bounds()
        out.append((plist.get_virtual_filename(k), start[0], end[0]))
    return out
