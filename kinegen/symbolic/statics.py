"""The exact rows a force solve needs beside Φ_q: one row per actuation element, and the loads'
generalized forces -- written in the bodies' stored and frame symbols like the constraint rows,
so that the backends print them as kernels (:mod:`kinegen.codegen.kernels`: ``actuation``, ``loads``).

Conventions (velocity coordinates v as the parametrization defines them; global axes):

* A body's angular velocity is linear in its velocity coordinates, ω = T_ω v_b; column k of T_ω
  is ∂ω/∂v_k of the parametrization's own expression (``frame_expressions``), exact in each.
* A body point P moves with J_P = ∂P/∂v: the tangent derivatives of its position
  (:func:`~kinegen.symbolic.assembly.tangent_jacobian`, as for Φ_q).
* An actuator's row is dL/dv of its length L = |P1 − P2| (an element of parallel cylinders: the
  sum of their rows, as they push with one force); a motor's is dθ/dv = a·(T_ω2 − T_ω1) of
  its joint's angle θ, a = the joint's axis (turning with the first body). Each element's
  equation is thus "its length (angle) minus its input" with unit slope in the input.
* A load (force F at P, moment M on its body, both turned to global axes) does the virtual work
  Q δv with Q_k = F·J_P[:, k] + M·T_ω[:, k].
"""

from __future__ import annotations

import symengine as se
import sympy as sp

from kinegen.constraints import GROUND_FRAME
from kinegen.constraints.frames import Frame, dot
from kinegen.interface import frame_slices
from kinegen.model import Model
from kinegen.model.schema import GROUND, Load, Motor
from kinegen.symbolic.assembly import BodyCoordinates, Coordinates, generic_body, tangent_jacobian
from kinegen.symbolic.engine import Bridge

#: an element's (name, kind) and row: column -> expression
ElementRow = tuple[str, str, dict[int, sp.Expr]]


def _acceleration(symbol: sp.Symbol) -> sp.Symbol:
    """``v_<body>_<c>`` -> ``dv_<body>_<c>``: its time derivative (the kernels' slot ``a``)."""
    return sp.Symbol("d" + str(symbol), real=True)


def frame_rates(coords: Coordinates, body: BodyCoordinates) -> dict[str, sp.Matrix]:
    """The body's global origin velocity and acceleration, angular velocity and acceleration (keys
    as :data:`kinegen.interface.FRAME_FIELDS`), in its stored, frame, velocity and acceleration
    symbols: the parametrization's own expressions (``frame_expressions``), renamed from the generic body."""
    param = coords.parametrization
    generic = generic_body(param)
    accelerations = [_acceleration(s) for s in generic.velocity]
    values = param.frame_expressions(sp.Matrix(generic.stored), sp.Matrix(generic.velocity), sp.Matrix(accelerations))
    values = [e.xreplace(dict(zip(generic.frame_values, generic.frame_symbols))) for e in values]
    rename = dict(zip([*generic.stored, *generic.frame_symbols, *generic.velocity, *accelerations],
                      [*body.stored, *body.frame_symbols, *body.velocity, *(_acceleration(s) for s in body.velocity)]))  # fmt: skip
    return {name: sp.Matrix([e.xreplace(rename) for e in values[at]]) for name, at in frame_slices().items()
            if name in ("velocity", "angular_velocity", "acceleration", "angular_acceleration")}  # fmt: skip


def angular_velocity_columns(coords: Coordinates, body: BodyCoordinates) -> dict[int, sp.Matrix]:
    """T_ω of ``body`` by column (its velocity offset + k): ∂ω/∂v_k, in the body's stored and frame
    symbols; columns identically zero left out."""
    omega = frame_rates(coords, body)["angular_velocity"]
    out = {}
    for k, v in enumerate(body.velocity):
        column = sp.Matrix([sp.expand(e.diff(v)) for e in omega])
        if any(x != 0 for x in column):
            out[body.velocity_offset + k] = column
    return out


def point_columns(coords: Coordinates, body: BodyCoordinates, local: sp.Matrix) -> dict[int, sp.Matrix]:
    """J_P of the body point at ``local`` (body coordinates) by column: ∂P/∂v_k."""
    position = body.frame.point(sp.Matrix(local))
    parts = [tangent_jacobian(x, [body]) for x in position]
    columns = sorted(set().union(*parts))
    return {c: sp.Matrix([part.get(c, sp.Integer(0)) for part in parts]) for c in columns}


