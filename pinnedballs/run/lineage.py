"""The lineage of an output: the provenance a run's results and an ensemble's directory record. What this process
is (`util.provenance`: versions, command, host, CPU) and what the run used, as its engine says
(`engine.protocol.Backend.resources`: the threads, or the GPU). `life` begins a run's entry, `checkpointed` brings
it up to a checkpoint (its ``ended`` and ``steps``); `ensemble` gives an ensemble's, `ended` closes it. Metadata
only: no bit of a run depends on it.
"""

from __future__ import annotations

import contextlib

from .._version import __version__
from ..util import provenance as facts

__all__ = ["resources", "life", "checkpointed", "ensemble", "ended", "dask_facts", "GPU_PACKAGES"]

#: the packages a GPU run records beside `util.provenance.PACKAGES`
GPU_PACKAGES = ("numba-cuda",)


def resources(sim) -> dict:
    """What the simulation ``sim`` has run on so far: its engine's `resources` (``{"kind": "cpu", "threads": k,
    ...}`` or ``{"kind": "cuda", "gpu": ...}``), or ``{"kind": sim.device}`` for an engine that says nothing."""
    said = getattr(getattr(sim, "engine", None), "resources", None)
    return said() if callable(said) else {"kind": str(getattr(sim, "device", "cpu"))}


def life(sim, call: str) -> dict:
    """The entry of a run's life begun now at ``sim``'s state (``steps`` ``[sim.steps, sim.steps]``); ``call``: the
    Python call it is where no command line is recorded (`util.provenance.command`)."""
    used = resources(sim)
    out = facts.entry(__version__, call, used, GPU_PACKAGES if "gpu" in used else ())  # a GPU's names it
    out["steps"] = [int(sim.steps), int(sim.steps)]
    return out


def checkpointed(entry: dict, sim, steps: int) -> dict:
    """``entry`` brought up to a checkpoint of ``sim`` at ``steps``: ended now, the resources used so far, the
    steps ``[first, steps]``."""
    first = entry.get("steps", [int(steps)])[0]
    return {**entry, "device": resources(sim) if sim is not None else entry["device"],
            "steps": [min(int(first), int(steps)), int(steps)], "ended": facts.now()}


def ensemble(call: str, device: dict, *, gpu: bool = False) -> dict:
    """An ensemble's entry, begun now; ``device``: where its replicas run (``{"kind": "cpu", "workers": 4}``,
    ``{"kind": "cuda", "gpu": ...}``, with ``dask`` and ``hosts`` on a cluster); ``gpu``: on GPUs (the GPU's
    packages recorded too)."""
    return facts.entry(__version__, call, device, GPU_PACKAGES if gpu else ())


def ended(entry: dict, **more) -> dict:
    """``entry`` ended now, with ``more`` facts learnt on the way (``device``: where it ran)."""
    out = {**entry, "ended": facts.now()}
    if "device" in more:
        out["device"] = {**entry["device"], **more.pop("device")}
    out.update(more)
    return out


def dask_facts(client) -> dict:
    """``{"dask": the scheduler's address, "workers": how many, "hosts": their host names}`` of ``client``'s
    cluster, what of it Dask says (nothing it cannot)."""
    out = {}
    with contextlib.suppress(Exception):  # noqa: BLE001 - facts about a cluster never stop its ensemble
        out["dask"] = str(client.scheduler.address)
    with contextlib.suppress(Exception):  # noqa: BLE001
        workers = client.scheduler_info().get("workers", {})
        out["workers"] = len(workers)
        out["hosts"] = sorted({str(w.get("host", "")) for w in workers.values()} - {""})
    return out
