"""One contender of the benchmark per function; each runs in its own process.

A *workload* is ``chain-N`` (``docs/chain-N.md``) or ``excavator-<case>``.
Every contender solves the same equations (kinegen's Phi of the model in Euler
parameters: for chain-N these are the benchmark's literal equations up to row sign, scale
and order) on the same work: 1000 time points, Newton to max |Phi| < 1e-10 (at most 25
iterations) from the previous solution, then velocity and acceleration. Each reports build
time, trajectory time, Newton iterations per step and the largest error of a tracked point:
against the analytic tip for chain-N, against kinegen's quaternion solution (another
parametrization, other generated code) of the bucket tip for the excavator.
"""

from __future__ import annotations

import gc
import os
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from kinegen.runtime import kinematics

PARAMETRIZATION = "euler-parameters"
STEPS = 1000
TOLERANCE = 1e-10
MAX_ITERATIONS = 25
ROOT = Path(__file__).resolve().parents[2]
#: each contender's trajectory is timed up to this many times in its process and the shortest counts (as
#: timeit's best of n): on the shared machines one run of the same code differs from the next by up to
#: 50 %. Fewer when the runs have taken TIME_BUDGET seconds. ``python -m kinegen.bench --repeats N``.
REPEATS = int(os.environ.get("KINEGEN_BENCH_REPEATS", "5"))
TIME_BUDGET = 2.0
Out = TypeVar("Out")


@dataclass(frozen=True)
class Workload:
    """A model, case, time grid and the point whose path is checked."""

    name: str
    model: Any  # kinegen.model.Model
    case: str
    times: np.ndarray
    body: str
    point: str
    reference: Callable[[], np.ndarray]  #: (K, 3) path of the point the errors are measured against


@cache
def workload(name: str) -> Workload:
    """``chain-14`` or ``excavator-digging`` (any case of models/excavator.yaml)."""
    from kinegen.model import load, loads

    kind, _, arg = name.partition("-")
    if kind == "chain":
        from kinegen.bench.chain import chain_yaml, tip_reference

        n = int(arg)
        times = np.linspace(0, 10.0, STEPS)
        model = loads(chain_yaml(n, 10.0, STEPS), f"chain{n}.yaml")
        return Workload(name, model, "drive", times, f"link{n}", "tip", lambda: tip_reference(n, times)[0])
    if kind == "excavator":
        model = load(ROOT / "models" / "excavator.yaml")
        case = model.cases[arg]
        times = np.linspace(float(case.t0), float(case.t1), STEPS)
        spec = model.working_range
        body, point = spec.point.body, spec.point.name

        def reference() -> np.ndarray:
            from kinegen.api import Session
            from kinegen.runtime import Solver, SolverOptions

            system = Session(ROOT / "generated").system(ROOT / "models" / "excavator.yaml", arg)
            solved = Solver(system, SolverOptions(condition="none", tolerance=1e-12)).solve(times)
            return kinematics.point_position(solved, body, point)

        return Workload(name, model, arg, times, body, point, reference)
    raise ValueError(f"unknown workload {name!r} (chain-N or excavator-<case>)")


def _error(w: Workload, qs: np.ndarray) -> float:
    """Largest distance of the tracked point (from Euler-parameter coordinates) to the reference."""
    from kinegen import rotations

    parametrization = rotations.get("euler-parameters")
    nominal = w.model.at() if w.model.design else w.model
    k = [b.name for b in nominal.bodies].index(w.body)
    local = np.array([float(x) for x in nominal.bodies[k].points[w.point]])
    origin, rotation = parametrization.pose(np.asarray(qs)[:, k * parametrization.nq : (k + 1) * parametrization.nq])
    path = origin + np.einsum("kij,j->ki", rotation, local)
    return float(np.abs(path - w.reference()).max())


def _initial(w: Workload) -> np.ndarray:
    from kinegen import rotations
    from kinegen.codegen import initial_q

    return initial_q(w.model, rotations.get(PARAMETRIZATION))


def _settle() -> None:
    """Before a timed trajectory: collect, then freeze every object alive (the SymPy objects
    this harness made to give each contender the same Phi) so that no contender's Python
    loop pays garbage-collector passes over them (they cost 20-40 % of a chain-14 loop)."""
    gc.collect()
    gc.freeze()


