"""`reproduce --extended` on tiny sizes: results.json["extended"], the report's tables, the figures;
the exponent fit on synthetic power laws."""

import csv
import json
import math
import re

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.run import reproduction as rp
from pinnedballs.run.cli import main as cli
from pinnedballs.run.reproduction import extended as ext

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these

TINY = dict(sizes=((10, 5), (20, 10)), detail=(20, 10), torus=(8, 8), steps=(3_000, 6_000), long_steps=20_000,
            collisions=30, replicas=4, size_replicas=2)
TINY_X = rp.ExtendedPlan(scaling=((10, 5, 3), (20, 10, 3), (30, 15, 2)), torus_sides=(6, 8), torus_times=(50, 200),
                         torus_replicas=4, sphere_frequency=3, hyperbolic_layers=(1, 2), hyperbolic_replicas=3,
                         fcc=((2, 2, 2), (3, 3, 2)), fcc_replicas=2, orders_replicas=20, orders_max_states=2000)
PNG = b"\x89PNG\r\n\x1a\n"
SCALING_KEYS = {"length", "depth", "balls", "replicas", "collisions_mean", "collisions_sd", "steps_mean"}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("extended") / "out"
    report = rp.reproduce(out, workers=1, extended=TINY_X, **TINY)
    return out, report.read_text(), json.loads((out / "results.json").read_text())


def test_results_hold_every_study(tiny):
    _, _, results = tiny
    x = results["extended"]
    assert set(ext.STUDIES) <= set(x) and set(x["seconds"]) == set(ext.STUDIES) == set(x["figures"])
    assert results["checks"]  # the paper's sections ran first, as before
    assert x["plan"]["scaling"] == [list(s) for s in TINY_X.scaling]


def test_scaling_rows_match_their_replicas(tiny):
    out, text, results = tiny
    rows = results["extended"]["scaling"]
    assert [(r["length"], r["depth"], r["replicas"]) for r in rows] == [tuple(map(float, s[:2])) + (s[2],)
                                                                          for s in TINY_X.scaling]
    for r in rows:
        assert SCALING_KEYS <= set(r)
        assert r["balls"] == pb.HalfPlane.from_size(r["length"], r["depth"]).n_balls
        assert r["frozen"] == r["replicas"]
        with open(out / "ensembles" / f"scaling_{r['length']:g}x{r['depth']:g}" / "replicas.csv") as f:
            table = [row for row in csv.DictReader(f) if row["at"] == "final"]
        collisions = np.array([float(row["collisions"]) for row in table])
        steps = np.array([float(row["steps"]) for row in table])
        assert len(table) == r["replicas"]
        assert r["collisions_mean"] == pytest.approx(collisions.mean(), rel=1e-12)
        assert r["collisions_sd"] == pytest.approx(collisions.std(ddof=1), rel=1e-12)
        assert r["steps_mean"] == pytest.approx(steps.mean(), rel=1e-12)
        assert (steps >= collisions).all()
        # every replica kept the energy, all in the profile's deciles
        assert all(math.isclose(float(row["energy"]), 100.0, rel_tol=1e-10) for row in table)
        profile = results["extended"]["scaling_profiles"][f"{r['length']:g}x{r['depth']:g}"]
        assert len(profile) == ext.DECILES and sum(profile) == pytest.approx(1.0, abs=1e-9)
        # the closing margins of the replicas' counts, carried from replicas.csv (in thresholds)
        near = [int(row["near_collisions"]) for row in table]
        smallest = [float(row["smallest_collision"]) for row in table]
        assert r["thin"] == sum(n > 0 for n in near) and r["near_collisions_mean"] == pytest.approx(np.mean(near))
        assert r["smallest_collision_min"] == min(smallest) > 1  # every replica collided, above the threshold
        remnants = [float(row["largest_remnant"]) for row in table if row["largest_remnant"]]
        assert r["largest_remnant_max"] == (max(remnants) if remnants else None)
    fit = dict(results["extended"]["scaling_fit"]["collisions"])  # a copy: the fixture is shared
    again = rp.fit_exponent([r["balls"] for r in rows], [r["collisions_mean"] for r in rows],
                            [r["collisions_sd"] / math.sqrt(r["replicas"]) for r in rows])
    local = fit.pop("local_exponents")
    for key in ("local_exponents_se", "local_z_2", "local_at_balls"):
        assert len(fit.pop(key)) == len(rows) - 1
    assert fit == again and fit["exponent_se"] > 0

    def slope(a, b):
        return math.log(b["collisions_mean"] / a["collisions_mean"]) / math.log(b["balls"] / a["balls"])

    assert local == pytest.approx([slope(a, b) for a, b in zip(rows, rows[1:])], rel=1e-12)
    assert f"Local exponents of collisions between consecutive sizes (± se from the replicas): {local[0]:.3f} ±" in text


