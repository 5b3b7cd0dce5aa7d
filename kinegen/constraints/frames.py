"""Symbolic body poses used by the constraint equations."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp


@dataclass(frozen=True)
class Line:
    """A line as a dual vector: unit direction ``l`` and moment ``m = P × l`` (its Plücker
    coordinates, global) with ``P`` a point on it, kept to write the moment terms compactly."""

    point: sp.Matrix
    direction: sp.Matrix

    @property
    def moment(self) -> sp.Matrix:
        return cross(self.point, self.direction)

    def dual_dot(self, other: Line) -> tuple[sp.Expr, sp.Expr]:
        """The dual scalar product ``L1·L2 = l1·l2 + ε (l1·m2 + m1·l2)`` = cos of the dual angle
        (θ + ε d) = cos θ − ε d sin θ, as (real part, dual part). It vanishes as a dual number
        exactly when the lines meet at a right angle. The dual part is written
        ``(P2 − P1)·(l2 × l1)``, the same number without the moments' large cancelling terms."""
        return dot(self.direction, other.direction), dot(other.point - self.point, cross(other.direction, self.direction))


@dataclass(frozen=True)
class Frame:
    """Pose of a body: origin ``r`` (3x1) and rotation ``A`` (body -> global), symbolic.

    For the dual-quaternion parametrizations (``unified``) ``r`` and ``A`` are the symbols of
    the pose σ = q_r + ε q_d (``r = 2 vec(q_d ⊗ q_r*)``, ``A = A(q_r)``), so :meth:`point` is the
    sandwich σ ⊗ (1 + ε p) ⊗ σ̄* and :meth:`line` the sandwich σ ⊗ L ⊗ σ* of a line, written out.
    """

    r: sp.Matrix
    A: sp.Matrix
    #: unit quaternion (w, x, y, z) of A when the parametrization stores one, else None
    e: sp.Matrix | None = None
    #: True when the body's pose is one dual quaternion: joints use the line and relative-pose forms
    unified: bool = False

    def point(self, local: sp.Matrix) -> sp.Matrix:
        """Global position of a body point given in body coordinates."""
        return self.r + self.A * local

    def vector(self, local: sp.Matrix) -> sp.Matrix:
        """Global direction of a body vector given in body coordinates."""
        return self.A * local

    def line(self, local_point: sp.Matrix, local_direction: sp.Matrix) -> Line:
        """The body's line through ``local_point`` along ``local_direction``, moved to the global
        frame: direction ``A h``, moment ``A (p × h) + r × A h`` = ``P × A h``."""
        return Line(self.point(local_point), self.vector(local_direction))


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
