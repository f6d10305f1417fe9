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
# # Exact counts and every order
#
# The number of collisions until the system freezes is what the theory is about
# (Athreya–Burdzy–Duarte 2018, Burdzy–Duarte 2022): finite for any finite configuration, whatever
# the order of collisions. This page counts it for the paper's half-plane in floating point and in
# exact arithmetic on the same random picks, reads how close a float run came to its collision
# criterion (its *closing margin*), treats the criterion as a parameter of the model, and then, on
# systems of a few balls, takes the fewest and the most collisions over every order, and the most
# over every initial velocity too.
# (The pages *Exact collision counts*, `docs/collisions.md`, and *Every order of collisions*,
# `docs/orders.md`, are the reference.)
#
# It runs top to bottom in about half a minute on a quiet 2-core machine (more where the cores are shared).

# %%
# %matplotlib inline
import time
import warnings

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import pinnedballs as pb


def paper_start(geometry) -> np.ndarray:
    """The paper's initial velocities: the boundary ball nearest the middle sent in with energy 100."""
    v = np.zeros((geometry.n_balls, 2))
    v[geometry.boundary_center()] = [0.0, np.sqrt(200.0)]
    return v


# %% [markdown]
# ## Float and exact, on the same picks
#
# `arithmetic="exact"` runs the same chain with every velocity an exact number: on the triangular
# lattice every contact normal is `(±1, 0)` or `(±1/2, ±√3/2)`, so velocities that start as floats
# (every float is a rational) stay in Q(√3) through any number of collisions, and the sign of every
# closing speed is decided exactly. The picks come from the same scheduler and the same random
# stream, so with the same seed both runs try the same contacts in the same order.

# %%
half = pb.HalfPlane.from_size(60, 30)
v = paper_start(half)

rows = {}
runs = {}
for arithmetic in ("float", "exact"):
    sim = pb.Simulation(half, v, seed=1, arithmetic=arithmetic)
    start = time.perf_counter()
    frozen = sim.run_until_frozen(max_steps=10**9)
    rows[arithmetic] = {"frozen": frozen, "steps": sim.steps, "collisions": sim.collisions,
                        "energy": sim.energy(), "seconds": round(time.perf_counter() - start, 2)}
    runs[arithmetic] = sim
counts = pd.DataFrame(rows).T
counts

# %%
float_run, exact_run = runs["float"], runs["exact"]
print("same count:", float_run.collisions == exact_run.collisions,
      "| last collision on the same step:", float_run.steps == exact_run.steps)
print(f"largest difference between the float velocities and the exact ones: "
      f"{np.abs(float_run.velocities - exact_run.velocities).max():.2g}")
print("the boundary ball's exact velocity:", exact_run.exact_velocities[half.boundary_center()])

# %% [markdown]
# The float run makes exactly the exact run's collisions, and its velocities stay within a few
# units in the last place of the exact ones (speeds here are up to √200 ≈ 14). The exact velocity
# shows what exactness costs: rationals with ever larger powers of 2 below, and every collision
# computed on them.
#
# ## The closing margin of a float run
#
# In exact arithmetic many closing speeds are exactly zero: a ball that handed on all of its
# velocity along a line of centres is at rest along it. In floats it keeps a *remnant* of a few
# units in the last place, and its contacts seem to approach at about 1e-16. So a float run
# collides a contact only when its closing speed exceeds a threshold, 4 units in the last place of
# the system's speed scale `V = √(2E/m)` (`sim.threshold`). `sim.closing_margin()` says how near
# that threshold the run's picks came, in thresholds: the smallest closing speed counted as a
# collision, the largest positive one set aside.

# %%
margin = float_run.closing_margin()
print(f"threshold {float_run.threshold:.3g} (resolution {float_run.resolution:.3g} of V)")
print(margin.describe())
print("thin:", margin.thin)

# %% [markdown]
# About ten orders of magnitude lie between the slowest genuine collision and the largest
# remnant: any criterion in between counts the same collisions, so the count is a clean fact. A
# margin is
# *thin* when a collision closed within a factor 10^4 of the threshold: genuine closing speeds then
# reach down towards the criterion, and some might lie below it. They do in larger systems, where
# a tiny collision moves a tiny momentum and makes tinier closing speeds elsewhere. On the 200 x 100
# half-plane (5,800 balls, three million picks, a fraction of a second in floats) the margin is
# thin, and the run says so once, as a `MarginWarning`:

