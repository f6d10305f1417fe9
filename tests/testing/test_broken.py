"""The kit catches broken components: a rule that creates energy, a scheduler with a biased pick, a
geometry with a wrong normal, ... Each is a small, plausible mistake, and the test asserts the
`AssertionError` names the broken property and a counterexample."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.streams.xoshiro import bounded
from pinnedballs.rules import CollisionRule, closing_speed, remnant_threshold
from pinnedballs.testing import (
    check_contact_graph_round_trip,
    check_contact_tables,
    check_contacts_are_touching_pairs,
    check_energy_conserved_if_elastic,
    check_energy_never_created,
    check_exact_agrees,
    check_frames,
    check_geometry,
    check_geometry_pickles,
    check_geometry_spec_round_trip,
    check_momentum_conserved,
    check_restitution_law,
    check_rule,
    check_scheduler,
    check_scheduler_law,
    check_scheduler_picks_in_range,
    check_scheduler_same_seed_same_run,
    check_scheduler_state_round_trip,
    check_separating_untouched,
    check_swap_symmetric,
    checks_for,
    parametrize_with_checks,
)
from pinnedballs.testing.samples import TableGeometry

# ---------------------------------------------------------------- rules


@njit(inline="always")
def push(v, units, i, j, a, b, masses, factor, w, dim, flat, write):
    """``v_i -= factor m_j / (m_i + m_j) w t_i``, ``v_j -= factor m_i / (m_i + m_j) w t_j`` (factor 2: elastic)."""
    s = factor * w / (masses[i] + masses[j])
    for k in range(dim):
        tj = -units[a, k] if flat else units[b, k]
        if write:
            v[i, k] -= s * masses[j] * units[a, k]
            v[j, k] -= s * masses[i] * tj
    return w != 0.0


@njit
def collide_greedy(v, units, i, j, a, b, masses, params, dim, flat, write):
    """The paper's rule with 10 % too much impulse: creates energy."""
    tau = remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    return push(v, units, i, j, a, b, masses, 2.2, w, dim, flat, write)


@njit
def collide_meddler(v, units, i, j, a, b, masses, params, dim, flat, write):
    """Forgets the test ``w > threshold``: separating balls collide too."""
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    return push(v, units, i, j, a, b, masses, 2.0, w, dim, flat, write)


@njit
def collide_one_sided(v, units, i, j, a, b, masses, params, dim, flat, write):
    """Stops ball i along the line of centres and leaves j alone: momentum is lost."""
    tau = remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    vi = 0.0
    for k in range(dim):
        vi += v[i, k] * units[a, k]
    if write and vi > 0:
        for k in range(dim):
            v[i, k] -= vi * units[a, k]
    return vi > 0


@njit
def collide_lopsided(v, units, i, j, a, b, masses, params, dim, flat, write):
    """Elastic, but only when the lower-numbered ball comes first: the other way round nothing happens."""
    tau = remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau or i > j:
        return False
    return push(v, units, i, j, a, b, masses, 2.0, w, dim, flat, write)


@njit
def collide_damped(v, units, i, j, a, b, masses, params, dim, flat, write):
    """Restitution 0.9."""
    tau = remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    return push(v, units, i, j, a, b, masses, 1.9, w, dim, flat, write)


class UserRule(CollisionRule):
    """A rule of the user's: one ``collide`` for equal and unequal masses."""

    def __init__(self, collide, elastic: bool = False, exact: float | None = None):
        self.collide, self.elastic, self.exact = collide, elastic, exact

    def kernel(self, equal_masses: bool):
        return self.collide, np.zeros(1)

    def exact_restitution(self):
        return self.exact

    def __repr__(self) -> str:
        return f"UserRule({self.collide.__name__})"


def test_a_rule_that_creates_energy():
    with pytest.raises(AssertionError, match=r"^energy never created: 2-D flat, equal masses, pair \d+: t_i = \(.*\), "
                                             r"t_j = \(.*\), masses \(1, 1\), v_i = .* energy .* became .*$"):
        check_energy_never_created(UserRule(collide_greedy))


def test_a_rule_that_says_it_is_elastic_and_is_not():
    rule = UserRule(collide_damped, elastic=True)
    check_energy_never_created(rule)  # it only loses energy
    with pytest.raises(AssertionError, match=r"^energy conserved \(elastic\): 2-D flat, equal masses, pair \d+: .* "
                                             r"energy [0-9.e+-]+ became [0-9.e+-]+$"):
        check_energy_conserved_if_elastic(rule)
    with pytest.raises(AssertionError, match=r"^energy conserved \(elastic\): "):
        check_rule(rule)


