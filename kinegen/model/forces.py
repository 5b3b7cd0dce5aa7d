"""Reading what a model says about forces: actuators' hydraulic data, motors, tool points, loads.

```yaml
actuators:
  bucket_cylinder:
    points: [bucket_cyl_barrel.base, bucket_cyl_rod.eye]
    hydraulics:
      bore: 0.115              # m, piston diameter
      rod: 0.080               # m, rod diameter
      relief: 34.3e6           # Pa: one number, or {extend: .., retract: ..} (cap side, rod side)
      holding: 39.2e6          # Pa: port relief when another cylinder works (default: relief)
      cylinders: 1             # identical cylinders in parallel (default 1)
motors:
  swing_motor: {joint: swing}  # the torque about a revolute joint's axis
tool_points:
  lip: bucket.T
loads:
  payload: {point: bucket.Q, force: [0, 0, -9806.65]}              # N, global axes
  cutting: {point: lip, force: ["-20000*t", 0, 0], axes: bucket}    # functions of t; body axes
tool_forces:                   # ISO 6015 (kinegen forces)
  case: digging                # a case whose drivers move the cylinders
  lip: lip                     # the tool point the forces act at
  bucket: {actuator: bucket_cylinder, driver: bucket_length, pivot: bucket.Q}
  arm: {actuator: arm_cylinder, driver: arm_length, pivot: arm.E}   # stroke: [min, max] optional
  published: {bucket: 158e3, arm: 111e3}                             # N, printed beside
lift_chart:                    # hydraulic lift capacity (kinegen forces --lift)
  case: digging
  point: arm.Q                 # the lift point: the arm's end (bucket pin), the bucket removed
  lifting: boom_cylinder_left  # the cylinder that lifts (relief setting); the others hold
  place: [boom_length, arm_length]   # the inputs that place the point (ranges: the working range's, or ranges:)
  heights: [6, 4.5, 3, 1.5, 0, -1.5, -3]
  radii: [3, 4.5, 6, 7.5]
```

When a model declares motors or hydraulic actuators, they carry its load (``Model.actuation``)
and must be as many as the mechanism's mobility; otherwise each case's drivers carry it.
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from kinegen.errors import shown
from kinegen.model.kinds import JOINT_KINDS
from kinegen.model.schema import (
    GROUND,
    Actuator,
    Case,
    Hydraulics,
    LiftChartSpec,
    Load,
    Motor,
    PointRef,
    ToolForce,
    ToolForces,
    WorkingRange,
)

#: the loader's reader of a model file (kinegen.model.loader._Reader); errors name file and entry through it
Loader = Any

#: joints a motor may sit at: those with one rotation axis
MOTOR_JOINTS = ("revolute", "cylindrical")


def read_hydraulics(loader: Loader, value: Any, entry: str) -> Hydraulics:
    """An actuator's ``hydraulics:`` mapping."""
    spec = loader.mapping(value, entry, ("bore", "rod", "relief", "holding", "cylinders"), ("bore", "rod", "relief"))
    bore = loader.scalar(spec["bore"], f"{entry}.bore", design=True)
    rod = loader.scalar(spec["rod"], f"{entry}.rod", design=True)
    if not 0 < loader.value(rod) < loader.value(bore):
        raise loader.fail(f"{entry}.rod", f"expected 0 < rod < bore (diameters in m), got rod {shown(spec['rod'])}, bore {shown(spec['bore'])}")
    for key, value in (("bore", bore), ("rod", rod)):
        loader.plausible(value, f"{entry}.{key}", "m", (0.01, 1.0), f"a hydraulic cylinder's {key} diameter",
                         f"diameters are in m: {loader.value(value):g} mm is {loader.value(value) / 1e3:g}")  # fmt: skip
    relief = _pressures(loader, spec["relief"], f"{entry}.relief")
    holding = _pressures(loader, spec["holding"], f"{entry}.holding") if "holding" in spec else relief
    cylinders = spec.get("cylinders", 1)
    if isinstance(cylinders, bool) or not isinstance(cylinders, int) or cylinders < 1:
        raise loader.fail(f"{entry}.cylinders", f"expected a whole number >= 1, got {shown(cylinders)}")
    return Hydraulics(bore, rod, relief, holding, cylinders)


