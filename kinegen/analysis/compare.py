"""``kinegen compare``: every parametrization of one model, built and solved, in one table.

Per parametrization: coordinates, velocity columns, equations, Jacobian non-zeros, the
highest polynomial degree of Φ's entries in the stored coordinates, build time (symbolic
derivation and printing of the Python module and the C, no compilation), generated lines,
Newton iterations per step (kinegen's default solver, and previous-q starts), solve time of
the case (pure Python, and compiled when a C compiler is there), the range of kinegen's condition
number of the Jacobian along the case (the 2-norm's, as in the case plot and the CSV), the
largest time step at which plain Newton (previous-q starts, no line search, no step
refinement) still converges over the whole case, and where the parametrization is singular.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from kinegen import rotations
from kinegen.errors import KinegenError
from kinegen.model.schema import Model
from kinegen.runtime import kinematics

#: The parametrizations compared by default (Euler angles in the two sequences of the paper's discussion).
DEFAULT = rotations.SHOWN
#: Time-point counts tried for the largest converging step (the case's own grid first).
STEP_COUNTS = (3, 5, 9, 17, 33, 65, 129, 257, 513)


@dataclass
class Comparison:
    """One parametrization's row of the table (None where the run failed)."""

    parametrization: str
    coordinates: int
    velocity_columns: int
    equations: int
    jacobian_nonzeros: int
    degree: str  # highest polynomial degree of Phi in the coordinates, or "trigonometric"
    build_seconds: float
    generated_lines: int
    singular_set: str
    iterations: float | None = None
    iterations_previous_q: float | None = None
    solve_seconds: float | None = None
    solve_seconds_compiled: float | None = None
    condition: tuple[float, float] | None = None
    largest_step: float | None = None
    failure: str | None = None
    notes: list[str] = field(default_factory=list)


def compare(model: Model, case: str | None = None, parametrizations: tuple[str, ...] = DEFAULT, compiled: bool = True) -> list[Comparison]:
    """Build and solve ``model``'s ``case`` (default: the first) in every parametrization (a model
    with design parameters at their nominal values: ``model.at()``, the machine as drawn)."""
    model = model.at() if model.design else model
    case = case or next(iter(model.cases))
    from kinegen.progress import progress

    return [_one(model, case, rotations.get(name), compiled) for name in progress(parametrizations, "compare: build and solve", unit="parametrization")]


def _one(model: Model, case: str, param: rotations.Parametrization, compiled: bool) -> Comparison:
    from sympy.core.cache import clear_cache

    from kinegen.codegen import generate, module_name, write_files
    from kinegen.runtime import Solver, SolverOptions, from_module, load_module
    from kinegen.symbolic.assembly import build_systems

    clear_cache()  # every parametrization derives from a cold SymPy cache
    start = time.perf_counter()
    files = generate(model, param, ("python", "c-model"))
    build = time.perf_counter() - start
    lines = sum(text.count("\n") for target in files.values() for name, text in target.items() if name.endswith((".py", ".c")))
    system = build_systems(model, param, [case])[case]
    row = Comparison(
        param.name, len(system.coordinates.stored_symbols), len(system.coordinates.velocity_symbols), len(system.rows),
        len(system.jacobian_pattern), _degree(system), build, lines, param.singular_set,
    )  # fmt: skip
    with tempfile.TemporaryDirectory() as folder:
        write_files(folder, {name: text for target in files.values() for name, text in target.items()})
        module = load_module(Path(folder) / f"{module_name(model, param)}.py")
        python = from_module(module, case, compiled=False)
        times = np.linspace(python.t0, python.t1, python.steps)
        try:
            start = time.perf_counter()
            results = Solver(python, SolverOptions(condition="none")).solve(times)
            row.solve_seconds = time.perf_counter() - start
            row.iterations = float(results.iterations.mean())
            previous = Solver(python, SolverOptions(condition="none", predictor=False)).solve(times)
            row.iterations_previous_q = float(previous.iterations.mean())
        except KinegenError as error:
            row.failure = str(error).splitlines()[0]
            return row
        row.condition = _condition_range(python, results)
        row.largest_step = _largest_step(python)
        if compiled:
            try:
                native = from_module(module, case, compiled=True)
                if native.native is not None:
                    solver = Solver(native, SolverOptions(condition="none"))
                    solver.solve(times)  # the library is loaded and warm
                    start = time.perf_counter()
                    solver.solve(times)
                    row.solve_seconds_compiled = time.perf_counter() - start
            except KinegenError as error:
                row.notes.append(f"compiled: {str(error).splitlines()[0]}")
    return row