# %%
big = pb.HalfPlane.from_size(200, 100)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    big_run = pb.Simulation(big, paper_start(big), seed=2)
    big_run.run_until_frozen(max_steps=10**9)
print(big_run.collisions, "collisions;", big_run.closing_margin().describe())
for warning in caught:
    print(f"{warning.category.__name__}: {warning.message}")

# %% [markdown]
# ## The criterion as a model: N_e
#
# `resolution=e` makes the criterion part of the model: a pick collides when its closing speed
# exceeds `e V`, and the count until frozen is `N_e`, a number of its own (no warning then: the
# criterion is stated). A vanishing `e` counts every pick that changes a bit of a velocity, rounding
# remnants included; a large one leaves slow genuine approaches out. Here `N_e` for resolutions from
# 1e-30 to 1e-2 on both half-planes, against the exact count.

# %%
ULP = 2.0**-53  # the default resolution is 4 ULP
resolutions = np.logspace(-30, -2, 57)


def counts_by_resolution(geometry, seed: int) -> pd.Series:
    """N_e until frozen for each resolution e, the paper's start and picks seeded by ``seed``."""
    start = paper_start(geometry)
    n_e = {}
    for e in resolutions:
        sim = pb.Simulation(geometry, start, seed=seed, resolution=e)
        sim.run_until_frozen(max_steps=10**9)
        n_e[e] = sim.collisions
    return pd.Series(n_e, name="N_e")


n_small = counts_by_resolution(half, seed=1)
n_big = counts_by_resolution(big, seed=2)

# %% [markdown]
# The exact count of the large run is 476,553 (`arithmetic="exact"` with the same seed, measured
# once: it takes one to ten minutes on 2 cores, as busy as they are, so it is not run here). Near
# the default resolution, in units in the last place of `V` (ULP, `2^-53 V`):

# %%
EXACT_BIG = 476_553  # pb.Simulation(big, paper_start(big), seed=2, arithmetic="exact"), measured once

columns = {"1/4 ULP": ULP / 4, "1 ULP": ULP, "4 ULP (default)": 4 * ULP, "8 ULP": 8 * ULP,
           "16 ULP": 16 * ULP}
near_default = pd.DataFrame(index=["60x30", "200x100"], columns=[*columns, "exact"])
for name, geometry, seed in (("60x30", half, 1), ("200x100", big, 2)):
    for column, e in columns.items():
        sim = pb.Simulation(geometry, paper_start(geometry), seed=seed, resolution=e)
        sim.run_until_frozen(max_steps=10**9)
        near_default.loc[name, column] = sim.collisions
near_default["exact"] = [exact_run.collisions, EXACT_BIG]
near_default

# %% [markdown]
# The whole range, as the difference `N_e - N_exact` (on a scale linear within ±1, logarithmic
# beyond):

# %%
fig, ax = plt.subplots(figsize=(8, 4.5))
for name, n_e, exact in (("60 x 30, seed 1", n_small, exact_run.collisions),
                         ("200 x 100, seed 2", n_big, EXACT_BIG)):
    ax.plot(n_e.index, n_e.values - exact, "o-", ms=3, label=f"{name} (exact: {exact:,})")
ax.axhline(0, color="k", lw=0.8)
ax.axvline(4 * ULP, color="tab:red", lw=1, ls="--", label="default resolution, 4 ULP")
ax.set(xscale="log", yscale="symlog", xlabel="resolution e (a pick collides when its closing speed w > e V)",
       ylabel="N_e - exact count", title="Collisions until frozen, float with resolution e, against exact")
ax.legend(loc="lower left")

# %%
for name, n_e, exact in (("60 x 30", n_small, exact_run.collisions), ("200 x 100", n_big, EXACT_BIG)):
    agree = n_e.index[n_e.values == exact]
    print(f"{name}: N_e - exact = {n_e.iloc[0] - exact:+,} at e = 1e-30 and {n_e.iloc[-1] - exact:+,} "
          f"at e = 1e-2; N_e = exact at {len(agree)} of {len(n_e)} resolutions, "
          f"from {agree.min():.1e} to {agree.max():.1e}")

