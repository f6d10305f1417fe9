"""What a geometry must be, each a check: ``check(geometry)`` returns, or raises an `AssertionError` naming
the property and the first contact or ball that breaks it.

Run them on small instances: `check_contact_graph_round_trip` builds a networkx graph of every
contact, and `check_contacts_are_touching_pairs` looks at every pair of balls within reach.
"""

from __future__ import annotations

import numpy as np

from ..geometry.checks import UNIT_TOLERANCE, check_contacts
from ..geometry.graph import GraphGeometry
from ..util.errors import FieldError
from .samples import fail, vector

__all__ = ["check_contact_tables", "check_contacts_are_touching_pairs", "check_contact_graph_round_trip",
           "check_frames", "check_boundary"]


def check_contact_tables(geometry) -> None:
    """The contact tables are sound (what `Simulation` checks, `pinnedballs.geometry.checks`): balls and
    ends in range, no ball touching itself, no pair twice, unit vectors of length 1 pointing from
    each ball towards the other, flat contacts ``2 * radius`` long.

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    try:
        check_contacts(geometry)
    except FieldError as error:
        fail("contact tables sound", str(error))


def _touching_pairs(geometry) -> set[tuple[int, int]]:
    """Every pair of balls ``2 * radius`` apart within ``geometry.rtol``, to the nearest periodic image."""
    from scipy.spatial import cKDTree

    p = np.array(geometry.positions, dtype=np.float64)
    k = p.shape[1]
    box = np.full(k, np.inf) if geometry.box is None else np.asarray(geometry.box, dtype=np.float64)
    reach = 2.0 * geometry.radius * (1 + geometry.rtol)
    finite = np.isfinite(box)
    wrapped = np.mod(p[:, finite], box[finite])
    p[:, finite] = np.where(wrapped >= box[finite], 0.0, wrapped)  # -1e-17 mod L rounds to L itself
    lo = p.min(axis=0)
    p[:, ~finite] -= lo[~finite]  # open axes: a box wider than twice the extent never wraps a contact
    size = np.where(finite, box, p.max(axis=0) * 2 + 4 * reach + 1.0)
    found = cKDTree(p, boxsize=size).query_pairs(reach, output_type="ndarray")
    d = p[found[:, 1]] - p[found[:, 0]]
    d[:, finite] -= box[finite] * np.round(d[:, finite] / box[finite])
    close = np.abs(np.linalg.norm(d, axis=1) - 2.0 * geometry.radius) <= geometry.rtol * 2.0 * geometry.radius
    return {(int(i), int(j)) for i, j in found[close]}


def check_contacts_are_touching_pairs(geometry) -> None:
    """Flat space: the contacts are exactly the pairs of balls that touch (``2 * radius`` apart within
    ``geometry.rtol``, to the nearest periodic image of `Geometry.box`): none joins balls apart, none
    is left out. (On a curved surface a contact's length is the surface's own business, not checked.)

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    if geometry.curved:
        return
    prop = "contacts are the touching pairs"
    contacts = {(min(i, j), max(i, j)) for i, j in np.asarray(geometry.contacts.pairs, dtype=np.int64).tolist()}
    touching = _touching_pairs(geometry)
    apart = sorted(contacts - touching)
    if apart:
        i, j = apart[0]
        fail(prop, f"balls {i} and {j} at {vector(geometry.positions[i])} and {vector(geometry.positions[j])} are a "
                   f"contact but do not touch (radius {geometry.radius:g}; {len(apart)} such contact(s))")
    missed = sorted(touching - contacts)
    if missed:
        i, j = missed[0]
        fail(prop, f"balls {i} and {j} at {vector(geometry.positions[i])} and {vector(geometry.positions[j])} touch "
                   f"but are no contact ({len(missed)} touching pair(s) left out)")


def check_contact_graph_round_trip(geometry) -> None:
    """``GraphGeometry(geometry.contact_graph())`` has the same balls and the same contacts, in the same
    order and orientation, with the same unit vectors, bit for bit (so the same seed gives the same run).

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "contact graph round trip"
    try:
        twin = GraphGeometry(geometry.contact_graph(), radius=geometry.radius)
    except (ValueError, TypeError) as error:
        fail(prop, f"GraphGeometry refused its contact graph: {type(error).__name__}: {error}")
    a, b = geometry.contacts, twin.contacts
    if not np.array_equal(np.asarray(geometry.positions), twin.positions):
        fail(prop, "the positions differ")
    if len(a) != len(b):
        fail(prop, f"{len(a)} contacts became {len(b)}")
    for name, x, y in (("balls", a.pairs, b.pairs), ("t_i", a.t_i, b.t_i), ("t_j", a.t_j, b.t_j)):
        same = (np.asarray(x, dtype=np.float64) == np.asarray(y, dtype=np.float64)).all(axis=1)
        if not same.all():
            e = int(np.flatnonzero(~same)[0])
            fail(prop, f"contact {e}: {name} {vector(x[e])} became {vector(y[e])}")


def check_frames(geometry) -> None:
    """`Geometry.frames` is ``(n_balls, dim, k)``, finite and orthonormal, under the geometry's metric
    where it states one (`Geometry.metric`), to ``1e-12``.

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "frames orthonormal"
    n, dim, k = geometry.n_balls, geometry.dim, np.shape(geometry.positions)[1]
    f = np.asarray(geometry.frames(), dtype=np.float64)
    if f.shape != (n, dim, k) or not np.isfinite(f).all():
        fail(prop, f"frames() must be finite and of shape (n_balls, dim, k) = {(n, dim, k)}, got {f.shape}")
    metric = np.ones(k) if geometry.metric is None else np.asarray(geometry.metric, dtype=np.float64)
    gram = np.einsum("nak,nbk->nab", f * metric, f)
    off = np.abs(gram - np.eye(dim)).max(axis=(1, 2))
    bad = np.flatnonzero(off > 1e-12)
    if len(bad):
        fail(prop, f"ball {bad[0]}: the frame {f[bad[0]].tolist()} has Gram matrix {gram[bad[0]].tolist()}, not "
                   f"the identity")


def check_boundary(geometry) -> None:
    """A boundary (`Geometry.boundary`), where the geometry has one: ``distance (n_balls,)`` finite and
    ``>= 0``, ``outward (n_balls, dim)`` unit vectors (within ``1e-12``). (Nothing to check without one.)

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    b = geometry.boundary
    if b is None:
        return
    prop = "boundary"
    n, dim = geometry.n_balls, geometry.dim
    d, out = np.asarray(b.distance, dtype=np.float64), np.asarray(b.outward, dtype=np.float64)
    if d.shape != (n,) or out.shape != (n, dim):
        fail(prop, f"distance must be ({n},) and outward ({n}, {dim}), got {d.shape} and {out.shape}")
    bad = np.flatnonzero(~(d >= 0) | ~np.isfinite(d))
    if len(bad):
        fail(prop, f"ball {bad[0]} is at distance {d[bad[0]]} from the boundary")
    bad = np.flatnonzero(~(np.abs(np.linalg.norm(out, axis=1) - 1.0) <= UNIT_TOLERANCE))
    if len(bad):
        fail(prop, f"ball {bad[0]}: outward {vector(out[bad[0]])} is not a unit vector")
