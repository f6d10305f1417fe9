# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Your own geometry, rule and scheduler
#
# The engine's loop sees plain data (the contacts) and two small compiled functions (what a
# collision does, which contact comes next), so each of the three is yours to write: here a
# honeycomb from a networkx graph and a star of balls built by hand, a collision rule whose
# restitution depends on the direction of the contact, and a scheduler whose picks wander along
# the list of contacts. Each is checked with the project's own battery, `pinnedballs.testing`,
# and one deliberately broken rule shows what a failed check says.
# (The pages *Extending*, `docs/extending.md`, and *Testing your components*, `docs/testing.md`, are
# the reference.)
#
# It runs top to bottom in one to two minutes on a quiet 2-core machine, most of it compiling: a function defined
# in a notebook is compiled once per kernel (one defined in a module is cached on disk).

# %%
# %matplotlib inline
import networkx as nx
import numpy as np
from numba import njit

import pinnedballs as pb
from pinnedballs.testing import check_geometry, check_rule, check_scheduler, parametrize_with_checks

# %% [markdown]
# ## A geometry from a graph: a honeycomb
#
# `pb.GraphGeometry(graph)` takes any networkx graph whose nodes carry `"pos"`: each node is a
# ball, each edge a contact. networkx draws a honeycomb with edges of length 1; balls of radius 1
# touch at distance 2, so the positions are doubled. Each ball touches three others (two on the
# rim), a packing none of the built-in lattices gives.

# %%
graph = nx.hexagonal_lattice_graph(4, 5)
for _node, data in graph.nodes(data=True):
    data["pos"] = 2.0 * np.asarray(data["pos"])
honeycomb = pb.GraphGeometry(graph)
honeycomb

# %% [markdown]
# `check_geometry` runs every check that applies: the contact tables (balls in range, unit vectors
# of length 1 pointing from each ball to the other, each contact `2 * radius` long), that the
# contacts are exactly the pairs of balls that touch, the round trip through `contact_graph()`, a
# pickle. It returns None, or raises an `AssertionError` naming the first property that broke.

# %%
check_geometry(honeycomb)
print("honeycomb: every geometry check passed")

# %% [markdown]
# ## A geometry of your own: a star
#
# A subclass of `pb.Geometry` sets `positions` and returns its contacts from `_build_contacts()`
# with `pb.Contacts.build(pairs, ends, units)`: for each contact its two balls `(i, j)`, and the
# rows of `units` holding the unit vector at `i` pointing to `j` and the one at `j` pointing back.
# Here a centre ball and `arms` straight arms of `length` balls: every contact of an arm lies
# along the arm, so the star needs only two unit vectors per arm, shared by its contacts (the
# lattices do the same with six). The arms must be at least 60 degrees apart, or their first balls
# would overlap.

# %%
class Star(pb.Geometry):
    """A centre ball (ball 0) and ``arms`` straight arms of ``length`` balls, evenly spread."""

    def __init__(self, arms: int, length: int):
        if not 2 <= arms <= 6:
            raise pb.FieldError("arms", f"must be 2 to 6 (arms closer than 60 degrees overlap), got {arms}")
        if length < 1:
            raise pb.FieldError("length", f"must be at least 1, got {length}")
        self.arms, self.length = arms, length
        angle = 2 * np.pi * np.arange(arms) / arms
        self.directions = np.column_stack([np.cos(angle), np.sin(angle)])       # (arms, 2)
        steps = 2.0 * np.arange(1, length + 1)                                   # centres 2 apart
        arm_balls = steps[None, :, None] * self.directions[:, None, :]          # (arms, length, 2)
        self.positions = np.vstack([np.zeros((1, 2)), arm_balls.reshape(-1, 2)])

    def _build_contacts(self) -> pb.Contacts:
        # contact s of arm a joins the arm's ball s (ball 1 + a * length + s) to the ball before it
        a, s = np.divmod(np.arange(self.arms * self.length), self.length)
        outer = 1 + a * self.length + s
        inner = np.where(s == 0, 0, outer - 1)                   # the centre, or the arm's ball before
        units = np.vstack([self.directions, -self.directions])   # row a: arm a outward; arms + a: inward
        return pb.Contacts.build(np.column_stack([inner, outer]), np.column_stack([a, self.arms + a]), units)

    def __repr__(self) -> str:
        return f"Star(arms={self.arms}, length={self.length})"


star = Star(arms=5, length=6)
check_geometry(star)
print(f"{star}: {star.n_balls} balls, {star.n_contacts} contacts; every geometry check passed")
star

