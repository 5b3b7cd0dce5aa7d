"""What the fastest cycle costs (issue 40): the excavator's digging path on 1,000 points, compiled --
its solve, then ``kinegen.forces.cycle.fastest`` (the limits along it from three force solves per
point, the tipping margin's parts, the reachability analysis with the engine's power) -- and one
``cycle_time`` with its exact gradient by every design parameter on the case's own grid (the solve
included, as a study measures it); each the median of repeated runs in one process."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def cycle_cost(repeats: int = 5, points: int = 1000) -> dict:
    """Median seconds of the compiled path solve and of its re-timing, with the cycle time found."""
    from kinegen.api import Session
    from kinegen.forces.cycle import fastest
    from kinegen.runtime import solve

    session = Session(ROOT / "generated")
    model_file = ROOT / "models" / "excavator.yaml"
    model = session.model(model_file)
    system = session.system(model_file, "digging", "quaternion", compiled=True)  # the module with sensitivity kernels
    times = np.linspace(system.t0, system.t1, points)
    solves, retimings, found = [], [], None
    for _ in range(repeats):
        start = time.perf_counter()
        path = solve(system, times)
        middle = time.perf_counter()
        found = fastest(path, model, ("payload",))
        retimings.append(time.perf_counter() - middle)
        solves.append(middle - start)
    from kinegen.forces.cycle import cycle_time

    grid = solve(system)  # the case's own grid, as a study measures it
    with_gradient = []
    for _ in range(repeats):
        start = time.perf_counter()
        cycle_time(solve(system), model, ("payload",))
        with_gradient.append(time.perf_counter() - start)
    return {"points": points, "solve": statistics.median(solves), "retiming": statistics.median(retimings), "cycle_time": found.duration,
            "gradient_points": len(grid.times), "with_gradient": statistics.median(with_gradient), "parameters": len(system.design)}
