"""The shipped excavator with more design parameters, for the benchmark of sensitivities.

models/excavator.yaml has twelve design parameters (the boom- and arm-cylinder rod pins C and F,
the boom cylinder's retracted length, the two bucket-linkage lengths, the bucket-link pin K, the
bucket cylinder's bore and the counterweight's mass and position); the benchmark adds the
arm-cylinder base D on the boom (x, z; ±2 cm): fourteen, ten of them in the geometry (one an
actuator's range, one a bore, two masses). At the nominal
values the model is the shipped one, number for number.
"""

from __future__ import annotations

from pathlib import Path

EXCAVATOR = Path(__file__).resolve().parents[2] / "models" / "excavator.yaml"
BOUND = 0.02  # m either side of the nominal value
#: text of models/excavator.yaml -> the same with design parameters D_x, D_z
_PIN = ("D: [2.2875, 0, 2.785]", "D: [D_x, 0, D_z]")


def excavator_design_yaml() -> str:
    """models/excavator.yaml with the arm-cylinder base D (x, z) as design parameters too."""
    text = EXCAVATOR.read_text()
    plain, symbolic = _PIN
    if text.count(plain) != 1 or "\ndesign:\n" not in text:
        raise ValueError(f"models/excavator.yaml changed: {plain!r} is not there exactly once, or it has no design: section")
    extra = "".join(
        f"  {name}: {{nominal: {value}, bounds: [{float(value) - BOUND:.6f}, {float(value) + BOUND:.6f}]}}\n"
        for name, value in (("D_x", "2.2875"), ("D_z", "2.785"))
    )
    return text.replace(plain, symbolic).replace("\ndesign:\n", "\ndesign:\n" + extra, 1)


def sensitivity_cost(case: str = "digging", points: int = 1000, repeats: int = 3) -> dict:
    """Issue 13's figure: the trajectory solve of ``case`` (``points`` time points) of the
    excavator with fourteen design parameters, compiled and pure Python, and its sensitivities by
    all of them (dq/dp, dv/dp, da/dp), best of ``repeats`` each, in seconds; and the build time."""
    import tempfile
    import time

    import numpy as np

    from kinegen import rotations
    from kinegen.codegen import generate, write_files
    from kinegen.model import loads
    from kinegen.runtime import from_module, load_module, solve
    from kinegen.runtime.sensitivity import state_sensitivities

    model = loads(excavator_design_yaml(), "excavator_design.yaml")
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        made = generate(model, rotations.get("quaternion"))
        build = time.perf_counter() - start
        write_files(folder, {name: text for files in made.values() for name, text in files.items()})
        module = load_module(Path(folder) / next(iter(made["python"])))
        row: dict = {"build": build, "parameters": len(model.design)}
        for label, compiled in (("compiled", True), ("python", False)):
            system = from_module(module, case, compiled=compiled)
            times = np.linspace(system.t0, system.t1, points)
            solve(system, times)  # warm: compilation, first calls
            best_solve = best_sensitivities = float("inf")
            for _ in range(repeats):
                start = time.perf_counter()
                results = solve(system, times)
                best_solve = min(best_solve, time.perf_counter() - start)
                start = time.perf_counter()
                state_sensitivities(results)
                best_sensitivities = min(best_sensitivities, time.perf_counter() - start)
            row[f"{label}_solve"], row[f"{label}_sensitivities"] = best_solve, best_sensitivities
    return row


def study_cost(method: str = "SLSQP") -> dict:
    """Issue 13's comparison: both design studies of the shipped excavator (models/excavator.yaml,
    its committed quaternion module) on the exact gradients and on SciPy's finite differences:
    per study and gradient kind, iterations, gradient evaluations, designs measured, seconds;
    and how far the two optima are apart."""
    import numpy as np

    from kinegen.analysis.studies import StudyProblem, optimize
    from kinegen.model import load
    from kinegen.runtime import load_module

    model = load(EXCAVATOR)
    module = load_module(EXCAVATOR.parents[1] / "generated" / "excavator_quaternion.py", EXCAVATOR)
    out: dict = {}
    for name, study in model.studies.items():
        runs = {kind: optimize(StudyProblem(model, module, study), method, kind) for kind in ("exact", "fd")}
        out[name] = {
            kind: {"iterations": r.iterations, "gradient_evaluations": r.gradient_evaluations, "designs": r.evaluations,
                   "seconds": r.seconds, "success": r.success, "objective": r.objective_after}
            for kind, r in runs.items()
        }  # fmt: skip
        out[name]["optimum_difference"] = float(max(abs(runs["exact"].optimum[n] - runs["fd"].optimum[n]) for n in runs["exact"].optimum))
        out[name]["parameters"] = len(study.parameters)
        out[name]["seconds_ratio"] = float(np.float64(runs["fd"].seconds) / runs["exact"].seconds)
    return out
