"""Immutable, validated model objects (what a mechanism *is*).

All geometry is exact SymPy (rationals, ``pi``, square roots): decimals in the model
file are taken as exact rationals so that the Jacobian can be evaluated exactly.
Points and vectors are stored in *body* coordinates, whatever way the file gave them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

GROUND = "ground"

Vector = sp.ImmutableMatrix  # a 3x1 exact column


@dataclass(frozen=True)
class Body:
    """A moving rigid body: initial pose and named geometry in body coordinates."""

    name: str
    position: Vector
    rotation: sp.ImmutableMatrix
    points: dict[str, Vector] = field(default_factory=dict)
    vectors: dict[str, Vector] = field(default_factory=dict)


@dataclass(frozen=True)
class Joint:
    """A joint between ``body1`` and ``body2`` with its geometry in each body's frame.

    ``point1``/``point2`` are the joint points, ``axis1``/``axis2`` the unit joint axes,
    ``reference1``/``reference2`` unit vectors perpendicular to the axes from which the
    relative rotation angle is measured (angle = rotation of reference2 away from
    reference1 about axis1), ``lock2`` body-2 vectors that coincide at the initial pose
    with body-1's (``reference1``, ``axis1 x reference1``, ``axis1``); ``length`` the
    distance of a ``distance`` joint.
    """

    name: str
    type: str
    body1: str
    body2: str
    point1: Vector | None = None
    point2: Vector | None = None
    axis1: Vector | None = None
    axis2: Vector | None = None
    reference1: Vector | None = None
    reference2: Vector | None = None
    lock2: tuple[Vector, Vector, Vector] | None = None
    length: sp.Expr | None = None


@dataclass(frozen=True)
class PointRef:
    """A named point on a body, with its body coordinates."""

    body: str
    name: str
    local: Vector


@dataclass(frozen=True)
class Driver:
    """A driving constraint with its time function ``function(t)`` (exact SymPy).

    Types: ``joint_angle`` (revolute/cylindrical joint), ``joint_translation``
    (prismatic/cylindrical joint, along axis1 from point1 to point2), ``distance``
    (between two points), ``coordinate`` (global x/y/z of a point), ``body_angle``
    (absolute rotation of a body about a global axis).
    """

    name: str
    type: str
    function: sp.Expr
    joint: str | None = None
    points: tuple[PointRef, ...] = ()
    component: int | None = None
    body: str | None = None
    axis: Vector | None = None
    reference: Vector | None = None
    body_reference: Vector | None = None
    entry: str = ""  #: where the function stands in the model file, e.g. ``cases.swing.drivers.phi1.function``
    text: str = ""  #: the function as written there


@dataclass(frozen=True)
class Actuator:
    """A length between two body points that a run reports (e.g. a hydraulic cylinder).

    ``range`` is its allowed (min, max) length; leaving it is reported, not an error.
    """

    name: str
    points: tuple[PointRef, PointRef]
    range: tuple[float, float] | None = None


@dataclass(frozen=True)
class Case:
    """A named way to drive the model, with its default time grid."""

    name: str
    drivers: tuple[Driver, ...]
    t0: float = 0.0
    t1: float = 1.0
    steps: int = 101


@dataclass(frozen=True)
class WorkingRange:
    """How ``kinegen envelope`` sweeps a forward case.

    ``inputs`` maps every driver of ``case`` to a fixed value or a (min, max) range;
    ``dump_pivot`` is the point the tool hangs from when dumping (the dumping height is
    the highest position of ``point`` directly below it); ``published`` holds reference
    figures (reported as unverified).
    """

    case: str
    point: PointRef
    inputs: dict[str, float | tuple[float, float]]
    dump_pivot: PointRef | None = None
    published: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Model:
    """A validated mechanism model."""

    name: str
    file: str
    source_sha256: str
    description: str
    parameters: dict[str, sp.Expr]
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    cases: dict[str, Case]
    actuators: tuple[Actuator, ...] = ()
    working_range: WorkingRange | None = None
    redundant: bool = False  #: the model declares redundant (dependent) constraints
    ground_points: dict[str, Vector] = field(default_factory=dict)  #: named fixed points, global

    def body(self, name: str) -> Body:
        """The body called ``name`` (not ground)."""
        for body in self.bodies:
            if body.name == name:
                return body
        raise KeyError(name)