def test_torus_sphere_and_frozen_studies(tiny):
    _, _, results = tiny
    x = results["extended"]
    torus = x["torus_law"]
    assert [(r["side"], r["steps_per_ball"]) for r in torus] == [(s, t) for s in TINY_X.torus_sides
                                                                 for t in TINY_X.torus_times]
    for r in torus:
        assert r["steps"] == r["steps_per_ball"] * r["side"] ** 2 and r["replicas"] == TINY_X.torus_replicas
        assert 0 < r["approaching_fraction_mean"] < 1 and -1 < r["line_of_centres_correlation_mean"] < 1
        assert r["kurtosis_normal"] == pytest.approx(-6 / (r["balls"] + 1))
    assert set(x["torus_law_verdicts"]) == {name for name, _ in ext.LAW}
    assert [r["steps_per_ball"] for r in x["sphere"]] == list(TINY_X.torus_times)
    assert x["sphere_torus_side"] == 8 and x["sphere"][0]["balls"] == 92
    for r, t in zip(x["sphere"], [r for r in torus if r["side"] == 8]):
        assert r["approaching_fraction_minus_torus"] == pytest.approx(
            r["approaching_fraction_mean"] - t["approaching_fraction_mean"], abs=1e-15)
    assert [(r["layers"], r["balls"]) for r in x["hyperbolic"]] == [(1, 8), (2, 29)]
    assert [(r["nx"], r["ny"], r["nz"], r["balls"]) for r in x["fcc_half_space"]] == [(2, 2, 2, 32), (3, 3, 2, 72)]
    for r in x["hyperbolic"] + x["fcc_half_space"]:
        assert r["frozen"] == r["replicas"]
    for profile in (*x["hyperbolic_profiles"].values(), *x["fcc_half_space_profiles"].values()):
        assert sum(profile) == pytest.approx(1.0, abs=1e-9)


def test_orders_study_brackets_the_random_order(tiny):
    _, _, results = tiny
    rows = results["extended"]["orders"]
    assert [r["name"] for r in rows] == list(ext.order_configurations())
    for r in rows:
        assert sum(n for _, n in r["random_histogram"]) == r["replicas"] == TINY_X.orders_replicas
        assert r["fewest_known"] <= r["random_min"] and r["most_known"] >= r["random_max"]
        if r["exhaustive"]:
            assert r["min_collisions"] <= r["random_min"] and r["max_collisions"] >= r["random_max"]
    rhombus = rows[0]
    assert rhombus["exhaustive"] and (rhombus["min_collisions"], rhombus["max_collisions"]) == (2, 6)


def _table_rows(text: str, heading: str) -> list[list[str]]:
    section = text.split(heading, 1)[1].split("\n#", 1)[0]  # to the next heading
    lines = [line for line in section.splitlines() if line.startswith("| ")]
    return [[c.strip() for c in line.strip("|").split(" | ")] for line in lines[1:]]


