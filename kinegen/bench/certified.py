"""What the step certificate costs (issue 25): the excavator's smooth cases solved by the compiled
C loop with every step certified (the default) and without the certificate
(``keep_branch=False``), alternating in one process, and whether any step was subdivided. Issue 38:
also certified along the cubic Hermite path of the case's samples (its inputs given as a table, the
certificate's assumption before the case's own time functions were enclosed over each step), so
that what enclosing them costs is measured in the same run."""

from __future__ import annotations

import statistics
import time

import numpy as np

from kinegen.bench.contenders import ROOT
from kinegen.runtime import Solver, SolverOptions, from_module, load_module


def certificate_cost(cases: tuple[str, ...] = ("digging", "level_cut"), repeats: int = 9, points: int = 1000) -> dict:
    """Per case: the median certified, uncertified and sampled (certified along the samples' cubic
    path) trajectory times [s] on ``points`` time points, the ratios certified / uncertified and
    certified / sampled, and ``subdivided``: whether any step was halved (the rows differ from a
    solve allowed no halving)."""
    module = load_module(ROOT / "generated" / "excavator_quaternion.py", ROOT / "models" / "excavator.yaml")
    out = {}
    for case in cases:
        system = from_module(module, case)
        times = np.linspace(system.t0, system.t1, points)
        certified, plain = Solver(system), Solver(system, SolverOptions(keep_branch=False))
        table = system.driver_inputs(times)
        seconds: dict[str, list[float]] = {"certified": [], "plain": [], "sampled": []}
        for _ in range(repeats):
            for name, solver in (("certified", certified), ("plain", plain), ("sampled", certified)):
                start = time.perf_counter()
                solved = solver.solve(times, inputs=table if name == "sampled" else None)
                seconds[name].append(time.perf_counter() - start)
                if name == "certified":
                    certified_q = solved.q
        whole = Solver(system, SolverOptions(max_refinements=0)).solve(times)
        medians = {name: statistics.median(values) for name, values in seconds.items()}
        out[case] = {**medians, "ratio": medians["certified"] / medians["plain"], "enclosed": medians["certified"] / medians["sampled"],
                     "subdivided": not np.array_equal(certified_q, whole.q)}  # fmt: skip
    return out
