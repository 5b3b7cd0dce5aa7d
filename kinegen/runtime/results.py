"""Results of a trajectory solve: per body and time, poses, velocities, accelerations.

Arrays are indexed by time first. Rotation matrices map body to global coordinates;
quaternions are (w, x, y, z); omega and omega_dot are global; point quantities are
global positions, velocities and accelerations of named body points.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from kinegen.files import STDOUT, atomic_writer, write_atomic
from kinegen.model.schema import GROUND
from kinegen.runtime.system import NumericSystem


@dataclass
class Results:
    """Time histories of one solve (the *data*; the system is the model)."""

    system: NumericSystem
    times: np.ndarray
    q: np.ndarray  #: stored coordinates, (K, n)
    v: np.ndarray  #: velocity coordinates, (K, nv)
    a: np.ndarray  #: their time derivatives, (K, nv)
    iterations: np.ndarray  #: Newton iterations per time point
    residuals: np.ndarray  #: max |Phi| at convergence per time point
    conditions: np.ndarray  #: the solver's condition number of Phi_q per time point (``condition_kind``)
    inputs: np.ndarray  #: driver inputs u per time point, (K, n_inputs)
    condition_kind: str = "none"  #: "none" (NaN, the solver's default), "estimate" (1-norm) or "exact" (2-norm)
    #: per time point: True where Newton reached the tolerance (False only for the last
    #: point of a run stopped with ``on_failure="stop"``; its q, v, a are NaN)
    converged: np.ndarray | None = None
    failure: Exception | None = None  #: the error that stopped the run, if it stopped

    def __post_init__(self) -> None:
        if self.converged is None:
            self.converged = np.ones(len(self.times), dtype=bool)

    @property
    def complete(self) -> bool:
        """True when every time point converged."""
        return self.failure is None and bool(np.all(self.converged))

    def _body(self, body: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The body's stored, velocity and acceleration coordinates over time (K, nq), (K, nv), (K, nv)."""
        if body not in self.system.bodies:
            raise KeyError(f"no body {body!r} (bodies: {', '.join(self.system.bodies)})")
        coordinates = self.system.body_coordinates
        return coordinates(self.q, body), coordinates(self.v, body, velocity=True), coordinates(self.a, body, velocity=True)

    def position(self, body: str) -> np.ndarray:
        """Body-frame origin, global, (K, 3)."""
        return self.system.parametrization.pose(self._body(body)[0])[0]

    def velocity(self, body: str) -> np.ndarray:
        """Velocity of the body-frame origin, (K, 3)."""
        return self.system.parametrization.frame_velocity(*self._body(body)[:2])[0]

    def acceleration(self, body: str) -> np.ndarray:
        """Acceleration of the body-frame origin, (K, 3)."""
        return self.system.parametrization.frame_acceleration(*self._body(body))[0]

    def rotation_matrix(self, body: str) -> np.ndarray:
        """Rotation matrices body -> global, (K, 3, 3)."""
        return self.system.parametrization.pose(self._body(body)[0])[1]

    def quaternion(self, body: str) -> np.ndarray:
        """Unit quaternions (w, x, y, z), (K, 4), sign chosen with w >= 0."""
        from kinegen.rotations import quaternion_algebra as qa

        return qa.from_matrix(self.rotation_matrix(body))

    def euler_angles(self, body: str, sequence: str = "zxz") -> np.ndarray:
        """Intrinsic Euler angles for display (SciPy ``as_euler(sequence.upper())``), (K, 3)."""
        from kinegen.rotations import get

        return get(f"euler:{sequence}").from_matrix(self.rotation_matrix(body))

    def omega(self, body: str) -> np.ndarray:
        """Global angular velocity, (K, 3)."""
        return self.system.parametrization.frame_velocity(*self._body(body)[:2])[1]

    def omega_dot(self, body: str) -> np.ndarray:
        """Global angular acceleration, (K, 3)."""
        return self.system.parametrization.frame_acceleration(*self._body(body))[1]

    def arm(self, body: str, point: str) -> np.ndarray:
        """The global vector [m] (K, 3) from a body's frame origin to its named point, at every time point."""
        points = self.system.points.get(body, {})
        if point not in points:
            raise KeyError(f"no point {point!r} on body {body!r} (points: {', '.join(points) or 'none'})")
        return np.einsum("kij,j->ki", self.rotation_matrix(body), np.array(points[point]))

    def _ground_point(self, point: str) -> np.ndarray:
        points = self.system.ground_points
        if point not in points:
            raise KeyError(f"no point {point!r} on body 'ground' (points: {', '.join(points) or 'none'})")
        return np.tile(np.array(points[point], dtype=float), (len(self.times), 1))

    def point_position(self, body: str, point: str) -> np.ndarray:
        """Global position of a named body point (``ground`` allowed), (K, 3)."""
        if body == GROUND:
            return self._ground_point(point)
        return self.position(body) + self.arm(body, point)

    def point_velocity(self, body: str, point: str) -> np.ndarray:
        """Global velocity of a named body point: r' + omega x (A s'), (K, 3)."""
        if body == GROUND:
            return 0.0 * self._ground_point(point)
        return self.velocity(body) + np.cross(self.omega(body), self.arm(body, point))

    def point_acceleration(self, body: str, point: str) -> np.ndarray:
        """Global acceleration: r'' + omega' x (A s') + omega x (omega x A s'), (K, 3)."""
        if body == GROUND:
            return 0.0 * self._ground_point(point)
        arm = self.arm(body, point)
        w = self.omega(body)
        return self.acceleration(body) + np.cross(self.omega_dot(body), arm) + np.cross(w, np.cross(w, arm))

    def sensitivity(self, body: str, point: str, parameter: str | None = None, kind: str = "position") -> np.ndarray:
        """Exact derivative of a named point's global ``kind`` (position, velocity or
        acceleration) by a design parameter, (K, 3), or by all of them, (K, 3, n_design)
        (implicit differentiation: :mod:`kinegen.runtime.sensitivity`)."""
        from kinegen.runtime.sensitivity import point_sensitivity

        out = point_sensitivity(self, body, point, kind)
        return self._by_parameter(out, parameter)

    def rotation_sensitivity(self, body: str, parameter: str | None = None) -> np.ndarray:
        """Exact change of a body's orientation by a design parameter as a global rotation vector
        (dA/dp = [dθ/dp]× A), (K, 3), or by all of them, (K, 3, n_design)."""
        from kinegen.runtime.sensitivity import rotation_sensitivity

        out = rotation_sensitivity(self, body)
        return self._by_parameter(out, parameter)

    def relative_angle_sensitivity(self, body1: str, body2: str, axis: tuple[float, float, float], parameter: str | None = None) -> np.ndarray:
        """Exact derivative of the rotation angle of ``body2`` relative to ``body1`` about ``axis``
        (a unit vector in body-1 coordinates, e.g. a revolute joint's axis; ``body1`` may be
        ``ground``) by a design parameter, (K,), or by all of them, (K, n_design)."""
        from kinegen.runtime.sensitivity import rotation_sensitivity

        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        turn = rotation_sensitivity(self, body2)
        if body1 == GROUND:
            direction = np.broadcast_to(axis, (len(self.times), 3))
        else:
            turn = turn - rotation_sensitivity(self, body1)
            direction = self.rotation_matrix(body1) @ axis
        out = np.einsum("ki,kij->kj", direction, turn)
        return self._by_parameter(out, parameter)

    def smallest_singular_value_sensitivity(
        self, parameter: str | None = None, bodies: tuple[str, ...] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """σ_min of Φ_q at every time point (the distance to a singular pose) and its exact
        derivative by a design parameter, (K,), or by all of them, (K, n_design). With ``bodies``
        (a linkage), of the critical block instead: at each time point the diagonal block of Φ_q's
        block-triangular form holding their coordinates with the smallest σ_min, where a toggle
        shows undiluted by the rest of the mechanism."""
        from kinegen.runtime.sensitivity import critical_block_sensitivity, singular_value_sensitivity

        if bodies is None:
            sigma, derivative = singular_value_sensitivity(self)
        else:
            sigma, derivative, _ = critical_block_sensitivity(self, tuple(bodies))
        return sigma, self._by_parameter(derivative, parameter)

    def actuator_length_sensitivity(self, name: str, parameter: str | None = None) -> np.ndarray:
        """Exact derivative of an actuator's length by a design parameter, (K,), or all, (K, n_design)."""
        from kinegen.runtime.sensitivity import point_sensitivity

        d, *_ = self._actuator(name)
        (b1, p1), (b2, p2), _ = self.system.actuators[name]
        change = point_sensitivity(self, b2, p2) - point_sensitivity(self, b1, p1)
        out = np.einsum("ki,kij->kj", d / np.linalg.norm(d, axis=1)[:, None], change)
        return self._by_parameter(out, parameter)

    def time_points(self, which: slice | np.ndarray) -> Results:
        """These results at some of their time points (a slice or indices): what a quantity measured
        at one time point (its maximum over a motion) differentiates there. Sensitivities are
        recomputed for them, not sliced."""
        fields = ("times", "q", "v", "a", "iterations", "residuals", "conditions", "inputs", "converged")
        return dataclasses.replace(self, **{name: getattr(self, name)[which] for name in fields})

    def state_sensitivities(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dq/dp, dv/dp, da/dp), each (K, n_v, n_design), in velocity coordinates (computed once)."""
        from kinegen.runtime.sensitivity import state_sensitivities

        return self._computed("state", state_sensitivities)

    def frame_sensitivities(self) -> np.ndarray:
        """The change of every body's frame values per unit of each design parameter, (K, n_bodies,
        FRAME_VALUES, n_design) (:func:`kinegen.runtime.sensitivity.frame_sensitivities`, computed once)."""
        from kinegen.runtime.sensitivity import frame_sensitivities

        return self._computed("frames", frame_sensitivities)

    def condition_numbers(self) -> np.ndarray:
        """kinegen's condition number of Phi_q at each time point -- one definition everywhere (the
        CSV's ``jacobian_condition``, the case plot, ``kinegen compare``): the 2-norm condition number
        sigma_max / sigma_min, exact (the solve's own where it computed them so, else from the solved
        configurations, one SVD per point); NaN where a point is not solved, inf where Phi_q is singular."""

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

        return self._computed("condition_numbers", compute)

    def _computed(self, name: str, compute):
        """``compute(self)``, computed once per results (the sensitivities of one solve)."""
        cache = self.__dict__.setdefault("_sensitivity_cache", {})
        if name not in cache:
            cache[name] = compute(self)
        return cache[name]

    def _by_parameter(self, values: np.ndarray, parameter: str | None) -> np.ndarray:
        """``values`` with the design parameters on the last axis: all of them (None), or one."""
        if parameter is None:
            return values
        names = list(self.system.design)
        if parameter not in names:
            raise KeyError(f"no design parameter {parameter!r} (design parameters: {', '.join(names) or 'none'})")
        return values[..., names.index(parameter)]

    def _actuator(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if name not in self.system.actuators:
            raise KeyError(f"no actuator {name!r} (actuators: {', '.join(self.system.actuators) or 'none'})")
        (b1, p1), (b2, p2), _ = self.system.actuators[name]
        d = self.point_position(b2, p2) - self.point_position(b1, p1)
        dv = self.point_velocity(b2, p2) - self.point_velocity(b1, p1)
        da = self.point_acceleration(b2, p2) - self.point_acceleration(b1, p1)
        length = np.linalg.norm(d, axis=1)
        return d, dv, da, length, np.einsum("ki,ki->k", d, dv) / length, np.einsum("ki,ki->k", dv, dv)

    def actuator_length(self, name: str) -> np.ndarray:
        """Distance between the actuator's two points, (K,)."""
        return self._actuator(name)[3]

    def actuator_rate(self, name: str) -> np.ndarray:
        """Extension rate dL/dt, (K,)."""
        return self._actuator(name)[4]

    def actuator_acceleration(self, name: str) -> np.ndarray:
        """Extension acceleration d2L/dt2 = (|d'|^2 + d.d'' - L'^2) / L, (K,)."""
        d, _, da, length, rate, speed2 = self._actuator(name)
        return (speed2 + np.einsum("ki,ki->k", d, da) - rate**2) / length

    def range_violations(self) -> list[tuple[float, str, float, tuple[float, float]]]:
        """(time, actuator, length, range) for every time point where an actuator is outside its range."""
        found = []
        for name, (_, _, limits) in self.system.actuators.items():
            if limits is None:
                continue
            length = self.actuator_length(name)
            for k in np.flatnonzero((length < limits[0]) | (length > limits[1])):
                found.append((float(self.times[k]), name, float(length[k]), tuple(limits)))
        return sorted(found)

    def table(self) -> tuple[list[str], np.ndarray]:
        """Column names and values of the CSV export."""
        columns = [
            self.times[:, None], self.converged[:, None].astype(float), self.iterations[:, None], self.residuals[:, None],
            self.condition_numbers()[:, None], self.inputs,
        ]  # fmt: skip
        names = [
            "t", "converged", "newton_iterations", "max_abs_phi", "jacobian_condition",
            *(f"input.{d}" for d in self.system.driver_names),
        ]  # fmt: skip
        for body in self.system.bodies:
            for label, values in (
                ("", self.position(body)),
                ("q", self.quaternion(body)),
                ("v", self.velocity(body)),
                ("a", self.acceleration(body)),
                ("omega", self.omega(body)),
                ("omega_dot", self.omega_dot(body)),
            ):
                axes = "wxyz" if label == "q" else "xyz"
                names += [f"{body}.{label}{'_' if label else ''}{c}" for c in axes]
                columns.append(values)
            for point in self.system.points.get(body, {}):
                for label, values in (
                    ("", self.point_position(body, point)),
                    ("v", self.point_velocity(body, point)),
                    ("a", self.point_acceleration(body, point)),
                ):
                    names += [f"{body}.{point}.{label}{'_' if label else ''}{c}" for c in "xyz"]
                    columns.append(values)
        for name in self.system.actuators:
            names += [f"{name}.length", f"{name}.rate", f"{name}.acceleration"]
            columns.append(np.c_[self.actuator_length(name), self.actuator_rate(name), self.actuator_acceleration(name)])
        return names, np.hstack(columns)

    def sensitivity_table(self) -> tuple[list[str], np.ndarray]:
        """Column names and values of the sensitivity CSV export: per time point, the derivative
        of every named point's position, velocity and acceleration (``d(body.point_x)/d(p)``,
        ``d(body.point_vx)/d(p)``, ``d(body.point_ax)/d(p)``) and of every actuator's length by
        every design parameter."""
        names, columns = ["t"], [self.times[:, None]]
        for body, points in self.system.points.items():
            for point in points:
                for kind, label in (("position", ""), ("velocity", "v"), ("acceleration", "a")):
                    values = self.sensitivity(body, point, kind=kind)  # (K, 3, n_design)
                    for k, parameter in enumerate(self.system.design):
                        names += [f"d({body}.{point}_{label}{c})/d({parameter})" for c in "xyz"]
                        columns.append(values[:, :, k])
        for actuator in self.system.actuators:
            values = self.actuator_length_sensitivity(actuator)
            names += [f"d({actuator}.length)/d({parameter})" for parameter in self.system.design]
            columns.append(values)
        return names, np.hstack(columns)

    def sensitivities_to_csv(self, path: str | Path) -> Path:
        """Write :meth:`sensitivity_table` to a CSV file (one row per time point)."""
        return self._write_csv(path, *self.sensitivity_table())

    def sensitivities_to_json(self, path: str | Path) -> Path:
        """Write :meth:`sensitivity_table` as JSON: model, case, the design values, and per column
        name its values over time."""
        import json

        names, values = self.sensitivity_table()
        path = Path(path)
        document = {
            "model": self.system.model, "case": self.system.case, "design": self.system.design,
            "columns": {name: values[:, i].tolist() for i, name in enumerate(names)},
        }  # fmt: skip
        write_atomic(path, json.dumps(document))
        return path

    def to_csv(self, path: str | Path, extra: tuple[list[str], np.ndarray] | None = None) -> Path:
        """Write every time history to a CSV file (one row per time point); ``extra``: more
        columns (names, values (K, n)) after them, e.g. the forces of :mod:`kinegen.forces`."""
        names, values = self.table()
        if extra is not None:
            names, values = names + list(extra[0]), np.hstack([values, extra[1]])
        return self._write_csv(path, names, values)

    def _write_csv(self, path: str | Path, names: list[str], values: np.ndarray) -> Path:
        """The table as CSV into ``path`` (``-``: standard output), all or nothing: a full disk
        or an interrupted write keeps the previous file."""
        if str(path) == STDOUT:
            _csv_rows(sys.stdout, names, values)
            sys.stdout.flush()
            return Path(path)
        path = Path(path)
        with atomic_writer(path) as binary:
            handle = io.TextIOWrapper(binary, encoding="utf-8", newline="")
            _csv_rows(handle, names, values)
            handle.flush()
            handle.detach()
        return path


#: columns that hold counts and flags: written as integers (as the C target's example writes them)
INTEGER_COLUMNS = ("converged", "newton_iterations")


def _csv_rows(handle: TextIO, names: list[str], values: np.ndarray) -> None:
    """Values as round-trip decimals; the counts and flags of :data:`INTEGER_COLUMNS` as integers."""
    writer = csv.writer(handle)
    writer.writerow(names)
    whole = [name in INTEGER_COLUMNS for name in names]
    writer.writerows([[str(int(x)) if w and np.isfinite(x) else repr(float(x)) for x, w in zip(row, whole)] for row in values])
