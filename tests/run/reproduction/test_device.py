"""`reproduce(..., device="cuda")` and ``reproduce --device``: the scaling study on the counter stream on the GPU
(numba-cuda's simulator here, tests/conftest.py) gives the CPU's rows on that stream; everything else runs on the
CPU with the bits of ``device="cpu"``; the plans' new fields and their checks."""

import csv
import dataclasses
import json

import pytest

import pinnedballs as pb
from pinnedballs.run import ensemble as ens
from pinnedballs.run import reproduction as rp
from pinnedballs.run.cli import main as cli
from pinnedballs.run.reproduction import extended as ext
from pinnedballs.util.errors import InputError

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)

TINY = dict(sizes=((10, 5), (20, 10)), detail=(20, 10), torus=(8, 8), steps=(3_000, 6_000), long_steps=20_000,
            collisions=30, replicas=4, size_replicas=2)
#: 10x5 (15 balls) counted exactly, N_e beyond it at 20x10 (60 balls): every count on the GPU (the exact one, certified
#: arithmetic, one replica at a time)
TINY_X = rp.ExtendedPlan(scaling=((10, 5, 2), (20, 10, 2)), exact_max_balls=15, resolution_max_balls=60,
                         resolutions=(1e-6,), torus_sides=(6,), torus_times=(50,), torus_replicas=2, sphere_frequency=2,
                         hyperbolic_layers=(1,), hyperbolic_replicas=2, fcc=((2, 2, 2),), fcc_replicas=2,
                         orders_replicas=4, orders_max_states=200, exact_gpu_min_balls=0)
PAPER_ENSEMBLES = ("half_plane_10x5", "half_plane_20x10", "paper_lattice", "torus")


def _without_seconds(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if not k.endswith("seconds")} for r in rows]


@pytest.fixture(scope="module")
def on_cuda(tmp_path_factory):
    """The tiny reproduction with ``device="cuda"``: its directory, log lines and results."""
    out = tmp_path_factory.mktemp("cuda") / "out"
    log: list[str] = []
    rp.reproduce(out, workers=1, extended=TINY_X, device="cuda", log=log.append, **TINY)
    return out, log, json.loads((out / "results.json").read_text())


@pytest.mark.slow
def test_the_gpu_gives_the_cpus_scaling_rows_on_the_counter_stream(on_cuda, tmp_path):
    """The same plan on the counter stream on the CPU: the same rows (counts, shares, margins), size by size."""
    _, _, results = on_cuda
    x = results["extended"]
    assert x["plan"]["stream"] == x["scaling_stream"] == "counter"  # set by device="cuda", not by TINY_X

    def on_cpu(name, spec, replicas, **kwargs):
        return ens.run_ensemble(spec, replicas, workers=1, **kwargs)

    cpu = ext.scaling(dataclasses.replace(TINY_X, stream="counter"), tmp_path, on_cpu)
    assert _without_seconds(x["scaling"]) == json.loads(json.dumps(_without_seconds(cpu["rows"])))
    assert x["scaling_ran_on"] == {"float": ["GPU"], "exact": ["GPU, one replica at a time"], "N_e": ["GPU"]}
    assert cpu["ran_on"] == {"float": ["in-process"], "exact": ["in-process"], "N_e": ["in-process"]}
    xoshiro = ext.scaling(TINY_X, tmp_path, on_cpu)["rows"]  # the default stream: the same seeds, other picks
    assert [r["steps_mean"] for r in xoshiro] != [r["steps_mean"] for r in x["scaling"]]
    # N_e reaches past the exact count (resolution_max_balls): 20x10 has N_e and no exact count
    small, large = x["scaling"]
    assert "exact_collisions_mean" in small and "exact_collisions_mean" not in large
    assert small["N_1e-06_replicas"] == large["N_1e-06_replicas"] == 2


