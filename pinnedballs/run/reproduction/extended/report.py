"""The extended studies' section of ``report.md``: a table per study, what is settled and what stays open."""

from __future__ import annotations

import math

from .torus_law_study import LAW


def _f(x, fmt: str = ".3g") -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def _pm(mean, se, fmt: str = "+.4f") -> str:
    return f"{_f(mean, fmt)} ± {_f(se, '.4f')}"


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head), *("| " + " | ".join(r) + " |" for r in rows), ""]


def extended_section(x: dict) -> list[str]:
    """Markdown lines for ``results["extended"]`` (`extended.run_extended`)."""
    lines = ["## Beyond the paper (`--extended`)", "",
             "Wall time of each study (s; included in the wall time above): "
             + ", ".join(f"{k} {v:.1f}" for k, v in x["seconds"].items()) + ".", ""]
    lines += _scaling(x) + _torus(x) + _sphere(x) + _hyperbolic(x) + _fcc(x) + _orders(x)
    lines += ["### Figures", ""] + [f"* ![{n}]({n})" for names in x["figures"].values() for n in names]
    return lines


def _scaling(x: dict) -> list[str]:
    rows = [[f"{r['length']:g}x{r['depth']:g}", f"{r['rows']}x{r['cols']}", f"{r['balls']:,}", str(r["replicas"]),
             str(r["frozen"]), f"{r['collisions_mean']:,.0f}", f"{_f(r['collisions_sd'], ',.0f')}",
             f"{r['steps_mean']:,.0f}", _f(r["boundary_share_mean"], ".3f"), _f(r["far_half_share_mean"], ".2e"),
             *_margin_cells(r), f"{r['seconds']:.1f}"] for r in x["scaling"]]
    fits = x["scaling_fit"]
    fit_text = "; ".join(f"{what} ~ N^({f['exponent']:.3f} ± {f['exponent_se']:.3f}) "
                         f"(chi²/dof {f['chi2_per_dof']:.2f}, {f['points']} sizes)" for what, f in fits.items())
    return ["### Scaling: until frozen against the number of balls", "",
            "Half-plane `HalfPlane.from_size(L, D)`, the boundary-centre ball moving inward with energy 100, "
            "`UniformRandomPair` (the paper's chain), run until frozen.", "", *_stream(x),
            *_table(["L x D", "rows x cols", "balls N", "replicas", "frozen", "collisions (mean)", "collisions (sd)",
                     "steps (mean)", "boundary share", "far-half share", "thin margins", "smallest collision",
                     "largest remnant", "near collisions (mean)", "wall s"], rows),
            "Closing margins (`sim.closing_margin()`, in thresholds of the float criterion, final states): replicas "
            "with a collision closing within a factor 10,000 of the threshold (thin: their counts depend on the "
            "criterion), the smallest collision and the largest remnant over the replicas, and the mean number of "
            "collisions within that factor.", "",
            f"Fitted: {fit_text}. Method: weighted least squares of log(mean) on log(N), each size weighted by "
            "1/(relative standard error of its mean)², se = sd/sqrt(replicas); the exponent's standard error is "
            "the fit's, scaled up by sqrt(chi²/dof) when the sizes scatter more than their errors.", "",
            *[f"Local exponents of {what} between consecutive sizes (± se from the replicas): "
              + ", ".join(f"{a:.3f} ± {e:.3f}" for a, e in zip(f["local_exponents"], f["local_exponents_se"]))
              + (" (chi²/dof > 3: the sizes do not lie on one power law; the fitted exponent is an average)."
                 if f["chi2_per_dof"] > 3 else ".") for what, f in fits.items()], "", *_exact_counts(x)]


def _stream(x: dict) -> list[str]:
    """Which stream the scaling study drew its picks from, and where each count ran."""
    stream = x.get("scaling_stream", "xoshiro")  # results written before the plan had a stream: xoshiro
    ran_on = x.get("scaling_ran_on", {})
    on = lambda where: f"the {where}" if where.startswith("GPU") else f"the CPU ({where})"  # noqa: E731 (`EnsembleResult.where`)
    where = "; ".join(f"{label} on {', '.join(map(on, ran_on[key]))}" for key, label in (
        ("float", "float counts"), ("exact", "exact counts (certified arithmetic)"), ("N_e", "N_e")) if ran_on.get(key))
    if stream == "counter":
        head = ("Picks from the **counter stream** (`UniformRandomPair(stream=\"counter\")`, Philox: the pick of "
                "step s a function of the seed and s), the stream a GPU runs with the CPU's bits: these are "
                "counter-stream replicas, the same law as the default xoshiro stream's but other picks, so each "
                "replica's counts differ from a CPU run's on the xoshiro stream with the same seed.")
    else:
        head = "Picks from the **xoshiro stream** (the default: every published seed's bits)."
    return [head + (f" Ran: {where}." if where else ""), ""]


