"""Which joints' equations depend on each other: the rank of the joint rows of Φ_q at a model's
initial pose, for the message of an over-constrained model (the loader asks only when the count
of equations and coordinates does not match its drivers or actuators).

The joint rows (and the parametrization's normalization rows) of the reference parametrization
are derived exactly and evaluated at the initial pose as given (design parameters at their nominal
values). Their rank is the number of singular values above 1e-9 of the largest; a row belongs to a
dependency when it carries weight (above 1e-6) in a left null vector -- the rows that repeat each
other, named by their joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from kinegen import rotations
from kinegen.errors import ModelError, OverConstrainedError
from kinegen.interface import row_owner
from kinegen.model.schema import Model
from kinegen.symbolic.assembly import coordinates, kinematic_rows

#: singular values below this fraction of the largest count as zero
RANK_TOLERANCE = 1e-9


@dataclass(frozen=True)
class JointRank:
    """The joint rows' rank at the initial pose and the joints whose equations repeat each other."""

    equations: int  #: joint equations (normalization rows left out)
    coordinates: int  #: 6 per body
    rank: int  #: independent joint equations
    dependent: tuple[str, ...]  #: joints with an equation in a dependency, in the model's order

    @property
    def mobility(self) -> int:
        """Degrees of freedom the independent equations leave."""
        return self.coordinates - self.rank

    def describe(self) -> str:
        """In words: "joints D, D2 repeat 3 of their equations (rank of Phi_q at the initial pose: 17 of 20)"."""
        if self.rank == self.equations:
            return f"all {self.equations} joint equations are independent (rank of Phi_q at the initial pose)"
        return (f"joints {', '.join(self.dependent)} repeat {self.equations - self.rank} of their equations "
                f"(rank of Phi_q at the initial pose: {self.rank} of {self.equations})")


def joint_rank(model: Model) -> JointRank:
    """The rank of ``model``'s joint rows at its initial pose and the joints in its dependencies."""
    from kinegen.codegen.kernels import initial_q

    model = model.at() if model.design else model
    parametrization = rotations.get(rotations.REFERENCE)
    coords = coordinates(model, parametrization)
    rows = kinematic_rows(model, coords)
    values = dict(zip(coords.stored_symbols, (sp.Float(x, 17) for x in initial_q(model, parametrization))))
    definitions = {s: e.xreplace(values) for s, e in coords.frame_definitions.items()}
    jacobian = np.zeros((len(rows), len(coords.velocity_symbols)))
    for i, row in enumerate(rows):
        for column, expr in row.jacobian.items():
            jacobian[i, column] = float(expr.xreplace(definitions).xreplace(values))
    u, s, _ = np.linalg.svd(jacobian)
    rank = int(np.sum(s > RANK_TOLERANCE * s[0])) if len(s) else 0
    null = u[:, rank:]
    involved = {row_owner(rows[i].name)[0] for i in range(len(rows)) if np.linalg.norm(null[i]) > 1e-6 and not row_owner(rows[i].name)[1]}
    normalization = sum(row_owner(r.name)[1] for r in rows)
    return JointRank(len(rows) - normalization, 6 * len(model.bodies), rank - normalization,
                     tuple(j.name for j in model.joints if j.name in involved))  # fmt: skip


def explain(error: OverConstrainedError) -> ModelError:
    """``error`` in the words of the mistake: which joints' equations repeat each other at the
    initial pose, and whether the independent ones leave the freedom the drivers need (then
    ``redundant: true`` would do); the count's message when the rank cannot be found."""
    try:
        rank = joint_rank(error.stand_in)
    except (ModelError, ArithmeticError, ValueError, TypeError, KeyError, np.linalg.LinAlgError):
        return error
    if rank.rank < rank.equations and rank.mobility == error.count:
        problem = (f"over-constrained: {rank.describe()}; the others leave {rank.mobility} degree(s) of freedom for the "
                   f"{error.count} {error.what}: remove the repeated equations (a joint twice; in a planar loop of revolutes "
                   "make one spherical or universal), or declare `redundant: true`")  # fmt: skip
    else:
        problem = f"{error.problem}; {rank.describe()}"
    return ModelError(error.file, error.entry, problem, error.line)