@pytest.mark.slow
def test_only_the_scaling_studys_ensembles_run_on_the_gpu_and_the_log_says_so_once(on_cuda):
    out, log, results = on_cuda
    notes = [line for line in log if line.startswith("device cuda:")]
    assert len(notes) == 1 and log[0] == notes[0]  # once, before anything runs
    assert "paper's figures keep their published seeds on the xoshiro stream and run on the CPU" in notes[0]
    assert "scaling study runs on the GPU on the counter stream" in notes[0]
    on_gpu = sorted(line.split("ensemble ", 1)[1].split(":")[0] for line in log if line.endswith(" on the GPU"))
    assert on_gpu == ["scaling_10x5", "scaling_10x5_N_1e-06", "scaling_10x5_exact", "scaling_20x10",
                      "scaling_20x10_N_1e-06"]
    assert results["device"] == "cuda"
    for name in on_gpu:  # every replica froze, on the counter stream
        spec = json.loads((out / "ensembles" / name / "spec.json").read_text())
        assert spec["scheduler"]["stream"] == "counter"
        assert spec["arithmetic"] == ("certified" if name.endswith("exact") else "float")
        with open(out / "ensembles" / name / "replicas.csv") as f:
            assert [row["frozen"] for row in csv.DictReader(f) if row["at"] == "final"] == ["1", "1"]
    text = (out / "report.md").read_text()
    assert ("Picks from the **counter stream**" in text and "Ran: float counts on the GPU; exact counts (certified "
            "arithmetic) on the GPU, one replica at a time; N_e on the GPU." in text)


@pytest.mark.slow
def test_the_papers_sections_keep_their_xoshiro_bits_on_cuda(on_cuda, tmp_path):
    """Figures 1-8 on device "cuda": the specs, every replica's row and every check of device "cpu"."""
    out, _, results = on_cuda
    cpu_out = tmp_path / "cpu"
    rp.reproduce(cpu_out, workers=1, **TINY)
    cpu = json.loads((cpu_out / "results.json").read_text())
    assert (results["detail"], results["checks"]) == (cpu["detail"], cpu["checks"]) and cpu["device"] == "cpu"
    for spec in (cpu_out / "specs").iterdir():
        assert json.loads(spec.read_text())["scheduler"].get("stream", "xoshiro") == "xoshiro"
        assert (out / "specs" / spec.name).read_text() == spec.read_text()
    for name in PAPER_ENSEMBLES:
        table = "ensembles/" + name + "/replicas.csv"
        assert (out / table).read_text() == (cpu_out / table).read_text(), name


# ---------------------------------------------------------------- plans and their checks


class _Planned(Exception):
    """Raised in place of `check_extended_plan`: carries the plan `reproduce` chose."""


@pytest.fixture
def chosen_plan(monkeypatch, tmp_path):
    """``reproduce(...)``'s extended plan, stopped before anything runs."""
    import pinnedballs.run.reproduction.run as run

    def stop(plan):
        raise _Planned(plan)

    monkeypatch.setattr(run, "check_extended_plan", stop)

    def chosen(**kwargs) -> rp.ExtendedPlan:
        with pytest.raises(_Planned) as info:
            rp.reproduce(tmp_path / "x", **TINY, **kwargs)
        assert not (tmp_path / "x").exists()
        return info.value.args[0]

    return chosen


def test_cuda_runs_the_gpu_plan_and_any_plan_on_the_counter_stream(chosen_plan):
    assert chosen_plan(extended=True, device="cuda") == rp.EXTENDED_GPU
    assert chosen_plan(extended=True, quick=True, device="cuda") == dataclasses.replace(rp.EXTENDED_QUICK,
                                                                                        stream="counter")
    assert chosen_plan(extended=TINY_X, device="cuda") == dataclasses.replace(TINY_X, stream="counter")
    assert chosen_plan(extended=True) == rp.EXTENDED_FULL and rp.EXTENDED_FULL.stream == "xoshiro"
    assert chosen_plan(extended=True, quick=True) == rp.EXTENDED_QUICK and rp.EXTENDED_QUICK.stream == "xoshiro"


def test_a_gpu_counts_exactly_the_sizes_of_its_plan():
    """With ``device="cuda"``, the scaling study's certified ensembles of at least ``exact_gpu_min_balls`` balls run
    on the GPU, smaller ones on the CPU; float ones always on the GPU, the xoshiro stream never."""
    plan = dataclasses.replace(TINY_X, stream="counter", exact_gpu_min_balls=60)
    small, large = (ext.scaling_spec(*size, plan, arithmetic="certified") for size in ((10, 5), (20, 10)))
    assert (small.build().geometry.n_balls, large.build().geometry.n_balls) == (15, 60)
    assert [rp.run._runs_on_gpu(s, plan) for s in (small, large)] == [False, True]
    assert rp.run._runs_on_gpu(ext.scaling_spec(10, 5, plan), plan)
    assert not rp.run._runs_on_gpu(ext.scaling_spec(20, 10, TINY_X, arithmetic="certified"), TINY_X)  # xoshiro


