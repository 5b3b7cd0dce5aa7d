"""What the forces cost (issue 28): the forces that hold the excavator's loads along its digging
cycle against the compiled trajectory solve they follow, and the ISO 6015 tool forces."""

from __future__ import annotations

from pathlib import Path

MODELS = Path(__file__).resolve().parents[2] / "models"


def force_cost(points: int = 1000, repeats: int = 3) -> dict:
    """Best of ``repeats``, in seconds: the compiled trajectory solve of the excavator's digging case
    (``points`` time points); the forces holding its payload and cutting loads at those points, by the
    compiled force solve (``kinegen_forces``: multipliers and element forces; ``compiled_dynamics``: with
    the bodies' weight and inertia, inverse dynamics) and by
    :func:`kinegen.forces.forces` (also every reaction and pressure); ``kinegen forces`` (the ISO 6015
    tool forces), the tangent force map (10,625 poses) and the hydraulic lift chart, all compiled."""
    import time

    import numpy as np

    from kinegen.api import Session
    from kinegen.forces import forces
    from kinegen.forces.iso6015 import tool_forces
    from kinegen.forces.lift import lift_chart
    from kinegen.forces.maps import force_map
    from kinegen.runtime import solve

    session = Session(Path(__file__).resolve().parents[2] / "generated")
    model_file = MODELS / "excavator.yaml"
    model = session.model(model_file)
    system = session.system(model_file, "digging")
    times = np.linspace(system.t0, system.t1, points)
    results = solve(system, times)  # warm: compilation, first calls
    forces(results, model, ["payload", "cutting"])
    tool_forces(system, model)
    force_map(system, model, "tangent")
    lift_chart(system, model)
    weights = np.array([float(name in ("payload", "cutting")) for name in system.statics.load_names])
    best = dict.fromkeys(("solve", "compiled_forces", "compiled_dynamics", "forces", "tool_forces", "map", "lift"), float("inf"))
    for _ in range(repeats):
        start = time.perf_counter()
        results = solve(system, times)
        laps = {"solve": time.perf_counter() - start}
        for name, run in (("compiled_forces", lambda r=results: system.native.forces(r.times, r.q, r.inputs, weights)),
                          ("compiled_dynamics", lambda r=results: system.native.forces(r.times, r.q, r.inputs, weights, (r.v, r.a))),
                          ("forces", lambda results=results: forces(results, model, ["payload", "cutting"])), ("tool_forces", lambda: tool_forces(system, model)),
                          ("map", lambda: force_map(system, model, "tangent")), ("lift", lambda: lift_chart(system, model))):  # fmt: skip
            start = time.perf_counter()
            run()
            laps[name] = time.perf_counter() - start
        best = {name: min(best[name], laps[name]) for name in best}
    return {**best, "points": points, "poses": 25 * 17 * 25}
