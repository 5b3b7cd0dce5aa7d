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

Where a body's pose is one dual quaternion σ (``Frame.unified``: the parametrizations
``dual-quaternion`` and ``dual-euler-parameters``), the equations are written in its terms:
points moved by σ (:meth:`Frame.point`), joint axes as lines (dual vectors, Plücker
coordinates) moved by σ (:meth:`Frame.line`), a weld as the relative pose σ1* ⊗ σ2:

=============  =========================================================  =========
cylindrical    H2·F1 = 0, H2·G1 = 0 as dual numbers: the axis line of       4
               body 2 meets body 1's lines F1, G1 (through P1 along f1,
               g1) at right angles, so it is body 1's axis line; real
               parts axis_f, axis_g, dual parts line_f, line_g
prismatic      cylindrical + f1.u2 = 0                                    5
revolute       P1 - P2 = 0 and the real parts of H1·F2, H1·G2 (their       5
               dual parts vanish once the points coincide): the relative
               screw is a pure rotation about the common axis line
universal      P1 - P2 = 0 and the real part of H1·H2                     4
fixed          P1 - P2 = 0, 2 vec(q_r1* ⊗ q_r2 ⊗ p0*) = 0 (p0: the         6
               relative rotation at the initial pose) -- σ1* ⊗ σ2 fixed
=============  =========================================================  =========

(Revolute and universal rows are then the same expressions as above.)
"""

from __future__ import annotations

import sympy as sp

from kinegen.constraints.drivers import exact_quaternion
from kinegen.constraints.frames import Equation, Frame, cross, dot
from kinegen.model.schema import Joint
from kinegen.rotations.quaternion_algebra import symbolic_conjugate, symbolic_product


def joint_equations(joint: Joint, frame1: Frame, frame2: Frame, moving: tuple[str, ...]) -> list[Equation]:
    """The equations of ``joint`` given the two body frames; ``moving`` names its moving bodies."""
    n = joint.name

    def eq(suffix: str, expr: sp.Expr) -> Equation:
        return Equation(f"{n}.{suffix}", moving, expr)

    unified = frame1.unified or frame2.unified
    equations: list[Equation] = []
    if joint.type in ("spherical", "revolute", "universal", "fixed"):
        gap = frame1.point(joint.point1) - frame2.point(joint.point2)
        equations += [eq(axis, gap[i]) for i, axis in enumerate("xyz")]
    if joint.type == "revolute" or (joint.type in ("cylindrical", "prismatic") and not unified):
        h1 = frame1.vector(joint.axis1)
        f2 = frame2.vector(joint.reference2)
        g2 = frame2.vector(cross(joint.axis2, joint.reference2))
        equations += [eq("axis_f", dot(h1, f2)), eq("axis_g", dot(h1, g2))]
    if joint.type in ("cylindrical", "prismatic") and unified:
        axis2 = frame2.line(joint.point2, joint.axis2)
        f_line = frame1.line(joint.point1, joint.reference1)
        g_line = frame1.line(joint.point1, cross(joint.axis1, joint.reference1))
        (f_real, f_dual), (g_real, g_dual) = f_line.dual_dot(axis2), g_line.dual_dot(axis2)
        equations += [eq("axis_f", f_real), eq("axis_g", g_real), eq("line_f", f_dual), eq("line_g", g_dual)]
    elif joint.type in ("cylindrical", "prismatic"):
        d = frame2.point(joint.point2) - frame1.point(joint.point1)
        f1 = frame1.vector(joint.reference1)
        g1 = frame1.vector(cross(joint.axis1, joint.reference1))
        equations += [eq("line_f", dot(f1, d)), eq("line_g", dot(g1, d))]
    if joint.type == "prismatic":
        f1 = frame1.vector(joint.reference1)
        equations.append(eq("roll", dot(f1, frame2.vector(joint.lock2[1]))))
    if joint.type == "universal":
        equations.append(eq("cross", dot(frame1.vector(joint.axis1), frame2.vector(joint.axis2))))
    if joint.type == "fixed" and unified:
        # σ1* ⊗ σ2 = σ0: its translation by the coincident points, its rotation here
        zero_angle = exact_quaternion(sp.Matrix.hstack(*(sp.Matrix(v) for v in joint.lock2)).T)
        relative = symbolic_product(symbolic_product(symbolic_conjugate(frame1.e), frame2.e), symbolic_conjugate(zero_angle))
        equations += [eq(f"rot_{axis}", 2 * relative[1 + i]) for i, axis in enumerate("xyz")]
    elif joint.type == "fixed":
        x1, y1, z1 = (frame1.vector(sp.eye(3)[:, i]) for i in range(3))
        u2x, u2y, u2z = (frame2.vector(v) for v in joint.lock2)
        equations += [eq("rot_xy", dot(x1, u2y)), eq("rot_yz", dot(y1, u2z)), eq("rot_zx", dot(z1, u2x))]
    if joint.type == "distance":
        gap = frame1.point(joint.point1) - frame2.point(joint.point2)
        equations.append(eq("length", dot(gap, gap) - joint.length**2))
    return equations