def element_rows(model: Model, coords: Coordinates) -> list[ElementRow]:
    """The row of each actuation element (``model.actuation``: motors, then hydraulic actuators)."""
    frames = {b.name: b.frame for b in coords.bodies}

    def frame_of(name: str) -> Frame:
        return GROUND_FRAME if name == GROUND else frames[name]

    joints = {j.name: j for j in model.joints}
    rows: list[ElementRow] = []
    for element in model.actuation:
        if isinstance(element, Motor):
            joint = joints[element.joint]
            axis = frame_of(joint.body1).vector(sp.Matrix(joint.axis1))
            row: dict[int, sp.Expr] = {}
            for sign, name in ((1, joint.body2), (-1, joint.body1)):
                if name != GROUND:
                    for c, column in angular_velocity_columns(coords, coords.body(name)).items():
                        row[c] = row.get(c, sp.Integer(0)) + sign * dot(axis, column)
            rows.append((element.name, "motor", {c: e for c, e in sorted(row.items()) if e != 0}))
        else:  # the element's cylinders (itself and those parallel to it) push with one force
            row = {}
            for member in model.members(element.name):
                ends = [frame_of(p.body).point(sp.Matrix(p.local)) for p in member.points]
                gap = ends[0] - ends[1]
                bodies = [coords.body(n) for n in dict.fromkeys(p.body for p in member.points) if n != GROUND]
                for c, e in tangent_jacobian(sp.sqrt(dot(gap, gap)), bodies).items():
                    row[c] = row[c] + e if c in row else e
            rows.append((element.name, "actuator", dict(sorted(row.items()))))
    return rows


def load_row(load: Load, coords: Coordinates) -> dict[int, sp.Expr]:
    """Q of one load by column (its body's velocity coordinates), exact in t."""
    body = coords.body(load.point.body)
    turn = GROUND_FRAME if load.axes == GROUND else coords.body(load.axes).frame
    force, moment = turn.vector(sp.Matrix(load.force)), turn.vector(sp.Matrix(load.moment))
    row: dict[int, sp.Expr] = {}
    if any(x != 0 for x in force):
        for c, column in point_columns(coords, body, load.point.local).items():
            row[c] = dot(force, column)
    if any(x != 0 for x in moment):
        for c, column in angular_velocity_columns(coords, body).items():
            row[c] = row.get(c, sp.Integer(0)) + dot(moment, column)
    return {c: e for c, e in sorted(row.items()) if e != 0}


def inertia_row(model: Model, coords: Coordinates) -> list[dict[int, sp.Expr]]:
    """The generalized force of gravity and of the bodies' inertia (d'Alembert) by column, one
    dict per massive body (its own columns), in the stored, frame, velocity and acceleration
    symbols: per body with a mass m, centre of mass C (c = A c_local from the origin) and inertia
    J = A J_b Aᵀ about C, Q_k = m (g − a_C)·J_C[:, k] − (J ω̇ + ω × J ω)·T_ω[:, k],
    a_C = a_O + ω̇ × c + ω × (ω × c). The products are SymEngine's (:class:`kinegen.symbolic.engine.Bridge`)."""
    bridge = Bridge()
    gravity = bridge.to(sp.Matrix(model.gravity))
    rows = []
    for body in model.massive:
        row: dict[int, se.Basic] = {}
        inertia = body.inertia
        symbols = coords.body(body.name)
        rates = {name: bridge.to(value) for name, value in frame_rates(coords, symbols).items()}
        rotation = bridge.to(symbols.frame.A)
        arm = rotation * bridge.to(sp.Matrix(inertia.center))
        omega, omega_dot = rates["angular_velocity"], rates["angular_acceleration"]
        center_acceleration = rates["acceleration"] + omega_dot.cross(arm) + omega.cross(omega.cross(arm))
        force = (gravity - center_acceleration) * bridge.to(inertia.mass)
        tensor = rotation * bridge.to(sp.Matrix(inertia.tensor)) * rotation.T
        moment = -(tensor * omega_dot + omega.cross(tensor * omega))
        for c, column in point_columns(coords, symbols, inertia.center).items():
            row[c] = row.get(c, se.Integer(0)) + force.dot(bridge.to(column))
        for c, column in angular_velocity_columns(coords, symbols).items():
            row[c] = row.get(c, se.Integer(0)) + moment.dot(bridge.to(column))
        rows.append({c: bridge.back(e) for c, e in sorted(row.items()) if e != 0})
    return rows


__all__ = ["angular_velocity_columns", "element_rows", "frame_rates", "inertia_row", "load_row", "point_columns"]
