"""The exact design derivatives of the limits along a path (:class:`kinegen.forces.cycle.PathConstraints`),
for the cycle time's gradient (:func:`kinegen.forces.cycle.cycle_time`).

Every coefficient of the limits is a function of the design p through the path's poses, velocities and
accelerations (their state sensitivities dq/dp, dv/dp, da/dp at the case's own inputs), the masses,
the cylinders' areas, the settings and the pumps' data:

* the elements' forces at rest, per unit s̈ and per unit ṡ² come from three motions -- at rest (dq/dp,
  0, 0), at (v, a) = (0, q') (dq/dp, 0, dv/dp) and the case's own (dq/dp, dv/dp, da/dp) -- stacked as
  one of 3K points and differentiated at once (:class:`kinegen.forces.sensitivity.MultiplierChanges`
  with the inertia, the loads held as constant forces at their points);
* the tipping margins the same way (:func:`kinegen.forces.dynamics.tipping_margin` with changes);
* a cylinder's rate L' = e·(v1 - v2) from its points' positions and velocities and their exact
  sensitivities, a motor's θ' = a·(ω2 - ω1) from the frames' sensitivities;
* the constant data (areas, settings, displacements, pumps, engine) by their expressions' gradients.

Arrays carry the design parameters last (P of them, in the system's design order).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from kinegen.errors import KinegenError
from kinegen.model import Model
from kinegen.model.schema import GROUND, design_gradient, design_value
from kinegen.runtime import kinematics
from kinegen.runtime.results import Results
from kinegen.runtime.sensitivity import STATE, frame_sensitivities, point_sensitivity, state_sensitivities


def stacked_motions(results: Results, changes: bool) -> Results:
    """The path's three motions as one of 3K points: at rest, at (v, a) = (0, q') and the case's own
    (q', q''); with ``changes``, their state sensitivities seeded (the solve's own, per motion)."""
    zero = np.zeros_like(results.v)
    triple = lambda x: np.concatenate([x, x, x])  # noqa: E731
    stacked = dataclasses.replace(
        results, times=triple(results.times), q=triple(results.q), v=np.concatenate([zero, zero, results.v]),
        a=np.concatenate([zero, results.v, results.a]), iterations=triple(results.iterations), residuals=triple(results.residuals),
        conditions=triple(results.conditions), inputs=triple(results.inputs), converged=triple(results.converged),
    )  # fmt: skip
    if changes:
        s, v, a = state_sensitivities(results)
        none = np.zeros_like(s)
        seeded = (triple(s), np.concatenate([none, none, v]), np.concatenate([none, v, a]))
        stacked.once(STATE, lambda _: seeded)  # what state_sensitivities(stacked) then gives
    return stacked


def split(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(at rest, per unit s̈, per unit ṡ²) of a quantity over the stacked motions (first axis 3K)."""
    count = len(values) // 3
    rest = values[:count]
    return rest, values[count : 2 * count] - rest, values[2 * count :] - rest


def load_weights(results: Results, model: Model, loads: tuple[str, ...]) -> list:
    """The loads as constant global forces at body points, as :class:`MultiplierChanges` takes them
    (body, local point, its design change, force, its change); a load that is not one is refused."""
    system = results.system
    n_design = len(system.design)
    out = []
    for name in loads:
        load = model.loads[name]
        if load.axes != GROUND or any(x != 0 for x in load.moment) or any(e.free_symbols for e in load.force):
            raise KinegenError(f"the cycle time's gradient holds constant global forces: load {name} is not one")
        body, point = load.point.body, load.point.name
        if body == GROUND:
            continue
        local = np.asarray(system.points[body][point], dtype=float)
        d_local = np.asarray(system.point_derivatives.get(body, {}).get(point, np.zeros((3, n_design))), dtype=float)
        out.append((body, local, d_local, np.array([float(x) for x in load.force]), np.zeros((3, n_design))))
    return out