def best_time(run: Callable[[], Out], repeats: int | None = None, budget: float = TIME_BUDGET) -> tuple[float, Out]:
    """The shortest wall time of up to ``repeats`` (default :data:`REPEATS`) calls of ``run``, each
    after :func:`_settle`, stopping once the calls have taken ``budget`` seconds; and the last call's
    result (every call does the same work from the same start)."""
    best, spent, out = float("inf"), 0.0, None
    for _ in range(max(1, REPEATS if repeats is None else repeats)):
        _settle()
        start = time.perf_counter()
        out = run()
        elapsed = time.perf_counter() - start
        best, spent = min(best, elapsed), spent + elapsed
        if spent >= budget:
            break
    return best, out  # type: ignore[return-value]


def _result(build: float, trajectory: float, iterations: list[int] | np.ndarray, w: Workload, qs, **extra) -> dict[str, Any]:
    return {
        "build": build,
        "trajectory": trajectory,
        "iterations": float(np.mean(iterations)),
        "error": _error(w, qs),
        **extra,
    }


# ---- kinegen ---------------------------------------------------------------------------
def kinegen_run(name: str, predictor: bool, parametrization: str = PARAMETRIZATION, compiled: bool = False) -> dict[str, Any]:
    """kinegen: generated module (build = symbolic derivation + code generation, and with
    ``compiled`` the compilation of the model's C with kinegen's C solver, which then solves)."""

    from kinegen import rotations
    from kinegen.codegen import generate, module_name, write_files
    from kinegen.runtime import Solver, SolverOptions, from_module, load_module
    from kinegen.runtime.native import compile_in_background

    w = workload(name)
    param = rotations.get(parametrization)
    # the model's C compiled afresh, timed as part of the build; kinegen's C solver, compiled once per machine
    # for every model, is not timed: the cache's own object (compiled there first if it was not)
    with tempfile.TemporaryDirectory() as folder, _fresh_cache(solver=compiled):
        compiling = []

        def ready(target: str, files: dict[str, str]) -> None:  # as `kinegen build`: compile while printing Python
            if target == "c-model":
                compiling.append(compile_in_background(files))

        start = time.perf_counter()
        made = generate(w.model, param, ("python", "c-model") if compiled else ("python",), ready)
        for thread in compiling:
            thread.join()
        write_files(folder, {file: text for files in made.values() for file, text in files.items()})
        module = load_module(Path(folder) / f"{module_name(w.model, param)}.py")
        system = from_module(module, w.case, compiled=compiled)
        build = time.perf_counter() - start
    # "as specified": previous-q starts and no polish; own: predictor + polishing correction
    solver = Solver(system, SolverOptions(condition="none", predictor=predictor, polish=predictor, compiled=compiled))
    trajectory, results = best_time(lambda: solver.solve(w.times))
    path = kinematics.point_position(results, w.body, w.point)
    error = float(np.abs(path - w.reference()).max())
    return {"build": build, "trajectory": trajectory, "iterations": float(results.iterations.mean()), "error": error}


@contextmanager
def _fresh_cache(solver: bool = False) -> Iterator[None]:
    """kinegen's cache set to a new, empty folder for the block, then back to what it was (the
    folder removed): a cache left pointing at the removed folder sent every later compile of the
    process into a re-created copy of it, outside any cache anyone cleans. ``solver``: the new
    folder holds the C solver's object of the cache before (compiled there first if it was not;
    the trust store knows its bytes), as a machine that built any model has it."""
    from kinegen.runtime.native import copy_solver_object

    previous = os.environ.get("KINEGEN_CACHE")
    with tempfile.TemporaryDirectory() as cache:
        if solver:
            copy_solver_object(Path(cache))
        os.environ["KINEGEN_CACHE"] = cache
        try:
            yield
        finally:
            if previous is None:
                del os.environ["KINEGEN_CACHE"]
            else:
                os.environ["KINEGEN_CACHE"] = previous


