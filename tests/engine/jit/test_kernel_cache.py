"""The compiled loops' on-disk cache: one entry per (rule, scheduler, dim, flat), hits across processes."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from helpers import pick_loops
from numba import njit

from pinnedballs.engine.jit.cache import _ClosureCache
from pinnedballs.rules import collide_equal, collide_masses
from pinnedballs.schedulers.simple import pick_random_sweep, pick_sweep, pick_uniform

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these


def _key(loops):
    kernel = loops.limited
    return _ClosureCache(kernel.py_func)._index_key(("sig",), kernel.targetctx.codegen())


def test_every_combination_has_its_own_key():
    """A shared key would load one rule's compiled loop for another (a bug we once had)."""
    combos = [(c, p, d, f) for c in (collide_equal, collide_masses)
              for p in (pick_uniform, pick_sweep, pick_random_sweep) for d in (1, 2, 3) for f in (True, False)]
    keys = {_key(pick_loops(*combo)) for combo in combos}
    assert len(keys) == len(combos)


def test_key_is_the_same_in_another_process():
    here = _key(pick_loops(collide_equal, pick_sweep, 2, True))
    code = textwrap.dedent("""
        from pinnedballs.engine.jit.cache import _ClosureCache
        from pinnedballs.engine.sequential.loops import loops, pick_selector
        from pinnedballs.rules import collide_equal
        from pinnedballs.schedulers.simple import pick_sweep
        s = pick_selector(pick_sweep)
        k = loops(collide_equal, s.select, s.begin, s.changed, s.skips, 2, True).limited
        print(repr(_ClosureCache(k.py_func)._index_key(("sig",), k.targetctx.codegen())))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == repr(here)


def test_function_without_source_file_is_not_disk_cached():
    ns = {}
    exec("def f(v, units, i, j, a, b, masses, params, dim, flat):\n    return False", ns)
    loops = pick_loops(njit(ns["f"]), pick_uniform, 2, True)
    colliding = [loops.limited, loops.limited_prefetched, loops.limited_rows, loops.tracked]
    assert not any(isinstance(kernel._cache, _ClosureCache) for kernel in colliding)
    assert isinstance(loops.picks._cache, _ClosureCache)  # it never calls the rule


def test_cached_loops_give_each_rule_its_own_physics(tmp_path):
    """In fresh processes sharing one cache dir, three rules on one exact case give three answers."""
    code = textwrap.dedent("""
        import numpy as np, pinnedballs as pb
        g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0]])
        out = []
        for rule, masses in ((pb.Elastic(), None), (pb.Restitution(0.0), None), (pb.Elastic(), [1.0, 3.0])):
            sim = pb.Simulation(g, [[1.0, 0.0], [0.0, 0.0]], rule=rule, masses=masses, scheduler=pb.Sweep())
            sim.run(steps=1)
            out.append(sim.velocities[:, 0].tolist())
        print(out)
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
            for _ in range(2)]  # the second run loads every loop from the cache
    expected = [[0.0, 1.0], [0.5, 0.5], [-0.5, 0.5]]  # exchange; stick together; 1 hits 3 head-on
    for run in runs:
        np.testing.assert_allclose(eval(run.stdout), expected, rtol=0, atol=1e-15)


