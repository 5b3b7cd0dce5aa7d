"""Joint (kinematic) constraint equations, each in the coordinates of its two bodies.

Notation: joint points P1 (body 1) and P2 (body 2); unit axes h1, h2; reference
vectors f1 (perpendicular to h1), g1 = h1 x f1; f2, g2 likewise on body 2.

=============  =========================================================  =========
joint          equations                                                  count
=============  =========================================================  =========
spherical      P1 - P2 = 0                                                3
revolute       P1 - P2 = 0, h1.f2 = 0, h1.g2 = 0                          5
cylindrical    h1.f2 = 0, h1.g2 = 0, f1.d = 0, g1.d = 0 (d = P2 - P1)     4
prismatic      cylindrical + f1.u2 = 0 (u2 = g1 at the initial pose)      5
universal      P1 - P2 = 0, h1.h2 = 0                                     4
fixed          P1 - P2 = 0, x1.u2y = 0, y1.u2z = 0, z1.u2x = 0             6
distance       |P1 - P2|^2 - L^2 = 0                                      1
=============  =========================================================  =========

With the revolute equations written this way, the boom of the paper has exactly the
Jacobian of its eq. (19) in the quaternion parametrization.
"""

from __future__ import annotations

import sympy as sp

from kinegen.constraints.frames import Equation, Frame, cross, dot
from kinegen.model.schema import Joint


def joint_equations(joint: Joint, frame1: Frame, frame2: Frame, moving: tuple[str, ...]) -> list[Equation]:
    """The equations of ``joint`` given the two body frames; ``moving`` names its moving bodies."""
    n = joint.name

    def eq(suffix: str, expr: sp.Expr) -> Equation:
        return Equation(f"{n}.{suffix}", moving, expr)

    equations: list[Equation] = []
    if joint.type in ("spherical", "revolute", "universal", "fixed"):
        gap = frame1.point(joint.point1) - frame2.point(joint.point2)
        equations += [eq(axis, gap[i]) for i, axis in enumerate("xyz")]
    if joint.type in ("revolute", "cylindrical", "prismatic"):
        h1 = frame1.vector(joint.axis1)
        f2 = frame2.vector(joint.reference2)
        g2 = frame2.vector(cross(joint.axis2, joint.reference2))
        equations += [eq("axis_f", dot(h1, f2)), eq("axis_g", dot(h1, g2))]
    if joint.type in ("cylindrical", "prismatic"):
        d = frame2.point(joint.point2) - frame1.point(joint.point1)
        f1 = frame1.vector(joint.reference1)
        g1 = frame1.vector(cross(joint.axis1, joint.reference1))
        equations += [eq("line_f", dot(f1, d)), eq("line_g", dot(g1, d))]
    if joint.type == "prismatic":
        f1 = frame1.vector(joint.reference1)
        equations.append(eq("roll", dot(f1, frame2.vector(joint.lock2[1]))))
    if joint.type == "universal":
        equations.append(eq("cross", dot(frame1.vector(joint.axis1), frame2.vector(joint.axis2))))
    if joint.type == "fixed":
        x1, y1, z1 = (frame1.vector(sp.eye(3)[:, i]) for i in range(3))
        u2x, u2y, u2z = (frame2.vector(v) for v in joint.lock2)
        equations += [eq("rot_xy", dot(x1, u2y)), eq("rot_yz", dot(y1, u2z)), eq("rot_zx", dot(z1, u2x))]
    if joint.type == "distance":
        gap = frame1.point(joint.point1) - frame2.point(joint.point2)
        equations.append(eq("length", dot(gap, gap) - joint.length**2))
    return equations
