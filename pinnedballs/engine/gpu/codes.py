"""The built-in rules as the GPU kernels number them (no numba-cuda needed to ask)."""

from __future__ import annotations

__all__ = ["ELASTIC", "EQUAL", "MASSES", "rule_code"]

#: ``collide_elastic``, ``collide_equal`` (equal masses, restitution ``r``), ``collide_masses``
ELASTIC, EQUAL, MASSES = 0, 1, 2


def rule_code(collide) -> int | None:
    """The number of a built-in rule's ``collide`` (`ELASTIC`, `EQUAL`, `MASSES`), None for any other."""
    from ...rules import collide_elastic, collide_equal, collide_masses

    return {collide_elastic: ELASTIC, collide_equal: EQUAL, collide_masses: MASSES}.get(collide)
