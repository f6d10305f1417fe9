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
# # A first run and its figures
#
# The paper's half-plane: a 100 x 50 rectangle of pinned balls (29 rows of 50), one ball on the
# boundary sent into the others with energy 100, run until no contact approaches any more. Along the
# way: how a geometry and a simulation show themselves in a notebook, the figures, the same run from a
# spec file, and its numbers as a table.
#
# This page is a notebook: open `docs/tutorials/first_run.py` in Jupyter (with jupytext), or run it
# headless into a notebook with its outputs, `jupytext --to notebook --execute docs/tutorials/first_run.py`
# (both from `python3 -m pip install ".[notebook]"`). It runs top to bottom in about half a minute on a quiet
# 2-core machine (more where the cores are shared).

# %%
# %matplotlib inline
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import pinnedballs as pb

scratch = tempfile.TemporaryDirectory(prefix="pinnedballs-tutorial-")  # removed when the kernel stops
work = Path(scratch.name)  # the run directories go here

# %% [markdown]
# ## The geometry
#
# `HalfPlane.from_size(100, 50)` is the paper's rectangle, lengths in ball radii; row 0 is the
# boundary. A geometry shows a table of what a reader checks first, beside a picture of its balls.

# %%
half = pb.HalfPlane.from_size(100, 50)
half

# %% [markdown]
# ## A simulation, before and after
#
# All velocities zero except the boundary ball nearest the middle, pointing into the balls with
# energy 100 (speed √200). The paper's scheduler picks a contact uniformly at random; the pair
# collides when it approaches. A simulation shows its counters, its energy and whether it froze,
# beside its state.

# %%
v = np.zeros((half.n_balls, 2))
v[half.boundary_center()] = [0.0, np.sqrt(200.0)]
sim = pb.Simulation(half, v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=0)
sim.run(steps=90_000)
sim

# %%
frozen = sim.run_until_frozen(max_steps=10**9)
print(frozen, sim.steps, sim.collisions, round(sim.energy(), 9))
sim

# %% [markdown]
# `sim.plot()` draws the same state and returns the matplotlib figure, to change or save. Given an
# `ax`, it draws there, so states sit side by side:

# %%
fig, (left, right) = plt.subplots(1, 2, figsize=(12, 3.8), layout="constrained")
pb.Simulation(half, v, seed=0).plot(ax=left, title="the start")
sim.plot(ax=right, title=f"frozen after {sim.collisions:,} collisions")

# %% [markdown]
# ## The same run from a spec, as `pinnedballs run` does it
#
# A run spec is JSON: `pb.load_spec` reads and checks it, with the command line's one-line messages;
# `pb.run_spec` runs it into a directory (results, checkpoints, figures) and returns the results.

# %%
spec_file = work / "halfplane.json"
spec_file.write_text("""{
  "geometry": {"kind": "half_plane", "length": 100, "depth": 50},
  "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
  "stop": {"frozen": true, "max_steps": 1000000000},
  "snapshots": {"at_collisions": [0, 5000, 22579]},
  "seed": 1
}""")
spec = pb.load_spec(spec_file)
spec

# %% [markdown]
# A typo is one line that names the field and suggests the word meant:

# %%
bad = work / "typo.json"
bad.write_text(spec_file.read_text().replace('"length"', '"lenght"'))
try:
    pb.load_spec(bad)
except ValueError as error:
    print(error)

# %%
res = pb.run_spec(spec, work / "halfplane")
res

# %% [markdown]
# ## The figures
#
# `res.plot(...)` returns each figure that `pinnedballs plot` writes beside the results: the final
# state, the energy by distance from the boundary (the paper's Figure 3: about 30 % of the energy
# ends in the boundary row) and the histograms of the velocity components.

# %%
res.plot("final")

# %%
res.plot("energy")

# %%
res.plot("histograms")

# %%
res.plot("snapshot", snapshot=-1)

# %% [markdown]
# ## The numbers as a table
#
# `res.to_pandas()` has a row per snapshot and the state the run stopped in as the last row (here
# the frozen state, after the last snapshot), with scalar columns only.

# %%
table = res.to_pandas()
table

# %%
table.iloc[-1][["steps", "collisions", "energy", "frozen"]]

# %% [markdown]
# `res.to_xarray()` labels every array; the velocities stay on disk until a value is asked for, so
# a run of a million balls opens at once.

# %%
ds = res.to_xarray()
ds

# %%
speeds = np.hypot(ds.velocities.sel(component="x"), ds.velocities.sel(component="y"))  # lazy: nothing read yet
float(speeds.isel(snapshot=-1).max())  # reads the final state, and only it

# %% [markdown]
# ## A movie
#
# `res.animate()` writes a GIF of the snapshots and the final state; a notebook shows it.

# %%
res.animate(work / "halfplane.gif", fps=2)

# %% [markdown]
# The scratch folder and the run in it go when the kernel stops; to remove them now:

# %%
scratch.cleanup()