def _exact_counts(x: dict) -> list[str]:
    """The exact count, the float count and N_e side by side, their local exponents, and the verdict."""
    names = [n for n in x.get("scaling_counts", {}) if n != "exact"]
    # the sizes counted exactly or as N_e (N_e may reach beyond the exact count: `ExtendedPlan.resolution_max_balls`)
    rows = [r for r in x["scaling"] if any(f"{n}_collisions_mean" in r for n in ("exact", *names))]
    if not rows:
        return []

    def count(r: dict, n: str) -> str:
        if f"{n}_collisions_mean" not in r:
            return "—"
        return (f"{r[f'{n}_collisions_mean']:,.0f} ± {_f(r[f'{n}_collisions_se'], ',.0f')}"
                + ("" if r[f"{n}_replicas"] == r["replicas"] else f" ({r[f'{n}_replicas']} replicas)"))

    def exact(r: dict) -> tuple[str, str, str]:
        """The float misses, the smallest genuine collision and the wall time of a size's exact count."""
        if "exact_collisions_mean" not in r:
            return "—", "—", "—"
        return (f"{100 * r['float_misses_mean']:.3f} % (max {100 * r['float_misses_max']:.3f} %)",
                _f(r["exact_smallest_collision_min"], ".2g") + " T", f"{r['exact_seconds']:.1f}")

    table = [[f"{r['length']:g}x{r['depth']:g}", f"{r['balls']:,}", str(r["replicas"]), count(r, "exact"),
              f"{r['collisions_mean']:,.0f} ± {_f(r['collisions_se'], ',.0f')}", *exact(r)[:2],
              *[count(r, n) for n in names], exact(r)[2]] for r in rows]
    # each count's local exponents, by the pair of sizes (in balls) they lie between
    local = [("float", _by_pair(x["scaling"], x["scaling_fit"]["collisions"])),
             *((n, _by_pair([r for r in x["scaling"] if f"{n}_collisions_mean" in r], f))
               for n, f in x["scaling_counts"].items())]
    pairs = [[f"{a['length']:g}x{a['depth']:g} and {b['length']:g}x{b['depth']:g}",
              *[by_pair.get((a["balls"], b["balls"]), "—") for _, by_pair in local]]
             for a, b in zip(rows, rows[1:])]
    labels = {"float": "float", "exact": "exact", **{n: f"N_e, e = {n[2:]}" for n in names}}
    return ["#### Exact counts beside the float count", "",
            "The same seeds counted three ways: exactly (`arithmetic=\"certified\"`: every decision proven, so the "
            "count is the exact one), by the float chain with the paper's criterion (4 ulp, the table above), and by "
            "the float chain with a coarser criterion e (a pick collides when its closing speed exceeds e V: the "
            "model N_e). Mean ± standard error over the replicas; \"float misses\": exact minus float count over the "
            "exact count, per replica on the same seed; \"smallest genuine\": the smallest closing speed the exact "
            "runs counted as a collision, in thresholds T of the float criterion; \"exact s\": the exact "
            "ensemble's wall time.", "",
            *_table(["L x D", "balls N", "replicas", "exact", "float", "float misses (mean)", "smallest genuine",
                     *[labels[n] for n in names], "exact s"], table),
            "Local exponents of each count between consecutive sizes (± se from the replicas):", "",
            *_table(["between", *[labels[n] for n, _ in local]], pairs), *_verdict(x["scaling_verdict"]), ""]


def _by_pair(rows: list[dict], f: dict) -> dict[tuple[int, int], str]:
    """``{(balls, balls of the next size): "slope ± se"}``: the local exponents ``f`` of consecutive ``rows``."""
    return {(a["balls"], b["balls"]): f"{e:.3f} ± {se:.3f}"
            for a, b, e, se in zip(rows, rows[1:], f["local_exponents"], f["local_exponents_se"])}