def _pressures(loader: Loader, value: Any, entry: str) -> tuple[sp.Expr, sp.Expr]:
    """One pressure [Pa] for both sides, or ``{extend: cap side, retract: rod side}``."""
    if isinstance(value, dict):
        spec = loader.mapping(value, entry, ("extend", "retract"), ("extend", "retract"))
        pair = (loader.scalar(spec["extend"], f"{entry}.extend", design=True), loader.scalar(spec["retract"], f"{entry}.retract", design=True))
    else:
        pressure = loader.scalar(value, entry, design=True)
        pair = (pressure, pressure)
    for side, pressure in zip(("extend", "retract"), pair):
        if not loader.value(pressure) > 0:
            raise loader.fail(entry, f"the {side} pressure must be positive (Pa), got {loader.value(pressure):g}")
        if loader.value(pressure) < 1e5:
            raise loader.fail(entry, f"{loader.value(pressure):g} Pa is below 1 bar: pressures are in Pa (34.3 MPa is 34.3e6)")
        loader.plausible(pressure, entry, "Pa", (1e6, 1e8), "a hydraulic circuit's setting (10 .. 1,000 bar)", "pressures are in Pa (34.3 MPa is 34.3e6)")
    return pair


def read_motors(loader: Loader, value: Any) -> tuple[Motor, ...]:
    """``motors: {name: {joint: <revolute or cylindrical joint>}}``."""
    motors = []
    for key, spec in loader.mapping(value, "motors", loader.keys(value)).items():
        entry = f"motors.{key}"
        loader.name(key, entry)
        spec = loader.mapping(spec, entry, ("joint", "displacement"), ("joint",))
        joint = loader.joints.get(spec["joint"]) if isinstance(spec["joint"], str) else None
        if joint is None:
            raise loader.fail(f"{entry}.joint", f"unknown joint {shown(spec['joint'])} (joints: {', '.join(loader.joints)})")
        if joint.type not in MOTOR_JOINTS:
            raise loader.fail(f"{entry}.joint", f"{joint.name} is a {joint.type} joint: a motor turns a {' or '.join(MOTOR_JOINTS)} joint")
        displacement = None
        if "displacement" in spec:
            displacement = loader.positive(spec["displacement"], f"{entry}.displacement", "m^3/rad: the oil per radian of the joint's turn")
            loader.plausible(displacement, f"{entry}.displacement", "m^3/rad", (1e-7, 1e-2), "a motor's displacement per radian of its joint",
                             "m^3 per radian of the joint (the gear included)")  # fmt: skip
        motors.append(Motor(key, joint.name, displacement))
    return tuple(motors)


def read_tool_points(loader: Loader, value: Any) -> dict[str, PointRef]:
    """``tool_points: {name: body.point}``: named points of moving bodies."""
    points = {}
    for key, item in loader.mapping(value, "tool_points", loader.keys(value)).items():
        entry = f"tool_points.{key}"
        loader.name(key, entry)
        ref = loader.point_ref(item, entry)
        if ref.body == GROUND:
            raise loader.fail(entry, "a tool point is on a moving body, not the ground")
        points[key] = ref
    return points


def read_loads(loader: Loader, value: Any, tool_points: dict[str, PointRef]) -> dict[str, Load]:
    """``loads: {name: {point: body.point or a tool point, force: [..], moment: [..], axes: global or the body}}``."""
    loads = {}
    for key, spec in loader.mapping(value, "loads", loader.keys(value)).items():
        entry = f"loads.{key}"
        loader.name(key, entry)
        spec = loader.mapping(spec, entry, ("point", "force", "moment", "axes"), ("point",))
        if "force" not in spec and "moment" not in spec:
            raise loader.fail(entry, "expected a force, a moment or both")
        where = spec["point"]
        ref = tool_points[where] if isinstance(where, str) and where in tool_points else loader.point_ref(where, f"{entry}.point")
        if ref.body == GROUND:
            raise loader.fail(f"{entry}.point", "a load on the ground moves nothing: put it on a moving body")
        force, moment = (
            sp.ImmutableMatrix([_component(loader, spec[k], f"{entry}.{k}", i) for i in range(3)]) if k in spec else sp.ImmutableMatrix([0, 0, 0])
            for k in ("force", "moment")
        )
        axes = spec.get("axes", "global")
        if axes not in ("global", ref.body):
            raise loader.fail(f"{entry}.axes", f"expected global or {ref.body} (the point's body), got {shown(axes)}")
        loads[key] = Load(key, ref, force, moment, GROUND if axes == "global" else ref.body)
    return loads


