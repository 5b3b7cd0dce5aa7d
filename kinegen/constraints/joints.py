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

from collections.abc import Callable

import sympy as sp

from kinegen.constraints.drivers import exact_quaternion
from kinegen.constraints.frames import Equation, Frame, cross, dot
from kinegen.model.kinds import JOINT_KINDS, check_registered, registrar
from kinegen.model.schema import Joint
from kinegen.rotations.quaternion_algebra import symbolic_conjugate, symbolic_product

#: a kind's equations: (joint, frame 1, frame 2, whether a frame is a dual quaternion) -> (suffix, expression) rows
Builder = Callable[[Joint, Frame, Frame, bool], list[tuple[str, sp.Expr]]]
#: the equations of every joint kind (kinegen.model.kinds.JOINT_KINDS lists the kinds)
BUILDERS: dict[str, Builder] = {}

_builds = registrar(BUILDERS)


def joint_equations(joint: Joint, frame1: Frame, frame2: Frame, moving: tuple[str, ...]) -> list[Equation]:
    """The equations of ``joint`` given the two body frames; ``moving`` names its moving bodies."""
    unified = bool(frame1.unified or frame2.unified)
    return [Equation(f"{joint.name}.{suffix}", moving, expr) for suffix, expr in BUILDERS[joint.type](joint, frame1, frame2, unified)]


def _gap(joint: Joint, frame1: Frame, frame2: Frame) -> sp.Matrix:
    """P1 - P2, global."""
    return frame1.point(joint.point1) - frame2.point(joint.point2)


def _points(joint: Joint, frame1: Frame, frame2: Frame) -> list[tuple[str, sp.Expr]]:
    """P1 - P2 = 0."""
    gap = _gap(joint, frame1, frame2)
    return [(axis, gap[i]) for i, axis in enumerate("xyz")]


def _axes(joint: Joint, frame1: Frame, frame2: Frame) -> list[tuple[str, sp.Expr]]:
    """h1.f2 = 0, h1.g2 = 0: the axes aligned."""
    h1 = frame1.vector(joint.axis1)
    f2 = frame2.vector(joint.reference2)
    g2 = frame2.vector(cross(joint.axis2, joint.reference2))
    return [("axis_f", dot(h1, f2)), ("axis_g", dot(h1, g2))]


def _line(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    """The axis of body 2 on body 1's axis line: as dual numbers where a frame is a dual quaternion."""
    if unified:
        axis2 = frame2.line(joint.point2, joint.axis2)
        f_line = frame1.line(joint.point1, joint.reference1)
        g_line = frame1.line(joint.point1, cross(joint.axis1, joint.reference1))
        (f_real, f_dual), (g_real, g_dual) = f_line.dual_dot(axis2), g_line.dual_dot(axis2)
        return [("axis_f", f_real), ("axis_g", g_real), ("line_f", f_dual), ("line_g", g_dual)]
    d = frame2.point(joint.point2) - frame1.point(joint.point1)
    f1 = frame1.vector(joint.reference1)
    g1 = frame1.vector(cross(joint.axis1, joint.reference1))
    return [*_axes(joint, frame1, frame2), ("line_f", dot(f1, d)), ("line_g", dot(g1, d))]


@_builds("spherical")
def _spherical(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    return _points(joint, frame1, frame2)


@_builds("revolute")
def _revolute(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    return [*_points(joint, frame1, frame2), *_axes(joint, frame1, frame2)]


@_builds("cylindrical")
def _cylindrical(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    return _line(joint, frame1, frame2, unified)


@_builds("prismatic")
def _prismatic(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    roll = dot(frame1.vector(joint.reference1), frame2.vector(joint.lock2[1]))
    return [*_line(joint, frame1, frame2, unified), ("roll", roll)]


@_builds("universal")
def _universal(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    return [*_points(joint, frame1, frame2), ("cross", dot(frame1.vector(joint.axis1), frame2.vector(joint.axis2)))]


@_builds("fixed")
def _fixed(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    rows = _points(joint, frame1, frame2)
    if unified:  # σ1* ⊗ σ2 = σ0: its translation by the coincident points, its rotation here
        zero_angle = exact_quaternion(sp.Matrix.hstack(*(sp.Matrix(v) for v in joint.lock2)).T)
        relative = symbolic_product(symbolic_product(symbolic_conjugate(frame1.e), frame2.e), symbolic_conjugate(zero_angle))
        return rows + [(f"rot_{axis}", 2 * relative[1 + i]) for i, axis in enumerate("xyz")]
    x1, y1, z1 = (frame1.vector(sp.eye(3)[:, i]) for i in range(3))
    u2x, u2y, u2z = (frame2.vector(v) for v in joint.lock2)
    return rows + [("rot_xy", dot(x1, u2y)), ("rot_yz", dot(y1, u2z)), ("rot_zx", dot(z1, u2x))]


@_builds("distance")
def _distance(joint: Joint, frame1: Frame, frame2: Frame, unified: bool) -> list[tuple[str, sp.Expr]]:
    gap = _gap(joint, frame1, frame2)
    return [("length", dot(gap, gap) - joint.length**2)]


check_registered("kinegen.constraints.joints", JOINT_KINDS, BUILDERS)
