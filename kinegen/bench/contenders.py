"""One contender of the chain-N benchmark per function; each runs in its own process.

Every contender solves the same equations (kinegen's Phi of the chain-N model in Euler
parameters, the benchmark's coordinates) on the same workload: 1000 time points on
[0, 10], Newton to max |Phi| < 1e-10 (at most 25 iterations), then velocity and
acceleration, and reports build time, trajectory time, Newton iterations per step and the
largest tip-position error against the analytic solution.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

PARAMETRIZATION = "euler-parameters"
STEPS = 1000
T1 = 10.0


def _model(n: int):
    from kinegen.bench.chain import chain_yaml
    from kinegen.model import loads

    return loads(chain_yaml(n, T1, STEPS), f"chain{n}.yaml")


def _tip_error(n: int, times: np.ndarray, tips: np.ndarray) -> float:
    from kinegen.bench.chain import tip_reference

    return float(np.abs(tips - tip_reference(n, times)[0]).max())


def kinegen_run(n: int, predictor: bool) -> dict[str, Any]:
    """kinegen: generated module (build = symbolic derivation + code generation), sparse Phi_q values."""
    import tempfile
    from pathlib import Path

    from kinegen import rotations
    from kinegen.codegen import generate_source
    from kinegen.runtime import Solver, SolverOptions, from_module, load_module

    model = _model(n)
    start = time.perf_counter()
    source = generate_source(model, rotations.get(PARAMETRIZATION))
    build = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"chain{n}.py"
        path.write_text(source)
        system = from_module(load_module(path))
    solver = Solver(system, SolverOptions(condition="none", predictor=predictor))
    start = time.perf_counter()
    results = solver.solve()
    trajectory = time.perf_counter() - start
    tips = results.point_position(f"link{n}", "tip")
    return {
        "build": build,
        "trajectory": trajectory,
        "iterations": float(results.iterations.mean()),
        "error": _tip_error(n, results.times, tips),
    }


def _symbolic_phi(n: int):
    """kinegen's Phi of chain-N as one SymPy column in the stored coordinates and t."""
    import sympy as sp

    from kinegen import rotations
    from kinegen.symbolic import build_systems

    system = build_systems(_model(n), rotations.get(PARAMETRIZATION))["drive"]
    coords = system.coordinates
    time_functions = dict(zip(system.inputs.u, system.inputs.functions))
    phi = sp.Matrix([r.phi.xreplace(coords.rotation_definitions).xreplace(time_functions) for r in system.rows])
    return sp.Matrix(coords.stored_symbols), phi


def _naive_functions(n: int, cse: bool):
    """Dense Phi(q, t), Phi_q, Phi_t, gamma by Matrix.jacobian + lambdify on the whole system."""
    import sympy as sp

    from kinegen.model.expressions import T

    q, phi = _symbolic_phi(n)
    qd = sp.Matrix([sp.Symbol(f"qd{i}") for i in range(len(q))])
    jacobian = phi.jacobian(q)
    phi_t = phi.diff(T)
    gamma = -(jacobian * qd).jacobian(q) * qd - 2 * phi_t.jacobian(q) * qd - phi_t.diff(T)
    compile_ = lambda args, expr: sp.lambdify(args, expr, "numpy", cse=cse)  # noqa: E731
    return (
        compile_([q, T], phi),
        compile_([q, T], jacobian),
        compile_([q, T], phi_t),
        compile_([q, qd, T], gamma),
    )


def _initial(n: int) -> np.ndarray:
    from kinegen import rotations
    from kinegen.codegen import initial_q

    return initial_q(_model(n), rotations.get(PARAMETRIZATION))


def _tip(q: np.ndarray, n: int) -> np.ndarray:
    from kinegen.rotations import quaternion_algebra as qa

    body = q[7 * (n - 1) : 7 * n]
    return body[:3] + qa.to_matrix(body[3:]) @ np.array([1.0, 0, 0])


def naive_sympy_run(n: int, cse: bool) -> dict[str, Any]:
    """Naive SymPy: dense Matrix.jacobian + lambdify, dense LU per Newton iteration."""
    start = time.perf_counter()
    phi, jacobian, phi_t, gamma = _naive_functions(n, cse)
    build = time.perf_counter() - start
    times = np.linspace(0, T1, STEPS)
    q = _initial(n)
    tips, iterations = [], []
    start = time.perf_counter()
    for t in times:
        residual = np.asarray(phi(q, t), dtype=float).ravel()
        count = 0
        while np.abs(residual).max() >= 1e-10 and count < 25:
            q = q - np.linalg.solve(np.asarray(jacobian(q, t), dtype=float), residual)
            residual = np.asarray(phi(q, t), dtype=float).ravel()
            count += 1
        matrix = np.asarray(jacobian(q, t), dtype=float)
        qd = np.linalg.solve(matrix, -np.asarray(phi_t(q, t), dtype=float).ravel())
        np.linalg.solve(matrix, np.asarray(gamma(q, qd, t), dtype=float).ravel())
        tips.append(_tip(q, n))
        iterations.append(count)
    trajectory = time.perf_counter() - start
    return {
        "build": build,
        "trajectory": trajectory,
        "iterations": float(np.mean(iterations)),
        "error": _tip_error(n, times, np.array(tips)),
    }


def scipy_hybr_run(n: int) -> dict[str, Any]:
    """SciPy only: NumPy Phi + scipy.optimize.root(method='hybr') with finite differences.

    Phi is the lambdified residual (no symbolic Jacobian is used); velocity and
    acceleration by finite-difference Jacobians as such a user would.
    """
    import sympy as sp
    from scipy.optimize import approx_fprime, root

    from kinegen.model.expressions import T

    start = time.perf_counter()
    q_syms, exprs = _symbolic_phi(n)
    phi_numeric = sp.lambdify([q_syms, T], exprs, "numpy", cse=True)
    build = time.perf_counter() - start

    def phi(q: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(phi_numeric(q, t), dtype=float).ravel()

    times = np.linspace(0, T1, STEPS)
    q = _initial(n)
    tips, evaluations, velocities = [], [], []
    h = 1e-6
    start = time.perf_counter()
    for t in times:
        solution = root(phi, q, args=(t,), method="hybr", options={"xtol": 1e-13})
        q = solution.x
        matrix = approx_fprime(q, phi, 1e-8, t)
        phi_t = (phi(q, t + h) - phi(q, t - h)) / (2 * h)
        velocities.append(np.linalg.solve(matrix, -phi_t))
        tips.append(_tip(q, n))
        evaluations.append(solution.nfev)
    trajectory = time.perf_counter() - start
    return {
        "build": build,
        "trajectory": trajectory,
        "iterations": float(np.mean(evaluations)),
        "error": _tip_error(n, times, np.array(tips)),
        "note": "iterations = Phi evaluations per step; acceleration not computed",
    }