def _component(loader: Loader, vector: Any, entry: str, i: int) -> sp.Expr:
    if not isinstance(vector, (list, tuple)) or len(vector) != 3:
        raise loader.fail(entry, f"expected a list of 3 numbers or functions of t, got {shown(vector)}")
    return loader.scalar(vector[i], f"{entry}[{i}]", allow_time=True)


def check_actuation(loader: Loader, motors: tuple[Motor, ...], actuators: tuple[Actuator, ...]) -> None:
    """Declared actuation (motors and hydraulic actuators) must number the mechanism's mobility."""
    carrying = [*(m.name for m in motors), *(a.name for a in actuators if a.hydraulics is not None)]
    if not carrying or loader.redundant:
        return
    mobility = 6 * len(loader.bodies) - sum(JOINT_KINDS[j.type].equations for j in loader.joints.values())
    if len(carrying) > mobility:
        raise loader.over_constrained("motors" if motors else "actuators", len(carrying), "motors and hydraulic actuators")
    if len(carrying) != mobility:
        raise loader.fail(
            "motors" if motors else "actuators",
            f"the motors and the actuators with hydraulic data carry the load, so they must be as many as the mobility "
            f"({mobility}); {len(carrying)} are declared: {', '.join(carrying)}",
        )


TOOL_FORCES = ("bucket", "arm")


def read_tool_forces(
    loader: Loader, value: Any, cases: dict[str, Case], actuators: tuple[Actuator, ...], tool_points: dict[str, PointRef],
    working_range: WorkingRange | None,
) -> ToolForces:  # fmt: skip
    """``tool_forces:`` -- what ``kinegen forces`` computes (ISO 6015 bucket and arm cylinder tool forces)."""
    entry = "tool_forces"
    spec = loader.mapping(value, entry, ("case", "lip", *TOOL_FORCES, "published"), ("case", "lip"))
    case = cases.get(spec["case"]) if isinstance(spec["case"], str) else None
    if case is None:
        raise loader.fail(f"{entry}.case", f"unknown case {shown(spec['case'])} (cases: {', '.join(cases)})")
    lip = spec["lip"]
    lip = tool_points[lip] if isinstance(lip, str) and lip in tool_points else loader.point_ref(lip, f"{entry}.lip")
    hydraulic = {a.name: a for a in actuators if a.hydraulics is not None}
    drivers = [d.name for d in case.drivers]
    forces = {}
    for name in TOOL_FORCES:
        if name not in spec:
            continue
        where = f"{entry}.{name}"
        item = loader.mapping(spec[name], where, ("actuator", "driver", "pivot", "stroke"), ("actuator", "driver", "pivot"))
        if not isinstance(item["actuator"], str) or item["actuator"] not in hydraulic:
            raise loader.fail(f"{where}.actuator", f"{shown(item['actuator'])} is not an actuator with hydraulic data "
                              f"(those: {', '.join(hydraulic) or 'none'})")  # fmt: skip
        if item["driver"] not in drivers:
            raise loader.fail(f"{where}.driver", f"{shown(item['driver'])} is not a driver of case {case.name} ({', '.join(drivers)})")
        pivot = loader.point_ref(item["pivot"], f"{where}.pivot")
        if pivot.body == GROUND:
            raise loader.fail(f"{where}.pivot", "the pivot is the pin the working part turns about: a point of a moving body (bucket.Q)")
        forces[name] = ToolForce(name, item["actuator"], item["driver"], pivot, _stroke(loader, item, where, case.name, working_range))
    if not forces:
        raise loader.fail(entry, f"expected at least one of {', '.join(TOOL_FORCES)}")
    published = {}
    for key, item in loader.mapping(spec.get("published"), f"{entry}.published", TOOL_FORCES).items():
        published[key] = float(loader.scalar(item, f"{entry}.published.{key}"))
    return ToolForces(case.name, lip, forces, published)


def _stroke(loader: Loader, item: dict, where: str, case: str, working_range: WorkingRange | None) -> tuple[float, float]:
    """The searched range of the driver's input: given, or the working range's for that input."""
    missing = (where, f"no stroke: give stroke: [min, max] (the working range does not sweep {item['driver']} in {case})")
    return _input_range(loader, item.get("stroke"), f"{where}.stroke", item["driver"], case, working_range, missing)


