"""``kinegen info``: what a model holds, in one screen -- bodies, joints, drivers, cases with
their time grids, actuators with their ranges (and hydraulic data), motors and loads, design parameters, studies, and per
parametrization the coordinates and equations it gives (counted from the equations, not built)."""

from __future__ import annotations

import sympy as sp

from kinegen import rotations
from kinegen.model.schema import GROUND, Model, design_value


def counts(model: Model, parametrization: rotations.Parametrization) -> dict[str, int]:
    """Stored coordinates, velocity coordinates, joint and normalization equations of ``model``
    in ``parametrization`` (the equations formed, nothing derived)."""
    from kinegen.constraints.joints import joint_equations
    from kinegen.symbolic.assembly import GROUND_FRAME, _moving, coordinates

    coords = coordinates(model, parametrization)
    frames = {b.name: b.frame for b in coords.bodies}
    joints = sum(
        len(joint_equations(j, frames.get(j.body1, GROUND_FRAME), frames.get(j.body2, GROUND_FRAME), _moving((j.body1, j.body2))))
        for j in model.joints
    )
    normalization = sum(len(parametrization.body_normalization(sp.Matrix(b.stored))) for b in coords.bodies)
    return {"stored": len(coords.stored_names), "velocity": len(coords.velocity_names), "joints": joints, "normalization": normalization}


#: what ``kinegen info`` counts unless told
DEFAULT_PARAMETRIZATIONS = rotations.SHOWN


def describe(model: Model, parametrizations: tuple[str, ...] = DEFAULT_PARAMETRIZATIONS) -> str:
    """The model as text (see the module docstring)."""
    lines = [f"model {model.name}" + (f": {model.description}" if getattr(model, "description", "") else "")]
    lines.append(f"bodies ({len(model.bodies)}): " + ", ".join(b.name for b in model.bodies))
    lines.append(f"joints ({len(model.joints)}):")
    lines += [f"  {j.name:<22} {j.type:<12} {j.body1} - {j.body2}" for j in model.joints]
    lines.append(f"cases ({len(model.cases)}):")
    for case in model.cases.values():
        drivers = ", ".join(f"{d.name} ({d.type})" for d in case.drivers)
        lines.append(f"  {case.name:<22} t = {case.t0:g} .. {case.t1:g} s, {case.steps} points; drivers: {drivers}")
    if model.actuators:
        lines.append(f"actuators ({len(model.actuators)}):")
        for a in model.actuators:
            limits = a.limits({d.name: float(d.nominal) for d in model.design})
            shown = f"[{limits[0]:.4f}, {limits[1]:.4f}] m" if limits else "no range"
            hydraulics = ""
            if a.hydraulics is not None:
                h, nominal = a.hydraulics, {d.name: float(d.nominal) for d in model.design}
                relief = design_value(h.relief[0], nominal) / 1e6
                hydraulics = (f"; cylinder{'s' if h.cylinders > 1 else ''} {h.cylinders} x {1e3 * design_value(h.bore, nominal):.0f}/"
                              f"{1e3 * design_value(h.rod, nominal):.0f} mm, relief {relief:.1f} MPa")  # fmt: skip
            elif a.parallel is not None:
                hydraulics = f"; parallel to {a.parallel} (its data and pressure: the same force, at its own pins)"
            lines.append(f"  {a.name:<22} {a.points[0].body}.{a.points[0].name} - {a.points[1].body}.{a.points[1].name}, {shown}{hydraulics}")
    if model.motors:
        lines.append("motors: " + ", ".join(f"{m.name} (at {m.joint})" for m in model.motors))
    if model.supply is not None:
        nominal = {d.name: float(d.nominal) for d in model.design}
        pumps = ", ".join(f"{p.name} {design_value(p.max_flow, nominal) * 60000:.0f} L/min" for p in model.supply.pumps)
        circuits = "; ".join(f"{name} <- {' + '.join(fed)}" for name, fed in model.supply.circuits.items())
        lines.append(f"pumps (kinegen solve: FLOW, POWER): {pumps}; engine {design_value(model.supply.engine_power, nominal) / 1e3:.0f} kW; "
                     f"circuits {circuits}")  # fmt: skip
    if model.loads:
        lines.append("loads: " + ", ".join(f"{name} (at {load.point.body}.{load.point.name})" for name, load in model.loads.items()))
    if model.massive:
        total = sum(float(sp.N(b.inertia.mass.xreplace({d.symbol: d.nominal for d in model.design}))) for b in model.massive)
        lines.append(f"masses (kinegen solve --dynamics): {len(model.massive)} of {len(model.bodies)} bodies, {total:,.0f} kg; "
                     f"gravity {', '.join(f'{float(g):g}' for g in model.gravity)} m/s^2")  # fmt: skip
    if model.tool_forces is not None:
        lines.append(f"tool forces (kinegen forces): {', '.join(model.tool_forces.forces)} at {model.tool_forces.lip.body}.{model.tool_forces.lip.name}"
                     + (", lift chart (kinegen forces --lift)" if model.lift_chart is not None else ""))  # fmt: skip
    if model.design:
        lines.append(f"design parameters ({len(model.design)}):")
        lines += [f"  {d.name:<22} {float(d.nominal):.6g} in [{float(d.lower):g}, {float(d.upper):g}]" for d in model.design]
    if model.studies:
        lines.append("studies: " + ", ".join(f"{s.name} ({s.sense}, {len(s.parameters)} parameters)" for s in model.studies.values()))
    if model.working_range is not None:
        lines.append(f"working range: point {model.working_range.point.body}.{model.working_range.point.name} over case {model.working_range.case}")
    lines.append("per parametrization: coordinates stored / velocity, equations = joints + normalization + drivers of a case")
    drivers = max((len(c.drivers) for c in model.cases.values()), default=0)
    for name in parametrizations:
        c = counts(model, rotations.get(name))
        total = c["joints"] + c["normalization"] + drivers
        square = "square" if total == c["velocity"] else f"NOT square ({total} equations, {c['velocity']} velocity coordinates)"
        lines.append(
            f"  {name:<22} {c['stored']:>4} / {c['velocity']:<4} {c['joints']:>4} + {c['normalization']} + {drivers} = {total}  ({square})"
        )
    return "\n".join(lines).replace(f" {GROUND} - ", " ground - ")
