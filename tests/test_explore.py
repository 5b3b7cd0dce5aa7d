"""kinegen explore: sampling, the measured variants against independent references, and runs on a
real Dask LocalCluster (2 worker processes; a worker killed mid-run; an interrupted run resumed)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dask.distributed", reason="kinegen explore needs Dask: pip install 'kinegen[explore]'")
pytest.importorskip("pyarrow", reason="kinegen explore needs pyarrow: pip install 'kinegen[explore]'")

import pyarrow.parquet as pq
from dask.distributed import Client

from kinegen.errors import ExitCode
from kinegen.explore.plots import pareto_front, ranking
from kinegen.explore.run import Exploration, explore, local_cluster, run_in_process, sample
from kinegen.explore.store import ExplorationError, Store
from tests.conftest import GENERATED, MODELS, ROOT

MODEL = MODELS / "excavator.yaml"
MODULE = GENERATED / "excavator_quaternion.py"


def identical(a, b) -> bool:
    """Two tables with the same columns holding the same values, floats bit for bit (NaN included)."""
    if a.schema != b.schema or a.num_rows != b.num_rows:
        return False
    for name in a.column_names:
        x, y = a.column(name).to_numpy(zero_copy_only=False), b.column(name).to_numpy(zero_copy_only=False)
        if x.dtype == np.float64:
            x, y = x.view(np.int64), y.view(np.int64)
        if not np.array_equal(x, y):
            return False
    return True


def calibration(samples: int = 40, partition_size: int = 8, **kw) -> Exploration:
    return Exploration(MODEL, MODULE, "calibration", samples, partition_size=partition_size, **kw)


# ---- sampling, front and ranking against brute force / known answers ------------------------------------
def test_samples_are_seeded_and_in_bounds() -> None:
    lower, upper = np.array([1.0, -2.0, 0.5]), np.array([2.0, -1.0, 0.75])
    for sampler in ("sobol", "lhs"):
        a, b = sample(lower, upper, 100, sampler, seed=3), sample(lower, upper, 100, sampler, seed=3)
        assert np.array_equal(a, b)
        assert not np.array_equal(a, sample(lower, upper, 100, sampler, seed=4))
        assert (a >= lower).all() and (a <= upper).all()
    # a Latin hypercube has exactly one point in each of the 100 strata of every parameter
    unit = (sample(lower, upper, 100, "lhs", seed=1) - lower) / (upper - lower)
    for column in unit.T:
        assert sorted(np.floor(column * 100).astype(int)) == list(range(100))
    # a Sobol' prefix is the start of the longer sample with the same seed
    assert np.array_equal(sample(lower, upper, 37, "sobol", 5), sample(lower, upper, 64, "sobol", 5)[:37])


def test_pareto_front_is_the_brute_force_set() -> None:
    rng = np.random.default_rng(7)
    x, y = rng.normal(size=300), rng.normal(size=300)
    x[:20] = np.round(x[:20], 1)  # ties
    for maximize in ((True, True), (True, False), (False, False)):
        sx, sy = (1 if maximize[0] else -1) * x, (1 if maximize[1] else -1) * y
        dominated = [bool(np.any((sx >= sx[i]) & (sy >= sy[i]) & ((sx > sx[i]) | (sy > sy[i])))) for i in range(len(x))]
        assert set(pareto_front(x, y, maximize).tolist()) == {i for i in range(len(x)) if not dominated[i]}


def test_ranking_recovers_a_known_linear_law() -> None:
    rng = np.random.default_rng(0)
    p = {"a": rng.uniform(0, 1, 500), "b": rng.uniform(0, 10, 500), "c": rng.uniform(-1, 1, 500)}
    y = 3 * p["a"] - 0.2 * p["b"] + 0.0 * p["c"]
    result = ranking(p, {"y": y, "flat": np.full(500, 0.157)})
    np.testing.assert_allclose(result.slope[0], [3, -0.2, 0], atol=1e-12)
    expected = np.array([3 * p["a"].std(), -0.2 * p["b"].std(), 0]) / y.std()
    np.testing.assert_allclose(result.src[0], expected, atol=1e-12)
    assert result.r2[0] == pytest.approx(1.0)
    assert np.isnan(result.r2[1]) and "constant" in result.table()


# ---- the measured variants -------------------------------------------------------------------------------
def test_variants_match_working_ranges_sampled_afresh_and_their_slopes_the_exact_sensitivities() -> None:
    """Each variant's figures (refined from the nominal optima) against a working range sampled and
    refined from scratch at that design; the sample's regression slopes against the figures' exact
    sensitivities at the nominal design (envelope theorem) -- nearly linear over the +-2 cm box."""
    from kinegen.analysis.envelope import figure_sensitivities, working_range
    from kinegen.model import load
    from kinegen.runtime import from_module, load_module

    exploration = calibration(samples=32, partition_size=16)
    results = run_in_process(exploration)
    assert [r.partition for r in results] == [0, 1]
    model, module = load(MODEL), load_module(MODULE, MODEL)
    spec = model.working_range
    names = list(results[0].parameters)
    parameters = {n: np.concatenate([r.parameters[n] for r in results]) for n in names}
    figures = {f: np.concatenate([r.quantities[f] for r in results]) for f in results[0].quantities}
    status = np.concatenate([r.status for r in results])
    assert set(status) <= {"ok", "unreachable", "singular", "failed"}
    checked = 0
    for k in np.flatnonzero(status == "ok"):
        design = {n: float(parameters[n][k]) for n in names}
        if abs(design["boom_retracted"] - 1.7352) > 0.02:  # near the boom cylinder's toggle a fresh grid is unreliable
            continue
        fresh = working_range(from_module(module, spec.case, True, design), spec)
        compared = [figure for figure in fresh.figures if figure in figures]  # the study's five
        assert len(compared) == 5
        for figure in compared:
            assert figures[figure][k] == pytest.approx(fresh.figures[figure], abs=1e-9), (k, figure)
        checked += 1
        if checked == 3:
            break
    assert checked == 3
    ok = status == "ok"
    result = ranking({n: parameters[n][ok] for n in names}, {f: figures[f][ok] for f in spec.published})
    system = from_module(module, spec.case, True)
    exact = figure_sensitivities(working_range(system, spec), system)
    order = list(system.design)
    for i, figure in enumerate(result.quantities):
        gradient = np.array([exact[figure][order.index(n)] for n in names])
        scale = np.abs(gradient).max()
        assert np.abs(result.slope[i] - gradient).max() < 0.05 * scale, (figure, result.slope[i], gradient)


def test_status_says_unreachable_exactly_where_the_boom_cylinder_cannot_retract_that_far() -> None:
    """The boom cylinder joins B (on the upper structure) and C (on the boom), which turn about A:
    it cannot be shorter than |AC| - |AB|. A retracted length below that is unreachable, one
    1 cm above it is measured."""
    from kinegen.explore.variants import VariantEvaluator
    from kinegen.model import load

    model = load(MODEL)
    evaluator = VariantEvaluator(str(MODEL), str(MODULE), __import__("hashlib").sha256(MODEL.read_bytes()).hexdigest(), "calibration", True)
    upper, boom = (next(body for body in model.bodies if body.name == name) for name in ("upper", "boom"))
    a, b = (np.array([float(x) for x in upper.points[n]]) for n in ("A", "B_left"))
    assert [float(x) for x in boom.points["A"]] == [0, 0, 0]  # the boom's frame is at A
    c_x, c_z = 1.41283, 2.021922  # C at the upper ends of its bounds, at the same y as B
    shortest = np.hypot(c_x, c_z) - np.hypot(*(b - a)[[0, 2]])  # |AC| - |AB| in the plane of the boom
    assert 1.6852 < shortest < 1.7852
    f_x, f_z = -0.786562, -0.369691
    status, message, values = evaluator.evaluate(np.array([c_x, c_z, f_x, f_z, shortest - 0.005]))
    assert status == "unreachable" and "cannot be measured" in message and np.isnan(values["max_depth"])
    status, message, values = evaluator.evaluate(np.array([c_x, c_z, f_x, f_z, shortest + 0.01]))
    assert (status, message) == ("ok", "") and np.isfinite(values["max_depth"])


# ---- on a real LocalCluster ------------------------------------------------------------------------------
#: the tests that read the one-worker run run in one test process (make test distributes with --dist
#: loadgroup), so that its 40 variants (~9 s) are measured once, and the two-worker cluster is started once
CLUSTER_GROUP = pytest.mark.xdist_group(name="explore_cluster")


@pytest.fixture(scope="module")
def two_workers():
    """A real LocalCluster of two worker processes and its client, shared by the tests that need two
    (a worker killed there is restarted by its nanny: the cluster has two again)."""
    with local_cluster(2, ":0") as cluster, Client(cluster) as client:
        yield client


@pytest.fixture(scope="module")
def one_worker_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("explore") / "one.parquet"
    with local_cluster(1, ":0") as cluster, Client(cluster) as client:
        report = explore(calibration(), out, client=client, progress=False)
    assert report.workers == 1 and report.computed == 5
    return out


@CLUSTER_GROUP
def test_two_workers_end_to_end_give_the_one_worker_parquet(one_worker_run: Path, two_workers, tmp_path: Path) -> None:
    out, client = tmp_path / "two.parquet", two_workers
    client.wait_for_workers(2, timeout=120)  # (after the kill test, until the nanny's new worker is in)
    report = explore(calibration(), out, client=client, progress=False)
    workers = {r["name"] for r in client.scheduler_info()["workers"].values()}
    assert report.workers == 2 and len(workers) == 2
    assert report.computed == 5 and report.variants == 40
    one, two = Store(one_worker_run).read(), Store(out).read()
    assert identical(one, two)
    assert one.column("variant").to_pylist() == list(range(40))
    status = one.column("status").to_pylist()
    assert sum(report.statuses.values()) == 40 and report.statuses["ok"] == status.count("ok") > 30
    for name in ("max_reach", "max_depth"):  # an ok variant has every quantity, any other NaN and a message
        values = one.column(name).to_numpy()
        assert all(np.isfinite(v) == (s == "ok") for v, s in zip(values, status))
    for s, message in zip(status, one.column("message").to_pylist()):
        assert (message == "") == (s == "ok")
    # provenance: in the folder and in every part
    provenance = Store(out).provenance()
    assert provenance["seed"] == 0 and provenance["samples"] == 40 and provenance["study"] == "calibration"
    assert b"kinegen" in pq.read_schema(out / "part-000000.parquet").metadata


@CLUSTER_GROUP
def test_a_worker_killed_mid_run_is_survived(one_worker_run: Path, two_workers, tmp_path: Path) -> None:
    out, client = tmp_path / "killed.parquet", two_workers
    killed: list[int] = []
    client.wait_for_workers(2, timeout=120)
    pids = client.run(os.getpid)

    def kill_one(_result) -> None:
        if killed:
            return
        busy = [address for address, keys in client.processing().items() if keys]
        victim = pids[busy[0]] if busy else next(iter(pids.values()))
        os.kill(victim, signal.SIGKILL)  # a real kill of a worker process in the middle of a task
        killed.append(victim)

    report = explore(calibration(), out, client=client, progress=False, on_partition=kill_one)
    client.wait_for_workers(2, timeout=120)
    after = set(client.run(os.getpid).values())
    assert killed and killed[0] not in after  # the nanny started a new worker process
    assert report.computed == 5
    table = Store(out).read()
    assert table.column("variant").to_pylist() == list(range(40))  # every variant exactly once
    assert identical(table, Store(one_worker_run).read())


def _interruptible() -> None:
    """In the child before it runs: Ctrl-C's default action, as on a terminal. A test run started in
    the background of a non-interactive shell (``pytest ... &``) ignores SIGINT, and so would the
    command it starts: Python then installs no KeyboardInterrupt, and the run wrote all 40 partitions."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@CLUSTER_GROUP