def c_target_memory(name: str, parametrization: str = PARAMETRIZATION) -> dict[str, Any]:
    """Memory of one solver instance of the standalone C target: its workspace (the generated
    header's ``<stem>_workspace``: ``*_WORK_DOUBLES`` doubles and ``*_WORK_INTS`` ints), the
    ``kinegen_solver`` struct, and the stack of a step (gcc's call graph,
    :class:`kinegen.bench.callgraph.CallGraph`: the deepest chain of frames from kinegen_step, plus the
    deepest kernel's with its section functions, which it calls through a pointer). Static data (the
    model's tables) is shared by every instance and reported apart."""
    import re
    import subprocess

    from kinegen import rotations
    from kinegen.bench.callgraph import CallGraph
    from kinegen.codegen import generate, module_name
    from kinegen.runtime.native import c_compiler

    w = workload(name)
    param = rotations.get(parametrization)
    stem = module_name(w.model, param)
    files = generate(w.model, param, ("c",))["c"]
    with tempfile.TemporaryDirectory() as folder:
        for file, text in files.items():
            (Path(folder) / file).write_text(text)
        (Path(folder) / "size.c").write_text(
            f'#include <stdio.h>\n#include "{stem}.h"\n'
            f'int main(void) {{ printf("%zu %zu", sizeof(kinegen_solver), sizeof({stem}_workspace)); return 0; }}\n'
        )
        compiler = c_compiler()
        for source in (f"{stem}.c", "kinegen_solver.c"):
            subprocess.run([compiler, "-std=c99", "-O2", "-fcallgraph-info=su", "-c", source], cwd=folder, check=True)
        subprocess.run([compiler, "-std=c99", "-o", "size", "size.c"], cwd=folder, check=True)
        struct, workspace = map(int, subprocess.run([str(Path(folder) / "size")], capture_output=True, text=True, check=True).stdout.split())
        graph = CallGraph(*Path(folder).glob("*.ci"))
        subprocess.run([compiler, "-std=c99", "-O2", "-c", f"{stem}.c", "-o", "model.o"], cwd=folder, check=True)
        sizes = subprocess.run(["size", "-A", "model.o"], cwd=folder, capture_output=True, text=True).stdout
    static = sum(int(m.group(1)) for m in re.finditer(r"^\.(?:rodata|data)\S*\s+(\d+)", sizes, re.MULTILINE))
    # the step's deepest chain of the solver's frames, plus the deepest kernel called through a pointer from it
    # (through its kernel-table entry point, call_<kernel>, into which -O2 may inline the kernel)
    kernels = max(graph.deepest(k) for k in graph.frames
                  if k.split(":")[-1].removeprefix("call_").startswith(("phi_jac_", "gamma_", "nu_")))
    stack = graph.deepest("kinegen_step") + kernels
    return {"workspace": workspace, "struct": struct, "stack": stack, "static": static}


# ---- the same Phi for the other contenders ---------------------------------------------
def symbolic_phi(w: Workload):
    """kinegen's Phi(q, t) of the workload as SymPy expressions in the stored coordinates."""
    from kinegen import rotations
    from kinegen.symbolic import build_systems

    nominal = w.model.at() if w.model.design else w.model  # the baselines solve the nominal design (numbers only)
    system = build_systems(nominal, rotations.get(PARAMETRIZATION), [w.case])[w.case]
    coords = system.coordinates
    time_functions = dict(zip(system.inputs.u, system.inputs.functions))
    phi = [r.phi.xreplace(coords.frame_definitions).xreplace(time_functions) for r in system.rows]
    return list(coords.stored_symbols), phi


def _newton_trajectory(w: Workload, evaluate, rates) -> tuple[np.ndarray, list[int]]:
    """Full-step Newton from the previous solution; ``evaluate(q, t) -> (Phi, dense Phi_q)``,
    ``rates(q, Phi_q, t) -> None`` computes velocity and acceleration."""
    q = _initial(w)
    qs, iterations = [], []
    for t in w.times:
        phi, jacobian = evaluate(q, t)
        count = 0
        while np.abs(phi).max() >= TOLERANCE and count < MAX_ITERATIONS:
            q = q - np.linalg.solve(jacobian, phi)
            phi, jacobian = evaluate(q, t)
            count += 1
        rates(q, jacobian, t)
        qs.append(q)
        iterations.append(count)
    return np.array(qs), iterations


