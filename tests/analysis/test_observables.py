"""Observables against hand-computed values on tiny states, and statistical facts on larger ones."""

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.analysis import observables as obs

SQRT3 = np.sqrt(3.0)


def chain(n):
    """``n`` balls on the x-axis, contacts ``(k, k+1)``: pairs, t_i = (1, 0), t_j = (-1, 0)."""
    pairs = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    t_i = np.tile([1.0, 0.0], (n - 1, 1))
    return pairs, t_i, -t_i


# ---------------------------------------------------------------- energy and momentum

def test_energy_and_momentum_of_three_balls():
    v = np.array([[3.0, 4.0], [0.0, 0.0], [1.0, 0.0]])
    m = np.array([1.0, 2.0, 4.0])
    np.testing.assert_array_equal(obs.energy_per_ball(v, m), [12.5, 0.0, 2.0])
    np.testing.assert_array_equal(obs.energy_per_ball(v), [12.5, 0.0, 0.5])
    assert obs.total_energy(v, m) == 14.5
    np.testing.assert_array_equal(obs.total_momentum(v, m), [7.0, 4.0])


def test_energy_and_momentum_agree_with_simulation():
    geom = pb.FlatTorus(rows=4, cols=5)
    rng = np.random.default_rng(3)
    v, m = rng.normal(size=(geom.n_balls, 2)), rng.uniform(0.5, 2.0, geom.n_balls)
    sim = pb.Simulation(geom, v, masses=m)
    assert obs.total_energy(v, m) == pytest.approx(sim.energy(), rel=1e-14)
    np.testing.assert_allclose(obs.total_momentum(v, m), sim.momentum(), rtol=1e-14)


# ---------------------------------------------------------------- energy against distance

def test_energy_profile_per_row_exact_fractions():
    d = np.array([0.0, 1e-12, SQRT3, 2 * SQRT3])          # first two balls: one row up to rounding
    v = np.sqrt(2 * np.array([[1.0], [2.0], [3.0], [4.0]])) * [1.0, 0.0]   # energies 1, 2, 3, 4
    centres, fraction = obs.energy_profile(d, v)
    np.testing.assert_allclose(centres, [0.0, SQRT3, 2 * SQRT3], atol=1e-12)
    np.testing.assert_allclose(fraction, [0.3, 0.3, 0.4])
    assert obs.boundary_share(d, v) == pytest.approx(0.3)


def test_energy_profile_fixed_bins_include_empty_ones():
    d = np.array([0.0, 0.5, 4.5])
    v = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 2.0]])    # energies 0.5, 0.5, 2
    centres, fraction = obs.energy_profile(d, v, bin_width=2.0)
    np.testing.assert_allclose(centres, [1.0, 3.0, 5.0])
    np.testing.assert_allclose(fraction, [1 / 3, 0.0, 2 / 3])


def test_energy_profile_of_half_plane_rows():
    half = pb.HalfPlane(rows=4, cols=3)
    v = np.zeros((half.n_balls, 2))
    v[2 * 3 + 1] = [0.0, 5.0]                              # all the energy in row 2
    centres, fraction = obs.energy_profile(half.boundary_distance(), v)
    np.testing.assert_allclose(centres, SQRT3 * np.arange(4), atol=1e-12)
    np.testing.assert_array_equal(fraction, [0.0, 0.0, 1.0, 0.0])
    assert obs.boundary_share(half.boundary_distance(), v) == 0.0


def test_masses_weight_the_profile():
    d = np.array([0.0, SQRT3])
    v = np.ones((2, 2))
    assert obs.boundary_share(d, v, masses=[3.0, 1.0]) == pytest.approx(0.75)


def test_outward_energy_fraction():
    row = np.array([[0.0, -1.0], [1.0, 1.0], [2.0, 0.0]])   # energies 0.5, 1, 2; only the first moves out
    assert obs.outward_energy_fraction(row) == pytest.approx(0.5 / 3.5)
    assert obs.outward_energy_fraction(row, outward=(1.0, 0.0)) == pytest.approx(3.0 / 3.5)
    assert obs.outward_energy_fraction(row, outward=(0.0, -7.0), masses=[5.0, 1.0, 1.0]) == pytest.approx(2.5 / 5.5)


def test_zero_energy_gives_nan_fractions():
    v = np.zeros((3, 2))
    d = np.array([0.0, 1.0, 2.0])
    assert np.isnan(obs.energy_profile(d, v)[1]).all()
    assert np.isnan(obs.boundary_share(d, v))
    assert np.isnan(obs.outward_energy_fraction(v))


# ---------------------------------------------------------------- histograms and normality

