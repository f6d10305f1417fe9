"""`FieldBackend`: exact or certified arithmetic's chain run on the float chain's picks, and its state saved and
restored (the exact velocities' coefficients, the certified fixed point and its bounds), so that nothing above
the engine knows what a field chain keeps."""

from __future__ import annotations

import numpy as np

from ...util.errors import FieldError
from ..chain import COLLISIONS, LAST, LIVE, STEPS, ChainState, Model
from ..harness import limits_loop
from ..protocol import Backend
from ..sequential.loops import loops
from ..streams.philox import CounterPicks
from .fixed_state import CertifiedState, nearest_floats
from .limbs import from_limbs

__all__ = ["FieldBackend"]


class FieldBackend(Backend):
    """Exact or certified arithmetic on the CPU (the chain in ``state.field_chain``): the compiled selector's
    picks in blocks, each tried by the field chain (`engine.field.rational.FieldChain.run`), within the limits of
    `engine.harness`; a block cut short is drawn again to its end, so the stream and the scheduler's state
    are those of the float loop after the same steps. A decision certified arithmetic cannot make raises
    once the picks before it are counted."""

    def __init__(self, model: Model, state: ChainState, listeners: list | None = None, device=None, *,
                 arithmetic: str = "exact"):
        super().__init__(model, state, listeners, device)
        self.arithmetic = arithmetic  #: ``"exact"`` or ``"certified"``
        s, g = model.selector, model.geometry
        self.loops = loops(model.collide, s.select, s.begin, s.changed, s.skips, g.dim, g.contacts.flat)
        self._to_limits = limits_loop(_no_mark, self._advance, self._live, _no_settle)

    def set_velocities(self, velocities: np.ndarray) -> None:
        """The chain's exact velocities replaced by ``velocities`` ``(n_balls, dim)`` (each float exactly: the
        field element with it as rational coefficient), and the state's floats by them; the velocities the chain
        rounds to already (those read back) leave its exact ones as they are."""
        v = np.array(velocities, dtype=np.float64)
        chain = self.state.field_chain
        if not np.array_equal(v, chain.sync()):
            chain.set_velocities([[chain.field.of(float(x)) for x in row] for row in v.tolist()])
        self.state.velocities = v

    def _run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        ex = self.state.field_chain
        ex.prepare(until_frozen)
        taken, *_ = self._to_limits(until_frozen, None, self.state.collisions, max_steps, max_collisions,
                                    until_frozen, max(1, max_steps))
        self.state.counters[LIVE] = ex.live
        return taken

    def _live(self, until_frozen, carry) -> bool:
        return self.state.field_chain.live != 0  # -1: not known, so maybe live

    def _advance(self, until_frozen, carry, count: int, left: int, taken: int, collisions: int):
        """Blocks of picks to ``count`` steps or ``left`` collisions (or the freeze); the counters advanced."""
        ex, st, s, n = self.state.field_chain, self.state, self.model.selector, self.model.geometry.n_contacts
        used_all, made_all, last = 0, 0, -1
        first = st.steps + 1  # the step of the chunk's first pick
        drawn = s.counter and getattr(ex, "picks", None) is not None and ex.picks.draws and not self.listeners
        while used_all < count and made_all < left and not (until_frozen and ex.live == 0) and ex.failure is None:
            block = int(min(ex.block, count - used_all))
            # the counter stream's picks, drawn where they are tried (a GPU): the stream's words (k0, k1, s, 0)
            if drawn:
                picks = CounterPicks(st.rng[0], st.rng[1], int(st.rng[2]), block, n)
                used, made, at = ex.run(picks, left - made_all, until_frozen, first + used_all)
                st.rng[2] = np.uint64(int(st.rng[2]) + used)
            else:
                rng, sched = st.rng.copy(), st.scheduler.copy()
                picks = ex.picks_buffer(block)
                self.loops.picks(st.scheduler, s.aux, st.rng, n, picks)
                used, made, at = ex.run(picks, left - made_all, until_frozen, first + used_all)
            if made:
                at = np.asarray(at, dtype=np.int64)
                last = used_all + int(at[-1])
                if self.listeners:
                    self.tell(first + used_all + at, picks[at])
            if used < block and not drawn:
                st.rng[:], st.scheduler[:] = rng, sched
                self.loops.picks(st.scheduler, s.aux, st.rng, n, picks[:used])
            used_all, made_all = used_all + used, made_all + made
        st.counters[STEPS] += used_all  # the velocities are rounded when read (`velocities`)
        st.counters[COLLISIONS] += made_all
        if last >= 0:
            st.counters[LAST] = first + last
        failure, ex.failure = ex.failure, None
        if failure is not None:
            st.counters[LIVE] = ex.live
            raise failure
        return used_all, made_all, last, carry

    def velocities(self) -> np.ndarray:
        return self.state.field_chain.sync()

    def resources(self) -> dict:
        """One thread of the CPU, or what its chain's picks say of where they are tried (a GPU's
        `engine.gpu.certified.DevicePicks`: the GPU's name, certified arithmetic)."""
        said = getattr(getattr(self.state.field_chain, "picks", None), "resources", None)
        return said() if callable(said) else super().resources()

    def approaching(self) -> int:
        return self.state.field_chain.count_live()

    def is_frozen(self) -> bool:
        return self.approaching() == 0

    # ------------------------------------------------------------ its state, saved and restored
    def saved(self) -> dict:
        """``{"exact": (n_balls, dim, m) str}``, the exact velocities' coefficients on the field's basis, or
        ``{"certified": CertifiedState}`` (its fixed point, bounds and margin); no float margin is kept."""
        field = self.state.field_chain
        if self.arithmetic == "certified":
            return {"certified": field.certified_state()}
        return {"exact": field.coefficients()}

    def restore(self, state, velocities: np.ndarray) -> None:
        field = self.state.field_chain
        if self.arithmetic == "certified":
            field.set_certified_state(self._certified(state, velocities))
            return
        exact = self._exact(state, velocities)
        try:
            field.set_velocities(exact)
        except ValueError as exc:
            raise FieldError("exact", str(exc)) from None

    def _exact(self, state, velocities: np.ndarray) -> list:
        """The exact velocities of ``state``, checked: they parse in this geometry's field and round to
        ``velocities``."""
        field = self.state.field_chain
        if state.exact is None:
            raise FieldError("exact", "a simulation in exact arithmetic resumes only from an exact state "
                                      "(this one holds float velocities only)")
        shape = (*velocities.shape, field.field.m)
        if np.shape(state.exact) != shape:
            raise FieldError("exact", f"must have shape (n_balls, dim, m) = {shape} in {field.field}, "
                                      f"got {np.shape(state.exact)}")
        try:
            exact = field.parse(state.exact)
        except (ValueError, TypeError, ZeroDivisionError) as exc:
            raise FieldError("exact", f"a coefficient is not a rational number ({exc})") from None
        F = field.field
        rounded = np.array([[F.to_float(x) for x in row] for row in exact])
        if not np.array_equal(rounded, velocities):
            raise FieldError("exact", "the exact velocities do not round to the state's velocities")
        return exact

    def _certified(self, state, velocities: np.ndarray) -> CertifiedState:
        """The `CertifiedState` of ``state``, checked: it fits this geometry and its nearest floats are
        ``velocities``."""
        c = state.certified
        if not isinstance(c, CertifiedState):
            raise FieldError("certified", "a simulation in certified arithmetic resumes only from a certified state "
                                          f"(this one holds {'exact' if state.exact is not None else 'float'} "
                                          "velocities)")
        ex = self.state.field_chain
        c.check((*velocities.shape, ex.field.m), ex.B.shape[1])
        if not np.array_equal(nearest_floats(from_limbs(c.limbs), int(c.scale), ex.field.basis[-1]), velocities):
            raise FieldError("certified", "the fixed-point velocities do not round to the state's velocities")
        return c


def _no_mark(data, carry, count, left):
    return carry


def _no_settle(data, start, carry, used, count, frozen):
    return carry
