"""Plain-Python twin of the compiled loop, used only by tests.

Obviously correct and slow: Python ints for the random stream, Python floats for
the velocities, one pick at a time. It reproduces the engine's arithmetic
operation by operation, so the two must agree bit for bit (velocities, counters
and the final random state), not merely to a tolerance.

Semantics (see the docstrings of `Xoshiro`, the schedulers and `collide`):

- random stream: xoshiro256** seeded by ``SeedSequence(seed).generate_state(4, uint64)``;
- ``bounded(n)``: Lemire's multiply-and-reject on the top 32 bits;
- schedulers: ``uniform`` (``bounded(n)`` each step), ``sweep`` (0, 1, ..., n-1, 0, ...),
  ``random_sweep`` (Fisher-Yates shuffle of a kept order at the start of every sweep),
  ``colored_sweep`` / ``colored_sweep_shuffle`` (the given colour classes in turn, contact by
  contact: a class's contacts share no ball, so this equals the engine's parallel class; with
  shuffle, a Fisher-Yates shuffle of ``0..C-1`` at the start of every sweep);
- `ReferenceRejectionFree`: the n-fold way with a live array, a position map, and a geometric
  number of picks ``1 + floor(log(1 - u) / log1p(-L/M))``;
- a step is one pick; a collision is a pick whose closing speed ``w`` is positive.
"""

from __future__ import annotations

import math

import numpy as np

MASK64 = (1 << 64) - 1
MASK32 = (1 << 32) - 1
GOLDEN = 0x9E3779B97F4A7C15

SCHEDULERS = ("uniform", "sweep", "random_sweep", "colored_sweep", "colored_sweep_shuffle")


# ---------------------------------------------------------------- random stream


def seed_state(seed: int) -> list[int]:
    """The 4 words of the initial xoshiro256** state for an integer seed."""
    words = [int(x) for x in np.random.SeedSequence(seed).generate_state(4, dtype=np.uint64)]
    if not any(words):
        words[0] = GOLDEN
    return words


def _rotl(x: int, k: int) -> int:
    return ((x << k) | (x >> (64 - k))) & MASK64


class Xoshiro:
    """xoshiro256** on four Python ints (each kept in ``[0, 2**64)``)."""

    def __init__(self, state):
        self.s = [int(x) & MASK64 for x in state]
        if not any(self.s):
            raise ValueError("xoshiro256** state must not be all zero")
        self.draws = 0  # how many 64-bit words were used (rejections make it exceed the picks)

    def next(self) -> int:
        self.draws += 1
        s0, s1, s2, s3 = self.s
        result = (_rotl((s1 * 5) & MASK64, 7) * 9) & MASK64
        t = (s1 << 17) & MASK64
        s2 ^= s0
        s3 ^= s1
        s1 ^= s2
        s0 ^= s3
        s2 ^= t
        s3 = _rotl(s3, 45)
        self.s = [s0, s1, s2, s3]
        return result

    def bounded(self, n: int) -> int:
        """A uniform integer in ``[0, n)`` for ``1 <= n <= 2**32`` (Lemire 2019)."""
        if not 1 <= n <= 1 << 32:
            raise ValueError(f"bounded: n must be in [1, 2**32], got {n}")
        m = (self.next() >> 32) * n
        low = m & MASK32
        if low < n:
            threshold = ((1 << 32) - n) % n
            while low < threshold:
                m = (self.next() >> 32) * n
                low = m & MASK32
        return m >> 32

    def uniform(self) -> float:
        """A float in ``[0, 1)`` from the top 53 bits of one draw."""
        return (self.next() >> 11) * (1.0 / 9007199254740992.0)

    @property
    def state(self) -> list[int]:
        return list(self.s)


# ---------------------------------------------------------------- schedulers


class UniformPicker:
    """The paper's scheduler: each step a contact uniformly at random."""

    def __init__(self, n: int):
        self.n = n

    def pick(self, rng: Xoshiro) -> int:
        return rng.bounded(self.n)


class SweepPicker:
    """Contacts 0, 1, ..., n-1, 0, 1, ...; no randomness."""

    def __init__(self, n: int):
        self.n = n
        self.next_k = 0

    def pick(self, rng: Xoshiro) -> int:
        k = self.next_k
        self.next_k = (k + 1) % self.n
        return k


class RandomSweepPicker:
    """Every contact once per sweep; the kept order is reshuffled (Fisher-Yates) before each sweep."""

    def __init__(self, n: int):
        self.n = n
        self.order = list(range(n))
        self.position = n  # shuffle before the first pick

    def pick(self, rng: Xoshiro) -> int:
        if self.position >= self.n:
            order = self.order
            for m in range(self.n - 1, 0, -1):
                r = rng.bounded(m + 1)
                order[m], order[r] = order[r], order[m]
            self.position = 0
        k = self.order[self.position]
        self.position += 1
        return k