def _verdict(v: dict) -> list[str]:
    """Whether the rise past 2 survives in exact counts, in words."""
    if v.get("exact_sizes", 0) < 2:
        return []
    n0, n1 = v["between"]
    head = (f"**Does the rise past 2 survive in exact counts?** Between {n0:,} and {n1:,} balls (the largest sizes "
            f"counted exactly) the exact local exponent is {v['exact']:.3f} ± {v['exact_se']:.3f} "
            f"(z = {_f(v['exact_z'], '+.1f')} from 2), the float one {v['float']:.3f} ± {v['float_se']:.3f} "
            f"(z = {_f(v['float_z'], '+.1f')}). ")
    if v["survives"] is True:
        tail = "Yes: the float counts' exponent lies above 2 there, and the exact counts' too."
    elif v["survives"] is False:
        tail = "No: the float counts' exponent lies above 2 there, but the exact counts' does not."
    else:
        l0, l1 = v["float_last_between"]
        tail = (f"Not testable at these sizes: the float exponent does not lie 3 se above 2 there; it does between "
                f"{l0:,} and {l1:,} balls ({v['float_last']:.3f} ± {v['float_last_se']:.3f}), beyond the exact "
                f"counts' reach." if (v["float_last"] - 2) > 3 * v["float_last_se"] else
                "Not testable: the float counts' exponent does not pass 2 at any size of this plan.")
    return [head + tail, ""]


def _margin_cells(r: dict) -> list[str]:
    """The closing-margin cells of a scaling row (— in a row written before rows had them)."""
    if "thin" not in r:
        return ["—"] * 4
    return [f"{r['thin']} of {r['replicas']}", _f(r["smallest_collision_min"]), _f(r["largest_remnant_max"]),
            _f(r["near_collisions_mean"], ",.1f")]


def _torus(x: dict) -> list[str]:
    rows = [[f"{r['side']}x{r['side']}", f"{r['balls']:,}", f"{r['steps_per_ball']:,}", str(r["replicas"]),
             _pm(r["kurtosis_mean"], r["kurtosis_se"], "+.3f"), _f(r["kurtosis_normal"], "+.4f"),
             _pm(r["approaching_fraction_mean"], r["approaching_fraction_se"], ".4f"),
             _pm(r["line_of_centres_correlation_mean"], r["line_of_centres_correlation_se"])] for r in x["torus_law"]]
    return ["### The torus's long-run law", "",
            "`FlatTorus(side, side)`, ball 0 moving along x with energy 100, `UniformRandomPair`; mean ± standard "
            "error over replicas. Kurtosis: the mean of the x- and y-components' sample excess kurtosis; a normal "
            "sample of N values gives -6/(N+1) on average.", "",
            *_table(["torus", "balls N", "steps per ball", "replicas", "excess kurtosis", "normal sample",
                     "approaching fraction", "line-of-centres correlation"], rows),
            *_verdicts(x["torus_law_verdicts"]), ""]


def _verdicts(v: dict) -> list[str]:
    """What is settled and what stays open, from z-scores: |z| > 3 a difference, |z| < 2 none seen."""
    out = ["**What is settled and what stays open** (largest torus, longest time; z = difference / its standard "
           "error; |z| > 3 counts as a difference, below that none is claimed):", ""]
    for name, label in LAW:
        d = v[name]
        text = (f"* {label}: {_pm(d['mean'], d['se'])} at {d['side']}x{d['side']}, {d['steps_per_ball']:,} steps "
                f"per ball; reference {_f(d['reference'], '+.4f')}, z = {_f(d['z'], '+.1f')}")
        moving = "time_z" in d and not abs(d["time_z"]) <= 3
        sized = "size_z" in d and not abs(d["size_z"]) <= 3
        if "time_change" in d:
            text += (f"; change since the time before {_pm(d['time_change'], d['time_change_se'])} "
                     f"(z = {_f(d['time_z'], '+.1f')})")
        if "size_change" in d:
            text += (f"; change from the smallest torus {_pm(d['size_change'], d['size_change_se'])} "
                     f"(z = {_f(d['size_z'], '+.1f')})")
        if moving:
            verdict = "**open**: still changing with time, so its long-run value is not reached"
        elif abs(d["z"]) > 3:
            verdict = ("**settled: differs from the reference** and no longer changes with time"
                       + (", but it changes with size" if sized else ", nor (within errors) with size"))
        else:
            verdict = "**no difference from the reference seen** at this precision"
        out.append(f"{text}. {verdict}.")
    return out


