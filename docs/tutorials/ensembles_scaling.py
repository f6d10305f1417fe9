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
# # Ensembles and the scaling law, small
#
# How many collisions does the paper's half-plane take to freeze, as the rectangle grows? One run
# answers for one random order; an ensemble of independent replicas gives a mean and its error. Here:
# five sizes from 15 to 1,450 balls, 8 replicas each on local processes, a fit of collisions against
# balls on log scales, and the same ensemble on a Dask cluster giving the same table, bit for bit.
# (The page *Beyond the paper*, `docs/extended.md`, runs the same study up to 577,000 balls.)
#
# It runs top to bottom in about a minute on a quiet 2-core machine (more where the cores are shared).

# %%
# %matplotlib inline
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import pinnedballs as pb

scratch = tempfile.TemporaryDirectory(prefix="pinnedballs-ensembles-")  # removed when the kernel stops
work = Path(scratch.name)


def half_plane(length: int, depth: int) -> pb.RunSpec:
    """The paper's set-up on an L x D rectangle: one boundary ball sent in with energy 100, run until frozen."""
    return pb.RunSpec.model_validate({
        "geometry": {"kind": "half_plane", "length": length, "depth": depth},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
        "stop": {"frozen": True, "max_steps": 10**9},
        "seed": 2024,
    })


half_plane(100, 50)

# %% [markdown]
# ## One ensemble
#
# `pb.run_ensemble(spec, replicas, workers=2)` runs the replicas on two local processes. Replica `k`
# is seeded with child `k` of `SeedSequence(spec.seed)`: its result depends on the spec and `k`
# only, not on how many replicas or workers there are. The result shows a short table; its
# `to_pandas()` has a row per replica (the final state of each).

# %%
ensemble = pb.run_ensemble(half_plane(30, 15), replicas=8, workers=2)
ensemble

# %%
ensemble.to_pandas()[["steps", "collisions", "frozen", "energy", "boundary_share", "far_half_share"]]

# %% [markdown]
# ## Five sizes
#
# The same for five rectangles; each size's mean number of collisions until frozen, with the
# standard error of the mean over its replicas.

# %%
sizes = [(10, 5), (20, 10), (30, 15), (60, 30), (100, 50)]
ensembles = {size: pb.run_ensemble(half_plane(*size), replicas=8, workers=2) for size in sizes}

rows = []
for (length, depth), result in ensembles.items():
    final = result.to_pandas()
    rows.append({"size": f"{length}x{depth}", "balls": pb.HalfPlane.from_size(length, depth).n_balls,
                 "replicas": len(final), "frozen": int(final["frozen"].sum()),
                 "collisions": final["collisions"].mean(),
                 "collisions_se": final["collisions"].std(ddof=1) / np.sqrt(len(final)),
                 "steps": final["steps"].mean()})
scaling = pd.DataFrame(rows).set_index("size")
scaling

# %% [markdown]
# ## The fit
#
# A power law `collisions ~ C N^a` is a line on log scales: a least-squares fit of log(mean) on
# log(N), each size weighted by the inverse square of its relative error. (Over 15 to 1,450 balls
# the slope is about 1.65; the large study finds it still rising at half a million balls, so read it
# as a local exponent, not a law.)

# %%
x, y = np.log(scaling["balls"]), np.log(scaling["collisions"])
relative_error = scaling["collisions_se"] / scaling["collisions"]
slope, intercept = np.polyfit(x, y, 1, w=1 / relative_error)
print(f"collisions ~ {np.exp(intercept):.3g} N^{slope:.3f}")

fig, ax = plt.subplots(figsize=(6, 4))
ax.errorbar(scaling["balls"], scaling["collisions"], yerr=1.96 * scaling["collisions_se"], fmt="o",
            label="mean over 8 replicas (95 % interval)")
n = np.geomspace(scaling["balls"].min(), scaling["balls"].max(), 50)
ax.plot(n, np.exp(intercept) * n**slope, label=f"fit: N^{slope:.2f}")
ax.set(xscale="log", yscale="log", xlabel="balls N", ylabel="collisions until frozen")
ax.legend()

# %% [markdown]
# ## The same ensemble on a Dask cluster
#
# `cluster=` sends the replicas to a Dask cluster: here a `LocalCluster` of two worker processes
# on this machine, in practice one spread over many (`pinnedballs ensemble --dask ADDRESS` from the
# command line). The table is the same, bit for bit, wherever the replicas ran.
#
# In a script (not a notebook) start the cluster under `if __name__ == "__main__":`: Dask's worker
# processes import the script again, and without the guard each starts a cluster of its own ("Nanny
# failed to start"). *Getting started* (`docs/getting-started.md`, "Many replicas: ensembles and Dask")
# has that script, a cluster started by hand (`dask scheduler`, `dask worker ADDRESS`, `--dask ADDRESS`)
# and a recipe for SLURM. The client is opened after the cluster and closed before it (one `with`,
# which closes in reverse order): a cluster closed under a client still talking to it has Dask print
# its connections' errors.

# %%
from dask.distributed import Client, LocalCluster

with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
        Client(cluster) as client:
    on_dask = pb.run_ensemble(half_plane(60, 30), replicas=8, cluster=client)
on_dask

# %%
on_dask.to_pandas().equals(ensembles[(60, 30)].to_pandas())

# %% [markdown]
# ## Written to a directory and read back
#
# `pinnedballs ensemble SPEC --replicas N --out DIR` writes `replicas.csv`, `summary.json` and the
# correlation histograms, as a result's `save(DIR)` does; `pb.load_ensemble(DIR)` reads them back into
# the same result (`pinnedballs info DIR` describes it).

# %%
on_dask.save(work / "ensemble_60x30")
back = pb.load_ensemble(work / "ensemble_60x30")
print(back.to_pandas().equals(on_dask.to_pandas()))
back

# %% [markdown]
# The scratch folder goes when the kernel stops; to remove it now:

# %%
scratch.cleanup()