# %% [markdown]
# ## A rule: restitution by direction
#
# A rule hands the loop a compiled `collide(v, units, i, j, a, b, masses, params, dim, flat, write)`
# and its parameters as a float array. With `t_i = units[a]` and `t_j = units[b]` (or `-t_i` in flat
# space), the closing speed is `w = v_i . t_i + v_j . t_j`, and a collision with restitution `r`
# takes `(1 + r) m_j / (m_i + m_j) w t_i` from `v_i` and `(1 + r) m_i / (m_i + m_j) w t_j` from `v_j`.
#
# Here `r` depends on the contact's direction: `r_x` for a contact along x, `r_y` along y, and in
# between `r = r_x + (r_y - r_x) t_y^2`, with `t_y^2` averaged over the two ends (on a curved
# surface `t_i` and `t_j` differ, and naming the balls the other way round must give the same
# collision). The function keeps the engine's protocol: it reads the threshold the engine appends
# to `params` first, collides only when `w` exceeds it (smaller closing speeds are rounding
# remnants, not approaches), writes only when `write` is true, and says whether a velocity changed.

# %%
from pinnedballs.rules import CollisionRule, closing_speed, remnant_threshold


@njit
def collide_by_direction(v, units, i, j, a, b, masses, params, dim, flat, write):
    """params = [r_x, r_y, threshold]: restitution r_x along x, r_y along y, interpolated by t_y^2."""
    r_x, r_y, tau = params[0], params[1], remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    t_jy = -units[a, 1] if flat else units[b, 1]
    r = r_x + (r_y - r_x) * 0.5 * (units[a, 1] ** 2 + t_jy**2)
    s = (1.0 + r) * w / (masses[i] + masses[j])
    changed = False
    for k in range(dim):
        t_jk = -units[a, k] if flat else units[b, k]
        new_i, new_j = v[i, k] - s * masses[j] * units[a, k], v[j, k] - s * masses[i] * t_jk
        changed |= (new_i != v[i, k]) | (new_j != v[j, k])
        if write:
            v[i, k], v[j, k] = new_i, new_j
    return changed


class ByDirection(CollisionRule):
    """Restitution ``r_x`` for contacts along x, ``r_y`` along y (velocities of 2 or more components)."""

    def __init__(self, r_x: float, r_y: float):
        self.r_x, self.r_y = float(r_x), float(r_y)

    @property
    def elastic(self) -> bool:  # a rule that says so is held to conserving energy by the checks
        return self.r_x == self.r_y == 1.0

    def kernel(self, equal_masses: bool):
        return collide_by_direction, np.array([self.r_x, self.r_y])

    def __repr__(self) -> str:
        return f"ByDirection({self.r_x}, {self.r_y})"


# %% [markdown]
# `check_rule` collides the rule on a few hundred random pairs, in 2-D and 3-D flat space and as on
# a curved surface, with equal and unequal masses, and holds it to what any rule must do: leave
# separating balls alone, never create energy, keep momentum in flat space, not care which ball is
# called `i`, pickle. A rule that says it is elastic is also held to keeping the energy.

# %%
check_rule(ByDirection(1.0, 0.5))
check_rule(ByDirection(1.0, 1.0))  # elastic: its energy is checked too
print("ByDirection: every rule check passed")

# %% [markdown]
# ## A scheduler: picks that wander
#
# A scheduler answers "which contact next". The simple kind gives a compiled
# `pick(state, rng, n_contacts) -> (k, rng)`: `state` is its own `int64` array (everything that
# changes lives there, so a checkpoint resumes it), `rng` the simulation's random stream, advanced
# only through `pinnedballs.engine.streams.xoshiro` (here `bounded(rng, 2)`: 0 or 1, uniform).
#
# This one remembers its last pick and moves one place left or right in the list of contacts: a
# local, correlated order, unlike the paper's independent uniform picks. On the star, contacts
# next to each other in the list share a ball along an arm.

# %%
from pinnedballs.engine.streams.xoshiro import bounded
from pinnedballs.schedulers import Scheduler


@njit
def pick_wandering(state, rng, n_contacts):
    """state = [last pick]: the next pick is the contact before or after it (cyclically)."""
    r, rng = bounded(rng, 2)
    n = np.int64(n_contacts)
    k = (state[0] + 2 * np.int64(r) - 1 + n) % n  # int64 throughout: uint64 with int64 gives a float
    state[0] = k
    return np.uint64(k), rng


class Wander(Scheduler):
    """Each pick one place before or after the last one in the list of contacts, at random."""

    def kernel(self):
        return pick_wandering

    def initial_state(self, n_contacts: int) -> np.ndarray:
        return np.zeros(1, dtype=np.int64)


# %% [markdown]
# `check_scheduler` runs it on a small torus and a half-plane: every pick a contact, the same seed
# giving the same run, a run split into calls ending where one call does, bit for bit, and its
# state saved and restored elsewhere continuing the run exactly.

# %%
check_scheduler(Wander())
print("Wander: every scheduler check passed")