def _sphere(x: dict) -> list[str]:
    side = x["sphere_torus_side"]
    rows = [[f"{r['steps_per_ball']:,}", str(r["replicas"]),
             *[f"{_pm(r[f'{n}_mean'], r[f'{n}_se'], '+.4f')} (z {_f(r[f'{n}_z'], '+.1f')})" for n, _ in LAW]]
            for r in x["sphere"]]
    f = x["plan"]["sphere_frequency"]
    return ["### Curved spaces: one moving ball on the sphere", "",
            f"`Sphere.geodesic({f})` ({10 * f * f + 2:,} balls), ball 0 moving with energy 100, components in each "
            f"ball's own frame; z compares with the {side}x{side} torus at the same steps per ball.", "",
            *_table(["steps per ball", "replicas", *[label for _, label in LAW]], rows)]


def _hyperbolic(x: dict) -> list[str]:
    rows = [[str(r["layers"]), f"{r['balls']:,}", str(r["replicas"]), str(r["frozen"]), f"{r['collisions_mean']:,.0f}",
             f"{r['steps_mean']:,.0f}", _f(r["boundary_share_mean"], ".3f"), _f(r["far_half_share_mean"], ".2e"),
             _f(r["centre_share_mean"], ".2e")] for r in x["hyperbolic"]]
    return ["### Curved spaces: the hyperbolic disk", "",
            "`HyperbolicPlane(q=7, layers=L)`, the rim ball nearest the middle of the rim moving inward "
            "(`\"direction\": \"inward\"`), energy 100, `RejectionFree`, until frozen. Shares are of the frozen "
            "energy; the profile by rings is the figure.", "",
            *_table(["rings L", "balls", "replicas", "frozen", "collisions (mean)", "steps (mean)", "rim share",
                     "inner-half share", "centre-ball share"], rows)]


def _fcc(x: dict) -> list[str]:
    rows = [[f"{r['nx']}x{r['ny']}x{r['nz']}", f"{r['balls']:,}", str(r["replicas"]), str(r["frozen"]),
             f"{r['collisions_mean']:,.0f}", f"{r['steps_mean']:,.0f}", _f(r["boundary_share_mean"], ".3f"),
             _f(r["boundary_outward_fraction_mean"], ".3f"), _f(r["far_half_share_mean"], ".2e")]
            for r in x["fcc_half_space"]]
    return ["### 3-D: the half-space experiment on FCC", "",
            "`FCC(nx, ny, nz, periodic=False)`: an open block, boundary the layer z = 0 (a block periodic in x and y "
            "is infinite in those directions and never freezes). The boundary ball nearest the middle moves "
            "inward (+z) with energy 100, `RejectionFree`, until frozen.", "",
            *_table(["cells", "balls", "replicas", "frozen", "collisions (mean)", "steps (mean)",
                     "boundary-layer share", "outward fraction there", "far-half share"], rows)]


def _orders(x: dict) -> list[str]:
    bound = lambda r, sign: "" if r["exhaustive"] else sign  # noqa: E731
    rows = [[r["name"], str(r["balls"]), str(r["contacts"]), bound(r, "≤ ") + str(r["fewest_known"]),
             bound(r, "≥ ") + str(r["most_known"]), "yes" if r["exhaustive"] else "no",
             f"{r['states']:,}", str(r["replicas"]), f"{r['random_mean']:.2f} ± {r['random_sd']:.2f}",
             f"{r['random_min']}–{r['random_max']}", f"{r['random_at_min']:.3f}", f"{r['random_at_max']:.3f}"]
            for r in x["orders"]]
    return ["### Every order of collisions against the random order", "",
            "`explore_orders` (fewest and most collisions until frozen over every order; when not exhaustive, "
            "bounds from the orders it and the random runs reached) against `UniformRandomPair` replicas (mean ± sd, "
            "range, share of replicas reaching the "
            "fewest and the most).", "",
            *_table(["system", "balls", "contacts", "fewest", "most", "exhaustive", "states", "random runs",
                     "random: mean ± sd", "random: range", "at fewest", "at most"], rows)]
