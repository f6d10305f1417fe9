"""Sums over the balls (`util.sums`) whose bits do not depend on the machine: the same on 1 and on 2 BLAS threads
(numpy's ``@`` is not), and correct to a few units in the last place."""

import math
import subprocess
import sys
from fractions import Fraction

import numpy as np
from helpers import ROOT

from pinnedballs.util.sums import dot, kinetic_energy, momentum

_CHILD = r"""
import hashlib
import numpy as np
from pinnedballs.specs.run import parse_spec
spec = parse_spec({"geometry": {"kind": "half_plane", "rows": 1000, "cols": 1000},
                   "initial": {"kind": "gaussian", "energy": 100, "zero_momentum": True}, "stop": {"steps": 1},
                   "seed": 1})
sim = spec.build()
v = np.random.default_rng(2).normal(size=2_000_000)
print(hashlib.sha1(sim.velocities.tobytes()).hexdigest(), sim.energy().hex(), sim.momentum().tobytes().hex(),
      (v @ v).hex())
"""


def test_a_gaussian_start_its_energy_and_momentum_do_not_depend_on_the_blas_threads():
    """A million balls' Gaussian start (its momentum removed, its energy scaled), its energy and its momentum: the
    same bits with ``OPENBLAS_NUM_THREADS`` 1 and 2, where numpy's own ``v @ v`` differs."""
    outs = [subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, cwd=ROOT, timeout=300,
                           env={"OPENBLAS_NUM_THREADS": str(t), "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
            for t in (1, 2)]
    assert all(o.returncode == 0 for o in outs), outs[0].stderr[-2000:]
    ours = [o.stdout.split()[:3] for o in outs]
    assert ours[0] == ours[1]
    assert outs[0].stdout.split()[3] != outs[1].stdout.split()[3]  # the BLAS's sum: other last bits


def test_the_sums_are_correct_to_a_few_units_in_the_last_place():
    rng = np.random.default_rng(3)
    m, v = rng.uniform(0.5, 2.0, 10_001), rng.normal(size=(10_001, 3))
    exact = sum(Fraction(float(mi)) * sum(Fraction(float(x)) ** 2 for x in row) for mi, row in zip(m, v)) / 2
    assert math.isclose(kinetic_energy(m, v), float(exact), rel_tol=1e-14)
    for k in range(3):
        assert math.isclose(momentum(m, v)[k], math.fsum((m * v[:, k]).tolist()), rel_tol=1e-12, abs_tol=1e-9)
    assert math.isclose(dot(v[:, 0], v[:, 1]), math.fsum((v[:, 0] * v[:, 1]).tolist()), rel_tol=1e-12, abs_tol=1e-9)
    assert momentum(m, v).shape == (3,) and kinetic_energy(m[:0], v[:0]) == 0.0
