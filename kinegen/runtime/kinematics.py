"""Kinematics of a solve, as functions of its :class:`~kinegen.runtime.results.Results`.

Every function takes the results first and returns arrays indexed by time first (K time
points). Frames: rotation matrices map body to global coordinates; quaternions are
(w, x, y, z) with w >= 0; angular velocities and accelerations are global; a point's
position, velocity and acceleration are global, in m, m/s and m/s^2. Points are named as
in the model (``ground`` allowed for points of the fixed frame).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kinegen.model.schema import GROUND

if TYPE_CHECKING:
    from kinegen.runtime.results import Results


def position(results: Results, body: str) -> np.ndarray:
    """Body-frame origin, global [m], (K, 3)."""
    return results.system.parametrization.pose(results.body_coordinates(body)[0])[0]


def velocity(results: Results, body: str) -> np.ndarray:
    """Velocity of the body-frame origin [m/s], (K, 3)."""
    return results.system.parametrization.frame_velocity(*results.body_coordinates(body)[:2])[0]


def acceleration(results: Results, body: str) -> np.ndarray:
    """Acceleration of the body-frame origin [m/s^2], (K, 3)."""
    return results.system.parametrization.frame_acceleration(*results.body_coordinates(body))[0]


def rotation_matrix(results: Results, body: str) -> np.ndarray:
    """Rotation matrices body -> global, (K, 3, 3)."""
    return results.system.parametrization.pose(results.body_coordinates(body)[0])[1]


def quaternion(results: Results, body: str) -> np.ndarray:
    """Unit quaternions (w, x, y, z), (K, 4), sign chosen with w >= 0."""
    from kinegen.rotations import quaternion_algebra as qa

    return qa.from_matrix(rotation_matrix(results, body))


def euler_angles(results: Results, body: str, sequence: str = "zxz") -> np.ndarray:
    """Intrinsic Euler angles [rad] for display (SciPy ``as_euler(sequence.upper())``), (K, 3)."""
    from kinegen.rotations import get

    return get(f"euler:{sequence}").from_matrix(rotation_matrix(results, body))


def omega(results: Results, body: str) -> np.ndarray:
    """Global angular velocity [rad/s], (K, 3)."""
    return results.system.parametrization.frame_velocity(*results.body_coordinates(body)[:2])[1]


def omega_dot(results: Results, body: str) -> np.ndarray:
    """Global angular acceleration [rad/s^2], (K, 3)."""
    return results.system.parametrization.frame_acceleration(*results.body_coordinates(body))[1]


def arm(results: Results, body: str, point: str) -> np.ndarray:
    """The global vector [m] (K, 3) from a body's frame origin to its named point, at every time point."""
    points = results.system.points.get(body, {})
    if point not in points:
        raise KeyError(f"no point {point!r} on body {body!r} (points: {', '.join(points) or 'none'})")
    return np.einsum("kij,j->ki", rotation_matrix(results, body), np.array(points[point]))


def _ground_point(results: Results, point: str) -> np.ndarray:
    points = results.system.ground_points
    if point not in points:
        raise KeyError(f"no point {point!r} on body 'ground' (points: {', '.join(points) or 'none'})")
    return np.tile(np.array(points[point], dtype=float), (len(results.times), 1))


def point_position(results: Results, body: str, point: str) -> np.ndarray:
    """Global position of a named body point [m] (``ground`` allowed), (K, 3)."""
    if body == GROUND:
        return _ground_point(results, point)
    return position(results, body) + arm(results, body, point)


def point_velocity(results: Results, body: str, point: str) -> np.ndarray:
    """Global velocity of a named body point: r' + omega x (A s') [m/s], (K, 3)."""
    if body == GROUND:
        return 0.0 * _ground_point(results, point)
    return velocity(results, body) + np.cross(omega(results, body), arm(results, body, point))


def point_acceleration(results: Results, body: str, point: str) -> np.ndarray:
    """Global acceleration: r'' + omega' x (A s') + omega x (omega x A s') [m/s^2], (K, 3)."""
    if body == GROUND:
        return 0.0 * _ground_point(results, point)
    lever = arm(results, body, point)
    w = omega(results, body)
    return acceleration(results, body) + np.cross(omega_dot(results, body), lever) + np.cross(w, np.cross(w, lever))


def _actuator(results: Results, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The actuator's end-to-end vector, its rate and acceleration, its length, its rate of
    extension and |d'|^2, at every time point."""
    actuators = results.system.actuators
    if name not in actuators:
        raise KeyError(f"no actuator {name!r} (actuators: {', '.join(actuators) or 'none'})")
    (b1, p1), (b2, p2), _ = actuators[name]
    d = point_position(results, b2, p2) - point_position(results, b1, p1)
    dv = point_velocity(results, b2, p2) - point_velocity(results, b1, p1)
    da = point_acceleration(results, b2, p2) - point_acceleration(results, b1, p1)
    length = np.linalg.norm(d, axis=1)
    return d, dv, da, length, np.einsum("ki,ki->k", d, dv) / length, np.einsum("ki,ki->k", dv, dv)


def actuator_length(results: Results, name: str) -> np.ndarray:
    """Distance [m] between the actuator's two points, (K,)."""
    return _actuator(results, name)[3]


def actuator_rate(results: Results, name: str) -> np.ndarray:
    """Extension rate dL/dt [m/s], (K,)."""
    return _actuator(results, name)[4]


def actuator_acceleration(results: Results, name: str) -> np.ndarray:
    """Extension acceleration d2L/dt2 = (|d'|^2 + d.d'' - L'^2) / L [m/s^2], (K,)."""
    d, _, da, length, rate, speed2 = _actuator(results, name)
    return (speed2 + np.einsum("ki,ki->k", d, da) - rate**2) / length


def range_violations(results: Results) -> list[tuple[float, str, float, tuple[float, float]]]:
    """(time, actuator, length, range) for every time point where an actuator is outside its range."""
    found = []
    for name, (_, _, limits) in results.system.actuators.items():
        if limits is None:
            continue
        length = actuator_length(results, name)
        for k in np.flatnonzero((length < limits[0]) | (length > limits[1])):
            found.append((float(results.times[k]), name, float(length[k]), tuple(limits)))
    return sorted(found)


def condition_numbers(results: Results) -> np.ndarray:
    """kinegen's condition number of Phi_q at each time point -- one definition everywhere (the
    CSV's ``jacobian_condition``, the case plot, ``kinegen compare``): the 2-norm condition number
    sigma_max / sigma_min, exact (the solve's own where it computed them so, else from the solved
    configurations, one SVD per point, computed once for these results); NaN where a point is not
    solved, inf where Phi_q is singular."""

    def compute(results: Results) -> np.ndarray:
        if results.condition_kind == "exact":
            return results.conditions
        out = np.full(len(results.times), np.nan)
        solved = np.flatnonzero(results.converged)
        if len(solved):
            matrices = np.stack([results.system.jacobian(results.q[k], results.inputs[k]) for k in solved])
            s = np.linalg.svd(matrices, compute_uv=False)
            with np.errstate(divide="ignore"):
                out[solved] = np.where(s[:, -1] > 0, s[:, 0] / s[:, -1], np.inf)
        return out

    return results.once("condition_numbers", compute)


__all__ = [
    "acceleration", "actuator_acceleration", "actuator_length", "actuator_rate", "arm", "condition_numbers", "euler_angles",
    "omega", "omega_dot", "point_acceleration", "point_position", "point_velocity", "position", "quaternion", "range_violations",
    "rotation_matrix", "velocity",
]  # fmt: skip