# ---- naive SymPy ---------------------------------------------------------------------------
def naive_sympy_run(name: str, cse: bool) -> dict[str, Any]:
    """Naive SymPy: dense Matrix.jacobian + lambdify on the whole system, dense LU per iteration."""
    import sympy as sp

    from kinegen.model.expressions import T

    w = workload(name)
    start = time.perf_counter()
    q_list, phi_list = symbolic_phi(w)
    q, phi = sp.Matrix(q_list), sp.Matrix(phi_list)
    qd = sp.Matrix([sp.Symbol(f"qd{i}") for i in range(len(q))])
    jacobian = phi.jacobian(q)
    phi_t = phi.diff(T)
    gamma = -(jacobian * qd).jacobian(q) * qd - 2 * phi_t.jacobian(q) * qd - phi_t.diff(T)
    compile_ = lambda args, expr: sp.lambdify(args, expr, "numpy", cse=cse)  # noqa: E731
    f_phi, f_jac = compile_([q, T], phi), compile_([q, T], jacobian)
    f_phi_t, f_gamma = compile_([q, T], phi_t), compile_([q, qd, T], gamma)
    build = time.perf_counter() - start

    def evaluate(q, t):
        return np.asarray(f_phi(q, t), dtype=float).ravel(), np.asarray(f_jac(q, t), dtype=float)

    def rates(q, jacobian, t):
        velocity = np.linalg.solve(jacobian, -np.asarray(f_phi_t(q, t), dtype=float).ravel())
        np.linalg.solve(jacobian, np.asarray(f_gamma(q, velocity, t), dtype=float).ravel())

    elapsed, (qs, iterations) = best_time(lambda: _newton_trajectory(w, evaluate, rates))
    return _result(build, elapsed, iterations, w, qs)


# ---- SymEngine -------------------------------------------------------------------------------
def symengine_run(name: str) -> dict[str, Any]:
    """SymEngine: Phi converted from SymPy, Jacobian and gamma differentiated by SymEngine,
    Lambdify (LLVM backend, cse) of Phi + the non-zero Phi_q entries, of Phi_t and of gamma."""
    import symengine as se

    w = workload(name)
    q_sympy, phi_sympy = symbolic_phi(w)
    start = time.perf_counter()
    q = [se.Symbol(str(s)) for s in q_sympy]
    qd = [se.Symbol(f"qd{i}") for i in range(len(q))]
    t = se.Symbol("t")
    phi = [se.sympify(e) for e in phi_sympy]
    entries = [(i, j, d) for i, e in enumerate(phi) for j, s in enumerate(q) if (d := e.diff(s)) != 0]
    phi_t = [e.diff(t) for e in phi]
    psi = [sum((d * qd[j] for i2, j, d in entries if i2 == i), se.Integer(0)) for i in range(len(phi))]  # Phi_q qd
    gamma = [
        -sum((p.diff(s) * qd[j] for j, s in enumerate(q)), se.Integer(0)) - 2 * p.diff(t) - ft.diff(t)
        for p, ft in zip(psi, phi_t)
    ]
    backend = "llvm"
    f_eval = se.Lambdify([*q, t], [*phi, *(d for _, _, d in entries)], backend=backend, cse=True)
    f_phi_t = se.Lambdify([*q, t], phi_t, backend=backend, cse=True)
    f_gamma = se.Lambdify([*q, *qd, t], gamma, backend=backend, cse=True)
    build = time.perf_counter() - start
    m, n = len(phi), len(q)
    flat = np.array([i * n + j for i, j, _ in entries])

    def evaluate(qv, tv):
        values = f_eval(np.append(qv, tv))
        dense = np.zeros((m, n))
        dense.flat[flat] = values[m:]
        return values[:m], dense

    def rates(qv, jacobian, tv):
        velocity = np.linalg.solve(jacobian, -f_phi_t(np.append(qv, tv)))
        np.linalg.solve(jacobian, f_gamma(np.concatenate((qv, velocity, [tv]))))

    elapsed, (qs, iterations) = best_time(lambda: _newton_trajectory(w, evaluate, rates))
    return _result(build, elapsed, iterations, w, qs, note=f"{len(entries)} Jacobian entries, {backend}")