# %% [markdown]
# On 60 x 30 the float count is the exact one over ten decades of resolution, from about 3e-17 to
# 3e-7, with the default in the middle: below, rounding remnants are counted as collisions (43 more
# when every bit change counts); above, slow genuine collisions are left out, and the count falls.
# On 200 x 100 the plateau has shrunk to a factor of about 16, from about a quarter of a ULP to
# about 5: the largest remnant closed at 0.07 thresholds and the slowest collision at 1.2, and a
# criterion a little beyond either changes the count. The default's count is the exact one here,
# but nothing in the float run can show it: only the exact run does. In larger systems genuine
# approaches close slower still, below any float criterion (*Exact collision counts*,
# `docs/collisions.md`): count exactly, or state the resolution as part of the model and report `N_e`.
#
# ## Every order of a small system
#
# The paper's scheduler follows one random order. `pb.explore_orders` searches every order of a
# small system (in exact arithmetic, merging states that are exactly equal) and returns the fewest
# and the most collisions until frozen, with an order reaching each. The 2 x 5 half-plane (two rows
# of five balls, 17 contacts), the paper's start:

# %%
tiny = pb.HalfPlane(2, 5)
v_tiny = paper_start(tiny)
orders = pb.explore_orders(tiny, v_tiny)
print(orders)
print("most:", orders.max_order)

# %% [markdown]
# `pb.Replay(order)` is a scheduler that tries the given contacts in turn: the most order, replayed
# in exact arithmetic, collides at every pick and ends frozen.

# %%
replay = pb.Simulation(tiny, v_tiny, scheduler=pb.Replay(orders.max_order), arithmetic="exact")
frozen = replay.run_until_frozen(max_steps=len(orders.max_order))
print(f"frozen {frozen} after {replay.steps} steps, {replay.collisions} collisions")
replay.plot(title=f"2 x 5 half-plane, frozen after the most order: {replay.collisions} collisions")

# %% [markdown]
# How often does the paper's random order come near the most? 2,000 runs of its uniform picks, one
# seed each:

# %%
random_counts = []
for seed in range(2000):
    sim = pb.Simulation(tiny, v_tiny, seed=seed)
    sim.run_until_frozen(max_steps=10**6)
    random_counts.append(sim.collisions)
random_counts = np.array(random_counts)
print(f"random order: {random_counts.min()} to {random_counts.max()} collisions, "
      f"mean {random_counts.mean():.2f}; every order: {orders.min_collisions} to {orders.max_collisions}")

fig, ax = plt.subplots(figsize=(6.5, 3.8))
ax.hist(random_counts, bins=np.arange(orders.min_collisions - 1, orders.max_collisions + 2) - 0.5, rwidth=0.8)
for n, name in ((orders.min_collisions, "fewest"), (orders.max_collisions, "most")):
    ax.axvline(n, color="k", ls="--", lw=1)
    ax.annotate(f"{name} over every order: {n}", (n, 0.95), xycoords=("data", "axes fraction"), rotation=90,
                ha="right", va="top")
ax.set(xlabel="collisions until frozen", ylabel="runs",
       title="2 x 5 half-plane, the paper's start: 2,000 random orders")

# %% [markdown]
# ## The most over velocities and orders
#
# The theory bounds the most collisions over every order *and* every initial velocity.
# `pb.search_max_collisions` climbs over velocities (only their direction matters), taking each
# one's most over every order, and verifies the best it finds by replaying its order in exact
# arithmetic. On the smallest half-plane, 2 x 2 (four balls, five contacts: a rhombus), the paper's
# start gives 2 collisions in every order:

# %%
rhombus = pb.HalfPlane(2, 2)
print(pb.explore_orders(rhombus, paper_start(rhombus)))
best = pb.search_max_collisions(rhombus, trials=200, seed=0)
print(best)
print("velocities:\n", best.velocities, "\norder:", best.order)

# %% [markdown]
# These are the best found, not proven maxima: more trials may find more (`docs/orders.md` has a
# table for small configurations). Replayed on its own, the order does what the search says:

# %%
check = pb.Simulation(rhombus, best.velocities, scheduler=pb.Replay(best.order), arithmetic="exact")
print(check.run_until_frozen(max_steps=len(best.order)), check.collisions)
