"""Telling singularities apart, with the evidence printed.

* representation singularity: Phi_q loses column rank in one parametrization but has full
  column rank in another at the same physical configuration (gimbal lock of Euler angles);
* mechanism singularity: column rank is lost in every parametrization, and only at this
  pose (configurations a little earlier and later along the case have full rank): a
  dead centre or toggle position;
* redundant constraints: more equations than the rank, the residual is zero (the
  equations are consistent) and the same equations stay dependent at nearby
  configurations: they can be removed without changing the motion.

A singular pose is never reported as a redundant constraint: both the residual and the
persistence of the dependency across nearby configurations are checked.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kinegen.analysis.inspect import Inspection, configuration_at, convert, inspect
from kinegen.errors import ConvergenceError, SingularJacobianError, bodies_in
from kinegen.model import Model
from kinegen.rotations import REFERENCE, Parametrization, get
from kinegen.runtime import NumericSystem, Solver

REPRESENTATION = "representation singularity"
MECHANISM = "mechanism singularity"
REDUNDANT = "redundant constraints"
REGULAR = "regular"


@dataclass
class Classification:
    """The verdict and the evidence behind it."""

    kind: str
    evidence: list[str] = field(default_factory=list)
    dependent_constraints: list[str] = field(default_factory=list)

    def text(self) -> str:
        return "\n".join([f"classification: {self.kind}", *(f"  {line}" for line in self.evidence)])


def _numeric_rank(system: NumericSystem, q: np.ndarray, u: np.ndarray, tolerance: float = 1e-9) -> tuple[int, float, list[str]]:
    """Rank, sigma_min/sigma_max and dependent constraints of Phi_q at (q, u), in double precision."""
    jacobian = system.jacobian(q, u)
    left, sigma, _ = np.linalg.svd(jacobian)
    rank = int(np.sum(sigma > tolerance * sigma[0]))
    dependent = sorted(
        {system.constraint_names[i] for k in range(rank, jacobian.shape[0]) for i in np.flatnonzero(np.abs(left[:, k]) > 1e-6)}
    )
    return rank, float(sigma[min(jacobian.shape) - 1] / sigma[0]), dependent


def _nearby(system: NumericSystem, q: np.ndarray, t: float, delta: float) -> list[tuple[float, int, float, list[str]]]:
    """(time, rank, sigma ratio, dependent constraints) at configurations solved at t -+ delta."""
    solver = Solver(system)
    rng = np.random.default_rng(0)
    found = []
    for when in (t - delta, t + delta):
        u = system.driver_inputs(when)[0]
        start = solver.retract(q, 1e-4 * rng.standard_normal(system.n_velocity))  # leave an exactly singular start
        try:
            solved, _, _ = solver.position(start, u, when)
        except (ConvergenceError, SingularJacobianError):
            continue
        found.append((when, *_numeric_rank(system, solved, u)))
    return found


def classify(
    model: Model,
    parametrization: Parametrization,
    case: str,
    t: float,
    report: Inspection | None = None,
    numeric: NumericSystem | None = None,
    others: tuple[str, ...] = (REFERENCE, "euler-parameters"),
    physical: np.ndarray | None = None,
    system_of: Callable[[str], NumericSystem | None] | None = None,
) -> Classification:
    """Classify Phi_q of ``case`` at time ``t``.

    ``report`` is an inspection already made in ``parametrization``; ``physical`` the
    configuration in quaternion coordinates (default: solved at ``t``). A model with design
    parameters is classified at their nominal values. ``system_of(name)``: the case's numeric system
    in another parametrization (e.g. from its generated module), or None; the rank there is then
    taken from it instead of from functions lambdified for this call (~2.7 s for the excavator).
    """
    from kinegen.codegen.inmemory import lambdify_model
    from kinegen.runtime import from_module

    model = model.at() if model.design else model
    quaternion = get(REFERENCE)
    numeric = numeric or from_module(lambdify_model(model, quaternion), case)
    if physical is None:
        physical = configuration_at(model, quaternion, case, t, numeric)
    if report is None:
        own = convert(physical, quaternion, parametrization, len(model.bodies))
        report = inspect(model, parametrization, case, t, own, numeric)
    m, n = report.jacobian.shape
    name = parametrization.name
    evidence = [f"{name}: rank {report.rank} of {m} x {n} ({report.rank_method})"]
    if report.rank == n == m:
        return Classification(REGULAR, evidence)
    u = numeric.driver_inputs(t)[0]
    if report.rank < n:
        regular_elsewhere = []
        for other_name in others:
            other = get(other_name)
            if other.name == name:
                continue
            system = numeric if other.name == quaternion.name else (system_of and system_of(other.name))
            system = system or from_module(lambdify_model(model, other), case)
            q_other = convert(physical, quaternion, other, len(model.bodies))
            rank, ratio, _ = _numeric_rank(system, q_other, u)
            evidence.append(
                f"{other.name}: rank {rank} of {len(system.constraint_names)} x {system.n_velocity} at the same physical "
                f"configuration (double precision, sigma_min/sigma_max = {abs(ratio):.1e})"
            )
            if rank == system.n_velocity:
                regular_elsewhere.append(other.name)
        if regular_elsewhere:
            bodies = sorted({b for block in report.singular_blocks for b in block.bodies}) or bodies_in(report.null_space)
            evidence.append(
                f"singular only in {name}: its coordinates of {', '.join(bodies) or 'the bodies named above'} are degenerate here"
            )
            return Classification(REPRESENTATION, evidence, report.dependent_constraints)
    # every parametrization (or only rows) is rank-deficient: residual and neighbourhood decide
    residual = float(np.max(np.abs(numeric.phi(physical, u))))
    evidence.append(f"max |Phi| at this configuration = {residual:.1e}")
    rank_here, ratio_here, dependent_here = _numeric_rank(numeric, physical, u)
    evidence.append(f"here: rank {rank_here} (double precision, sigma_min/sigma_max = {abs(ratio_here):.1e})")
    span = max(numeric.t1 - numeric.t0, 1e-9)
    nearby = _nearby(numeric, physical, t, 0.01 * span)
    for when, rank, ratio, dependent in nearby:
        evidence.append(
            f"nearby t = {when:.6g}: rank {rank} (sigma_min/sigma_max = {abs(ratio):.1e}), dependent: {', '.join(dependent) or '-'}"
        )
    persistent = bool(nearby) and all(rank == rank_here and dependent == dependent_here for _, rank, _, dependent in nearby)
    if rank_here == n and residual <= 1e-8 and persistent:
        evidence.append(
            f"{m - rank_here} equation(s) depend on the others everywhere nearby and are satisfied: removable without changing the motion"
        )
        return Classification(REDUNDANT, evidence, dependent_here)
    if residual > 1e-8:
        evidence.append("the constraints are not satisfied here: not a solved configuration")
    evidence.append("rank is lost in every parametrization" + (" and only at this pose" if not persistent else ", persistently"))
    return Classification(MECHANISM, evidence, dependent_here)
