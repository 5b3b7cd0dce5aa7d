"""Running an exploration on Dask (``kinegen explore``).

The client samples the study's parameters in their bounds (:func:`sample`), cuts the variants
into partitions of ``partition_size`` and submits one task per partition not yet on disk
(:func:`kinegen.explore.variants.evaluate_partition`); as each task finishes, the client writes
its partition (:class:`kinegen.explore.store.Store`). Dask's scheduler re-runs the tasks of a
worker that dies; a partition is written only by the client, once, when its task's result
arrives, so every variant is measured and written exactly once per run.

Without a scheduler address the run starts a ``LocalCluster`` with one single-threaded worker
process per core (BLAS threads 1: Dask's default environment for worker processes). With
``scheduler="tcp://host:8786"`` it connects to a running cluster (``dask scheduler`` /
``dask worker``, dask-jobqueue on SLURM/PBS, dask-kubernetes): the workers import kinegen and
read the model file and its generated module at the same paths as the client (a shared file
system, or the same checkout in every image).
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from kinegen import __version__
from kinegen.errors import KinegenError
from kinegen.explore.store import ExplorationError, Store
from kinegen.explore.variants import STATUSES, PartitionResult, PartitionTask, VariantEvaluator, evaluate_partition, evaluator

SAMPLERS = ("sobol", "lhs")
#: variants per task unless told: ~20 s of work for the excavator's calibration study (0.1 s a
#: variant), long beside Dask's few milliseconds per task, short enough to lose little to a crash
PARTITION_SIZE = 200


def sample(lower: np.ndarray, upper: np.ndarray, count: int, sampler: str = "sobol", seed: int = 0) -> np.ndarray:
    """``count`` points in the box [lower, upper] (one row each): scrambled Sobol' or Latin
    hypercube (:mod:`scipy.stats.qmc`), seeded -- the same arguments give the same points.
    (A Sobol' sample is best balanced for a power of two; any count is a valid prefix.)"""
    from scipy.stats import qmc

    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if sampler == "sobol":
        engine = qmc.Sobol(len(lower), scramble=True, rng=seed)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
            unit = engine.random(count)
    elif sampler == "lhs":
        unit = qmc.LatinHypercube(len(lower), rng=seed).random(count)
    else:
        raise ValueError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    return qmc.scale(unit, lower, upper)


@dataclass(frozen=True)
class Exploration:
    """What a run explores: a study of a model, through one generated module, on sampled variants."""

    model_file: Path
    module_file: Path
    study: str
    samples: int
    sampler: str = "sobol"
    seed: int = 0
    partition_size: int = PARTITION_SIZE
    compiled: bool = True  #: measure with the module's compiled C (False: its Python functions)

    def partitions(self) -> int:
        return -(-self.samples // self.partition_size)


@dataclass
class Report:
    """What a run did."""

    out: Path
    partitions: int  #: in the whole exploration
    already: int  #: found on disk (resumed)
    computed: int  #: computed by this run
    variants: int  #: variants computed by this run
    seconds: float  #: from the first task submitted to the last partition written
    statuses: dict[str, int] = field(default_factory=dict)  #: over every variant on disk
    workers: int = 0
    dashboard: str | None = None
    task_seconds: float = 0.0  #: the workers' summed time in the tasks (module loading excluded)
    setup_seconds: float = 0.0  #: the workers' summed time loading the module and the nominal design

    @property
    def rate(self) -> float:
        """Variants per second of this run (wall clock)."""
        return self.variants / self.seconds if self.seconds > 0 else float("nan")

    def summary(self) -> str:
        statuses = ", ".join(f"{self.statuses.get(s, 0)} {s}" for s in STATUSES if self.statuses.get(s))
        resumed = f" ({self.already} already on disk)" if self.already else ""
        lines = [f"{self.out}: {self.already + self.computed} of {self.partitions} partitions{resumed}; variants: {statuses or 'none'}"]
        if self.computed:
            lines.append(
                f"  this run: {self.variants} variants in {self.computed} partitions on {self.workers} workers, "
                f"{self.seconds:.1f} s ({self.rate:.1f} variants/s)"
            )
        return "\n".join(lines)


def parameter_unit(description: str) -> str:
    """A design parameter's unit as its description states it first ("... (m; ...)", "(kg; ESTIMATED)");
    without one, the geometry's (m for lengths, rad for angles)."""
    import re

    found = re.search(r"\((kg|rad|deg|MPa|Pa|N m|N|m)\b", description)
    return found.group(1) if found else "m or rad"


def provenance(exploration: Exploration, nominal: VariantEvaluator) -> dict:
    """What fixes the variants and their numbers (checked on ``--resume``), and when the run began."""
    problem = nominal.problem
    module = problem.module
    return {
        "model": module.MODEL,
        "model_file": str(exploration.model_file),
        "source_sha256": module.SOURCE_SHA256,
        "parametrization": module.PARAMETRIZATION,
        "study": exploration.study,
        "parameters": {n: [float(lo), float(hi)] for n, (lo, hi) in zip(problem.names, problem.bounds)},
        "quantities": nominal.columns,
        # what the study says of each quantity it ranks (its objective's terms): the plot's "larger is better" only there
        "senses": {t.quantity.label: ("target" if t.target is not None else problem.study.sense) for t in problem.study.terms},
        "units": {d.name: parameter_unit(d.description) for d in problem.model.design if d.name in problem.names},
        "sampler": exploration.sampler,
        "seed": exploration.seed,
        "samples": exploration.samples,
        "partition_size": exploration.partition_size,
        "solver": "C" if exploration.compiled else "Python",
        "kinegen_version": __version__,
        "nominal": {"parameters": dict(zip(problem.names, (problem.nominal_design[n] for n in problem.names))), "quantities": nominal.nominal},
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def tasks(exploration: Exploration, skip: set[int]) -> list[PartitionTask]:
    """One task per partition not in ``skip``, each with its variants' parameter values."""
    problem = nominal_evaluator(exploration).problem
    points = sample(problem.bounds[:, 0], problem.bounds[:, 1], exploration.samples, exploration.sampler, exploration.seed)
    size = exploration.partition_size
    source, study, compiled = problem.module.SOURCE_SHA256, exploration.study, exploration.compiled
    model_file, module_file = str(exploration.model_file), str(exploration.module_file)
    return [
        PartitionTask(model_file, module_file, source, study, compiled, i, i * size, points[i * size : (i + 1) * size])
        for i in range(exploration.partitions())
        if i not in skip
    ]


def nominal_evaluator(exploration: Exploration) -> VariantEvaluator:
    """The client's evaluator (the nominal design measured; the C compiled into the cache the
    local workers then load)."""
    from kinegen.model.loader import source_digest

    source = source_digest(exploration.model_file)  # what the module records (checked)
    return evaluator(str(exploration.model_file), str(exploration.module_file), source, exploration.study, exploration.compiled)[0]


#: Dask settings of the LocalCluster's workers. Dask's default environment sets glibc's
#: MALLOC_TRIM_THRESHOLD_ to 64 KiB (to hand memory back to the system); in the worker's task
#: thread that made the measurement's many small NumPy arrays 15-20 % slower (72 calibration
#: variants in a thread: 8.4-9.4 s without, 10.1-10.6 s with). The statistical profiler (10 ms)
#: and the event loop's monitors (20-500 ms) are slowed to 1 s: tasks here take seconds.
#: BLAS stays single-threaded (one worker process per core).
WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ": {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "1s",
}


def local_cluster(workers: int | None = None, dashboard_address: str = ":8787"):
    """A ``LocalCluster`` of ``workers`` single-threaded worker processes (default: one per core),
    configured for kinegen's tasks (:data:`WORKER_CONFIG`)."""
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set(WORKER_CONFIG):
        return LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True, dashboard_address=dashboard_address)


def explore(
    exploration: Exploration,
    out: str | Path,
    *,
    resume: bool = False,
    client=None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool | None = None,
    say: Callable[[str], None] | None = None,
    on_partition: Callable[[PartitionResult], None] | None = None,
) -> Report:
    """Measure every variant of ``exploration`` not yet in ``out`` on Dask and write them there.

    ``client``: a ``dask.distributed.Client`` to use (kept open); else one for ``scheduler``
    (an address), else a new ``LocalCluster`` of ``workers`` processes (default: one per core),
    both closed at the end. ``progress``: a progress bar on stderr (None: when it is a terminal).
    ``say``: where the run's lines go (the dashboard's address, what is resumed).
    ``on_partition``: called with each partition's result after it is written."""
    say = say or (lambda _line: None)
    store = Store(out)
    meta = provenance(exploration, nominal_evaluator(exploration))
    done = store.start(meta, resume)
    if resume and done:
        say(f"resuming {store.path}: {len(done)} of {exploration.partitions()} partitions already written")
    todo = tasks(exploration, set(done))
    report = Report(store.path, exploration.partitions(), len(done), 0, 0, 0.0)
    if todo:
        _run(todo, store, meta, report, client, scheduler, workers, progress, say, on_partition)
    report.statuses = _statuses(store)
    return report


def _run(todo, store, meta, report, client, scheduler, workers, progress, say, on_partition) -> None:
    from dask.distributed import Client, as_completed

    from kinegen.progress import counter

    own = []
    if client is None:
        if scheduler:
            client = Client(scheduler)
        else:
            cluster = local_cluster(workers)
            own.append(cluster)
            client = Client(cluster)
        own.insert(0, client)
    try:
        report.workers = len(client.scheduler_info().get("workers", {}))
        report.dashboard = client.dashboard_link
        say(f"Dask: {report.workers} workers, dashboard {report.dashboard}")
        token = meta["source_sha256"][:8]
        start = time.perf_counter()
        futures = [client.submit(evaluate_partition, task, key=f"kinegen-explore-{meta['study']}-{token}-{task.partition:06d}", retries=2)
                   for task in todo]  # fmt: skip
        total = sum(len(t.samples) for t in todo)
        with counter("explore", total, "variant", show=progress, leave=True) as bar:
            for future, result in as_completed(futures, with_results=True):
                store.write(result, meta)
                future.release()
                report.computed += 1
                report.variants += len(result.variant)
                report.task_seconds += result.seconds
                report.setup_seconds += result.worker_setup_seconds
                bar.update(len(result.variant))
                if on_partition is not None:
                    on_partition(result)
        report.seconds = time.perf_counter() - start
    except KinegenError:
        raise
    except Exception as exc:  # a task that failed on a worker: its error, with what is kept
        raise ExplorationError(f"the exploration stopped ({type(exc).__name__}: {exc}); the partitions written so far are kept -- rerun with --resume") from exc
    finally:
        for thing in own:
            thing.close()


def _statuses(store: Store) -> dict[str, int]:
    import pyarrow.compute as pc

    if not store.done():
        return {}
    counts = pc.value_counts(store.read(["status"]).column("status")).to_pylist()
    return {c["values"]: c["counts"] for c in counts}


def run_in_process(exploration: Exploration, partitions: list[int] | None = None) -> list[PartitionResult]:
    """The same partitions measured here, one after the other, without Dask: the baseline of
    the benchmark's Dask overhead."""
    todo = tasks(exploration, set())
    if partitions is not None:
        todo = [t for t in todo if t.partition in partitions]
    return [evaluate_partition(task) for task in todo]