def test_the_gpu_plan_fits_the_issue():
    """EXTENDED_FULL's sizes up to 1000x500, then 2000x1000 (8 replicas) and 4000x2000 (4): float and N_e at every
    size, the exact count where the CPU plan has it."""
    gpu, full = rp.EXTENDED_GPU, rp.EXTENDED_FULL
    assert gpu.scaling[:-2] == full.scaling[:-1] and gpu.scaling[-2:] == ((2000, 1000, 8), (4000, 2000, 4))
    largest = pb.HalfPlane.from_size(4000, 2000).n_balls
    assert largest == 2_310_000 and gpu.resolution_limit() >= largest > gpu.exact_max_balls == full.exact_max_balls
    assert gpu.stream == "counter" and ext.scaling_spec(4000, 2000, gpu).scheduler.threads == 1
    assert dataclasses.replace(gpu, scaling=full.scaling, resolution_max_balls=None, stream="xoshiro") == full
    for plan in (full, rp.EXTENDED_QUICK):  # CPU plans: N_e stops with the exact count, on the xoshiro stream
        assert plan.resolution_max_balls is None and plan.resolution_limit() == plan.exact_max_balls
        assert ext.scaling_spec(10, 5, plan).scheduler.stream == "xoshiro"
    ext.check_extended_plan(gpu)


def test_scaling_specs_draw_from_the_plans_stream():
    xoshiro = ext.scaling_spec(10, 5, rp.ExtendedPlan())
    counter = ext.scaling_spec(10, 5, rp.ExtendedPlan(stream="counter"), arithmetic="certified")
    assert (xoshiro.scheduler.stream, counter.scheduler.stream, counter.arithmetic) == ("xoshiro", "counter",
                                                                                         "certified")
    assert xoshiro.seed == counter.seed and xoshiro.geometry == counter.geometry


@pytest.mark.parametrize("field,bad,message", [
    ("stream", "philox", "stream: the scaling study's UniformRandomPair stream must be 'xoshiro' or 'counter', got "
                         "'philox'"),
    ("stream", None, "stream: the scaling study's UniformRandomPair stream must be 'xoshiro' or 'counter', got None"),
    *(("resolution_max_balls", bad, "resolution_max_balls: must be a whole number of balls >= 0 or None (up to "
                                    f"exact_max_balls), got {bad!r}") for bad in (-1, 1.5, True, "60")),
    *(("exact_gpu_min_balls", bad, f"exact_gpu_min_balls: must be a whole number of balls >= 0, got {bad!r}")
      for bad in (-1, 2.5, None)),
])
def test_bad_new_plan_fields_name_themselves(tmp_path, field, bad, message):
    plan = dataclasses.replace(TINY_X, **{field: bad})
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        ext.check_extended_plan(plan)
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        rp.reproduce(tmp_path / "x", extended=plan, **TINY)
    assert not (tmp_path / "x").exists()


def test_reproduce_refuses_an_unknown_device_before_writing(tmp_path):
    with pytest.raises(InputError, match=r"device: must be 'cpu' or 'cuda', got 'tpu'"):
        rp.reproduce(tmp_path / "x", device="tpu", **TINY)
    assert not (tmp_path / "x").exists()


# ---------------------------------------------------------------- the command line


def test_cli_passes_the_device_and_refuses_an_unknown_one(tmp_path, fake_reproduce, capsys):
    seen = fake_reproduce
    assert cli.main(["reproduce", "--out", str(tmp_path / "x"), "--extended", "--device", "cuda", "--quiet"]) == 0
    assert (seen["device"], seen["extended"]) == ("cuda", True)
    assert cli.main(["reproduce", "--out", str(tmp_path / "y"), "--quiet"]) == 0
    assert seen["device"] == "cpu"
    capsys.readouterr()
    assert cli.main(["reproduce", "--out", str(tmp_path / "z"), "--device", "tpu"]) == 2
    assert "invalid choice: 'tpu'" in capsys.readouterr().err and not (tmp_path / "z").exists()