class ColoredSweepPicker:
    """The colour classes in turn, each contact by contact; with ``shuffle`` the classes' order is
    ``0..C-1`` shuffled (Fisher-Yates) at the start of every sweep."""

    def __init__(self, classes, shuffle: bool):
        self.classes = [[int(k) for k in c] for c in classes]
        self.shuffle = shuffle
        self.order: list[int] = []
        self.slot, self.offset = -1, 0  # -1: start a sweep before the next pick

    def pick(self, rng: Xoshiro) -> int:
        if self.slot < 0:
            self.order = list(range(len(self.classes)))
            if self.shuffle:
                for m in range(len(self.order) - 1, 0, -1):
                    r = rng.bounded(m + 1)
                    self.order[m], self.order[r] = self.order[r], self.order[m]
            self.slot, self.offset = 0, 0
        members = self.classes[self.order[self.slot]]
        k = members[self.offset]
        self.offset += 1
        if self.offset == len(members):
            self.slot = self.slot + 1 if self.slot + 1 < len(self.classes) else -1
            self.offset = 0
        return k


def make_picker(kind: str, n: int, classes=None):
    if kind.startswith("colored_sweep"):
        return ColoredSweepPicker(classes, shuffle=kind.endswith("shuffle"))
    return {"uniform": UniformPicker, "sweep": SweepPicker, "random_sweep": RandomSweepPicker}[kind](n)


# ---------------------------------------------------------------- collisions


def closing_speed(v: list[list[float]], i: int, j: int, ti, tj) -> float:
    """``w = v_i . t_i + v_j . t_j``, summed component by component in this exact order."""
    w = 0.0
    for c in range(len(ti)):
        w += v[i][c] * ti[c] + v[j][c] * tj[c]
    return w


def collide(v, i, j, ti, tj, r: float, masses, write: bool = True, threshold: float = 0.0) -> bool:
    """Collide contact ``(i, j)`` if it approaches (closing speed above ``threshold``, which is
    >= 0: smaller ones are rounding remnants); return whether any velocity component changes (a
    collision, as the paper counts them). Writes only if ``write``.

    ``masses`` is None for equal masses, else a list of floats.
    """
    w = closing_speed(v, i, j, ti, tj)
    if not w > 0.0 or not w > threshold:
        return False
    if masses is None:
        ci = cj = w * ((1.0 + r) / 2.0)
    else:
        s = (1.0 + r) * w / (masses[i] + masses[j])
        ci, cj = s * masses[j], s * masses[i]
    new_i = [v[i][c] - ci * ti[c] for c in range(len(ti))]
    new_j = [v[j][c] - cj * tj[c] for c in range(len(tj))]
    changed = new_i != v[i] or new_j != v[j]
    if write:
        v[i], v[j] = new_i, new_j
    return changed


# ---------------------------------------------------------------- the chain


