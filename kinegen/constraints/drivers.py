"""Driving constraint equations ``Phi_D(q, t) = 0``.

Rotation drivers use ``sin(theta(t) - phi) = 0`` written with dot products
(``sin(theta) f1.f2 - cos(theta) g1.f2``), where ``phi`` is the rotation of f2 away from
f1 about h1. It holds for every angle (no atan, no (-pi/2, pi/2) limit); its other root,
phi = theta + pi, lies half a turn away from the trajectory the solver tracks.
Distances use ``|P1 - P2|^2 - L(t)^2``; coordinates ``P[k] - x(t)``.
"""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp

from kinegen.constraints.frames import Equation, Frame, cross, dot
from kinegen.model.schema import Driver, Joint


def _angle_residual(theta: sp.Expr, f1: sp.Matrix, g1: sp.Matrix, f2: sp.Matrix) -> sp.Expr:
    return sp.sin(theta) * dot(f1, f2) - sp.cos(theta) * dot(g1, f2)


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
    theta = driver.function if value is None else value
    if driver.type in ("joint_angle", "joint_translation"):
        joint = joints[driver.joint]
        frame1, frame2 = frame_of(joint.body1), frame_of(joint.body2)
        bodies = moving((joint.body1, joint.body2))
        f1 = frame1.vector(joint.reference1)
        if driver.type == "joint_angle":
            g1 = frame1.vector(cross(joint.axis1, joint.reference1))
            f2 = frame2.vector(joint.reference2)
            return Equation(driver.name, bodies, _angle_residual(theta, f1, g1, f2))
        d = frame2.point(joint.point2) - frame1.point(joint.point1)
        return Equation(driver.name, bodies, dot(frame1.vector(joint.axis1), d) - theta)
    if driver.type == "distance":
        p1, p2 = driver.points
        gap = frame_of(p1.body).point(p1.local) - frame_of(p2.body).point(p2.local)
        return Equation(driver.name, moving((p1.body, p2.body)), dot(gap, gap) - theta**2)
    if driver.type == "coordinate":
        (p,) = driver.points
        return Equation(driver.name, moving((p.body,)), frame_of(p.body).point(p.local)[driver.component] - theta)
    if driver.type == "body_angle":
        f1 = sp.Matrix(driver.reference)
        g1 = cross(driver.axis, driver.reference)
        f2 = frame_of(driver.body).vector(driver.body_reference)
        return Equation(driver.name, moving((driver.body,)), _angle_residual(theta, f1, g1, f2))
    raise ValueError(f"unknown driver type {driver.type!r}")


__all__ = ["driver_equation"]
