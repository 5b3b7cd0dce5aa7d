"""A design-parameter version of the shipped excavator, for benchmarks and tests of sensitivities.

Ten pin coordinates of the front linkage (m, in the body frames of models/excavator.yaml)
become design parameters with ±2 cm bounds around their values there: the boom-cylinder
rod pins C (x, z; both sides), the arm-cylinder base D on the boom, the arm-cylinder rod pin
F and the bucket-cylinder base G on the arm, and the side link's pin J. At the nominal
values the model is the shipped one, number for number.
"""

from __future__ import annotations

from pathlib import Path

EXCAVATOR = Path(__file__).resolve().parents[2] / "models" / "excavator.yaml"

#: (text in models/excavator.yaml, the same with design parameters, the parameters: name -> nominal)
_PINS = (
    ("C_left: [1.39283, 0.32, 2.001922]", "C_left: [C_x, 0.32, C_z]", {"C_x": "1.39283", "C_z": "2.001922"}),
    ("C_right: [1.39283, -0.32, 2.001922]", "C_right: [C_x, -0.32, C_z]", {}),
    ("D: [2.2875, 0, 2.785]", "D: [D_x, 0, D_z]", {"D_x": "2.2875", "D_z": "2.785"}),
    ("F: [-0.786562, 0, -0.369691]", "F: [F_x, 0, F_z]", {"F_x": "-0.786562", "F_z": "-0.369691"}),
    ("G: [-0.24687, 0, 0.73594]", "G: [G_x, 0, G_z]", {"G_x": "-0.24687", "G_z": "0.73594"}),
    ("J: [-0.332658, 0, 0.481235]", "J: [J_x, 0, J_z]", {"J_x": "-0.332658", "J_z": "0.481235"}),
)
BOUND = 0.02  # m either side of the nominal value


def excavator_design_yaml(names: tuple[str, ...] | None = None) -> str:
    """models/excavator.yaml with ``names`` (default: all ten) as design parameters."""
    text = EXCAVATOR.read_text()
    design = []
    for plain, symbolic, parameters in _PINS:
        if text.count(plain) != 1:
            raise ValueError(f"models/excavator.yaml changed: {plain!r} is not there exactly once")
        chosen = {name: value for name, value in parameters.items() if names is None or name in names}
        kept = symbolic
        for name, value in parameters.items():
            if name not in chosen:
                kept = kept.replace(name, value)
        if not parameters:  # the other side of C: as the first
            kept = symbolic if names is None or {"C_x", "C_z"} <= set(names) else _partial(symbolic, names)
        text = text.replace(plain, kept)
        for name, value in chosen.items():
            low, high = float(value) - BOUND, float(value) + BOUND
            design.append(f"  {name}: {{nominal: {value}, bounds: [{low:.6f}, {high:.6f}]}}")
    return text.replace("\nground:", "\ndesign:\n" + "\n".join(design) + "\nground:", 1)


def _partial(symbolic: str, names: tuple[str, ...]) -> str:
    values = {"C_x": "1.39283", "C_z": "2.001922"}
    for name, value in values.items():
        if name not in names:
            symbolic = symbolic.replace(name, value)
    return symbolic


def sensitivity_cost(case: str = "digging", points: int = 1000, repeats: int = 3) -> dict:
    """Issue 13's figure: the trajectory solve of ``case`` (``points`` time points) of the ten-
    parameter excavator, compiled and pure Python, and its sensitivities by all ten parameters
    (dq/dp, dv/dp, da/dp), best of ``repeats`` each, in seconds; and the build time."""
    import tempfile
    import time

    import numpy as np

    from kinegen import rotations
    from kinegen.codegen import generate
    from kinegen.model import loads
    from kinegen.runtime import from_module, load_module, solve

    model = loads(excavator_design_yaml(), "excavator_design.yaml")
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        made = generate(model, rotations.get("quaternion"))
        build = time.perf_counter() - start
        for files in made.values():
            for name, text in files.items():
                (Path(folder) / name).write_text(text)
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
                results.state_sensitivities()
                best_sensitivities = min(best_sensitivities, time.perf_counter() - start)
            row[f"{label}_solve"], row[f"{label}_sensitivities"] = best_solve, best_sensitivities
    return row