# %% [markdown]
# ## Running them
#
# The star, its centre ball sent along 15 degrees with energy 100: under the paper's elastic rule
# and uniform picks, then under the rule above with uniform picks, then with wandering ones. Finitely
# many balls in the plane, like the star, freeze under elastic collisions whatever the order
# (Athreya–Burdzy–Duarte 2018; Burdzy–Duarte 2022); the lossy runs freeze too, while a torus never
# does (`docs/model.md`). The table gives each arm's energy in the frozen state (arm 0 points along
# x, arm 1 at 72 degrees, ...).

# %%
import pandas as pd

v = np.zeros((star.n_balls, 2))
v[0] = np.sqrt(200.0) * np.array([np.cos(np.pi / 12), np.sin(np.pi / 12)])

lossy = ByDirection(1.0, 0.5)
runs = {"elastic, uniform picks": pb.Simulation(star, v, seed=1),
        "ByDirection, uniform picks": pb.Simulation(star, v, rule=lossy, seed=1),
        "ByDirection, wandering picks": pb.Simulation(star, v, rule=lossy, scheduler=Wander(), seed=1)}
rows = {}
for name, sim in runs.items():
    frozen = sim.run_until_frozen(max_steps=10**6)
    arm_energy = 0.5 * (sim.velocities[1:] ** 2).sum(axis=1).reshape(star.arms, star.length).sum(axis=1)
    rows[name] = {"frozen": frozen, "steps": sim.steps, "collisions": sim.collisions, "energy": sim.energy(),
                  **{f"arm {a}": e for a, e in enumerate(arm_energy)}}
table = pd.DataFrame.from_dict(rows, orient="index").round(2)
table

# %% [markdown]
# The elastic run keeps all 100 and spreads it over three arms. The lossy rule loses energy on
# every collision off the x-axis. The wandering picks start beside contact 0, the centre's contact
# with arm 0, and reach it long before the centre's contacts with the other arms (contacts 6, 12,
# 18 and 24): the centre ball hands its velocity's component along x, cos²15° = 93.3 % of the
# energy, down arm 0, where collisions are elastic, and little is lost. The order of collisions is
# part of the model.
#
# `sim.plot()` draws a state in the geometry's own view (arrows on the ball centres for a flat
# 2-D geometry, the user's as much as the built-in ones) and returns the matplotlib figure; given
# `ax=`, it draws there.

# %%
import matplotlib.pyplot as plt

fig, axes = plt.subplots(1, 3, figsize=(15, 5.0), layout="constrained")
for ax, (name, sim) in zip(axes, runs.items()):
    sim.plot(ax=ax, title=f"{name}:\nfrozen after {sim.collisions} collisions")

# %% [markdown]
# The honeycomb, every ball given a random velocity, under a lossier rule: a simulation shows
# itself in a notebook as its counters beside its state.

# %%
v = np.random.default_rng(7).normal(size=(honeycomb.n_balls, 2))
sim = pb.Simulation(honeycomb, v, rule=ByDirection(1.0, 0.2), seed=3)
frozen = sim.run_until_frozen(max_steps=10**6)
print(f"frozen {frozen} after {sim.collisions} collisions: energy {0.5 * (v**2).sum():.3f} "
      f"-> {sim.energy():.3f}")
sim

# %% [markdown]
# ## A broken rule, caught
#
# `ByDirection` takes any numbers. Given `r_y = 1.2`, a typo or a misread paper, its collisions
# along y push the balls apart faster than they closed: energy appears from nowhere. A run would
# simply give wrong numbers; the checks say what broke, with one pair of balls that shows it
# (its unit vectors, masses and velocities):

# %%
try:
    check_rule(ByDirection(1.0, 1.2))
except AssertionError as error:
    print(error)

# %% [markdown]
# The fix is to refuse such coefficients where the rule is made, with one line naming the
# argument: `pb.FieldError` is a `ValueError` whose `.field` is the argument's name.

# %%
class CheckedByDirection(ByDirection):
    """`ByDirection` with its coefficients checked: each in [0, 1]."""

    def __init__(self, r_x: float, r_y: float):
        for name, r in (("r_x", r_x), ("r_y", r_y)):
            if not 0.0 <= r <= 1.0:
                raise pb.FieldError(name, f"a coefficient of restitution must be in [0, 1], got {r}")
        super().__init__(r_x, r_y)


try:
    CheckedByDirection(1.0, 1.2)
except ValueError as error:
    print(error)

# %% [markdown]
# ## In your test suite
#
# `parametrize_with_checks` makes one pytest test per component and check, named
# `<component>-<check>`, so a failure says which at a glance. A check a component is known to fail
# is declared with its reason and runs as a strict `xfail`. In a test file:
#
# ```python
# @parametrize_with_checks([Star(5, 6), ByDirection(1.0, 0.5), Wander()])
# def test_my_components(component, check):
#     check(component)
# ```
#
# These are the tests it makes:

# %%
mark = parametrize_with_checks([Star(5, 6), ByDirection(1.0, 0.5), Wander()])
names, cases = mark.args
print(len(cases), "tests:")
print("\n".join(case.id for case in cases))
