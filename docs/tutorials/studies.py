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
# # Parameter studies: a family of systems in one call
#
# How does the number of collisions until frozen grow with the size of the system, in each of the paper's
# two orientations of the lattice? A **study** says it as data: a base run spec, the fields to vary (by
# dotted path: `geometry.length`, `rule.r`, ...) and how many replicas of each point. `pb.run_study`
# runs every point's ensemble into one directory, a [signac](https://signac.io) project (a job a
# point), and `pb.load_study` reads back one table, its means and errors, a fit and a figure.
#
# Here: half-planes of three small sizes, rows of balls along the boundary and across it (the paper's
# 1,425-ball count), four replicas of each of the six points. It runs in about 15 seconds on a quiet 2-core machine.

# %%
# %matplotlib inline
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import pinnedballs as pb

scratch = tempfile.TemporaryDirectory(prefix="pinnedballs-studies-")  # removed when the kernel stops
work = Path(scratch.name)

# %% [markdown]
# ## The study, as data
#
# `base` is a run spec (inline here; a path to one works too). `zip` lists values varied together (the
# k-th size takes the k-th length and the k-th depth); `grid` crosses every value with every point so far.
# So: 3 sizes x 2 orientations = 6 points. Every point is validated before anything runs: a typo in a path
# or a bad value is one line naming the point and the field.

# %%
study = {
    "description": "half-planes of three sizes in the paper's two orientations",
    "base": {
        "geometry": {"kind": "half_plane", "length": 10, "depth": 5},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
        "stop": {"frozen": True, "max_steps": 10**8},
    },
    "zip": {"geometry.length": [10, 20, 30], "geometry.depth": [5, 10, 15]},
    "grid": {"geometry.orientation": ["along", "across"]},
    "replicas": 4,
    "seed": 2024,
}
path = work / "study.json"
path.write_text(json.dumps(study, indent=1))

# %% [markdown]
# ## Running it
#
# Each point's ensemble runs through `pb.run_ensemble` (here on two local processes; `dask_address=` or
# `cluster=` sends them to a Dask cluster, `device="cuda"` to a GPU). A point's seed is derived from the
# study's seed and the point's own overrides, not from its place: adding points later changes no row.

# %%
res = pb.run_study(path, work / "sizes", workers=2)
res

# %%
table = res.to_pandas()
table[["point", "geometry.length", "geometry.depth", "geometry.orientation", "n_balls", "replica", "collisions",
       "steps", "frozen"]].head(8)

# %% [markdown]
# ## Means, errors and the scaling law
#
# `summary()` has a row per point: the mean, the standard deviation and the standard error over its
# replicas of each observable. `fit()` is a power law `mean ~ C N^a`, weighted by the errors, with the
# local exponents between consecutive sizes; `where=` fits one part of the study.

# %%
summary = res.summary(["collisions", "steps"])
summary[["geometry.length", "geometry.orientation", "n_balls", "replicas", "collisions_mean", "collisions_se",
         "steps_mean"]]

# %%
for orientation in ("along", "across"):
    fit = res.fit("collisions", against="n_balls", where={"geometry.orientation": orientation})
    print(f"{orientation}: collisions ~ {fit['prefactor']:.3g} N^{fit['exponent']:.2f} ± {fit['exponent_se']:.2f}")

# %% [markdown]
# `plot()` draws the means with their error bars, a series for each orientation (the paths the zip does not
# vary; `by=` names others), each with its fitted law (log-log against the number of balls;
# `against="geometry.length"` or any path the study varies instead). `pinnedballs plot DIR` writes the same
# figure.

# %%
res.plot("collisions", against="n_balls")

# %% [markdown]
# ## The directory is a signac project
#
# A job a point, its state point the point's overrides (and the base spec's digest), its ensemble inside:
# `signac find`, `signac view` and signac's DataFrame work on it, and so do signac-flow and row, to send
# the points to a cluster.

# %%
import signac

project = signac.get_project(work / "sizes", search=False)
(job,) = project.find_jobs({"geometry.length": 20, "geometry.orientation": "across"})
print(job.statepoint())
project.to_dataframe()[["sp.geometry", "doc.n_balls", "doc.replicas"]]

# %% [markdown]
# ## A point added later runs alone
#
# Add a fourth size to the study and run it again with `resume=True`: only the two new points run
# (`res.ran`), and the six done keep their rows, bit for bit. A killed study resumes the same way, to the
# table it would have had.

# %%
study["zip"] = {"geometry.length": [10, 20, 30, 40], "geometry.depth": [5, 10, 15, 20]}
path.write_text(json.dumps(study, indent=1))
more = pb.run_study(path, work / "sizes", workers=2, resume=True)
print("ran now:", more.ran)
before = table.set_index(["point", "replica"])
after = more.to_pandas().set_index(["point", "replica"]).loc[before.index]
print("the six points done keep their rows:", after.equals(before))

# %% [markdown]
# ## From the command line
#
# The same study: `pinnedballs study study.json --out DIR --workers 2` (`--resume` after a kill, or to run
# points added since), `pinnedballs info DIR` for the points done, `pinnedballs plot DIR` for the figure.
# `pinnedballs schema --study` prints the JSON Schema of study files.

# %%
info = subprocess.run([sys.executable, "-m", "pinnedballs", "info", str(work / "sizes")], capture_output=True,
                      text=True, check=True)
print(info.stdout)

# %% [markdown]
# The scratch folder goes when the kernel stops; to remove it now:

# %%
scratch.cleanup()
