"""A run directory is the same whatever device wrote it: a run on the GPU (numba-cuda's simulator here) writes
the CPU's snapshots and state, records where it ran, and a checkpoint continues on either device."""

import h5py
import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.specs.run import parse_spec

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)

SPEC = {"geometry": {"kind": "half_plane", "length": 20, "depth": 10},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
        "scheduler": {"kind": "uniform_random_pair", "stream": "counter"},
        "stop": {"frozen": True, "max_steps": 10**6}, "snapshots": {"every_steps": 400}, "seed": 12}


def test_the_gpu_writes_the_cpus_run(tmp_path):
    spec = parse_spec(SPEC)
    cpu = pb.run_spec(spec, tmp_path / "cpu", figures=False)
    gpu = pb.run_spec(spec, tmp_path / "gpu", figures=False, device="cuda")
    assert (cpu.device, gpu.device) == ("cpu", "cuda")
    assert (gpu.steps, gpu.collisions, gpu.stop_reason) == (cpu.steps, cpu.collisions, cpu.stop_reason) != (0, 0, "")
    np.testing.assert_array_equal(gpu.velocities, cpu.velocities)
    assert len(gpu.snapshots) == len(cpu.snapshots) > 2
    for a, b in zip(gpu.snapshots, cpu.snapshots):
        assert (a.steps, a.collisions) == (b.steps, b.collisions)
        np.testing.assert_array_equal(a.velocities, b.velocities)
    assert gpu.closing_margin == cpu.closing_margin
    with h5py.File(tmp_path / "gpu" / "results.h5", "r") as f:
        assert f.attrs["device"] == "cuda"


def test_a_checkpoint_goes_on_on_the_other_device(tmp_path):
    spec = parse_spec({**SPEC, "stop": {"steps": 900}})
    part = pb.run_spec(spec, tmp_path / "part", figures=False)
    whole = pb.Simulation(part.geometry, part.initial_velocities, scheduler=pb.UniformRandomPair(stream="counter"),
                          seed=12)
    whole.run_until_frozen(max_steps=10**6, progress=False)
    for device in ("cuda", "cpu"):
        sim = part.simulation(device=device)
        assert sim.device == {"cuda": pb.CUDA(), "cpu": pb.CPU()}[device] and sim.steps == 900
        sim.run_until_frozen(max_steps=10**6, progress=False)
        np.testing.assert_array_equal(sim.velocities, whole.velocities)
        assert (sim.steps, sim.collisions) == (whole.steps, whole.collisions)


def test_a_certified_run_with_automatic_bits_writes_the_cpus_run_on_the_gpu(tmp_path):
    """``"precision": "auto"``: the attempt's bits recorded, the same run directory from either device."""
    spec = parse_spec({**SPEC, "geometry": {"kind": "half_plane", "length": 16, "depth": 8}, "arithmetic": "certified",
                       "precision": "auto", "seed": 0, "snapshots": {"every_steps": 500}})
    cpu = pb.run_spec(spec, tmp_path / "cpu", figures=False)
    gpu = pb.run_spec(spec, tmp_path / "gpu", figures=False, device="cuda")
    assert (gpu.steps, gpu.collisions, gpu.stop_reason) == (cpu.steps, cpu.collisions, cpu.stop_reason)
    assert gpu.stop_reason == "frozen" and gpu.device == "cuda"
    assert gpu.latest.certified.identical(cpu.latest.certified) and gpu.latest.certified.precision == 768
    for a, b in zip(gpu.snapshots, cpu.snapshots, strict=True):
        np.testing.assert_array_equal(a.velocities, b.velocities)
