"""Collision-rule specs: ``build()`` returns the `CollisionRule`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field

from .base import _Spec, engine_errors
from .python import PythonRuleSpec

if TYPE_CHECKING:  # built when asked: a spec is validated (its schema written) without the engine
    from ..rules import CollisionRule

__all__ = ["ElasticSpec", "RestitutionSpec", "RuleSpec"]



class ElasticSpec(_Spec):
    """Totally elastic collisions (`Elastic`)."""

    kind: Literal["elastic"] = "elastic"

    def build(self) -> CollisionRule:
        from ..rules import Elastic

        return Elastic()


class RestitutionSpec(_Spec):
    """Inelastic collisions with coefficient of restitution ``r`` (`Restitution`)."""

    kind: Literal["restitution"] = "restitution"
    r: float

    def build(self) -> CollisionRule:
        from ..rules import Restitution

        with engine_errors("rule", {"r": "rule.r"}):
            return Restitution(self.r)


RuleSpec = Annotated[ElasticSpec | RestitutionSpec | PythonRuleSpec, Field(discriminator="kind")]