class ReferenceSimulation:
    """The whole chain in plain Python: same inputs and seed as a `pinnedballs.Simulation`.

    pairs: ``(E, 2)`` ball indices; t_i, t_j: ``(E, dim)`` unit vectors (as from
    ``geom.contacts``); velocities ``(n_balls, dim)``; r: restitution (1 = elastic);
    masses: None or ``(n_balls,)`` (all equal is treated as None, as the engine does);
    scheduler: one of `SCHEDULERS`; classes: the colour classes (lists of contact indices) for
    the colored sweeps.
    """

    def __init__(self, pairs, t_i, t_j, velocities, r=1.0, masses=None, scheduler="uniform", seed=0, classes=None,
                 threshold=None):
        self.pairs = np.asarray(pairs).astype(np.int64).tolist()
        self._t_i = np.asarray(t_i, dtype=np.float64)  # rows become lists of Python floats on use
        self._t_j = np.asarray(t_j, dtype=np.float64)
        self.v = np.asarray(velocities, dtype=np.float64).tolist()
        self.r = float(r)
        if masses is not None:
            m = [float(x) for x in np.broadcast_to(np.asarray(masses, dtype=np.float64), (len(self.v),))]
            masses = None if all(x == m[0] for x in m) else m
        self.masses = masses
        if threshold is None:  # a parameter of the chain, as the engine sets it (tested on its own)
            from pinnedballs.rules import threshold as remnants
            m = np.ones(len(self.v)) if masses is None else np.asarray(masses, dtype=np.float64)
            threshold = remnants(np.asarray(velocities, dtype=np.float64), m)
        self.threshold = float(threshold)
        self.picker = make_picker(scheduler, len(self.pairs), classes)
        self.rng = Xoshiro(seed_state(seed))
        self.steps = 0
        self.collisions = 0
        self.picks: list[int] = []  # every contact tried, in order (for scheduler tests)
        self.collision_steps: list[int] = []  # the step number of every collision

    @classmethod
    def from_geometry(cls, geom, velocities, **kwargs) -> ReferenceSimulation:
        """The twin of a simulation on ``geom``; the colored sweeps take the engine's classes
        (the colouring itself is checked separately)."""
        c = geom.contacts
        if kwargs.get("scheduler", "").startswith("colored_sweep"):
            import pinnedballs as pb

            kwargs["classes"] = pb.ColoredSweep.classes(geom)
        return cls(c.pairs, c.t_i, c.t_j, velocities, **kwargs)

    # ---------------------------------------------------------- one step
    def units(self, k: int) -> tuple[list[float], list[float]]:
        """``t_i, t_j`` of contact ``k`` as lists of Python floats (exact copies)."""
        return self._t_i[k].tolist(), self._t_j[k].tolist()

    def w(self, k: int) -> float:
        i, j = self.pairs[k]
        return closing_speed(self.v, i, j, *self.units(k))

    def step(self) -> bool:
        """One pick; collide if approaching. Returns whether it collided."""
        k = self.picker.pick(self.rng)
        self.picks.append(k)
        self.steps += 1
        i, j = self.pairs[k]
        hit = collide(self.v, i, j, *self.units(k), self.r, self.masses, threshold=self.threshold)
        if hit:
            self.collisions += 1
            self.collision_steps.append(self.steps)
        return hit

    def live(self, k: int) -> bool:
        """Would picking contact ``k`` change velocities?"""
        i, j = self.pairs[k]
        return collide(self.v, i, j, *self.units(k), self.r, self.masses, write=False, threshold=self.threshold)

    def approaching(self) -> int:
        """Live contacts (0: frozen), counted afresh over all contacts."""
        return sum(1 for k in range(len(self.pairs)) if self.live(k))

    # ---------------------------------------------------------- runs
    def run(self, steps=None, collisions=None) -> int:
        """As `Simulation.run`: ``steps`` more picks and/or until ``collisions`` in total.

        With only ``collisions`` given, also stops once frozen.
        """
        track = steps is None
        max_steps = float("inf") if steps is None else steps
        max_collisions = float("inf") if collisions is None else collisions
        return self._run(max_steps, max_collisions, track)

    def run_until_frozen(self, max_steps: int) -> bool:
        self._run(max_steps, float("inf"), track=True)
        return self.approaching() == 0

    def _run(self, max_steps, max_collisions, track) -> int:
        """Pick until a limit; with ``track``, stop as soon as no contact is live."""
        taken, live = 0, self.approaching() if track else None
        while taken < max_steps and self.collisions < max_collisions and live != 0:
            taken += 1
            if self.step() and track:  # velocities change only at collisions
                live = self.approaching()
        return taken

    # ---------------------------------------------------------- results
    @property
    def velocities(self) -> np.ndarray:
        return np.array(self.v, dtype=np.float64)

    @property
    def rng_state(self) -> list[int]:
        return self.rng.state


# ---------------------------------------------------------------- every order (pinnedballs.orders)


class ReplayPicker:
    """The contacts of a given order in turn; refuses to go past its end (`orders.Replay`)."""

    def __init__(self, order):
        self.order = [int(k) for k in order]
        self.position = 0

    def pick(self, rng: Xoshiro) -> int:
        if self.position >= len(self.order):
            raise ValueError("Replay: every contact of its order has been picked")
        self.position += 1
        return self.order[self.position - 1]


