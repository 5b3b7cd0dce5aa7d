"""Issue 14's figures: ``kinegen explore`` on Dask against the same partitions measured in one process.

The excavator's calibration study (models/excavator.yaml: five parameters, the five working-range
figures and a boom-cylinder margin over the digging case), ``samples`` Sobol' variants in
partitions of ``partition_size``, measured three ways in one run:

* in this process, partition after partition, no Dask (:func:`kinegen.explore.run.run_in_process`);
* on a LocalCluster of 1 worker process, then of 2 (one per core), each written to Parquet as
  ``kinegen explore`` does.

The workers are warmed first (each loads the module and measures the nominal design once, as the
in-process baseline's evaluator already has): the figures are the steady state that 10^6 variants
run in. The workers' one-time set-up is reported beside them.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from kinegen.bench.contenders import ROOT


def exploration_scaling(samples: int = 144, partition_size: int = 24, rounds: int = 3) -> dict:
    """Seconds for ``samples`` variants in one process and on 1 and 2 Dask workers, each the
    median of ``rounds`` rounds (the three measured one after the other in every round: the
    machine's noise falls on all three alike)."""
    import statistics

    from dask.distributed import Client

    from kinegen.explore.run import Exploration, explore, local_cluster, nominal_evaluator, run_in_process, tasks
    from kinegen.explore.variants import evaluator_for

    exploration = Exploration(
        ROOT / "models" / "excavator.yaml", ROOT / "generated" / "excavator_quaternion.py", "calibration", samples, partition_size=partition_size
    )
    nominal_evaluator(exploration)  # the module loaded, the nominal measured, the C compiled
    warm = tasks(exploration, set())[0]
    times: dict[str, list[float]] = {"in_process": [], "workers_1": [], "workers_2": []}
    row: dict = {"samples": samples, "partition_size": partition_size, "rounds": rounds}
    for _ in range(rounds):
        start = time.perf_counter()
        direct = run_in_process(exploration)
        times["in_process"].append(time.perf_counter() - start)
        for workers in (1, 2):
            with local_cluster(workers, ":0") as cluster, Client(cluster) as client:
                setup = client.run(lambda task=warm: evaluator_for(task)[1])
                with tempfile.TemporaryDirectory() as folder:
                    report = explore(exploration, Path(folder) / "explore.parquet", client=client, progress=False)
                times[f"workers_{workers}"].append(report.seconds)
                row[f"setup_{workers}"] = max(setup.values())
    row.update({key: statistics.median(values) for key, values in times.items()})
    row["all"] = times
    row["statuses"] = {s: sum(r.statuses.get(s, 0) for r in direct) for s in ("ok", "unreachable", "singular", "failed")}
    return row