def _degree(system) -> str:
    """Highest total degree of the rows of Phi in the stored coordinates (frame symbols substituted)."""
    definitions = system.coordinates.frame_definitions
    stored = set(system.coordinates.stored_symbols)
    degree = 0
    for row in system.rows:
        expr = row.phi.xreplace(definitions)
        gens = sorted(expr.free_symbols & stored, key=str)
        if not gens:
            continue
        if not expr.is_polynomial(*gens):
            return "trigonometric"
        degree = max(degree, sp.Poly(expr, *gens).total_degree())
    return str(degree)


def _condition_range(system, results) -> tuple[float, float]:
    """min and max over the solved steps of kinegen's condition number of Phi_q (one definition
    everywhere: :func:`kinegen.runtime.kinematics.condition_numbers`, the 2-norm's)."""
    found = kinematics.condition_numbers(results)
    found = found[np.isfinite(found)]
    return float(np.min(found)), float(np.max(found))


def _largest_step(system) -> float | None:
    """The largest uniform time step (of :data:`STEP_COUNTS` over the case) at which full Newton
    from the previous q, without line search or refinement, converges at every point."""
    from kinegen.runtime import Solver, SolverOptions

    plain = SolverOptions(condition="none", predictor=False, line_search=False, keep_branch=False, max_refinements=0)
    for count in STEP_COUNTS:
        times = np.linspace(system.t0, system.t1, count)
        try:
            results = Solver(system, plain).solve(times)
        except KinegenError:
            continue
        if results.converged.all():
            return float(times[1] - times[0])
    return None


def table(rows: list[Comparison], model: str, case: str) -> str:
    """The comparison as a plain-text table."""

    def number(value: float | None, fmt: str) -> str:
        return "–" if value is None else format(value, fmt)

    header = ["parametrization", "q", "v", "eqs", "nnz", "deg", "build s", "lines", "it/step", "prev-q", "solve s", "C s",
              "cond (2-norm)", "max dt s"]  # fmt: skip
    body = []
    for r in rows:
        condition = "–" if r.condition is None else f"{r.condition[0]:.3g}–{r.condition[1]:.3g}"
        body.append([
            r.parametrization, str(r.coordinates), str(r.velocity_columns), str(r.equations), str(r.jacobian_nonzeros), r.degree,
            f"{r.build_seconds:.2f}", str(r.generated_lines), number(r.iterations, ".2f"), number(r.iterations_previous_q, ".2f"),
            number(r.solve_seconds, ".3f"), number(r.solve_seconds_compiled, ".4f"), condition, number(r.largest_step, ".3g"),
        ])  # fmt: skip
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(header)]
    lines = [f"{model}, case {case}: every parametrization, built and solved", ""]
    lines.append("  ".join(h.ljust(w) for h, w in zip(header, widths)))
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.ljust(w) for c, w in zip(b, widths)) for b in body]
    lines.append("")
    for r in rows:
        lines.append(f"{r.parametrization}: singular {r.singular_set}")
        if r.failure:
            lines.append(f"  this case: {r.failure}")
        lines += [f"  {n}" for n in r.notes]
    return "\n".join(lines)


def to_json(rows: list[Comparison]) -> list[dict[str, Any]]:
    return [asdict(r) for r in rows]