def test_component_histogram_by_hand():
    h = obs.component_histogram([-2.0, -1.0, 0.0, 1.0, 2.0], bin_width=0.5)
    np.testing.assert_allclose(h.edges, [-1.0, -0.5, 0.0, 0.5, 1.0])
    np.testing.assert_array_equal(h.counts, [1, 1, 1, 2])  # the last bin is closed: holds 0.5 and 1
    assert (h.scale, h.mean) == (2.0, 0.0)
    assert h.std == pytest.approx(np.sqrt(0.5))


def test_component_histogram_paper_bins_count_every_value():
    x = np.random.default_rng(0).normal(size=1000)
    h = obs.component_histogram(x)
    assert len(h.counts) == 80 and h.edges[0] == -1.0 and h.edges[-1] == 1.0
    np.testing.assert_allclose(np.diff(h.edges), 0.025)
    assert h.counts.sum() == 1000                            # the extremes land on +-1, inside
    assert h.scale == np.abs(x).max()
    assert h.mean == pytest.approx(x.mean() / h.scale) and h.std == pytest.approx(x.std() / h.scale)


def test_component_histogram_without_normalising_drops_outliers():
    h = obs.component_histogram([-3.0, 0.1, 0.2, 5.0], bin_width=0.5, normalise=False)
    assert h.counts.sum() == 2 and h.scale == 1.0


def test_component_histogram_of_zeros_keeps_them():
    h = obs.component_histogram(np.zeros(10))
    assert h.counts.sum() == 10 and h.counts[40] == 10 and h.std == 0.0


def test_normality_tests_accept_normal_sample():
    x = np.random.default_rng(1).normal(3.0, 2.0, size=2000)
    r = obs.normality_tests(x)
    assert r["ks_pvalue"] > 0.01
    assert r["ad_statistic"] < r["ad_critical_5pct"]
    assert r["n"] == 2000 and r["mean"] == pytest.approx(3.0, abs=0.15) and r["std"] == pytest.approx(2.0, rel=0.05)


def test_normality_tests_reject_uniform_sample_of_5000():
    r = obs.normality_tests(np.random.default_rng(2).uniform(-1, 1, size=5000))
    assert r["ks_pvalue"] < 1e-6
    assert r["ad_statistic"] > 10 * r["ad_critical_5pct"]


def test_anderson_darling_critical_value_matches_stephens_table():
    # scipy.stats.anderson's tabulated 5 % value for n = 100 (rounded to 3 decimals) is 0.746
    assert round(obs.ad_critical_5pct(100), 3) == 0.746


def test_normality_tests_need_spread():
    with pytest.raises(ValueError, match="values"):
        obs.normality_tests(np.ones(20))
    with pytest.raises(ValueError, match="values"):
        obs.normality_tests(np.arange(3.0))


# ---------------------------------------------------------------- contacts

def test_line_of_centres_correlation_by_hand():
    pairs, t_i, t_j = chain(5)
    vx = np.array([1.0, 3.0, 0.0, 2.0, 2.0])
    v = np.column_stack([vx, [9.0, -4.0, 7.0, 0.5, 1.0]])  # y is perpendicular to every line of centres
    u, u_prime = obs.line_of_centres_components(v, pairs, t_i, t_j)
    np.testing.assert_array_equal(u, [1.0, 3.0, 0.0, 2.0])
    np.testing.assert_array_equal(u_prime, [3.0, 0.0, 2.0, 2.0])
    # deviations (-.5, 1.5, -1.5, .5) and (1.25, -1.75, .25, .25): sum of products -3.5, squares 5 and 4.75
    expected = -3.5 / np.sqrt(5.0 * 4.75)
    assert obs.line_of_centres_correlation(v, pairs, t_i, t_j) == pytest.approx(expected, rel=1e-12)


def test_line_of_centres_components_use_each_end_s_own_unit_vector():
    pairs = np.array([[0, 1]])
    t_i, t_j = np.array([[0.6, 0.8]]), np.array([[0.0, -1.0]])   # not opposite, as on a curved surface
    v = np.array([[1.0, 1.0], [2.0, 3.0]])
    u, u_prime = obs.line_of_centres_components(v, pairs, t_i, t_j)
    assert (u[0], u_prime[0]) == pytest.approx((1.4, 3.0))
    assert obs.closing_speeds(v, pairs, t_i, t_j)[0] == pytest.approx(u[0] - u_prime[0])


def test_uniform_velocity_is_perfectly_correlated_and_frozen():
    torus = pb.FlatTorus(rows=4, cols=4)
    c = torus.contacts
    v = np.tile([1.0, 0.3], (torus.n_balls, 1))            # u = u' on every contact, and w = 0
    assert obs.line_of_centres_correlation(v, c.pairs, c.t_i, c.t_j) == pytest.approx(1.0, abs=1e-12)
    assert obs.approaching_fraction(v, c.pairs, c.t_i, c.t_j) == 0.0