def test_resume_after_an_interrupted_run_computes_only_the_missing_partitions(one_worker_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "resumed.parquet"
    command = [sys.executable, "-m", "kinegen.cli", "explore", str(MODEL), "--study", "calibration", "--samples", "40",
               "--partition-size", "1", "--workers", "1", "--out", str(out)]  # fmt: skip
    # 40 partitions of one variant: after the third, 37 are left to outrun the Ctrl-C below (with 10
    # of 4, a loaded machine wrote the last 7 before the interrupt took effect, 3 times in a row)
    environment = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    for _attempt in range(3):  # on a loaded machine this test may sleep until the run wrote every partition: again
        shutil.rmtree(out, ignore_errors=True)
        run = subprocess.Popen(command, cwd=ROOT, env=environment, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=_interruptible)  # fmt: skip
        deadline = time.monotonic() + 120
        while len(Store(out).done()) < 3 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        if run.poll() is None:
            run.send_signal(signal.SIGINT)  # as Ctrl-C
        run.communicate(timeout=60)
        if len(Store(out).done()) < 40:
            break
    assert len(Store(out).done()) < 40, "every partition was written before the run could be interrupted, 3 times"
    assert run.returncode != 0
    written = {i: (out / f"part-{i:06d}.parquet").stat() for i in Store(out).done()}
    assert 3 <= len(written) < 40
    # a new run into the same folder without --resume loses nothing: it is refused
    refused = subprocess.run(command, cwd=ROOT, env=environment, capture_output=True, text=True)
    assert refused.returncode == ExitCode.EXPLORATION and "--resume" in refused.stderr
    # resumed with the settings it recorded, and the plot
    plot = tmp_path / "front.png"
    resumed = subprocess.run(
        [*command[:7], "--out", str(out), "--resume", "--workers", "2", "--plot", str(plot), "--pareto", "max_reach", "--pareto", "max_depth"],
        cwd=ROOT, env=environment, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(written)} of 40 partitions already written" in resumed.stderr
    assert f"{40 - len(written)} variants in {40 - len(written)} partitions" in resumed.stdout
    for i, stat in written.items():  # the partitions written before were not computed again
        now = (out / f"part-{i:06d}.parquet").stat()
        assert (now.st_ino, now.st_mtime_ns) == (stat.st_ino, stat.st_mtime_ns)
    # other partitioning, same variants: the same table as the uninterrupted 1-worker run
    assert identical(Store(out).read(), Store(one_worker_run).read())
    assert plot.stat().st_size > 10_000 and "sensitivity ranking" in resumed.stdout


@CLUSTER_GROUP
def test_a_folder_of_another_run_is_not_resumed_or_overwritten(one_worker_run: Path) -> None:
    with pytest.raises(ExplorationError, match="seed: 0 there, 1 now"):
        explore(calibration(seed=1), one_worker_run, resume=True, progress=False)
    with pytest.raises(ExplorationError, match="already holds an exploration"):
        explore(calibration(), one_worker_run, progress=False)
    # resumed with the same settings and nothing missing: nothing computed, no cluster started
    report = explore(calibration(), one_worker_run, resume=True, progress=False)
    assert report.computed == 0 and report.already == 5 and report.workers == 0


@CLUSTER_GROUP
def test_the_readmes_one_liner_reads_the_parquet_folder_with_what_kinegen_explore_installs(one_worker_run: Path) -> None:
    """docs/studies.md's pyarrow line, as printed (its folder swapped for this run's), reads every variant."""
    import re
    import subprocess
    import sys

    readme = (Path(__file__).resolve().parents[1] / "docs" / "studies.md").read_text()
    snippet = re.search(r'`python -c "(import pyarrow\.dataset[^"]+)"`', readme).group(1)
    code = snippet.replace("out/excavator_calibration.parquet", str(one_worker_run)).replace("to_table())", "to_table().num_rows)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == sum(len(pq.read_table(part)) for part in one_worker_run.glob("part-*.parquet")) > 0
