"""The built-in rules as the GPU kernels number them (no numba-cuda needed to ask): `pinnedballs.rules`
registers them with `engine.closing.register_device_rule`."""

from __future__ import annotations

from ..closing import ELASTIC, EQUAL, MASSES, device_rule

__all__ = ["ELASTIC", "EQUAL", "MASSES", "rule_code"]


def rule_code(collide) -> int | None:
    """The number of a built-in rule's ``collide`` (`ELASTIC`, `EQUAL`, `MASSES`), None for any other."""
    return device_rule(collide)
