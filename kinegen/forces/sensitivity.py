"""Exact design sensitivities of the actuation forces that hold a load at fixed inputs.

With the inputs held, a design parameter moves the pose by S = dq/dp (in velocity coordinates;
:func:`kinegen.runtime.sensitivity.configuration_sensitivities`). Differentiating Φ_qᵀ λ = Q:

    Φ_qᵀ dλ = dQ − d(Φ_qᵀ) λ,

with d(Φ_qᵀ) λ the change of the rows' reactions at fixed λ:

* the joint rows' part, Σ_i λ_i (Σ_k D_k Φ_q[i, j] S_k + ∂Φ_q[i, j]/∂p), from the generated
  ``dvel`` kernel [M_v | E_v] at a unit velocity v = e_j (M_v = D_q(Φ_q v), E_v = ∂(Φ_q v)/∂p,
  exact; ν = 0 at zero input rates), one call per column j for every pose;
* the actuation rows' part and the load's dQ from the changes of the bodies' tangent maps, origins
  and rotations (the generated ``frames_d`` kernel along S at unit velocities) and of the named
  points' body coordinates (d s/dp), by the product rule on the rows of
  :mod:`kinegen.forces.statics`.

The forces are then f = −λ of the elements, and df/dp = −dλ of theirs.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetrs

from kinegen.errors import KinegenError
from kinegen.forces.statics import Rows, Statics
from kinegen.model.schema import GROUND, Motor
from kinegen.runtime.sensitivity import configuration_sensitivities, frame_changes


def element_force_sensitivities(statics: Statics, matrix: Rows, multipliers: np.ndarray, body: str, point: str, force: np.ndarray) -> np.ndarray:
    """d(element force)/d(design parameter), (K, n_elements, n_design), of the forces that hold the
    global ``force`` (K, 3) at ``body``'s named ``point`` (the solve ``multipliers`` = λ of
    ``matrix``), the inputs held."""
    return -MultiplierChanges(statics, matrix, multipliers, body, point, force).d_multipliers[:, statics.joint_rows :]


class MultiplierChanges:
    """dλ/dp (K, rows, n_design) of the solve that holds a global ``force`` (K, 3) at ``body``'s named
    ``point`` (None: no such load) and the ``weights`` (:meth:`Statics.weight_terms`: constant forces
    at body points), the inputs held (the module docstring) -- or the pose moving by ``s`` (K, n_v, P)
    per parameter, when the inputs move with the design (a lift point held in place); and the joints'
    reactions' changes from it. With ``inertia``, the load also holds the bodies' weights and
    d'Alembert forces along the motion (``statics``' results with their velocities and accelerations:
    inverse dynamics, the inputs' time functions held), :func:`inertial_load_changes`."""

    def __init__(self, statics: Statics, matrix: Rows, multipliers: np.ndarray, body: str | None, point: str | None,
                 force: np.ndarray | None, s: np.ndarray | None = None, weights: list | None = None,
                 inertia: bool = False) -> None:  # fmt: skip
        system = statics.system
        if not statics.declared:
            raise KinegenError("force sensitivities need the model's declared actuation (motors, hydraulic actuators)")
        if not system.design or not system.sensitivity_kernels or system.frames_d is None:
            raise KinegenError(f"{system.model}: force sensitivities need design parameters and the module's sensitivity kernels")
        self.statics, self.matrix, self.multipliers = statics, matrix, multipliers
        q, u = statics.results.q.T, statics.results.inputs.T
        # the pose's change per parameter: at held inputs, unless the caller moves them too (``s``)
        self.s = s = configuration_sensitivities(system, q, u)[0] if s is None else s  # (K, n_v, P)
        self.maps = maps = TangentChanges(statics, s)
        change = -_joint_rows_change(statics, multipliers, s)  # dQ - d(Phi_q^T) lambda, (K, n_v, P)
        for e, element in enumerate(statics.declared):
            lam = multipliers[:, statics.joint_rows + e][:, None, None]
            for b, row in (maps.motor_row(element) if isinstance(element, Motor) else maps.actuator_row(element)).items():
                change[:, statics.columns(b)] -= lam * row
        if body is not None and body != GROUND:
            jacobian_change = maps.point_jacobian(body, point)[1]  # (K, 3, n_vb, P)
            change[:, statics.columns(body)] += np.einsum("kicp,ki->kcp", jacobian_change, force)
        for weighed, local, d_local, weight, d_weight in weights or ():  # constant forces at body points (the weights)
            jacobian, jacobian_change = maps.point_jacobian_at(weighed, local, d_local)
            change[:, statics.columns(weighed)] += np.einsum("kicp,i->kcp", jacobian_change, weight) + np.einsum("kic,ip->kcp", jacobian, d_weight)
        if inertia:
            change += inertial_load_changes(statics, maps)
        out = np.empty_like(change)
        for k in range(len(change)):
            lu, pivots, _ = dgetrf(matrix.dense(k))
            out[k] = dgetrs(lu, pivots, change[k], trans=1)[0]
        self.d_multipliers = out

    def reaction(self, joint) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(force (K, 3), d force/dp (K, 3, P), moment about the joint's point (K, 3), its change) of
        what ``joint``'s first body exerts on its second (:meth:`Statics.reaction`, differentiated)."""
        statics, maps = self.statics, self.maps
        rows = statics.joint_row_indices(joint.name)
        mask = np.zeros(self.multipliers.shape[1])
        mask[rows] = 1.0
        generalized = -self.matrix.transpose_times(self.multipliers, rows)  # (K, n)
        d_generalized = -_joint_rows_change(statics, self.multipliers * mask, self.s) - _transpose_times_change(self.matrix, self.d_multipliers, rows)
        body, sign = (joint.body2, 1.0) if joint.body2 != GROUND else (joint.body1, -1.0)
        if statics.normalization_rows(body):
            raise KinegenError(f"reaction sensitivities of {joint.name}: not yet for parametrizations with normalization rows")
        columns = statics.columns(body)
        tv, tw = statics.tangents[body]
        square = np.concatenate([tv, tw], axis=1)  # (K, 6, 6)
        d_square = np.concatenate([maps.dv[body], maps.dw[body]], axis=1)  # (K, 6, 6, P)
        w = np.linalg.solve(square.swapaxes(1, 2), generalized[:, columns, None])[:, :, 0]
        right = d_generalized[:, columns] - np.einsum("kicp,ki->kcp", d_square, w)
        d_w = np.linalg.solve(square.swapaxes(1, 2), right)
        force, moment, d_force, d_moment = sign * w[:, :3], sign * w[:, 3:], sign * d_w[:, :3], sign * d_w[:, 3:]
        local2 = statics.design_vector(joint.point2 if joint.point2 is not None else [0, 0, 0])
        name2 = _point_named(statics, joint.body2, local2)
        if name2 is None:
            raise KinegenError(f"reaction sensitivities of {joint.name}: its point on {joint.body2} is not a named point")
        point, d_point, _, _ = maps.point(joint.body2, name2)
        origin, d_origin = statics.poses[body][0], maps.dorigin[body]
        arm, d_arm = point - origin, d_point - d_origin
        moment_p = moment - np.cross(arm, force)
        d_moment_p = d_moment - np.cross(d_arm.transpose(0, 2, 1), force[:, None, :]).transpose(0, 2, 1) - np.cross(
            arm[:, None, :], d_force.transpose(0, 2, 1)
        ).transpose(0, 2, 1)
        return force, d_force, moment_p, d_moment_p


def inertial_load_changes(statics: Statics, maps: TangentChanges) -> np.ndarray:
    """d Q_inertia / dp (K, n_v, P) along ``statics``' motion (its results' q, v, a): per massive body
    Q = J_Cᵀ F + T_ωᵀ M with F = m (g − a_C) at the centre of mass C and M = −(J ω̇ + ω × J ω)
    (:mod:`kinegen.forces.dynamics`), so dQ = dJ_Cᵀ F + J_Cᵀ dF + dT_ωᵀ M + T_ωᵀ dM: the tangent maps'
    changes from ``maps``, the wrench's from the frames' changes along (dq/dp, dv/dp, da/dp) and the
    design's own in the masses, centres and inertias. The generated ``inertia`` kernel is its value."""
    from kinegen.forces.dynamics import MachineWrenches, inertia_numbers

    results, model = statics.results, statics.model
    design = statics.system.design
    wrenches = MachineWrenches(results, model, changes=True)
    out = np.zeros((len(results.times), statics.n_v, maps.s.shape[2]))
    for body in model.massive:
        wrenches.add_body(body, inertia=True)
        _, force, moment, _, d_force, d_moment = wrenches.items[-1]
        local = inertia_numbers(body.inertia, design)[1]
        d_local = np.array([wrenches.gradient(x) for x in body.inertia.center])
        jacobian, d_jacobian = maps.point_jacobian_at(body.name, local, d_local)  # (K, 3, n_vb), (K, 3, n_vb, P)
        tw = statics.tangents[body.name][1]
        out[:, statics.columns(body.name)] += (np.einsum("kicp,ki->kcp", d_jacobian, force) + np.einsum("kic,kip->kcp", jacobian, d_force)
                                               + np.einsum("kicp,ki->kcp", maps.dw[body.name], moment)
                                               + np.einsum("kic,kip->kcp", tw, d_moment))  # fmt: skip
    return out


def _transpose_times_change(matrix: Rows, d_multipliers: np.ndarray, rows: list[int]) -> np.ndarray:
    """(K, n, P): the rows' part of Φ_qᵀ dλ, for each parameter."""
    return np.stack([matrix.transpose_times(d_multipliers[:, :, p], rows) for p in range(d_multipliers.shape[2])], axis=2)


def _point_named(statics: Statics, body: str, local: np.ndarray) -> str | None:
    """The name of ``body``'s point at ``local`` (body coordinates; the ground's: global), if any."""
    points = statics.system.ground_points if body == GROUND else statics.system.points[body]
    for name, value in points.items():
        if np.allclose(value, local, atol=1e-12):
            return name
    return None


def _joint_rows_change(statics: Statics, multipliers: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Σ_i λ_i dΦ_q[i, :] over the joint rows along S and p: (K, n_v, P). The ``dvel`` kernel runs
    once per velocity coordinate j at a unit velocity e_j -- on the distinct poses only, when the
    results repeat their poses (a cycle's stacked motions) -- and each j's sum runs over the entries
    it moves (the rows of the bodies of coordinate j)."""
    system = statics.system
    n, count, n_design = system.n_velocity, s.shape[0], s.shape[2]
    rows, cols = (np.asarray(x) for x in system.sensitivity_patterns["dvel"])
    joint = rows < statics.joint_rows
    rows, cols = rows[joint], cols[joint]
    state = cols < n
    q, u = statics.results.q.T, statics.results.inputs.T
    distinct = count
    for parts in (3, 2):  # the same poses repeated: the kernel's values are the same
        if count % parts == 0 and all(np.array_equal(q[:, : count // parts], q[:, k * count // parts : (k + 1) * count // parts])
                                      and np.array_equal(u[:, : count // parts], u[:, k * count // parts : (k + 1) * count // parts])
                                      for k in range(1, parts)):  # fmt: skip
            distinct = count // parts
            break
    still = np.zeros((system.n_inputs, distinct))
    lam = multipliers[:, rows]  # (K, entries)
    s_state = s[:, cols[state], :]  # (K, state entries, P)
    state_index = np.flatnonzero(state)
    out = np.zeros((count, n, n_design))
    for j in range(n):
        v = np.zeros((n, distinct))
        v[j] = 1.0
        values = np.asarray(system.sensitivity_kernels["dvel"](q[:, :distinct], v, u[:, :distinct], still), dtype=float).reshape(len(joint), -1)
        values = np.broadcast_to(values, (len(joint), distinct))[joint]  # (entries, distinct)
        moved = np.flatnonzero(np.any(values != 0, axis=1))
        if len(moved) == 0:
            continue
        weights = np.tile(values[moved].T, (count // distinct, 1)) * lam[:, moved]  # (K, moved entries)
        in_state = state[moved]
        if in_state.any():
            positions = np.searchsorted(state_index, moved[in_state])
            out[:, j] += np.einsum("ke,kep->kp", weights[:, in_state], s_state[:, positions, :])
        if (~in_state).any():
            explicit = np.zeros((n_design, count))
            np.add.at(explicit, cols[moved[~in_state]] - n, weights[:, ~in_state].T)
            out[:, j] += explicit.T
    return out


class TangentChanges:
    """The bodies' tangent maps, origins and rotations and their changes along S (per parameter)."""

    def __init__(self, statics: Statics, s: np.ndarray) -> None:
        self.statics = statics
        system = statics.system
        self.s = s
        n_vb = system.parametrization.nv
        count = s.shape[0]
        q = statics.results.q.T
        slices = system.frame_slices
        zero_state = np.zeros((system.n_velocity, count))
        zero_change = np.zeros_like(s)
        self.dv, self.dw = {}, {}  # body -> (K, 3, n_vb, P)
        self.dorigin, self.drotation = {}, {}  # body -> (K, 3, P), (K, 3, 3, P)
        for k in range(n_vb):
            unit = np.zeros((system.n_velocity, count))
            for _, offset in system.bodies.values():
                unit[offset + k] = 1.0
            changes = frame_changes(system, q, unit, zero_state, s, zero_change, zero_change)  # (K, bodies, FRAME_VALUES, P)
            for b, body in enumerate(system.bodies):
                self.dv.setdefault(body, np.zeros((count, 3, n_vb, s.shape[2])))[:, :, k] = changes[:, b, slices["velocity"]]
                self.dw.setdefault(body, np.zeros((count, 3, n_vb, s.shape[2])))[:, :, k] = changes[:, b, slices["angular_velocity"]]
                if k == 0:
                    self.dorigin[body] = changes[:, b, slices["origin"]]
                    self.drotation[body] = changes[:, b, slices["rotation"]].reshape(count, 3, 3, -1)

    def point(self, body: str, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(global position (K, 3), its change (K, 3, P), the arm from the origin (K, 3), its change)
        of ``body``'s named point."""
        statics, system = self.statics, self.statics.system
        derivative = system.point_derivatives.get(body, {}).get(name)
        d_local = np.zeros((3, self.s.shape[2])) if derivative is None else np.asarray(derivative, dtype=float)
        return self.point_at(body, statics.local(body, name), d_local)

    def point_at(self, body: str, local: np.ndarray, d_local: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`point` of the point at ``local`` (body coordinates) that moves by ``d_local`` (3, P)
        in them with the design."""
        statics = self.statics
        count, n_design = self.s.shape[0], self.s.shape[2]
        if body == GROUND:
            position = np.broadcast_to(local, (count, 3))
            return position, np.broadcast_to(d_local, (count, 3, n_design)), np.zeros((count, 3)), np.zeros((count, 3, n_design))
        origin, rotation = statics.poses[body]
        arm = rotation @ local
        d_arm = np.einsum("kijp,j->kip", self.drotation[body], local) + np.einsum("kij,jp->kip", rotation, d_local)
        return origin + arm, self.dorigin[body] + d_arm, arm, d_arm

    def point_jacobian(self, body: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """J_P (K, 3, n_vb) and its change (K, 3, n_vb, P): J_P = T_v + T_ω × arm."""
        return self._jacobian(body, self.point(body, name))

    def point_jacobian_at(self, body: str, local: np.ndarray, d_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`point_jacobian` of the point at ``local`` (body coordinates; see :meth:`point_at`)."""
        return self._jacobian(body, self.point_at(body, local, d_local))

    def _jacobian(self, body: str, located: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        tw = self.statics.tangents[body][1]
        position, _, arm, d_arm = located
        jacobian = self.statics.point_jacobian(body, position)
        d_cross = np.cross(self.dw[body].transpose(0, 2, 3, 1), arm[:, None, None, :]) + np.cross(
            tw.swapaxes(1, 2)[:, :, None, :], d_arm.transpose(0, 2, 1)[:, None, :, :]
        )  # (K, n_vb, P, 3)
        return jacobian, self.dv[body] + d_cross.transpose(0, 3, 1, 2)

    def actuator_row(self, actuator) -> dict[str, np.ndarray]:
        """Per body, the change of the element's row along S: (K, n_vb, P) -- the sum of its cylinders'
        (the actuator and those parallel to it, :meth:`kinegen.model.schema.Model.members`)."""
        out: dict[str, np.ndarray] = {}
        for member in self.statics.model.members(actuator.name):
            for body, change in self._length_row(member).items():
                out[body] = out.get(body, 0.0) + change
        return out

    def _length_row(self, actuator) -> dict[str, np.ndarray]:
        """Per body, the change of one cylinder's row dL/dv = e.(J_P1 - J_P2) along S: (K, n_vb, P)."""
        ends = [(ref.body, ref.name) for ref in actuator.points]
        (r1, d1, _, _), (r2, d2, _, _) = (self.point(b, p) for b, p in ends)
        gap, d_gap = r1 - r2, d1 - d2
        length = np.linalg.norm(gap, axis=1)
        e = gap / length[:, None]
        d_e = (d_gap - e[:, :, None] * np.einsum("ki,kip->kp", e, d_gap)[:, None, :]) / length[:, None, None]
        out: dict[str, np.ndarray] = {}
        for sign, (body, name) in zip((1.0, -1.0), ends):
            if body == GROUND:
                continue
            jacobian, d_jacobian = self.point_jacobian(body, name)
            change = np.einsum("kip,kic->kcp", d_e, jacobian) + np.einsum("ki,kicp->kcp", e, d_jacobian)
            out[body] = out.get(body, 0.0) + sign * change
        return out

    def motor_row(self, motor: Motor) -> dict[str, np.ndarray]:
        """Per body, the change of the row dθ/dv = a.(T_ω2 - T_ω1) along S: (K, n_vb, P)."""
        statics = self.statics
        joint = statics.joints[motor.joint]
        axis_local = statics.design_vector(joint.axis1)
        axis = np.einsum("kij,j->ki", statics.rotation(joint.body1), axis_local)
        if joint.body1 == GROUND:
            d_axis = np.zeros((*axis.shape, self.s.shape[2]))
        else:
            d_axis = np.einsum("kijp,j->kip", self.drotation[joint.body1], axis_local)
        out: dict[str, np.ndarray] = {}
        for sign, body in ((1.0, joint.body2), (-1.0, joint.body1)):
            if body == GROUND:
                continue
            tw = statics.tangents[body][1]
            change = np.einsum("kip,kic->kcp", d_axis, tw) + np.einsum("ki,kicp->kcp", axis, self.dw[body])
            out[body] = out.get(body, 0.0) + sign * change
        return out
