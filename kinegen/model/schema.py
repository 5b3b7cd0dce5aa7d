"""Immutable, validated model objects (what a mechanism *is*).

All geometry is exact SymPy (rationals, ``pi``, square roots): decimals in the model
file are taken as exact rationals so that the Jacobian can be evaluated exactly.
Points and vectors are stored in *body* coordinates, whatever way the file gave them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import Any

import numpy as np
import sympy as sp

GROUND = "ground"

Vector = sp.ImmutableMatrix  # a 3x1 exact column


#: the default acceleration of gravity [m/s^2, global]: standard gravity 9.80665 along -z, exact
STANDARD_GRAVITY = sp.ImmutableMatrix([0, 0, -sp.Rational(980665, 100000)])


@dataclass(frozen=True)
class Inertia:
    """A body's mass [kg], its centre of mass [m, body coordinates] and its inertia tensor about
    the centre of mass in body axes [kg m^2]; exact, design parameters allowed."""

    mass: sp.Expr
    center: Vector
    tensor: sp.ImmutableMatrix  #: 3 x 3, symmetric


@dataclass(frozen=True)
class Body:
    """A moving rigid body: initial pose and named geometry in body coordinates."""

    name: str
    position: Vector
    rotation: sp.ImmutableMatrix
    points: dict[str, Vector] = field(default_factory=dict)
    vectors: dict[str, Vector] = field(default_factory=dict)
    #: a drawing of the body (m, body coordinates): a closed polygon, drawn projected on a chart's plane
    outline: tuple[tuple[float, float, float], ...] = ()
    #: its mass, centre of mass and inertia (``mass:``, ``center_of_mass:``, ``inertia:``), or None: massless
    inertia: Inertia | None = None


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


def design_value(expr: Any, design: Mapping[str, float] | None = None) -> float:
    """The number of an exact model value that may use design parameters (their symbols
    ``p_<name>``), at ``design`` (name -> value; every parameter it uses must be given)."""
    expr = sp.sympify(expr)
    if expr.free_symbols:
        values = dict(design or {})
        missing = sorted(str(s)[2:] for s in expr.free_symbols if str(s)[2:] not in values)
        if missing:
            raise KeyError(f"no value given for design parameter(s) {', '.join(missing)}")
        expr = expr.xreplace({s: sp.Float(values[str(s)[2:]], 17) for s in expr.free_symbols})
    return float(expr)


def design_gradient(expr: Any, names: Sequence[str], design: Mapping[str, float]) -> np.ndarray:
    """d(expr)/d(design parameter) for each of ``names``, at ``design`` (see :func:`design_value`)."""
    expr = sp.sympify(expr)
    out = np.zeros(len(names))
    for symbol in expr.free_symbols:
        if str(symbol)[2:] in names:
            out[list(names).index(str(symbol)[2:])] = design_value(expr.diff(symbol), design)
    return out


@dataclass(frozen=True)
class Hydraulics:
    """A hydraulic cylinder's data (``hydraulics:`` of an actuator). Diameters in m, pressures in Pa.

    A pushing force (the actuator extends against its load) is carried by the cap side, area
    pi/4 bore^2; a pulling force by the rod side, the annulus pi/4 (bore^2 - rod^2). ``relief``
    is the pressure the circuit's relief valve allows when this cylinder does the work, per
    side as (extend = cap side, retract = rod side); ``holding`` the port relief pressure that
    limits it when another cylinder does the work and this one holds (same order). ``cylinders``
    identical cylinders in parallel share the force (the model drives one of them).
    """

    bore: sp.Expr
    rod: sp.Expr
    relief: tuple[sp.Expr, sp.Expr]
    holding: tuple[sp.Expr, sp.Expr]
    cylinders: int = 1

    def areas(self, design: Mapping[str, float] | None = None) -> tuple[float, float]:
        """(cap side, rod side) areas of all the cylinders together [m^2] at ``design``."""
        bore, rod = design_value(self.bore, design), design_value(self.rod, design)
        return self.cylinders * np.pi / 4 * bore**2, self.cylinders * np.pi / 4 * (bore**2 - rod**2)

    def area_gradients(self, names: Sequence[str], design: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """d(cap side area)/dp and d(rod side area)/dp [m^2 per unit] for the design parameters ``names``."""
        bore, rod = design_value(self.bore, design), design_value(self.rod, design)
        d_bore, d_rod = design_gradient(self.bore, names, design), design_gradient(self.rod, names, design)
        d_cap = self.cylinders * np.pi / 2 * bore * d_bore
        return d_cap, d_cap - self.cylinders * np.pi / 2 * rod * d_rod


@dataclass(frozen=True)
class Actuator:
    """A length between two body points that a run reports (e.g. a hydraulic cylinder).

    ``range`` is its allowed (min, max) length, exact (it may use design parameters: a
    cylinder's retracted length); leaving it is reported, not an error. With ``hydraulics`` it
    carries load: its force (pushing positive) is one of the model's actuation forces.
    ``parallel`` names the hydraulic actuator this one works beside (a twin cylinder on the same
    circuit, e.g. an excavator's two boom cylinders): it has that actuator's data and pressure, so
    it pushes with the same force, at its own pins; the two make one actuation element.
    """

    name: str
    points: tuple[PointRef, PointRef]
    range: tuple[sp.Expr, sp.Expr] | None = None
    hydraulics: Hydraulics | None = None
    parallel: str | None = None

    def limits(self, design: Mapping[str, float] | None = None) -> tuple[float, float] | None:
        """``range`` as numbers at the design values ``design`` (see :func:`design_value`)."""
        return None if self.range is None else (design_value(self.range[0], design), design_value(self.range[1], design))


@dataclass(frozen=True)
class Motor:
    """A rotary actuator at a revolute (or cylindrical) joint: it carries the torque about the
    joint's axis that turns ``joint``'s second body relative to its first (positive about axis1).
    ``displacement``: the oil it takes per radian of the joint's turn [m^3/rad] (a hydraulic motor
    through its gear: flow = displacement x |turn rate|; its pressure = torque / displacement), None
    where it is not hydraulic."""

    name: str
    joint: str
    displacement: sp.Expr | None = None


@dataclass(frozen=True)
class Pump:
    """A hydraulic pump (``pumps.pumps``): its largest flow [m^3/s] and the pressure it can reach [Pa]."""

    name: str
    max_flow: sp.Expr
    max_pressure: sp.Expr


@dataclass(frozen=True)
class Supply:
    """The machine's hydraulic supply (``pumps:``): the pumps, the engine power they share [W] and which
    pumps feed each actuation element (``circuits``: a hydraulic actuator or a motor with a displacement
    -> its pumps). Confluence: an element fed by several pumps draws its flow from them in equal shares
    (their flows merged); a pump's flow is the sum of its shares. A pump delivers at the highest pressure
    among the elements it feeds; the pumps together take at most ``engine_power`` (total power control:
    the sum of pressure x flow), each at most its own largest flow and pressure."""

    pumps: tuple[Pump, ...]
    engine_power: sp.Expr
    circuits: dict[str, tuple[str, ...]]


@dataclass(frozen=True)
class Load:
    """A force [N] and moment [N m] applied to the machine at a body point (``loads:``), each a
    3-vector of exact expressions of t, in global axes or (``axes`` = the body's name) in the
    body's axes. The machine holds it: the actuation forces balance it."""

    name: str
    point: PointRef
    force: Vector
    moment: Vector
    axes: str = GROUND  #: "ground": global axes; else the name of the point's body

    @property
    def fingerprint(self) -> str:
        """SHA-256 of what the load is (point, force, moment, axes; exact): a generated module's
        ``loads`` kernel serves a load only when its fingerprint is the one the module was built with."""
        import hashlib

        content = (self.point.body, self.point.name, tuple(map(sp.srepr, self.point.local)), tuple(map(sp.srepr, self.force)),
                   tuple(map(sp.srepr, self.moment)), self.axes)  # fmt: skip
        return hashlib.sha256(repr(content).encode()).hexdigest()

    def limits(self, design: Mapping[str, float] | None = None) -> tuple[float, float] | None:
        """``range`` as numbers at the design values ``design`` (see :func:`design_value`)."""
        return None if self.range is None else (design_value(self.range[0], design), design_value(self.range[1], design))


@dataclass(frozen=True)
class ToolForce:
    """How to find one ISO 6015 tool force (``tool_forces:``): the force at the lip tangent to its
    circle about ``pivot`` that ``actuator`` produces when it works, searched over ``stroke`` of
    the case input ``driver`` that moves it (the other inputs at the case's start)."""

    name: str  #: "bucket" (bucket cylinder tool force) or "arm" (arm cylinder tool force)
    actuator: str
    driver: str
    pivot: PointRef
    stroke: tuple[float, float]


@dataclass(frozen=True)
class ToolForces:
    """The ISO 6015 tool forces of a backhoe (``kinegen forces``): computed in ``case`` at the tool
    point ``lip``; ``published`` [N] holds figures to print beside them (unverified unless said)."""

    case: str
    lip: PointRef
    forces: dict[str, ToolForce]
    published: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class LiftChartSpec:
    """Where ``kinegen forces --lift`` finds the hydraulic lift capacity (``lift_chart:``): the load at
    ``point`` (m; global heights and radii from the swing axis in the boom plane), the inputs of
    ``case`` that place it (``place``, within ``ranges``; the others at the case's start),
    ``lifting`` at its relief setting and the other cylinders holding."""

    case: str
    point: PointRef
    lifting: str
    place: tuple[str, ...]
    ranges: dict[str, tuple[float, float]]
    heights: tuple[float, ...]
    radii: tuple[float, ...]
    #: bodies whose weight is left out (``without:``, e.g. the bucket: the load hangs at the arm's end)
    without: tuple[str, ...] = ()


@dataclass(frozen=True)
class Machine:
    """What the tipping limit needs beside the moving bodies (``machine:``): the undercarriage's mass
    [kg] and centre of mass [m, global] (it does not move), and its tracks: ``track_length`` the
    tumbler distance (sprocket to idler centres), ``gauge`` between the tracks' centrelines,
    ``shoe_width``; the swing axis is the global z axis, at the middle of the tracks. Exact numbers."""

    undercarriage_mass: sp.Expr
    undercarriage_center: Vector
    track_length: sp.Expr
    gauge: sp.Expr
    shoe_width: sp.Expr


@dataclass(frozen=True)
class Case:
    """A named way to drive the model, with its default time grid."""

    name: str
    drivers: tuple[Driver, ...]
    t0: float = 0.0
    t1: float = 1.0
    steps: int = 101


#: The working-range figures kinegen computes (``kinegen envelope``; ISO 7135-style), in the order
#: reports list them; the one list the loader, the design studies and the envelope read.
WORKING_RANGE_FIGURES = ("max_reach", "max_reach_at_ground", "max_depth", "max_cutting_height", "max_dumping_height", "max_vertical_wall_depth")
#: ... and what a model may publish to be compared with them.
PUBLISHED_FIGURES = (*WORKING_RANGE_FIGURES, "min_front_swing_radius")


@dataclass(frozen=True)
class WorkingRange:
    """How ``kinegen envelope`` sweeps a forward case.

    ``inputs`` maps every driver of ``case`` to a fixed value or a (min, max) range;
    ``dump_pivot`` is the point the tool hangs from when dumping (the dumping height is
    the highest position of ``point`` directly below it); ``published`` holds reference
    figures (reported as unverified); ``arm_pivot`` and ``transport``: see the fields.
    """

    case: str
    point: PointRef
    inputs: dict[str, sp.Expr | tuple[sp.Expr, sp.Expr]]  #: exact; may use design parameters
    dump_pivot: PointRef | None = None
    published: dict[str, float] = field(default_factory=dict)
    #: the arm's upper pin: the vertical-wall digging depth is the deepest ``point`` with this pin
    #: directly above ``dump_pivot`` (the arm vertical)
    arm_pivot: PointRef | None = None
    #: the swept inputs of the transport pose (the silhouette of the working-range chart)
    transport: dict[str, float] = field(default_factory=dict)

    def numbers(self, design: Mapping[str, float] | None = None) -> dict[str, float | tuple[float, float]]:
        """``inputs`` as numbers at the design values ``design`` (see :func:`design_value`)."""
        return {
            name: (design_value(v[0], design), design_value(v[1], design)) if isinstance(v, tuple) else design_value(v, design)
            for name, v in self.inputs.items()
        }


@dataclass(frozen=True)
class DesignParameter:
    """A parameter the geometry keeps as a symbol (``design:`` in the model file).

    Every point, vector, position, angle or length that depends on it is an expression of
    ``symbol`` (named ``p_<name>``); ``nominal`` is its value in the design as drawn and
    ``lower``/``upper`` its bounds (same unit as the expressions that use it: m or rad).
    """

    name: str
    symbol: sp.Symbol
    nominal: sp.Expr
    lower: sp.Expr
    upper: sp.Expr
    description: str = ""


#: what a design study can measure (:class:`Quantity`)
#: every study quantity's kind and the unit it is measured in (see :class:`Quantity`; "1": a number)
QUANTITY_UNITS = {
    "working_range": "m", "rotation_range": "rad", "stroke": "m", "toggle_margin": "1", "actuator_margin": "m",
    "transmission_angle": "rad", "digging_force": "kN", "crowd_force": "kN", "cylinder_pressure": "MPa", "pin_load": "kN",
    "lift_capacity": "kN", "tool_force": "kN", "tipping_margin": "kN m", "peak_pressure": "MPa", "mass": "t",
    "cycle_time": "s",
}  # fmt: skip
#: a mass quantity's name for the whole machine (the moving bodies and the undercarriage)
MACHINE = "machine"
#: a lift_capacity's sides (``over``) and limits (``limit``): ISO 10567's rated capacity (the smaller of
#: 75 % of the tipping load and 87 % of the hydraulic capacity) or either of its two halves unshared
LIFT_SIDES = ("front", "side")
LIFT_LIMITS = ("rated", "hydraulic", "tipping")
#: a tipping_margin with or without the bodies' d'Alembert forces
TIPPING_KINDS = ("dynamic", "static")
QUANTITY_KINDS = tuple(QUANTITY_UNITS)


@dataclass(frozen=True)
class Quantity:
    """A figure of a design, measured by ``kinegen optimize`` (:mod:`kinegen.analysis.studies`).

    * ``working_range``: a working-range figure (``figure``, m);
    * ``rotation_range``: over ``case``, the largest minus the smallest rotation angle of ``body``
      relative to ``relative_to`` about ``axis`` (in ``relative_to``'s frame; rad);
    * ``stroke``: over ``case``, the longest minus the shortest length of ``actuator`` (m);
    * ``toggle_margin``: over ``case``, the smallest σ_min of the diagonal blocks of Φ_q's
      block-triangular form that hold coordinates of ``bodies`` -- the distance to the linkage's
      toggle, where it vanishes;
    * ``actuator_margin``: over ``case``, the smallest distance of ``actuator``'s length to the
      ends of its range (m; negative outside it);
    * ``transmission_angle``: over ``case``, the smallest distance of the angle at the second of
      ``points`` (between the lines to the first and the third) from 0 and from π (rad): a
      linkage transmits force badly near both (at 0 or π it is at a dead point).
    * ``digging_force`` / ``crowd_force``: over ``case`` (one in which only ``actuator`` moves, such
      as a sweep of its stroke), the largest force at the ``tool_forces`` lip along the lip's path
      that ``actuator`` produces at its relief setting, relief x cap area x |L'| / |v_lip| by virtual
      work (kN): the ISO 6015 bucket (arm) cylinder tool force before any other circuit limits it;
    * ``cylinder_pressure``: over ``case``, the largest pressure ``actuator`` needs to hold ``load``
      (MPa; :mod:`kinegen.forces`);
    * ``pin_load``: over ``case``, the largest force the joint named ``actuator`` carries holding
      ``load`` (kN);
    * ``lift_capacity``: with the ``lift_chart`` point at ``at`` (radius, height; m; the placing inputs
      solved for each design), ``over`` the front or the side, the rated lift capacity (``limit``
      "rated": the smaller of 75 % of the tipping load and 87 % of the hydraulic capacity, ISO 10567),
      or the whole hydraulic capacity ("hydraulic") or the whole tipping load ("tipping"), as a
      load's weight (kN);
    * ``tipping_margin``: over ``case``, the smallest moment that keeps the machine on the ground
      about its nearest tipping line (kN m; :func:`kinegen.forces.dynamics.tipping_margin`), with the
      bodies' d'Alembert forces ("dynamic") or their weights alone ("static"), and ``load`` if named;
    * ``mass``: the mass of ``body``, or of the whole machine (``body`` "machine": the moving bodies
      and the ``machine:`` section's undercarriage) (t; no case: design parameters may appear in the
      masses, e.g. a counterweight);
    * ``peak_pressure``: over ``case`` at its speed, the largest pressure ``actuator`` needs (MPa): the
      inverse dynamics with the bodies' weights and inertia, and ``load`` if named;
    * ``cycle_time``: the fastest timing of ``case``'s path from rest to rest within the pumps, the
      engine, the pressures, the motors' torque and the tipping margin, with the bodies' weight and
      inertia and ``load`` if named (s; :func:`kinegen.forces.cycle.cycle_time`, on the case's grid);
    * ``tool_force``: over ``case``'s poses, the largest force the point ``points[0]`` can exert along
      the global direction ``axis`` with every hydraulic cylinder at most at its relief setting (kN;
      a force map's value, :mod:`kinegen.forces.maps`).
    """

    kind: str
    case: str | None = None
    figure: str | None = None
    body: str | None = None
    relative_to: str = GROUND
    axis: tuple[float, float, float] | None = None
    actuator: str | None = None
    bodies: tuple[str, ...] = ()
    points: tuple[tuple[str, str], ...] = ()  #: (body, point) each
    load: str | None = None  #: the load a cylinder_pressure is measured under
    at: tuple[float, float] | None = None  #: a lift_capacity's radius and height [m]
    over: str = "front"  #: a lift_capacity's side (:data:`LIFT_SIDES`)
    limit: str = "rated"  #: a lift_capacity's limit (:data:`LIFT_LIMITS`)
    inertia: bool = True  #: a tipping_margin's d'Alembert forces ("dynamic") or not ("static")

    @property
    def unit(self) -> str:
        """Its unit (:data:`QUANTITY_UNITS`), "" for a singular value of Φ_q (mixed units)."""
        return "" if self.kind == "toggle_margin" else QUANTITY_UNITS[self.kind]

    @property
    def label(self) -> str:
        """A short name: ``max_depth``, ``rotation_range(bucket/arm, bucket_stroke)``, ..."""
        if self.kind == "working_range":
            return str(self.figure)
        if self.kind == "lift_capacity" and self.at is not None:
            extra = "" if (self.over, self.limit) == ("front", "rated") else f", {self.over} {self.limit}"
            return f"lift_capacity({self.at[0]:g} m, {self.at[1]:g} m{extra})"
        if self.kind == "tipping_margin":
            held = f" holding {self.load}" if self.load else ""
            return f"tipping_margin({'dynamic' if self.inertia else 'static'}{held}, {self.case})"
        if self.kind == "mass":
            return f"mass({self.body})"
        if self.kind == "cycle_time":
            return f"cycle_time({self.case}{f' holding {self.load}' if self.load else ''})"
        if self.kind == "peak_pressure" and self.load:
            return f"peak_pressure({self.actuator} holding {self.load}, {self.case})"
        if self.kind == "tool_force" and self.points and self.axis is not None:
            (body, point), d = self.points[0], self.axis
            return f"tool_force({body}.{point} along [{d[0]:g}, {d[1]:g}, {d[2]:g}], {self.case})"
        what = {
            "rotation_range": f"{self.body}/{self.relative_to}", "toggle_margin": "+".join(self.bodies),
            "transmission_angle": "-".join(f"{b}.{p}" for b, p in self.points),
            "cylinder_pressure": f"{self.actuator} holding {self.load}", "pin_load": f"{self.actuator} holding {self.load}",
        }.get(self.kind, self.actuator)  # fmt: skip
        return f"{self.kind}({what}, {self.case})"


@dataclass(frozen=True)
class Term:
    """One term of a study's objective: ``weight`` x the quantity, or with a ``target``
    ``weight`` x (quantity - target)^2."""

    quantity: Quantity
    weight: float = 1.0
    target: float | None = None


@dataclass(frozen=True)
class StudyConstraint:
    """A study's constraint: the quantity at least ``at_least`` and/or at most ``at_most``."""

    quantity: Quantity
    at_least: float | None = None
    at_most: float | None = None


@dataclass(frozen=True)
class Study:
    """A design study (``studies:`` in the model file, ``kinegen optimize``): vary ``parameters``
    (design parameters, within their bounds; the others at their nominal values) to minimize or
    maximize (``sense``) the sum of ``terms`` subject to ``constraints``."""

    name: str
    parameters: tuple[str, ...]
    sense: str
    terms: tuple[Term, ...]
    constraints: tuple[StudyConstraint, ...] = ()
    description: str = ""


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
    ground_outline: tuple[tuple[float, float, float], ...] = ()  #: a drawing of the ground body (m, global): see Body.outline
    #: parameters kept symbolic in the geometry (empty: every geometry value is a number)
    design: tuple[DesignParameter, ...] = ()
    studies: dict[str, Study] = field(default_factory=dict)  #: design studies by name
    motors: tuple[Motor, ...] = ()  #: rotary actuators (a swing motor)
    tool_points: dict[str, PointRef] = field(default_factory=dict)  #: named tool points (a bucket's lip)
    loads: dict[str, Load] = field(default_factory=dict)  #: named loads on the machine
    tool_forces: ToolForces | None = None  #: how to compute the ISO 6015 tool forces
    lift_chart: LiftChartSpec | None = None  #: where to find the hydraulic lift capacity
    #: the undercarriage and its tracks (``machine:``), for the tipping limit; None: not given
    machine: Machine | None = None
    #: the hydraulic supply (``pumps:``): pumps, engine power, circuits; None: not given
    supply: Supply | None = None
    #: the acceleration of gravity, global [m/s^2] (``gravity:``; default 9.80665 along -z)
    gravity: Vector = STANDARD_GRAVITY

    @property
    def massive(self) -> tuple[Body, ...]:
        """The bodies with inertial data (their masses, gravity and inertia enter the dynamics)."""
        return tuple(b for b in self.bodies if b.inertia is not None)

    @property
    def tips(self) -> bool:
        """Whether the machine's tipping can be computed: masses and a ``machine:`` section."""
        return bool(self.massive) and self.machine is not None

    @property
    def actuation(self) -> tuple[Actuator | Motor, ...]:
        """What carries the machine's load: the motors, then the actuators with hydraulic data
        (empty: the model declares none, and each case's drivers carry it)."""
        return (*self.motors, *(a for a in self.actuators if a.hydraulics is not None))

    def members(self, name: str) -> tuple[Actuator, ...]:
        """The physical cylinders of the actuation element ``name``: the actuator itself, then those
        declared ``parallel`` to it (empty for a motor or an unknown name)."""
        return tuple(a for a in self.actuators if a.name == name or a.parallel == name)

    def lead(self, name: str) -> str:
        """The actuation element an actuator's force belongs to: the one it is ``parallel`` to, else itself."""
        for a in self.actuators:
            if a.name == name and a.parallel is not None:
                return a.parallel
        return name

    def at(self, values: Mapping[str, float] | None = None) -> Model:
        """This model with its design parameters replaced by numbers: ``values`` (by name; a
        float is taken exactly, as the model file would write it) and the nominal value for
        any not given. The result has no design parameters: the model as if its file had
        been written with those numbers."""
        from kinegen.model.expressions import number  # the schema stays import-light

        values = dict(values or {})
        unknown = set(values) - {d.name for d in self.design}
        if unknown:
            raise KeyError(f"not design parameters of {self.name}: {', '.join(sorted(unknown))}")
        mapping = {d.symbol: number(values[d.name]) if d.name in values else d.nominal for d in self.design}
        substituted = _substitute(self, mapping)
        return replace(substituted, design=())

    def body(self, name: str) -> Body:
        """The body called ``name`` (not ground)."""
        for body in self.bodies:
            if body.name == name:
                return body
        raise KeyError(name)


def _substitute(item: Any, mapping: dict[sp.Symbol, sp.Expr]) -> Any:
    """``item`` (a model or any part of it) with ``mapping`` applied to every expression in it;
    an expression that changes is put back in compact exact form (as the loader writes it)."""
    from kinegen.model.expressions import compact

    if isinstance(item, sp.MatrixBase):
        return sp.ImmutableMatrix(item.applyfunc(lambda e: _substitute(e, mapping)))
    if isinstance(item, sp.Basic):
        if not (item.free_symbols & mapping.keys()):
            return item
        return compact(sp.expand(item.xreplace(mapping)))
    if is_dataclass(item) and not isinstance(item, type):
        return replace(item, **{f.name: _substitute(getattr(item, f.name), mapping) for f in fields(item) if f.init})
    if isinstance(item, dict):
        return {k: _substitute(v, mapping) for k, v in item.items()}
    if isinstance(item, (tuple, list)):
        return type(item)(_substitute(v, mapping) for v in item)
    return item
