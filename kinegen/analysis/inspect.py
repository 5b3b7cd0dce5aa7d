"""Exact inspection of Phi_q at one configuration: rank, null spaces, determinant.

The configuration is taken exactly: numeric coordinates are converted back to exact
numbers (``1.78`` -> ``89/50``, ``0.7071...`` -> ``sqrt(2)/2``, ``1.5707...`` -> ``pi/2``)
and the symbolic Jacobian is evaluated in exact arithmetic, so a rank deficiency is a
proof, not a floating-point guess.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from kinegen.codegen.inmemory import lambdify_model
from kinegen.model import Model
from kinegen.rotations import Parametrization
from kinegen.runtime import Solver, from_module
from kinegen.symbolic import System, build_systems

#: Largest Phi_q whose determinant is expanded directly.
MAX_DIRECT_DETERMINANT = 12


def exact_number(value: float) -> sp.Expr:
    """The simple exact number (rational, surd, multiple of pi) equal to ``value`` to 1e-13."""
    if value == 0:
        return sp.Integer(0)
    guess = sp.nsimplify(value, [sp.pi], tolerance=1e-13, rational=False)
    if abs(float(guess) - value) <= 1e-12 * max(1.0, abs(value)):
        return guess
    return sp.Rational(repr(float(value)))


def configuration_at(model: Model, parametrization: Parametrization, case: str, t: float) -> np.ndarray:
    """Stored coordinates at time ``t``: the initial pose if it satisfies Phi there, else a solve."""
    system = from_module(lambdify_model(model, parametrization), case)
    q0 = system.initial_q
    if np.max(np.abs(system.phi(q0, system.driver_inputs(t)[0]))) <= 1e-10:
        return q0
    steps = max(2, int(abs(t - system.t0) / max(system.t1 - system.t0, 1e-12) * (system.steps - 1)) + 1)
    return Solver(system).solve(np.linspace(system.t0, t, steps)).q[-1]


def _combination(vector: sp.Matrix, names: list[str]) -> str:
    pivot = next(x for x in vector if x != 0)
    terms = [sp.nsimplify(sp.simplify(c / pivot)) * sp.Symbol(n) for c, n in zip(vector, names) if c != 0]
    return sp.sstr(sp.Add(*terms))


@dataclass
class Inspection:
    """What ``kinegen inspect`` found."""

    system: System
    t: sp.Expr
    q: list[sp.Expr]
    jacobian: sp.Matrix  # exact, at the configuration
    rank: int
    null_space: list[str]
    dependent_constraints: list[str]
    determinant: sp.Expr | None = None  # symbolic, simplified and factored
    determinant_value: sp.Expr | None = None
    vanishing_factors: list[sp.Expr] = field(default_factory=list)

    @property
    def velocity_names(self) -> list[str]:
        return self.system.coordinates.velocity_names

    @property
    def singular(self) -> bool:
        return self.rank < min(self.jacobian.shape)

    def text(self) -> str:
        """Readable report; the matrix is printed in full when it is small."""
        coords, names = self.system.coordinates, self.system.constraint_names
        m, n = self.jacobian.shape
        lines = [
            f"model {self.system.model.name}, case {self.system.case.name}, "
            f"parametrization {coords.parametrization.name}, t = {sp.sstr(self.t)}",
            "configuration (exact): " + ", ".join(f"{k} = {sp.sstr(v)}" for k, v in zip(coords.stored_names, self.q)),
            f"Phi_q: {m} x {n}, exact rank {self.rank}" + (" (singular)" if self.singular else " (full rank)"),
        ]
        if n <= 16:
            cells = [[sp.sstr(self.jacobian[i, j]) for j in range(n)] for i in range(m)]
            width = [max(len(self.velocity_names[j]), *(len(cells[i][j]) for i in range(m))) for j in range(n)]
            label = max(len(x) for x in names)
            lines.append(" " * (label + 2) + "  ".join(h.rjust(w) for h, w in zip(self.velocity_names, width)))
            for i in range(m):
                lines.append(f"{names[i].ljust(label)}  " + "  ".join(c.rjust(w) for c, w in zip(cells[i], width)))
        if self.determinant is not None:
            lines.append(f"det Phi_q (symbolic, factored) = {sp.sstr(self.determinant)}")
            lines.append(f"det Phi_q at this configuration = {sp.sstr(self.determinant_value)}")
            for factor in self.vanishing_factors:
                lines.append(f"vanishing factor: {sp.sstr(factor)}")
        elif m == n:
            lines.append(f"det Phi_q: not expanded symbolically ({n} > {MAX_DIRECT_DETERMINANT} coordinates)")
        if self.singular:
            lines.append("null space (coordinate combinations Phi_q cannot see): " + "; ".join(self.null_space))
            lines.append("dependent constraints (left null space): " + ", ".join(self.dependent_constraints))
        return "\n".join(lines)

    def latex(self) -> str:
        """LaTeX of the determinant (or of Phi_q when there is no determinant)."""
        if self.determinant is not None:
            return r"\det \Phi_q = " + sp.latex(self.determinant)
        return r"\Phi_q = " + sp.latex(self.jacobian)

    def to_json(self) -> dict[str, Any]:
        """Machine-readable report (expressions as SymPy strings)."""
        return {
            "model": self.system.model.name,
            "case": self.system.case.name,
            "parametrization": self.system.coordinates.parametrization.name,
            "t": sp.sstr(self.t),
            "configuration": dict(zip(self.system.coordinates.stored_names, map(sp.sstr, self.q))),
            "constraints": self.system.constraint_names,
            "coordinates": self.velocity_names,
            "jacobian": [[sp.sstr(x) for x in row] for row in self.jacobian.tolist()],
            "rank": self.rank,
            "singular": self.singular,
            "null_space": self.null_space,
            "dependent_constraints": self.dependent_constraints,
            "determinant": None if self.determinant is None else sp.sstr(self.determinant),
            "determinant_value": None if self.determinant_value is None else sp.sstr(self.determinant_value),
            "vanishing_factors": [sp.sstr(f) for f in self.vanishing_factors],
        }

    def json_text(self) -> str:
        return json.dumps(self.to_json(), indent=2)


def inspect(
    model: Model, parametrization: Parametrization, case: str | None = None, t: str | float = 0, q: np.ndarray | None = None
) -> Inspection:
    """Inspect Phi_q of ``model`` at time ``t`` (exact expression) or at the given coordinates ``q``."""
    from kinegen.model.expressions import parse

    case = case or next(iter(model.cases))
    system = build_systems(model, parametrization, [case])[case]
    t_exact = parse(t, allow_time=False) if isinstance(t, str) else exact_number(float(t))
    if q is None:
        q = configuration_at(model, parametrization, case, float(t_exact))
    q_exact = [exact_number(float(x)) for x in q]
    values = dict(zip(system.coordinates.stored_symbols, q_exact))
    values.update(system.inputs.at_time(t_exact))
    symbolic = system.jacobian_matrix()
    exact = symbolic.xreplace(values).applyfunc(lambda e: sp.nsimplify(sp.simplify(e)))
    rank = exact.rank(simplify=True)
    null = [_combination(v, system.coordinates.velocity_names) for v in exact.nullspace(simplify=True)]
    dependent: list[str] = []
    for v in exact.T.nullspace(simplify=True):
        dependent += [n for x, n in zip(v, system.constraint_names) if x != 0 and n not in dependent]
    inspection = Inspection(system, t_exact, q_exact, exact, rank, null, dependent)
    m, n = exact.shape
    if m == n and n <= MAX_DIRECT_DETERMINANT:
        named = {u: sp.Symbol(name, real=True) for u, name in zip(system.inputs.u, system.inputs.names)}
        values.update({named[u]: values[u] for u in system.inputs.u})
        det = symbolic.xreplace(named).det(method="berkowitz")
        det = sp.factor(sp.trigsimp(sp.simplify(det)))
        inspection.determinant = det
        inspection.determinant_value = sp.simplify(det.xreplace(values))
        _, factors = sp.factor_list(det)
        inspection.vanishing_factors = [f for f, _ in factors if sp.simplify(f.xreplace(values)) == 0]
    return inspection