def test_a_rule_that_touches_separating_balls():
    with pytest.raises(AssertionError, match=r"^separating balls untouched: 2-D flat, equal masses, pair \d+: .* \(w = "
                                             r"-[0-9.e+-]+ <= 0\): became .*; \d+ collision\(s\) counted$"):
        check_separating_untouched(UserRule(collide_meddler))


def test_a_rule_that_loses_momentum():
    with pytest.raises(AssertionError, match=r"^momentum conserved: 2-D flat, equal masses, pair \d+: .*: momentum "
                                             r"\(.*\) became \(.*\)$"):
        check_momentum_conserved(UserRule(collide_one_sided))


def test_a_rule_that_depends_on_which_ball_comes_first():
    rule = UserRule(collide_lopsided)
    check_momentum_conserved(rule)
    check_energy_never_created(rule)
    with pytest.raises(AssertionError, match=r"^symmetric under swapping the balls: 2-D flat, equal masses, pair \d+: "
                                             r".*: as \(i, j\) \(.*\), \(.*\); as \(j, i\) \(.*\), \(.*\)$"):
        check_swap_symmetric(rule)


def test_a_rule_that_claims_an_exact_form_it_does_not_have():
    rule = UserRule(collide_damped, exact=1.0)
    with pytest.raises(AssertionError, match=r"^closing speed becomes -r w: 2-D flat, equal masses, pair \d+: .*: w = "
                                             r"[0-9.e+-]+ became [0-9.e+-]+, not -1 w$"):
        check_restitution_law(rule)
    with pytest.raises(AssertionError, match=r"^float and exact arithmetic agree: 3 x 4 half-plane, ball \d+ sent with "
                                             r"\(0.3, 1\), seed 20250, 3,000 steps: ball \d+ has .* in float and .* "
                                             r"exactly \(\d+ and \d+ collisions\)$"):
        check_exact_agrees(rule)


def test_a_rule_the_engine_refuses_fails_its_checks_with_the_reason():
    """A plain Python collide (no @njit): the simulation refuses it, and the check says so."""
    rule = UserRule(collide_greedy.py_func)
    with pytest.raises(AssertionError, match=r"^separating balls untouched: the simulation refused it: FieldTypeError: "
                                             r"rule: UserRule\.kernel\(\)'s collide must be a numba-compiled function"):
        check_rule(rule)


# ---------------------------------------------------------------- schedulers


@njit
def pick_biased(state, rng, n_contacts):
    """Uniform over n + 1 slots, the last one contact 0: contact 0 twice as often."""
    r, rng = bounded(rng, n_contacts + 1)
    return (np.uint64(0) if r == n_contacts else r), rng


@njit
def pick_short_sweep(state, rng, n_contacts):
    """A sweep that forgets its last contact: 0, 0, 1, ..., n-2, 0, 0, 1, ..."""
    k = state[0]
    state[0] = k + 1 if k + 1 < n_contacts else 0
    return np.uint64(max(k - 1, 0)), rng


@njit
def pick_too_far(state, rng, n_contacts):
    """Uniform over one contact too many."""
    return bounded(rng, n_contacts + 1)


@njit
def pick_own_stream(state, rng, n_contacts):
    """Draws from numba's own generator, not from the simulation's seeded stream."""
    return np.uint64(np.random.randint(0, n_contacts)), rng


@njit
def pick_uniform(state, rng, n_contacts):
    return bounded(rng, n_contacts)


class UserScheduler(pb.Scheduler):
    def __init__(self, pick, law=None):
        self.pick, self.law = pick, law

    def kernel(self):
        return self.pick

    def __repr__(self) -> str:
        return f"UserScheduler({self.pick.__name__})"


class Unresumable(UserScheduler):
    """Refuses every state it is given back."""

    def check_state(self, state, n_contacts):
        raise ValueError("scheduler_state: not mine")


def test_a_biased_pick_fails_the_uniform_law():
    with pytest.raises(AssertionError, match=r"^the law it claims \(uniform\): 20000 picks over the 10 contacts of a "
                                             r"chain, seed 20250: counts \[\d{4}, .*\], chi-square p = .* < 0\.001$"):
        check_scheduler_law(UserScheduler(pick_biased, law="uniform"))


def test_a_sweep_that_misses_a_contact():
    with pytest.raises(AssertionError, match=r"^the law it claims \(sweep\): sweep 0 of FlatTorus\(n_balls=12, "
                                             r"n_contacts=36, dim=2\) \(36 contacts\), seed 20250, "
                                             r"picked contact 0 2 times$"):
        check_scheduler_law(UserScheduler(pick_short_sweep, law="sweep"))


