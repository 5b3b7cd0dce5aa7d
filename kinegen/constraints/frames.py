"""Symbolic body poses used by the constraint equations."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


@dataclass(frozen=True)
class Frame:
    """Pose of a body: origin ``r`` (3x1) and rotation ``A`` (body -> global), symbolic."""

    r: sp.Matrix
    A: sp.Matrix
    #: unit quaternion (w, x, y, z) of A when the parametrization stores one, else None
    e: sp.Matrix | None = None

    def point(self, local: sp.Matrix) -> sp.Matrix:
        """Global position of a body point given in body coordinates."""
        return self.r + self.A * local

    def vector(self, local: sp.Matrix) -> sp.Matrix:
        """Global direction of a body vector given in body coordinates."""
        return self.A * local


GROUND_FRAME = Frame(sp.zeros(3, 1), sp.eye(3), sp.Matrix([1, 0, 0, 0]))


def dot(a: sp.Matrix, b: sp.Matrix) -> sp.Expr:
    """Scalar product of two 3x1 columns."""
    return (a.T * b)[0]


def cross(a: sp.Matrix, b: sp.Matrix) -> sp.Matrix:
    """Vector product of two 3x1 columns."""
    return sp.Matrix(a).cross(sp.Matrix(b))


@dataclass(frozen=True)
class Equation:
    """One scalar constraint equation ``expr(q, t) = 0`` and the moving bodies it touches."""

    name: str
    bodies: tuple[str, ...]
    expr: sp.Expr
