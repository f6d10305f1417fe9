"""The built-in engines, one per room, in the order the door prefers them (`engine.door`).

* ``colored_sweep``: a scheduler's own parallel loop (`ColoredSweep`'s colour classes on every core).
* ``threads``: the paper's picks on every core, by regions (xoshiro) or deterministic reservations (counter
  stream) (`engine.threads`); where threads do not pay, the sequential loop.
* ``sequential``: the compiled loops on one core (`engine.sequential`); every float chain on the CPU.
* ``field``: exact and certified arithmetic on the CPU (`engine.field`), on the float chain's picks.
* ``gpu_certified``: certified arithmetic with its picks tried on an NVIDIA GPU (`engine.gpu.certified`).
* ``gpu``: the counter stream's float chain on an NVIDIA GPU (`engine.gpu.chain`).
* ``gpu_replicas``: an ensemble's small replicas together, a GPU thread each (`engine.gpu.replicas`).

Each gives the bits of ``sequential`` (``field``'s: exact arithmetic's decisions) on the chains it runs:
`pinnedballs.testing.check_engine` holds every registered engine to that.
"""

from __future__ import annotations

from fractions import Fraction

from ..util.errors import FieldError, described
from .backends import DeviceBackend, LoopBackend
from .devices import Device
from .protocol import Engine, Refusal

__all__ = ["Sequential", "Threads", "ColoredSweepThreads", "Field", "GPU", "GPUCertified", "GPUReplicas",
           "BUILT_IN", "COUNTER"]

_ONE = Fraction(1)
#: the scheduler a GPU runs, as Python builds it and as a spec states it
COUNTER = "UniformRandomPair(stream='counter')"
_COUNTER_SPEC = '{"kind": "uniform_random_pair", "stream": "counter"}'


class Sequential(Engine):
    """The compiled loops on one core: any rule, any scheduler, float arithmetic."""

    name, devices, arithmetics = "sequential", ("cpu",), ("float",)

    def build(self, model, state, listeners, device, options):
        return LoopBackend(model, state, listeners, device=device)


class Threads(Engine):
    """The paper's picks on several threads with the bits of one (`engine.threads`): the xoshiro stream by
    regions, the counter stream by deterministic reservations; one thread where threads do not pay."""

    name, devices, arithmetics = "threads", ("cpu",), ("float",)

    def supports(self, model, arithmetic, device):
        refusal = self.refuse_kinds(arithmetic, device)
        if refusal is None and model.threads == 1:
            refusal = Refusal("engine", "'threads' was asked for one thread", "engine 'sequential' runs it")
        if refusal is None and (model.selector.tracks or not (model.selector.uniform or model.selector.counter)):
            refusal = Refusal("engine", f"'threads' runs UniformRandomPair's picks; {described(model.scheduler)} "
                                        f"picks otherwise", "engine 'sequential' runs it")
        return refusal

    def build(self, model, state, listeners, device, options):
        return LoopBackend(model, state, listeners, device=device, parallel=True)


class ColoredSweepThreads(Engine):
    """A scheduler's own loop for plain steps, on its threads (`ColoredSweep`: colour classes in parallel); the
    compiled loops for runs to a collision count or a freeze."""

    name, devices, arithmetics = "colored_sweep", ("cpu",), ("float",)

    def supports(self, model, arithmetic, device):
        refusal = self.refuse_kinds(arithmetic, device)
        if refusal is None and model.selector.steps is None:
            refusal = Refusal("engine", f"'colored_sweep' runs a scheduler's own loop, and "
                                        f"{described(model.scheduler)} has none", "engine 'sequential' runs it")
        return refusal

    def build(self, model, state, listeners, device, options):
        return LoopBackend(model, state, listeners, device=device, own_loop=True)


def _refuse_field(model, arithmetic: str) -> Refusal | None:
    """What exact and certified arithmetic need of a chain, wherever they run: a built-in rule (its exact
    form) and picks made without a live set."""
    if model.rule.exact_kick(_ONE, _ONE) is None:
        return Refusal("arithmetic", f"{arithmetic} arithmetic runs the built-in rules (Elastic, Restitution); "
                                     f"{described(model.rule)} has no exact form")
    if model.selector.tracks:
        return Refusal("arithmetic", f"{arithmetic} arithmetic follows the picks of a scheduler that needs no live "
                                     f"set; {described(model.scheduler)} picks among live contacts in float "
                                     f"arithmetic (UniformRandomPair has the same law)")
    return None