def test_report_has_a_table_per_study_and_every_figure(tiny):
    out, text, results = tiny
    x = results["extended"]
    for heading, study in (("### Scaling", "scaling"), ("### The torus's long-run law", "torus_law"),
                           ("one moving ball on the sphere", "sphere"), ("the hyperbolic disk", "hyperbolic"),
                           ("### 3-D", "fcc_half_space"), ("### Every order", "orders")):
        rows = _table_rows(text, heading)
        assert len(rows) == len(x[study]), study
    scaling = _table_rows(text, "### Scaling")
    assert [row[2] for row in scaling] == [f"{r['balls']:,}" for r in x["scaling"]]
    assert [row[10:12] for row in scaling] == [[f"{r['thin']} of {r['replicas']}", f"{r['smallest_collision_min']:.3g}"]
                                              for r in x["scaling"]]
    fit = x["scaling_fit"]["collisions"]
    assert f"collisions ~ N^({fit['exponent']:.3f} ± {fit['exponent_se']:.3f})" in text
    assert len(re.findall(r"\*\*(open|settled: differs|no difference from the reference seen)", text)) == 3
    names = rp.expected_extended_figures()
    assert sorted(n for names_ in x["figures"].values() for n in names_) == sorted(names)
    for name in names:
        assert (out / name).read_bytes()[:8] == PNG and f"]({name})" in text


def test_exact_counts_stand_beside_the_float_count(tiny):
    """Up to exact_max_balls every size is counted exactly (certified) and as N_e on the float run's seeds: at
    these sizes no genuine collision closes near the float criterion, so each replica's exact count is its float
    count, and the coarsest criterion counts no more than the finest."""
    out, text, results = tiny
    x = results["extended"]
    for r in x["scaling"]:
        label = f"scaling_{r['length']:g}x{r['depth']:g}"
        counts = {}
        for name in ("", "_exact", "_N_1e-06", "_N_1e-09", "_N_1e-12"):
            with open(out / "ensembles" / f"{label}{name}" / "replicas.csv") as f:
                counts[name] = [int(row["collisions"]) for row in csv.DictReader(f) if row["at"] == "final"]
        assert counts["_exact"] == counts[""] and r["exact_replicas"] == r["replicas"]
        assert r["exact_collisions_mean"] == pytest.approx(np.mean(counts["_exact"]), rel=1e-12)
        assert r["N_1e-06_collisions_mean"] == pytest.approx(np.mean(counts["_N_1e-06"]), rel=1e-12)
        assert r["float_misses_mean"] == 0.0 and r["float_misses_max"] == 0.0
        assert r["exact_smallest_collision_min"] > 1e4  # wide: far above the criterion
        assert r["exact_reruns"] == 0  # no replica needed its full precision behind the first wave
        assert np.mean(counts["_N_1e-06"]) <= np.mean(counts["_N_1e-12"]) <= np.mean(counts[""])
    counted = x["scaling_counts"]
    assert set(counted) == {"exact", "N_1e-06", "N_1e-09", "N_1e-12"}
    assert counted["exact"]["local_exponents"] == pytest.approx(ext.local_exponents(x["scaling"], "collisions")
                                                                ["local_exponents"])
    table = _table_rows(text, "#### Exact counts beside the float count")
    head = table.index(["between", "float", "exact", *(f"N_e, e = 1e-{k:02d}" for k in (6, 9, 12))])
    table, local = table[:head], table[head + 1:]
    assert [row[2] for row in local] == [f"{a:.3f} ± {e:.3f}" for a, e in zip(counted["exact"]["local_exponents"],
                                                                             counted["exact"]["local_exponents_se"])]
    assert [row[0] for row in table] == [f"{r['length']:g}x{r['depth']:g}" for r in x["scaling"]]
    assert [row[3] for row in table] == [f"{r['exact_collisions_mean']:,.0f} ± {r['exact_collisions_se']:,.0f}"
                                         for r in x["scaling"]]
    assert "**Does the rise past 2 survive in exact counts?**" in text and "Not testable" in text