class OrderTree:
    """Every order of collisions of a small system, by plain recursion over sequences.

    No state is merged with another and nothing is memoised: each sequence of live contacts
    is followed to the freeze on its own copy of the velocities (Python floats, `collide`).
    Arguments as for `ReferenceSimulation` (without scheduler and seed).
    """

    def __init__(self, pairs, t_i, t_j, velocities, r=1.0, masses=None):
        self.sim = ReferenceSimulation(pairs, t_i, t_j, velocities, r=r, masses=masses)
        self.v0 = [list(row) for row in self.sim.v]

    @classmethod
    def from_geometry(cls, geom, velocities, **kwargs) -> OrderTree:
        c = geom.contacts
        return cls(c.pairs, c.t_i, c.t_j, velocities, **kwargs)

    def live(self, v) -> list[int]:
        """Contacts whose collision would change some velocity component, in contact order."""
        s = self.sim
        return [k for k in range(len(s.pairs))
                if collide(v, *s.pairs[k], *s.units(k), s.r, s.masses, write=False, threshold=s.threshold)]

    def after(self, v, k: int):
        """A copy of ``v`` after colliding contact ``k``."""
        s = self.sim
        w = [list(row) for row in v]
        collide(w, *s.pairs[k], *s.units(k), s.r, s.masses, threshold=s.threshold)
        return w

    def sequences(self) -> list[tuple[int, ...]]:
        """Every order: each sequence of live contacts that ends frozen."""
        out = []

        def descend(v, prefix):
            ks = self.live(v)
            if not ks:
                out.append(tuple(prefix))
            for k in ks:
                descend(self.after(v, k), prefix + [k])

        descend(self.v0, [])
        return out

    def states(self) -> set[bytes]:
        """The distinct states (bits of the velocities) some order passes through, the start included."""
        seen = set()

        def descend(v):
            seen.add(np.array(v, dtype=np.float64).tobytes())
            for k in self.live(v):
                descend(self.after(v, k))

        descend(self.v0)
        return seen

    def random_order_law(self) -> dict[int, float]:
        """``{collisions: probability}`` under the paper's scheduler, whose next collision is
        uniform among the live contacts (rejected picks change nothing)."""
        law: dict[int, float] = {}

        def descend(v, n, p):
            ks = self.live(v)
            if not ks:
                law[n] = law.get(n, 0.0) + p
            for k in ks:
                descend(self.after(v, k), n + 1, p / len(ks))

        descend(self.v0, 0, 1.0)
        return law
# ---------------------------------------------------------------- the n-fold way


def picks_until_live(rng: Xoshiro, n_live: int, n_contacts: int) -> int:
    """Geometric with ``p = n_live / n_contacts``: ``1 + floor(log(1 - u) / log1p(-p))``, capped
    at 2**62; ``p = 1`` gives 1 without a draw."""
    if n_live == n_contacts:
        return 1
    u = rng.uniform()
    x = 1.0 + math.floor(math.log(1.0 - u) / math.log1p(-(n_live / n_contacts)))
    return int(min(x, float(2**62)))


class ReferenceRejectionFree(ReferenceSimulation):
    """`pinnedballs.RejectionFree` in plain Python: the same inputs and seed give the same bits.

    The live contacts are a list (initially in contact order) with a position map; after a
    collision the contacts of ball i, then of ball j, each in contact order, are re-tested:
    a newly live one is appended, one no longer live is replaced by the last entry. ``rest``
    keeps the picks still to come when a run ends at its step limit.
    """

    def __init__(self, *args, **kwargs):
        kwargs["scheduler"] = "uniform"  # unused: this class has its own loop
        super().__init__(*args, **kwargs)
        n_balls = len(self.v)
        self.incident = [[] for _ in range(n_balls)]
        for k, (i, j) in enumerate(self.pairs):
            self.incident[i].append(k)
            self.incident[j].append(k)
        self.live_list = [k for k in range(len(self.pairs)) if self.live(k)]
        self.pos = {k: m for m, k in enumerate(self.live_list)}
        self.rest = 0

    def _update(self, ball: int) -> None:
        for c in self.incident[ball]:
            now = self.live(c)
            if now and c not in self.pos:
                self.pos[c] = len(self.live_list)
                self.live_list.append(c)
            elif not now and c in self.pos:
                at = self.pos.pop(c)
                last = self.live_list.pop()
                if last != c:
                    self.live_list[at] = last
                    self.pos[last] = at

    def _run(self, max_steps, max_collisions, track) -> int:
        taken, n = 0, len(self.pairs)
        while taken < max_steps and self.collisions < max_collisions and not (track and not self.live_list):
            left = max_steps - taken
            if not self.live_list:
                taken = max_steps
                break
            if self.rest > 0:
                g, self.rest = self.rest, 0
            else:
                g = picks_until_live(self.rng, len(self.live_list), n)
            if g > left:
                self.rest = g - left
                taken = max_steps
                break
            taken += g
            k = self.live_list[self.rng.bounded(len(self.live_list))]
            self.picks.append(k)
            i, j = self.pairs[k]
            assert collide(self.v, i, j, *self.units(k), self.r, self.masses, threshold=self.threshold)
            self.collisions += 1
            self.collision_steps.append(self.steps + taken)
            self._update(i)
            self._update(j)
        self.steps += taken
        return taken