def test_a_helper_in_another_module_is_part_of_the_key(tmp_path, monkeypatch):
    """Editing a jitted helper that a user's rule calls from a third module changes the key,
    so the cached loop is not reused with the old helper's numbers."""
    helper = tmp_path / "myhelpers.py"
    rule = tmp_path / "myrule.py"
    rule.write_text(textwrap.dedent("""
        from numba import njit
        from myhelpers import scale
        from pinnedballs.rules import collide_equal

        @njit(inline="always")
        def collide(v, units, i, j, a, b, masses, params, dim, flat, write):
            return collide_equal(v, units, i, j, a, b, masses, params * scale(), dim, flat, write)
    """))
    code = textwrap.dedent("""
        import numpy as np, pinnedballs as pb
        from pinnedballs.engine.jit.cache import _ClosureCache
        from pinnedballs.engine.chain import NO_LIMIT
        from pinnedballs.engine.sequential.loops import NO_PATTERN, loops as make_loops, pick_selector
        from pinnedballs.engine.margin import new_margin
        from pinnedballs.engine.sequential.choice import new_tune
        from pinnedballs.engine.streams.xoshiro import seed_state
        from pinnedballs.schedulers.simple import pick_sweep
        import myrule
        s = pick_selector(pick_sweep)
        loops = make_loops(myrule.collide, s.select, s.begin, s.changed, s.skips, 2, True)
        k = loops.limited
        key = _ClosureCache(k.py_func)._index_key(("sig",), k.targetctx.codegen())
        v = np.array([[1.0, 0.0], [0.0, 0.0]])
        g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0]])
        counters = np.zeros(4, np.int64)
        k(v, g.contacts.pairs, g.contacts.ends, g.contacts.units, np.ones(2), np.array([1.0, 0.0]), NO_PATTERN,
          np.zeros(1, np.int64), np.zeros(0, np.int64), seed_state(0), counters, new_margin(), 1, NO_LIMIT, False, 1,
          np.zeros(1, np.int64), np.empty((0, 2), np.int64), new_tune())
        print(repr(key), v[:, 0].tolist())
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(tmp_path))
    outputs = []
    for factor in ("1.0", "0.5", "0.5"):
        helper.write_text(f"from numba import njit\n\n@njit\ndef scale():\n    return {factor}\n")
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
        outputs.append(run.stdout.split(" [", 1))
    (key1, v1), (key2, v2), (key3, v3) = outputs
    assert key1 != key2 and key2 == key3
    assert v1.strip() == "0.0, 1.0]"          # elastic exchange with scale 1
    assert v2.strip() == v3.strip() == "0.5, 0.5]"  # half the exchange: they share the momentum


def test_parallel_colored_sweep_loop_is_loaded_from_disk_in_a_fresh_process(tmp_path):
    """The prange loop of ColoredSweep (parallel=True) is cached like the others: a second
    process with the same cache directory loads it instead of compiling, and gets the same bits."""
    code = textwrap.dedent("""
        import numpy as np
        import pinnedballs as pb
        geom = pb.FlatTorus(6, 6)
        sim = pb.Simulation(geom, np.random.default_rng(1).normal(size=(36, 2)), scheduler=pb.ColoredSweep(), seed=1)
        sim.run(steps=1000)
        stats = sim.engine.own_steps.loop.stats
        print(sum(stats.cache_hits.values()), sum(stats.cache_misses.values()), sim.velocities.sum().hex())
    """)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": root}
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
            .stdout.split() for _ in range(2)]
    assert runs[0][:2] == ["0", "1"]  # compiled
    assert runs[1][:2] == ["1", "0"]  # loaded
    assert runs[0][2] == runs[1][2]


def test_two_processes_filling_one_cache_never_swap_entries(tmp_path):
    """Two writers that read the index before either saves (two test workers compiling at once),
    then write in the order index B, index A, data A, data B: with numba's numbering both keys get
    data file 1, and the index names key A while the file holds B's code: a loop compiled for one
    rule loaded for another. Named after their keys, entries never share a file."""
    from numba.core.caching import IndexDataCacheFile

    from pinnedballs.engine.jit.cache import _KeyedFiles

    def interleaved(files_class):
        path = tmp_path / files_class.__name__
        path.mkdir()
        a, b = (files_class(str(path), "loop", "stamp") for _ in range(2))
        saves = {}
        for files, key, code in ((a, ("sig", "rule A"), "code of A"), (b, ("sig", "rule B"), "code of B")):
            written = []  # save() with its two writes held back, as if the other process ran between them
            files._save_index = lambda overloads, w=written: w.append(("index", dict(overloads)))
            files._save_data = lambda name, data, w=written: w.append(("data", name, data))
            files.save(key, code)
            del files._save_index, files._save_data
            saves[key] = written
        (_, index_a), (_, name_a, code_a) = saves[("sig", "rule A")]
        (_, index_b), (_, name_b, code_b) = saves[("sig", "rule B")]
        b._save_index(index_b)
        a._save_index(index_a)
        a._save_data(name_a, code_a)
        b._save_data(name_b, code_b)
        return a.load(("sig", "rule A"))

    assert interleaved(IndexDataCacheFile) == "code of B"  # numba's own files: A's key, B's code
    assert interleaved(_KeyedFiles) == "code of A"


CHECKS = textwrap.dedent("""
    import pinnedballs as pb
    from pinnedballs.geometry.checks import _first_fault, check_contacts
    check_contacts(pb.FlatTorus(4, 4))
    stats = _first_fault.stats
    print(sum(stats.cache_hits.values()), sum(stats.cache_misses.values()), _first_fault._cache.cache_path)
""")


def _compiled_files(root) -> set:
    """``(path, size, mtime)`` of every numba cache file (index and data) under ``root``."""
    from pathlib import Path

    return {(str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in Path(root).rglob("*.nb[ic]")}


def test_the_cache_lives_in_the_users_cache_directory_not_beside_the_sources(tmp_path):
    """``python3 -m pinnedballs`` inside a checkout wrote numba's cache into its ``__pycache__`` (issue 49):
    without NUMBA_CACHE_DIR it goes to the user's cache directory (XDG_CACHE_HOME here), under the
    package's name and version, and a second process loads what the first compiled; NUMBA_CACHE_DIR,
    when set, comes first. Nothing in the package's tree is written."""
    import pinnedballs
    from pinnedballs._version import __version__

    package = os.path.dirname(pinnedballs.__file__)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_CACHE_LOCATOR_CLASSES")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), PYTHONPATH=os.path.dirname(package))
    before = _compiled_files(package)
    runs = [subprocess.run([sys.executable, "-c", CHECKS], capture_output=True, text=True, check=True, env=env)
            .stdout.split() for _ in range(2)]
    home = str(tmp_path / "xdg" / "pinnedballs" / "numba" / __version__)
    assert runs[0][:2] == ["0", "1"] and runs[0][2].startswith(home + os.sep)  # compiled, kept there
    assert runs[1] == ["1", "0", runs[0][2]]                                     # loaded by the next process
    given = subprocess.run([sys.executable, "-c", CHECKS], capture_output=True, text=True, check=True,
                           env={**env, "NUMBA_CACHE_DIR": str(tmp_path / "given")}).stdout.split()
    assert given[:2] == ["0", "1"] and given[2].startswith(str(tmp_path / "given") + os.sep)
    assert _compiled_files(package) == before