def element_force_changes(stacked: Results, model: Model, loads: tuple[str, ...]) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """The elements' names, forces (3K, n_e) over the stacked motions and their exact derivatives (3K, n_e, P)."""
    from kinegen.forces.dynamics import inertial_load
    from kinegen.forces.sensitivity import MultiplierChanges
    from kinegen.forces.statics import Statics

    statics = Statics(stacked, model)
    matrix = statics.matrix()
    load = sum((statics.generalized_load(model.loads[name]) for name in loads), np.zeros((len(stacked.times), statics.n_v)))
    multipliers = statics.solve(matrix, load + inertial_load(stacked))
    changes = MultiplierChanges(statics, matrix, multipliers, None, None, None, s=state_sensitivities(stacked)[0],
                                weights=load_weights(stacked, model, loads), inertia=True)  # fmt: skip
    gains = statics.input_gains()
    forces = statics.element_forces(multipliers)
    d_forces = changes.d_multipliers[:, statics.joint_rows :] * gains[:, :, None]
    return tuple(e.name for e in statics.elements), forces, d_forces


def actuator_rate_changes(results: Results, name: str) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder's rate L' = e·(v1 - v2) (K,) at the case's own pace and its exact derivative (K, P)."""

    ends = results.system.actuators[name][:2]
    r = [kinematics.point_position(results, b, p) for b, p in ends]
    v = [kinematics.point_velocity(results, b, p) for b, p in ends]
    dr = [point_sensitivity(results, b, p, kind="position") for b, p in ends]
    dv = [point_sensitivity(results, b, p, kind="velocity") for b, p in ends]
    gap, d_gap = r[0] - r[1], dr[0] - dr[1]
    motion, d_motion = v[0] - v[1], dv[0] - dv[1]
    length = np.linalg.norm(gap, axis=1)
    e = gap / length[:, None]
    d_e = (d_gap - e[:, :, None] * np.einsum("ki,kip->kp", e, d_gap)[:, None, :]) / length[:, None, None]
    rate = np.einsum("ki,ki->k", e, motion)
    return rate, np.einsum("kip,ki->kp", d_e, motion) + np.einsum("ki,kip->kp", e, d_motion)


def turn_rate_changes(results: Results, model: Model, joint_name: str) -> tuple[np.ndarray, np.ndarray]:
    """A joint's turn rate θ' = a·(ω2 - ω1) (K,) and its exact derivative (K, P), a = the joint's
    axis carried by its first body."""
    from kinegen.forces.supply import turn_rate

    system = results.system
    joint = next(j for j in model.joints if j.name == joint_name)
    design = system.design
    axis = np.array([design_value(x, design) for x in joint.axis1], dtype=float)
    norm = np.linalg.norm(axis)
    d_axis_raw = np.array([design_gradient(x, list(design), design) for x in joint.axis1])  # (3, P)
    unit = axis / norm
    d_unit = (d_axis_raw - np.outer(unit, unit @ d_axis_raw)) / norm
    frames = frame_sensitivities(results)
    slices, bodies = system.frame_slices, list(system.bodies)
    count, n_design = len(results.times), len(design)

    def omega(body: str) -> tuple[np.ndarray, np.ndarray]:
        if body == GROUND:
            return np.zeros((count, 3)), np.zeros((count, 3, n_design))
        return kinematics.omega(results, body), frames[:, bodies.index(body), slices["angular_velocity"]]

    (w1, dw1), (w2, dw2) = omega(joint.body1), omega(joint.body2)
    if joint.body1 == GROUND:
        carried, d_carried = np.broadcast_to(unit, (count, 3)), np.broadcast_to(d_unit, (count, 3, n_design))
    else:
        rotation = kinematics.rotation_matrix(results, joint.body1)
        d_rotation = frames[:, bodies.index(joint.body1), slices["rotation"]].reshape(count, 3, 3, n_design)
        carried = rotation @ unit
        d_carried = np.einsum("kijp,j->kip", d_rotation, unit) + np.einsum("kij,jp->kip", rotation, d_unit)
    relative, d_relative = w2 - w1, dw2 - dw1
    rate = turn_rate(results, model, joint_name)
    return rate, np.einsum("kip,ki->kp", d_carried, relative) + np.einsum("ki,kip->kp", carried, d_relative)


def number(expr, design: dict[str, float]) -> tuple[float, np.ndarray]:
    """An expression of the design parameters at ``design`` and its gradient (P,)."""
    return float(design_value(expr, design)), design_gradient(expr, list(design), design)