def _input_range(
    loader: Loader, bounds: Any, where: str, driver: str, case: str, working_range: WorkingRange | None, missing: tuple[str, str]
) -> tuple[float, float]:  # fmt: skip
    """A driver input's range: ``bounds`` as given ([min, max], at entry ``where``), else the working
    range's for ``driver`` when it sweeps it in ``case``; ``missing``: (entry, problem) when neither."""
    if bounds is not None:
        if not isinstance(bounds, (list, tuple)) or len(bounds) != 2:
            raise loader.fail(where, "expected [min, max]")
        low, high = (loader.value(loader.scalar(b, f"{where}[{i}]", design=True)) for i, b in enumerate(bounds))
    elif working_range is not None and working_range.case == case and isinstance(working_range.inputs.get(driver), tuple):
        low, high = (loader.value(x) for x in working_range.inputs[driver])
    else:
        raise loader.fail(*missing)
    if not low < high:
        raise loader.fail(where, f"min {low:g} must be below max {high:g}")
    return float(low), float(high)


def read_lift_chart(loader: Loader, value: Any, cases: dict[str, Case], actuators: tuple[Actuator, ...], working_range: WorkingRange | None) -> LiftChartSpec:
    """``lift_chart:`` -- where ``kinegen forces --lift`` finds the hydraulic lift capacity."""
    entry = "lift_chart"
    spec = loader.mapping(value, entry, ("case", "point", "lifting", "place", "ranges", "heights", "radii", "without"),
                          ("case", "point", "lifting", "place", "heights", "radii"))  # fmt: skip
    case = cases.get(spec["case"]) if isinstance(spec["case"], str) else None
    if case is None:
        raise loader.fail(f"{entry}.case", f"unknown case {shown(spec['case'])} (cases: {', '.join(cases)})")
    point = loader.point_ref(spec["point"], f"{entry}.point")
    if point.body == GROUND:
        raise loader.fail(f"{entry}.point", "the lift point is on a moving body")
    hydraulic = [a.name for a in actuators if a.hydraulics is not None]
    if not isinstance(spec["lifting"], str) or spec["lifting"] not in hydraulic:
        raise loader.fail(f"{entry}.lifting", f"{shown(spec['lifting'])} is not an actuator with hydraulic data (those: {', '.join(hydraulic) or 'none'})")
    place = spec["place"]
    drivers = [d.name for d in case.drivers]
    if not isinstance(place, list) or len(place) != 2 or any(not isinstance(p, str) or p not in drivers for p in place):
        raise loader.fail(f"{entry}.place", f"expected two drivers of case {case.name} ({', '.join(drivers)}), got {shown(place)}")
    if place[0] == place[1]:
        raise loader.fail(f"{entry}.place", f"two different drivers place the lift point (radius and height); {place[0]} is named twice")
    given = loader.mapping(spec.get("ranges"), f"{entry}.ranges", tuple(place))
    ranges = {}
    for name in place:
        missing = (f"{entry}.ranges", f"no range for {name}: give ranges: {{{name}: [min, max]}}")
        ranges[name] = _input_range(loader, given.get(name), f"{entry}.ranges.{name}", name, case.name, working_range, missing)
    heights, radii = (_numbers(loader, spec[k], f"{entry}.{k}") for k in ("heights", "radii"))
    if any(r <= 0 for r in radii):
        raise loader.fail(f"{entry}.radii", "radii are distances from the swing axis: positive")
    without = spec.get("without", [])
    bodies = [b for b in loader.bodies]
    if not isinstance(without, list) or any(not isinstance(b, str) or b not in bodies for b in without):
        raise loader.fail(f"{entry}.without", f"expected a list of bodies (of {', '.join(bodies)}), got {shown(without)}")
    return LiftChartSpec(case.name, point, spec["lifting"], tuple(place), ranges, heights, radii, tuple(without))


def _numbers(loader: Loader, value: Any, entry: str) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise loader.fail(entry, f"expected a list of numbers (m), got {shown(value)}")
    return tuple(float(loader.scalar(v, f"{entry}[{i}]")) for i, v in enumerate(value))