def test_independent_normal_velocities_are_uncorrelated():
    # 10,000 balls, 30,000 contacts: standard errors about 0.01 and 0.006; tolerances are 4 of them
    torus = pb.FlatTorus(rows=100, cols=100)
    c = torus.contacts
    v = np.random.default_rng(4).normal(size=(torus.n_balls, 2))
    assert abs(obs.line_of_centres_correlation(v, c.pairs, c.t_i, c.t_j)) < 0.025
    assert abs(obs.xy_correlation(v)) < 0.04


def test_xy_correlation_by_hand():
    v = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    assert obs.xy_correlation(v) == pytest.approx(1.0)
    assert obs.xy_correlation(v * [1.0, -1.0]) == pytest.approx(-1.0)
    assert np.isnan(obs.xy_correlation(np.array([[1.0, 0.0], [2.0, 0.0]])))   # constant y


def test_one_contact_approaches_and_one_does_not():
    pairs, t_i, t_j = chain(3)
    v = np.array([[1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])    # 0 runs into 1; 2 moves away from 1
    np.testing.assert_array_equal(obs.closing_speeds(v, pairs, t_i, t_j), [1.0, -1.0])
    assert obs.approaching_fraction(v, pairs, t_i, t_j) == 0.5


# ---------------------------------------------------------------- summary

def test_summary_of_half_plane_by_hand():
    half = pb.HalfPlane(rows=2, cols=3)                     # balls 0-2 on the boundary, 3-5 above
    v = np.zeros((6, 2))
    v[0], v[1], v[4] = [1.0, 0.0], [0.0, -2.0], [0.0, 1.0]  # energies 0.5, 2 (outward), 0.5
    s = obs.summary(v, half)
    assert s["energy"] == 3.0
    assert (s["momentum_x"], s["momentum_y"]) == (1.0, -1.0)
    assert s["boundary_share"] == pytest.approx(2.5 / 3.0)
    assert s["boundary_outward_fraction"] == pytest.approx(0.8)
    c = half.contacts
    assert s["approaching_fraction"] == obs.approaching_fraction(v, c.pairs, c.t_i, c.t_j)
    assert all(isinstance(x, float) for x in s.values())


def test_summary_of_torus_has_no_boundary():
    torus = pb.FlatTorus(rows=4, cols=3)
    v = np.random.default_rng(5).normal(size=(12, 2))
    s = obs.summary(v, torus)
    assert set(s) == {"energy", "momentum_x", "momentum_y", "approaching_fraction",
                      "line_of_centres_correlation", "xy_correlation"}
    assert s["xy_correlation"] == obs.xy_correlation(v)


# ---------------------------------------------------------------- errors

@pytest.mark.parametrize("call, name", [
    (lambda: obs.energy_per_ball(np.ones(3)), "velocities"),
    (lambda: obs.total_energy(np.ones((3, 2)), masses=np.ones(4)), "masses"),
    (lambda: obs.energy_profile(np.zeros(2), np.ones((3, 2))), "distances"),
    (lambda: obs.boundary_share(np.zeros((3, 1)), np.ones((3, 2))), "distances"),
    (lambda: obs.outward_energy_fraction(np.ones((3, 2)), outward=(0.0, 0.0, -1.0)), "outward"),
    (lambda: obs.component_histogram(np.ones((3, 2))), "values"),
    (lambda: obs.xy_correlation(np.ones((3, 1))), "velocities"),
    (lambda: obs.approaching_fraction(np.ones((3, 2)), np.zeros((2, 3), int), np.ones((2, 2)), np.ones((2, 2))),
     "pairs"),
    (lambda: obs.approaching_fraction(np.ones((3, 2)), np.array([[0, 3]]), np.ones((1, 2)), np.ones((1, 2))),
     "pairs"),
    (lambda: obs.line_of_centres_correlation(np.ones((3, 2)), np.array([[0, 1]]), np.ones((2, 2)),
                                             np.ones((1, 2))), "t_i"),
    (lambda: obs.line_of_centres_correlation(np.ones((3, 2)), np.array([[0, 1]]), np.ones((1, 2)),
                                             np.ones((1, 3))), "t_j"),
    (lambda: obs.summary(np.ones((5, 2)), pb.FlatTorus(rows=4, cols=3)), "velocities"),
])
def test_bad_shapes_name_the_argument(call, name):
    with pytest.raises(ValueError, match=rf"^{name}:"):
        call()