def _rows(balls, exact_slopes, float_slopes, rel=0.002):
    """Scaling rows whose exact and float counts grow with the given local slopes, relative se ``rel``."""
    rows, e, f = [], 1e3, 1e3
    for k, n in enumerate(balls):
        if k:
            e *= (n / balls[k - 1]) ** exact_slopes[k - 1]
            f *= (n / balls[k - 1]) ** float_slopes[k - 1]
        rows.append({"balls": n, "collisions_mean": f, "collisions_se": rel * f, "exact_collisions_mean": e,
                     "exact_collisions_se": rel * e})
    return rows


def test_exact_verdict_says_whether_the_rise_past_2_survives():
    balls = [1000, 4000, 16000]
    fits = lambda rows: {"collisions": ext.local_exponents(rows, "collisions")}  # noqa: E731
    rows = _rows(balls, [1.9, 2.1], [1.9, 2.05])  # both above 2 between the two largest: it survives
    v = ext.exact_verdict(rows, fits(rows))
    assert v["survives"] is True and v["between"] == [4000, 16000]
    assert v["exact"] == pytest.approx(2.1) and v["float"] == pytest.approx(2.05)
    assert v["exact_z"] == pytest.approx(0.1 / (math.sqrt(2) * 0.002 / math.log(4)))
    rows = _rows(balls, [1.9, 2.0], [1.9, 2.05])  # the float count rises past 2, the exact one does not
    assert ext.exact_verdict(rows, fits(rows))["survives"] is False
    rows = _rows(balls, [1.8, 1.9], [1.8, 1.9])  # nothing passes 2: nothing to survive
    assert ext.exact_verdict(rows, fits(rows))["survives"] is None
    rows = _rows(balls[:2], [1.9], [1.9])[:1] + [{"balls": 4000, "collisions_mean": 1e4, "collisions_se": 1.0}]
    assert ext.exact_verdict(rows, fits(rows)) == {"survives": None, "exact_sizes": 1}


def test_scaling_counts_each_size_on_the_float_runs_seeds():
    spec = ext.scaling_spec(100, 50, rp.ExtendedPlan())
    exact = ext.scaling_spec(100, 50, rp.ExtendedPlan(), arithmetic="certified")
    coarse = ext.scaling_spec(100, 50, rp.ExtendedPlan(), resolution=1e-9)
    assert (spec.arithmetic, exact.arithmetic, coarse.resolution) == ("float", "certified", 1e-9)
    assert spec.seed == exact.seed == coarse.seed and spec.scheduler.threads == 1  # replicas side by side
    assert ext.count_name(1e-6) == "N_1e-06" and ext.count_name(1e-12) == "N_1e-12"


def test_scaling_study_is_bit_identical_for_the_same_seed(tmp_path):
    from pinnedballs.run import ensemble as ens

    plan = rp.ExtendedPlan(scaling=((10, 5, 3), (20, 10, 2)))

    def ensemble(name, spec, replicas, **kwargs):
        return ens.run_ensemble(spec, replicas, workers=1, **kwargs)

    a = ext.scaling(plan, tmp_path, ensemble)["rows"]
    b = ext.scaling(plan, tmp_path, ensemble)["rows"]
    keep = lambda rows: [{k: v for k, v in r.items() if not k.endswith("seconds")} for r in rows]  # noqa: E731
    assert keep(a) == keep(b)


# ---------------------------------------------------------------- the exponent fit


def test_fit_recovers_an_exact_power_law():
    n = np.array([15, 60, 135, 1500, 6000])
    f = rp.fit_exponent(n, 3.5 * n**1.75, 0.035 * n**1.75)
    assert f["exponent"] == pytest.approx(1.75, abs=1e-12) and f["prefactor"] == pytest.approx(3.5, rel=1e-10)
    assert f["chi2_per_dof"] == pytest.approx(0.0, abs=1e-20) and f["points"] == 5
    # equal relative errors 1 %: the slope's se is 0.01 / sqrt(sum (log n - mean)^2)
    x = np.log(n)
    assert f["exponent_se"] == pytest.approx(0.01 / math.sqrt(((x - x.mean()) ** 2).sum()), rel=1e-10)


