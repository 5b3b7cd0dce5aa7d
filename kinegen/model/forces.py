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
```

When a model declares motors or hydraulic actuators, they carry its load (``Model.actuation``)
and must be as many as the mechanism's mobility; otherwise each case's drivers carry it.
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from kinegen.errors import shown
from kinegen.model.kinds import JOINT_KINDS
from kinegen.model.schema import GROUND, Actuator, Hydraulics, Load, Motor, PointRef

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
    return pair


def read_motors(loader: Loader, value: Any) -> tuple[Motor, ...]:
    """``motors: {name: {joint: <revolute or cylindrical joint>}}``."""
    motors = []
    for key, spec in loader.mapping(value, "motors", tuple(k for k in (value or {}) if isinstance(k, str))).items():
        entry = f"motors.{key}"
        loader.name(key, entry)
        spec = loader.mapping(spec, entry, ("joint",), ("joint",))
        joint = loader.joints.get(spec["joint"]) if isinstance(spec["joint"], str) else None
        if joint is None:
            raise loader.fail(f"{entry}.joint", f"unknown joint {shown(spec['joint'])} (joints: {', '.join(loader.joints)})")
        if joint.type not in MOTOR_JOINTS:
            raise loader.fail(f"{entry}.joint", f"{joint.name} is a {joint.type} joint: a motor turns a {' or '.join(MOTOR_JOINTS)} joint")
        motors.append(Motor(key, joint.name))
    return tuple(motors)


def read_tool_points(loader: Loader, value: Any) -> dict[str, PointRef]:
    """``tool_points: {name: body.point}``: named points of moving bodies."""
    points = {}
    for key, item in loader.mapping(value, "tool_points", tuple(k for k in (value or {}) if isinstance(k, str))).items():
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
    for key, spec in loader.mapping(value, "loads", tuple(k for k in (value or {}) if isinstance(k, str))).items():
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
    if len(carrying) != mobility:
        raise loader.fail(
            "motors" if motors else "actuators",
            f"the motors and the actuators with hydraulic data carry the load, so they must be as many as the mobility "
            f"({mobility}); {len(carrying)} are declared: {', '.join(carrying)}",
        )
