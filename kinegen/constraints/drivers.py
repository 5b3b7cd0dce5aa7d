"""Driving constraint equations ``Phi_D(q, t) = 0``.

Joint angles, when both bodies carry a quaternion (Euler parameters, quaternion), use the
half-angle form of the relative quaternion ``p = conj(e1) ⊗ e2 ⊗ conj(p0)`` (``p0`` the
relative rotation at zero angle, from the joint's references):
``2 (sin(theta/2) p_w - cos(theta/2) h1·p_v) = 2 sin((theta - phi)/2)``. It is polynomial
in q, valid for every angle and has the single root phi = theta (mod 2 pi); the factor 2
gives it unit slope at the root, like ``sin(theta - phi)``. This is the chain-N
benchmark's driver (``docs/chain-N.md``).

Otherwise (Euler angles; body angles) rotation drivers use ``sin(theta(t) - phi) = 0``
written with dot products (``sin(theta) f1.f2 - cos(theta) g1.f2``), where ``phi`` is the
rotation of f2 away from f1 about h1. It holds for every angle; its other root,
phi = theta + pi, lies half a turn away from the trajectory the solver tracks.
Distances use ``|P1 - P2|^2 - L(t)^2``; coordinates ``P[k] - x(t)``.
"""

from __future__ import annotations

from collections.abc import Callable

import mpmath
import sympy as sp

from kinegen.constraints.frames import Equation, Frame, cross, dot
from kinegen.model.kinds import DRIVER_KINDS, check_registered, registrar
from kinegen.model.schema import Driver, Joint
from kinegen.rotations.quaternion_algebra import symbolic_conjugate as conjugate
from kinegen.rotations.quaternion_algebra import symbolic_product as quaternion_product


def _angle_residual(theta: sp.Expr, f1: sp.Matrix, g1: sp.Matrix, f2: sp.Matrix) -> sp.Expr:
    return sp.sin(theta) * dot(f1, f2) - sp.cos(theta) * dot(g1, f2)


def exact_quaternion(rotation: sp.Matrix) -> sp.Matrix:
    """Unit quaternion (w, x, y, z), w >= 0, of an exact rotation matrix (Shepperd's method).

    The identity gives (1, 0, 0, 0) exactly; otherwise the components are computed to 40
    digits and kept as exact decimal rationals.
    """
    if rotation == sp.eye(3):
        return sp.Matrix([1, 0, 0, 0])
    with mpmath.workdps(40):
        m = [[mpmath.mpf(sp.N(rotation[i, j], 45)) for j in range(3)] for i in range(3)]
        trace = m[0][0] + m[1][1] + m[2][2]
        k = max(range(4), key=lambda i: trace if i == 0 else m[i - 1][i - 1])
        if k == 0:
            w = mpmath.sqrt(1 + trace) / 2
            q = [w, (m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w), (m[1][0] - m[0][1]) / (4 * w)]
        else:
            i, j, k2 = k - 1, k % 3, (k + 1) % 3
            x = mpmath.sqrt(1 + 2 * m[i][i] - trace) / 2
            q = [0, 0, 0, 0]
            q[0], q[1 + i] = (m[k2][j] - m[j][k2]) / (4 * x), x
            q[1 + j], q[1 + k2] = (m[j][i] + m[i][j]) / (4 * x), (m[k2][i] + m[i][k2]) / (4 * x)
        sign = -1 if q[0] < 0 else 1
        return sp.Matrix([sp.Rational(mpmath.nstr(sign * c, 34, min_fixed=-40, max_fixed=40)) for c in q])


def _half_angle_residual(theta: sp.Expr, joint: Joint, frame1: Frame, frame2: Frame) -> sp.Expr:
    def basis(reference: sp.Matrix, axis: sp.Matrix) -> sp.Matrix:
        return sp.Matrix.hstack(sp.Matrix(reference), cross(axis, reference), sp.Matrix(axis))

    zero_angle = basis(joint.reference1, joint.axis1) * basis(joint.reference2, joint.axis2).T
    if zero_angle.free_symbols:
        raise ValueError(
            f"joint {joint.name}: its axes or references depend on design parameters, which a joint-angle driver "
            "does not take yet (keep the joint's directions fixed, move its points)"
        )
    p = quaternion_product(quaternion_product(conjugate(frame1.e), frame2.e), conjugate(exact_quaternion(zero_angle)))
    along = dot(sp.Matrix(joint.axis1), sp.Matrix(p[1:]))
    return 2 * (sp.sin(theta / 2) * p[0] - sp.cos(theta / 2) * along)


