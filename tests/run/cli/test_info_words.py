"""What ``info`` and ``validate`` say of a run in words (issue 42, items 2 and 5): the error bound G of certified
arithmetic with its meaning and units, the arithmetic and its bits, the random stream, the device it last ran on
(numba-cuda's simulator named as such: the tests run it), the chain's time as the chain's; and the run's summary
line, which says "frozen" once."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs.run.cli.commands import _duration
from pinnedballs.specs import parse_spec

CERTIFIED = spec(HALF_PLANE, geometry={"kind": "half_plane", "length": 30, "depth": 15}, arithmetic="certified",
                 precision=256, late_precision=128)
COUNTER = {"kind": "uniform_random_pair", "stream": "counter"}


def info_lines(out) -> dict[str, str]:
    """``info``'s lines by their label (a line continuing the one before is kept under ``label + "+"``)."""
    code, text, err = call("info", out)
    assert (code, err) == (0, "")
    lines, label = {}, ""
    for line in text.splitlines():
        if line.startswith(" "):
            lines[label + "+"] = line.strip()
        else:
            label, _, rest = line.partition(":")
            lines[label] = rest.strip()
    return lines


def test_info_says_what_the_error_bound_is_and_the_bits(tmp_path):
    """G in words and units where the run has rounded (the 30x15 half-plane at 64 bits, which fails at step
    1,099: `test_failed_runs`), and what a G of 0 means where it has not (at 256 bits, 128 behind the front)."""
    rounded = spec(CERTIFIED, initial__direction="inward", seed=1, precision=64, late_precision=...)
    assert call("run", write(tmp_path / "s.json", rounded), "--out", tmp_path / "r", "--quiet", "--no-figures")[0] == 2
    G, largest = pb.load(tmp_path / "r").latest.certified.error_bound()
    lines = info_lines(tmp_path / "r")
    assert G > 0 and lines["arithmetic+"] == (
        f"G = {G:.3g} (in the velocities' units) bounds how far all the certified velocities together (the length "
        f"of the whole difference) are from exact arithmetic's; {largest:.3g} bounds each ball's")
    assert lines["arithmetic"].endswith(f"velocities within {largest:.3g} of exact arithmetic's (error bound G = "
                                        f"{G:.3g}), 64 bits")
    pb.run_spec(parse_spec(CERTIFIED), tmp_path / "exact", figures=False)
    lines = info_lines(tmp_path / "exact")
    assert lines["arithmetic+"] == "G = 0: no rounding yet: the certified velocities are exact arithmetic's"
    # narrowed
    assert lines["arithmetic"].endswith(", 128 bits (256 through the first wave, 128 behind the first wave)")


def test_validate_says_the_arithmetic_and_its_bits(tmp_path):
    for changes, words in [({}, "; certified arithmetic, 256 bits through the first wave, 128 behind it; "),
                           ({"late_precision": ...}, "; certified arithmetic, 256 bits; "),
                           ({"precision": "auto", "late_precision": ...},
                            "; certified arithmetic, precision auto: 768 bits to start, more where a decision cannot "
                            "be proved; "),
                           ({"arithmetic": "exact", "precision": ..., "late_precision": ...}, "; exact arithmetic; ")]:
        code, out, err = call("validate", write(tmp_path / "s.json", spec(CERTIFIED, **changes)))
        assert (code, err) == (0, "") and words in out, out


@pytest.mark.cuda
def test_info_names_the_random_stream_and_the_device(tmp_path):
    """xoshiro256** by default, Philox4x64-10 on the counter stream; the CPU, or the GPU as numba-cuda's
    simulator (on in the tests) stood in for it, whose results are the CPU's bit for bit."""
    data = spec(HALF_PLANE, geometry={"kind": "half_plane", "length": 20, "depth": 10})
    pb.run_spec(parse_spec(data), tmp_path / "xoshiro", figures=False)
    pb.run_spec(parse_spec(spec(data, scheduler=COUNTER)), tmp_path / "cpu", figures=False)
    gpu = pb.run_spec(parse_spec(spec(data, scheduler=COUNTER)), tmp_path / "gpu", figures=False, device="cuda")
    assert (gpu.device, gpu.simulated) == ("cuda", True) and np.array_equal(gpu.velocities,
                                                                           pb.load(tmp_path / "cpu").velocities)
    said = {name: info_lines(tmp_path / name) for name in ("xoshiro", "cpu", "gpu")}
    assert (said["xoshiro"]["random"], said["xoshiro"]["device"]) == ("xoshiro256**", "cpu")
    counter = "counter (Philox4x64-10: the pick of step s a function of the seed and s alone)"
    assert (said["cpu"]["random"], said["cpu"]["device"]) == (counter, "cpu")
    assert (said["gpu"]["random"], said["gpu"]["device"]) == (counter, "cuda (simulated)")
    assert said["xoshiro"]["arithmetic"] == "float (64-bit floating point)"
    assert said["xoshiro"]["margin"].startswith("smallest collision ")


def test_info_calls_the_time_the_chains(tmp_path):
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "s.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    res = pb.load(out)
    assert info_lines(out)["time"] == (f"{_duration(res.elapsed_seconds)} running the chain in 2 checkpoint(s) "
                                       f"(building, compiling and figures not counted); written by pinnedballs "
                                       f"{res.version}")


@pytest.mark.parametrize("data, ending", [(HALF_PLANE, "energy 100"), (TORUS, "energy 100, not frozen")])
def test_the_summary_of_a_run_says_frozen_once(tmp_path, data, ending):
    out = tmp_path / "out"
    code, stdout, err = call("run", write(tmp_path / "s.json", spec(data, snapshots=...)), "--out", out,
                             "--no-figures")
    res = pb.load(out)
    assert code == 0 and stdout == (f"{res.stop_reason}: {res.steps:,} steps, {res.collisions:,} collisions, "
                                    f"{ending}; wrote {out}\n")
    assert stdout.count("frozen") == 1 and res.stop_reason == ("frozen" if data is HALF_PLANE else "steps")
