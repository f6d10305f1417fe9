"""What an engine is (`Engine`: a name, the devices and arithmetics it runs, `Engine.supports` and `Engine.build`)
and what it says when it does not run a chain (`Refusal`, raised as `Refused`). The door (`engine.door`) keeps
the registered engines and chooses among them; the built-in ones are `engine.builtin`'s."""

from __future__ import annotations

from dataclasses import dataclass

from ..util.errors import FieldError
from .devices import Device

__all__ = ["Refusal", "Refused", "Engine"]


@dataclass(frozen=True)
class Refusal:
    """Why an engine does not run a chain: ``field`` (what to change: ``"device"``, ``"arithmetic"``,
    ``"engine"``...), ``reason`` and ``instead`` (what runs it instead), and ``needs``: what it would take, by the
    field a spec states it in (``{"scheduler": "counter"}``: the counter stream), for a caller that says it in
    its own words."""

    field: str
    reason: str
    instead: str = ""
    needs: tuple[tuple[str, str], ...] = ()

    @property
    def message(self) -> str:
        """The reason and what runs it instead, as one line."""
        return f"{self.reason}; {self.instead}" if self.instead else self.reason

    def error(self) -> Refused:
        """The refusal as the error that says it (a `FieldError` on ``field``)."""
        return Refused(self)


class Refused(FieldError):
    """A chain no engine runs, as the error that says so: a `FieldError` on the refusal's field, its
    `Refusal` kept (``refusal``) for a caller that words it for its own input (a spec)."""

    def __init__(self, refusal: Refusal):
        super().__init__(refusal.field, refusal.message)
        self.refusal = refusal

    def __reduce__(self):
        return type(self), (self.refusal,)


class Engine:
    """What runs chains: a name, the devices (kinds: ``"cpu"``, ``"cuda"``) and arithmetics it runs, whether it
    runs an ensemble's replicas together (``replicas``), and the two calls of the door.

    Subclass it, set the attributes, and override `supports` and `build` (docs/architecture.md shows one).
    """

    name: str = ""
    devices: tuple[str, ...] = ()
    arithmetics: tuple[str, ...] = ()
    #: it runs many replicas of one spec together (an ensemble's), not one simulation's chain
    replicas: bool = False

    def supports(self, model, arithmetic: str, device: Device) -> Refusal | None:
        """None when this engine runs ``model`` (`engine.chain.Model`) in ``arithmetic`` on ``device``, else why
        not. Cheap: what needs a compile or a GPU is checked by `build`."""
        return self.refuse_kinds(arithmetic, device)

    def build(self, model, state, listeners: list, device: Device, options: dict):
        """The backend running ``model`` from ``state`` (`engine.chain.ChainState`, written in place), telling
        ``listeners`` of each collision; a `FieldError` where a check only the build can make fails."""
        raise NotImplementedError

    def refuse_kinds(self, arithmetic: str, device: Device) -> Refusal | None:
        """The refusal of an arithmetic or a device this engine does not run at all."""
        if device.kind not in self.devices:
            return Refusal("device", f"engine {self.name!r} runs on {' and '.join(self.devices)}, not {device.kind}")
        if arithmetic not in self.arithmetics:
            return Refusal("arithmetic", f"engine {self.name!r} runs {' and '.join(self.arithmetics)} arithmetic, "
                                         f"not {arithmetic}")
        return None

    def __repr__(self) -> str:
        return (f"<engine {self.name!r}: {', '.join(self.arithmetics)} on {', '.join(self.devices)}"
                f"{', replicas' if self.replicas else ''}>")