#: a kind's equation: (driver, its input's value, joints by name, frame of a body, moving bodies filter) -> Equation
Builder = Callable[[Driver, sp.Expr, dict, Callable[[str], Frame], Callable[[tuple[str, ...]], tuple[str, ...]]], Equation]
#: the equation of every driver kind (kinegen.model.kinds.DRIVER_KINDS lists the kinds)
BUILDERS: dict[str, Builder] = {}

_builds = registrar(BUILDERS)


def driver_equation(
    driver: Driver,
    joints: dict[str, Joint],
    frame_of: Callable[[str], Frame],
    moving: Callable[[tuple[str, ...]], tuple[str, ...]],
    value: sp.Expr | None = None,
) -> Equation:
    """The equation of ``driver``; ``frame_of`` gives a body's frame, ``moving`` filters ground.

    ``value`` stands for the driver's input (an angle, a translation, a length or a
    coordinate); by default it is the driver's time function.
    """
    if driver.type not in BUILDERS:
        raise ValueError(f"unknown driver type {driver.type!r}")
    return BUILDERS[driver.type](driver, driver.function if value is None else value, joints, frame_of, moving)


@_builds("joint_angle")
def _joint_angle(driver: Driver, theta: sp.Expr, joints: dict, frame_of, moving) -> Equation:
    joint = joints[driver.joint]
    frame1, frame2 = frame_of(joint.body1), frame_of(joint.body2)
    bodies = moving((joint.body1, joint.body2))
    if frame1.e is not None and frame2.e is not None:
        return Equation(driver.name, bodies, _half_angle_residual(theta, joint, frame1, frame2))
    f1 = frame1.vector(joint.reference1)
    g1 = frame1.vector(cross(joint.axis1, joint.reference1))
    f2 = frame2.vector(joint.reference2)
    return Equation(driver.name, bodies, _angle_residual(theta, f1, g1, f2))


@_builds("joint_translation")
def _joint_translation(driver: Driver, theta: sp.Expr, joints: dict, frame_of, moving) -> Equation:
    joint = joints[driver.joint]
    frame1, frame2 = frame_of(joint.body1), frame_of(joint.body2)
    d = frame2.point(joint.point2) - frame1.point(joint.point1)
    return Equation(driver.name, moving((joint.body1, joint.body2)), dot(frame1.vector(joint.axis1), d) - theta)


@_builds("distance")
def _distance(driver: Driver, theta: sp.Expr, joints: dict, frame_of, moving) -> Equation:
    p1, p2 = driver.points
    gap = frame_of(p1.body).point(p1.local) - frame_of(p2.body).point(p2.local)
    return Equation(driver.name, moving((p1.body, p2.body)), dot(gap, gap) - theta**2)


@_builds("coordinate")
def _coordinate(driver: Driver, theta: sp.Expr, joints: dict, frame_of, moving) -> Equation:
    (p,) = driver.points
    return Equation(driver.name, moving((p.body,)), frame_of(p.body).point(p.local)[driver.component] - theta)


@_builds("body_angle")
def _body_angle(driver: Driver, theta: sp.Expr, joints: dict, frame_of, moving) -> Equation:
    f1 = sp.Matrix(driver.reference)
    g1 = cross(driver.axis, driver.reference)
    f2 = frame_of(driver.body).vector(driver.body_reference)
    return Equation(driver.name, moving((driver.body,)), _angle_residual(theta, f1, g1, f2))


check_registered("kinegen.constraints.drivers", DRIVER_KINDS, BUILDERS)


__all__ = ["driver_equation", "exact_quaternion"]
