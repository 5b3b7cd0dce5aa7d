"""What the forces cost (issue 28): the forces that hold the excavator's loads along its digging
cycle against the compiled trajectory solve they follow, and the ISO 6015 tool forces."""

from __future__ import annotations

from pathlib import Path

MODELS = Path(__file__).resolve().parents[2] / "models"


def force_cost(points: int = 1000, repeats: int = 3) -> dict:
    """Best of ``repeats``, in seconds: the compiled trajectory solve of the excavator's digging case
    (``points`` time points), the forces holding its payload and cutting loads at those points, and
    ``kinegen forces`` (the ISO 6015 tool forces, compiled)."""
    import time

    import numpy as np

    from kinegen.api import Session
    from kinegen.forces import forces
    from kinegen.forces.iso6015 import tool_forces
    from kinegen.runtime import solve

    session = Session(Path(__file__).resolve().parents[2] / "generated")
    model_file = MODELS / "excavator.yaml"
    model = session.model(model_file)
    system = session.system(model_file, "digging")
    times = np.linspace(system.t0, system.t1, points)
    results = solve(system, times)  # warm: compilation, first calls
    forces(results, model, ["payload", "cutting"])
    tool_forces(system, model)
    best = {"solve": float("inf"), "forces": float("inf"), "tool_forces": float("inf")}
    for _ in range(repeats):
        start = time.perf_counter()
        results = solve(system, times)
        middle = time.perf_counter()
        forces(results, model, ["payload", "cutting"])
        end = time.perf_counter()
        tool_forces(system, model)
        best = {"solve": min(best["solve"], middle - start), "forces": min(best["forces"], end - middle),
                "tool_forces": min(best["tool_forces"], time.perf_counter() - end)}  # fmt: skip
    return {**best, "points": points}