class Field(Engine):
    """Exact or certified arithmetic on the CPU (`engine.field`): the chain in the number field of the contact
    normals, on the float chain's picks. Builds the field's chain from the state's velocities."""

    name, devices, arithmetics = "field", ("cpu",), ("exact", "certified")

    def supports(self, model, arithmetic, device):
        return self.refuse_kinds(arithmetic, device) or _refuse_field(model, arithmetic)

    def build(self, model, state, listeners, device, options, picks=None):
        from .field.arithmetic import built_field_chain

        state.field_chain = built_field_chain(model, state.velocities, options["arithmetic"],
                                              options.get("precision"), options.get("late_precision"), picks)
        state.velocities = state.field_chain.shadow  # its values rounded, brought up to date when read
        from .field.backend import FieldBackend

        return FieldBackend(model, state, listeners, device=device, arithmetic=options["arithmetic"])


class _OnGPU(Engine):
    """What the GPU's engines ask of a chain: the counter stream; then, before building, numba-cuda, a rule it
    compiles with the CPU's rounding (float arithmetic), and a GPU."""

    devices = ("cuda",)

    def supports(self, model, arithmetic, device):
        refusal = self.refuse_kinds(arithmetic, device)
        if refusal is None and not model.selector.counter:
            refusal = Refusal("device", f"'cuda' runs {COUNTER} (in a spec {_COUNTER_SPEC}: the pick of step s a "
                                        f"function of the seed and s)", f"{described(model.scheduler)} runs on the CPU",
                              needs=(("scheduler", "counter"),))
        return refusal

    def check(self, model, arithmetic: str, device: Device, *, here: bool = True, rule=None, scheduler=None) -> None:
        """numba-cuda (a `GPUUnavailable` saying it is missing), the rule compiled for the GPU (float arithmetic:
        certified arithmetic runs its own kernels) and a GPU; ``here=False``: the chain runs on other machines'
        GPUs, so this process needs neither numba-cuda nor a GPU (without numba-cuda the rule is compiled
        there)."""
        from .gpu import GPUUnavailable, importable, load

        try:
            importable()
        except GPUUnavailable:
            if here:
                raise
            return
        if arithmetic == "float":
            from .gpu.compile import check_rule

            g = model.geometry
            check_rule(model.rule if rule is None else rule, model.collide, g.dim, bool(g.contacts.flat))
        if here:
            load()


class GPU(_OnGPU):
    """The counter stream's float chain on an NVIDIA GPU, by deterministic reservations (`engine.gpu.chain`),
    with the CPU's bits; any rule numba-cuda compiles with the CPU's rounding."""

    name, arithmetics = "gpu", ("float",)

    def build(self, model, state, listeners, device, options):
        self.check(model, "float", device)
        return DeviceBackend(model, state, listeners, device=device)


class GPUCertified(_OnGPU):
    """Certified arithmetic with its picks tried on an NVIDIA GPU (`engine.gpu.certified.DevicePicks`): the
    CPU's certified chain, its state on the GPU, the CPU's certified bits."""

    name, arithmetics = "gpu_certified", ("certified",)

    def supports(self, model, arithmetic, device):
        return super().supports(model, arithmetic, device) or _refuse_field(model, arithmetic)

    def build(self, model, state, listeners, device, options):
        self.check(model, "certified", device)
        from .gpu.certified import DevicePicks

        return Field().build(model, state, listeners, device, options, picks=DevicePicks())


class GPUReplicas(_OnGPU):
    """An ensemble's replicas of one small system together on an NVIDIA GPU, a GPU thread each
    (`engine.gpu.replicas`): each replica's state is its CPU simulation's, continued with the CPU's bits."""

    name, arithmetics, replicas = "gpu_replicas", ("float",), True

    def build(self, model, state, listeners, device, options):
        raise FieldError("engine", "'gpu_replicas' runs an ensemble's replicas together (run_ensemble(..., "
                                   "device='cuda')), not one simulation")

    def build_replicas(self, backends: list, device: Device, pattern=None):
        """The replicas of ``backends`` (their simulations' engines: one model's chains, each its own state) as
        one `engine.gpu.replicas.ReplicaSet` on the GPU, each state written back after every launch."""
        model = backends[0].model
        self.check(model, "float", device)
        from .gpu.replicas import ReplicaSet

        return ReplicaSet(backends, pattern)


#: the built-in engines, in the order the door prefers them
BUILT_IN = (ColoredSweepThreads(), Threads(), Sequential(), Field(), GPUCertified(), GPU(), GPUReplicas())