# ---- CasADi ------------------------------------------------------------------------------------
def _casadi_functions(w: Workload):
    """Phi in CasADi SX (translated from SymPy by lambdify with CasADi's functions), its
    sparse Jacobian, Phi_t and gamma; returns (SX q, SX t, phi, Function eval, Function gamma)."""
    import casadi as ca
    import sympy as sp

    from kinegen.model.expressions import T

    q_sympy, phi_sympy = symbolic_phi(w)
    start = time.perf_counter()
    names = {"sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "sqrt": ca.sqrt, "exp": ca.exp, "log": ca.log, "tanh": ca.tanh}
    translate = sp.lambdify([q_sympy, T], phi_sympy, modules=[names, "math"])
    n = len(q_sympy)
    q, qd, t = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("t")
    phi = ca.vertcat(*translate(ca.vertsplit(q), t))
    jacobian = ca.jacobian(phi, q)
    phi_t = ca.jacobian(phi, t)
    psi = ca.mtimes(jacobian, qd)
    gamma = -ca.mtimes(ca.jacobian(psi, q), qd) - 2 * ca.jacobian(psi, t) - ca.jacobian(phi_t, t)
    evaluate = ca.Function("evaluate", [q, t], [phi, ca.densify(jacobian), phi_t])
    acceleration = ca.Function("gamma", [q, qd, t], [gamma])
    return start, q, t, phi, evaluate, acceleration


class _Buffered:
    """A CasADi Function called through its buffer interface: NumPy arrays bound once.

    (Converting a dense 98x98 result with ``DM.full()`` costs ~290 us; the buffer call ~20 us.)
    """

    def __init__(self, function, arg_sizes: list[int], res_shapes: list[tuple[int, ...]]) -> None:
        self.buffer, self.call = function.buffer()
        self.args = [np.zeros(k) for k in arg_sizes]
        self.results = [np.zeros(shape, order="F") for shape in res_shapes]
        for i, a in enumerate(self.args):
            self.buffer.set_arg(i, memoryview(a))
        for i, r in enumerate(self.results):
            self.buffer.set_res(i, memoryview(r.reshape(-1, order="F")))

    def __call__(self, *args) -> list[np.ndarray]:
        for target, value in zip(self.args, args):
            target[:] = value
        self.call()
        return self.results


def casadi_run(name: str, rootfinder: bool) -> dict[str, Any]:
    """CasADi SX: a Python Newton loop calling one Function (Phi, Phi_q, Phi_t) per iteration
    through NumPy buffers, or ``rootfinder('newton')`` per step; then velocity and acceleration."""
    import casadi as ca

    w = workload(name)
    start, q_sym, t_sym, phi, evaluate, acceleration = _casadi_functions(w)
    n = q_sym.numel()
    m = phi.numel()
    fused = _Buffered(evaluate, [n, 1], [(m,), (m, n), (m,)])
    gamma = _Buffered(acceleration, [n, n, 1], [(m,)])
    solve_step = None
    if rootfinder:
        residual = ca.Function("residual", [q_sym, t_sym], [phi])
        solve_step = ca.rootfinder("step", "newton", residual, {"abstol": TOLERANCE, "max_iter": MAX_ITERATIONS})
    build = time.perf_counter() - start

    def evaluate_phi(q, t):
        phi_value, jacobian, _ = fused(q, t)
        return phi_value.copy(), jacobian.copy()

    def rates(q, jacobian, t):
        velocity = np.linalg.solve(jacobian, -fused.results[2])
        np.linalg.solve(jacobian, gamma(q, velocity, t)[0])

    def rootfinder_trajectory() -> tuple[np.ndarray, list[int]]:
        q = _initial(w)
        qs, iterations = [], []
        for t in w.times:
            q = solve_step(q, t).full().ravel()
            iterations.append(solve_step.stats().get("iter_count", 0))
            _, jacobian = evaluate_phi(q, t)
            rates(q, jacobian, t)
            qs.append(q)
        return np.array(qs), iterations

    run = (lambda: _newton_trajectory(w, evaluate_phi, rates)) if solve_step is None else rootfinder_trajectory
    elapsed, (qs, iterations) = best_time(run)
    return _result(build, elapsed, iterations, w, qs)


def casadi_c_run(name: str) -> dict[str, Any]:
    """CasADi, whole trajectory in generated C: one step = ``rootfinder('fast_newton')`` (the
    Newton plugin that supports code generation; abstol 1e-10, at most 25 iterations) from
    the previous solution, then velocity and acceleration by QR solves; ``mapaccum`` over
    the 1000 time points, C generated, compiled with the machine's C compiler and loaded
    with ``external`` (all of that is its build). Iterations per step are not reported."""
    import os
    import subprocess

    import casadi as ca

    from kinegen.runtime.native import c_compiler

    w = workload(name)
    start, q, t, phi, _, acceleration = _casadi_functions(w)
    n = q.numel()
    residual = ca.Function("residual", [q, t], [phi])
    newton = ca.rootfinder("newton", "fast_newton", residual, {"abstol": TOLERANCE, "max_iter": MAX_ITERATIONS})
    jacobians = ca.Function("jacobians", [q, t], [ca.jacobian(phi, q), ca.jacobian(phi, t)])
    q_previous, time_point = ca.MX.sym("q", n), ca.MX.sym("t")
    q_next = newton(q_previous, time_point)
    jacobian, phi_t = jacobians(q_next, time_point)
    velocity = ca.solve(jacobian, -phi_t, "qr")
    accel = ca.solve(jacobian, acceleration(q_next, velocity, time_point), "qr")
    step = ca.Function("step", [q_previous, time_point], [q_next, velocity, accel])
    trajectory = step.mapaccum("trajectory", len(w.times))
    compiler = c_compiler()
    with tempfile.TemporaryDirectory() as folder:
        here = os.getcwd()
        os.chdir(folder)  # CasADi writes the C file into the working directory
        try:
            trajectory.generate("trajectory.c")
        finally:
            os.chdir(here)
        library = Path(folder) / "trajectory.so"
        subprocess.run(
            [compiler, "-O2", "-shared", "-fPIC", "-o", str(library), str(Path(folder) / "trajectory.c"), "-lm"], check=True
        )
        compiled = ca.external(trajectory.name(), str(library))
        build = time.perf_counter() - start
        q0 = _initial(w)
        elapsed, solved = best_time(lambda: compiled(q0, w.times.reshape(1, -1)))
        qs = np.array(solved[0]).T
    return _result(build, elapsed, [np.nan], w, qs)


# ---- SciPy only ----------------------------------------------------------------------------------
def scipy_hybr_run(name: str) -> dict[str, Any]:
    """SciPy only: NumPy Phi + scipy.optimize.root(method='hybr') with finite differences.

    Phi is the lambdified residual (no symbolic Jacobian is used); velocity and
    acceleration by finite-difference Jacobians as such a user would.
    """
    import sympy as sp
    from scipy.optimize import approx_fprime, root

    from kinegen.model.expressions import T

    w = workload(name)
    start = time.perf_counter()
    q_syms, exprs = symbolic_phi(w)
    phi_numeric = sp.lambdify([q_syms, T], exprs, "numpy", cse=True)
    build = time.perf_counter() - start

    def phi(q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(phi_numeric(q, t), dtype=float).ravel()

    h = 1e-6

    def trajectory() -> tuple[list[np.ndarray], list[int]]:
        q = _initial(w)
        qs, evaluations = [], []
        for t in w.times:
            solution = root(phi, q, args=(t,), method="hybr", options={"xtol": 1e-13})
            q = solution.x
            matrix = approx_fprime(q, phi, 1e-8, t)
            phi_t = (phi(q, t + h) - phi(q, t - h)) / (2 * h)
            np.linalg.solve(matrix, -phi_t)
            qs.append(q)
            evaluations.append(solution.nfev)
        return qs, evaluations

    elapsed, (qs, evaluations) = best_time(trajectory)
    return _result(
        build, elapsed, evaluations, w, np.array(qs),
        note="iterations = Phi evaluations per step; acceleration not computed",
    )  # fmt: skip