def test_a_sweep_is_not_uniform():
    with pytest.raises(AssertionError, match=r"^the law it claims \(uniform\): 19999 consecutive pairs of picks "
                                             r"over the 100 ordered pairs of contacts, seed 20250: "
                                             r"chi-square p = 0 < 0\.001 \(pick \d then \d: \d+ times, "
                                             r"200 expected\)$"):
        check_scheduler_law(UserScheduler(pb.Sweep().kernel(), law="uniform"))


def test_a_pick_out_of_range():
    with pytest.raises(AssertionError, match=r"^picks in range: on FlatTorus\(n_balls=12, n_contacts=36, dim=2\) \(36 "
                                             r"contacts\), seed 20250: UserScheduler\.kernel\(\)'s pick 'pick_too_far' "
                                             r"picked contact 36, but there are 36 contacts \(0 to 35\)$"):
        check_scheduler_picks_in_range(UserScheduler(pick_too_far))


def test_a_scheduler_that_draws_from_another_stream():
    with pytest.raises(AssertionError, match=r"^same seed, same run: seed 20250 on FlatTorus\(.*\): pick \d+ was "
                                             r"contact \d+, then \d+$"):
        check_scheduler_same_seed_same_run(UserScheduler(pick_own_stream))


def test_a_scheduler_that_refuses_its_own_state():
    with pytest.raises(AssertionError, match=r"^state round trip: after 1,500 steps on FlatTorus\(.*\) its own state "
                                             r"was refused: ValueError: scheduler_state: not mine$"):
        check_scheduler_state_round_trip(Unresumable(pick_uniform))


def test_a_sound_user_scheduler_passes_every_check():
    check_scheduler(UserScheduler(pick_uniform, law="uniform"))


# ---------------------------------------------------------------- geometries


def half_plane_tables(**change) -> TableGeometry:
    """A 3 x 4 half-plane as a user's tables: a unit vector per contact end."""
    g = pb.HalfPlane(3, 4)
    c = g.contacts
    e = len(c)
    units = np.empty((2 * e, 2))
    units[0::2], units[1::2] = c.t_i, c.t_j
    tables = dict(positions=g.positions, pairs=c.pairs.astype(np.int64), ends=np.arange(2 * e).reshape(e, 2),
                  units=units)
    tables.update(change)
    return TableGeometry(**tables)


def test_a_user_geometry_that_is_sound_passes():
    check_geometry(half_plane_tables())


def test_a_wrong_normal():
    g = half_plane_tables()
    g.tables[2][10] *= -1
    with pytest.raises(AssertionError, match=r"^contact tables sound: units: contact 5 \(balls \(\d+, \d+\)\): t_i = "
                                             r"\(.*\) points away from ball \d+: t_i \. \(x_j - x_i\) <= 0$"):
        check_contact_tables(g)
    with pytest.raises(AssertionError, match=r"^contact tables sound: "):
        check_geometry(g)


def test_a_touching_pair_left_out():
    """The public peer's bug (PAPER.md): a tolerance too tight misses contacts."""
    full = half_plane_tables()
    pairs, ends, units = full.tables
    g = half_plane_tables(pairs=np.delete(pairs, 3, axis=0), ends=np.delete(ends, 3, axis=0))
    check_contact_tables(g)
    i, j = sorted(pairs[3].tolist())
    with pytest.raises(AssertionError, match=rf"^contacts are the touching pairs: balls {i} and {j} at \(.*\) "
                                             rf"and \(.*\) touch but are no contact "
                                             rf"\(1 touching pair\(s\) left out\)$"):
        check_contacts_are_touching_pairs(g)


class MisspeltTorus(pb.FlatTorus):
    """Says it is a torus of two more rows than it has."""

    def to_spec(self) -> dict:
        return {**super().to_spec(), "rows": self.rows + 2}


def test_a_spec_that_builds_another_geometry():
    with pytest.raises(AssertionError, match=r"^spec round trip: a MisspeltTorus came back as a FlatTorus$"):
        check_geometry_spec_round_trip(MisspeltTorus(4, 3))


class Tagged(pb.HalfPlane):
    """Keeps a function (a lambda) among its attributes: it does not pickle."""

    def __init__(self, rows, cols):
        super().__init__(rows, cols)
        self.label = lambda ball: f"ball {ball}"


def test_a_geometry_that_does_not_pickle():
    with pytest.raises(AssertionError, match=r"^pickles: Tagged\(n_balls=12, n_contacts=23, dim=2\) does not pickle: "):
        check_geometry_pickles(Tagged(3, 4))


class Stretched(pb.Sphere):
    """Frames twice as long as they should be."""

    def frames(self):
        return 2.0 * super().frames()