def test_local_exponents_of_an_exact_power_law():
    """Counts 3 N^1.8 with 2 % relative errors: every local slope is 1.8, its se is
    sqrt(2) * 0.02 / log(N2/N1), and it lies 0.2/se standard errors below 2."""
    balls = [50, 200, 800]
    rows = [{"balls": n, "collisions_mean": 3.0 * n**1.8, "collisions_se": 0.06 * n**1.8} for n in balls]
    local = ext.local_exponents(rows, "collisions")
    se = math.sqrt(2) * 0.02 / math.log(4)
    assert local["local_exponents"] == pytest.approx([1.8, 1.8], rel=1e-12)
    assert local["local_exponents_se"] == pytest.approx([se, se], rel=1e-12)
    assert local["local_z_2"] == pytest.approx([0.2 / se, 0.2 / se], rel=1e-10)
    assert local["local_at_balls"] == pytest.approx([100.0, 400.0], rel=1e-12)


def test_fit_error_bars_cover_the_true_exponent():
    """2,000 synthetic scaling studies (exponent 1.6, 8 sizes, known relative errors): the fitted exponent
    is unbiased and within 1.96 standard errors in 95 % of them (binomial sd 0.5 %; we accept 93-97 %)."""
    rng = np.random.default_rng(12)
    n = np.array([15, 135, 366, 1442, 5776, 14641, 36000, 144000], dtype=float)
    rel = np.array([0.05, 0.04, 0.03, 0.03, 0.02, 0.02, 0.05, 0.08])
    z = []
    for _ in range(2000):
        mean = 2.0 * n**1.6 * np.exp(rel * rng.standard_normal(len(n)))
        f = rp.fit_exponent(n, mean, rel * mean)
        z.append((f["exponent"] - 1.6) / f["exponent_se"])
    z = np.array(z)
    assert abs(z.mean()) < 4 / math.sqrt(len(z))
    assert 0.93 <= np.mean(np.abs(z) < 1.96) <= 0.97