def test_frames_that_are_not_orthonormal():
    s = pb.Sphere.geodesic(1)
    g = Stretched(s.positions, s.pairs)
    check_contact_tables(g)  # the directions are right, the lengths are not
    with pytest.raises(AssertionError, match=r"^frames orthonormal: ball 0: the frame .* has Gram matrix "
                                             r"\[\[4\.0.*, not the identity$"):
        check_frames(g)


def test_a_graph_that_loses_contacts_on_the_way_back():
    class Forgetful(pb.HalfPlane):
        def contact_graph(self):
            g = super().contact_graph()
            g.remove_edge(*next(iter(g.edges)))
            return g

    with pytest.raises(AssertionError, match=r"^contact graph round trip: GraphGeometry refused its contact graph: "
                                             r"FieldError: graph: edge 'contact' attributes must number"):
        check_contact_graph_round_trip(Forgetful(3, 4))


# ---------------------------------------------------------------- the pytest decorator


def test_parametrize_with_checks_makes_one_case_per_check_and_marks_expected_failures():
    rule = UserRule(collide_greedy)
    mark = parametrize_with_checks([pb.Elastic(), rule], expected_failed_checks=lambda c: (
        {"check_energy_never_created": "it gives 10 % too much"} if c is rule else {}))
    names, cases = mark.args
    assert names == "component, check"
    assert [p.id for p in cases] == ([f"Elastic()-{c.__name__}" for c in checks_for(pb.Elastic())]
                                     + [f"UserRule(collide_greedy)-{c.__name__}" for c in checks_for(rule)])
    marked = {p.id: p.marks[0].kwargs for p in cases if p.marks}
    assert marked == {"UserRule(collide_greedy)-check_energy_never_created": {
        "reason": "it gives 10 % too much", "strict": True, "raises": AssertionError}}


class Plain(CollisionRule):
    """A user's rule with object's repr (a memory address, different in every process)."""

    def kernel(self, equal_masses: bool):
        return collide_damped, np.zeros(1)


def test_parametrize_with_checks_ids_are_the_same_in_every_process():
    """A component without a repr of its own is named by its class and place, so pytest-xdist's workers
    collect the same ids (with the memory address each got a different id, and ``-n 2`` stopped with
    "Different tests were collected")."""
    _, cases = parametrize_with_checks([pb.Elastic(), Plain(), Plain()]).args
    ids = [p.id for p in cases]
    assert not [i for i in ids if "0x" in i]
    assert {i.split("-")[0] for i in ids} == {"Elastic()", "Plain[1]", "Plain[2]"}
    assert len(set(ids)) == len(ids)


@pytest.mark.slow
def test_parametrize_with_checks_runs_under_xdist(tmp_path):
    import subprocess
    import sys

    (tmp_path / "test_mine.py").write_text(
        "import numpy as np\n"
        "from pinnedballs.rules import CollisionRule, collide_elastic\n"
        "from pinnedballs.testing import parametrize_with_checks\n"
        "class Mine(CollisionRule):\n"
        "    def kernel(self, equal_masses):\n"
        "        return collide_elastic, np.ones(1)\n"
        "@parametrize_with_checks([Mine()])\n"
        "def test_mine(component, check):\n"
        "    pass\n")
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider", "test_mine.py"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-2000:]
    assert " passed" in out.stdout and "Different tests were collected" not in out.stdout


def test_parametrize_with_checks_refuses_an_unknown_check_name():
    with pytest.raises(ValueError, match=r"^expected_failed_checks: \['check_energy_conserved'\] are no checks of "
                                         r"Elastic\(\) \(its checks: \['check_separating_untouched', "):
        parametrize_with_checks([pb.Elastic()], expected_failed_checks={"check_energy_conserved": "typo"})


@parametrize_with_checks([UserRule(collide_greedy, elastic=True)], expected_failed_checks={
    "check_energy_never_created": "10 % too much impulse", "check_energy_conserved_if_elastic": "the same"})
def test_declared_failures_run_as_strict_xfail(component, check):
    """The two energy checks fail as declared (xfail, strict: they would turn the run red if they passed);
    the others pass."""
    check(component)


def test_checks_for_refuses_what_is_no_component():
    with pytest.raises(TypeError, match=r"^component: must be a Geometry, a CollisionRule, a Scheduler or an "
                                        r"Engine, got str$"):
        checks_for("torus")


def test_user_rule_pickles_for_the_record():
    """(The broken rules above pickle: the round-trip checks have something to compare.)"""
    assert pickle.loads(pickle.dumps(UserRule(collide_greedy))).collide is collide_greedy