@pytest.mark.parametrize("args,message", [
    (([10], [1.0], [0.1]), "balls: need at least two different sizes"),
    (([10, 20], [1.0, -1.0], [0.1, 0.1]), "means: must be finite and > 0"),
    (([10, 20], [1.0, 2.0], [0.1, -0.1]), "standard_errors: must be finite and >= 0"),
    (([10, 20], [1.0, 2.0], [0.1]), "must be 1-D of one length"),
])
def test_fit_refuses_bad_input(args, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        rp.fit_exponent(*args)


# ---------------------------------------------------------------- plans and the command line


def test_plans_fit_the_issue():
    full = rp.EXTENDED_FULL.scaling
    assert len(full) >= 8 and full[0][:2] == (10, 5) and full[-1][:2] == (2000, 1000)
    assert all(s[2] >= 2 for s in full)
    # issues 17 and 27: at least 8 replicas at the large sizes, counted exactly up to 1000x500; the largest
    # (2000x1000, float only) has fewer so that the whole --extended fits its time budget (issue 23)
    assert all(s[2] >= 8 for s in full if 500 <= s[0] <= 1000)
    assert rp.EXTENDED_FULL.exact_max_balls >= pb.HalfPlane.from_size(1000, 500).n_balls
    assert rp.EXTENDED_FULL.exact_max_balls < pb.HalfPlane.from_size(2000, 1000).n_balls
    assert rp.EXTENDED_FULL.resolutions == (1e-6, 1e-9, 1e-12)
    for plan in (rp.EXTENDED_FULL, rp.EXTENDED_QUICK):
        ext.check_extended_plan(plan)


def test_bad_extended_plan_names_its_field(tmp_path):
    from pinnedballs.util.errors import InputError

    with pytest.raises(InputError, match=r"scaling: give at least two \(length, depth, replicas >= 2\)"):
        rp.reproduce(tmp_path / "x", extended=rp.ExtendedPlan(scaling=((10, 5, 1), (20, 10, 3))), **TINY)
    with pytest.raises(InputError, match="torus_replicas: must be an integer >= 1"):
        rp.reproduce(tmp_path / "x", extended=rp.ExtendedPlan(torus_replicas=0), **TINY)
    for bad in (0.0, 1.0, -1e-9, float("nan"), "1e-6", True):
        with pytest.raises(InputError, match=r"resolutions: each must be a criterion e in \(0, 1\), got "):
            rp.reproduce(tmp_path / "x", extended=rp.ExtendedPlan(resolutions=(1e-6, bad)), **TINY)
    for bad in (-1, 1.5, None, True):
        with pytest.raises(InputError, match="exact_max_balls: must be a whole number of balls >= 0, got "):
            rp.reproduce(tmp_path / "x", extended=rp.ExtendedPlan(exact_max_balls=bad), **TINY)
    for bad in (32, 800, 256.0, True, "256"):
        with pytest.raises(InputError, match=r"exact_late_precision: must be a whole number of bits in \[64, 768\] "
                                             r"or None, got "):
            rp.reproduce(tmp_path / "x", extended=rp.ExtendedPlan(exact_late_precision=bad), **TINY)
    assert not (tmp_path / "x").exists()


def test_a_certified_replica_failing_once_narrowed_runs_again_without_narrowing(monkeypatch):
    """The exact count's task: narrowed too early (every check passes, in the middle of the first wave),
    the 20x10 half-plane at 64 bits cannot decide a pick; the replica runs again at 256 bits throughout,
    with the counts of exact arithmetic, and says so. A failure before any narrowing is the replica's."""
    from pinnedballs.engine.field.fixed import FixedChain, UncertifiedDecision
    from pinnedballs.run import ensemble as ens
    from pinnedballs.run.reproduction.extended.scaling_study import RERUN, certified_replica, scaling_spec

    plan = rp.ExtendedPlan(exact_late_precision=64)
    spec = scaling_spec(20, 10, plan, arithmetic="certified", precision=256, late_precision=64)
    exact = ens_final(ens.run_replica(scaling_spec(20, 10, plan, arithmetic="exact"), 1))
    monkeypatch.setattr(FixedChain, "settled", lambda self: True)
    with pytest.raises(UncertifiedDecision):
        ens.run_replica(spec, 1)
    rows = certified_replica(spec, 1)
    assert rows[-1][RERUN] == 1 and (rows[-1]["steps"], rows[-1]["collisions"]) == exact
    with pytest.raises(UncertifiedDecision) as info:  # 64 bits from the start: no narrowing to blame
        certified_replica(spec.model_copy(update={"precision": 64}), 1)
    assert not info.value.narrowed
    monkeypatch.undo()
    rows = certified_replica(spec.model_copy(update={"late_precision": 128}), 1)
    assert rows[-1][RERUN] == 0 and (rows[-1]["steps"], rows[-1]["collisions"]) == exact


def ens_final(rows: list[dict]) -> tuple[int, int]:
    """The steps and collisions of a replica's final row."""
    return rows[-1]["steps"], rows[-1]["collisions"]


def test_cli_extended_refuses_a_non_empty_directory(tmp_path, capsys):
    (tmp_path / "keep.txt").write_text("mine")
    assert cli.main(["reproduce", "--out", str(tmp_path), "--quick", "--extended"]) == 2
    assert "not empty" in capsys.readouterr().err


def test_cli_passes_extended_and_quick_to_reproduce(tmp_path, fake_reproduce):
    seen = fake_reproduce
    assert cli.main(["reproduce", "--out", str(tmp_path / "x"), "--quick", "--extended", "--quiet"]) == 0
    assert (seen["quick"], seen["extended"]) == (True, True)
    assert cli.main(["reproduce", "--out", str(tmp_path / "y"), "--quiet"]) == 0
    assert (seen["quick"], seen["extended"]) == (False, False)
